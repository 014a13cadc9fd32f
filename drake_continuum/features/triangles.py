"""The baseline descriptor: triangle histograms of tactile contacts (the paper's reference [1],
Zhang et al. 2016, "tactile triangles").

Triangles join three contact points of one object (the contacts of all its wraps pooled, as
[1] pooled the touches of a hand). Each triangle is described as in [1]'s released code by
l0 and l1, its longest and middle side lengths, and a0, its largest angle (the one between
those two sides); triangles within 1 degree of a straight line are rejected, as there.
[1] sampled triples inside hand-sized spheres of a dense point cloud; wrap contacts are few
and spread along the arm, so we sample uniformly among all triples of an object (every
triple when there are at most `n_triangles`). The histogram is `ChordHistogram` with d = 3
and 10 bins a dimension (1,000 cells), normalised per object, classified by a linear SVM.
"""

from __future__ import annotations

from math import comb

import numpy as np

__all__ = ["TRIANGLE_PARAMETERS", "COLLINEAR_TOLERANCE", "triangle_parameters", "sample_triangles"]

TRIANGLE_PARAMETERS = ("l0", "l1", "a0")
COLLINEAR_TOLERANCE = np.radians(1.0)


def triangle_parameters(a, b, c) -> np.ndarray:
    """(k, 3) [l0, l1, a0] of triangles with corners a, b, c (each (k, 3)); degenerate
    triangles (a side of zero length or an angle within 1 deg of 180) are left out."""
    a, b, c = (np.asarray(v, dtype=float) for v in (a, b, c))
    sides = np.stack([np.linalg.norm(b - c, axis=1), np.linalg.norm(c - a, axis=1),
                      np.linalg.norm(a - b, axis=1)], axis=1)  # side i is opposite corner i
    ok = sides.min(axis=1) > 1e-9
    sides = sides[ok]
    l0, l1, l2 = np.sort(sides, axis=1)[:, ::-1].T
    # The largest angle is opposite the longest side (law of cosines).
    a0 = np.arccos(np.clip((l1 ** 2 + l2 ** 2 - l0 ** 2) / (2 * l1 * l2), -1.0, 1.0))
    keep = a0 < np.pi - COLLINEAR_TOLERANCE
    return np.column_stack([l0, l1, a0])[keep]


def sample_triangles(points, n_triangles: int = 2000, rng=None) -> np.ndarray:
    """(k, 3) triangle parameters from triples of points (m, 3): all triples if there are
    at most n_triangles of them, else n_triangles random triples of distinct points."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    m = len(points)
    if m < 3:
        return np.zeros((0, 3))
    if comb(m, 3) <= n_triangles:
        i, j, k = np.meshgrid(np.arange(m), np.arange(m), np.arange(m), indexing="ij")
        sel = (i < j) & (j < k)
        idx = np.column_stack([i[sel], j[sel], k[sel]])
    else:
        rng = np.random.default_rng(0) if rng is None else rng
        idx = np.zeros((0, 3), dtype=np.int64)
        while len(idx) < n_triangles:
            draw = rng.integers(0, m, size=(2 * n_triangles, 3))
            distinct = (draw[:, 0] != draw[:, 1]) & (draw[:, 1] != draw[:, 2]) & \
                       (draw[:, 0] != draw[:, 2])
            idx = np.concatenate([idx, draw[distinct]])
        idx = idx[:n_triangles]
    return triangle_parameters(points[idx[:, 0]], points[idx[:, 1]], points[idx[:, 2]])
