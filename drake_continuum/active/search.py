"""Monte Carlo tree search over the next wraps (paper section IV-D, eq. 1-3; results in V-C).

Given a trained chord classifier and the training wraps, choose the planes to wrap next on an
unknown object, trading movement cost against the probability of misclassification (eq. 1).

A node holds an observation, an edge an action. Selection by UCT (eq. 2), one new node a
simulation with its observation drawn from eq. 3 (the observation model, active.observation),
then a random rollout to the horizon that stores nothing; the leaf's reward 1 - C_T (eq. 1) is
backpropagated with discount. Moving to a plane already on the path is allowed (the arm stays
or goes back: no new chords, the cost of the move); such repeats are dropped from the plan,
which is why a plan of horizon 5 has 0 to 5 new wraps, as in Table II.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from ..features.cells import CellCounts, contact_bounds, extent_of_bounds
from ..features.chords import bin_index, contact_extent
from .observation import ActiveModel, ObservationModel
from .params import N_CHORD_DIMS, ActiveParams

__all__ = ["TreeSearch", "SearchResult", "strong_prediction"]


# --------------------------------------------------------------------------- state and posterior

def strong_prediction(proba: np.ndarray, params: ActiveParams = ActiveParams()) -> bool:
    """The paper's stop rule: top probability above 0.5 and at least 3 times the next."""
    p = np.sort(np.asarray(proba, dtype=float))[::-1]
    second = p[1] if len(p) > 1 else 0.0
    return bool(p[0] > params.strong_probability
                and p[0] >= params.strong_ratio * second - 1e-12)  # "at least": 3 * 0.2 rounds up


def _entropy(p: np.ndarray) -> np.ndarray:
    p = np.clip(p, 1e-12, 1.0)
    return -(p * np.log(p)).sum(axis=-1)


class _Posterior:
    """p(y | h): the classifier on real chords plus training observations, cached by id set.

    The accumulated set of a tree path is (real history) + (training wraps on the path); the
    history is fixed during one search, so the sorted tuple of training ids is the cache key.
    A classifier with `predict_proba_bins` (classify.ChordModel) is given histogram cells
    directly (and the camera's view of the object, when known and the classifier uses it;
    and the contact extent of the set's wraps, real and training, when it learnt one); any
    other gets chords at bin centres, which fall in the same cells. A classifier that
    takes cell counts (ChordModel.takes_cell_counts) gets each wrap's CellCounts instead of
    the set's cells, and the extent comes from each wrap's contact bounds: both are binned
    and bounded once a wrap, not once a set.
    """

    def __init__(self, model: "ActiveModel"):
        self.model = model
        self.obs = model.observations
        clf = model.classifier
        self.by_cells = hasattr(clf, "predict_proba_bins")
        self.by_counts = self.by_cells and bool(getattr(clf, "takes_cell_counts", False))
        self.uses_extent = self.by_cells and len(getattr(clf, "extent_mean", ())) > 0
        self.by_bounds = not getattr(clf, "turn_invariant", False)
        self.history: list = []
        self.history_contacts: list[np.ndarray] = []
        self.history_bounds: list[np.ndarray] = []
        self.view: np.ndarray | None = None
        self._parts: dict[int, np.ndarray] = {}
        self._cache: dict[tuple, np.ndarray] = {}
        self.calls = 0

    def set_history(self, chords: Sequence[np.ndarray], contacts: Sequence = ()) -> None:
        """The real wraps' chords and contact centres ((m, 3) each; fewer, or None, where
        unknown)."""
        chords = [np.asarray(c, dtype=float).reshape(-1, N_CHORD_DIMS) for c in chords]
        self.history = ([bin_index(c, self.obs.edges) for c in chords] if self.by_cells
                        else chords)
        if self.by_counts and self.history:  # the real wraps' counts summed once a search
            self.history = [CellCounts.summed(CellCounts.of(c) for c in self.history)]
        self.history_contacts = [np.asarray(c, dtype=float).reshape(-1, 3) for c in contacts
                                 if c is not None]
        self.history_bounds = [contact_bounds(c) for c in self.history_contacts if len(c)]
        self._cache.clear()

    def extent(self, ids: Sequence[int]) -> np.ndarray:
        """(5,) chords.contact_extent of the real wraps' and training wraps `ids`' contact
        centres together (NaN: none known)."""
        if self.by_bounds:
            bounds = self.history_bounds + [b for b in map(self.obs.contact_bounds, ids)
                                            if b is not None]
            return extent_of_bounds(np.array(bounds) if bounds else np.zeros((0, 7)))
        points = self.history_contacts + [self.obs.contact_points(i) for i in ids]
        return contact_extent(np.concatenate(points) if points else np.zeros((0, 3)),
                              bool(getattr(self.model.classifier, "turn_invariant", False)))

    def set_view(self, view) -> None:
        """The camera's view of the object (perception.locate.view_extent) for a classifier
        that uses it (ChordModel.uses_view); None: unknown (or not used)."""
        clf = self.model.classifier
        uses = self.by_cells and getattr(clf, "uses_view", False)
        self.view = (np.asarray(view, dtype=float).reshape(1, -1)
                     if view is not None and uses else None)
        self._cache.clear()

    def _part(self, i: int):
        p = self._parts.get(i)
        if p is None:
            p = self._parts[i] = (self.obs.cell_counts(i) if self.by_counts
                                  else self.obs.cells(i) if self.by_cells
                                  else self.obs.centres(i))
        return p

    def _input(self, ids: Sequence[int]):
        parts = self.history + [self._part(i) for i in ids]
        if self.by_counts:
            return tuple(parts)
        if parts:
            return np.concatenate(parts)
        return np.zeros(0, np.int64) if self.by_cells else np.zeros((0, N_CHORD_DIMS))

    def _predict(self, id_sets: list) -> np.ndarray:
        self.calls += 1
        clf = self.model.classifier
        inputs = [self._input(ids) for ids in id_sets]
        if not self.by_cells:
            return np.asarray(clf.predict_proba(inputs))
        extra = {}
        if self.view is not None:
            extra["views"] = np.repeat(self.view, len(inputs), axis=0)
        if self.uses_extent:
            extra["extents"] = np.array([self.extent(ids) for ids in id_sets])
        return np.asarray(clf.predict_proba_bins(inputs, **extra))

    def __call__(self, ids: tuple) -> np.ndarray:
        p = self._cache.get(ids)
        if p is None:
            p = (self.obs.class_prior if not self.history and not ids and self.view is None
                 else self._predict([ids])[0])
            self._cache[ids] = p
        return p

    def batch(self, id_sets: Sequence[tuple]) -> np.ndarray:
        """(len(id_sets), C), one classifier call for all sets not yet cached."""
        todo = [s for s in dict.fromkeys(id_sets) if s not in self._cache]
        if todo:
            self._cache.update(zip(todo, self._predict(todo)))
        return np.array([self(s) for s in id_sets])


class _Observations:
    """Successor candidates p(z'|z, a, y) for any observation id.

    Ids 0..n-1 are training wraps; n + r is the r-th real wrap of the object being recognised;
    None is "no wrap yet".
    """

    def __init__(self, obs: ObservationModel):
        self.obs = obs
        self.real: list[tuple[int, tuple]] = []     # (plane, successors) of real wraps

    def add_real(self, plane: int, chords: np.ndarray) -> int:
        sim = (self.obs.discretise(chords) @ self.obs.histograms_t).toarray()
        succ, count = self.obs.successors_of(sim, plane)
        self.real.append((plane, (succ[0], count[0])))
        return self.obs.n_observations + len(self.real) - 1

    def plane(self, z) -> int:
        n = self.obs.n_observations
        return int(self.obs.obs_plane[z]) if z < n else self.real[z - n][0]

    def successors(self, z) -> tuple[np.ndarray, np.ndarray]:
        """(C, P, K) candidate ids and (C, P) counts."""
        if z is None:
            return self.obs.initial_successors
        n = self.obs.n_observations
        if z < n:
            succ, count = self.obs.training_successors
            return succ[z], count[z]
        return self.real[z - n][1]


# --------------------------------------------------------------------------- tree search

class _Node:
    """A tree node: the observation reached, the planes visited on the path, edge statistics."""

    __slots__ = ("obs", "plane", "depth", "ids", "visited", "visits", "n_a", "w_a",
                 "children", "feasible")

    def __init__(self, obs, plane: int, depth: int, *, ids: tuple, visited: dict, feasible):
        self.obs = obs
        self.plane = plane
        self.depth = depth
        self.ids = ids              # sorted training ids accumulated on the path
        self.visited = visited      # plane -> observation id on the path (incl. history)
        self.visits = 0
        self.n_a = np.zeros(len(feasible))
        self.w_a = np.zeros(len(feasible))
        self.children: dict[int, _Node] = {}
        self.feasible = feasible    # (P,) bool: actions that can be taken here

    def mean_reward(self) -> np.ndarray:
        """(P,) the stored 1 - C_a of each action (nan where never visited)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.n_a > 0, self.w_a / self.n_a, np.nan)

    def uct(self, c: float) -> np.ndarray:
        """(P,) eq. 2: (1 - C_a) + c sqrt(2 ln N / N_a); inf for untried, -inf for infeasible."""
        with np.errstate(invalid="ignore", divide="ignore"):
            u = self.w_a / self.n_a + c * np.sqrt(2.0 * np.log(max(self.visits, 1)) / self.n_a)
        u = np.where(self.n_a > 0, u, np.inf)
        return np.where(self.feasible, u, -np.inf)


@dataclass
class SearchResult:
    """One tree search (one iteration).

    Attributes:
        plan: planes to wrap, in order; planes already wrapped and repeats removed.
        path: the raw best path of actions from the root (may repeat planes).
        root_actions: per plane, [visits, mean reward] of the root's edges.
        n_simulations, time_s, classifier_calls: effort.
    """

    plan: list
    path: list
    root_actions: list
    n_simulations: int
    time_s: float
    classifier_calls: int


class TreeSearch:
    """Monte Carlo tree search over wrap planes for one object being recognised.

    Holds the object's real wraps so far; `search()` returns the next plan. The tree is built
    afresh each search (each iteration), as in the paper.
    """

    def __init__(self, model: ActiveModel, params: ActiveParams = ActiveParams(), *,
                 available: Sequence[int] | None = None, rng: np.random.Generator | None = None,
                 view=None):
        self.model = model
        self.params = params
        self.obs = model.observations
        P = self.obs.n_planes
        self.available = np.ones(P, bool) if available is None else np.isin(np.arange(P),
                                                                           list(available))
        self.rng = rng if rng is not None else np.random.default_rng(params.seed)
        self.cost = self.obs.cost_matrix / np.pi            # normalised to [0, 1]
        self.posterior = _Posterior(model)
        self.posterior.set_view(view)                       # the camera's, before any wrap
        self.observations = _Observations(self.obs)
        self.obs.training_successors                        # built once a model, not timed
        self.history: list[tuple[int, int]] = []            # (plane, observation id)
        self.history_chords: list[np.ndarray] = []
        self.history_contacts: list[np.ndarray | None] = []
        self.current_plane = int(params.start_plane)
        self.root: _Node | None = None                      # the last search's tree

    # -- the object's real wraps
    def add_wrap(self, plane: int, chords: np.ndarray, contacts=None) -> None:
        """Record a real wrap (its chords, and its (m, 3) contact centres if known): it
        becomes the root observation and part of h."""
        z = self.observations.add_real(plane, chords)
        self.history.append((plane, z))
        self.history_chords.append(np.asarray(chords, dtype=float).reshape(-1, N_CHORD_DIMS))
        self.history_contacts.append(contacts)
        self.current_plane = plane

    def mark_unavailable(self, plane: int) -> None:
        self.available[plane] = False

    def proba(self) -> np.ndarray:
        """p(y | h) of the real wraps so far."""
        self.posterior.set_history(self.history_chords, self.history_contacts)
        return self.posterior(())

    # -- the tree
    def _feasible(self, z, visited: Mapping[int, int]) -> np.ndarray:
        count = self.observations.successors(z)[1]
        f = self.available & (count.sum(axis=0) > 0)
        f[list(visited)] = True                            # staying or going back: always possible
        return f

    def _root(self) -> _Node:
        visited = {p: z for p, z in self.history}
        z = self.history[-1][1] if self.history else None
        return _Node(z, self.current_plane, 0, ids=(), visited=visited,
                     feasible=self._feasible(z, visited))

    def _step(self, z, visited: dict, ids: tuple, *, a: int, p_y: np.ndarray):
        """Observation after action a, eq. 3; returns (z', ids', visited', y drawn)."""
        if a in visited:                                   # a repeat brings no new chords
            y = self.rng.choice(len(p_y), p=p_y)
            return visited[a], ids, visited, y
        succ, count = self.observations.successors(z)
        w = p_y * (count[:, a] > 0)
        y = self.rng.choice(len(w), p=w / w.sum())
        z2 = int(succ[y, a, self.rng.integers(count[y, a])])
        return z2, tuple(sorted(ids + (z2,))), {**visited, a: z2}, y

    def _simulate(self, root: _Node) -> None:
        T, prm = self.params.horizon, self.params
        node, edges, move = root, [], 0.0
        y = None
        while node.depth < T:                              # selection
            if not node.feasible.any():
                break
            untried = np.flatnonzero(node.feasible & (node.n_a == 0))
            a = int(self.rng.choice(untried)) if len(untried) else int(np.argmax(
                node.uct(prm.exploration)))
            edges.append((node, a))
            move += self.cost[node.plane, a]
            child = node.children.get(a)
            if child is None:                              # expansion: one new node
                z, ids, visited, y = self._step(node.obs, node.visited, node.ids, a=a,
                                                p_y=self.posterior(node.ids))
                child = node.children[a] = _Node(z, a, node.depth + 1, ids=ids, visited=visited,
                                                 feasible=self._feasible(z, visited))
                node = child
                break
            node = child
        z, plane, ids, visited, depth = node.obs, node.plane, node.ids, node.visited, node.depth
        if depth < T and y is None:
            p = self.posterior(ids)
            y = self.rng.choice(len(p), p=p)
        while depth < T:                                   # rollout: random, stores nothing
            succ, count = self.observations.successors(z)
            f = self.available & (count[y] > 0)
            f[list(visited)] = True
            a = int(self.rng.choice(np.flatnonzero(f)))
            move += self.cost[plane, a]
            if a in visited:
                z = visited[a]
            else:
                z = int(succ[y, a, self.rng.integers(count[y, a])])
                visited = {**visited, a: z}
                ids = tuple(sorted(ids + (z,)))
            plane, depth = a, depth + 1
        if depth == 0:
            return
        self._backpropagate(edges, self.reward(move, depth, self.posterior(ids)), depth)

    def reward(self, move: float, n_steps: int, proba: np.ndarray) -> float:
        """1 - C_T, eq. 1: C_T = lambda/T sum(cost/pi) + (1 - lambda)(1 - max p(y | h_T))."""
        lam = self.params.cost_weight
        return 1.0 - (lam * move / n_steps + (1.0 - lam) * (1.0 - float(np.max(proba))))

    def _backpropagate(self, edges: list, reward: float, n_steps: int) -> None:
        """Discounted: the edge taken at depth d receives gamma^(n_steps - 1 - d) * reward."""
        g = self.params.discount
        for node, a in edges:
            node.visits += 1
            node.n_a[a] += 1
            node.w_a[a] += g ** (n_steps - 1 - node.depth) * reward

    def search(self, n_simulations: int | None = None) -> SearchResult:
        """One tree search from the current state; returns the best plan."""
        t0 = time.perf_counter()
        self.posterior.set_history(self.history_chords, self.history_contacts)
        calls0 = self.posterior.calls
        root = self.root = self._root()
        n = self.params.n_simulations if n_simulations is None else n_simulations
        if root.feasible.any():
            for _ in range(n):
                self._simulate(root)
        path, node = [], root
        while node.children:
            q = np.where(node.n_a > 0, node.mean_reward(), -np.inf)
            a = int(np.argmax(q))
            path.append(a)
            node = node.children[a]
        done = {p for p, _ in self.history}
        plan = []
        for a in path:
            if a not in done and a not in plan:
                plan.append(a)
        roots = [[int(root.n_a[a]), float(root.w_a[a] / root.n_a[a]) if root.n_a[a] else None]
                 for a in range(self.obs.n_planes)]
        return SearchResult(plan, path, roots, n, time.perf_counter() - t0,
                            self.posterior.calls - calls0)

    # -- greedy baseline
    def expected_information_gain(self) -> np.ndarray:
        """(P,) H(y|h) - E_{z'~p(z'|z,a)} H(y|h, z') for new planes (nan where impossible)."""
        self.posterior.set_history(self.history_chords, self.history_contacts)
        p_y = self.posterior(())
        z = self.history[-1][1] if self.history else None
        succ, count = self.observations.successors(z)
        done = {p for p, _ in self.history}
        sets, weights, owner = [], [], []
        for a in np.flatnonzero(self.available):
            if a in done:
                continue
            w_y = p_y * (count[:, a] > 0)
            if w_y.sum() <= 0:
                continue
            w_y = w_y / w_y.sum()
            for y in np.flatnonzero(w_y):
                for z2 in succ[y, a, :count[y, a]]:
                    sets.append((int(z2),))
                    weights.append(w_y[y] / count[y, a])
                    owner.append(a)
        gain = np.full(self.obs.n_planes, np.nan)
        if not sets:
            return gain
        H = _entropy(self.posterior.batch(sets))
        owner, weights = np.asarray(owner), np.asarray(weights)
        expected = np.bincount(owner, weights * H, minlength=len(gain))
        mass = np.bincount(owner, weights, minlength=len(gain))
        has = mass > 0
        gain[has] = _entropy(p_y) - expected[has] / mass[has]
        return gain


