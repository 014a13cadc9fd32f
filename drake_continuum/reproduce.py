"""One command reproduces the paper: dataset, wraps, Table I, Fig. 5, 7 and 8, Table II, and
a report (Markdown and HTML) with the paper's numbers beside ours.

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
import time
from dataclasses import dataclass
from pathlib import Path

from .config import Config, config_to_tree, load_config, tree_difference
from .errors import ConfigError, InputError
from .files import write_json, writable_folder

__all__ = ["PAPER", "RunSettings", "STEPS", "STEP_INPUTS", "STEP_AFTER", "STEP_OUTPUTS",
           "steps_to_redo", "reproduce"]

log = logging.getLogger(__name__)

PAPER = {
    "accuracy": 0.759, "baseline_accuracy": 0.747,
    "table1": {  # category: (mean chords, mean wraps, ms a wrap), paper Table I (C++)
        "apple": (2676, 10, 400), "banana": (1816, 9.7, 190), "bottle": (1760, 10, 130),
        "bowl": (2090, 9.6, 230), "cup": (2317, 10, 540), "donut": (1365, 5.1, 200),
        "hammer": (1711, 10, 110), "mug": (2557, 10, 530), "teapot": (2350, 9.8, 1200),
        "toilet_paper": (2944, 10, 260)},
}


@dataclass(frozen=True)
class RunSettings:
    """What a reproduction runs.

    Args:
        out: results folder.
        quick: a subset for a first look (per_category objects a category, fewer splits).
        per_category: objects a category in quick mode.
        splits: random 50/50 splits for classification.
        workers: local processes for wrapping (None: all cores).
        scheduler: Dask scheduler address for wrapping, or None.
        seed: seed of the dataset, the splits and the tree search.
        config: the experiment's parameters (default: models/config.yaml).
        redo: with other settings than the folder's run, redo the steps they change
            (default: refuse).
    """

    out: Path = Path("results")
    quick: bool = False
    per_category: int = 4
    splits: int = 100
    workers: int | None = None
    scheduler: str | None = None
    seed: int = 0
    config: Config | None = None
    redo: bool = False

    @property
    def cfg(self) -> Config:
        return self.config if self.config is not None else load_config()

    @property
    def effective_splits(self) -> int:
        return min(self.splits, 20) if self.quick else self.splits


def _marker(out: Path, step: str) -> Path:
    return out / f"{step}.done.json"


def _step(out: Path, step: str, run):
    """Run a step unless its marker exists; return its recorded figures."""
    marker = _marker(out, step)
    if marker.exists():
        log.info("%s: done in an earlier run, skipped (%s)", step, marker)
        return json.loads(marker.read_text())
    log.info("%s ...", step)
    t0 = time.perf_counter()
    figures = run()
    figures["time_s"] = time.perf_counter() - t0
    write_json(marker, figures)
    log.info("%s: %.1f s", step, figures["time_s"])
    return figures


def _dataset(s: RunSettings) -> dict:
    from .objects.dataset import generate_dataset
    from .objects.generators import CATEGORY_COUNTS
    counts = ({c: min(n, s.per_category) for c, n in CATEGORY_COUNTS.items()} if s.quick
              else dict(CATEGORY_COUNTS))
    generate_dataset(s.out / "dataset", seed=s.seed, counts=counts, workers=s.workers)
    return {"counts": counts, "n_objects": sum(counts.values())}


def _gallery(s: RunSettings) -> dict:
    from .objects.dataset import load_manifest
    from .objects.gallery import render_gallery
    render_gallery(load_manifest(s.out / "dataset"), s.out / "figures" / "objects.png")
    return {"png": "figures/objects.png"}


def _collect(s: RunSettings) -> dict:
    from .collect import collect
    cfg = s.cfg
    report = collect(s.out / "dataset", s.out / "wraps", workers=s.workers,
                     scheduler=s.scheduler, params=cfg.wrap, alpha_deg=cfg.alpha_deg,
                     arm_yaml=cfg.arm_yaml, both_directions=cfg.both_directions)
    if report.failed:  # the step is not done: a rerun retries these objects
        oid, message = next(iter(report.failed.items()))
        raise InputError(f"collect: {len(report.failed)} object(s) failed, e.g. {oid}: "
                         f"{message}; rerun to retry them")
    return _as_dict(report)


def _wrap_figure(s: RunSettings) -> dict:
    """The paper's Fig. 5: two completed wraps a category (of two objects where it has them),
    each its object's most conforming one, titled with how much of it lies near the surface."""
    import trimesh

    from .classify import read_object_wraps
    from .objects.dataset import load_manifest
    from .viz import plot_wraps_grid, wrap_cell
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
            done = [w for w in wraps if w.status == "complete" and w.usable]
            if done:
                w = max(done, key=lambda w: (w.conformity, len(w.contacts)))
                items.append(wrap_cell(trimesh.load(entry.path, force="mesh"), arm, w,
                                       f"{entry.id}: {w.conformity:.0%} near"))
                shown += 1
                if shown == 2:
                    break
    if items:
        plot_wraps_grid(items, s.out / "figures" / "wraps.png", ncols=4)
    return {"png": "figures/wraps.png" if items else None, "n": len(items)}


def _classification(s: RunSettings) -> dict:
    from .classify import evaluate_to_folder, load_collection
    objects, skipped = load_collection(s.out / "wraps", s.cfg.chords)
    for item in skipped:
        log.warning("object %s left out: %s", item["object_id"], item["reason"])
    return evaluate_to_folder(objects, s.out / "classification", s.effective_splits, s.seed,
                              s.cfg.classifier, skipped)


def _active(s: RunSettings) -> dict:
    from dataclasses import replace

    from .active import evaluate_active
    cfg = s.cfg
    report = evaluate_active(s.out / "wraps", params=replace(cfg.active, seed=s.seed),
                             seed=s.seed, chords=cfg.chords, classifier=cfg.classifier,
                             out=s.out / "active")
    policies = {name: {k: v for k, v in r.items() if k != "runs"}
                for name, r in report["policies"].items()}
    return {"policies": policies, "n_train": report["n_train"],
            "n_test": report["n_test"]}


def _real(s: RunSettings) -> dict:
    """Fig. 8 on the clouds shipped in real/data, with a model trained on every object so
    that the real and the simulated wrap each get a category."""
    import warnings

    from .classify import WrapDataWarning, load_wraps, train
    from .pointcloud import compare_shipped_clouds
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", WrapDataWarning)
        model = train(load_wraps(s.out / "wraps", s.cfg.chords), seed=s.seed,
                      params=s.cfg.chords, classifier=s.cfg.classifier)
    return compare_shipped_clouds(s.out / "real", model)


def _as_dict(obj) -> dict:
    if isinstance(obj, dict):
        return obj
    if hasattr(obj, "to_dict"):
        return obj.to_dict()
    return {k: v for k, v in vars(obj).items() if not k.startswith("_")}


STEPS = ("dataset", "gallery", "collect", "wrap_figure", "classification", "active", "real")
# The settings each step reads (settings.json keys, dotted); a step also reads the outputs of
# the steps before it that it names in STEP_AFTER.
_DATASET = ("quick", "per_category", "seed")
STEP_INPUTS = {
    "dataset": _DATASET, "gallery": _DATASET,
    "collect": _DATASET + ("config.arm", "config.planes", "config.wrap"),
    "wrap_figure": _DATASET + ("config.arm", "config.planes", "config.wrap"),
    "classification": ("splits", "config.chords", "config.classifier"),
    "active": ("config.chords", "config.classifier", "config.active"),
    "real": ("config.chords", "config.classifier"),
}
STEP_AFTER = {"gallery": ("dataset",), "collect": ("dataset",), "wrap_figure": ("collect",),
              "classification": ("collect",), "active": ("collect",), "real": ("collect",)}
STEP_OUTPUTS = {"dataset": "dataset", "collect": "wraps", "classification": "classification",
                "active": "active", "real": "real"}


def steps_to_redo(changed_keys) -> list[str]:
    """The steps a change of these settings keys (dotted) invalidates, in order."""
    redo = []
    for step in STEPS:
        reads = any(k == i or k.startswith(i + ".") or i.startswith(k + ".")
                    for k in changed_keys for i in STEP_INPUTS[step])
        if reads or any(s in redo for s in STEP_AFTER.get(step, ())):
            redo.append(step)
    return redo


def _settings(settings: RunSettings) -> dict:
    return {"quick": settings.quick, "per_category": settings.per_category,
            "splits": settings.effective_splits, "seed": settings.seed,
            "config": config_to_tree(settings.cfg)}


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
        if step in STEP_OUTPUTS and (out / STEP_OUTPUTS[step]).is_dir():
            shutil.rmtree(out / STEP_OUTPUTS[step])


def reproduce(settings: RunSettings) -> Path:
    """Run every step (skipping finished ones) and write report.md and report.html."""
    out = writable_folder(settings.out)
    (out / "figures").mkdir(exist_ok=True)
    runs = {"dataset": _dataset, "gallery": _gallery, "collect": _collect,
            "wrap_figure": _wrap_figure, "classification": _classification,
            "active": _active, "real": _real}
    settings_json = _settings(settings)
    _check_settings(out, settings_json, settings.redo)
    write_json(out / "settings.json", settings_json, indent=1)
    figures = {step: _step(out, step, lambda step=step: runs[step](settings)) for step in STEPS}
    from .report import write_report
    return write_report(out, figures, settings_json)
