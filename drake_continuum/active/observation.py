"""The observation model (paper IV-D.2): tallies of which training wrap follows which, a
class and a plane, and its files (observations.json + .npz).

A training wrap is one observation z, identified by its index. It is stored discretised at
histogram bin centres (occupied bin indices with counts), which rebuilds its histogram
exactly. Every ordered pair (i, j) of wraps of one training object is a tally for
p(z' = j | z = i, a = plane(j), y = class of the object). The action is the *target plane*,
so an action means the same on every object and its cost is the rotation angle from the
current plane. An observation that is not in the tallies (the real wrap at the root, or a
training wrap of another class) is matched to the `neighbours` training wraps of class y on
the same plane whose histograms are most similar (cosine of bin counts): p(z'|z, a, y) is the
tally of their successors on plane a. Before the first wrap there is no z, and p(z'|a, y) is
uniform over the training wraps of class y on plane a. Each training wrap keeps its contact
centres, so that a tree path's contact extent is that of the wraps on it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Sequence

import numpy as np
import scipy.sparse as sp
from numba import njit

from ..errors import InputError, MissingFileError
from ..features.cells import CellCounts, cell_rows, contact_bounds
from ..features.chords import bin_centres, bin_index
from ..files import array_shapes, model_digest, write_atomic, write_json
from ..kinematics.jit import CACHE
from .params import (
    N_CHORD_DIMS,
    ChordClassifier,
    ObjectWraps,
    bin_histograms,
    chord_edges,
    n_cells,
    plane_cost_matrix,
    unit_rows,
)

__all__ = ["ObservationModel", "fit_observation_model", "save_observation_model",
           "load_observation_model", "ActiveModel"]


FORMAT_VERSION = 3  # 2: array shapes and their SHA-256 in observations.json; 3: contacts
_KIND = "drake_continuum.active.observation_model"
# --------------------------------------------------------------------------- observation model

@dataclass(frozen=True, eq=False)
class ObservationModel:
    """Training observations and the tallies of p(z' | z, a, y).

    Args:
        classes: (C,) category names, in the classifier's column order.
        object_names: (O,) training object ids; object_class: (O,) class index of each.
        plane_normals: (P, 3) unit normals of the wrap planes.
        edges: (7, bins + 1) histogram bin edges (the classifier's, fitted on training data).
        obs_object, obs_plane: (n,) object and plane of each training wrap.
        obs_indptr: (n + 1,) CSR pointer into obs_cells / obs_counts.
        obs_cells: (nnz,) occupied flat histogram cells; obs_counts: (nnz,) chords in each.
        pair_from, pair_to: (m,) the tallies: every ordered pair of wraps of one object.
        contact_indptr: (n + 1,) pointer into contacts; contacts: (M, 3) each training wrap's
            contact centres (none where unknown).
        neighbours: training wraps of a class matched to an observation.
    """

    classes: np.ndarray
    object_names: np.ndarray
    object_class: np.ndarray
    plane_normals: np.ndarray
    edges: np.ndarray
    obs_object: np.ndarray
    obs_plane: np.ndarray
    obs_indptr: np.ndarray
    obs_cells: np.ndarray
    obs_counts: np.ndarray
    pair_from: np.ndarray
    pair_to: np.ndarray
    contact_indptr: np.ndarray
    contacts: np.ndarray
    neighbours: int = 5

    @property
    def n_observations(self) -> int:
        return len(self.obs_object)

    @property
    def n_planes(self) -> int:
        return len(self.plane_normals)

    @property
    def n_classes(self) -> int:
        return len(self.classes)

    @cached_property
    def obs_class(self) -> np.ndarray:
        return self.object_class[self.obs_object]

    @cached_property
    def pair_action(self) -> np.ndarray:
        """(m,) action of each tally: the target plane."""
        return self.obs_plane[self.pair_to]

    @cached_property
    def pair_cost(self) -> np.ndarray:
        """(m,) movement cost of each tally, rad."""
        return self.cost_matrix[self.obs_plane[self.pair_from], self.pair_action]

    @cached_property
    def cost_matrix(self) -> np.ndarray:
        return plane_cost_matrix(self.plane_normals)

    @cached_property
    def class_prior(self) -> np.ndarray:
        """(C,) class frequencies of the training objects: p(y | h_0) before any wrap."""
        counts = np.bincount(self.object_class, minlength=self.n_classes).astype(float)
        return counts / counts.sum()

    @cached_property
    def histograms(self) -> sp.csr_matrix:
        """(n, n_cells) unit-norm chord counts of each training wrap."""
        m = sp.csr_matrix((self.obs_counts.astype(float), self.obs_cells, self.obs_indptr),
                          shape=(self.n_observations, n_cells(self.edges)))
        return unit_rows(m)

    @cached_property
    def successor(self) -> np.ndarray:
        """(n, P) the tallied successor of wrap i under action a (-1: none)."""
        s = np.full((self.n_observations, self.n_planes), -1, dtype=np.int64)
        s[self.pair_from, self.pair_action] = self.pair_to
        return s

    def cells(self, i: int) -> np.ndarray:
        """(k,) histogram cell of each chord of training wrap i (the multiset)."""
        return self.cell_counts(i).multiset()

    def cell_counts(self, i: int) -> CellCounts:
        """The cells of training wrap i as CellCounts (its row of obs_cells and obs_counts:
        cells.cell_rows), made once a model: their places among a classifier's columns are
        then looked up once too."""
        got = self._parts.get(i)
        if got is None:
            lo, hi = self.obs_indptr[i], self.obs_indptr[i + 1]
            got = self._parts[i] = CellCounts(self.obs_cells[lo:hi], self.obs_counts[lo:hi])
        return got

    def contact_bounds(self, i: int) -> np.ndarray | None:
        """chords.contact_bounds of training wrap i's contact centres (None: none known),
        made once a model."""
        if i not in self._bounds:
            points = self.contact_points(i)
            self._bounds[i] = contact_bounds(points) if len(points) else None
        return self._bounds[i]

    @cached_property
    def _parts(self) -> dict:
        return {}

    @cached_property
    def _bounds(self) -> dict:
        return {}

    @cached_property
    def histograms_t(self) -> sp.csr_matrix:
        """histograms.T in CSR, the form a product with it takes (made once, not a wrap)."""
        return sp.csr_matrix(self.histograms.T)

    def contact_points(self, i: int) -> np.ndarray:
        """(m, 3) contact centres of training wrap i (none where unknown)."""
        return self.contacts[self.contact_indptr[i]:self.contact_indptr[i + 1]]

    def centres(self, i: int) -> np.ndarray:
        """(k, 7) chords of training wrap i, at their bin centres."""
        return bin_centres(self.cells(i), self.edges)

    def discretise(self, chords: np.ndarray) -> sp.csr_matrix:
        """(1, n_cells) unit-norm chord counts of a new wrap."""
        return unit_rows(bin_histograms([chords], self.edges))

    def successors_of(self, similarity: np.ndarray, plane: int) -> tuple[np.ndarray, np.ndarray]:
        """Candidates z' of p(z'|z, a, y) for observations z on one plane.

        Args:
            similarity: (r, n) histogram similarity of r observations to every training wrap.
            plane: the plane of the r observations.
        Returns:
            succ (r, C, P, K) training wrap ids, -1 padded; count (r, C, P) valid entries.
        """
        K = self.neighbours
        on_plane = np.flatnonzero(self.obs_plane == plane)
        r = similarity.shape[0]
        succ = np.full((r, self.n_classes, self.n_planes, K), -1, dtype=np.int64)
        if len(on_plane) == 0:
            return succ, np.zeros((r, self.n_classes, self.n_planes), dtype=np.int64)
        order = np.argsort(-similarity[:, on_plane], axis=1, kind="stable")
        cand = on_plane[order]                                   # (r, n_p), best match first
        count = np.zeros((r, self.n_classes, self.n_planes), dtype=np.int64)
        _first_successors(self.successor[cand], self.obs_class[cand], succ, count)
        return succ, count

    @cached_property
    def training_successors(self) -> tuple[np.ndarray, np.ndarray]:
        """successors_of for every training wrap: (n, C, P, K) and (n, C, P)."""
        succ = np.full((self.n_observations, self.n_classes, self.n_planes, self.neighbours), -1,
                       dtype=np.int64)
        X = self.histograms
        for p in np.unique(self.obs_plane):
            rows = np.flatnonzero(self.obs_plane == p)
            sim = (X[rows] @ self.histograms_t).toarray()
            succ[rows] = self.successors_of(sim, int(p))[0]
        return succ, (succ >= 0).sum(axis=3)

    @cached_property
    def initial_successors(self) -> tuple[np.ndarray, np.ndarray]:
        """p(z'|a, y) before any wrap: every training wrap of class y on plane a."""
        groups = [[np.flatnonzero((self.obs_class == y) & (self.obs_plane == a))
                   for a in range(self.n_planes)] for y in range(self.n_classes)]
        K = max(1, max(len(g) for row in groups for g in row))
        succ = np.full((self.n_classes, self.n_planes, K), -1, dtype=np.int64)
        for y, row in enumerate(groups):
            for a, g in enumerate(row):
                succ[y, a, :len(g)] = g
        return succ, (succ >= 0).sum(axis=2)


@njit(cache=CACHE)
def _first_successors(successor, cls, succ, count):
    """succ[i, y, a, :count[i, y, a]]: the tallied successors under action a of the first
    (at most K) candidates of class y of observation i, in candidate order (successor
    (r, n, P), -1: none; cls (r, n))."""
    K = succ.shape[3]
    for i in range(successor.shape[0]):
        for j in range(successor.shape[1]):
            y = cls[i, j]
            for a in range(successor.shape[2]):
                z = successor[i, j, a]
                if z >= 0 and count[i, y, a] < K:
                    succ[i, y, a, count[i, y, a]] = z
                    count[i, y, a] += 1


def fit_observation_model(objects: Sequence[ObjectWraps], classes: Sequence[str], edges,
                          *, plane_normals: np.ndarray, neighbours: int = 5) -> ObservationModel:
    """Tally the training wraps (IV-D.2): discretise every wrap, pair the wraps of each object.

    Args:
        objects: training objects with their usable wraps.
        classes: category names in the classifier's column order (`classifier.classes_`).
        edges: the classifier's fitted bin edges, (7, bins + 1).
        plane_normals: (P, 3) wrap-plane normals (planes.py).
        neighbours: see ObservationModel.
    """
    edges = chord_edges(edges)
    classes = np.asarray([str(c) for c in classes])
    index = {c: k for k, c in enumerate(classes)}
    missing = sorted({o.label for o in objects} - set(index))
    if missing:
        raise InputError(f"observation model: labels {missing} are not classifier classes")
    P = len(plane_normals)
    obs_object, obs_plane, counted = [], [], []
    points, point_ptr = [], [0]
    pair_from, pair_to = [], []
    for k, obj in enumerate(objects):
        ids = []
        for plane in sorted(obj.wraps):
            if not 0 <= plane < P:
                raise InputError(f"observation model: object {obj.name} has plane {plane}, "
                                 f"outside 0..{P - 1}")
            chords = np.asarray(obj.wraps[plane], dtype=float).reshape(-1, N_CHORD_DIMS)
            if len(chords) == 0:
                continue
            ids.append(len(obs_object))
            obs_object.append(k)
            obs_plane.append(plane)
            counted.append(CellCounts.of(bin_index(chords, edges)))
            touched = np.asarray(obj.contacts.get(plane, np.zeros((0, 3))), float).reshape(-1, 3)
            points.append(touched)
            point_ptr.append(point_ptr[-1] + len(touched))
        ids = np.asarray(ids, dtype=np.int64)
        a, b = np.meshgrid(ids, ids, indexing="ij")
        off = a != b
        pair_from.append(a[off])
        pair_to.append(b[off])
    def cat(xs, dt):
        return np.concatenate(xs).astype(dt) if xs else np.zeros(0, dt)
    indptr, cells, counts = cell_rows(counted)
    return ObservationModel(
        classes=classes,
        object_names=np.asarray([o.name for o in objects]),
        object_class=np.asarray([index[o.label] for o in objects], dtype=np.int64),
        plane_normals=np.asarray(plane_normals, dtype=float),
        edges=edges,
        obs_object=np.asarray(obs_object, dtype=np.int64),
        obs_plane=np.asarray(obs_plane, dtype=np.int64),
        obs_indptr=indptr, obs_cells=cells, obs_counts=counts,
        pair_from=cat(pair_from, np.int64), pair_to=cat(pair_to, np.int64),
        contact_indptr=np.asarray(point_ptr, dtype=np.int64),
        contacts=np.concatenate(points).astype(float) if points else np.zeros((0, 3)),
        neighbours=int(neighbours))


def save_observation_model(model: ObservationModel, directory) -> tuple[Path, Path]:
    """Write observations.npz (arrays) and observations.json (metadata) into `directory`."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    arrays = {k: getattr(model, k) for k in (
        "object_class", "plane_normals", "obs_object", "obs_plane", "obs_indptr", "obs_cells",
        "obs_counts", "pair_from", "pair_to", "contact_indptr", "contacts")}
    arrays["edges"] = model.edges
    arrays["pair_action"] = model.pair_action
    arrays["pair_cost"] = model.pair_cost
    meta = {"kind": _KIND, "format_version": FORMAT_VERSION,
            "classes": [str(c) for c in model.classes],
            "object_names": [str(n) for n in model.object_names],
            "neighbours": model.neighbours, "n_observations": model.n_observations,
            "n_planes": model.n_planes, "n_pairs": int(len(model.pair_from)),
            "arrays": sorted(arrays)}
    meta["array_shapes"] = array_shapes(arrays)
    meta["sha256"] = model_digest(arrays, meta)
    npz, js = directory / "observations.npz", directory / "observations.json"
    write_atomic(npz, lambda f: np.savez_compressed(f, **arrays))
    write_json(js, meta)
    return npz, js


def load_observation_model(directory) -> ObservationModel:
    """Read what save_observation_model wrote; no pickle is ever loaded. A missing, damaged
    or old model raises classify.ModelFormatError naming the file."""
    import zipfile

    from ..learning.model import ModelFormatError, check_saved_arrays

    directory = Path(directory)
    js, npz = directory / "observations.json", directory / "observations.npz"
    retrain = "retrain with `drake-continuum train-active`"
    try:
        meta = json.loads(js.read_text())
    except FileNotFoundError:
        made_by_train = (directory / "model.json").is_file()
        raise MissingFileError(
            f"observation model {js}: file not found" + (
                f"; {directory} is a classifier made by `drake-continuum train`: train an "
                f"active-recognition model with `drake-continuum train-active`"
                if made_by_train else "")) from None
    except (OSError, ValueError) as e:
        raise ModelFormatError(f"damaged model {js} (not valid JSON: {e}); {retrain}") from None
    if not isinstance(meta, dict) or meta.get("kind") != _KIND:
        raise ModelFormatError(f"observation model {js}: not an observation model")
    if meta.get("format_version") != FORMAT_VERSION:
        raise ModelFormatError(f"observation model {js}: format version "
                               f"{meta.get('format_version')} cannot be read by this "
                               f"drake-continuum, which reads {FORMAT_VERSION}; {retrain}")
    try:
        with np.load(npz, allow_pickle=False) as z:
            a = {k: np.array(z[k]) for k in z.files}
    except FileNotFoundError:
        raise MissingFileError(f"observation model {npz}: file not found") from None
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
        raise ModelFormatError(f"damaged model {npz} ({type(e).__name__}: {e}); "
                               f"{retrain}") from None
    check_saved_arrays(f"observation model {npz}", meta, a, retrain=retrain)
    missing = sorted(set(meta["arrays"]) - set(a))
    if missing:
        raise ModelFormatError(f"damaged model {npz} (missing arrays {missing}); {retrain}")
    model = ObservationModel(
        classes=np.asarray(meta["classes"]), object_names=np.asarray(meta["object_names"]),
        object_class=a["object_class"], plane_normals=a["plane_normals"],
        edges=chord_edges(a["edges"]),
        obs_object=a["obs_object"], obs_plane=a["obs_plane"], obs_indptr=a["obs_indptr"],
        obs_cells=a["obs_cells"], obs_counts=a["obs_counts"], pair_from=a["pair_from"],
        pair_to=a["pair_to"], contact_indptr=a["contact_indptr"],
        contacts=a["contacts"].reshape(-1, 3), neighbours=int(meta["neighbours"]))
    if model.obs_indptr[-1] != len(model.obs_cells) or len(model.obs_indptr) != \
            model.n_observations + 1 or len(model.contact_indptr) != model.n_observations + 1 \
            or model.contact_indptr[-1] != len(model.contacts):
        raise ModelFormatError(f"damaged model {npz} (inconsistent observation arrays); "
                               f"{retrain}")
    return model


@dataclass(frozen=True, eq=False)
class ActiveModel:
    """What recognition needs: the trained classifier and the observation model, and the
    probability of each category before any wrap that recognition assumes (`class_prior`,
    (C,); None: the training objects' frequencies, observations.class_prior), under which
    the stop rule and the answer read the posterior (reweighted)."""

    classifier: ChordClassifier
    observations: ObservationModel
    class_prior: np.ndarray | None = None

    def __post_init__(self):
        ours = [str(c) for c in self.observations.classes]
        if [str(c) for c in self.classifier.classes_] != ours:
            raise InputError("ActiveModel: classifier classes differ from the observation "
                             f"model's ({list(self.classifier.classes_)} vs {ours})")
        if self.class_prior is not None:
            prior = np.asarray(self.class_prior, dtype=float)
            if (prior.shape != (len(ours),) or not np.all(prior > 0)
                    or not np.isclose(prior.sum(), 1.0)):
                raise InputError(f"ActiveModel: class_prior must be {len(ours)} positive "
                                 f"probabilities summing to 1, got {prior.tolist()}")

    @property
    def prior(self) -> np.ndarray:
        """(C,) p(y) before any wrap."""
        return (self.observations.class_prior if self.class_prior is None
                else np.asarray(self.class_prior, dtype=float))

    def reweighted(self, proba: np.ndarray) -> np.ndarray:
        """(n, C) the classifier's probabilities, which learnt the training frequencies,
        under `prior` instead: p(y | h) prior(y) / frequency(y), renormalised (Bayes' rule
        for a change of prior). Unchanged without a class_prior."""
        proba = np.asarray(proba, dtype=float)
        if self.class_prior is None:
            return proba
        p = proba * (self.prior / self.observations.class_prior)
        return p / p.sum(axis=-1, keepdims=True)


