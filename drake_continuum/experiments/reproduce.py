"""One command reproduces the paper: dataset, wraps, Table I, Fig. 5, 7 and 8, Table II, and
a report (Markdown and HTML) with the paper's numbers beside ours; then what the paper did
not test: the objects placed as a robot meets them (turned, on another side, nudged), on this
dataset and on a second one never used to choose a setting, and the recommended models
(OUT/model for classify, OUT/active-model for recognize).

Every step writes its outputs under one folder and a `<step>.done.json` marker with its
figures, written only when the step succeeded; a rerun skips finished steps (and collection
itself resumes per object), so an interrupted run continues where it stopped. `quick` is a
stated subset for a first look.

settings.json records everything the run was made with (quick, per_category, splits, seed and
the whole configuration). A rerun with other settings is refused, naming the keys that
differ, unless `redo` is set: then the steps those keys feed (STEP_INPUTS) and every step
after them that reads their outputs are done again.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path

from .. import __version__
from ..config import Config, config_to_tree, tree_difference
from ..errors import ConfigError, InputError
from ..files import writable_folder, write_json
from ..wrapping.wrap_types import WrapStatus
from . import schedule
from .collection import training_settings
from .settings import PLACEMENTS, QUICK_PLACEMENTS, RunSettings, settings_record
from .timing import Work, step_clock

__all__ = ["PLACEMENTS", "QUICK_PLACEMENTS", "held_out_kinds", "RunSettings", "STEPS",
           "STEP_INPUTS", "STEP_AFTER", "STEP_OUTPUTS", "STEP_WRAPS", "steps_to_redo",
           "outputs_to_remove", "reproduce"]

log = logging.getLogger(__name__)

# Objects seen through the camera (experiments/observed.py): (a category, categories; None:
# all) of a full run and of a quick one, whose few objects keep its cost to minutes (a split
# by object trains on two a category).
OBSERVED, QUICK_OBSERVED = (4, None), (4, 2)


def _marker(out: Path, step: str) -> Path:
    return out / f"{step}.done.json"


# The kind of work (timing.KINDS) of each step's own CPU time; the collections inside a
# step add their own kinds (_collected).
STEP_KIND = {"dataset": "dataset", "gallery": "figures", "collect": "other",
             "wrap_figure": "figures", "classification": "training",
             "active": "active recognition", "real": "other", "placements": "training",
             "active_placed": "active recognition", "second": "training", "observed": "camera"}
_WORK = Work()  # the running step's work by kind, and the CPU time of its own the kinds count


def _clock() -> float:
    """A step's CPU clock: step_clock less the work run ahead meanwhile, counted apart."""
    return step_clock() - schedule.ahead_cpu()


def _collected(report, ahead_s: float | None = None, placing_s: float = 0.0):
    """Count a collection's work (its kinds; placing its objects, "dataset") in the running
    step's. The CPU time its kinds count that ran in this process (placing, generating,
    objects wrapped inline) is out of the step's own when it ran there, and out of the CPU
    time of the thread that ran it ahead (ahead_s) when one did, whose rest is "other"."""
    _WORK.add(report.work_s, {"dataset": placing_s} if placing_s else {})
    counted = (placing_s + report.work_s.get("dataset", 0.0)
               + (sum(report.object_cpu_s.values()) if report.inline else 0.0))
    _WORK.add({"counted": counted} if ahead_s is None else {"other": ahead_s - counted})
    return report


def _start_ahead(s: RunSettings) -> None:
    """As collect starts, on a pool of local workers: place the copies and queue their
    collection behind the originals (submitted as collect starts; placing takes seconds),
    and the second dataset's collections behind them (schedule.py), for the steps still to
    run. The order only changes when each collection ends, not its wraps."""
    pool = schedule.run_pool(s)
    if pool is None:  # one process, or a Dask cluster: in its step
        return
    copies = None
    if not _marker(s.out, "placements").exists():
        copies = schedule.start("placements",
                                lambda: _placed_collection(s, s.out, s.seed, where=pool))
    if s.second_dataset and not _marker(s.out, "second").exists():
        originals = schedule.start("second", lambda: _second_originals(s, pool, copies))
        schedule.start("second_placed", lambda: _second_copies(s, pool, originals))


def _queue_observations(s: RunSettings) -> None:
    """As collect has ended, on the run's pool: queue the camera study's fits (behind the
    placed copies, before the second dataset) when that step is still to run."""
    pool = schedule.POOL.get("pool")  # made for the collections; none made for these
    if pool is None or getattr(pool, "_broken", False):
        return
    if s.observed and not _marker(s.out, "observed").exists():
        from .observed import submit_study
        schedule.keep("observed", submit_study(pool, **_observed_options(s)))


def _step(out: Path, step: str, run):
    """Run a step unless its marker exists; return its recorded figures, with its wall time
    (time_s) and its work by kind in CPU seconds (work_s)."""
    marker = _marker(out, step)
    if marker.exists():
        log.info("%s: done in an earlier run, skipped (%s)", step, marker)
        return json.loads(marker.read_text())
    log.info("%s ...", step)
    _WORK.clear()
    t0, c0 = time.perf_counter(), _clock()
    figures = run()
    figures["time_s"] = time.perf_counter() - t0
    own = _clock() - c0 - _WORK.pop("counted", 0.0)
    started = schedule.started_cpu()  # the run's workers' starts, in the step they ended in
    if started:
        _WORK.add({"other": started})
    figures["version"] = __version__  # the results page says which version made each figure
    figures["date"] = time.strftime("%Y-%m-%d", time.gmtime())
    figures["work_s"] = dict(Work(_WORK).add({STEP_KIND[step]: max(own, 0.0)}))
    write_json(marker, figures)
    log.info("%s: %.1f s", step, figures["time_s"])
    return figures


def _dataset_counts(s: RunSettings) -> dict:
    from ..objects.generators import CATEGORY_COUNTS
    chosen = s.categories or tuple(CATEGORY_COUNTS)
    return {c: min(n, s.per_category) if s.quick else n for c, n in CATEGORY_COUNTS.items()
            if c in chosen}


def _dataset(s: RunSettings) -> dict:
    from ..objects.dataset import generate_dataset
    counts = _dataset_counts(s)
    # The run's own folder: a resumed run writes the same seed's bytes again.
    generate_dataset(s.out / "dataset", seed=s.seed, counts=counts, workers=s.workers,
                     overwrite=True)
    return {"counts": counts, "n_objects": sum(counts.values())}


def _gallery(s: RunSettings) -> dict:
    from ..objects.dataset import load_manifest
    from ..objects.gallery import render_gallery
    render_gallery(load_manifest(s.out / "dataset"), s.out / "figures" / "objects.png")
    return {"png": "figures/objects.png"}


def _collect(s: RunSettings) -> dict:
    from .collect import collect
    cfg = s.cfg
    report = _collected(collect(s.out / "dataset", s.out / "wraps", cfg, workers=s.workers,
                                scheduler=schedule.where(s)))
    if report.failed:  # the step is not done: a rerun retries these objects
        oid, message = next(iter(report.failed.items()))
        raise InputError(f"collect: {len(report.failed)} object(s) failed, e.g. {oid}: "
                         f"{message}; rerun to retry them")
    return _as_dict(report)


def _wrap_figure(s: RunSettings) -> dict:
    """The paper's Fig. 5: two completed wraps a category (of two objects where it has them),
    each its object's most conforming one, titled with how much of it lies near the surface."""
    import trimesh

    from ..learning.records import read_object_wraps
    from ..objects.dataset import load_manifest
    from ..viz.plots import plot_wraps_grid, wrap_cell
    arm = s.cfg.arm()
    dataset = load_manifest(s.out / "dataset")
    items = []
    for category in dataset.categories:
        shown = 0
        for entry in dataset.by_category(category):
            try:
                _, wraps = read_object_wraps(s.out / "wraps", entry.id)
            except (OSError, ValueError):
                continue
            done = [w for w in wraps if w.status == WrapStatus.COMPLETE and w.usable]
            if done:
                w = max(done, key=lambda w: (w.conformity, len(w.contacts)))
                items.append(wrap_cell(trimesh.load(entry.path, force="mesh"), arm, w,
                                       title=f"{entry.id}: {w.conformity:.0%} near"))
                shown += 1
                if shown == 2:
                    break
    if items:
        plot_wraps_grid(items, s.out / "figures" / "wraps.png", ncols=4)
    return {"png": "figures/wraps.png" if items else None, "n": len(items)}


def _classification(s: RunSettings) -> dict:
    from ..learning.evaluation import evaluate_to_folder
    from ..learning.records import load_collection
    objects, skipped = load_collection(s.out / "wraps", s.cfg.chords)
    for item in skipped:
        log.warning("object %s left out: %s", item["object_id"], item["reason"])
    return evaluate_to_folder(objects, s.out / "classification", n_splits=s.effective_splits,
                              seed=s.seed, params=s.cfg.classifier, skipped=skipped)


def _active(s: RunSettings) -> dict:
    from ..active.training import evaluate_active
    cfg = s.cfg
    report = evaluate_active(s.out / "wraps", params=replace(cfg.active, seed=s.seed),
                             seed=s.seed, chords=cfg.chords, classifier=cfg.classifier,
                             out=s.out / "active", workers=s.workers)
    policies = {name: {k: v for k, v in r.items() if k != "runs"}
                for name, r in report["policies"].items()}
    return {"policies": policies, "n_train": report["n_train"],
            "n_test": report["n_test"]}


def _real(s: RunSettings) -> dict:
    """Fig. 8 on the clouds shipped in real/data, with a model trained on every object so
    that the real and the simulated wrap each get a category."""
    import warnings

    from ..learning.model import train
    from ..learning.records import WrapDataWarning, load_wraps
    from ..perception.comparison import compare_shipped_clouds
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", WrapDataWarning)
        model = train(load_wraps(s.out / "wraps", s.cfg.chords), s.cfg, seed=s.seed)
    # The fits and figures no model changes are kept by a redo of the step.
    return compare_shipped_clouds(s.out / "real", model, cache=s.out / "real_cache")


def _train_kinds(s: RunSettings) -> tuple:
    from ..objects.placement_kinds import TRAINING_KINDS, parse_counts
    counts = parse_counts(s.placements)
    return ("generated",) + tuple(k for k in TRAINING_KINDS if counts.get(k))


def held_out_kinds(placements: str) -> tuple:
    """The placed kinds active recognition tests on the held-out objects: turned, rest,
    lying and nudged copies, and without `rest` copies their `side` copies, which lie on
    the likeliest other side as a `rest` copy does (QUICK_PLACEMENTS)."""
    from ..objects.placement_kinds import parse_counts
    kinds = ("turned", "rest", "lying", "nudged")
    return kinds if parse_counts(placements).get("rest") else kinds + ("side",)


def _placed_collection(s: RunSettings, root: Path, seed: int, *, where) -> tuple:
    """Place root/dataset's objects (seed) and collect their wraps on `where`
    (schedule.where):
    (the collection's CollectReport, the CPU seconds placing took in this thread)."""
    from ..objects.placement import parse_counts, place_dataset
    from .collect import collect
    c0 = time.thread_time()
    place_dataset(root / "dataset", root / "placed", parse_counts(s.placements), seed=seed,
                  limit_per_category=s.effective_placed_per_category, progress=False,
                  overwrite=True)
    placing_s = time.thread_time() - c0
    return (collect(root / "placed", root / "placed_wraps", s.cfg, workers=s.workers,
                    scheduler=where, progress=False, prune=True), placing_s)


def _placed_evaluation(s: RunSettings, root: Path, seed: int) -> dict:
    """Place root/dataset's objects (seed), collect their wraps (or take the collection run
    ahead: _start_ahead), and evaluate chords and triangles on them beside the originals
    (root/wraps), splits by object: root/placements/."""
    import warnings

    from ..files import write_atomic, write_json
    from ..learning.placements import evaluate_placements, placements_table
    from ..learning.records import WrapDataWarning, load_wraps
    cfg = s.cfg
    taken, ahead_s = schedule.take_timed("placements" if root == s.out else "second_placed")
    report, placing_s = (taken if taken is not None
                         else _placed_collection(s, root, seed, where=schedule.where(s)))
    _collected(report, ahead_s, placing_s)  # the copies' meshes: made ahead, or here
    if report.pruned:
        log.info("placements: %d stored copies no longer placed so were removed (%s ...)",
                 len(report.pruned), ", ".join(report.pruned[:3]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", WrapDataWarning)
        records = (load_wraps(root / "wraps", cfg.chords)
                   + load_wraps(root / "placed_wraps", cfg.chords))
    kinds = _train_kinds(s)
    results = {"chords": evaluate_placements(records, s.effective_splits, s.seed, method="chords",
                                             params=cfg.classifier, train_kinds=kinds,
                                             progress=False),
               "triangles": evaluate_placements(records, s.effective_splits, s.seed,
                                                method="triangles", params=cfg.classifier,
                                                train_kinds=kinds, progress=False)}
    out = root / "placements"
    write_atomic(out / "placements.md", placements_table(results).encode())
    write_json(out / "placements.json", results)
    brief = {m: {"kinds": {k: {q: v[q] for q in ("accuracy_mean", "accuracy_std",
                                                 "n_records")}
                           for k, v in r["kinds"].items()},
                 "flips": r["flips"]} for m, r in results.items()}
    return {"results": brief, "train_kinds": list(kinds), "table": "placements/placements.md",
            "collect": {k: v for k, v in report.to_dict().items() if k != "failed"},
            "records": records}


def _placements(s: RunSettings) -> dict:
    """Placed copies of the dataset, their accuracy, and the models this run recommends:
    OUT/model (classify) and OUT/active-model (recognize), trained on every object and its
    training placements."""
    from ..active.training import save_active_model, train_active
    from ..learning.model import save_model, train
    from ..objects.placement_kinds import placement_kind
    cfg = s.cfg
    figures = _placed_evaluation(s, s.out, s.seed)
    records = figures.pop("records")
    kinds = set(figures["train_kinds"])
    chosen = [r for r in records if placement_kind(r.object_id) in kinds]
    settings = training_settings(cfg, s.out / "wraps")  # classify/recognize wrap as these
    model = train(chosen, cfg, seed=s.seed)
    model.info["settings"] = settings
    save_model(model, s.out / "model")
    active = train_active(s.out / "wraps", params=replace(cfg.active, seed=s.seed),
                          seed=s.seed, chords=cfg.chords, records=chosen,
                          classifier=cfg.classifier)
    active.classifier.info["settings"] = settings
    save_active_model(active, s.out / "active-model")
    figures["model"] = "model"
    figures["active_model"] = "active-model"
    figures["n_trained"] = len(chosen)
    return figures


def _active_placed(s: RunSettings) -> dict:
    """Active recognition of the held-out objects' placed copies (turned, other side,
    nudged), trained as the recommended active model is. Without `rest` copies the held-out
    objects' `side` copies stand for the other side (QUICK_PLACEMENTS)."""
    from ..active.training import evaluate_active
    cfg = s.cfg
    report = evaluate_active(s.out / "wraps", params=replace(cfg.active, seed=s.seed),
                             seed=s.seed, chords=cfg.chords, classifier=cfg.classifier,
                             out=s.out / "active_placed", placed=[s.out / "placed_wraps"],
                             train_kinds=_train_kinds(s),
                             test_kinds=held_out_kinds(s.placements), workers=s.workers)
    policies = {name: {k: v for k, v in r.items() if k != "runs"}
                for name, r in report["policies"].items()}
    return {"policies": policies, "n_train": report["n_train"], "n_test": report["n_test"]}


def _second_originals(s: RunSettings, where, before=None):
    """Generate the second dataset (seed + 1) and collect its originals on `where`, after
    the collection `before` (an Ahead) when one is given: the CollectReport, whose work
    includes generating ("dataset")."""
    from ..objects.dataset import generate_dataset
    from .collect import collect
    root = s.out / "second"
    # In one process when run ahead (a thread beside this process's steps must not fork):
    # the same objects whatever the number of workers. Its CPU time: its thread's when
    # run ahead, else the step's.
    clock = time.thread_time if isinstance(threading.current_thread(), schedule.Ahead) else _clock
    c0 = clock()
    generate_dataset(root / "dataset", seed=s.seed + 1, counts=_dataset_counts(s),
                     workers=1 if before is not None else s.workers, progress=False,
                     overwrite=True)
    generating_s = clock() - c0
    if before is not None:
        before.join()
        schedule.still_running()
    report = collect(root / "dataset", root / "wraps", s.cfg, workers=s.workers,
                     scheduler=where, progress=False)
    report.work_s.add({"dataset": generating_s})
    return report


def _second_copies(s: RunSettings, where, originals) -> tuple:
    """The second dataset's _placed_collection on `where`, once its originals (an Ahead)
    are collected."""
    originals.join()
    schedule.still_running()
    return _placed_collection(s, s.out / "second", s.seed + 1, where=where)


def _second(s: RunSettings) -> dict:
    """A second generated dataset (seed + 1, never used to choose a setting): its wraps,
    the classification of its originals and of its placed copies."""
    if not s.second_dataset:
        return {"skipped": True}
    import warnings

    from ..learning.evaluation import evaluate_to_folder
    from ..learning.records import WrapDataWarning, load_wraps
    cfg = s.cfg
    root = s.out / "second"
    seed = s.seed + 1
    report, ahead_s = schedule.take_timed("second")
    if report is None:
        report = _second_originals(s, schedule.where(s))
    _collected(report, ahead_s)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", WrapDataWarning)
        objects = load_wraps(root / "wraps", cfg.chords)
    cls = evaluate_to_folder(objects, root / "classification", n_splits=s.effective_splits,
                             seed=seed, params=cfg.classifier)
    figures = _placed_evaluation(s, root, seed)
    figures.pop("records")
    figures["seed"] = seed
    figures["classification"] = {k: cls[k] for k in ("accuracy_mean", "accuracy_std",
                                                     "baseline_accuracy_mean",
                                                     "baseline_accuracy_std", "n_objects",
                                                     "n_splits")}
    figures["table"] = "second/placements/placements.md"
    return figures


def _observed_options(s: RunSettings) -> dict:
    """observed_study's collection, objects, seed, chords and cache of this run."""
    per_category, categories = QUICK_OBSERVED if s.quick else OBSERVED
    return {"wraps": s.out / "wraps", "out": s.out / "observed",
            "per_category": per_category, "categories": categories,
            "seed": s.seed, "chords": replace(s.cfg.chords, frame=s.cfg.observed.frame),
            "cache": s.out / "observed_cache"}  # kept by a redo of the step


def _observed(s: RunSettings) -> dict:
    """Recognition from what the camera sees of the arm (experiments/observed.py), its chords
    in the frame and its classifiers with the tie width of the config's `observed` section
    (all four rows alike); the fits queued as collect ended are taken."""
    from .observed import observed_study
    if not s.observed:
        return {"skipped": True}
    cfg = s.cfg
    submitted, timing = schedule.take("observed"), {}
    result = observed_study(n_splits=s.effective_splits,
                            classifier=replace(cfg.classifier,
                                               tie_width=cfg.observed.tie_width),
                            active=replace(cfg.active, seed=s.seed), workers=s.workers,
                            pool=schedule.run_pool(s), submitted=submitted, timing=timing,
                            **_observed_options(s))
    # Fitted on the run's workers: their CPU time is the camera's work
    _WORK.add({"camera": timing.get("observing_s", 0.0)})
    return {k: result[k] for k in ("conditions", "active", "n_objects", "n_collection",
                                   "n_splits", "frame", "confusion_one_view")}


def _as_dict(obj) -> dict:
    if isinstance(obj, dict):
        return obj
    if hasattr(obj, "to_dict"):
        return obj.to_dict()
    return {k: v for k, v in vars(obj).items() if not k.startswith("_")}


STEPS = ("dataset", "gallery", "collect", "wrap_figure", "classification", "active", "real",
         "placements", "active_placed", "second", "observed")
# The settings each step reads (settings.json keys, dotted); a step also reads the outputs of
# the steps before it that it names in STEP_AFTER.
_DATASET = ("quick", "per_category", "categories", "seed")
STEP_INPUTS = {
    "dataset": _DATASET, "gallery": _DATASET,
    "collect": _DATASET + ("config.arm", "config.planes", "config.wrap"),
    "wrap_figure": _DATASET + ("config.arm", "config.planes", "config.wrap"),
    "classification": ("splits", "config.chords", "config.classifier"),
    "active": ("config.chords", "config.classifier", "config.active"),
    "real": ("config.chords", "config.classifier"),
    "placements": _DATASET + ("splits", "placements", "placed_per_category", "config.arm",
                              "config.planes", "config.wrap", "config.chords",
                              "config.classifier",
                              "config.active.neighbours"),  # all the active model reads
    "active_placed": ("placements", "placed_per_category", "config.chords",
                      "config.classifier", "config.active"),
    "second": _DATASET + ("splits", "placements", "placed_per_category", "second_dataset",
                          "config.arm", "config.planes", "config.wrap", "config.chords",
                          "config.classifier"),
    "observed": ("splits", "observed", "config.chords", "config.classifier",
                 "config.active", "config.observed"),
}
# The order this process runs them in: the camera study, whose fits the pool makes first
# (schedule.py), before the second dataset, whose copies it wraps last.
_RUN_ORDER = ("dataset", "gallery", "collect", "wrap_figure", "classification", "active",
              "real", "placements", "active_placed", "observed", "second")
STEP_AFTER = {"gallery": ("dataset",), "collect": ("dataset",), "wrap_figure": ("collect",),
              "classification": ("collect",), "active": ("collect",), "real": ("collect",),
              "placements": ("collect",), "active_placed": ("placements",),
              "observed": ("collect",)}
# The folders (under OUT) a step writes, removed when it is redone.
STEP_OUTPUTS = {"dataset": ("dataset",), "collect": ("wraps",),
                "classification": ("classification",), "active": ("active",), "real": ("real",),
                "placements": ("placements", "model", "active-model"),
                "active_placed": ("active_placed",),
                "second": ("second/classification", "second/placements"),
                "observed": ("observed",)}
# The meshes and wrap collections a step makes, and the settings that make all their wraps:
# a redo removes them only when one of those changed. Otherwise the step writes the meshes
# again and `collect` resumes the wraps, so a classifier setting does not re-wrap a
# thousand placed copies (27 minutes of the full run). Other placement counts keep every
# copy drawn as before byte for byte: collect's prune drops the rest, and only the new
# copies are wrapped.
_WRAPS = _DATASET + ("config.arm", "config.planes", "config.wrap")
STEP_WRAPS = {"placements": (("placed", "placed_wraps"), _WRAPS),
              "second": (("second/dataset", "second/wraps", "second/placed",
                          "second/placed_wraps"), _WRAPS + ("second_dataset",))}


def _reads(changed_keys, inputs) -> bool:
    """Whether settings keys (dotted) `inputs` include or lie inside a changed key."""
    return any(k == i or k.startswith(i + ".") or i.startswith(k + ".")
               for k in changed_keys for i in inputs)


def steps_to_redo(changed_keys) -> list[str]:
    """The steps a change of these settings keys (dotted) invalidates, in order."""
    redo = []
    for step in STEPS:
        if _reads(changed_keys, STEP_INPUTS[step]) or any(s in redo for s in
                                                          STEP_AFTER.get(step, ())):
            redo.append(step)
    return redo


def outputs_to_remove(step: str, changed_keys) -> tuple:
    """The folders a redo of `step` removes for these changed keys: its outputs, and its
    meshes and wraps when a setting that makes them changed (STEP_WRAPS)."""
    folders, inputs = STEP_WRAPS.get(step, ((), ()))
    return STEP_OUTPUTS.get(step, ()) + (folders if _reads(changed_keys, inputs) else ())


def _pooled_steps(s: RunSettings) -> tuple:
    """The steps worth starting the run's pool for: its collections and the camera study."""
    return (("collect", "placements") + (("second",) if s.second_dataset else ())
            + (("observed",) if s.observed else ()))


def _check_settings(out: Path, now: dict, redo: bool) -> None:
    """Refuse a folder made with other settings, naming them; with `redo`, remove what they
    invalidate (markers and outputs of those steps)."""
    import shutil

    stamp = out / "settings.json"
    if not stamp.exists():
        return
    try:
        before = json.loads(stamp.read_text())
    except ValueError:
        before = {}
    if isinstance(before.get("config"), dict):  # a section recorded before it existed
        before["config"] = {**config_to_tree(Config()), **before["config"]}  # its defaults
    differ = tree_difference(before, now)
    if not differ:
        return
    keys = [d.split(" ", 1)[0] for d in differ]
    if not redo:
        raise ConfigError(f"{out} holds a run made with other settings: {'; '.join(differ)}. "
                          f"Choose another --out, or add --redo to redo the steps they "
                          f"change ({', '.join(steps_to_redo(keys))})")
    for step in steps_to_redo(keys):
        log.info("%s: settings changed (%s), redone", step, ", ".join(keys))
        _marker(out, step).unlink(missing_ok=True)
        for folder in outputs_to_remove(step, keys):
            if (out / folder).is_dir():
                shutil.rmtree(out / folder)


def reproduce(settings: RunSettings) -> Path:
    """Run every step (skipping finished ones) and write report.md and report.html."""
    out = writable_folder(settings.out)
    (out / "figures").mkdir(exist_ok=True)
    runs = {"dataset": _dataset, "gallery": _gallery, "collect": _collect,
            "wrap_figure": _wrap_figure, "classification": _classification,
            "active": _active, "real": _real, "placements": _placements,
            "active_placed": _active_placed, "second": _second, "observed": _observed}
    settings_json = settings_record(settings)
    _check_settings(out, settings_json, settings.redo)
    write_json(out / "settings.json", settings_json, indent=1)
    with ExitStack() as stack:  # the run's worker pool ends with the run (schedule.where)
        stack.callback(schedule.end)  # after the pool (entered later, so closed first)
        schedule.POOL.update(stack=stack, pool=None)
        try:
            if any(not _marker(out, step).exists() for step in _pooled_steps(settings)):
                schedule.warm(settings)
            figures = {}
            for step in _RUN_ORDER:
                if step == "collect":
                    _start_ahead(settings)
                figures[step] = _step(out, step, lambda step=step: runs[step](settings))
                if step == "collect":
                    _queue_observations(settings)
        finally:
            schedule.POOL.clear()
    figures = {step: figures[step] for step in STEPS}
    from .report import write_report
    from .results import write_results
    report = write_report(out, figures, settings_json)
    write_results(out, figures, settings_json, dest=settings.results_md)
    return report
