"""What of a wrap adds up with other wraps: its chords as histogram cell counts, its
contact centres as bounds.

Active recognition's tree search classifies thousands of sets of wraps (the real wraps so
far plus training wraps on a tree path), each set a sum of a few wraps' histograms. Each
wrap is binned once (`CellCounts`: its distinct cells, sorted, and their counts); a set's
histogram row is the sum of its wraps' counts, restricted to the cells a classifier keeps
(its occupied columns), the positions of each wrap's cells among them looked up once
(`CellCounts.within`; the sum: learning.projection.kept_column_entries). Counts are
integers, so the sum is exact and the histogram it gives equals, entry for entry, the one
of the set's chords binned together. Likewise a set's contact extent
(chords.contact_extent) comes from its wraps' contact bounds (`contact_bounds`,
`extent_of_bounds`): extremes of extremes. An evaluation's splits count each object's
chords as CellCounts too (chord_cells.counted_cells), once under each split's edges.
Several CellCounts laid end to end (`cell_rows`) are the rows of a CSR histogram and the
training wraps of a stored observation model.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CellCounts", "cell_rows", "contact_bounds", "extent_of_bounds"]


class CellCounts:
    """A multiset of flat histogram cells: its distinct cells (increasing) and the count of
    each (positive); `total` chords in all.

    Args:
        cells: (m,) distinct flat cells, increasing.
        counts: (m,) chords in each.
    """

    __slots__ = ("cells", "counts", "total", "_within")

    def __init__(self, cells, counts):
        cells = np.asarray(cells, dtype=np.int64).reshape(-1)
        counts = np.asarray(counts, dtype=np.int64).reshape(-1)
        if len(cells) != len(counts) or np.any(np.diff(cells) <= 0) or np.any(counts <= 0):
            raise ValueError("CellCounts: cells must increase and counts be positive, one a "
                             "cell")
        self._hold(cells, counts)

    def _hold(self, cells: np.ndarray, counts: np.ndarray) -> None:
        self.cells, self.counts = cells, counts
        self.total = int(counts.sum())
        self._within: dict[int, tuple] = {}

    @classmethod
    def of(cls, flat_index) -> "CellCounts":
        """The counts of a multiset of flat cells (chords.bin_index of a wrap's chords).
        np.unique's cells increase and its counts are positive: held without the checks
        (about 20 us an array, and an evaluation counts every object anew each split)."""
        made = cls.__new__(cls)
        made._hold(*np.unique(np.asarray(flat_index, dtype=np.int64), return_counts=True))
        return made

    def multiset(self) -> np.ndarray:
        """(total,) every cell as often as it is counted, increasing."""
        return np.repeat(self.cells, self.counts)

    @classmethod
    def summed(cls, parts) -> "CellCounts":
        """The sum of several multisets (the chords of several wraps together)."""
        parts = list(parts)
        if len(parts) == 1:
            return parts[0]
        cells = np.concatenate([p.cells for p in parts] or [np.zeros(0, np.int64)])
        counts = np.concatenate([p.counts for p in parts] or [np.zeros(0, np.int64)])
        order = np.argsort(cells, kind="stable")
        cells, counts = cells[order], counts[order]
        first = np.flatnonzero(np.r_[True, cells[1:] != cells[:-1]]) if len(cells) else \
            np.zeros(0, np.int64)
        return cls(cells[first], np.add.reduceat(counts, first) if len(first) else counts)

    def within(self, columns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(positions in `columns`, counts) of the cells that `columns` (increasing) holds;
        remembered for each columns array asked about (a model and its standing model)."""
        got = self._within.get(id(columns))
        if got is None or got[0] is not columns:  # (the array kept: its id stays its own)
            if len(columns):
                pos = np.minimum(np.searchsorted(columns, self.cells), len(columns) - 1)
                hit = columns[pos] == self.cells
            else:
                pos, hit = np.zeros(len(self.cells), np.int64), np.zeros(len(self.cells), bool)
            got = self._within[id(columns)] = (columns, pos[hit], self.counts[hit])
        return got[1], got[2]


def cell_rows(counted) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(indptr (n + 1,), cells, counts) of n CellCounts laid end to end, one a row: row i's
    cells and counts are cells[indptr[i]:indptr[i + 1]] and counts[...] (CSR's layout)."""
    counted = list(counted)
    indptr = np.zeros(len(counted) + 1, np.int64)
    indptr[1:] = np.cumsum([len(c.cells) for c in counted])
    if not counted:
        return indptr, np.zeros(0, np.int64), np.zeros(0, np.int64)
    return (indptr, np.concatenate([c.cells for c in counted]),
            np.concatenate([c.counts for c in counted]))


def contact_bounds(points) -> np.ndarray:
    """(7,) lowest x, y, z, highest x, y, z and largest distance from the vertical axis of
    contact centres (m, 3), at least one: all contact_extent reads of them (turn_invariant
    apart), so that the extent of several wraps together comes from theirs."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    out = np.empty(7)
    out[:3], out[3:6], out[6] = p.min(axis=0), p.max(axis=0), np.hypot(p[:, 0], p[:, 1]).max()
    return out


def extent_of_bounds(bounds) -> np.ndarray:
    """(5,) chords.contact_extent (not turn_invariant: extent x, y, z, top, reach) of the
    union of point sets given by their contact_bounds (k, 7); NaN for none. Equal to it to
    the bit: extremes are exact."""
    b = np.asarray(bounds, dtype=float).reshape(-1, 7)
    if not len(b):
        return np.full(5, np.nan)
    low, high = b[:, :3].min(axis=0), b[:, 3:6].max(axis=0)
    out = np.empty(5)
    out[:3], out[3], out[4] = high - low, high[2], b[:, 6].max()
    return out
