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
           "wrap_contact_points", "partial_records",
           "collection_plane_normals", "save_active_model", "load_active_model", "train_active",
           "evaluate_active"]


# The active model's partial rows (train_active): random subsets of 1, 2 and 3 of a
# training object's wraps, 3 of each size, as recognition sees an object at its stops
# (2.4-3.2 wraps on average), and the weight of its contact extent block (the all-wraps
# classifier's classifier.extent_weight is 0.8; measured: BENCHMARKS.md, Point clouds).
PARTIAL_SIZES = (1, 2, 3)
PARTIAL_PER_SIZE = 3
ACTIVE_EXTENT_WEIGHT = 1.6
# What recognition assumes of an object's category before its first wrap (train_active):
# "training", the training objects' frequencies (a bottle is 51 of the paper's 185 objects, a
# cup 10), right for objects drawn as the training ones were (the paper's splits); or
# "uniform", every category alike, right for a test of N objects a category (measured:
# BENCHMARKS.md, Point clouds).
CLASS_PRIORS = ("training", "uniform")

# --------------------------------------------------------------------------- wrap collections

def object_wraps_from_records(records) -> list[ObjectWraps]:
    """classify.ObjectRecord (load_wraps) -> ObjectWraps: each usable wrap's chords and
    contact centres by plane (the first wrap of a plane if a collection wrapped one twice)."""
    out = []
    for r in records:
        wraps, contacts = {}, {}
        points = wrap_contact_points(r)
        for k, plane in enumerate(np.asarray(r.plane_index)):
            chords = r.chords.values[r.chords.wrap == k]
            if r.usable[k] and len(chords) and int(plane) not in wraps:
                wraps[int(plane)] = chords
                if points is not None:
                    contacts[int(plane)] = points[k]
        view = np.asarray(getattr(r, "view", np.full(3, np.nan)), dtype=float)
        out.append(ObjectWraps(str(r.object_id), str(r.category), wraps,
                               None if np.isnan(view).any() else view, contacts))
    return out


def wrap_contact_points(record) -> list | None:
    """(m_k, 3) contact centres of each wrap of an ObjectRecord (empty for unusable wraps),
    split from its contact_points by each usable wrap's contact regions (one centre a
    region); None when the record does not tell them apart (no regions recorded)."""
    usable = np.asarray(record.usable, dtype=bool)
    regions = np.asarray(record.contact_regions, dtype=np.int64)
    points = np.asarray(record.contact_points, dtype=float).reshape(-1, 3)
    if len(regions) != len(usable) or (not len(regions) and len(points)):
        return None
    counts = np.where(usable, regions, 0)
    if counts.sum() != len(points):
        raise InputError(f"object {record.object_id}: {len(points)} contact centres against "
                         f"{int(counts.sum())} contact regions of its usable wraps")
    return np.split(points, np.cumsum(counts)[:-1])


def partial_records(records, *, sizes: Sequence[int] = PARTIAL_SIZES,
                    per_size: int = PARTIAL_PER_SIZE, seed: int = 0) -> list:
    """Each record again with only some of its usable wraps (chords and contact centres), as
    active recognition sees an object after its first wraps: for each size k in `sizes`
    under the record's usable wraps, `per_size` distinct random subsets of k wraps (all of
    them if there are fewer). A record whose contacts are not told apart by wrap
    (wrap_contact_points None) gives none."""
    rng = np.random.default_rng(seed)
    out = []
    for r in records:
        points = wrap_contact_points(r)
        usable = np.flatnonzero(np.asarray(r.usable, dtype=bool))
        if points is None:
            continue
        for k in sizes:
            if not 0 < k < len(usable):
                continue
            for combo in _subsets(len(usable), k, count=per_size, rng=rng):
                keep = np.zeros(len(r.usable), bool)
                keep[usable[list(combo)]] = True
                out.append(replace(
                    r, chords=type(r.chords)(r.chords.values[keep[r.chords.wrap]],
                                             r.chords.wrap[keep[r.chords.wrap]]),
                    contact_points=np.concatenate([points[j] for j in np.flatnonzero(keep)]),
                    usable=keep))
    return out


def _subsets(n: int, k: int, *, count: int, rng: np.random.Generator) -> list[tuple]:
    """`count` distinct k-subsets of range(n) drawn at random (all if there are fewer)."""
    from itertools import combinations
    from math import comb

    if comb(n, k) <= count:
        return list(combinations(range(n), k))
    seen = set()
    while len(seen) < count:
        seen.add(tuple(sorted(rng.choice(n, size=k, replace=False).tolist())))
    return sorted(seen)


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


PRIOR_FILE = "prior.json"


def save_active_model(model: ActiveModel, folder) -> None:
    """The classifier (learning.model.save_model: model.json/.npz), the observation model
    (observations.json/.npz) and the class prior recognition assumes (prior.json: null for
    the training frequencies) in one folder; no pickle."""
    from ..learning.model import save_model

    save_model(model.classifier, folder)
    save_observation_model(model.observations, folder)
    prior = None if model.class_prior is None else [float(p) for p in model.class_prior]
    write_json(Path(folder) / PRIOR_FILE, {"class_prior": prior})


def load_active_model(folder) -> ActiveModel:
    """What save_active_model wrote."""
    import json

    from ..errors import MissingFileError
    from ..learning.model import ModelFormatError, load_model

    classifier, observations = load_model(folder), load_observation_model(folder)
    path = Path(folder) / PRIOR_FILE
    retrain = "retrain with `drake-continuum train-active`"
    try:
        prior = json.loads(path.read_text())["class_prior"]
    except FileNotFoundError:
        raise MissingFileError(f"active model {path}: file not found (a model made before "
                               f"recognition took a class prior); {retrain}") from None
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ModelFormatError(f"damaged model {path} ({e}); {retrain}") from None
    return ActiveModel(classifier, observations,
                       None if prior is None else np.asarray(prior, dtype=float))


def train_active(folder, scenario: Config | None = None, *, params: ActiveParams | None = None,
                 seed: int = 0, frame: str | None = None, records=None, train_index=None,
                 classifier=None, chords=None, class_prior: str = "training") -> ActiveModel:
    """Train the classifier and tally the observations on a wrap collection (or on the
    objects `train_index` of its records), with the scenario's active, classifier and chords
    sections (default: the shipped configuration, Config()) as collect, train and recognize
    take it; `params`, `classifier` and `chords` given by keyword replace its sections, and
    `frame` is a shortcut for chords=ChordParams(frame=frame) without a scenario.

    The classifier (`classifier` ClassifierParams) is trained on the fine chord histogram
    (of `chords`), without the coarse histogram and the wrap descriptors that help the
    all-wraps classifier: recognition sees the chords of one to a few wraps, and there both
    blocks cost accuracy at stop (measured: BENCHMARKS.md, Decisions). It keeps the camera's
    view (classifier.view_weight), which is known before the first wrap, and the contact extent
    (weighted ACTIVE_EXTENT_WEIGHT) as the search gives it, that of the wraps made so far:
    each training object also gives PARTIAL_PER_SIZE rows of each of PARTIAL_SIZES of its
    wraps (partial_records; measured: BENCHMARKS.md, Point clouds).

    `class_prior` (CLASS_PRIORS) is the category probabilities recognition starts from:
    "training" keeps the classifier's probabilities, which learnt the training frequencies;
    "uniform" reweights them to every category alike for the stop rule and the answer
    (ActiveModel.reweighted)."""

    from ..features.chords import ChordParams
    from ..learning.model import train
    from ..learning.records import load_wraps

    if class_prior not in CLASS_PRIORS:
        raise InputError(f"class_prior must be one of {CLASS_PRIORS}, got {class_prior!r}")
    if frame is not None and (chords is not None or scenario is not None):
        raise InputError("train_active: frame is a shortcut for chords without a scenario; "
                         "give the frame in the chords (or the scenario's chords section)")
    if chords is None:
        chords = scenario.chords if scenario is not None else ChordParams(frame=frame or "world")
    base = Config() if scenario is None else scenario
    params = base.active if params is None else params
    classifier = base.classifier if classifier is None else classifier
    records = load_wraps(folder, chords) if records is None else records
    normals = collection_plane_normals(folder, records)
    if train_index is not None:
        records = [records[i] for i in train_index]
    active = replace(classifier, coarse=0, wrap_weight=0.0,
                     extent_weight=ACTIVE_EXTENT_WEIGHT)
    rows = list(records) + partial_records(records, seed=seed)
    clf = train(rows, Config(chords=chords, classifier=active), seed=seed)
    clf = replace(clf, info={**clf.info, "n_objects": len(records),
                             "n_partial_rows": len(rows) - len(records)})
    model = build_active_model(clf, object_wraps_from_records(records), normals, params=params)
    if class_prior == "training":
        return model
    n = len(model.observations.classes)
    return replace(model, class_prior=np.full(n, 1.0 / n))


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


