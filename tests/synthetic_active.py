"""A synthetic active-recognition problem with a known answer, for the tests and the
benchmark.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from drake_continuum.active.params import N_CHORD_DIMS, ChordClassifier, ObjectWraps

# --------------------------------------------------------------------------- synthetic problem

def paper_plane_normals(alpha_deg: float | None = None) -> np.ndarray:
    """(P, 3) normals of planes.enumerate_planes (default: the paper's 10 planes)."""
    from drake_continuum.wrapping.planes import PAPER_ALPHA_DEG, enumerate_planes

    planes = enumerate_planes(np.zeros(3), PAPER_ALPHA_DEG if alpha_deg is None else alpha_deg)
    return np.array([p.normal for p in planes])


def synthetic_planes() -> np.ndarray:
    """(5, 3) normals: tabletop (0), 22.5 deg about x (1), 45 deg about x (2), 90 deg about x
    (3), 90 deg about y (4)."""
    n = paper_plane_normals()
    return n[[0, 1, 2, 4, 9]]


SYNTHETIC_SIGNAL = {1: 0.3, 4: 0.8}   # plane -> fraction of chords carrying the class
SYNTHETIC_BINS = 7


def synthetic_objects(n_per_class: int = 8, classes: Sequence[str] = ("a", "b", "c"),
                      n_chords: int = 40, seed: int = 0,
                      signal: Mapping[int, float] = SYNTHETIC_SIGNAL,
                      n_planes: int = 5) -> list[ObjectWraps]:
    """A problem with a known answer, for tests and the benchmark.

    Chords fall in histogram cells drawn from a pool shared by all classes, except on the planes
    in `signal`, where that fraction of chords falls in cells of the object's class. With
    synthetic_planes(), plane 1 is cheap (22.5 deg from the start) and weakly informative,
    plane 4 is costly (90 deg) and strongly informative, the others carry nothing.
    """
    rng = np.random.default_rng(seed)
    pool = np.random.default_rng(12345).integers(0, SYNTHETIC_BINS,
                                                 (20 + 4 * len(classes), N_CHORD_DIMS))
    shared, own = pool[:20], pool[20:].reshape(len(classes), 4, N_CHORD_DIMS)
    out = []
    for k, c in enumerate(classes):
        for j in range(n_per_class):
            wraps = {}
            for plane in range(n_planes):
                cells = shared[rng.integers(0, len(shared), n_chords)]
                m = rng.random(n_chords) < signal.get(plane, 0.0)
                cells[m] = own[k][rng.integers(0, 4, m.sum())]
                wraps[plane] = (cells + rng.random(cells.shape)) / SYNTHETIC_BINS
            out.append(ObjectWraps(f"{c}{j:02d}", c, wraps))
    return out


def train_synthetic_classifier(objects: Sequence[ObjectWraps]) -> ChordClassifier:
    """A stand-in for learning.pipeline without its fast path: ChordHistogram + logistic regression
    on each object's pooled chords (a scikit-learn Pipeline with `classes_`, `edges_`)."""
    from sklearn.feature_selection import VarianceThreshold
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import Pipeline

    from drake_continuum.features.chords import ChordHistogram

    pipe = Pipeline([("histogram", ChordHistogram(bins=SYNTHETIC_BINS)),
                     ("occupied", VarianceThreshold()),    # 823,543 cells -> the used ones
                     ("logistic", LogisticRegression(C=20.0, max_iter=2000))])
    pipe.fit([np.concatenate(list(o.wraps.values())) for o in objects],
             [o.label for o in objects])
    pipe.edges_ = pipe["histogram"].edges_
    return pipe

