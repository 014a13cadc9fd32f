"""The classifier: object categories from chord histograms (the paper's IV-C), as a
scikit-learn Pipeline, and the triangle-histogram baseline's features.

The classifier is a scikit-learn Pipeline:
  ObjectFeatures: ChordHistogram (sparse 7-D, each object's row sums to 1; optionally the
     nested c ** 7 coarse histogram of the same chords, also summing to 1), then the wrap
     descriptors (chords.wrap_descriptors: 7 numbers of arm shape a wrap, one slot a plane),
     standardised on the training objects and weighted so that they weigh `wrap_weight`
     against the histogram's unit norm, then the object's contact extent
     (chords.contact_extent: its size as touched, 5 numbers), standardised the same way and
     weighted `extent_weight`, then the depth camera's view of the object (its height and
     footprint extents, perception.locate.view_extent: known before any wrap, whatever
     the wraps), standardised the same way and weighted `view_weight`. An object known
     only by its chords gets the training mean in the wrap and extent blocks, i.e. zeros;
     active recognition gives the view it has and the contact extent of the wraps made so
     far (its model learnt that of some of each object's wraps: active.training).
  -> OccupiedColumns: keeps only the cells some training object occupies (still sparse).
     Every other column is zero over the whole training set, so it has zero mean and zero
     variance there and every principal component has zero weight on it: dropping it leaves
     PCA's projection of any object (training or new) exactly unchanged.
  -> GramPCA keeping 95 % of the variance (the paper's choice). With n training objects
     (about 92) and d occupied cells (10^3 to 2 x 10^5), the principal axes come from the
     n x n Gram matrix of the centred rows, computed from the sparse matrix: nothing of
     size n x d is densified, and it is 40 times faster than an SVD of the dense rows when
     d is large. The components are the same as sklearn's PCA's (up to sign).
  -> GlobalScale: one factor making the mean squared norm of training rows 1, so the SVM's
     C = 1 means the same whatever the number of cells (histogram entries are ~1e-3)
  -> linear SVM with calibrated probabilities: LinearSVC inside CalibratedClassifierCV
     (Platt sigmoids from cross-validated decision values, one SVM fitted on all training
     objects). SVC(probability=True) is deprecated in scikit-learn 1.9, and the linear
     one-vs-rest form is a handful of arrays we can store and evaluate without pickle.
     Inside CategoryClassifier: with rest classes (ClassifierParams.rest_classes) the SVM
     learns a category's training objects lying on another side (placed copies, their
     recorded side) as a class of their own, "<category> (other side)", and a category's
     probability is the sum of its classes'. A lying bottle and a standing one share no
     linear boundary against the bananas and bowls; forced into one class, the lying copies
     pull the standing objects' boundaries (measured: BENCHMARKS.md, Placements).

A trained model is exported to `ChordModel` (plain arrays, numpy-only prediction, in
learning.model), saved as model.json + model.npz (`save_model`, `load_model`).
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp
from sklearn.base import BaseEstimator, ClassifierMixin, TransformerMixin, clone
from sklearn.calibration import CalibratedClassifierCV
from sklearn.pipeline import Pipeline
from sklearn.svm import LinearSVC
from sklearn.utils.validation import check_is_fitted

from ..errors import InputError
from ..features.chords import (
    CONTACT_EXTENT,
    TIE_WIDTH,
    WRAP_DESCRIPTORS,
    ChordHistogram,
    ChordSet,
    contact_extent,
)
from ..features.triangles import sample_triangles
from ..perception.locate import VIEW_EXTENT
from .params import VARIANCE_KEPT, ClassifierParams
from .records import ObjectRecord

# The pipeline a user builds and fits, and the class names it predicts; the transformers
# and descriptor helpers inside it (GramPCA, OccupiedColumns, wrap_slots, ...) are importable
# by name but are not the surface.
__all__ = ["METHODS", "BLOCKS", "REST_CLASS", "ClassifierParams", "rest_class",
           "is_rest_class", "class_category", "stands_as_generated", "CategoryClassifier",
           "ObjectFeatures", "SideMixture", "features", "make_pipeline", "fit_pipeline"]


METHODS = ("chords", "triangles")
TRIANGLE_BINS = 10    # [1]'s
N_TRIANGLES = 2000    # triangles an object for the baseline
REST_CLASS = " (other side)"  # appended to a category: its objects lying on another side
REST_CLASS_MIN = 3    # training objects a rest class needs (fewer join their category)
# The feature blocks and what each needs: "touch" the wraps alone (the arm's shape, felt or
# seen, and where it touched), "object visible" the depth camera's view of the object, which
# a transparent object does not give.
BLOCKS = {"histogram": "touch", "wrap": "touch", "extent": "touch", "view": "object visible"}


# ---------------------------------------------------------------- classes

def rest_class(category: str) -> str:
    """The class of a category's objects lying on another side."""
    return f"{category}{REST_CLASS}"


def is_rest_class(label) -> bool:
    """Whether a class is a rest class (a category's objects lying on another side)."""
    return str(label).endswith(REST_CLASS)


def stands_as_generated(x) -> bool:
    """Whether a training input stands as generated (ObjectRecord.side not "other"; inputs
    without a side do): the objects the standing model (SideMixture) learns."""
    return getattr(x, "side", "generated") != "other"


def class_category(label: str) -> str:
    """The category a class counts for (itself, or the category of a rest class)."""
    label = str(label)
    return label[:-len(REST_CLASS)] if label.endswith(REST_CLASS) else label


def training_labels(X, y, *, method: str = "chords",
                    params: ClassifierParams = ClassifierParams()) -> np.ndarray:
    """The classes the SVM learns for training inputs X (ObjectRecords for chords) with
    categories y: y itself, or with rest classes (chords, params.rest_classes) the rest
    class of each record on another side, where the category has at least REST_CLASS_MIN
    of them (fewer cannot be learnt apart: they stay in the category). InputError for a
    record whose side is unknown (a placed copy collected without its placement) or a
    category named like a rest class."""
    y = np.asarray(y).astype(str)
    bad = [c for c in np.unique(y) if c.endswith(REST_CLASS)]
    if bad:
        raise InputError(f"category {bad[0]!r} ends with {REST_CLASS!r}, which names the "
                         f"classifier's rest classes: rename it")
    if method != "chords" or not params.rest_classes:
        return y
    sides = []
    for x in X:
        side = getattr(x, "side", "generated")
        if side is None:
            raise InputError(f"training object {x.object_id!r}: the side it stood on is not "
                             f"recorded (a placed copy collected before 0.4.0): collect it "
                             f"again, or set classifier.rest_classes false")
        sides.append(side)
    other = np.array(sides) == "other"
    labels = y.astype(object)
    for c in np.unique(y[other]):
        sel = other & (y == c)
        if sel.sum() >= REST_CLASS_MIN:
            labels[sel] = rest_class(c)
    return labels.astype(str)


class CategoryClassifier(ClassifierMixin, BaseEstimator):
    """A probabilistic classifier over classes that count for categories (class_category):
    fitted on the classes, it predicts categories, each with the sum of its classes'
    probabilities. classes_ are the categories, svm_classes_ the estimator's classes."""

    def __init__(self, estimator=None):
        self.estimator = estimator

    def fit(self, X, y):
        self.estimator_ = clone(self.estimator).fit(X, y)
        self.svm_classes_ = np.asarray(self.estimator_.classes_)
        cats = np.array([class_category(c) for c in self.svm_classes_])
        self.classes_ = np.unique(cats)
        self.class_of_ = np.searchsorted(self.classes_, cats)
        return self

    def predict_proba(self, X) -> np.ndarray:
        check_is_fitted(self)
        return merge_classes(self.estimator_.predict_proba(X), self.class_of_,
                             len(self.classes_))

    def predict(self, X) -> np.ndarray:
        return self.classes_[np.argmax(self.predict_proba(X), axis=1)]


def merge_classes(proba, class_of, n_categories: int) -> np.ndarray:
    """(n, C) category probabilities from (n, K) class probabilities: column k adds to
    category class_of[k]."""
    proba = np.asarray(proba, dtype=float)
    out = np.zeros((proba.shape[0], n_categories))
    np.add.at(out.T, np.asarray(class_of), proba.T)
    return out


# ---------------------------------------------------------------- pipeline pieces

class OccupiedColumns(TransformerMixin, BaseEstimator):
    """The columns of a sparse matrix that are non-zero somewhere in the training data."""

    def fit(self, X, y=None):
        X = sp.csr_matrix(X)
        self.columns_ = np.unique(X.indices).astype(np.int64)
        self.n_features_in_ = X.shape[1]
        return self

    def transform(self, X) -> sp.csr_matrix:
        check_is_fitted(self)
        return sp.csr_matrix(X)[:, self.columns_]


class GramPCA(TransformerMixin, BaseEstimator):
    """PCA of a sparse (n, d) matrix with n << d through its n x n centred Gram matrix.

    Keeps the fewest components whose explained variance ratio reaches n_components (as
    sklearn's PCA with a float n_components); signs are fixed so that each component's
    largest-magnitude entry is positive. transform(X) = (X - mean_) @ components_.T.

    Args:
        n_components: fraction of the variance to keep, in (0, 1].
    """

    def __init__(self, n_components: float = VARIANCE_KEPT):
        self.n_components = n_components

    def fit(self, X, y=None):
        X = sp.csr_matrix(X, dtype=float)
        n = X.shape[0]
        if n < 2:
            raise ValueError("GramPCA: need at least 2 rows")
        mean = np.asarray(X.mean(axis=0)).ravel()
        r = X @ mean
        gram = (X @ X.T).toarray() - r[:, None] - r[None, :] + mean @ mean
        w, U = np.linalg.eigh((gram + gram.T) / 2)
        w, U = w[::-1], U[:, ::-1]
        positive = w > max(w[0], 0.0) * 1e-12
        w, U = w[positive], U[:, positive]
        ratio = w / w.sum()
        k = min(int(np.searchsorted(np.cumsum(ratio), self.n_components, side="right")) + 1,
                len(w))
        w, U = w[:k], U[:, :k]
        # Right singular vectors: V^T = U^T (X - 1 mean^T) / s.
        comp = ((X.T @ U).T - U.sum(axis=0)[:, None] * mean[None, :]) / np.sqrt(w)[:, None]
        big = np.argmax(np.abs(comp), axis=1)
        comp *= np.sign(comp[np.arange(k), big])[:, None]
        self.mean_, self.components_ = mean, comp
        self.explained_variance_ = w / (n - 1)
        self.explained_variance_ratio_ = ratio[:k]
        self.n_components_ = k
        return self

    def transform(self, X) -> np.ndarray:
        check_is_fitted(self)
        return np.asarray(X @ self.components_.T) - self.mean_ @ self.components_.T


class GlobalScale(TransformerMixin, BaseEstimator):
    """Multiply by one factor so that the training rows' mean squared norm is 1."""

    def fit(self, X, y=None):
        sq = X.multiply(X).sum() if sp.issparse(X) else np.sum(np.asarray(X) ** 2)
        ms = float(sq) / X.shape[0]
        self.scale_ = 1.0 / np.sqrt(ms) if ms > 0 else 1.0
        return self

    def transform(self, X):
        check_is_fitted(self)
        return X * self.scale_ if sp.issparse(X) else np.asarray(X) * self.scale_


def object_parts(item, turn_invariant: bool = False
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(chords (k, 7), descriptors (w, 7), plane_index (w,), contact extent (5,), camera
    view (3,); NaN where unknown) of one classifier input: an ObjectRecord, or chords alone
    (a ChordSet or (k, 7) array: no wrap descriptors, no contacts, no view).
    turn_invariant: contact_extent's."""
    if isinstance(item, ObjectRecord):
        desc = np.asarray(item.descriptors, dtype=float).reshape(-1, len(WRAP_DESCRIPTORS))
        plane = np.asarray(item.plane_index, dtype=np.int64).reshape(-1)
        if len(desc) != len(plane):
            desc, plane = desc[:0], plane[:0]  # descriptors unknown
        return (item.chords.values, desc, plane,
                contact_extent(item.contact_points, turn_invariant),
                np.asarray(item.view, dtype=float))
    values = item.values if isinstance(item, ChordSet) else np.asarray(item, dtype=float)
    return (values, np.zeros((0, len(WRAP_DESCRIPTORS))), np.zeros(0, np.int64),
            np.full(len(CONTACT_EXTENT), np.nan), np.full(len(VIEW_EXTENT), np.nan))


def descriptor_slots(desc, plane, n_planes: int) -> np.ndarray:
    """(n_planes * 7,) an object's wrap descriptors, plane p in entries 7p to 7p + 6; NaN
    where no wrap of the plane is known. The first wrap of a plane wrapped twice counts;
    planes outside [0, n_planes) are left out."""
    m = len(WRAP_DESCRIPTORS)
    out = np.full((n_planes, m), np.nan)
    for k in range(len(plane) - 1, -1, -1):  # backwards: the first wrap of a plane wins
        if 0 <= plane[k] < n_planes:
            out[plane[k]] = desc[k]
    return out.reshape(-1)


def pooled_descriptors(desc) -> np.ndarray:
    """(2 * 7,) mean and largest of each wrap descriptor over an object's usable wraps
    (those with a wrapped length), whatever their planes: turning the object about the
    vertical changes which plane sees which side, not what the wraps are like together.
    NaN where no wrap is usable."""
    desc = np.asarray(desc, dtype=float).reshape(-1, len(WRAP_DESCRIPTORS))
    used = desc[desc[:, 0] > 0]
    if not len(used):
        return np.full(2 * len(WRAP_DESCRIPTORS), np.nan)
    return np.r_[used.mean(axis=0), used.max(axis=0)]


def wrap_slots(desc, plane, n_planes: int, *, turn_invariant: bool) -> np.ndarray:
    """The wrap descriptor block's values of one object: pooled_descriptors with
    turn_invariant, else descriptor_slots (one slot a plane)."""
    return pooled_descriptors(desc) if turn_invariant else descriptor_slots(desc, plane,
                                                                            n_planes)


def standardisation(values, weight: float) -> tuple[np.ndarray, np.ndarray]:
    """(mean, scale) of training values (n, s), NaN where unknown, for descriptor_block:
    each column standardised by its known values' mean and standard deviation, the block
    multiplied by weight / sqrt(s) so that an average row has norm about `weight`. A column
    never known gets mean 0; a constant one scale weight / sqrt(s) (it stays 0)."""
    values = np.asarray(values, dtype=float)
    known = ~np.isnan(values)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-unknown column
        mean, std = np.nanmean(values, axis=0), np.nanstd(values, axis=0)
    mean = np.where(known.any(axis=0), mean, 0.0)
    std = np.where(known.any(axis=0) & (std > 1e-12), std, 1.0)
    return mean, float(weight) / np.sqrt(values.shape[1]) / std


def descriptor_block(slots, mean, scale) -> np.ndarray:
    """(n, s) standardised, weighted descriptors (n, s): (v - mean) * scale, with the
    training mean (zero) where a value is unknown (NaN)."""
    z = (np.asarray(slots, dtype=float) - mean) * scale
    return np.where(np.isnan(z), 0.0, z)


def descriptor_blocks(n: int, blocks, *, dense: bool = False) -> list:
    """The feature blocks after the histograms, for n objects: descriptor_block of each
    (values (n, s), or None when all unknown; mean; scale) whose mean is fitted (non-empty),
    as CSR matrices (or arrays if dense). ObjectFeatures and the exported ChordModel both
    build them here."""
    out = []
    for values, mean, scale in blocks:
        if len(mean):
            values = (np.full((n, len(mean)), np.nan) if values is None
                      else np.asarray(values, dtype=float).reshape(n, -1))
            block = descriptor_block(values, mean, scale)
            out.append(block if dense else sp.csr_matrix(block))
    return out


class ObjectFeatures(TransformerMixin, BaseEstimator):
    """The chord classifier's features of per-object inputs (ObjectRecords, or chords alone):
    the chord histograms (ChordHistogram, optionally with a nested coarse block), the wrap
    descriptors (one slot of 7 a plane), the contact extent, then the camera's view. Each
    descriptor, extent and view value is standardised by the training objects' mean and
    standard deviation (over that plane), and each block is multiplied by its weight /
    sqrt(its size): an average object's block then has norm about its weight, against 1
    for each Hellinger-mapped histogram (`standardisation`). Unknown values (no wrap of a
    plane, no contacts, no view, or chords alone) take the training mean: zero. Output:
    sparse CSR.

    Args:
        bins, edges, power, coarse, tie_width: the ChordHistogram's.
        wrap_weight: the descriptor block's weight (0: no block).
        extent_weight: the contact extent block's weight (0: no block).
        view_weight: the camera view block's weight (0: no block). There is no block
            either when no training input has a view (wraps collected before 0.4.0,
            synthetic wraps); an InputError names a training object without a view when
            others have one (a collection mixing two versions).
        turn_invariant: descriptors pooled over planes (pooled_descriptors) and the
            extent's horizontal ranges along the contacts' own axes (contact_extent).
    """

    def __init__(self, bins: int = 7, *, edges: str = "quantile", power: float = 0.5,
                 coarse: int = 0, wrap_weight: float = 0.0, extent_weight: float = 0.0,
                 turn_invariant: bool = False, view_weight: float = 0.0,
                 tie_width: float = TIE_WIDTH):
        self.bins = bins
        self.tie_width = tie_width
        self.edges = edges
        self.power = power
        self.coarse = coarse
        self.wrap_weight = wrap_weight
        self.extent_weight = extent_weight
        self.turn_invariant = turn_invariant
        self.view_weight = view_weight

    def fit(self, X, y=None):
        parts = [object_parts(x, self.turn_invariant) for x in X]
        self.histogram_ = ChordHistogram(self.bins, edges=self.edges, power=self.power,
                                         coarse=self.coarse, tie_width=self.tie_width
                                         ).fit([p[0] for p in parts])
        self.n_planes_ = 0
        if self.wrap_weight > 0:
            planes = [int(q) for p in parts for q in p[2]]
            self.n_planes_ = max(planes) + 1 if planes else 0
        n = self.n_planes_ * len(WRAP_DESCRIPTORS)
        if self.turn_invariant and n:
            n = 2 * len(WRAP_DESCRIPTORS)
        self.wrap_mean_, self.wrap_scale_ = np.zeros(n), np.zeros(n)
        if n:
            self.wrap_mean_, self.wrap_scale_ = standardisation(
                [wrap_slots(p[1], p[2], self.n_planes_,
                            turn_invariant=self.turn_invariant) for p in parts],
                self.wrap_weight)
        m = len(CONTACT_EXTENT) if self.extent_weight > 0 else 0
        self.extent_mean_, self.extent_scale_ = np.zeros(m), np.zeros(m)
        if m:
            self.extent_mean_, self.extent_scale_ = standardisation(
                [p[3] for p in parts], self.extent_weight)
        known = np.array([not np.isnan(p[4]).any() for p in parts])
        v = len(VIEW_EXTENT) if self.view_weight > 0 and known.any() else 0
        if v and not known.all():
            which = next(x for x, k in zip(X, known) if not k)
            raise InputError(f"training object {getattr(which, 'object_id', '(chords)')!r} "
                             f"has no camera view while others have one (wraps collected "
                             f"before 0.4.0 mixed with newer ones): collect it again, or set "
                             f"classifier.view_weight 0")
        self.view_mean_, self.view_scale_ = np.zeros(v), np.zeros(v)
        if v:
            self.view_mean_, self.view_scale_ = standardisation([p[4] for p in parts],
                                                                self.view_weight)
        self.n_features_ = self.histogram_.n_cells_ + n + m + v
        return self

    def transform(self, X) -> sp.csr_matrix:
        check_is_fitted(self)
        parts = [object_parts(x, self.turn_invariant) for x in X]
        blocks = [self.histogram_.transform([p[0] for p in parts])] + descriptor_blocks(
            len(parts),
            ((np.array([wrap_slots(p[1], p[2], self.n_planes_, turn_invariant=self.turn_invariant)
                        for p in parts]),
              self.wrap_mean_, self.wrap_scale_),
             (np.array([p[3] for p in parts]), self.extent_mean_, self.extent_scale_),
             (np.array([p[4] for p in parts]), self.view_mean_, self.view_scale_)))
        return blocks[0] if len(blocks) == 1 else sp.hstack(blocks, format="csr")

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.two_d_array = False  # X is a list of per-object inputs
        tags.input_tags.sparse = False
        tags.requires_fit = True
        return tags


def make_pipeline(method: str = "chords", *, seed: int = 0,
                  params: ClassifierParams = ClassifierParams(), edges=None) -> Pipeline:
    """The unfitted classifier: chords (histogram, PCA, SVM) or the triangle baseline
    (histogram, SVM: [1] used no PCA). edges: the chord histogram's bin edges, given
    (another model's) rather than learnt (chords only)."""
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    chords = method == "chords"
    svm = CategoryClassifier(CalibratedClassifierCV(LinearSVC(C=params.svm_c if chords else 1.0,
                                                              random_state=seed, max_iter=10000),
                                                    method="sigmoid", cv=3, ensemble=False))
    histogram = (ObjectFeatures(params.bins, edges=params.edges if edges is None else edges,
                                power=params.power, coarse=params.coarse,
                                wrap_weight=params.wrap_weight, extent_weight=params.extent_weight,
                                turn_invariant=params.turn_invariant,
                                view_weight=params.view_weight,
                                tie_width=params.tie_width) if chords
                 else ChordHistogram(TRIANGLE_BINS))
    steps = [("histogram", histogram), ("occupied", OccupiedColumns())]
    if method == "chords":
        steps.append(("pca", GramPCA(params.variance)))
    steps += [("scale", GlobalScale()), ("svm", svm)]
    return Pipeline(steps)


def fit_pipeline(X, y, *, method: str = "chords", seed: int = 0,
                 params: ClassifierParams = ClassifierParams()) -> "Pipeline | SideMixture":
    """Fit make_pipeline on per-object inputs X and categories y (chords: ObjectRecords, or
    chord arrays / ChordSets without wrap descriptors; triangles: arrays); the SVM learns
    training_labels. The calibration's folds are at most 3 and at most the smallest class's
    training count (>= 2 needed). With rest classes learnt and params.standing_model, a
    SideMixture of that pipeline and one fitted on the standing objects alone (when every
    category has 2 of them)."""
    names, counts = np.unique(np.asarray(y), return_counts=True)
    if len(counts) < 2 or counts.min() < 2:
        got = {str(n): int(c) for n, c in zip(names, counts)}
        raise InputError(f"training needs at least 2 categories with at least 2 objects "
                         f"each; got counts {got}")
    X = list(X)
    labels = training_labels(X, y, method=method, params=params)
    pipe = _fit_one(make_pipeline(method, seed=seed, params=params), X, labels)
    if not (params.standing_model and any(is_rest_class(c) for c in labels)):
        return pipe
    standing = np.array([stands_as_generated(x) for x in X])
    y = np.asarray(y).astype(str)
    _, counts = np.unique(y[standing], return_counts=True)
    if len(counts) < len(np.unique(y)) or counts.min() < 2:
        return pipe  # a category without 2 standing objects: nothing to mix with
    edges = pipe["histogram"].histogram_.edges_
    alone = _fit_one(make_pipeline(method, seed=seed, params=params, edges=edges),
                     [x for x, k in zip(X, standing) if k], y[standing])
    return SideMixture(pipe, alone)


def _fit_one(pipe: Pipeline, X, labels) -> Pipeline:
    """pipe fitted on X and its classes, with at most as many calibration folds as the
    smallest class has inputs (<= 3). Inputs of one object (ObjectRecords of one
    object_id: some of its wraps, as active recognition sees them) stay in one fold, so
    that the calibration never scores an object the SVM of its fold has learnt; unless a
    class has a single object, which no fold could then hold out: its inputs are folded
    one by one, as distinct objects' are."""
    folds = int(min(3, np.unique(labels, return_counts=True)[1].min()))
    ids = [getattr(x, "object_id", None) for x in X]
    objects = {} if None in ids else {i: lab for i, lab in zip(ids, labels)}
    whole = int(min(3, np.unique(list(objects.values()), return_counts=True)[1].min())) \
        if objects else 0
    if len(objects) < len(ids) and whole >= 2:
        folds = whole
        from sklearn.model_selection import StratifiedGroupKFold

        seed = pipe["svm"].estimator.estimator.random_state
        group = StratifiedGroupKFold(folds, shuffle=True, random_state=seed)
        folds = list(group.split(np.zeros(len(ids)), labels, ids))
    pipe.set_params(svm__estimator__cv=folds)
    return pipe.fit(X, labels)


class SideMixture:
    """Two fitted chord classifiers mixed by how the object stands: `full` learnt every
    training object, those lying on another side as rest classes; `standing` learnt only
    those standing as generated, with the same bin edges. P = (1 - q) P_standing + q P_full,
    q = full's probability of the rest classes (that the object lies on another side).

    Why: with lying copies in training, a standing object is read against lying ones of
    every category too (a standing banana next to lying bottles), and the standing-only
    model reads it better; a lying object still gets the model that has seen lying ones.
    The mixture is smooth in q, so a nudge that moves q a little moves P a little."""

    def __init__(self, full: Pipeline, standing: Pipeline):
        if list(full.classes_) != list(standing.classes_):
            raise ValueError("SideMixture: the two models' categories differ")
        self.full_, self.standing_ = full, standing
        svm = full["svm"]
        self.rest_ = np.array([is_rest_class(c) for c in svm.svm_classes_])

    @property
    def classes_(self) -> np.ndarray:
        return self.full_.classes_

    def _full_class_proba(self, X) -> np.ndarray:
        """(n, K) the full model's probabilities of its own classes (rest classes apart)."""
        return self.full_["svm"].estimator_.predict_proba(self.full_[:-1].transform(X))

    def lying_probability(self, X) -> np.ndarray:
        """(n,) q: the full model's probability that each object lies on another side."""
        return self._full_class_proba(X)[:, self.rest_].sum(axis=1)

    def predict_proba(self, X) -> np.ndarray:
        X = list(X)
        inner = self._full_class_proba(X)  # once: q and P_full both come from it
        svm = self.full_["svm"]
        q = inner[:, self.rest_].sum(axis=1)[:, None]
        full = merge_classes(inner, svm.class_of_, len(svm.classes_))
        return (1.0 - q) * self.standing_.predict_proba(X) + q * full

    def predict(self, X) -> np.ndarray:
        return self.classes_[np.argmax(self.predict_proba(X), axis=1)]


def features(objects, method: str = "chords", seed: int = 0) -> list[np.ndarray]:
    """Per-object inputs a method's pipeline takes: the ObjectRecords themselves (chords and
    wrap descriptors), or the baseline's triangles (sampled once an object, seeded by seed
    and the object's position)."""
    if method == "chords":
        return list(objects)
    if method == "triangles":
        return [sample_triangles(o.contact_points, N_TRIANGLES,
                                 np.random.default_rng([seed, i]))
                for i, o in enumerate(objects)]
    raise InputError(f"method must be one of {METHODS}, got {method!r}")


