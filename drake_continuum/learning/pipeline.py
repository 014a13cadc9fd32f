"""Object categories from chord histograms (the paper's IV-C and V-B), its evaluation over
random 50/50 splits, the triangle-histogram baseline, and a model format safe to share.

The classifier is a scikit-learn Pipeline:
  ObjectFeatures: ChordHistogram (sparse 7-D, each object's row sums to 1; optionally the
     nested c ** 7 coarse histogram of the same chords, also summing to 1), then the wrap
     descriptors (chords.wrap_descriptors: 7 numbers of arm shape a wrap, one slot a plane),
     standardised on the training objects and weighted so that they weigh `wrap_weight`
     against the histogram's unit norm, then the object's contact extent
     (chords.contact_extent: its size as touched, 5 numbers), standardised the same way and
     weighted `extent_weight`. An object known only by its chords (active recognition's
     accumulated cells) gets the training mean in both blocks, i.e. zeros.
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

A trained model is exported to `ChordModel` (plain arrays, numpy-only prediction), saved as
model.json + model.npz (`save_model`, `load_model`).
"""

from __future__ import annotations

import json
import logging
import time
import warnings
import zipfile
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.special import expit
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.calibration import CalibratedClassifierCV
from sklearn.model_selection import StratifiedShuffleSplit
from sklearn.pipeline import Pipeline
from sklearn.svm import LinearSVC
from sklearn.utils.validation import check_is_fitted
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from ..errors import DrakeContinuumError, InputError, MissingFileError
from ..features.chords import (
    CHORD_PARAMETERS,
    CONTACT_EXTENT,
    WRAP_DESCRIPTORS,
    ChordHistogram,
    ChordParams,
    ChordSet,
    bin_centres,
    bin_index,
    contact_extent,
    histogram_features,
    object_chords,
    wrap_descriptors,
)
from ..features.triangles import sample_triangles
from ..files import array_shapes, model_digest, writable_folder, write_atomic, write_json
from ..wrapping.wrap_types import WRAPS_FORMAT, WRAPS_FORMAT_VERSION, WrapResult

__all__ = ["FORMAT_VERSION", "MODEL_KIND", "METHODS", "TRIANGLE_BINS", "N_TRIANGLES",
           "VARIANCE_KEPT", "ClassifierParams", "WrapDataWarning", "WrapFileError",
           "WrapFormatError", "ModelFormatError", "ObjectRecord", "object_record",
           "check_wraps_format", "read_object_wraps", "load_collection", "load_wraps",
           "OccupiedColumns", "GramPCA", "GlobalScale", "object_parts", "descriptor_slots",
           "pooled_descriptors", "wrap_slots", "object_groups",
           "standardisation", "descriptor_block", "descriptor_blocks", "ObjectFeatures",
           "make_pipeline", "fit_pipeline", "features", "Evaluation", "splits", "evaluate",
           "evaluate_to_folder", "plot_confusion", "table1", "write_table1", "ChordModel", "train",
           "classify_wraps", "Classification", "classify", "check_saved_arrays", "save_model",
           "load_model"]

log = logging.getLogger(__name__)

FORMAT_VERSION = 5  # 2: Hellinger map; 3: coarse histogram, wrap descriptors; 4: contact
#                    extent; 5: array shapes and their SHA-256 in model.json
MODEL_KIND = "drake-continuum chord classifier"
METHODS = ("chords", "triangles")
TRIANGLE_BINS = 10    # [1]'s
N_TRIANGLES = 2000    # triangles an object for the baseline
VARIANCE_KEPT = 0.95  # the paper's PCA


@dataclass(frozen=True)
class ClassifierParams:
    """The chord classifier's settings (models/config.yaml, section classifier; what each
    is worth in BENCHMARKS.md, "Classification").

    Args:
        bins: histogram bins a dimension (the paper's 7).
        edges: "quantile" (equal-frequency bins learned on the training split) or "uniform"
            (the paper's reading).
        power: exponent of the normalised histogram; 0.5 is the Hellinger map, 1 none.
        variance: PCA variance kept (the paper's 95 %).
        svm_c: the linear SVM's C.
        coarse: bins a dimension of the nested coarse histogram appended to the 7-D one
            (0: none).
        wrap_weight: weight of the per-plane wrap descriptors against the histograms (0:
            none).
        extent_weight: weight of the contact extent block (0: none).
        turn_invariant: wrap descriptors pooled over planes and the contact extent's
            horizontal ranges along the contacts' own axes, so that they do not change when
            the object is turned about the vertical (ObjectFeatures). It helps turned
            objects and costs accuracy on objects as generated, so it is off by default
            (BENCHMARKS.md, "Placed objects").
    """

    bins: int = 7
    edges: str = "quantile"
    power: float = 0.5
    variance: float = VARIANCE_KEPT
    svm_c: float = 10.0
    coarse: int = 0
    wrap_weight: float = 0.4
    extent_weight: float = 0.8
    turn_invariant: bool = False


class WrapDataWarning(UserWarning):
    """A wrap file could not be read and was skipped."""


class WrapFileError(DrakeContinuumError):
    """One object's wrap files are missing or damaged (the message names the file)."""


class WrapFormatError(InputError):
    """A wrap file of another format version than this code reads (the message names it)."""


class ModelFormatError(DrakeContinuumError):
    """A model folder is missing, damaged or of another format version."""


# ---------------------------------------------------------------- objects and loading

@dataclass(frozen=True)
class ObjectRecord:
    """What classification needs of one object's wraps.

    Args:
        object_id: the object's name.
        category: its category (the label).
        chords: chords of its usable wraps; ChordSet.wrap is the position of the wrap in
            the object's list (plane_index[wrap] is its plane).
        contact_points: (m, 3) contact centres of all its usable wraps (the baseline's input).
        plane_index: (w,) plane index of each of its wraps, in order.
        usable: (w,) whether each wrap gave chords.
        wrap_time_s: (w,) wall time of each wrap, s.
        descriptors: (w, 7) chords.wrap_descriptors of each wrap (zeros for unusable ones);
            (0, 7) if unknown, as for an object known only by its chords.
        conformity: (w,) each wrap's WrapResult.conformity (nan where not measured).
        contact_regions: (w,) contact regions of each wrap's final configuration.
    """

    object_id: str
    category: str
    chords: ChordSet
    contact_points: np.ndarray
    plane_index: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    usable: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    wrap_time_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    descriptors: np.ndarray = field(
        default_factory=lambda: np.zeros((0, len(WRAP_DESCRIPTORS))))
    conformity: np.ndarray = field(default_factory=lambda: np.zeros(0))
    contact_regions: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def n_wraps(self) -> int:
        """Wraps that describe the object (usable ones)."""
        return int(np.count_nonzero(self.usable))


def object_record(object_id: str, category: str, wraps, params: ChordParams = ChordParams()
                  ) -> ObjectRecord:
    """An ObjectRecord from in-memory WrapResults."""
    wraps = list(wraps)
    usable = np.array([w.usable for w in wraps], dtype=bool)
    points = [w.contacts.p for w, u in zip(wraps, usable) if u]
    return ObjectRecord(
        object_id=object_id, category=category, chords=object_chords(wraps, params),
        contact_points=np.concatenate(points) if points else np.zeros((0, 3)),
        plane_index=np.array([w.plane_index for w in wraps], dtype=np.int64),
        usable=usable, wrap_time_s=np.array([w.time_s for w in wraps], dtype=float),
        descriptors=np.array([wrap_descriptors(w) for w in wraps],
                             dtype=float).reshape(-1, len(WRAP_DESCRIPTORS)),
        conformity=np.array([w.conformity for w in wraps], dtype=float),
        contact_regions=np.array([w.contact_regions for w in wraps], dtype=np.int64))


def check_wraps_format(path, meta) -> None:
    """A collection's JSON file (object or index.json) must be of the wrap format version
    this code reads: raises WrapFormatError naming the file, as a model of another version
    is refused, rather than reading numbers whose meaning may have changed."""
    version = meta.get("format_version") if isinstance(meta, dict) else None
    if version != WRAPS_FORMAT_VERSION or meta.get("format") != WRAPS_FORMAT:
        raise WrapFormatError(
            f"{path}: wrap file format {meta.get('format') if isinstance(meta, dict) else None!r}"
            f" version {version} cannot be read by this drake-continuum, which reads "
            f"{WRAPS_FORMAT!r} version {WRAPS_FORMAT_VERSION}; collect the wraps again "
            f"with this version")


def read_object_wraps(folder, object_id: str) -> tuple[dict, list[WrapResult]]:
    """(metadata, wraps) of one object from `<folder>/<object_id>.json` and `.npz`.

    Raises WrapFileError naming the file if one is missing, damaged or holds non-finite
    numbers (NaN, infinity: no wrap stores them), WrapFormatError if it is of another format
    version."""
    folder = Path(folder)
    json_path, npz_path = folder / f"{object_id}.json", folder / f"{object_id}.npz"
    try:
        meta = json.loads(json_path.read_text())
        n = int(meta["n_wraps"])
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise WrapFileError(f"{json_path}: {type(e).__name__}: {e}") from None
    check_wraps_format(json_path, meta)
    try:
        if not zipfile.is_zipfile(npz_path):
            raise ValueError("not an .npz archive (damaged or truncated)")
        with np.load(npz_path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        bad = sorted(k for k, a in arrays.items()
                     if a.dtype.kind in "fc" and not np.all(np.isfinite(a)))
        if bad:
            raise ValueError(f"non-finite numbers (NaN or infinity) in {', '.join(bad)}")
        wraps = [WrapResult.from_arrays(arrays, f"w{k}_") for k in range(n)]
    except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile) as e:
        raise WrapFileError(f"{npz_path}: {type(e).__name__}: {e}") from None
    return meta, wraps


def _object_ids(folder: Path) -> tuple[list[str], list[dict]]:
    """(ids of the collection's finished objects, index.json's failed entries); every
    object file when index.json is missing or unreadable."""
    every = sorted(p.stem for p in folder.glob("*.json") if p.name != "index.json"), []
    index = folder / "index.json"
    if not index.is_file():
        return every
    try:
        data = json.loads(index.read_text())
    except (OSError, ValueError) as e:
        warnings.warn(f"{index}: unreadable ({e}); reading every object file instead",
                      WrapDataWarning, stacklevel=3)
        return every
    check_wraps_format(index, data)
    try:
        ids = [e if isinstance(e, str) else str(e["object_id"]) for e in data["objects"]]
        failed = [f for f in data.get("failed", []) if isinstance(f, dict) and f.get("object_id")]
    except (KeyError, TypeError, AttributeError) as e:
        warnings.warn(f"{index}: unreadable ({type(e).__name__}: {e}); reading every object "
                      f"file instead", WrapDataWarning, stacklevel=3)
        return every
    return (ids, failed) if ids or failed else every


def load_collection(folder, params: ChordParams = ChordParams()
                    ) -> tuple[list[ObjectRecord], list[dict]]:
    """Every readable object of a wrap collection (WRAPS folder), chords computed once, and
    the objects left out: [{"object_id", "reason"}] for each whose files are missing,
    damaged or hold non-finite numbers, and each index.json lists as failed in collection.

    Raises WrapFormatError if a file is of another format version, FileNotFoundError if
    the folder holds no readable object.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise MissingFileError(f"{folder}: no such wrap folder")
    ids, failed = _object_ids(folder)
    records, skipped = [], []
    for object_id in ids:
        try:
            meta, wraps = read_object_wraps(folder, object_id)
            if "category" not in meta:
                raise WrapFileError(f"{folder / object_id}.json: no 'category'")
            records.append(object_record(str(meta.get("object_id", object_id)),
                                         str(meta["category"]), wraps, params))
        except WrapFileError as e:
            skipped.append({"object_id": str(object_id), "reason": str(e)})
    skipped += [{"object_id": str(f["object_id"]),
                 "reason": f"failed in collection: {f.get('error', 'no reason recorded')}"}
                for f in failed]
    if not records:
        raise MissingFileError(
            f"{folder}: no readable objects (<object_id>.json + .npz)"
            + (f"; skipped {'; '.join(s['object_id'] + ': ' + s['reason'] for s in skipped)}"
               if skipped else ""))
    return records, skipped


def load_wraps(folder, params: ChordParams = ChordParams()) -> list[ObjectRecord]:
    """load_collection's objects; each object left out is named in a WrapDataWarning."""
    records, skipped = load_collection(folder, params)
    for s in skipped:
        warnings.warn(f"skipped object {s['object_id']!r}: {s['reason']}", WrapDataWarning,
                      stacklevel=2)
    return records


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
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(chords (k, 7), descriptors (w, 7), plane_index (w,), contact extent (5,), NaN if
    unknown) of one classifier input: an ObjectRecord, or chords alone (a ChordSet or
    (k, 7) array: no wrap descriptors, no contacts). turn_invariant: contact_extent's."""
    if isinstance(item, ObjectRecord):
        desc = np.asarray(item.descriptors, dtype=float).reshape(-1, len(WRAP_DESCRIPTORS))
        plane = np.asarray(item.plane_index, dtype=np.int64).reshape(-1)
        if len(desc) != len(plane):
            desc, plane = desc[:0], plane[:0]  # descriptors unknown
        return (item.chords.values, desc, plane,
                contact_extent(item.contact_points, turn_invariant))
    values = item.values if isinstance(item, ChordSet) else np.asarray(item, dtype=float)
    return (values, np.zeros((0, len(WRAP_DESCRIPTORS))), np.zeros(0, np.int64),
            np.full(len(CONTACT_EXTENT), np.nan))


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


def wrap_slots(desc, plane, n_planes: int, turn_invariant: bool) -> np.ndarray:
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


def descriptor_blocks(n: int, blocks) -> list[sp.csr_matrix]:
    """The feature blocks after the histograms, for n objects: descriptor_block of each
    (values (n, s), or None when all unknown; mean; scale) whose mean is fitted (non-empty).
    ObjectFeatures and the exported ChordModel both build them here."""
    out = []
    for values, mean, scale in blocks:
        if len(mean):
            values = (np.full((n, len(mean)), np.nan) if values is None
                      else np.asarray(values, dtype=float).reshape(n, -1))
            out.append(sp.csr_matrix(descriptor_block(values, mean, scale)))
    return out


class ObjectFeatures(TransformerMixin, BaseEstimator):
    """The chord classifier's features of per-object inputs (ObjectRecords, or chords alone):
    the chord histograms (ChordHistogram, optionally with a nested coarse block), the wrap
    descriptors (one slot of 7 a plane), then the contact extent. Each descriptor and extent
    value is standardised by the training objects' mean and standard deviation (over that
    plane), and each block is multiplied by its weight / sqrt(its size): an average object's
    block then has norm about its weight, against 1 for each Hellinger-mapped histogram
    (`standardisation`). Unknown values (no wrap of a plane, no contacts, or chords alone)
    take the training mean: zero. Output: sparse CSR.

    Args:
        bins, edges, power, coarse: the ChordHistogram's.
        wrap_weight: the descriptor block's weight (0: no block).
        extent_weight: the contact extent block's weight (0: no block).
        turn_invariant: descriptors pooled over planes (pooled_descriptors) and the
            extent's horizontal ranges along the contacts' own axes (contact_extent).
    """

    def __init__(self, bins: int = 7, edges: str = "quantile", power: float = 0.5,
                 coarse: int = 0, wrap_weight: float = 0.0, extent_weight: float = 0.0,
                 turn_invariant: bool = False):
        self.bins = bins
        self.edges = edges
        self.power = power
        self.coarse = coarse
        self.wrap_weight = wrap_weight
        self.extent_weight = extent_weight
        self.turn_invariant = turn_invariant

    def fit(self, X, y=None):
        parts = [object_parts(x, self.turn_invariant) for x in X]
        self.histogram_ = ChordHistogram(self.bins, edges=self.edges, power=self.power,
                                         coarse=self.coarse).fit([p[0] for p in parts])
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
                [wrap_slots(p[1], p[2], self.n_planes_, self.turn_invariant) for p in parts],
                self.wrap_weight)
        m = len(CONTACT_EXTENT) if self.extent_weight > 0 else 0
        self.extent_mean_, self.extent_scale_ = np.zeros(m), np.zeros(m)
        if m:
            self.extent_mean_, self.extent_scale_ = standardisation(
                [p[3] for p in parts], self.extent_weight)
        self.n_features_ = self.histogram_.n_cells_ + n + m
        return self

    def transform(self, X) -> sp.csr_matrix:
        check_is_fitted(self)
        parts = [object_parts(x, self.turn_invariant) for x in X]
        blocks = [self.histogram_.transform([p[0] for p in parts])] + descriptor_blocks(
            len(parts),
            ((np.array([wrap_slots(p[1], p[2], self.n_planes_, self.turn_invariant)
                        for p in parts]),
              self.wrap_mean_, self.wrap_scale_),
             (np.array([p[3] for p in parts]), self.extent_mean_, self.extent_scale_)))
        return blocks[0] if len(blocks) == 1 else sp.hstack(blocks, format="csr")

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.two_d_array = False  # X is a list of per-object inputs
        tags.input_tags.sparse = False
        tags.requires_fit = True
        return tags


def make_pipeline(method: str = "chords", seed: int = 0,
                  params: ClassifierParams = ClassifierParams()) -> Pipeline:
    """The unfitted classifier: chords (histogram, PCA, SVM) or the triangle baseline
    (histogram, SVM: [1] used no PCA)."""
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    chords = method == "chords"
    svm = CalibratedClassifierCV(LinearSVC(C=params.svm_c if chords else 1.0,
                                           random_state=seed, max_iter=10000),
                                 method="sigmoid", cv=3, ensemble=False)
    histogram = (ObjectFeatures(params.bins, params.edges, params.power, params.coarse,
                                params.wrap_weight, params.extent_weight,
                                params.turn_invariant) if chords
                 else ChordHistogram(TRIANGLE_BINS))
    steps = [("histogram", histogram), ("occupied", OccupiedColumns())]
    if method == "chords":
        steps.append(("pca", GramPCA(params.variance)))
    steps += [("scale", GlobalScale()), ("svm", svm)]
    return Pipeline(steps)


def fit_pipeline(X, y, method: str = "chords", seed: int = 0,
                 params: ClassifierParams = ClassifierParams()) -> Pipeline:
    """Fit make_pipeline on per-object inputs X and labels y (chords: ObjectRecords, or
    chord arrays / ChordSets without wrap descriptors; triangles: arrays). The calibration's
    folds are at most 3 and at most the smallest category's training count (>= 2 needed)."""
    _, counts = np.unique(np.asarray(y), return_counts=True)
    if len(counts) < 2 or counts.min() < 2:
        raise InputError(f"training needs at least 2 categories with at least 2 objects "
                         f"each; got counts {dict(zip(*np.unique(y, return_counts=True)))}")
    pipe = make_pipeline(method, seed, params)
    pipe.set_params(svm__cv=int(min(3, counts.min())))
    return pipe.fit(list(X), np.asarray(y))


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


def splits(labels, n_splits: int = 100, seed: int = 0, groups=None):
    """(train, test) index pairs of random stratified 50/50 splits, the same for a seed.

    With `groups` (one name an item, e.g. objects.placement.source_id of each object id),
    the split is drawn over the groups, in order of first appearance, each labelled by its
    first item, and every item falls in its group's half: all placements of one object are
    on the same side. When every group is one item this is the plain split, index for index.
    """
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
    from ..objects.placement import source_id
    return [source_id(o.object_id) for o in objects]


def evaluate(objects, n_splits: int = 100, seed: int = 0, method: str = "chords",
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
    # 2-core machine one thread was 5 to 7 times faster than two.
    with threadpool_limits(limits=1):
        for train, test in tqdm(splits(y, n_splits, seed, object_groups(objects)),
                                desc=f"{method} splits",
                                unit="split", leave=False, disable=not progress):
            pipe = fit_pipeline([X[i] for i in train], y[train], method, seed, params)
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


def evaluate_to_folder(objects, out, n_splits: int = 100, seed: int = 0,
                       params: ClassifierParams = ClassifierParams(), skipped=()) -> dict:
    """The paper's V-B evaluation with its outputs: chords and the triangle baseline on the
    same splits; confusion matrices (PNG), Table I (Markdown, JSON) and evaluation.json in
    `out`. `skipped`: the collection's objects left out (load_collection), recorded with
    the figures they are missing from. Returns the summary (accuracies, per-class accuracy,
    Table I, skipped)."""
    objects = list(objects)
    out = writable_folder(out)  # before the long part
    chords = evaluate(objects, n_splits, seed, "chords", params)
    tri = evaluate(objects, n_splits, seed, "triangles")
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


def _or_na(x, fmt: str) -> str:
    return "n/a" if x is None else fmt.format(x)


def write_table1(rows, out_dir) -> None:
    """table1.md and table1.json in out_dir."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    md = ["| category | objects | mean # chords | mean # wraps | T_wrap (ms) | near surface "
          "(median) | contact regions (mean) |",
          "|---|---:|---:|---:|---:|---:|---:|"]
    md += [f"| {r['category']} | {r['n_objects']} | {r['mean_chords']:.0f} | "
           f"{r['mean_wraps']:.1f} | {r['mean_wrap_ms']:.0f} | "
           f"{_or_na(r['median_conformity'], '{:.0%}')} | "
           f"{_or_na(r['mean_contact_regions'], '{:.1f}')} |" for r in rows]
    write_atomic(out_dir / "table1.md", ("\n".join(md) + "\n").encode())
    write_json(out_dir / "table1.json", rows)


# ---------------------------------------------------------------- the portable model

@dataclass(frozen=True)
class ChordModel:
    """A trained chord classifier as plain arrays; prediction needs numpy only.

    Args:
        classes: (C,) category names.
        chord_params: how chords are taken from wraps (must match at prediction).
        edges: (7, bins + 1) histogram bin edges learned from the training chords.
        power: exponent of the normalised histograms (0.5: the Hellinger map).
        coarse: bins a dimension of the nested coarse histogram (0: none).
        wrap_mean, wrap_scale: (n_planes * 7,) standardisation of the wrap descriptor slots
            (ObjectFeatures; empty without descriptors).
        extent_mean, extent_scale: (5,) standardisation of the contact extent (empty
            without it).
        columns: (d,) feature columns occupied in training (sorted): fine cells, then
            bins ** 7 + coarse cells, then bins ** 7 + coarse ** 7 + descriptor slots, then
            the contact extent.
        pca_mean: (d,) and pca_components: (k, d): the PCA.
        scale: the global feature scale after PCA.
        coef: (K, k) and intercept: (K,): the linear SVM (K = C, or 1 for two classes).
        sigmoid_a, sigmoid_b: (K,) Platt calibration: p = 1 / (1 + exp(a f + b)).
        info: training facts (objects, seed, versions), stored as JSON.
        turn_invariant: wrap descriptors pooled over planes, the extent's horizontal ranges
            along the contacts' axes (ClassifierParams.turn_invariant).
    """

    classes: tuple
    chord_params: ChordParams
    edges: np.ndarray
    power: float
    coarse: int
    wrap_mean: np.ndarray
    wrap_scale: np.ndarray
    extent_mean: np.ndarray
    extent_scale: np.ndarray
    columns: np.ndarray
    pca_mean: np.ndarray
    pca_components: np.ndarray
    scale: float
    coef: np.ndarray
    intercept: np.ndarray
    sigmoid_a: np.ndarray
    sigmoid_b: np.ndarray
    info: dict = field(default_factory=dict)
    turn_invariant: bool = False

    _ARRAYS = ("edges", "wrap_mean", "wrap_scale", "extent_mean", "extent_scale", "columns",
               "pca_mean", "pca_components", "coef", "intercept", "sigmoid_a", "sigmoid_b")

    @property
    def classes_(self) -> np.ndarray:
        return np.array(self.classes)

    @property
    def edges_(self) -> np.ndarray:
        """(7, bins + 1) fitted bin edges (for active recognition's discretisation)."""
        return self.edges

    @property
    def bins(self) -> int:
        return self.edges.shape[1] - 1

    @property
    def n_cells(self) -> int:
        """Cells of the fine 7-D histogram (those bin_index returns)."""
        return self.bins ** self.edges.shape[0]

    @property
    def n_planes(self) -> int:
        """Planes the wrap descriptors were learned from (0: no descriptors): one slot a
        plane, or, pooled (turn_invariant), the planes of the training wraps (info)."""
        if self.turn_invariant:
            return int(self.info.get("n_planes", 0)) if len(self.wrap_mean) else 0
        return len(self.wrap_mean) // len(WRAP_DESCRIPTORS)

    @classmethod
    def from_pipeline(cls, pipe: Pipeline, chord_params: ChordParams, info=None
                      ) -> "ChordModel":
        cal = pipe["svm"]
        if len(cal.calibrated_classifiers_) != 1:
            raise ValueError("ChordModel: expected one calibrated classifier (ensemble=False)")
        cc = cal.calibrated_classifiers_[0]
        feats = pipe["histogram"]
        return cls(classes=tuple(str(c) for c in cal.classes_), chord_params=chord_params,
                   edges=feats.histogram_.edges_, power=float(feats.power),
                   coarse=int(feats.coarse), wrap_mean=feats.wrap_mean_,
                   wrap_scale=feats.wrap_scale_, extent_mean=feats.extent_mean_,
                   extent_scale=feats.extent_scale_, columns=pipe["occupied"].columns_,
                   pca_mean=pipe["pca"].mean_, pca_components=pipe["pca"].components_,
                   scale=float(pipe["scale"].scale_), coef=cc.estimator.coef_,
                   intercept=np.atleast_1d(cc.estimator.intercept_),
                   sigmoid_a=np.array([c.a_ for c in cc.calibrators], dtype=float),
                   sigmoid_b=np.array([c.b_ for c in cc.calibrators], dtype=float),
                   info=dict(info or {}), turn_invariant=bool(feats.turn_invariant))

    def bin_index(self, chords) -> np.ndarray:
        """(k,) flat histogram cell of each chord (k, 7) or ChordSet."""
        values = chords.values if isinstance(chords, ChordSet) else np.asarray(chords, float)
        return bin_index(values.reshape(-1, len(CHORD_PARAMETERS)), self.edges)

    def bin_centres(self, flat_index) -> np.ndarray:
        """(k, 7) chord parameters at the centres of the given cells."""
        return bin_centres(flat_index, self.edges)

    def features_from_bins(self, flat_indices, descriptor_slots=None, extents=None
                           ) -> sp.csr_matrix:
        """(n, d) sparse features restricted to the occupied columns, one row per array of
        fine flat cell indices: the histograms (chords.histogram_features, as the pipeline
        builds them, normalised before columns are dropped), the standardised wrap
        descriptor slots (n, n_planes * 7) and contact extents (n, 5), NaN where unknown;
        None: all unknown."""
        n = len(flat_indices)
        blocks = [histogram_features(flat_indices, self.bins, self.edges.shape[0],
                                     self.coarse, True, self.power)] + descriptor_blocks(
            n, ((descriptor_slots, self.wrap_mean, self.wrap_scale),
                (extents, self.extent_mean, self.extent_scale)))
        H = blocks[0] if len(blocks) == 1 else sp.hstack(blocks, format="csr")
        # H[:, self.columns] without scipy's column indexing (slow for 823,543 columns; this
        # runs in every step of active recognition's tree search).
        H = sp.csr_matrix(H)
        rows = np.repeat(np.arange(n), np.diff(H.indptr))
        pos = np.clip(np.searchsorted(self.columns, H.indices), 0, max(len(self.columns) - 1, 0))
        hit = self.columns[pos] == H.indices if len(self.columns) else np.zeros(0, bool)
        return sp.csr_matrix((H.data[hit], (rows[hit], pos[hit])), shape=(n, len(self.columns)))

    @cached_property
    def _projection(self) -> tuple[np.ndarray, np.ndarray]:
        """The PCA components as a C-ordered (d, k) array, and the projected mean: a sparse
        row times the transposed view copied all d x k entries at every call (4 ms of the
        tree search's every prediction; 0.01 ms now)."""
        return np.ascontiguousarray(self.pca_components.T), self.pca_mean @ self.pca_components.T

    def predict_proba_bins(self, flat_indices, descriptor_slots=None, extents=None
                           ) -> np.ndarray:
        """(n, C) probabilities from accumulated fine flat cell indices, one array an object
        (and optionally its descriptor slots and contact extents; without them, the
        training mean)."""
        X = self.features_from_bins(flat_indices, descriptor_slots, extents)
        components_t, mean_z = self._projection
        z = np.asarray(X @ components_t) - mean_z
        f = (z * self.scale) @ self.coef.T + self.intercept
        p = expit(-(self.sigmoid_a * f + self.sigmoid_b))
        if len(self.classes) == 2:
            proba = np.column_stack([1.0 - p[:, 0], p[:, 0]])
        else:
            den = p.sum(axis=1, keepdims=True)
            proba = np.divide(p, den, out=np.full_like(p, 1.0 / len(self.classes)),
                              where=den != 0)
        proba[(1.0 < proba) & (proba <= 1.0 + 1e-5)] = 1.0
        return proba

    def predict_proba(self, X) -> np.ndarray:
        """(n, C) probabilities, one row per input in X: an ObjectRecord (chords and wrap
        descriptors), or a chord array (k, 7) or ChordSet (an object's chords, or those
        accumulated so far in active recognition; descriptors at the training mean)."""
        parts = [object_parts(x, self.turn_invariant) for x in X]
        slots = np.array([wrap_slots(p[1], p[2], self.n_planes, self.turn_invariant)
                          for p in parts]).reshape(len(parts), -1) if len(self.wrap_mean) \
            else None
        extents = np.array([p[3] for p in parts]).reshape(len(parts), -1)
        return self.predict_proba_bins([self.bin_index(p[0]) for p in parts], slots, extents)

    def predict(self, X) -> np.ndarray:
        return self.classes_[np.argmax(self.predict_proba(X), axis=1)]


def train(objects, seed: int = 0, params: ChordParams | None = None,
          classifier: ClassifierParams = ClassifierParams()) -> ChordModel:
    """Fit the chord classifier on all objects and export it. `params` must be the
    ChordParams the objects' chords were made with (the default if None)."""
    import sklearn

    objects = list(objects)
    pipe = fit_pipeline(objects, [o.category for o in objects], "chords", seed, classifier)
    info = {"n_objects": len(objects), "seed": seed, "scikit_learn": sklearn.__version__,
            "n_components": int(pipe["pca"].n_components_),
            "n_occupied_cells": int(len(pipe["occupied"].columns_)),
            "n_planes": int(pipe["histogram"].n_planes_)}
    return ChordModel.from_pipeline(pipe, params or ChordParams(), info)


def classify_wraps(model: ChordModel, wraps) -> tuple[str, np.ndarray]:
    """(category, (C,) probabilities in model.classes_ order) of an object from its wraps
    (chords and wrap descriptors)."""
    record = object_record("", "", list(wraps), model.chord_params)
    proba = model.predict_proba([record])[0]
    return str(model.classes[int(np.argmax(proba))]), proba


@dataclass(frozen=True)
class Classification:
    """The category of one object.

    Args:
        category: the most probable category.
        probabilities: category -> probability, most probable first.
        n_wraps: usable wraps the decision rests on.
    """

    category: str
    probabilities: dict
    n_wraps: int


def classify(model: ChordModel, wraps) -> Classification:
    """Classify one object from its wraps: one a plane the model knows, in plane order (its
    wrap descriptors are kept a plane, as in training)."""
    _, proba = classify_wraps(model, wraps)
    order = np.argsort(proba)[::-1]
    return Classification(category=str(model.classes[order[0]]),
                          probabilities={str(model.classes[i]): float(proba[i]) for i in order},
                          n_wraps=int(sum(w.usable for w in wraps)))


def save_model(model: ChordModel, folder) -> None:
    """model.npz (arrays) then model.json (everything else, with format_version) in folder;
    each written atomically, the JSON last so a complete JSON means a complete model."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    arrays = {k: np.asarray(getattr(model, k)) for k in ChordModel._ARRAYS}
    write_atomic(folder / "model.npz", lambda f: np.savez(f, **arrays))
    meta = {"format_version": FORMAT_VERSION, "kind": MODEL_KIND,
            "classes": list(model.classes), "chord_params": model.chord_params.to_dict(),
            "chord_parameters": list(CHORD_PARAMETERS),
            "wrap_descriptors": list(WRAP_DESCRIPTORS),
            "contact_extent": list(CONTACT_EXTENT), "scale": model.scale,
            "power": model.power, "coarse": model.coarse,
            "turn_invariant": model.turn_invariant, "info": model.info,
            "array_shapes": array_shapes(arrays)}
    write_json(folder / "model.json", {**meta, "sha256": model_digest(arrays, meta)})


def check_saved_arrays(where: str, meta: dict, arrays: dict, retrain: str) -> None:
    """The arrays of a saved model against the shapes and SHA-256 written with them
    (files.array_shapes; files.model_digest of the arrays and every other entry of `meta`): a
    model whose files were edited, mixed with another model's or damaged is refused naming
    `where`, never used."""
    shapes = meta.get("array_shapes")
    if not isinstance(shapes, dict) or not isinstance(meta.get("sha256"), str):
        raise ModelFormatError(f"{where}: damaged model (no array shapes or checksum); "
                               f"{retrain}")
    for name in sorted(set(shapes) | set(arrays)):
        if name not in arrays or name not in shapes \
                or list(np.shape(arrays[name])) != list(shapes[name]):
            raise ModelFormatError(
                f"{where}: damaged model (array {name!r} has shape "
                f"{list(np.shape(arrays[name])) if name in arrays else 'missing'}, the model "
                f"records {shapes.get(name, 'none')}); {retrain}")
    rest = {k: v for k, v in meta.items() if k != "sha256"}
    if model_digest(arrays, rest) != meta["sha256"]:
        raise ModelFormatError(f"{where}: damaged model (its SHA-256 differs from the one "
                               f"recorded when it was saved); {retrain}")


def load_model(folder) -> ChordModel:
    """Load a model saved by save_model; no pickle is read. Raises ModelFormatError naming
    the folder if it is missing, damaged or of another format version."""
    folder = Path(folder)
    try:
        meta = json.loads((folder / "model.json").read_text())
    except (OSError, ValueError) as e:
        raise ModelFormatError(f"{folder}: not a drake-continuum model folder "
                               f"(model.json: {e})") from None
    version = meta.get("format_version") if isinstance(meta, dict) else None
    if version != FORMAT_VERSION:
        raise ModelFormatError(f"{folder}: model format version {version} cannot be read by "
                               f"this drake-continuum, which reads format version "
                               f"{FORMAT_VERSION}; retrain with `drake-continuum train`")
    retrain = "retrain with `drake-continuum train`"
    try:
        with np.load(folder / "model.npz", allow_pickle=False) as z:
            arrays = {k: np.array(z[k]) for k in z.files}
        check_saved_arrays(str(folder), meta, arrays, retrain)
        arrays = {k: arrays[k] for k in ChordModel._ARRAYS}
        model = ChordModel(classes=tuple(meta["classes"]),
                           chord_params=ChordParams.from_dict(meta["chord_params"]),
                           scale=float(meta["scale"]), power=float(meta["power"]),
                           coarse=int(meta["coarse"]), info=dict(meta.get("info", {})),
                           turn_invariant=bool(meta.get("turn_invariant", False)), **arrays)
    except ModelFormatError:
        raise
    except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile) as e:
        raise ModelFormatError(f"{folder}: damaged model ({type(e).__name__}: {e}); "
                               f"{retrain}") from None
    k, d = model.pca_components.shape
    n_features = (model.n_cells + (model.coarse ** len(CHORD_PARAMETERS) if model.coarse
                                   else 0) + len(model.wrap_mean) + len(model.extent_mean))
    n_svm = 1 if len(model.classes) == 2 else len(model.classes)
    if (model.edges.shape[0] != len(CHORD_PARAMETERS) or len(model.columns) != d
            or model.coef.shape != (n_svm, k) or len(model.classes) < 2
            or not len(model.intercept) == len(model.sigmoid_a) == len(model.sigmoid_b) == n_svm
            or len(model.pca_mean) != d
            or not 0 <= model.coarse <= model.bins
            or len(model.wrap_scale) != len(model.wrap_mean)
            or len(model.wrap_mean) % len(WRAP_DESCRIPTORS)
            or (model.turn_invariant and len(model.wrap_mean) not in
                (0, 2 * len(WRAP_DESCRIPTORS)))
            or len(model.extent_scale) != len(model.extent_mean)
            or len(model.extent_mean) not in (0, len(CONTACT_EXTENT))
            or (d and not 0 <= model.columns.min() <= model.columns.max() < n_features)):
        raise ModelFormatError(f"{folder}: damaged model (its arrays do not fit each other or "
                               f"its {len(model.classes)} classes); {retrain}")
    return model
