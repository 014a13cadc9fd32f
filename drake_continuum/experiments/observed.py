"""Accuracy when the arm's shape is measured by the camera rather than known.

Trained on the exact wraps of a collection, the classifier is tested by object on the same
held-out objects four ways: (a) the exact configurations; (b) each wrap's configuration
fitted from one simulated depth camera view (perception.observe); (c) from two views on
opposite sides; (d) the object transparent: left out of the depth image, and classified by
the touch-only model (ClassifierParams.touch_only, no camera view of the object), which is
also reported on exact configurations to separate what the view is worth from what the fit
costs. Each held-out object's wraps are observed once (the split does not change what the
camera sees) and every split tests the observations of its held-out half.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
from pathlib import Path

import numpy as np

from ..config import Config
from ..errors import InputError
from ..features.chords import ChordParams
from ..files import jsonable, write_atomic, write_json
from ..learning.evaluation import splits
from ..learning.pipeline import ClassifierParams
from ..learning.records import object_record, read_object_wraps, recorded_side, recorded_view
from ..markdown import markdown_table
from ..npz import npz_arrays
from ..perception.observe import observe_wraps, observed_result
from ..wrapping.wrap_types import WrapResult

__all__ = ["CONDITIONS", "CONDITION_NAMES", "TRAIN_ON",
           "collection_scene", "observation_tasks", "submit_observations", "submit_study",
           "study_objects",
           "collection_arm", "observe_object", "exact_object", "condition_records",
           "observed_records", "evaluate_observed", "evaluate_held_out", "active_observed",
           "observed_markdown", "observed_study"]

# name: observe_wrap's options (None: the exact configuration)
CONDITIONS = {"exact": None, "one_view": {"views": 1}, "two_views": {"views": 2},
              "transparent": {"views": 1, "transparent": True}}
# What an observation is made by (camera model, segmentation, fit): a cache of another
# version is observed again. Raised with every change to what observe_wrap returns.
OBSERVE_VERSION = 3


def collection_scene(folder, object_id: str, dataset=None):
    """(meta, wraps, arm, mesh) of one object of a collection: the arm it was wrapped with
    and its mesh where the wraps saw it (moved by the recorded centre, turned by the
    recorded bearing, as collect wrapped it)."""
    from ..objects.mesh import load_mesh
    from ..objects.placement import arm_frame
    from .collect import wrapped_mesh_path

    meta, wraps = read_object_wraps(folder, object_id)
    arm = collection_arm(meta)
    mesh = load_mesh(wrapped_mesh_path(folder, object_id, meta, dataset=dataset))
    centre = meta.get("centre") or (0.0, 0.0)
    turn = math.radians(float((meta.get("bearing") or {}).get("turn_deg", 0.0)))
    if turn or any(centre):
        mesh = arm_frame(mesh, centre, turn)
    return meta, wraps, arm, mesh


def collection_arm(meta: dict):
    """The arm a collection's object was wrapped with (its recorded description)."""
    import yaml

    from ..kinematics.arm import ContinuumArm, load_arm

    arm_yaml = (meta.get("params") or {}).get("arm_yaml")
    return load_arm() if arm_yaml is None else ContinuumArm.from_dict(yaml.safe_load(arm_yaml))


def observe_object(folder, object_id: str, *, seed: int = 0, chords=None,
                   dataset=None, cache=None) -> dict:
    """Each condition's observed wraps and ObjectRecord of one object (`condition_records`),
    and per fitted wrap its CPU time, tip error against the exact configuration (m) and
    whether the fit was confident. With `cache` (a folder) the observed wraps are read from
    <cache>/<object_id>.npz and .json when they were made with the same camera seed from the
    same stored wraps, and written there otherwise: observing is the slow part (about a
    second a wrap and view); each wrap is rebuilt on its cached fitted configuration."""
    meta, wraps = read_object_wraps(folder, object_id)
    oid, category = str(meta.get("object_id", object_id)), str(meta["category"])
    key = _cache_key(meta, seed)
    seen = _read_cache(cache, object_id, key)
    if seen is not None:  # rebuilt on the cached fits: the rebuild's code may be newer
        arm = collection_arm(meta)
        seen["wraps"] = {name: [observed_result(w, w.arm(arm), v.final_config)
                                if w.usable and v.usable else v for w, v in zip(wraps, vs)]
                         for name, vs in seen["wraps"].items()}
    else:
        seen = _observe_conditions(folder, object_id, seed, dataset)
        if cache is not None:
            _write_cache(cache, object_id, key, seen)
    out = {"object_id": oid, "category": category, "side": recorded_side(oid, meta),
           "view": recorded_view(meta.get("view"), f"{Path(folder) / object_id}.json"),
           "wraps": {"exact": wraps, **seen["wraps"]}, "fits": {"exact": [], **seen["fits"]}}
    out["records"] = condition_records(out, chords)
    return out


def _cache_key(meta: dict, seed: int) -> dict:
    """What an object's observations depend on: the camera seed, the stored wraps, the
    conditions and the code that observes (OBSERVE_VERSION)."""
    return {"version": OBSERVE_VERSION, "seed": int(seed), "wraps_sha256": meta.get("npz_sha256"),
            "conditions": {k: v for k, v in CONDITIONS.items() if v is not None}}


def exact_object(folder, object_id: str, chords=None) -> dict:
    """observe_object's result with the exact condition alone (nothing observed): an
    object only trained on."""
    meta, wraps = read_object_wraps(folder, object_id)
    oid = str(meta.get("object_id", object_id))
    out = {"object_id": oid, "category": str(meta["category"]),
           "side": recorded_side(oid, meta),
           "view": recorded_view(meta.get("view"), f"{Path(folder) / object_id}.json"),
           "wraps": {"exact": wraps}, "fits": {"exact": []}}
    out["records"] = condition_records(out, chords)
    return out


def _observe_conditions(folder, object_id: str, seed: int, dataset) -> dict:
    """{"wraps": {condition: observed wraps}, "fits": {condition: _fit_row of each}}."""
    _, wraps, arm, mesh = collection_scene(folder, object_id, dataset)
    out = {"wraps": {}, "fits": {}}
    for name, options in CONDITIONS.items():
        if options is None:
            continue
        seen = observe_wraps(wraps, arm, mesh, seed=seed, **options)
        out["wraps"][name] = [o.wrap for o in seen]
        out["fits"][name] = [_fit_row(arm, w, o) for w, o in zip(wraps, seen) if w.usable]
    return out


def _read_cache(cache, object_id: str, key: dict) -> dict | None:
    """The cached observations of an object, None when there are none or they were made
    otherwise (another seed, other stored wraps, other conditions)."""
    if cache is None:
        return None
    json_path, npz_path = Path(cache) / f"{object_id}.json", Path(cache) / f"{object_id}.npz"
    where = json_path
    try:
        meta = json.loads(json_path.read_text())
        if meta.get("key") != jsonable(key):
            return None
        where = npz_path
        arrays = npz_arrays(npz_path.read_bytes())  # np.load's arrays, in one pass
        wraps = {name: [WrapResult.from_arrays(arrays, f"{name}_w{k}_") for k in range(n)]
                 for name, n in meta["n_wraps"].items()}
    except FileNotFoundError:
        return None
    except (OSError, ValueError, KeyError, TypeError, zipfile.BadZipFile) as e:
        raise InputError(f"{where}: unreadable observation cache ({type(e).__name__}: "
                         f"{e}); remove it to observe again") from None
    return {"wraps": wraps, "fits": meta["fits"]}


def _write_cache(cache, object_id: str, key: dict, seen: dict) -> None:
    folder = Path(cache)
    folder.mkdir(parents=True, exist_ok=True)
    arrays = {}
    for name, wraps in seen["wraps"].items():
        for k, w in enumerate(wraps):
            arrays.update(w.to_arrays(f"{name}_w{k}_"))
    write_atomic(folder / f"{object_id}.npz", lambda f: np.savez_compressed(f, **arrays))
    write_json(folder / f"{object_id}.json",
               {"key": key, "n_wraps": {n: len(w) for n, w in seen["wraps"].items()},
                "fits": seen["fits"]})


def condition_records(observed: dict, chords=None) -> dict:
    """{condition: ObjectRecord} of an observe_object result, its chords taken with
    `chords` (ChordParams); the transparent one without the camera's view of the object."""
    chords = chords or ChordParams()
    return {name: object_record(observed["object_id"], observed["category"], wraps,
                                params=chords, side=observed["side"],
                                view=None if name == "transparent" else observed["view"])
            for name, wraps in observed["wraps"].items()}


def _fit_row(arm, exact, seen) -> dict:
    """One fitted wrap's figures (an unfound arm: tip error None)."""
    row = {"cpu_s": seen.cpu_s, "found": "error" not in seen.flags,
           "confident": bool(seen.flags.get("confident", False)),
           "ambiguous": bool(seen.flags.get("ambiguous", False)),
           "tip_uncertainty_mm": seen.flags.get("tip_uncertainty_mm"), "tip_error_m": None}
    if row["found"]:
        wrap_arm = exact.arm(arm)
        row["tip_error_m"] = float(np.linalg.norm(
            wrap_arm.tip_frame(seen.wrap.final_config)[1]
            - wrap_arm.tip_frame(exact.final_config)[1]))
    return row


def observed_records(folder, object_ids, *, seed: int = 0, chords=None, dataset=None,
                     progress=None, cache=None, workers: int | None = 1,
                     pool=None, submitted=None, timing=None) -> list[dict]:
    """observe_object of each object; the camera noise of the object k-th in the collection's
    index.json is seeded seed + 10000 k (the same whichever objects are chosen). With
    `workers` over 1 (None: every core) the objects `cache` does not hold are observed on
    that many spawned processes, stopped at once on Ctrl-C as collect's are, or on `pool`
    (an Executor of the caller's, e.g. reproduce's run, whose workers have their imports
    already), or were queued there already (`submitted`: submit_observations' answer for
    these objects); the records are the same as in one process. `timing` (a dict) gets the
    CPU seconds of the observations made on the caller's pool ("observing_s"; those of the
    processes started here are this process's children's)."""
    from concurrent.futures import FIRST_COMPLETED, wait
    from contextlib import nullcontext

    from ..workers import local_pool

    if workers is not None and workers < 1:
        raise InputError(f"workers must be at least 1, got {workers}")
    tasks = observation_tasks(folder, object_ids, seed=seed, chords=chords, dataset=dataset,
                              cache=cache)
    out = [None] * len(tasks)
    timing = {} if timing is None else timing

    def store(k, result):
        out[k] = result
        if progress is not None:
            progress(sum(r is not None for r in out), len(tasks), tasks[k]["object_id"])

    if submitted is not None and submitted["tasks"] != tasks:
        raise InputError("the observations queued are not those of these objects")
    todo = ([k for k, t in enumerate(tasks) if not _cached(t)] if submitted is None
            else list(submitted["futures"]))
    n_workers = min(workers or os.cpu_count() or 1, len(todo))
    if pool is None and submitted is None and n_workers <= 1:
        for k, task in enumerate(tasks):
            store(k, observe_object(**task))
        return out
    queued = pool is not None or submitted is not None  # a pool of the caller's
    with nullcontext(pool) if queued else local_pool(n_workers) as pool:
        if submitted is None:
            pending = _submit(pool, tasks, todo)
        else:
            pending = {future: k for k, future in submitted["futures"].items()}
        for k in sorted(set(range(len(tasks))) - set(todo)):  # read while the workers run
            store(k, observe_object(**tasks[k]))
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                result, seconds = fut.result()
                if queued:
                    timing["observing_s"] = timing.get("observing_s", 0.0) + seconds
                store(pending.pop(fut), result)
    return out


def observation_tasks(folder, object_ids, *, seed: int = 0, chords=None, dataset=None,
                      cache=None) -> list[dict]:
    """observe_object's arguments for each object (observed_records)."""
    index = json.loads((Path(folder) / "index.json").read_text())
    position = {str(e["object_id"]): k for k, e in enumerate(index["objects"])}
    return [{"folder": folder, "object_id": oid, "seed": seed + 10000 * position[str(oid)],
             "chords": chords, "dataset": dataset, "cache": cache} for oid in object_ids]


def _submit(pool, tasks: list, todo: list) -> dict:
    """Queue observe_object of tasks[k] for each k of `todo` on `pool`: {Future: k}."""
    from ..workers import sigint_held
    with sigint_held():  # workers start (spawned on submit) with Ctrl-C held
        return {pool.submit(_observe_timed, **tasks[k]): k for k in todo}


def _observe_timed(**task) -> tuple:
    """(observe_object(**task), its CPU seconds), in a worker."""
    import time
    c0 = time.process_time()
    return observe_object(**task), time.process_time() - c0


def submit_observations(pool, folder, object_ids, **options) -> dict:
    """Queue on `pool` now the observations of the objects the cache does not hold (options:
    observation_tasks'), for observed_records(submitted=...) to take later: a caller with
    other work (reproduce, as collect ends) keeps the pool busy with them meanwhile."""
    tasks = observation_tasks(folder, object_ids, **options)
    todo = [k for k, t in enumerate(tasks) if not _cached(t)]
    return {"tasks": tasks, "futures": {k: f for f, k in _submit(pool, tasks, todo).items()}}


def submit_study(pool, *, wraps, out, per_category: int, categories: int | None = None,
                 seed: int = 0, chords=None, cache=None) -> dict:
    """submit_observations of observed_study's objects (its arguments of the same names):
    their fits queued on `pool`, for observed_study(submitted=...)."""
    chosen, _ = study_objects(wraps, per_category, categories)
    return submit_observations(pool, wraps, chosen, seed=seed, chords=chords,
                               cache=cache or Path(out) / "cache")


def study_objects(wraps, per_category: int, categories: int | None = None) -> tuple:
    """(the objects observed_study sees through the camera, the rest of the collection):
    the first `per_category` of each of the first `categories` categories (None: all) of
    collection `wraps`, in its index's order; the rest of those categories."""
    index = json.loads((Path(wraps) / "index.json").read_text())
    chosen, count, rest = [], {}, []
    for entry in index["objects"]:
        cat = str(entry["category"])
        if cat not in count and categories is not None and len(count) >= categories:
            continue
        if count.get(cat, 0) < per_category:
            chosen.append(str(entry["object_id"]))
            count[cat] = count.get(cat, 0) + 1
        else:
            rest.append(str(entry["object_id"]))
    return chosen, rest


def _cached(task: dict) -> bool:
    """Whether the cache holds the observations of observed_records' task."""
    if task["cache"] is None:
        return False
    json_path = Path(task["folder"]) / f"{task['object_id']}.json"
    try:
        meta = json.loads(json_path.read_text())
    except (OSError, ValueError):
        return False  # observe_object names the file
    try:
        held = json.loads((Path(task["cache"]) / f"{task['object_id']}.json").read_text())
    except (OSError, ValueError):
        return False
    return isinstance(held, dict) and held.get("key") == jsonable(_cache_key(meta, task["seed"]))


def evaluate_observed(objects: list[dict], n_splits: int = 10, seed: int = 0,
                      classifier: ClassifierParams = ClassifierParams(), chords=None, *,
                      train_on: str = "exact", observed: int | None = None,
                      class_prior: str = "uniform") -> dict:
    """Accuracy of each condition over random stratified 50/50 splits by object (the
    recommended model, and the touch-only one for the transparent condition and
    `exact_touch_only`); with the fits' figures a condition. train_on "exact": every model
    is trained on the training half's exact wraps; "observed": each condition's on the
    training half's wraps observed the same way (what the camera would show of them).
    `observed`: only the first `observed` objects were seen through the camera, the rest are
    trained on only (_observed_splits). `class_prior` (train_active's): "uniform" answers
    with each model's probabilities reweighted from its training frequencies to every
    category alike, since the objects seen are drawn N a category; "training" as learnt."""
    pairs = _observed_splits([o["category"] for o in objects], n_splits, seed,
                             observed=observed)
    out = _evaluate(objects, pairs, seed, classifier, chords, train_on, class_prior)
    return {"n_objects": len(objects) if observed is None else observed,
            "n_collection": len(objects), "n_splits": len(pairs), **out}


def _observed_splits(labels, n_splits: int, seed: int, *, observed: int | None) -> list:
    """The random stratified 50/50 splits by object; with `observed`, each split's test half
    keeps its first `observed` objects only, and a split left without one is dropped."""
    pairs = splits(labels, n_splits=n_splits, seed=seed)
    if observed is None:
        return pairs
    return [(train, test[test < observed]) for train, test in pairs
            if np.any(test < observed)]


def evaluate_held_out(train: list[dict], test: list[dict], seed: int = 0,
                      classifier: ClassifierParams = ClassifierParams(), chords=None, *,
                      train_on: str = "exact", class_prior: str = "uniform") -> dict:
    """evaluate_observed's figures of models trained on every object of `train` and tested
    on every object of `test` (another dataset's, never seen in development)."""
    n = len(train)
    out = _evaluate(train + test, [(np.arange(n), np.arange(n, n + len(test)))], seed,
                    classifier, chords, train_on, class_prior)
    return {"n_train": n, "n_test": len(test), **out}


def _evaluate(objects, pairs, seed, classifier, chords, train_on, class_prior) -> dict:
    from ..active.training import CLASS_PRIORS

    if train_on not in TRAIN_ON:
        raise InputError(f"train_on must be one of {TRAIN_ON}, got {train_on!r}")
    if class_prior not in CLASS_PRIORS:
        raise InputError(f"class_prior must be one of {CLASS_PRIORS}, got {class_prior!r}")
    labels = [o["category"] for o in objects]
    tests = {name: (name == "transparent") for name in CONDITIONS}
    tests["exact_touch_only"] = True
    correct = {name: [] for name in tests}
    confusion = {}
    for train_idx, test_idx in pairs:
        models = _split_models(objects, train_idx, tests, seed, chords, classifier, train_on)
        for name in tests:
            records = [objects[i]["records"][_source(name)] for i in test_idx]
            model = models[name]
            proba = model.predict_proba(records)
            if class_prior == "uniform":  # Bayes' rule for a change of prior
                proba = proba / _frequencies(model.classes_, [labels[i] for i in train_idx])
            predicted = model.classes_[np.argmax(proba, axis=1)]
            truth = [labels[i] for i in test_idx]
            correct[name].append(float(np.mean(predicted == np.asarray(truth))))
            if name == "one_view":
                for t, p in zip(truth, predicted):
                    confusion.setdefault(t, {}).setdefault(str(p), 0)
                    confusion[t][str(p)] += 1
    out = {"seed": seed, "train_on": train_on, "class_prior": class_prior, "conditions": {}}
    for name, accs in correct.items():
        row = {"accuracy_mean": float(np.mean(accs)), "accuracy_std": float(np.std(accs)),
               "touch_only_model": tests[name]}
        row.update(_fit_figures([f for i in sorted({int(i) for _, t in pairs for i in t})
                                 for f in objects[i]["fits"][_source(name)]]))
        out["conditions"][name] = row
    out["confusion_one_view"] = confusion
    return out


def active_observed(folder, train: list[dict], test: list[dict], *, params=None,
                    seed: int = 0, chords=None, classifier=None,
                    class_prior: str = "uniform", workers: int | None = 1) -> dict:
    """Active recognition (the tree search, stopped by the paper's rule) of the `test`
    objects from each condition's wraps, with the active model trained on the `train`
    objects' exact wraps (collection `folder`'s planes; the touch-only one for the
    transparent condition): accuracy, wraps and movement at the stop a condition.
    `class_prior` (train_active's): "uniform" by default, since the objects tested here
    are drawn N a category (the camera study's first N of each, a held-out set's N), not
    as often as the training set holds each category (measured: BENCHMARKS.md, Point
    clouds). The runs go on `workers` processes (evaluate_policies: the same results)."""
    from ..active.params import ActiveParams
    from ..active.policies import evaluate_policies
    from ..active.training import object_wraps_from_records, train_active
    from ..learning.pipeline import ClassifierParams as Params

    params = params or ActiveParams()
    classifier = classifier or Params()
    exact = [o["records"]["exact"] for o in train]
    models = {touch: train_active(folder, params=params, seed=seed, records=exact,
                                  chords=chords, class_prior=class_prior,
                                  classifier=classifier.touch_only() if touch else classifier)
              for touch in (False, True)}
    out = {}
    for name in CONDITIONS:
        objects = object_wraps_from_records([o["records"][name] for o in test])
        r = evaluate_policies(models[name == "transparent"], objects, policies=("mcts",),
                              params=params, seed=seed, show_progress=False,
                              workers=workers)["mcts"]
        out[name] = {k: r[k] for k in ("n_objects", "accuracy_at_stop", "wraps_to_stop",
                                       "movement_cost_to_stop_rad", "strong_fraction")}
    return out


TRAIN_ON = ("exact", "observed")


def _frequencies(classes, train_labels) -> np.ndarray:
    """Each class's share of the training labels, in the model's class order."""
    train_labels = np.asarray(train_labels)
    return np.array([np.mean(train_labels == c) for c in classes])


def _source(name: str) -> str:
    """The condition whose records a test row reads."""
    return "exact" if name == "exact_touch_only" else name


def _split_models(objects, train_idx, tests: dict, seed, chords, classifier, train_on) -> dict:
    """{test row: its model} of one split; models trained on the same records shared."""
    from ..learning.model import train

    made, out = {}, {}
    for name, touch_only in tests.items():
        source = _source(name) if train_on == "observed" else "exact"
        key = (source, touch_only)
        if key not in made:
            scenario = Config(chords=chords or ChordParams(),
                              classifier=classifier.touch_only() if touch_only else classifier)
            made[key] = train([objects[i]["records"][source] for i in train_idx], scenario,
                              seed=seed)
        out[name] = made[key]
    return out


def _fit_figures(fits: list[dict]) -> dict:
    """Median CPU, tip error (median, p90), found and confident fractions of fitted wraps."""
    if not fits:
        return {}
    found = [f for f in fits if f["found"]]
    tip = np.array([f["tip_error_m"] for f in found])
    return {"n_wraps": len(fits), "found_fraction": len(found) / len(fits),
            "confident_fraction": float(np.mean([f["confident"] for f in fits])),
            "cpu_s_median": float(np.median([f["cpu_s"] for f in fits])),
            "tip_error_mm_median": 1e3 * float(np.median(tip)) if len(tip) else None,
            "tip_error_mm_p90": 1e3 * float(np.percentile(tip, 90)) if len(tip) else None}


CONDITION_NAMES = {"exact": "exact configurations", "one_view": "fitted, one camera view",
                   "two_views": "fitted, two views", "transparent":
                   "fitted, object transparent (touch-only model)"}


def observed_markdown(result: dict) -> str:
    """The table of evaluate_observed's result (with its "active" entry of active_observed
    when there is one), the confusion of one view and the cost of a fitted wrap."""
    from ..files import percent_text

    active = result.get("active") or {}
    rows = []
    for name, label in CONDITION_NAMES.items():
        c, a = result["conditions"][name], active.get(name)
        stop = ((percent_text(a["accuracy_at_stop"]), f"{a['wraps_to_stop']:.1f}") if a
                else ("n/a", "n/a"))
        rows.append((label, f"{percent_text(c['accuracy_mean'])} ± "
                            f"{percent_text(c['accuracy_std'])}", *stop))
    rows = markdown_table(("wraps seen as", "accuracy (by object)", "recognised at stop",
                           "wraps to stop"), rows)
    one = result["conditions"]["one_view"]
    classes = sorted(result["confusion_one_view"])
    got = result["confusion_one_view"]
    confusion = markdown_table(("true \\ predicted", *classes),
                               [(t, *(got[t].get(p, 0) for p in classes)) for t in classes])
    cost = (f"A fitted wrap costs {one['cpu_s_median']:.2f} s of CPU (median, one view; "
            f"rendering, segmenting and fitting); the fitted tip lies "
            f"{one['tip_error_mm_median']:.1f} mm from the exact one (median, 90th percentile "
            f"{one['tip_error_mm_p90']:.1f} mm).\n" if one.get("n_wraps") else "")
    return ("\n".join(rows) + "\n\n" + cost + "\nConfusion of one camera view (all splits' "
            "test objects):\n\n" + "\n".join(confusion) + "\n")


def observed_study(wraps, out, *, per_category: int, categories: int | None = None,
                   n_splits: int = 10, seed: int = 0, chords=None,
                   classifier: ClassifierParams = ClassifierParams(), active=None,
                   cache=None, workers: int | None = 1, pool=None, submitted=None,
                   timing=None) -> dict:
    """The study `reproduce` reports beside Table I: the first `per_category` objects of each
    of the first `categories` categories (None: all) of collection `wraps` seen through the
    camera on `workers` processes or `pool`, or queued there already (`submitted`:
    submit_study's answer) (observed_records, with `timing`; observations cached in
    `cache`, default out/cache), tested on `n_splits` splits by object of those categories'
    whole collection (each split's models trained on the exact wraps of its training half,
    as Table I's; its test half's observed objects tested), and active_observed
    (ActiveParams `active`, its runs on `workers` processes) on the first split; writes
    out/observed.json and out/observed.md."""
    out = Path(out)
    chosen, rest = study_objects(wraps, per_category, categories)
    seen = observed_records(wraps, chosen, seed=seed, chords=chords,
                            cache=cache or out / "cache", workers=workers, pool=pool,
                            submitted=submitted, timing=timing)
    # Trained at Table I's scale: a split's models learn the exact wraps of its whole
    # training half of the collection, and its test half's observed objects are tested.
    objects = seen + [exact_object(wraps, oid, chords) for oid in rest]
    result = evaluate_observed(objects, n_splits, seed, classifier, chords,
                               observed=len(seen))
    train_idx, test_idx = _observed_splits([o["category"] for o in objects], n_splits, seed,
                                           observed=len(seen))[0]
    result["active"] = active_observed(wraps, [objects[i] for i in train_idx],
                                       [objects[i] for i in test_idx], params=active,
                                       seed=seed, chords=chords, classifier=classifier,
                                       workers=workers)
    result["frame"] = (chords.frame if chords is not None else None)
    result["objects"] = chosen
    write_json(out / "observed.json", result)
    write_atomic(out / "observed.md", observed_markdown(result).encode())
    return result
