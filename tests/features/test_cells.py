"""Cell counts of wraps added up, and contact bounds joined, against the chords and points
put together and binned or measured at once."""

import numpy as np
import pytest
import scipy.sparse as sp

from drake_continuum.features.cells import (
    CellCounts,
    cell_rows,
    contact_bounds,
    extent_of_bounds,
)
from drake_continuum.features.chords import contact_extent


def test_cell_counts_add_up_to_the_counts_of_the_cells_together():
    rng = np.random.default_rng(0)
    wraps = [rng.integers(0, 50, size) for size in (30, 1, 45, 0, 12)]
    parts = [CellCounts.of(w) for w in wraps]
    together = np.concatenate(wraps)
    cells, counts = np.unique(together, return_counts=True)
    summed = CellCounts.summed(parts)
    np.testing.assert_array_equal(summed.cells, cells)
    np.testing.assert_array_equal(summed.counts, counts)
    assert summed.total == len(together) == sum(p.total for p in parts)
    np.testing.assert_array_equal(summed.multiset(), np.sort(together))
    empty = CellCounts.summed([CellCounts.of(np.zeros(0, np.int64))] * 2)
    assert empty.total == 0 and len(empty.cells) == 0


def test_cell_rows_are_the_csr_rows_of_each_wraps_counts():
    """Laid end to end, row i holds wrap i's counts: scipy's CSR of the dense counts of
    each wrap (np.bincount, not np.unique) has the same indptr, indices and data."""
    rng = np.random.default_rng(2)
    wraps = [rng.integers(0, 40, size) for size in (25, 0, 1, 60)]
    indptr, cells, counts = cell_rows(CellCounts.of(w) for w in wraps)
    dense = sp.csr_matrix(np.array([np.bincount(w, minlength=40) for w in wraps]))
    np.testing.assert_array_equal(indptr, dense.indptr)
    np.testing.assert_array_equal(cells, dense.indices)
    np.testing.assert_array_equal(counts, dense.data)
    assert indptr.dtype == cells.dtype == counts.dtype == np.int64
    none = cell_rows([])
    assert none[0].tolist() == [0] and len(none[1]) == len(none[2]) == 0


def test_within_gives_the_places_of_the_cells_a_column_set_holds():
    part = CellCounts(np.array([2, 5, 9, 40]), np.array([1, 3, 2, 7]))
    columns = np.array([0, 2, 3, 9, 10])
    pos, counts = part.within(columns)
    np.testing.assert_array_equal(pos, [1, 3])          # cells 2 and 9
    np.testing.assert_array_equal(counts, [1, 2])
    other = np.array([5, 40])                            # another model's columns
    np.testing.assert_array_equal(part.within(other)[0], [0, 1])
    np.testing.assert_array_equal(part.within(columns)[0], [1, 3])
    assert len(part.within(np.zeros(0, np.int64))[0]) == 0


@pytest.mark.parametrize("cells, counts", [([3, 3], [1, 1]), ([4, 2], [1, 1]), ([1], [0]),
                                           ([1, 2], [1])])
def test_cell_counts_refuse_cells_out_of_order_and_empty_counts(cells, counts):
    with pytest.raises(ValueError, match="increase"):
        CellCounts(np.array(cells), np.array(counts))


def test_the_extent_of_joined_bounds_is_the_extent_of_the_points_together_to_the_bit():
    rng = np.random.default_rng(1)
    sets = [rng.normal(size=(n, 3)) * rng.uniform(0.01, 0.2, 3) for n in (5, 1, 17)]
    joined = extent_of_bounds(np.array([contact_bounds(p) for p in sets]))
    np.testing.assert_array_equal(joined, contact_extent(np.concatenate(sets)))
    # by hand: ranges, top, reach
    p = np.concatenate(sets)
    np.testing.assert_array_equal(joined, [*(p.max(0) - p.min(0)), p[:, 2].max(),
                                           np.hypot(p[:, 0], p[:, 1]).max()])
    assert np.isnan(extent_of_bounds(np.zeros((0, 7)))).all()
