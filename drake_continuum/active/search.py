"""Active recognition by Monte Carlo tree search (paper section IV-D, eq. 1-3; results in V-C).

Given a trained chord classifier and the training wraps, choose the planes to wrap next on an
unknown object, trading movement cost against the probability of misclassification (eq. 1).

Observation model (IV-D.2). A training wrap is one observation z, identified by its index. It is
stored discretised at histogram bin centres (occupied bin indices with counts), which rebuilds
its histogram exactly. Every ordered pair (i, j) of wraps of one training object is a tally for
p(z' = j | z = i, a = plane(j), y = class of the object). The action is the *target plane*, so an
action means the same on every object and its cost is the rotation angle from the current plane.
An observation that is not in the tallies (the real wrap at the root, or a training wrap of
another class) is matched to the `neighbours` training wraps of class y on the same plane whose
histograms are most similar (cosine of bin counts): p(z'|z, a, y) is the tally of their
successors on plane a. Before the first wrap there is no z, and p(z'|a, y) is uniform over the
training wraps of class y on plane a.

Tree search (IV-D.2). A node holds an observation, an edge an action. Selection by UCT (eq. 2),
one new node a simulation with its observation drawn from eq. 3, then a random rollout to the
horizon that stores nothing; the leaf's reward 1 - C_T (eq. 1) is backpropagated with discount.
Moving to a plane already on the path is allowed (the arm stays or goes back: no new chords, the
cost of the move); such repeats are dropped from the plan, which is why a plan of horizon 5 has
0 to 5 new wraps, as in Table II.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, field, fields, replace
from functools import cached_property
from pathlib import Path
from typing import Callable, Mapping, Protocol, Sequence

import numpy as np
import scipy.sparse as sp

from ..errors import ConfigError, InputError, MissingFileError
from ..features.chords import bin_centres, bin_index, histogram_rows
from ..files import array_shapes, jsonable, model_digest, write_atomic, write_json

FORMAT_VERSION = 2  # 2: array shapes and their SHA-256 in observations.json
_KIND = "drake_continuum.active.observation_model"
N_CHORD_DIMS = 7


# --------------------------------------------------------------------------- parameters

@dataclass(frozen=True)
class ActiveParams:
    """Constants of active recognition; defaults in the `active` section of models/config.yaml.

    Args:
        exploration: c of eq. 2 (UCT exploration weight).
        horizon: T, the tree depth and the most wraps one plan can hold (paper: 5).
        cost_weight: lambda of eq. 1, weight of the movement cost.
        discount: gamma of the discounted backpropagation.
        n_simulations: simulations a tree search.
        max_iterations: tree searches a recognition (paper, Table II: 3).
        neighbours: training wraps of one class matched to an observation for p(z'|z, a, y).
        strong_probability, strong_ratio: the stop rule, top probability above
            strong_probability and at least strong_ratio times the next (paper: 0.5, 3).
        start_plane: plane index the arm rests on before the first wrap.
        seed: default seed.
    """

    exploration: float = 1.0 / math.sqrt(2.0)
    horizon: int = 5
    cost_weight: float = 0.5
    discount: float = 0.95
    n_simulations: int = 200
    max_iterations: int = 3
    neighbours: int = 5
    strong_probability: float = 0.5
    strong_ratio: float = 3.0
    start_plane: int = 0
    seed: int = 0

    def __post_init__(self):
        if self.horizon < 1 or self.n_simulations < 1 or self.max_iterations < 1:
            raise ConfigError("ActiveParams: horizon, n_simulations, max_iterations must be >= 1")
        if self.neighbours < 1:
            raise ConfigError("ActiveParams: neighbours must be >= 1")
        if not 0.0 <= self.cost_weight <= 1.0 or not 0.0 < self.discount <= 1.0:
            raise ConfigError("ActiveParams: need 0 <= cost_weight <= 1 and 0 < discount <= 1")
        if self.exploration < 0:
            raise ConfigError("ActiveParams: exploration must be >= 0")

    @classmethod
    def from_yaml(cls, path=None) -> "ActiveParams":
        """The `active` section of an experiment configuration (default models/config.yaml),
        read and checked by config.load_config."""
        from ..config import load_config

        return load_config(path).active


def load_params(path=None, **overrides) -> ActiveParams:
    """models/config.yaml's active section (or `path`'s) with keyword overrides that are not
    None."""
    return replace(ActiveParams.from_yaml(path),
                   **{k: v for k, v in overrides.items() if v is not None})


# --------------------------------------------------------------------------- protocols

class ChordClassifier(Protocol):
    """What active recognition needs of the trained classifier (classify.ChordModel).

    An optional `predict_proba_bins(list of flat cell arrays)` is used when present.
    """

    classes_: np.ndarray
    edges_: np.ndarray          # (7, bins + 1) fitted histogram bin edges

    def predict_proba(self, X: Sequence[np.ndarray]) -> np.ndarray:
        """(n, n_classes) class probabilities of n chord sets, each (k, 7)."""


@dataclass(frozen=True)
class ObjectWraps:
    """The wraps of one object: what training tallies and held-out evaluation read.

    Args:
        name: object id.
        label: category.
        wraps: plane index -> (k, 7) chords of the usable wrap on that plane. Planes without a
            usable wrap (empty cut, no contact) are absent: for a held-out object they are
            unavailable actions.
    """

    name: str
    label: str
    wraps: Mapping[int, np.ndarray]


# --------------------------------------------------------------------------- discretisation

def _edges(edges) -> np.ndarray:
    e = np.asarray(edges, dtype=float)
    if e.ndim != 2 or e.shape[0] != N_CHORD_DIMS or e.shape[1] < 2:
        raise ValueError(f"bin edges: expected a ({N_CHORD_DIMS}, bins + 1) array, "
                         f"got shape {e.shape}")
    return e


def n_cells(edges) -> int:
    e = _edges(edges)
    return (e.shape[1] - 1) ** e.shape[0]


def bin_histograms(chord_sets: Sequence[np.ndarray], edges) -> sp.csr_matrix:
    """(n, n_cells) sparse chord counts of n chord sets (rows not normalised)."""
    e = _edges(edges)
    flat = [bin_index(np.asarray(c, float).reshape(-1, N_CHORD_DIMS), e) for c in chord_sets]
    return histogram_rows(flat, n_cells(e), normalize=False)


def _scale_rows(m: sp.csr_matrix, norm: np.ndarray) -> sp.csr_matrix:
    """Rows divided by norm (rows of norm 0 left as they are); in place of a diagonal product,
    which costs O(n_cells) in scipy."""
    m = sp.csr_matrix(m, dtype=float, copy=True)
    m.data /= np.repeat(np.where(norm > 0, norm, 1.0), np.diff(m.indptr))
    return m


def _unit_rows(m: sp.csr_matrix) -> sp.csr_matrix:
    return _scale_rows(m, np.sqrt(np.asarray(m.multiply(m).sum(axis=1)).ravel()))


def plane_cost_matrix(plane_normals: np.ndarray) -> np.ndarray:
    """(P, P) rotation angle between plane normals, rad: the movement cost of eq. 1."""
    n = np.asarray(plane_normals, dtype=float)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    return np.arccos(np.clip(n @ n.T, -1.0, 1.0))


# --------------------------------------------------------------------------- observation model

@dataclass(frozen=True, eq=False)
class ObservationModel:
    """Training observations and the tallies of p(z' | z, a, y).

    Args:
        classes: (C,) category names, in the classifier's column order.
        object_names: (O,) training object ids; object_class: (O,) class index of each.
        plane_normals: (P, 3) unit normals of the wrap planes.
        edges: (7, bins + 1) histogram bin edges (the classifier's, fitted on training data).
        obs_object, obs_plane: (n,) object and plane of each training wrap.
        obs_indptr: (n + 1,) CSR pointer into obs_cells / obs_counts.
        obs_cells: (nnz,) occupied flat histogram cells; obs_counts: (nnz,) chords in each.
        pair_from, pair_to: (m,) the tallies: every ordered pair of wraps of one object.
        neighbours: training wraps of a class matched to an observation.
    """

    classes: np.ndarray
    object_names: np.ndarray
    object_class: np.ndarray
    plane_normals: np.ndarray
    edges: np.ndarray
    obs_object: np.ndarray
    obs_plane: np.ndarray
    obs_indptr: np.ndarray
    obs_cells: np.ndarray
    obs_counts: np.ndarray
    pair_from: np.ndarray
    pair_to: np.ndarray
    neighbours: int = 5

    @property
    def n_observations(self) -> int:
        return len(self.obs_object)

    @property
    def n_planes(self) -> int:
        return len(self.plane_normals)

    @property
    def n_classes(self) -> int:
        return len(self.classes)

    @cached_property
    def obs_class(self) -> np.ndarray:
        return self.object_class[self.obs_object]

    @cached_property
    def pair_action(self) -> np.ndarray:
        """(m,) action of each tally: the target plane."""
        return self.obs_plane[self.pair_to]

    @cached_property
    def pair_cost(self) -> np.ndarray:
        """(m,) movement cost of each tally, rad."""
        return self.cost_matrix[self.obs_plane[self.pair_from], self.pair_action]

    @cached_property
    def cost_matrix(self) -> np.ndarray:
        return plane_cost_matrix(self.plane_normals)

    @cached_property
    def class_prior(self) -> np.ndarray:
        """(C,) class frequencies of the training objects: p(y | h_0) before any wrap."""
        counts = np.bincount(self.object_class, minlength=self.n_classes).astype(float)
        return counts / counts.sum()

    @cached_property
    def histograms(self) -> sp.csr_matrix:
        """(n, n_cells) unit-norm chord counts of each training wrap."""
        m = sp.csr_matrix((self.obs_counts.astype(float), self.obs_cells, self.obs_indptr),
                          shape=(self.n_observations, n_cells(self.edges)))
        return _unit_rows(m)

    @cached_property
    def successor(self) -> np.ndarray:
        """(n, P) the tallied successor of wrap i under action a (-1: none)."""
        s = np.full((self.n_observations, self.n_planes), -1, dtype=np.int64)
        s[self.pair_from, self.pair_action] = self.pair_to
        return s

    def cells(self, i: int) -> np.ndarray:
        """(k,) histogram cell of each chord of training wrap i (the multiset)."""
        lo, hi = self.obs_indptr[i], self.obs_indptr[i + 1]
        return np.repeat(self.obs_cells[lo:hi], self.obs_counts[lo:hi])

    def centres(self, i: int) -> np.ndarray:
        """(k, 7) chords of training wrap i, at their bin centres."""
        return bin_centres(self.cells(i), self.edges)

    def discretise(self, chords: np.ndarray) -> sp.csr_matrix:
        """(1, n_cells) unit-norm chord counts of a new wrap."""
        return _unit_rows(bin_histograms([chords], self.edges))

    def successors_of(self, similarity: np.ndarray, plane: int) -> tuple[np.ndarray, np.ndarray]:
        """Candidates z' of p(z'|z, a, y) for observations z on one plane.

        Args:
            similarity: (r, n) histogram similarity of r observations to every training wrap.
            plane: the plane of the r observations.
        Returns:
            succ (r, C, P, K) training wrap ids, -1 padded; count (r, C, P) valid entries.
        """
        K = self.neighbours
        on_plane = np.flatnonzero(self.obs_plane == plane)
        r = similarity.shape[0]
        succ = np.full((r, self.n_classes, self.n_planes, K), -1, dtype=np.int64)
        if len(on_plane) == 0:
            return succ, np.zeros((r, self.n_classes, self.n_planes), dtype=np.int64)
        order = np.argsort(-similarity[:, on_plane], axis=1, kind="stable")
        cand = on_plane[order]                                   # (r, n_p), best match first
        s = self.successor[cand]                                 # (r, n_p, P)
        cls = self.obs_class[cand]
        for y in range(self.n_classes):
            valid = (cls == y)[:, :, None] & (s >= 0)
            keep = valid & (np.cumsum(valid, axis=1) <= K)
            first = np.argsort(~keep, axis=1, kind="stable")[:, :K, :]      # (r, <=K, P)
            picked = np.take_along_axis(s, first, axis=1)
            ok = np.take_along_axis(keep, first, axis=1)
            succ[:, y, :, :first.shape[1]] = np.where(ok, picked, -1).transpose(0, 2, 1)
        return succ, (succ >= 0).sum(axis=3)

    @cached_property
    def training_successors(self) -> tuple[np.ndarray, np.ndarray]:
        """successors_of for every training wrap: (n, C, P, K) and (n, C, P)."""
        succ = np.full((self.n_observations, self.n_classes, self.n_planes, self.neighbours), -1,
                       dtype=np.int64)
        X = self.histograms
        for p in np.unique(self.obs_plane):
            rows = np.flatnonzero(self.obs_plane == p)
            sim = (X[rows] @ X.T).toarray()
            succ[rows] = self.successors_of(sim, int(p))[0]
        return succ, (succ >= 0).sum(axis=3)

    @cached_property
    def initial_successors(self) -> tuple[np.ndarray, np.ndarray]:
        """p(z'|a, y) before any wrap: every training wrap of class y on plane a."""
        groups = [[np.flatnonzero((self.obs_class == y) & (self.obs_plane == a))
                   for a in range(self.n_planes)] for y in range(self.n_classes)]
        K = max(1, max(len(g) for row in groups for g in row))
        succ = np.full((self.n_classes, self.n_planes, K), -1, dtype=np.int64)
        for y, row in enumerate(groups):
            for a, g in enumerate(row):
                succ[y, a, :len(g)] = g
        return succ, (succ >= 0).sum(axis=2)


def fit_observation_model(objects: Sequence[ObjectWraps], classes: Sequence[str], edges,
                          plane_normals: np.ndarray, neighbours: int = 5) -> ObservationModel:
    """Tally the training wraps (IV-D.2): discretise every wrap, pair the wraps of each object.

    Args:
        objects: training objects with their usable wraps.
        classes: category names in the classifier's column order (`classifier.classes_`).
        edges: the classifier's fitted bin edges, (7, bins + 1).
        plane_normals: (P, 3) wrap-plane normals (planes.py).
        neighbours: see ObservationModel.
    """
    edges = _edges(edges)
    classes = np.asarray([str(c) for c in classes])
    index = {c: k for k, c in enumerate(classes)}
    missing = sorted({o.label for o in objects} - set(index))
    if missing:
        raise InputError(f"observation model: labels {missing} are not classifier classes")
    P = len(plane_normals)
    obs_object, obs_plane, cells, counts, indptr = [], [], [], [], [0]
    pair_from, pair_to = [], []
    for k, obj in enumerate(objects):
        ids = []
        for plane in sorted(obj.wraps):
            if not 0 <= plane < P:
                raise InputError(f"observation model: object {obj.name} has plane {plane}, "
                                 f"outside 0..{P - 1}")
            chords = np.asarray(obj.wraps[plane], dtype=float).reshape(-1, N_CHORD_DIMS)
            if len(chords) == 0:
                continue
            c, n = np.unique(bin_index(chords, edges), return_counts=True)
            ids.append(len(obs_object))
            obs_object.append(k)
            obs_plane.append(plane)
            cells.append(c)
            counts.append(n)
            indptr.append(indptr[-1] + len(c))
        ids = np.asarray(ids, dtype=np.int64)
        a, b = np.meshgrid(ids, ids, indexing="ij")
        off = a != b
        pair_from.append(a[off])
        pair_to.append(b[off])
    def cat(xs, dt):
        return np.concatenate(xs).astype(dt) if xs else np.zeros(0, dt)
    return ObservationModel(
        classes=classes,
        object_names=np.asarray([o.name for o in objects]),
        object_class=np.asarray([index[o.label] for o in objects], dtype=np.int64),
        plane_normals=np.asarray(plane_normals, dtype=float),
        edges=edges,
        obs_object=np.asarray(obs_object, dtype=np.int64),
        obs_plane=np.asarray(obs_plane, dtype=np.int64),
        obs_indptr=np.asarray(indptr, dtype=np.int64),
        obs_cells=cat(cells, np.int64), obs_counts=cat(counts, np.int64),
        pair_from=cat(pair_from, np.int64), pair_to=cat(pair_to, np.int64),
        neighbours=int(neighbours))


def save_observation_model(model: ObservationModel, directory) -> tuple[Path, Path]:
    """Write observations.npz (arrays) and observations.json (metadata) into `directory`."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    arrays = {k: getattr(model, k) for k in (
        "object_class", "plane_normals", "obs_object", "obs_plane", "obs_indptr", "obs_cells",
        "obs_counts", "pair_from", "pair_to")}
    arrays["edges"] = model.edges
    arrays["pair_action"] = model.pair_action
    arrays["pair_cost"] = model.pair_cost
    meta = {"kind": _KIND, "format_version": FORMAT_VERSION,
            "classes": [str(c) for c in model.classes],
            "object_names": [str(n) for n in model.object_names],
            "neighbours": model.neighbours, "n_observations": model.n_observations,
            "n_planes": model.n_planes, "n_pairs": int(len(model.pair_from)),
            "arrays": sorted(arrays)}
    meta["array_shapes"] = array_shapes(arrays)
    meta["sha256"] = model_digest(arrays, meta)
    npz, js = directory / "observations.npz", directory / "observations.json"
    write_atomic(npz, lambda f: np.savez_compressed(f, **arrays))
    write_json(js, meta)
    return npz, js


def load_observation_model(directory) -> ObservationModel:
    """Read what save_observation_model wrote; no pickle is ever loaded. A missing, damaged
    or old model raises classify.ModelFormatError naming the file."""
    import zipfile

    from ..learning.model import ModelFormatError, check_saved_arrays

    directory = Path(directory)
    js, npz = directory / "observations.json", directory / "observations.npz"
    retrain = "retrain with `drake-continuum train-active`"
    try:
        meta = json.loads(js.read_text())
    except FileNotFoundError:
        raise MissingFileError(f"observation model {js}: file not found") from None
    except (OSError, ValueError) as e:
        raise ModelFormatError(f"damaged model {js} (not valid JSON: {e}); {retrain}") from None
    if not isinstance(meta, dict) or meta.get("kind") != _KIND:
        raise ModelFormatError(f"observation model {js}: not an observation model")
    if meta.get("format_version") != FORMAT_VERSION:
        raise ModelFormatError(f"observation model {js}: format version "
                               f"{meta.get('format_version')} cannot be read by this "
                               f"drake-continuum, which reads {FORMAT_VERSION}; {retrain}")
    try:
        with np.load(npz, allow_pickle=False) as z:
            a = {k: np.array(z[k]) for k in z.files}
    except FileNotFoundError:
        raise MissingFileError(f"observation model {npz}: file not found") from None
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
        raise ModelFormatError(f"damaged model {npz} ({type(e).__name__}: {e}); "
                               f"{retrain}") from None
    check_saved_arrays(f"observation model {npz}", meta, a, retrain)
    missing = sorted(set(meta["arrays"]) - set(a))
    if missing:
        raise ModelFormatError(f"damaged model {npz} (missing arrays {missing}); {retrain}")
    model = ObservationModel(
        classes=np.asarray(meta["classes"]), object_names=np.asarray(meta["object_names"]),
        object_class=a["object_class"], plane_normals=a["plane_normals"],
        edges=_edges(a["edges"]),
        obs_object=a["obs_object"], obs_plane=a["obs_plane"], obs_indptr=a["obs_indptr"],
        obs_cells=a["obs_cells"], obs_counts=a["obs_counts"], pair_from=a["pair_from"],
        pair_to=a["pair_to"], neighbours=int(meta["neighbours"]))
    if model.obs_indptr[-1] != len(model.obs_cells) or len(model.obs_indptr) != \
            model.n_observations + 1:
        raise ModelFormatError(f"damaged model {npz} (inconsistent observation arrays); "
                               f"{retrain}")
    return model


@dataclass(frozen=True, eq=False)
class ActiveModel:
    """What recognition needs: the trained classifier and the observation model."""

    classifier: ChordClassifier
    observations: ObservationModel

    def __post_init__(self):
        ours = [str(c) for c in self.observations.classes]
        if [str(c) for c in self.classifier.classes_] != ours:
            raise InputError("ActiveModel: classifier classes differ from the observation "
                             f"model's ({list(self.classifier.classes_)} vs {ours})")


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
    directly; any other gets chords at bin centres, which fall in the same cells.
    """

    def __init__(self, model: "ActiveModel"):
        self.model = model
        self.obs = model.observations
        self.by_cells = hasattr(model.classifier, "predict_proba_bins")
        self.history: list[np.ndarray] = []
        self._parts: dict[int, np.ndarray] = {}
        self._cache: dict[tuple, np.ndarray] = {}
        self.calls = 0

    def set_history(self, chords: Sequence[np.ndarray]) -> None:
        chords = [np.asarray(c, dtype=float).reshape(-1, N_CHORD_DIMS) for c in chords]
        self.history = ([bin_index(c, self.obs.edges) for c in chords] if self.by_cells
                        else chords)
        self._cache.clear()

    def _part(self, i: int) -> np.ndarray:
        p = self._parts.get(i)
        if p is None:
            p = self._parts[i] = self.obs.cells(i) if self.by_cells else self.obs.centres(i)
        return p

    def _input(self, ids: Sequence[int]) -> np.ndarray:
        parts = self.history + [self._part(i) for i in ids]
        if parts:
            return np.concatenate(parts)
        return np.zeros(0, np.int64) if self.by_cells else np.zeros((0, N_CHORD_DIMS))

    def _predict(self, inputs: list) -> np.ndarray:
        self.calls += 1
        clf = self.model.classifier
        return np.asarray(clf.predict_proba_bins(inputs) if self.by_cells
                          else clf.predict_proba(inputs))

    def __call__(self, ids: tuple) -> np.ndarray:
        p = self._cache.get(ids)
        if p is None:
            p = (self.obs.class_prior if not self.history and not ids
                 else self._predict([self._input(ids)])[0])
            self._cache[ids] = p
        return p

    def batch(self, id_sets: Sequence[tuple]) -> np.ndarray:
        """(len(id_sets), C), one classifier call for all sets not yet cached."""
        todo = [s for s in dict.fromkeys(id_sets) if s not in self._cache]
        if todo:
            self._cache.update(zip(todo, self._predict([self._input(s) for s in todo])))
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
        sim = (self.obs.discretise(chords) @ self.obs.histograms.T).toarray()
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

    def __init__(self, obs, plane: int, depth: int, ids: tuple, visited: dict, feasible):
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
                 available: Sequence[int] | None = None, rng: np.random.Generator | None = None):
        self.model = model
        self.params = params
        self.obs = model.observations
        P = self.obs.n_planes
        self.available = np.ones(P, bool) if available is None else np.isin(np.arange(P),
                                                                           list(available))
        self.rng = rng if rng is not None else np.random.default_rng(params.seed)
        self.cost = self.obs.cost_matrix / np.pi            # normalised to [0, 1]
        self.posterior = _Posterior(model)
        self.observations = _Observations(self.obs)
        self.obs.training_successors                        # built once a model, not timed
        self.history: list[tuple[int, int]] = []            # (plane, observation id)
        self.history_chords: list[np.ndarray] = []
        self.current_plane = int(params.start_plane)
        self.root: _Node | None = None                      # the last search's tree

    # -- the object's real wraps
    def add_wrap(self, plane: int, chords: np.ndarray) -> None:
        """Record a real wrap: it becomes the root observation and part of h."""
        z = self.observations.add_real(plane, chords)
        self.history.append((plane, z))
        self.history_chords.append(np.asarray(chords, dtype=float).reshape(-1, N_CHORD_DIMS))
        self.current_plane = plane

    def mark_unavailable(self, plane: int) -> None:
        self.available[plane] = False

    def proba(self) -> np.ndarray:
        """p(y | h) of the real wraps so far."""
        self.posterior.set_history(self.history_chords)
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
        return _Node(z, self.current_plane, 0, (), visited, self._feasible(z, visited))

    def _step(self, z, visited: dict, ids: tuple, a: int, p_y: np.ndarray):
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
                z, ids, visited, y = self._step(node.obs, node.visited, node.ids, a,
                                                self.posterior(node.ids))
                child = node.children[a] = _Node(z, a, node.depth + 1, ids, visited,
                                                 self._feasible(z, visited))
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
        self.posterior.set_history(self.history_chords)
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
        self.posterior.set_history(self.history_chords)
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


# --------------------------------------------------------------------------- policies and loop

POLICIES = ("mcts", "greedy", "random")


def _next_planes(policy: str, search: TreeSearch, rng: np.random.Generator) -> list:
    """One decision of a policy: a plan (mcts) or a single plane (baselines)."""
    done = {p for p, _ in search.history}
    free = [int(a) for a in np.flatnonzero(search.available) if a not in done]
    if not free:
        return []
    if policy == "mcts":
        return search.search().plan
    if policy == "greedy":
        gain = search.expected_information_gain()
        if np.all(np.isnan(gain)):
            return [int(rng.choice(free))]
        return [int(np.nanargmax(gain))]
    if policy == "random":
        return [int(rng.choice(free))]
    raise InputError(f"unknown policy {policy!r}; one of {POLICIES}")


@dataclass
class Trajectory:
    """A recognition run: every wrap and every decision point.

    Attributes:
        planes: planes wrapped, in order.
        proba: (len(planes) + 1, C) p(y|h) before any wrap and after each wrap.
        cost: (len(planes) + 1,) cumulative movement, rad.
        checks: number of wraps at the end of each decision (iteration).
        stop: index into checks where the stop rule first held (None: never).
        stopped_because: "strong_prediction", "max_iterations" or "no_planes_left".
        search_times: seconds of each tree search (mcts only).
    """

    planes: list = field(default_factory=list)
    proba: list = field(default_factory=list)
    cost: list = field(default_factory=list)
    checks: list = field(default_factory=list)
    stop: int | None = None
    stopped_because: str = "max_iterations"
    search_times: list = field(default_factory=list)


def run_policy(model: ActiveModel, execute: Callable[[int], np.ndarray | None],
               policy: str = "mcts", *, params: ActiveParams = ActiveParams(),
               available: Sequence[int] | None = None, seed: int | None = None,
               max_decisions: int | None = None, stop_early: bool = True) -> Trajectory:
    """Recognise one object: decide, wrap, accumulate, classify, until the stop rule.

    Args:
        execute: plane -> (k, 7) chords of the wrap there; None or empty for no usable wrap
            (the plane then becomes unavailable; no wrap and no movement are counted).
        policy: "mcts" (a plan of up to T planes per decision), "greedy" (one-step expected
            information gain, movement cost ignored) or "random" (a random unused plane).
        available: planes that may be wrapped (default all).
        max_decisions: decisions before stopping; default max_iterations for mcts and
            max_iterations * horizon (the same most wraps) for the one-plane baselines.
        stop_early: stop at the first strong prediction; False runs every decision (Table II).
    """
    seed = params.seed if seed is None else seed
    rng = np.random.default_rng(seed)
    search = TreeSearch(model, params, available=available, rng=rng)
    if max_decisions is None:
        max_decisions = params.max_iterations * (1 if policy == "mcts" else params.horizon)
    cost = model.observations.cost_matrix
    tr = Trajectory(proba=[search.proba()], cost=[0.0])
    for _ in range(max_decisions):
        t0 = time.perf_counter()
        plan = _next_planes(policy, search, rng)
        if policy == "mcts":
            tr.search_times.append(time.perf_counter() - t0)
        done = {p for p, _ in search.history}
        if not plan and not (set(np.flatnonzero(search.available)) - done):
            tr.stopped_because = "no_planes_left"
            break
        for a in plan:
            chords = execute(a)
            if chords is None or len(chords) == 0:
                search.mark_unavailable(a)
                continue
            tr.cost.append(tr.cost[-1] + float(cost[search.current_plane, a]))
            search.add_wrap(a, chords)
            tr.planes.append(a)
            tr.proba.append(search.proba())
        tr.checks.append(len(tr.planes))
        if tr.stop is None and strong_prediction(tr.proba[-1], params):
            tr.stop = len(tr.checks) - 1
            if stop_early:
                tr.stopped_because = "strong_prediction"
                break
    tr.proba = [np.asarray(p) for p in tr.proba]
    return tr


def _top(proba: np.ndarray, classes: np.ndarray, k: int = 3) -> list:
    order = np.argsort(-proba, kind="stable")[:k]
    return [[str(classes[i]), round(float(proba[i]), 4)] for i in order]


@dataclass(frozen=True)
class RecognitionStep:
    """One tree search of a recognition and the wraps it chose.

    Args:
        planes: plane indices wrapped, in order.
        top3: [[category, probability], ...] after these wraps, most likely first.
        n_wraps: wraps made in this iteration.
        movement_cost: base movement of this iteration, rad.
        search_time_s: the tree search's time, s (None if no search ran).
    """

    planes: list
    top3: list
    n_wraps: int
    movement_cost: float
    search_time_s: float | None


@dataclass(frozen=True)
class Recognition:
    """What active recognition of one object found (section V-C).

    Args:
        category: the most probable category at the end.
        stopped_because: "strong_prediction", "max_iterations" or "no_planes_left".
        iterations: one RecognitionStep a tree search.
        n_wraps: wraps made in all.
        movement_cost: base movement in all, rad.
    """

    category: str
    stopped_because: str
    iterations: list
    n_wraps: int
    movement_cost: float

    def to_dict(self) -> dict:
        return asdict(self)


def recognize(model: ActiveModel, execute: Callable[[int], np.ndarray | None], *,
              params: ActiveParams | None = None, available: Sequence[int] | None = None,
              seed: int | None = None, stop_early: bool = True) -> Recognition:
    """Active recognition of one object by tree search (section V-C); costs in rad."""
    params = ActiveParams.from_yaml() if params is None else params
    tr = run_policy(model, execute, "mcts", params=params, available=available, seed=seed,
                    stop_early=stop_early)
    classes = model.observations.classes
    iterations, start = [], 0
    for k, end in enumerate(tr.checks):
        iterations.append(RecognitionStep(
            planes=[int(p) for p in tr.planes[start:end]],
            top3=_top(tr.proba[end], classes),
            n_wraps=end - start,
            movement_cost=round(tr.cost[end] - tr.cost[start], 6),
            search_time_s=round(tr.search_times[k], 4) if k < len(tr.search_times) else None))
        start = end
    return Recognition(category=str(classes[int(np.argmax(tr.proba[-1]))]),
                       stopped_because=tr.stopped_because, iterations=iterations,
                       n_wraps=len(tr.planes), movement_cost=round(tr.cost[-1], 6))


def simulated_execute(scene, planes, chord_params, wrap_params=None, log=None
                      ) -> Callable[[int], np.ndarray | None]:
    """Execute a plane by wrapping the scene's object there in simulation; its chords, or None
    when the wrap is unusable (empty cut, no contact). `log` collects every WrapResult."""
    from ..features.chords import wrap_chords
    from ..wrapping.wrap import WrapParams, wrap

    def execute(plane_index: int):
        result = wrap(scene, planes[plane_index], wrap_params or WrapParams())
        if log is not None:
            log.append(result)
        return wrap_chords(result, chord_params) if result.usable else None
    return execute


def precomputed_execute(obj: ObjectWraps) -> Callable[[int], np.ndarray | None]:
    """execute() over an object's precomputed wraps: the wrap on that plane, or None."""
    return lambda plane: obj.wraps.get(int(plane))


def build_active_model(classifier: ChordClassifier, train_objects: Sequence[ObjectWraps],
                       plane_normals: np.ndarray, params: ActiveParams = ActiveParams()
                       ) -> ActiveModel:
    """Tally the training objects' wraps with the classifier's bin edges (`edges_`)."""
    obs = fit_observation_model(train_objects, classifier.classes_, classifier.edges_,
                                plane_normals, params.neighbours)
    return ActiveModel(classifier, obs)


def evaluate_policies(model: ActiveModel, test_objects: Sequence[ObjectWraps], *,
                      policies: Sequence[str] = POLICIES, params: ActiveParams = ActiveParams(),
                      seed: int = 0, progress: Callable | None = None,
                      show_progress: bool = True) -> dict:
    """Run each policy on every held-out object (execute = its precomputed wraps), with a
    progress bar a policy unless show_progress is False.

    Returns per policy: accuracy, mean wraps and mean movement cost (rad) at the stop, the
    fraction stopped by the strong rule, and curves: accuracy after n wraps (the last
    prediction when a run ended earlier) and accuracy within a movement budget.
    """
    from tqdm import tqdm

    classes = model.observations.classes
    budget = params.max_iterations * params.horizon
    out = {}
    for policy in policies:
        runs = []
        for k, obj in enumerate(tqdm(test_objects, desc=policy, unit="obj", leave=False,
                                     disable=not show_progress)):
            tr = run_policy(model, precomputed_execute(obj), policy, params=params,
                            available=sorted(obj.wraps), seed=seed + k, stop_early=False)
            truth = obj.label
            correct = np.array([classes[int(np.argmax(p))] == truth for p in tr.proba])
            s = tr.stop if tr.stop is not None else len(tr.checks) - 1
            n_stop = tr.checks[s] if tr.checks else 0
            runs.append({"object": obj.name, "label": truth, "planes": tr.planes,
                         "correct": correct, "cost": np.asarray(tr.cost), "n_stop": n_stop,
                         "strong": tr.stop is not None, "search_times": tr.search_times})
            if progress:
                progress(policy, k)
        n_axis = np.arange(budget + 1)
        acc_n = np.mean([[r["correct"][min(n, len(r["correct"]) - 1)] for n in n_axis]
                         for r in runs], axis=0)
        c_axis = np.linspace(0.0, max([r["cost"][-1] for r in runs] + [1e-9]), 50)
        acc_c = np.mean([[r["correct"][np.searchsorted(r["cost"], c, side="right") - 1]
                          for c in c_axis] for r in runs], axis=0)
        times = [t for r in runs for t in r["search_times"]]
        out[policy] = {
            "n_objects": len(runs),
            "accuracy_at_stop": float(np.mean([r["correct"][r["n_stop"]] for r in runs])),
            "wraps_to_stop": float(np.mean([r["n_stop"] for r in runs])),
            "movement_cost_to_stop_rad": float(np.mean([r["cost"][r["n_stop"]] for r in runs])),
            "strong_fraction": float(np.mean([r["strong"] for r in runs])),
            "accuracy_vs_wraps": {"wraps": n_axis.tolist(), "accuracy": acc_n.tolist()},
            "accuracy_vs_cost": {"cost_rad": c_axis.tolist(), "accuracy": acc_c.tolist()},
            "median_search_time_s": float(np.median(times)) if times else None,
            "runs": [{"object": r["object"], "label": r["label"], "planes": r["planes"],
                      "n_stop": r["n_stop"], "correct_at_stop": bool(r["correct"][r["n_stop"]])}
                     for r in runs]}
    return out


def plot_policy_curves(results: Mapping[str, dict], path) -> Path:
    """Accuracy vs wraps and vs movement cost, one line a policy, as PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    for policy, r in results.items():
        ax1.plot(r["accuracy_vs_wraps"]["wraps"], r["accuracy_vs_wraps"]["accuracy"],
                 marker="o", ms=3, label=policy)
        ax2.step(np.degrees(r["accuracy_vs_cost"]["cost_rad"]), r["accuracy_vs_cost"]["accuracy"],
                 where="post", label=policy)
    ax1.set(xlabel="wraps", ylabel="accuracy", title="accuracy vs wraps", ylim=(0, 1.02))
    ax2.set(xlabel="movement cost (deg of plane rotation)", ylabel="accuracy",
            title="accuracy vs movement cost", ylim=(0, 1.02))
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
        ax.legend()
    fig.tight_layout()
    write_atomic(path, lambda f: fig.savefig(f, format="png", dpi=120))
    plt.close(fig)
    return path


# --------------------------------------------------------------------------- wrap collections

def object_wraps_from_records(records) -> list[ObjectWraps]:
    """classify.ObjectRecord (load_wraps) -> ObjectWraps: each usable wrap's chords by plane
    (the first wrap of a plane if a collection wrapped one twice)."""
    out = []
    for r in records:
        wraps = {}
        for k, plane in enumerate(np.asarray(r.plane_index)):
            chords = r.chords.values[r.chords.wrap == k]
            if r.usable[k] and len(chords) and int(plane) not in wraps:
                wraps[int(plane)] = chords
        out.append(ObjectWraps(str(r.object_id), str(r.category), wraps))
    return out


def collection_plane_normals(folder, records) -> np.ndarray:
    """(P, 3) normal of every plane index used in a wrap collection, read from its wraps."""
    from ..learning.records import read_object_wraps

    needed = {int(p) for r in records for p in np.asarray(r.plane_index) if p >= 0}
    normals: dict[int, np.ndarray] = {}
    for r in records:
        if needed <= set(normals):
            break
        for w in read_object_wraps(folder, r.object_id)[1]:
            if w.plane_index >= 0:
                normals.setdefault(int(w.plane_index), np.asarray(w.plane_normal, float))
    P = max(needed) + 1 if needed else 0
    missing = sorted(set(range(P)) - set(normals))
    if missing:
        raise InputError(f"{folder}: no wrap records the normal of planes {missing}")
    return np.array([normals[p] for p in range(P)]).reshape(-1, 3)


def save_active_model(model: ActiveModel, folder) -> None:
    """The classifier (classify.save_model: model.json/.npz) and the observation model
    (observations.json/.npz) in one folder; no pickle."""
    from ..learning.model import save_model

    save_model(model.classifier, folder)
    save_observation_model(model.observations, folder)


def load_active_model(folder) -> ActiveModel:
    """What save_active_model wrote."""
    from ..learning.model import load_model

    return ActiveModel(load_model(folder), load_observation_model(folder))


def train_active(folder, *, params: ActiveParams = ActiveParams(), seed: int = 0,
                 frame: str = "world", records=None, train_index=None,
                 classifier=None, chords=None) -> ActiveModel:
    """Train the classifier and tally the observations on a wrap collection (or on the
    objects `train_index` of its records).

    The classifier (`classifier` ClassifierParams, default classify's) is trained on the
    fine chord histogram (of `chords`, default ChordParams(frame=frame)) alone, without the
    coarse histogram and the wrap descriptors that help the all-wraps classifier:
    recognition sees the chords of one to a few wraps, and there both blocks cost accuracy
    at stop (BENCHMARKS.md, "Active recognition's classifier")."""
    from dataclasses import replace

    from ..features.chords import ChordParams
    from ..learning.model import train
    from ..learning.pipeline import ClassifierParams
    from ..learning.records import load_wraps

    chords = ChordParams(frame=frame) if chords is None else chords  # `frame` is its shortcut
    records = load_wraps(folder, chords) if records is None else records
    normals = collection_plane_normals(folder, records)
    if train_index is not None:
        records = [records[i] for i in train_index]
    chords_only = replace(classifier or ClassifierParams(), coarse=0, wrap_weight=0.0,
                          extent_weight=0.0)
    clf = train(records, seed=seed, params=chords, classifier=chords_only)
    return build_active_model(clf, object_wraps_from_records(records), normals, params)


def evaluate_active(folder, *, policies: Sequence[str] = POLICIES,
                    params: ActiveParams = ActiveParams(), seed: int = 0, frame: str = "world",
                    out=None, chords=None, classifier=None, placed=(),
                    train_kinds=("generated",), test_kinds=("turned", "rest", "nudged")) -> dict:
    """Train on one half of a stratified split of a wrap collection, run each policy on the
    held-out half; with `out`, write active.json, curves.png and table2.md there. `chords`
    and `classifier` as train_active's. Objects of the collection left out
    (classify.load_collection) are listed under "skipped".

    With `placed` (wrap collections of placed copies, objects/placement.py) the split is by
    object over originals and copies together; training takes the training half's records
    of `train_kinds` and the held-out half is tested on its copies of `test_kinds` (each
    policy's "by_kind" has the accuracy at stop of each)."""
    from ..features.chords import ChordParams
    from ..learning.evaluation import object_groups, splits
    from ..learning.records import load_collection
    from ..objects.placement import placement_kind

    chords = ChordParams(frame=frame) if chords is None else chords
    records, skipped = load_collection(folder, chords)
    for extra in placed:
        more, also = load_collection(extra, chords)
        records += more
        skipped += also
    train_idx, test_idx = splits([r.category for r in records], n_splits=1, seed=seed,
                                 groups=object_groups(records))[0]
    if placed:
        kinds = [placement_kind(r.object_id) for r in records]
        train_idx = np.array([i for i in train_idx if kinds[i] in train_kinds], np.int64)
        test_idx = np.array([i for i in test_idx if kinds[i] in test_kinds], np.int64)
    t0 = time.perf_counter()
    model = train_active(folder, params=params, seed=seed, records=records,
                         train_index=train_idx, chords=chords, classifier=classifier)
    test = [object_wraps_from_records([records[i]])[0] for i in test_idx]
    results = evaluate_policies(model, test, policies=policies, params=params, seed=seed)
    if placed:
        for r in results.values():
            by = {}
            for run in r["runs"]:
                by.setdefault(placement_kind(run["object"]), []).append(run["correct_at_stop"])
            r["by_kind"] = {k: float(np.mean(v)) for k, v in sorted(by.items())}
    rows = table_ii(model, test, params=params, seed=seed)
    report = {"wraps": str(folder), "seed": seed, "n_train": len(train_idx),
              "n_test": len(test_idx), "params": {f.name: getattr(params, f.name)
                                                   for f in fields(params)},
              "policies": results, "table2": rows, "time_s": time.perf_counter() - t0,
              "skipped": skipped}
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        plot_policy_curves(results, out / "curves.png")
        write_atomic(out / "table2.md", table_ii_markdown(rows).encode())
        write_json(out / "active.json", report)
    return report


# --------------------------------------------------------------------------- Table II

PAPER_TABLE_II = {
    # object: per iteration (top-3 [(category, p)], wraps); paper Table II, horizon 5.
    "bottle": [([("bottle", .39), ("mug", .19), ("banana", .08)], 3),
               ([("bottle", .42), ("mug", .14), ("banana", .10)], 1),
               ([("bottle", .70), ("mug", .05), ("teapot", .04)], 2)],
    "hammer": [([("hammer", .77), ("bottle", .04), ("cup", .03)], 2),
               ([("hammer", .81), ("bottle", .03), ("banana", .03)], 2),
               ([("hammer", .83), ("banana", .03), ("bottle", .02)], 1)],
    "cup": [([("cup", .51), ("mug", .09), ("bowl", .08)], 3),
            ([("cup", .56), ("mug", .11), ("bowl", .06)], 2),
            ([("cup", .57), ("mug", .12), ("bowl", .06)], 3)],
    "bowl": [([("bowl", .52), ("apple", .12), ("toilet paper", .12)], 5),
             ([("bowl", .65), ("toilet paper", .09), ("apple", .07)], 1),
             ([("bowl", .75), ("toilet paper", .05), ("apple", .04)], 2)],
    "mug": [([("mug", .46), ("apple", .14), ("cup", .12)], 3),
            ([("mug", .69), ("cup", .08), ("teapot", .07)], 2),
            ([("mug", .69), ("cup", .08), ("teapot", .07)], 0)],
}


def table_ii(model: ActiveModel, test_objects: Sequence[ObjectWraps], *,
             categories: Sequence[str] = tuple(PAPER_TABLE_II), params: ActiveParams | None = None,
             seed: int = 0) -> dict:
    """Table II: one held-out object a category, all iterations run (no early stop).

    The object of each category is the first held-out one by name; categories without one
    are skipped.
    """
    params = ActiveParams.from_yaml() if params is None else params
    rows = {}
    for c in categories:
        objs = sorted((o for o in test_objects if o.label == c), key=lambda o: o.name)
        if objs:
            rows[c] = {"object": objs[0].name, **recognize(
                model, precomputed_execute(objs[0]), params=params,
                available=sorted(objs[0].wraps), seed=seed, stop_early=False).to_dict()}
    return rows


def table_ii_markdown(rows: Mapping[str, dict]) -> str:
    """Our Table II next to the paper's, one row a category and iteration."""
    def fmt(top):
        return "<br>".join(f"{c} {p:.2f}" for c, p in top)

    lines = ["| object | iteration | ours: top-3 | ours: # wraps | paper: top-3 | paper: # wraps |",
             "|---|---|---|---|---|---|"]
    for c, r in rows.items():
        paper = PAPER_TABLE_II.get(c, [])
        for k, it in enumerate(r["iterations"]):
            p_top, p_n = paper[k] if k < len(paper) else ([], "")
            lines.append(f"| {c} ({r['object']}) | {k + 1} | {fmt(it['top3'])} | {it['n_wraps']} "
                         f"| {fmt(p_top)} | {p_n} |")
    if not rows:
        lines.append("\nNo held-out object of the paper's categories "
                     f"({', '.join(PAPER_TABLE_II)}).")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- synthetic problem

def paper_plane_normals(alpha_deg: float | None = None) -> np.ndarray:
    """(P, 3) normals of planes.enumerate_planes (default: the paper's 10 planes)."""
    from ..wrapping.planes import PAPER_ALPHA_DEG, enumerate_planes

    planes = enumerate_planes(np.zeros(3), PAPER_ALPHA_DEG if alpha_deg is None else alpha_deg)
    return np.array([p.normal for p in planes])


def synthetic_planes() -> np.ndarray:
    """(5, 3) normals: tabletop (0), 22.5 deg about x (1), 45 deg about x (2), 90 deg about x
    (3), 90 deg about y (4)."""
    n = paper_plane_normals()
    return n[[0, 1, 2, 4, 9]]


SYNTHETIC_SIGNAL = {1: 0.3, 4: 0.8}   # plane -> fraction of chords carrying the class
SYNTHETIC_BINS = 7


def synthetic_objects(n_per_class: int = 8, classes: Sequence[str] = ("a", "b", "c"),
                      n_chords: int = 40, seed: int = 0,
                      signal: Mapping[int, float] = SYNTHETIC_SIGNAL,
                      n_planes: int = 5) -> list[ObjectWraps]:
    """A problem with a known answer, for tests and the benchmark.

    Chords fall in histogram cells drawn from a pool shared by all classes, except on the planes
    in `signal`, where that fraction of chords falls in cells of the object's class. With
    synthetic_planes(), plane 1 is cheap (22.5 deg from the start) and weakly informative,
    plane 4 is costly (90 deg) and strongly informative, the others carry nothing.
    """
    rng = np.random.default_rng(seed)
    pool = np.random.default_rng(12345).integers(0, SYNTHETIC_BINS,
                                                 (20 + 4 * len(classes), N_CHORD_DIMS))
    shared, own = pool[:20], pool[20:].reshape(len(classes), 4, N_CHORD_DIMS)
    out = []
    for k, c in enumerate(classes):
        for j in range(n_per_class):
            wraps = {}
            for plane in range(n_planes):
                cells = shared[rng.integers(0, len(shared), n_chords)]
                m = rng.random(n_chords) < signal.get(plane, 0.0)
                cells[m] = own[k][rng.integers(0, 4, m.sum())]
                wraps[plane] = (cells + rng.random(cells.shape)) / SYNTHETIC_BINS
            out.append(ObjectWraps(f"{c}{j:02d}", c, wraps))
    return out


def train_synthetic_classifier(objects: Sequence[ObjectWraps]) -> ChordClassifier:
    """A stand-in for classify.py without its fast path: ChordHistogram + logistic regression
    on each object's pooled chords (a scikit-learn Pipeline with `classes_`, `edges_`)."""
    from sklearn.feature_selection import VarianceThreshold
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import Pipeline

    from ..features.chords import ChordHistogram

    pipe = Pipeline([("histogram", ChordHistogram(bins=SYNTHETIC_BINS)),
                     ("occupied", VarianceThreshold()),    # 823,543 cells -> the used ones
                     ("logistic", LogisticRegression(C=20.0, max_iter=2000))])
    pipe.fit([np.concatenate(list(o.wraps.values())) for o in objects],
             [o.label for o in objects])
    pipe.edges_ = pipe["histogram"].edges_
    return pipe


to_jsonable = jsonable  # numbers and arrays as plain JSON values (files.jsonable)


__all__ = [
    "ActiveParams", "load_params", "ChordClassifier", "ObjectWraps", "ObservationModel",
    "fit_observation_model", "save_observation_model", "load_observation_model", "ActiveModel",
    "TreeSearch", "SearchResult", "strong_prediction", "run_policy", "recognize", "Trajectory",
    "Recognition", "RecognitionStep", "simulated_execute",
    "evaluate_policies", "plot_policy_curves", "table_ii", "table_ii_markdown", "PAPER_TABLE_II",
    "build_active_model", "precomputed_execute",
    "bin_histograms", "plane_cost_matrix", "synthetic_planes", "paper_plane_normals",
    "synthetic_objects", "train_synthetic_classifier", "POLICIES", "to_jsonable",
    "object_wraps_from_records", "collection_plane_normals", "save_active_model",
    "load_active_model", "train_active", "evaluate_active",
]
