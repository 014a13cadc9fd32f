"""Active recognition on wrap collections: training (classifier and observation model),
saving and loading the model, evaluating the policies, Table II.
"""

from __future__ import annotations

import time
from dataclasses import fields, replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..config import Config
from ..errors import InputError
from ..files import write_atomic, write_json
from ..markdown import markdown_table
from .observation import ActiveModel, load_observation_model, save_observation_model
from .params import ActiveParams, ObjectWraps
from .policies import (
    POLICIES,
    build_active_model,
    evaluate_policies,
    plot_policy_curves,
    recognition,
    run_policies,
)

__all__ = ["table_ii", "table_ii_markdown", "PAPER_TABLE_II", "object_wraps_from_records",
           "collection_plane_normals", "save_active_model", "load_active_model", "train_active",
           "evaluate_active"]


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
        view = np.asarray(getattr(r, "view", np.full(3, np.nan)), dtype=float)
        out.append(ObjectWraps(str(r.object_id), str(r.category), wraps,
                               None if np.isnan(view).any() else view))
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
    """The classifier (learning.model.save_model: model.json/.npz) and the observation model
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
    at stop (measured: BENCHMARKS.md, Decisions). It keeps the camera's view
    (classifier.view_weight), which is known before the first wrap."""

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
    clf = train(records, Config(chords=chords, classifier=chords_only), seed=seed)
    return build_active_model(clf, object_wraps_from_records(records), normals, params=params)


def evaluate_active(folder, *, policies: Sequence[str] = POLICIES,
                    params: ActiveParams = ActiveParams(), seed: int = 0, frame: str = "world",
                    out=None, chords=None, classifier=None, placed=(),
                    train_kinds=("generated",), test_kinds=("turned", "rest", "lying", "nudged"),
                    test=(), workers: int | None = 1) -> dict:
    """Train on one half of a stratified split of a wrap collection, run each policy on the
    held-out half; with `out`, write active.json, curves.png and table2.md there. `chords`
    and `classifier` as train_active's. Objects of the collection left out
    (learning.records.load_collection) are listed under "skipped".

    With `placed` (wrap collections of placed copies, objects/placement.py) the split is by
    object over originals and copies together; training takes the training half's records
    of `train_kinds` and the held-out half is tested on its copies of `test_kinds` (each
    policy's "by_kind" has the accuracy at stop of each).

    With `test` (wrap collections of another dataset, e.g. another seed's originals and
    placed copies) the held-out half is not tested: every record of `test` is, of the kinds
    `test_kinds` and "generated" (objects never trained on, as learning.placements'
    test_objects).

    The recognition runs go over `workers` processes (None: all cores; 1: this process),
    with the same results (evaluate_policies)."""
    from ..features.chords import ChordParams
    from ..learning.evaluation import object_groups, splits
    from ..learning.records import load_collection
    from ..objects.placement_kinds import placement_kind

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
    if test:
        n_pool = len(records)
        for extra in test:
            more, also = load_collection(extra, chords)
            records += more
            skipped += also
        test_idx = np.array([i for i in range(n_pool, len(records))
                             if placement_kind(records[i].object_id)
                             in ("generated",) + tuple(test_kinds)], np.int64)
    t0 = time.perf_counter()
    model = train_active(folder, params=params, seed=seed, records=records,
                         train_index=train_idx, chords=chords, classifier=classifier)
    tested = [object_wraps_from_records([records[i]])[0] for i in test_idx]
    results = evaluate_policies(model, tested, policies=policies, params=params, seed=seed,
                                workers=workers)
    if placed or test:
        for r in results.values():
            by = {}
            for run in r["runs"]:
                by.setdefault(placement_kind(run["object"]), []).append(run["correct_at_stop"])
            r["by_kind"] = {k: float(np.mean(v)) for k, v in sorted(by.items())}
    rows = table_ii(model, tested, params=params, seed=seed, workers=workers)
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
             categories: Sequence[str] | None = None, params: ActiveParams | None = None,
             seed: int = 0, workers: int | None = 1) -> dict:
    """Table II: one held-out object a category, all iterations run (no early stop).

    The object of each category is the first held-out one by name; categories without one
    are skipped. Default categories: the paper's five of Table II that the held-out objects
    hold, or every label they hold when they hold none of those (a dataset of one's own).
    The objects are recognised over `workers` processes (run_policies).
    """
    from ..config import load_config

    params = load_config().active if params is None else params
    if categories is None:
        labels = sorted({o.label for o in test_objects})
        categories = [c for c in PAPER_TABLE_II if c in labels] or labels
    firsts = {c: min((o for o in test_objects if o.label == c), key=lambda o: o.name)
              for c in categories if any(o.label == c for o in test_objects)}
    if getattr(model.classifier, "uses_view", False) and any(
            o.view is None for o in firsts.values()):
        raise InputError("this active model classifies with the depth camera's view of the "
                         "object: Table II's objects need their view")
    runs = run_policies(model, [(o, "mcts", seed, False) for o in firsts.values()],
                        params=params, workers=workers)
    classes = model.observations.classes
    return {c: {"object": o.name, **recognition(tr, classes).to_dict()}
            for tr, (c, o) in zip(runs, firsts.items())}


def table_ii_markdown(rows: Mapping[str, dict]) -> str:
    """Our Table II next to the paper's, one row a category and iteration."""
    def fmt(top):
        return "<br>".join(f"{c} {p:.2f}" for c, p in top)

    def cells(c, r):
        paper = PAPER_TABLE_II.get(c, [])
        for k, it in enumerate(r["iterations"]):
            p_top, p_n = paper[k] if k < len(paper) else ([], "")
            yield [f"{c} ({r['object']})", k + 1, fmt(it["top3"]), it["n_wraps"], fmt(p_top), p_n]

    lines = markdown_table(["object", "iteration", "ours: top-3", "ours: # wraps",
                            "paper: top-3", "paper: # wraps"],
                           [row for c, r in rows.items() for row in cells(c, r)])
    if not rows:
        lines.append("\nNo held-out object.")
    return "\n".join(lines) + "\n"


