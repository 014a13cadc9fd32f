"""Accuracy over random stratified 50/50 splits (the paper's V-B), the confusion matrices
and Table I.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from sklearn.model_selection import StratifiedShuffleSplit
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from ..errors import InputError
from ..features.chord_cells import cells_once
from ..files import number_text, writable_folder, write_atomic, write_json
from ..markdown import markdown_table
from .pipeline import ClassifierParams, features, fit_pipeline

__all__ = ["object_groups", "Evaluation", "splits", "evaluate", "evaluate_to_folder",
           "plot_confusion", "table1", "write_table1"]

log = logging.getLogger(__name__)

# ---------------------------------------------------------------- evaluation

@dataclass(frozen=True)
class Evaluation:
    """Accuracy over random stratified splits.

    Args:
        method: "chords" or "triangles".
        classes: category names, in the confusion matrix's order.
        accuracies: (n_splits,) test accuracy of each split.
        confusion: (C, C) counts summed over splits; rows true, columns predicted.
        n_objects: objects evaluated.
        time_s: wall time of all splits, s.
        object_ids: (n,) the objects, in input order.
        categories: (n,) their true classes.
        predicted: (n, C) times each object was tested and predicted as each class (the
            row sums are how often it was in a test half).
    """

    method: str
    classes: tuple
    accuracies: np.ndarray
    confusion: np.ndarray
    n_objects: int
    time_s: float
    object_ids: tuple = ()
    categories: tuple = ()
    predicted: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), np.int64))

    @property
    def accuracy_mean(self) -> float:
        return float(np.mean(self.accuracies))

    @property
    def accuracy_std(self) -> float:
        return float(np.std(self.accuracies))

    @property
    def per_class(self) -> dict:
        """Accuracy (recall) of each category over all splits' test objects."""
        tot = self.confusion.sum(axis=1)
        return {c: float(self.confusion[i, i] / tot[i]) if tot[i] else float("nan")
                for i, c in enumerate(self.classes)}

    def misclassified(self) -> list[dict]:
        """The objects ever predicted wrongly, most often wrong first: object_id, category,
        tested, wrong and `as` (wrong class -> times)."""
        out = []
        for i, (oid, cat) in enumerate(zip(self.object_ids, self.categories)):
            row = self.predicted[i]
            own = self.classes.index(cat)
            wrong = int(row.sum() - row[own])
            if wrong:
                out.append({"object_id": oid, "category": cat, "tested": int(row.sum()),
                            "wrong": wrong,
                            "as": {self.classes[c]: int(row[c]) for c in np.argsort(-row)
                                   if c != own and row[c]}})
        return sorted(out, key=lambda r: (-r["wrong"] / r["tested"], r["object_id"]))

    def to_dict(self) -> dict:
        return {"method": self.method, "accuracy_mean": self.accuracy_mean,
                "accuracy_std": self.accuracy_std, "n_objects": self.n_objects,
                "n_splits": len(self.accuracies), "classes": list(self.classes),
                "per_class": self.per_class, "confusion": self.confusion.tolist(),
                "accuracies": self.accuracies.tolist(), "time_s": self.time_s}


def splits(labels, *, n_splits: int = 100, seed: int = 0, groups=None):
    """(train, test) index pairs of random stratified 50/50 splits, the same for a seed.

    With `groups` (one name an item, e.g. objects.placement.source_id of each object id),
    the split is drawn over the groups, in order of first appearance, each labelled by its
    first item, and every item falls in its group's half: all placements of one object are
    on the same side. When every group is one item this is the plain split, index for index.
    InputError for fewer than one split (no accuracy to average).
    """
    if isinstance(n_splits, bool) or not isinstance(n_splits, (int, np.integer)) \
            or n_splits < 1:
        raise InputError(f"n_splits must be a whole number of at least 1, got {n_splits!r}")
    labels = np.asarray(labels)
    sss = StratifiedShuffleSplit(n_splits=n_splits, test_size=0.5, random_state=seed)
    if groups is None:
        return list(sss.split(np.zeros(len(labels)), labels))
    groups = np.asarray(groups)
    _, first, inverse = np.unique(groups, return_index=True, return_inverse=True)
    order = np.argsort(first)                 # groups in order of first appearance
    position = np.empty(len(order), np.int64)
    position[order] = np.arange(len(order))
    of_item = position[inverse.reshape(-1)]   # each item's group position
    members = [[] for _ in order]
    for i, g in enumerate(of_item):
        members[g].append(i)

    def items(gs):  # the groups' items, in the split's order of groups
        return np.array([i for g in gs for i in members[g]], dtype=np.int64)

    return [(items(train), items(test))
            for train, test in sss.split(np.zeros(len(order)), labels[first[order]])]


def object_groups(objects) -> list[str]:
    """The object each record came from (placed copies share their original's)."""
    from ..objects.placement_kinds import source_id
    return [source_id(o.object_id) for o in objects]


def evaluate(objects, n_splits: int = 100, seed: int = 0, *, method: str = "chords",
             params: ClassifierParams = ClassifierParams(), progress: bool = True
             ) -> Evaluation:
    """Train on half, test on the other half, n_splits times (the paper's V-B protocol),
    split by object (placed copies of one object stay in one half).

    Per-object features are computed once; each split fits the whole pipeline (bin edges,
    occupied cells, PCA, SVM) on its training half only.
    """
    t0 = time.perf_counter()
    objects = list(objects)
    y = np.array([o.category for o in objects])
    classes = tuple(str(c) for c in np.unique(y))
    X = features(objects, method, seed)
    confusion = np.zeros((len(classes), len(classes)), dtype=np.int64)
    predicted = np.zeros((len(objects), len(classes)), dtype=np.int64)
    accuracies = []
    # The matrices are small (about 92 x 10^4): BLAS threads only spin, and on a shared
    # 2-core machine one thread is 5 to 7 times faster than two (BENCHMARKS.md,
    # Classification).
    with threadpool_limits(limits=1), cells_once():
        for train, test in tqdm(splits(y, n_splits=n_splits, seed=seed,
                                       groups=object_groups(objects)),
                                desc=f"{method} splits",
                                unit="split", leave=False, disable=not progress):
            pipe = fit_pipeline([X[i] for i in train], y[train], method=method, seed=seed,
                                params=params)
            pred = pipe.predict([X[i] for i in test])
            accuracies.append(float(np.mean(pred == y[test])))
            np.add.at(confusion, (np.searchsorted(classes, y[test]),
                                  np.searchsorted(classes, pred)), 1)
            np.add.at(predicted, (test, np.searchsorted(classes, pred)), 1)
    result = Evaluation(method, classes, np.array(accuracies), confusion, len(objects),
                        time.perf_counter() - t0, tuple(o.object_id for o in objects),
                        tuple(str(c) for c in y), predicted)
    log.info("%s: %d objects, %d splits, accuracy %.3f +- %.3f, %.1f s", method, len(objects),
             n_splits, result.accuracy_mean, result.accuracy_std, result.time_s)
    return result


def evaluate_to_folder(objects, out, *, n_splits: int = 100, seed: int = 0,
                       params: ClassifierParams = ClassifierParams(), skipped=(),
                       progress: bool = True) -> dict:
    """The paper's V-B evaluation with its outputs: chords and the triangle baseline on the
    same splits; confusion matrices (PNG), Table I (Markdown, JSON) and evaluation.json in
    `out`. `skipped`: the collection's objects left out (load_collection), recorded with
    the figures they are missing from; `progress`: the splits' progress bars. Returns the
    summary (accuracies, per-class accuracy, Table I, skipped)."""
    objects = list(objects)
    out = writable_folder(out)  # before the long part
    chords = evaluate(objects, n_splits, seed, method="chords", params=params, progress=progress)
    tri = evaluate(objects, n_splits, seed, method="triangles", progress=progress)
    plot_confusion(chords, out / "confusion.png")
    plot_confusion(tri, out / "confusion_triangles.png")
    rows = table1(objects)
    write_table1(rows, out)
    wrong = chords.misclassified()
    skipped = [dict(s) for s in skipped]
    write_json(out / "evaluation.json",
               {"chords": chords.to_dict(), "triangles": tri.to_dict(), "table1": rows,
                "misclassified": wrong, "skipped": skipped})
    return {"accuracy_mean": chords.accuracy_mean, "accuracy_std": chords.accuracy_std,
            "baseline_accuracy_mean": tri.accuracy_mean,
            "baseline_accuracy_std": tri.accuracy_std, "n_objects": len(objects),
            "n_splits": n_splits, "per_class": chords.per_class, "table1": rows,
            "misclassified": wrong, "skipped": skipped}


def plot_confusion(evaluation: Evaluation, path, title: str | None = None) -> None:
    """The row-normalised confusion matrix as a PNG (the paper's Fig. 7)."""
    from matplotlib.figure import Figure  # no pyplot: no GUI backend, no global state

    cm = evaluation.confusion.astype(float)
    cm = np.divide(cm, cm.sum(axis=1, keepdims=True), out=np.zeros_like(cm),
                   where=cm.sum(axis=1, keepdims=True) > 0)
    n = len(evaluation.classes)
    fig = Figure(figsize=(max(5.0, 1.5 + 0.65 * n), max(4.0, 1.2 + 0.6 * n)))
    ax = fig.subplots()
    im = ax.imshow(cm, cmap="Blues", vmin=0, vmax=1)
    ax.set_xticks(range(n), evaluation.classes, rotation=45, ha="right")
    ax.set_yticks(range(n), evaluation.classes)
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    for i in range(n):
        for j in range(n):
            ax.text(j, i, f"{cm[i, j]:.2f}", ha="center", va="center", fontsize=8,
                    color="white" if cm[i, j] > 0.5 else "black")
    ax.set_title(title or f"{evaluation.method}: accuracy {evaluation.accuracy_mean:.1%} "
                          f"over {len(evaluation.accuracies)} splits", fontsize=10)
    fig.colorbar(im, ax=ax, fraction=0.046)
    fig.tight_layout()
    write_atomic(Path(path), lambda f: fig.savefig(f, format="png", dpi=120))


def table1(objects) -> list[dict]:
    """The paper's Table I: per category, mean chords and wraps an object, mean ms a wrap;
    and how the usable wraps follow the object: the median fraction of the wrapped centre
    line near the surface (conformity) and the mean contact regions a wrap."""
    rows = []
    for cat in sorted({o.category for o in objects}):
        objs = [o for o in objects if o.category == cat]
        times = np.concatenate([o.wrap_time_s for o in objs])
        near = np.concatenate([o.conformity[o.usable] for o in objs if len(o.conformity)]
                              or [np.zeros(0)])
        near = near[np.isfinite(near)]
        regions = np.concatenate([o.contact_regions[o.usable] for o in objs
                                  if len(o.contact_regions)] or [np.zeros(0)])
        rows.append({"category": cat, "n_objects": len(objs),
                     "mean_chords": float(np.mean([len(o.chords) for o in objs])),
                     "mean_wraps": float(np.mean([o.n_wraps for o in objs])),
                     "mean_wrap_ms": float(1000 * times.mean()) if len(times) else float("nan"),
                     "median_conformity": float(np.median(near)) if len(near) else None,
                     "mean_contact_regions": float(regions.mean()) if len(regions)
                     else None})
    return rows


def write_table1(rows, out_dir) -> None:
    """table1.md and table1.json in out_dir."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    md = markdown_table(
        ["category", "objects", "mean # chords", "mean # wraps", "T_wrap (ms)",
         "near surface (median)", "contact regions (mean)"],
        [[r["category"], r["n_objects"], f"{r['mean_chords']:.0f}", f"{r['mean_wraps']:.1f}",
          f"{r['mean_wrap_ms']:.0f}", number_text(r["median_conformity"], "{:.0%}"),
          number_text(r["mean_contact_regions"], "{:.1f}")] for r in rows],
        align=["---"] + ["---:"] * 6)
    write_atomic(out_dir / "table1.md", ("\n".join(md) + "\n").encode())
    write_json(out_dir / "table1.json", rows)


