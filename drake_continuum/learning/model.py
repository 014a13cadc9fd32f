"""The trained classifier as plain arrays (ChordModel, numpy-only prediction) and its
files, model.json + model.npz, safe to share (no pickle).
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.special import expit
from sklearn.pipeline import Pipeline

from ..config import Config
from ..errors import DrakeContinuumError, InputError
from ..features.cells import CellCounts
from ..features.chords import (
    CHORD_PARAMETERS,
    CONTACT_EXTENT,
    WRAP_DESCRIPTORS,
    ChordParams,
    ChordSet,
    bin_centres,
    bin_index,
    coarse_index,
    histogram_features,
)
from ..files import array_shapes, model_digest, write_atomic, write_json
from ..perception.locate import VIEW_EXTENT
from .pipeline import (
    BLOCKS,
    SideMixture,
    class_category,
    descriptor_blocks,
    fit_pipeline,
    is_rest_class,
    merge_classes,
    object_parts,
    stands_as_generated,
    wrap_slots,
)
from .projection import kept_column_entries, project_rows
from .records import object_record

__all__ = ["FORMAT_VERSION", "MODEL_KIND", "ModelFormatError", "ChordModel", "train",
           "classify_wraps", "Classification", "classify", "check_saved_arrays", "save_model",
           "load_model"]


FORMAT_VERSION = 7  # 2: Hellinger map; 3: coarse histogram, wrap descriptors; 4: contact
#                    extent; 5: array shapes and their SHA-256 in model.json; 6: the SVM's
#                    own classes (rest classes) in model.json, the camera view block; 7: the
#                    standing model (pipeline.SideMixture), its arrays prefixed "standing."
STANDING = "standing."  # prefix of the standing model's arrays in model.npz
MODEL_KIND = "drake-continuum chord classifier"

class ModelFormatError(DrakeContinuumError):
    """A model folder is missing, damaged or of another format version."""


# ---------------------------------------------------------------- the portable model

def _is_counted(row) -> bool:
    """Whether a row of cells is given as a tuple of CellCounts (features.cells)."""
    return isinstance(row, tuple) and all(isinstance(p, CellCounts) for p in row)


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
        view_mean, view_scale: (3,) standardisation of the camera's view (empty without
            it).
        columns: (d,) feature columns occupied in training (sorted): fine cells, then
            bins ** 7 + coarse cells, then bins ** 7 + coarse ** 7 + descriptor slots, then
            the contact extent, then the view.
        pca_mean: (d,) and pca_components: (k, d): the PCA.
        scale: the global feature scale after PCA.
        coef: (K, k) and intercept: (K,): the linear SVM (K = C, or 1 for two classes).
        sigmoid_a, sigmoid_b: (K,) Platt calibration: p = 1 / (1 + exp(a f + b)).
        info: training facts (objects, seed, versions), stored as JSON.
        turn_invariant: wrap descriptors pooled over planes, the extent's horizontal ranges
            along the contacts' axes (ClassifierParams.turn_invariant).
        svm_classes: the SVM's classes (K) when they are not the categories: a category's
            rest class counts for it (pipeline.CategoryClassifier); () when they are.
        standing: the model of the objects standing as generated, mixed in by this one's
            probability of its rest classes (pipeline.SideMixture); same categories, chord
            parameters, bin edges and planes. None: this model alone.
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
    view_mean: np.ndarray
    view_scale: np.ndarray
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
    svm_classes: tuple = ()
    standing: "ChordModel | None" = None

    _ARRAYS = ("edges", "wrap_mean", "wrap_scale", "extent_mean", "extent_scale", "view_mean",
               "view_scale", "columns",
               "pca_mean", "pca_components", "coef", "intercept", "sigmoid_a", "sigmoid_b")

    @property
    def classes_(self) -> np.ndarray:
        return np.array(self.classes)

    @cached_property
    def class_of(self) -> np.ndarray:
        """(K,) the category (index into classes) each of the SVM's classes counts for."""
        if not self.svm_classes:
            return np.arange(len(self.classes))
        return np.array([self.classes.index(class_category(c)) for c in self.svm_classes])

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
    def from_pipeline(cls, pipe: "Pipeline | SideMixture", chord_params: ChordParams,
                      info=None) -> "ChordModel":
        if isinstance(pipe, SideMixture):
            standing = cls.from_pipeline(pipe.standing_, chord_params)
            return replace(cls.from_pipeline(pipe.full_, chord_params, info), standing=standing)
        cal = pipe["svm"].estimator_
        if len(cal.calibrated_classifiers_) != 1:
            raise ValueError("ChordModel: expected one calibrated classifier (ensemble=False)")
        cc = cal.calibrated_classifiers_[0]
        feats = pipe["histogram"]
        classes = tuple(str(c) for c in pipe["svm"].classes_)
        svm_classes = tuple(str(c) for c in cal.classes_)
        return cls(classes=classes, svm_classes=() if svm_classes == classes else svm_classes,
                   chord_params=chord_params,
                   edges=feats.histogram_.edges_, power=float(feats.power),
                   coarse=int(feats.coarse), wrap_mean=feats.wrap_mean_,
                   wrap_scale=feats.wrap_scale_, extent_mean=feats.extent_mean_,
                   extent_scale=feats.extent_scale_, view_mean=feats.view_mean_,
                   view_scale=feats.view_scale_, columns=pipe["occupied"].columns_,
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

    @property
    def takes_cell_counts(self) -> bool:
        """predict_proba_bins takes an object's cells as a tuple of CellCounts."""
        return True

    @property
    def uses_view(self) -> bool:
        """Whether the camera's view of the object is one of the features."""
        return len(self.view_mean) > 0

    @property
    def blocks(self) -> dict:
        """The feature blocks this model uses, each with what it needs (pipeline.BLOCKS)."""
        used = {"histogram": True, "wrap": len(self.wrap_mean) > 0,
                "extent": len(self.extent_mean) > 0, "view": self.uses_view}
        return {k: BLOCKS[k] for k, u in used.items() if u}

    @property
    def needs_object_visible(self) -> tuple:
        """The blocks that need the camera to see the object: a transparent object is
        classified only by a model without them (ClassifierParams.touch_only)."""
        return tuple(k for k, need in self.blocks.items() if need != "touch")

    def features_from_bins(self, flat_indices, *, descriptor_slots=None, extents=None,
                           views=None) -> sp.csr_matrix:
        """(n, d) sparse features restricted to the occupied columns, one row per array of
        fine flat cell indices: the histograms (chords.histogram_features, as the pipeline
        builds them, normalised before columns are dropped), the standardised wrap
        descriptor slots (n, n_planes * 7), contact extents (n, 5) and camera views (n, 3),
        NaN where unknown; None: all unknown."""
        n = len(flat_indices)
        blocks = [histogram_features(flat_indices, self.bins, self.edges.shape[0],
                                     coarse=self.coarse, power=self.power)] + descriptor_blocks(
            n, self._descriptor_sources(descriptor_slots, extents, views))
        H = blocks[0] if len(blocks) == 1 else sp.hstack(blocks, format="csr")
        # H[:, self.columns] without scipy's column indexing (slow for 823,543 columns; this
        # runs in every step of active recognition's tree search).
        H = sp.csr_matrix(H)
        rows = np.repeat(np.arange(n), np.diff(H.indptr))
        pos = np.clip(np.searchsorted(self.columns, H.indices), 0, max(len(self.columns) - 1, 0))
        hit = self.columns[pos] == H.indices if len(self.columns) else np.zeros(0, bool)
        return sp.csr_matrix((H.data[hit], (rows[hit], pos[hit])), shape=(n, len(self.columns)))

    def _descriptor_sources(self, descriptor_slots, extents, views) -> tuple:
        """(values, mean, scale) of each block after the histograms, in feature order."""
        return ((descriptor_slots, self.wrap_mean, self.wrap_scale),
                (extents, self.extent_mean, self.extent_scale),
                (views, self.view_mean, self.view_scale))

    @cached_property
    def _projection(self) -> tuple[np.ndarray, np.ndarray]:
        """The PCA components as a C-ordered (d, k) array, and the projected mean: a sparse
        row times the transposed view would copy all d x k entries at every call (4 ms of
        each of the tree search's predictions, against 0.01 ms)."""
        return np.ascontiguousarray(self.pca_components.T), self.pca_mean @ self.pca_components.T

    def predict_proba_bins(self, flat_indices, *, descriptor_slots=None, extents=None,
                           views=None) -> np.ndarray:
        """(n, C) probabilities from accumulated fine flat cell indices, one array an object
        or a tuple of CellCounts (features.cells) whose sum they are (and optionally its
        descriptor slots, contact extents and camera views; without them, the training
        mean). With a standing model, the mixture (1 - q) P_standing +
        q P_this, q this model's probability of its rest classes (pipeline.SideMixture)."""
        proba = self._class_proba(flat_indices, descriptor_slots, extents, views=views)
        merged = merge_classes(proba, self.class_of, len(self.classes)) if self.svm_classes \
            else proba
        if self.standing is not None:
            q = proba[:, [is_rest_class(c) for c in self.svm_classes]].sum(axis=1)[:, None]
            merged = (1.0 - q) * self.standing.predict_proba_bins(
                flat_indices, descriptor_slots=descriptor_slots, extents=extents,
                views=views) + q * merged
        merged[(1.0 < merged) & (merged <= 1.0 + 1e-5)] = 1.0
        return merged

    def _row_entries(self, flat_index) -> tuple[np.ndarray, np.ndarray]:
        """The histogram entries of one row of features_from_bins (fine cells, then coarse)
        as (positions in self.columns, values) in column order, built with numpy alone:
        scipy's sparse constructors cost ~3 ms a call, most of each of the tree search's
        predictions. flat_index: the row's fine cells, or a tuple of CellCounts."""
        if _is_counted(flat_index):
            flat_index = np.concatenate([p.multiset() for p in flat_index] or
                                        [np.zeros(0, np.int64)])
        d = self.edges.shape[0]
        cols, vals = [], []
        f = np.asarray(flat_index, dtype=np.int64)
        blocks = [(f, 0)]
        if self.coarse:
            blocks.append((coarse_index(f, self.bins, d, coarse=self.coarse), self.bins ** d))
        for cells, offset in blocks:
            if len(cells):
                uniq, c = np.unique(cells, return_counts=True)
                cols.append(uniq + offset)
                vals.append(self._powered(c / np.int64(len(cells))))
        if not cols or not len(self.columns):
            return np.zeros(0, np.int64), np.zeros(0)
        cols, vals = np.concatenate(cols), np.concatenate(vals)
        pos = np.minimum(np.searchsorted(self.columns, cols), len(self.columns) - 1)
        hit = self.columns[pos] == cols
        return pos[hit], vals[hit]

    def _powered(self, v: np.ndarray) -> np.ndarray:
        return v ** self.power if self.power != 1.0 else v

    @cached_property
    def _described_at(self) -> np.ndarray:
        """(s,) the row of each descriptor column (wrap slots, extent, view) among
        self.columns; -1 where training left it empty."""
        d = self.edges.shape[0]
        start = self.bins ** d + (self.coarse ** d if self.coarse else 0)
        cols = start + np.arange(len(self.wrap_mean) + len(self.extent_mean)
                                 + len(self.view_mean))
        if not len(self.columns):
            return np.full(len(cols), -1, np.int64)
        pos = np.minimum(np.searchsorted(self.columns, cols), len(self.columns) - 1)
        return np.where(self.columns[pos] == cols, pos, -1).astype(np.int64)

    def _projected(self, flat_indices, descriptor_slots, extents, *, views) -> np.ndarray:
        """(n, k) the PCA projection of features_from_bins' rows, X @ components - mean,
        summed entry by entry in column order as scipy's sparse product sums them (so equal
        to it to the bit) without building X (projection.project_rows). Rows given as
        CellCounts (without a coarse block) have their entries gathered compiled."""
        n = len(flat_indices)
        described = descriptor_blocks(n, self._descriptor_sources(descriptor_slots, extents,
                                                                  views), dense=True)
        described = np.hstack(described) if described else np.zeros((n, 0))
        components_t, mean_z = self._projection
        if not self.coarse and all(map(_is_counted, flat_indices)):
            row_ptr, pos, counts, totals = kept_column_entries(flat_indices, self.columns)
            vals = self._powered(counts / np.repeat(totals, np.diff(row_ptr)))
        else:
            entries = [self._row_entries(cells) for cells in flat_indices]
            row_ptr = np.r_[0, np.cumsum([len(p) for p, _ in entries])].astype(np.int64)
            pos = np.concatenate([p for p, _ in entries] or [np.zeros(0, np.int64)])
            vals = np.concatenate([v for _, v in entries] or [np.zeros(0)])
        return project_rows(row_ptr, pos, vals, described=described,
                            described_at=self._described_at,
                            components_t=components_t) - mean_z

    def _class_proba(self, flat_indices, descriptor_slots, extents, *, views) -> np.ndarray:
        """(n, K) the SVM's calibrated probabilities of its own classes."""
        z = self._projected(flat_indices, descriptor_slots, extents, views=views)
        f = (z * self.scale) @ self.coef.T + self.intercept
        p = expit(-(self.sigmoid_a * f + self.sigmoid_b))
        if len(self.class_of) == 2:
            proba = np.column_stack([1.0 - p[:, 0], p[:, 0]])
        else:
            den = p.sum(axis=1, keepdims=True)
            proba = np.divide(p, den, out=np.full_like(p, 1.0 / len(self.class_of)),
                              where=den != 0)
        return proba

    def predict_proba(self, X) -> np.ndarray:
        """(n, C) probabilities, one row per input in X: an ObjectRecord (chords and wrap
        descriptors), or a chord array (k, 7) or ChordSet (an object's chords, or those
        accumulated so far in active recognition; descriptors at the training mean)."""
        parts = [object_parts(x, self.turn_invariant) for x in X]
        slots = np.array([wrap_slots(p[1], p[2], self.n_planes, turn_invariant=self.turn_invariant)
                          for p in parts]).reshape(len(parts), -1) if len(self.wrap_mean) \
            else None
        extents = np.array([p[3] for p in parts]).reshape(len(parts), -1)
        views = np.array([p[4] for p in parts]).reshape(len(parts), -1)
        return self.predict_proba_bins([self.bin_index(p[0]) for p in parts],
                                       descriptor_slots=slots, extents=extents,
                                       views=views)

    def predict(self, X) -> np.ndarray:
        return self.classes_[np.argmax(self.predict_proba(X), axis=1)]


def train(objects, scenario: Config | None = None, *, seed: int = 0) -> ChordModel:
    """Fit the chord classifier on all objects and export it, with the scenario's classifier
    section (default: the shipped configuration, Config()). Its chords section must be the
    ChordParams the objects' chords were made with."""
    import sklearn

    scenario = Config() if scenario is None else scenario
    params, classifier = scenario.chords, scenario.classifier
    objects = list(objects)
    made = {getattr(o, "chord_params", None) for o in objects} - {None}
    if made - {params}:
        raise InputError(
            f"train: the objects' chords were taken with {', '.join(map(repr, made))}, the "
            f"scenario's chords section is {params!r}: the model would take a new object's "
            f"chords otherwise than it was trained on; read the wraps with the scenario's, "
            f"load_wraps(folder, scenario.chords)")
    fitted = fit_pipeline(objects, [o.category for o in objects], method="chords", seed=seed,
                          params=classifier)
    mixed = isinstance(fitted, SideMixture)
    pipe = fitted.full_ if mixed else fitted
    info = {"n_objects": len(objects), "seed": seed, "scikit_learn": sklearn.__version__,
            "n_components": int(pipe["pca"].n_components_),
            "n_occupied_cells": int(len(pipe["occupied"].columns_)),
            "n_planes": int(pipe["histogram"].n_planes_)}
    if mixed:
        info["n_standing_objects"] = int(sum(map(stands_as_generated, objects)))
    return ChordModel.from_pipeline(fitted, params, info)


def classify_wraps(model: ChordModel, wraps, view=None) -> tuple[str, np.ndarray]:
    """(category, (C,) probabilities in model.classes_ order) of an object from its wraps
    (chords and wrap descriptors) and the camera's view of it (perception.locate.view_extent;
    InputError if the model uses the view and none is given)."""
    if model.uses_view and view is None:
        raise InputError("this model classifies with the depth camera's view of the object "
                         "(its height and footprint): give the view")
    record = object_record("", "", list(wraps), params=model.chord_params, view=view)
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


def classify(model: ChordModel, wraps, view=None) -> Classification:
    """Classify one object from its wraps: one a plane the model knows, in plane order (its
    wrap descriptors are kept a plane, as in training), and the camera's view of it."""
    _, proba = classify_wraps(model, wraps, view)
    order = np.argsort(proba)[::-1]
    return Classification(category=str(model.classes[order[0]]),
                          probabilities={str(model.classes[i]): float(proba[i]) for i in order},
                          n_wraps=int(sum(w.usable for w in wraps)))


def _own_meta(model: ChordModel) -> dict:
    """The JSON entries of one model (the standing model has its own)."""
    return {"classes": list(model.classes), "chord_params": model.chord_params.to_dict(),
            "scale": model.scale, "power": model.power, "coarse": model.coarse,
            "turn_invariant": model.turn_invariant, "info": model.info,
            "svm_classes": list(model.svm_classes)}


def save_model(model: ChordModel, folder) -> None:
    """model.npz (arrays, the standing model's prefixed STANDING) then model.json
    (everything else, with format_version) in folder; each written atomically, the JSON
    last so a complete JSON means a complete model."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    arrays = {k: np.asarray(getattr(model, k)) for k in ChordModel._ARRAYS}
    meta = {"format_version": FORMAT_VERSION, "kind": MODEL_KIND,
            "chord_parameters": list(CHORD_PARAMETERS),
            "wrap_descriptors": list(WRAP_DESCRIPTORS),
            "contact_extent": list(CONTACT_EXTENT), "view_extent": list(VIEW_EXTENT),
            **_own_meta(model)}
    if model.standing is not None:
        arrays.update({STANDING + k: np.asarray(getattr(model.standing, k))
                       for k in ChordModel._ARRAYS})
        meta["standing"] = _own_meta(model.standing)
    meta["array_shapes"] = array_shapes(arrays)
    write_atomic(folder / "model.npz", lambda f: np.savez(f, **arrays))
    write_json(folder / "model.json", {**meta, "sha256": model_digest(arrays, meta)})


def check_saved_arrays(where: str, meta: dict, arrays: dict, *, retrain: str) -> None:
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
        check_saved_arrays(str(folder), meta, arrays, retrain=retrain)
        model = _model_from(meta, arrays, "")
        if meta.get("standing") is not None:
            model = replace(model, standing=_model_from(meta["standing"], arrays, STANDING))
    except ModelFormatError:
        raise
    except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile) as e:
        raise ModelFormatError(f"{folder}: damaged model ({type(e).__name__}: {e}); "
                               f"{retrain}") from None
    _check_fit(model, folder, retrain)
    if model.standing is not None:
        _check_fit(model.standing, folder, retrain)
        s = model.standing
        if (s.classes != model.classes or s.chord_params != model.chord_params
                or not np.array_equal(s.edges, model.edges) or s.n_planes != model.n_planes
                or s.turn_invariant != model.turn_invariant or s.standing is not None
                or not any(is_rest_class(c) for c in model.svm_classes)):
            raise ModelFormatError(f"{folder}: damaged model (its standing model does not "
                                   f"match it: categories, chord parameters, bin edges, planes "
                                   f"or rest classes differ); {retrain}")
    return model


def _model_from(meta: dict, arrays: dict, prefix: str) -> ChordModel:
    """One model from its JSON entries and its (prefixed) arrays."""
    return ChordModel(classes=tuple(meta["classes"]),
                      chord_params=ChordParams.from_dict(meta["chord_params"]),
                      scale=float(meta["scale"]), power=float(meta["power"]),
                      coarse=int(meta["coarse"]), info=dict(meta.get("info", {})),
                      turn_invariant=bool(meta.get("turn_invariant", False)),
                      svm_classes=tuple(str(c) for c in meta.get("svm_classes", [])),
                      **{k: arrays[prefix + k] for k in ChordModel._ARRAYS})


def _check_fit(model: ChordModel, folder, retrain: str) -> None:
    """ModelFormatError naming folder unless the model's arrays fit each other and its
    classes."""
    k, d = model.pca_components.shape
    n_features = (model.n_cells + (model.coarse ** len(CHORD_PARAMETERS) if model.coarse
                                   else 0) + len(model.wrap_mean) + len(model.extent_mean)
                  + len(model.view_mean))
    n_classes = len(model.svm_classes or model.classes)
    n_svm = 1 if n_classes == 2 else n_classes
    if (model.svm_classes and (sorted({class_category(c) for c in model.svm_classes})
                               != sorted(model.classes) or len(set(model.svm_classes))
                               != len(model.svm_classes))):
        raise ModelFormatError(f"{folder}: damaged model (its SVM's classes "
                               f"{list(model.svm_classes)} do not count for exactly its "
                               f"categories {list(model.classes)}); {retrain}")
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
            or len(model.view_scale) != len(model.view_mean)
            or len(model.view_mean) not in (0, len(VIEW_EXTENT))
            or (d and not 0 <= model.columns.min() <= model.columns.max() < n_features)):
        raise ModelFormatError(f"{folder}: damaged model (its arrays do not fit each other or "
                               f"its {len(model.classes)} classes); {retrain}")
