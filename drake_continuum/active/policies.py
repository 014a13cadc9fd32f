"""Choosing wraps one after another: the policies (tree search, greedy, random), the
recognition loop and its result, and the comparison of the policies.
"""

from __future__ import annotations

import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from contextlib import nullcontext
from dataclasses import asdict, dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import Callable, Iterator, Mapping, Sequence

import numpy as np

from ..config import Config
from ..errors import InputError
from ..files import write_atomic
from ..workers import main_not_rerun, sigint_held, stop_workers, worker_setup
from .observation import ActiveModel, fit_observation_model
from .params import ActiveParams, ChordClassifier, ObjectWraps
from .search import TreeSearch, strong_prediction

__all__ = ["run_policy", "recognize", "Trajectory", "Recognition", "RecognitionStep",
           "simulated_execute", "evaluate_policies", "plot_policy_curves", "build_active_model",
           "precomputed_execute", "run_policies", "recognition", "POLICIES"]


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
        proba: (len(planes) + 1, C) p(y|h) before any wrap and after each wrap, under the
            model's class prior (ActiveModel.reweighted): what the stop rule reads. The tree
            search plans on the classifier's own probabilities.
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
               max_decisions: int | None = None, stop_early: bool = True,
               view=None) -> Trajectory:
    """Recognise one object: decide, wrap, accumulate, classify, until the stop rule.

    Args:
        execute: plane -> (k, 7) chords of the wrap there, or a pair (chords, (m, 3) contact
            centres) for a classifier that learnt the contact extent; None or empty chords
            for no usable wrap (the plane then becomes unavailable; no wrap and no movement
            are counted).
        policy: "mcts" (a plan of up to T planes per decision), "greedy" (one-step expected
            information gain, movement cost ignored) or "random" (a random unused plane).
        available: planes that may be wrapped (default all).
        max_decisions: decisions before stopping; default max_iterations for mcts and
            max_iterations * horizon (the same most wraps) for the one-plane baselines.
        stop_early: stop at the first strong prediction; False runs every decision (Table II).
        view: the depth camera's view of the object (perception.locate.view_extent), for a
            classifier that uses it (the first decision is then made on it).
    """
    seed = params.seed if seed is None else seed
    rng = np.random.default_rng(seed)
    search = TreeSearch(model, params, available=available, rng=rng, view=view)
    if max_decisions is None:
        max_decisions = params.max_iterations * (1 if policy == "mcts" else params.horizon)
    cost = model.observations.cost_matrix
    tr = Trajectory(proba=[model.reweighted(search.proba())], cost=[0.0])
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
            chords, contacts = _wrap_seen(execute(a))
            if chords is None or len(chords) == 0:
                search.mark_unavailable(a)
                continue
            tr.cost.append(tr.cost[-1] + float(cost[search.current_plane, a]))
            search.add_wrap(a, chords, contacts)
            tr.planes.append(a)
            tr.proba.append(model.reweighted(search.proba()))
        tr.checks.append(len(tr.planes))
        if tr.stop is None and strong_prediction(tr.proba[-1], params):
            tr.stop = len(tr.checks) - 1
            if stop_early:
                tr.stopped_because = "strong_prediction"
                break
    tr.proba = [np.asarray(p) for p in tr.proba]
    return tr


def _wrap_seen(seen) -> tuple:
    """(chords, contact centres or None) of what an execute() returned."""
    return seen if isinstance(seen, tuple) else (seen, None)


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


def recognize(model: ActiveModel, execute: Callable[[int], np.ndarray | None],
              scenario: Config | None = None, *, available: Sequence[int] | None = None,
              seed: int | None = None, stop_early: bool = True, view=None) -> Recognition:
    """Active recognition of one object by tree search (section V-C) with the scenario's
    active section (default: the shipped configuration, Config()); costs in rad. view: the
    depth camera's view of the object (needed by a classifier that uses it)."""
    if getattr(model.classifier, "uses_view", False) and view is None:
        raise InputError("this active model classifies with the depth camera's view of the "
                         "object (its height and footprint): give the view")
    params = (Config() if scenario is None else scenario).active
    tr = run_policy(model, execute, "mcts", params=params, available=available, seed=seed,
                    stop_early=stop_early, view=view)
    return recognition(tr, model.observations.classes)


def recognition(tr: Trajectory, classes: np.ndarray) -> Recognition:
    """What a tree search's run (run_policy "mcts") found, iteration by iteration."""
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


def simulated_execute(scene, planes, chord_params, *, wrap_params=None, log=None
                      ) -> Callable[[int], np.ndarray | None]:
    """Execute a plane by wrapping the scene's object there in simulation; its chords and
    contact centres, or None when the wrap is unusable (empty cut, no contact). `log`
    collects every WrapResult."""
    from ..features.chords import wrap_chords
    from ..wrapping.wrap import WrapParams, wrap

    def execute(plane_index: int):
        result = wrap(scene, planes[plane_index], wrap_params or WrapParams())
        if log is not None:
            log.append(result)
        if not result.usable:
            return None
        return wrap_chords(result, chord_params), np.asarray(result.contacts.p, dtype=float)
    return execute


def precomputed_execute(obj: ObjectWraps) -> Callable[[int], tuple | None]:
    """execute() over an object's precomputed wraps: the wrap on that plane (its chords and
    contact centres, None where unknown), or None."""
    def execute(plane: int):
        chords = obj.wraps.get(int(plane))
        return None if chords is None else (chords, obj.contacts.get(int(plane)))
    return execute


# --------------------------------------------------------------------------- runs over processes

_worker_model: tuple | None = None  # (model, params) of a run_policies worker process


def _worker_init(model: ActiveModel, params: ActiveParams) -> None:
    """Pool initializer: the model reaches each worker once (inherited by a forked worker),
    not with every run."""
    global _worker_model
    worker_setup()
    _worker_model = (model, params)


def _run_job(model: ActiveModel, params: ActiveParams, job: tuple) -> Trajectory:
    obj, policy, seed, stop_early = job
    return run_policy(model, precomputed_execute(obj), policy, params=params,
                      available=sorted(obj.wraps), seed=seed, stop_early=stop_early,
                      view=obj.view)


def _worker_job(job: tuple) -> Trajectory:
    return _run_job(*_worker_model, job)


def run_policies(model: ActiveModel, jobs: Sequence[tuple], *,
                 params: ActiveParams = ActiveParams(), workers: int | None = 1
                 ) -> Iterator[Trajectory]:
    """run_policy on precomputed wraps for each job (ObjectWraps, policy, seed, stop_early),
    yielding the trajectories in the jobs' order. Runs are independent (each its own seed),
    so `workers` processes (None: all cores; 1: in this process) give the same planes, stops
    and probabilities, only the search times differ. On Linux the workers are forked: they
    inherit the imported package and the model instead of importing it again (seconds)."""
    if workers is not None and (isinstance(workers, bool) or workers < 1):
        raise InputError(f"workers must be at least 1, got {workers!r}")
    workers = min(workers or os.cpu_count() or 1, len(jobs))
    if workers <= 1:
        for job in jobs:
            yield _run_job(model, params, job)
        return
    fork = sys.platform == "linux"
    pool = ProcessPoolExecutor(max_workers=workers,
                               mp_context=get_context("fork" if fork else "spawn"),
                               initializer=_worker_init, initargs=(model, params))
    try:
        with nullcontext() if fork else main_not_rerun():
            with sigint_held():  # the workers start here: a Ctrl-C waits until they exist
                results = pool.map(_worker_job, jobs)
            yield from results
    except BaseException:  # Ctrl-C, a failed run, or the caller stopped early
        stop_workers(pool)
        raise
    pool.shutdown(wait=True)


def build_active_model(classifier: ChordClassifier, train_objects: Sequence[ObjectWraps],
                       plane_normals: np.ndarray, *, params: ActiveParams = ActiveParams()
                       ) -> ActiveModel:
    """Tally the training objects' wraps with the classifier's bin edges (`edges_`)."""
    obs = fit_observation_model(train_objects, classifier.classes_, classifier.edges_,
                                plane_normals=plane_normals, neighbours=params.neighbours)
    return ActiveModel(classifier, obs)


def evaluate_policies(model: ActiveModel, test_objects: Sequence[ObjectWraps], *,
                      policies: Sequence[str] = POLICIES, params: ActiveParams = ActiveParams(),
                      seed: int = 0, progress: Callable | None = None,
                      show_progress: bool = True, workers: int | None = 1) -> dict:
    """Run each policy on every held-out object (execute = its precomputed wraps; object k
    with seed + k) over `workers` processes (run_policies), with a progress bar unless
    show_progress is False; progress(policy, k) after each run.

    Returns per policy: accuracy, mean wraps and mean movement cost (rad) at the stop, the
    fraction stopped by the strong rule, and curves: accuracy after n wraps (the last
    prediction when a run ended earlier) and accuracy within a movement budget.
    """
    from tqdm import tqdm

    classes = model.observations.classes
    budget = params.max_iterations * params.horizon
    for policy in policies:
        if policy not in POLICIES:
            raise InputError(f"unknown policy {policy!r}; one of {POLICIES}")
    jobs = [(obj, policy, seed + k, False) for policy in policies
            for k, obj in enumerate(test_objects)]
    by_policy = {policy: [] for policy in policies}
    with tqdm(total=len(jobs), unit="run", leave=False, disable=not show_progress) as bar:
        for tr, (obj, policy, _, _) in zip(run_policies(model, jobs, params=params,
                                                        workers=workers), jobs):
            correct = np.array([classes[int(np.argmax(p))] == obj.label for p in tr.proba])
            s = tr.stop if tr.stop is not None else len(tr.checks) - 1
            n_stop = tr.checks[s] if tr.checks else 0
            by_policy[policy].append({
                "object": obj.name, "label": obj.label, "planes": tr.planes,
                "correct": correct, "cost": np.asarray(tr.cost), "n_stop": n_stop,
                "strong": tr.stop is not None, "search_times": tr.search_times})
            bar.set_description(policy, refresh=False)
            bar.update()
            if progress:
                progress(policy, len(by_policy[policy]) - 1)
    out = {}
    for policy, runs in by_policy.items():
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


