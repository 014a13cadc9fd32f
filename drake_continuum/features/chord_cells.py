"""Chords binned into histogram cells (`bin_index`), once under each set of edges however
often an evaluation's split asks.

An evaluation over random splits (learning.evaluation, learning.placements) fits a new
classifier a split, with bin edges learnt from that split's training half, and bins the
objects' chords under them: the training half when fitting, the test half when predicting,
and a SideMixture's standing-only model, which shares the edges, both again. While
`cells_once()` lasts, `binned_cells` keeps the cells (bin_index) of each array
binned under the current edges, and hands them out again for the same array (or a view of
the same memory) under the same edges; new edges start afresh. `counted_cells` keeps
each array's distinct cells and counts beside them (cells.CellCounts, as active
recognition counts a wrap's), and `histograms_of_counts` builds the histogram rows from
those (chords.ChordHistogram without a coarse block, in such a block). The cells are
bin_index's own and the counts integers, so the histograms are the same to the bit.
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np
import scipy.sparse as sp

from .cells import CellCounts, cell_rows

__all__ = ["bin_index", "cells_once", "remembering", "binned_cells", "counted_cells",
           "histograms_of_counts"]

_ACTIVE: list[dict] = []


def bin_index(values: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(k,) flat histogram cell of each row of values (k, d) under edges (d, bins + 1).

    Values outside the edges fall in the first or last bin of their dimension (a test
    object may lie beyond what training saw).
    """
    columns = np.ascontiguousarray(np.asarray(values, dtype=float).T)  # searched in place
    d, nb1 = edges.shape
    flat = np.zeros(columns.shape[1], dtype=np.int64)
    for k in range(d):  # one vectorised search a dimension (d = 7), not a loop over points
        flat *= nb1 - 1  # the row-major flat cell, dimension by dimension
        flat += np.searchsorted(edges[k, 1:-1], columns[k], side="right")
    return flat


def _memory(a: np.ndarray) -> tuple:
    """Where an array's values lie: arrays alike here hold the same values (the arrays
    remembered are kept, so their memory is not reused; chord arrays are not written to)."""
    return a.__array_interface__["data"][0], a.shape, a.strides, a.dtype.str


@contextmanager
def cells_once():
    """Let binned_cells remember each array's cells under the current edges until the
    block ends."""
    memo: dict = {"edges": None, "cells": {}}
    _ACTIVE.append(memo)
    try:
        yield memo
    finally:
        _ACTIVE.remove(memo)


def remembering() -> bool:
    """Whether a cells_once block is active: counted_cells then pays (each array counted
    once a split); outside one, one count of all the cells together is cheaper for many
    small arrays."""
    return bool(_ACTIVE)


def _remembered(arrays, edges) -> list[list]:
    """[array, cells, CellCounts or None] of each array under edges: those of the innermost
    cells_once block (made and kept there), or made afresh."""
    empty = np.zeros(0, np.int64)
    if not _ACTIVE:
        return [[a, bin_index(a, edges) if len(a) else empty, None] for a in arrays]
    memo = _ACTIVE[-1]
    key = (edges.shape, edges.tobytes())
    if memo["edges"] != key:
        memo["edges"], memo["cells"] = key, {}
    out = []
    for a in arrays:
        where = _memory(a)
        got = memo["cells"].get(where)
        if got is None:
            got = memo["cells"][where] = [a, bin_index(a, edges) if len(a) else empty, None]
        out.append(got)
    return out


def binned_cells(arrays, edges) -> list[np.ndarray]:
    """bin_index of each (k_i, d) array under edges (d, bins + 1); remembered in the
    innermost cells_once block, if any."""
    return [got[1] for got in _remembered(arrays, edges)]


def counted_cells(arrays, edges) -> list[CellCounts]:
    """The CellCounts of each array's bin_index under edges; remembered with its cells."""
    out = []
    for got in _remembered(arrays, edges):
        if got[2] is None:
            got[2] = CellCounts.of(got[1])
        out.append(got[2])
    return out


def histograms_of_counts(counted, n_cells: int, normalize: bool = True) -> sp.csr_matrix:
    """CSR (n, n_cells) over every cell: one row a CellCounts (counted_cells), L1-normalised
    if asked; entry for entry chords.histogram_rows of the cells themselves."""
    counted = list(counted)
    n = len(counted)
    totals = np.array([c.total for c in counted], dtype=np.int64)
    if totals.sum() == 0:
        return sp.csr_matrix((n, n_cells))
    indptr, cols, counts = cell_rows(counted)
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr))
    data = counts / totals[rows] if normalize else counts.astype(float)
    return sp.csr_matrix((data, cols, indptr), shape=(n, n_cells))
