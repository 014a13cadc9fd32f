"""The PCA projection of sparse feature rows, compiled (numba).

Active recognition's tree search projects thousands of histogram rows, one or a few hundred
at a time, each a few hundred occupied cells against tens to hundreds of components. In
numpy (the products of a row's values and its components' rows, then their sum) each row
builds an m x k array and sums it, after a dozen small array operations that find its
entries: most of a prediction's time. Compiled, a row's entries are gathered from its wraps'
cell counts (features.cells) and the products are added one after another into the row's
result, from 0.0, in the row's column order: the additions of numpy's sum over the first
axis and of scipy's sparse product, in the same order, so equal to them to the bit (a
flipped last bit could turn a search's choice; tests hold it to both).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..kinematics.jit import CACHE

__all__ = ["kept_column_entries", "project_rows"]


@njit(cache=CACHE)
def _merge(row_parts, part_ptr, positions, counts, out_positions, out_counts, out_ptr):
    """Row r's entries: the positions of its parts (row_parts[r]:row_parts[r + 1] into
    part_ptr, each part's entries part_ptr[j]:part_ptr[j + 1]), increasing and distinct,
    with their counts summed; written from out_ptr[r], out_ptr[r + 1] set."""
    w = 0
    for r in range(len(row_parts) - 1):
        lo, hi = part_ptr[row_parts[r]], part_ptr[row_parts[r + 1]]
        order = np.argsort(positions[lo:hi], kind="mergesort")
        last = -1
        for t in order:
            p = positions[lo + t]
            if p == last:
                out_counts[w - 1] += counts[lo + t]
            else:
                out_positions[w], out_counts[w], last = p, counts[lo + t], p
                w += 1
        out_ptr[r + 1] = w


@njit(cache=CACHE)
def _project(row_ptr, positions, values, described, described_at, components_t, out):
    """out[i] (zeros) += the products value * components_t[position] of row i's entries
    (row_ptr[i]:row_ptr[i + 1]), then of its non-zero described[i, s] at described_at[s]
    (>= 0: a column the model kept), one after another. Starting from 0.0 as numpy's sum
    and scipy's product start, a sum of -0.0 products is 0.0 as theirs is."""
    k = components_t.shape[1]
    for i in range(len(row_ptr) - 1):
        for a in range(row_ptr[i], row_ptr[i + 1]):
            p, v = positions[a], values[a]
            for c in range(k):
                out[i, c] += v * components_t[p, c]
        for s in range(described.shape[1]):
            p, v = described_at[s], described[i, s]
            if v != 0.0 and p >= 0:
                for c in range(k):
                    out[i, c] += v * components_t[p, c]


def kept_column_entries(rows, columns: np.ndarray) -> tuple[np.ndarray, ...]:
    """The fine histogram entries of rows given as tuples of CellCounts at the columns a
    model kept, `columns` (increasing): (row_ptr (n + 1,), positions in columns, counts)
    with each row's positions increasing and distinct and its counts summed over its parts,
    and (n,) the chords of each row (its parts' totals, cells outside columns included)."""
    found = [[p.within(columns) for p in row] for row in rows]
    row_parts = np.zeros(len(rows) + 1, np.int64)
    row_parts[1:] = np.cumsum([len(f) for f in found])
    flat = [f for row in found for f in row]
    part_ptr = np.zeros(len(flat) + 1, np.int64)
    part_ptr[1:] = np.cumsum([len(f[0]) for f in flat])
    positions = np.concatenate([f[0] for f in flat] or [np.zeros(0, np.int64)])
    counts = np.concatenate([f[1] for f in flat] or [np.zeros(0, np.int64)])
    out_pos, out_counts = np.empty_like(positions), np.empty_like(counts)
    row_ptr = np.zeros(len(rows) + 1, np.int64)
    _merge(row_parts, part_ptr, positions, counts, out_pos, out_counts, row_ptr)
    w = row_ptr[-1]
    totals = np.array([sum(p.total for p in row) for row in rows], np.int64)
    return row_ptr, out_pos[:w], out_counts[:w], totals


def project_rows(row_ptr: np.ndarray, positions: np.ndarray, values: np.ndarray, *,
                 described: np.ndarray, described_at: np.ndarray,
                 components_t: np.ndarray) -> np.ndarray:
    """(n, k) each row's sum of value * components_t[position] over its entries (row_ptr,
    positions, values), in their order, then over its described values (n, s) that are
    non-zero and whose column the model kept (described_at (s,): row of components_t, or
    -1); zeros for a row with neither."""
    n, k = len(row_ptr) - 1, components_t.shape[1]
    out = np.zeros((n, k))
    if n:
        _project(np.asarray(row_ptr, np.int64), np.asarray(positions, np.int64),
                 np.asarray(values, np.float64),
                 np.ascontiguousarray(described, np.float64).reshape(n, -1),
                 np.asarray(described_at, np.int64),
                 np.ascontiguousarray(components_t, np.float64), out)
    return out
