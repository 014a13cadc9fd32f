"""Accuracy on placed objects: as generated, turned, on another side, nudged, and the flip
rate, over random 50/50 splits BY OBJECT.

The objects are wrap records of originals (ids without '@') and of their placed copies
(`<object_id>@<kind><k>`, objects/placement.py). Each split is drawn over the originals
(learning.evaluation.splits with groups): a training half and a test half of objects, stratified by
category, and every placed copy goes with its original, so no placement of a test object is
ever trained on. The classifier is fitted on the training half's records of `train_kinds`
(the originals only, or also their training placements, "train" and "side") and predicts
every test half record;
the accuracy of each kind is over that kind's test records. A flip is a test object whose
`turned` k and `jitter` k placements (the same placement moved 1 mm and turned 1 deg) are
predicted differently.

With `test_objects` (the records of another dataset, e.g. one generated with another seed)
each split trains on the training half of `objects` as above and tests on every record of
`test_objects` instead of the other half: objects never trained on, from a seed never used
for choosing, recognised by a classifier trained on half a full dataset (as many training
objects as the paper's protocol) rather than on half of a small subset. With `train_all`
as well, one classifier is trained on every record of `objects` (of `train_kinds`), as
`reproduce` trains the model it recommends, and tested on `test_objects` once.
"""

from __future__ import annotations

import time
import warnings
from collections import defaultdict

import numpy as np
from sklearn.metrics import balanced_accuracy_score
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from ..errors import InputError
from ..features.chord_cells import cells_once
from ..markdown import markdown_row, markdown_table
from ..objects.placement_kinds import placement_kind
from .evaluation import object_groups, splits
from .pipeline import ClassifierParams, features, fit_pipeline

__all__ = ["TEST_KINDS", "placement_tags", "evaluate_placements", "placements_table"]

TEST_KINDS = ("generated", "turned", "rest", "lying", "nudged")


def placement_tags(objects) -> list[str]:
    """Each record's tag: '' for an original, else the part after '@' (e.g. 'turned0')."""
    return [o.object_id.split("@", 1)[1] if "@" in o.object_id else "" for o in objects]


def evaluate_placements(objects, n_splits: int = 100, seed: int = 0, *, method: str = "chords",
                        params: ClassifierParams = ClassifierParams(),
                        train_kinds=("generated",), progress: bool = True,
                        test_objects=None, train_all: bool = False) -> dict:
    """Per-kind accuracy over n_splits splits by object, and the flip rate (module
    docstring); test_objects: another dataset's records to test on instead of the other
    half; train_all: one classifier trained on all of `objects` (module docstring). Returns
    {"method", "train_kinds", "n_splits", "n_groups", "kinds": {kind:
    {"accuracy_mean", "accuracy_std", "balanced_mean", "n_records", "accuracies"}},
    "flips": {"pairs", "flips", "rate"}, "time_s"}; balanced_mean is the mean over splits
    of each category's accuracy averaged with every category weighing the same
    (scikit-learn's balanced_accuracy_score): a test set of 6 objects a category weighs
    bananas as much as bottles, the other half of a dataset (51 bottles, 6 bananas) not."""
    t0 = time.perf_counter()
    objects = list(objects)
    n_pool = len(objects)
    if test_objects is not None:
        objects += list(test_objects)
    y = np.array([o.category for o in objects])
    # Another dataset's objects may share ids with the pool's: their own groups.
    groups = np.array([g if i < n_pool else "\x00test/" + g
                       for i, g in enumerate(object_groups(objects))])
    kinds = np.array([placement_kind(o.object_id) for o in objects])
    tags = placement_tags(objects)
    trainable = np.isin(kinds, list(train_kinds)) & (np.arange(len(objects)) < n_pool)
    if not trainable.any():
        raise InputError(f"no records of the training kinds {list(train_kinds)} (present: "
                         f"{sorted(set(kinds))})")
    where = {(g, t): i for i, (g, t) in enumerate(zip(groups, tags))}
    pairs = [(i, where[(groups[i], "jitter" + t[len("turned"):])])
             for i, t in enumerate(tags)
             if t.startswith("turned") and (groups[i], "jitter" + t[len("turned"):]) in where]
    if train_all and n_pool == len(objects):
        raise InputError("train_all needs test_objects: the pool is all trained on")
    X = features(objects, method, seed)
    per_kind, balanced = defaultdict(list), defaultdict(list)
    rounds = ([(np.arange(n_pool), np.arange(0))] if train_all
              else splits(y[:n_pool], n_splits=n_splits, seed=seed, groups=groups[:n_pool]))
    n_pairs = n_flips = 0
    with threadpool_limits(limits=1), cells_once():
        for train, test in tqdm(rounds, desc=f"{method} placed", unit="split", leave=False,
                                disable=not progress):
            if n_pool < len(objects):
                test = np.arange(n_pool, len(objects))
            train = train[trainable[train]]
            pipe = fit_pipeline([X[i] for i in train], y[train], method=method, seed=seed,
                                params=params)
            pred = np.empty(len(objects), dtype=object)
            pred[test] = pipe.predict([X[i] for i in test])
            for kind in sorted(set(kinds[test])):
                sel = test[kinds[test] == kind]
                per_kind[kind].append(float(np.mean(pred[sel] == y[sel])))
                with warnings.catch_warnings():  # a prediction of a category absent from
                    warnings.filterwarnings(  # this kind's test records: still an error
                        "ignore", "y_pred contains classes not in y_true", UserWarning)
                    balanced[kind].append(float(balanced_accuracy_score(
                        y[sel], pred[sel].astype(str))))
            in_test = np.zeros(len(objects), bool)
            in_test[test] = True
            for a, b in pairs:
                if in_test[a]:
                    n_pairs += 1
                    n_flips += int(pred[a] != pred[b])
    return {"method": method, "train_kinds": list(train_kinds),
            "n_splits": 1 if train_all else n_splits,
            "n_groups": int(len(set(groups))), "n_test_objects": len(objects) - n_pool,
            "kinds": {k: {"accuracy_mean": float(np.mean(v)), "accuracy_std": float(np.std(v)),
                          "balanced_mean": float(np.mean(balanced[k])),
                          "n_records": int(np.sum(kinds == k)), "accuracies": v}
                      for k, v in sorted(per_kind.items())},
            "flips": {"pairs": n_pairs, "flips": n_flips,
                      "rate": n_flips / n_pairs if n_pairs else None},
            "time_s": time.perf_counter() - t0}


def placements_table(results: dict) -> str:
    """Markdown: one row a kind, one column a method (results: method -> evaluate_placements),
    then the flip rate."""
    methods = list(results)
    kinds = [k for k in TEST_KINDS + tuple(sorted({k for r in results.values()
                                                    for k in r["kinds"]} - set(TEST_KINDS)))
             if any(k in r["kinds"] for r in results.values())]
    names = {"generated": "as generated", "turned": "turned any way about the vertical",
             "rest": "on its likeliest other side (rest pose), turned",
             "lying": "on another side drawn by its probability, turned",
             "nudged": "nudged (<= 2 cm, 5 deg)",
             "train": "dropped at random (a rest pose by its probability, any turn)",
             "side": "on another side, turned its own way (a training kind)",
             "jitter": "turned, then moved 1 mm and 1 deg"}
    def accuracy(r):
        return "" if r is None else \
            f"{100 * r['accuracy_mean']:.1f} % ± {100 * r['accuracy_std']:.1f} %"

    out = markdown_table(["objects placed", *methods],
                         [[names.get(k, k), *(accuracy(results[m]["kinds"].get(k))
                                              for m in methods)] for k in kinds],
                         align=["---"] + ["---:"] * len(methods))
    flips = [results[m]["flips"] for m in methods]
    if any(f["pairs"] for f in flips):
        out.append(markdown_row(["flip rate (prediction changes under 1 mm / 1 deg)", *(
            "" if f["rate"] is None else
            f"{100 * f['rate']:.1f} % ({f['flips']} of {f['pairs']})" for f in flips)]))
    return "\n".join(out) + "\n"
