"""The vertex of least summed miss of a linearised L1 problem with a few equality rows: which
end-point coordinates an IK answer at the arm's limits leaves off their targets
(ik._newton_at_limits)."""

from __future__ import annotations

from functools import cache
from itertools import combinations

import numpy as np

__all__ = ["free_coordinates"]


def free_coordinates(J, residual, limits) -> np.ndarray | None:
    """The k coordinates that miss at the vertex of least summed miss, linearised at a point
    (J (d, d), the residual (d,) and the k active limits (g (k,), G (k, d)) there): the new
    residual y = residual + J dq must meet g + G dq = 0, i.e. W^T y = W^T residual - g with
    W = J^-T G^T, and min |y|_1 under k such rows has a vertex with k non-zero coordinates:
    the choice of least |y|_1 of every regular one (ties: the first). None when none is."""
    g, G = limits
    W = np.linalg.solve(J.T, G.T)
    b = W.T @ residual - g
    choices = _choices(len(residual), len(g))
    A = np.swapaxes(W[choices], 1, 2)  # (choices, k, k): the rows on each choice's y
    regular = np.abs(np.linalg.det(A)) > 1e-300
    if not regular.any():
        return None
    y = np.linalg.solve(A[regular], np.broadcast_to(b, (int(regular.sum()), len(g)))[..., None])
    return choices[regular][np.argmin(np.abs(y[..., 0]).sum(axis=1))]


@cache
def _choices(d: int, k: int) -> np.ndarray:
    """Every choice of k of d coordinates, (C(d, k), k) in lexicographic order (read-only)."""
    out = np.array(list(combinations(range(d), k)), dtype=np.int64).reshape(-1, k)
    out.flags.writeable = False
    return out
