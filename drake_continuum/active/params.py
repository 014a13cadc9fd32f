"""Active recognition's settings (ActiveParams), what it needs of a classifier
(ChordClassifier) and of an object (ObjectWraps), and the discretisation of chords into
histogram cells.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Protocol, Sequence

import numpy as np
import scipy.sparse as sp

from ..checks import at_least, between, check_fields, count
from ..features.chords import bin_index, histogram_rows

__all__ = ["ActiveParams", "ChordClassifier", "ObjectWraps", "N_CHORD_DIMS", "chord_edges",
           "n_cells", "bin_histograms", "unit_rows", "plane_cost_matrix"]


N_CHORD_DIMS = 7


# --------------------------------------------------------------------------- parameters

@dataclass(frozen=True)
class ActiveParams:
    """Constants of active recognition; defaults in the `active` section of models/config.yaml.

    Args:
        exploration: c of eq. 2 (UCT exploration weight).
        horizon: T, the tree depth and the most wraps one plan can hold (paper: 5).
        cost_weight: lambda of eq. 1, weight of the movement cost.
        discount: gamma of the discounted backpropagation.
        n_simulations: simulations a tree search.
        max_iterations: tree searches a recognition (paper, Table II: 3).
        neighbours: training wraps of one class matched to an observation for p(z'|z, a, y).
        strong_probability, strong_ratio: the stop rule, top probability above
            strong_probability and at least strong_ratio times the next (paper: 0.5, 3).
        start_plane: plane index the arm rests on before the first wrap.
        seed: default seed.
    """

    exploration: float = 1.0 / math.sqrt(2.0)
    horizon: int = 5
    cost_weight: float = 0.7
    discount: float = 0.95
    n_simulations: int = 200
    max_iterations: int = 3
    neighbours: int = 5
    strong_probability: float = 0.5
    strong_ratio: float = 3.0
    start_plane: int = 0
    seed: int = 0

    def __post_init__(self):
        check_fields(self, exploration=between(0, 1e3, open_low=False), horizon=count(100),
                     cost_weight=between(0, 1, open_low=False), discount=between(0, 1),
                     n_simulations=count(1_000_000), max_iterations=count(1000),
                     neighbours=count(1000), strong_probability=between(0, 1, open_low=False),
                     strong_ratio=at_least(1), start_plane=at_least(0), seed=at_least(0))


# --------------------------------------------------------------------------- protocols

class ChordClassifier(Protocol):
    """What active recognition needs of the trained classifier (classify.ChordModel).

    An optional `predict_proba_bins(list of flat cell arrays)` is used when present.
    """

    classes_: np.ndarray
    edges_: np.ndarray          # (7, bins + 1) fitted histogram bin edges

    def predict_proba(self, X: Sequence[np.ndarray]) -> np.ndarray:
        """(n, n_classes) class probabilities of n chord sets, each (k, 7)."""


@dataclass(frozen=True)
class ObjectWraps:
    """The wraps of one object: what training tallies and held-out evaluation read.

    Args:
        name: object id.
        label: category.
        wraps: plane index -> (k, 7) chords of the usable wrap on that plane. Planes without a
            usable wrap (empty cut, no contact) are absent: for a held-out object they are
            unavailable actions.
        view: (3,) the depth camera's view of the object (perception.locate.view_extent),
            known before any wrap; None if unknown.
        contacts: plane index -> (m, 3) contact centres of the wrap on that plane, for a
            classifier that learnt the contact extent (chords.contact_extent) of the wraps
            made so far; planes absent: contacts unknown.
    """

    name: str
    label: str
    wraps: Mapping[int, np.ndarray]
    view: np.ndarray | None = None
    contacts: Mapping[int, np.ndarray] = field(default_factory=dict)


# --------------------------------------------------------------------------- discretisation

def chord_edges(edges) -> np.ndarray:
    """(N_CHORD_DIMS, bins + 1) float bin edges of the chord parameters; ValueError for
    another shape."""
    e = np.asarray(edges, dtype=float)
    if e.ndim != 2 or e.shape[0] != N_CHORD_DIMS or e.shape[1] < 2:
        raise ValueError(f"bin edges: expected a ({N_CHORD_DIMS}, bins + 1) array, "
                         f"got shape {e.shape}")
    return e


def n_cells(edges) -> int:
    e = chord_edges(edges)
    return (e.shape[1] - 1) ** e.shape[0]


def bin_histograms(chord_sets: Sequence[np.ndarray], edges) -> sp.csr_matrix:
    """(n, n_cells) sparse chord counts of n chord sets (rows not normalised)."""
    e = chord_edges(edges)
    flat = [bin_index(np.asarray(c, float).reshape(-1, N_CHORD_DIMS), e) for c in chord_sets]
    return histogram_rows(flat, n_cells(e), normalize=False)


def _scale_rows(m: sp.csr_matrix, norm: np.ndarray) -> sp.csr_matrix:
    """Rows divided by norm (rows of norm 0 left as they are); in place of a diagonal product,
    which costs O(n_cells) in scipy."""
    m = sp.csr_matrix(m, dtype=float, copy=True)
    m.data /= np.repeat(np.where(norm > 0, norm, 1.0), np.diff(m.indptr))
    return m


def unit_rows(m: sp.csr_matrix) -> sp.csr_matrix:
    """The rows scaled to unit Euclidean norm (zero rows left as they are)."""
    return _scale_rows(m, np.sqrt(np.asarray(m.multiply(m).sum(axis=1)).ravel()))


def plane_cost_matrix(plane_normals: np.ndarray) -> np.ndarray:
    """(P, P) rotation angle between plane normals, rad: the movement cost of eq. 1."""
    n = np.asarray(plane_normals, dtype=float)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    return np.arccos(np.clip(n @ n.T, -1.0, 1.0))


