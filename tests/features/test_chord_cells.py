"""Binning once under each set of edges (chord_cells) and chords.bin_index against a plain
per-dimension search, on values exactly on edges, ties and values beyond the edges; the
quantile edges against np.quantile."""

import numpy as np

from drake_continuum.features.cells import CellCounts
from drake_continuum.features.chord_cells import (
    binned_cells,
    cells_once,
    counted_cells,
    histograms_of_counts,
)
from drake_continuum.features.chords import ChordHistogram, bin_index, histogram_rows


def _plain_cells(values, edges):
    """The flat cell of each row by a search of each value alone among its dimension's
    interior edges (a value on an edge goes above it), raveled row-major."""
    d, nb1 = edges.shape
    idx = [[int(np.searchsorted(edges[k, 1:-1], v[k], side="right")) for k in range(d)]
           for v in values]
    return np.array([np.ravel_multi_index(i, (nb1 - 1,) * d) for i in idx], dtype=np.int64)


def _edges_and_values(seed, n=400, d=4):
    """Edges (d, 6) and values drawn from few levels (ties), a quarter exactly on edges,
    some beyond both ends, -0.0 against an edge at 0."""
    rng = np.random.default_rng(seed)
    edges = np.sort(rng.normal(size=(d, 6)), axis=1)
    edges[0, 2] = 0.0
    values = rng.choice(np.round(rng.normal(size=12), 1), size=(n, d))
    on_edge = rng.random((n, d)) < 0.25
    pick = edges[np.arange(d)[None, :], rng.integers(0, 6, size=(n, d))]
    values = np.where(on_edge, pick, values)
    values[:5] = edges[:, 0] - 1.0
    values[5:10] = edges[:, -1] + 1.0
    values[10, 0] = -0.0
    return edges, values


def test_bin_index_is_the_plain_search_on_ties_edges_and_beyond():
    for seed in range(5):
        edges, values = _edges_and_values(seed)
        np.testing.assert_array_equal(bin_index(values, edges), _plain_cells(values, edges))
    edges = np.array([[0.0, 1.0, 2.0, 3.0], [0.0, 1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(bin_index(np.array([[1.0, 2.0], [-5.0, 9.0]]), edges),
                                  [1 * 3 + 2, 0 * 3 + 2])  # on an edge: above it
    assert bin_index(np.zeros((0, 2)), edges).shape == (0,)


def test_cells_once_hands_out_bin_index_under_each_set_of_edges():
    """Within the block: bin_index's cells under each set of edges (changed, then back),
    for the arrays, a view of one of them and an empty one; the same array again under the
    same edges gets the cells already computed, new edges new ones."""
    edges, values = _edges_and_values(7)
    other, _ = _edges_and_values(8)
    arrays = [values[:150], values[150:], np.zeros((0, 4))]
    with cells_once():
        first = binned_cells(arrays, edges)
        again = binned_cells([arrays[1], arrays[0], values[:150]], edges)
        moved = binned_cells(arrays, other)
        back = binned_cells(arrays, edges)
    for got, arr, e in [(first, arrays, edges), (moved, arrays, other), (back, arrays, edges),
                        (again, [arrays[1], arrays[0], values[:150]], edges)]:
        for cells, a in zip(got, arr):
            np.testing.assert_array_equal(cells, _plain_cells(a, e))
    assert again[0] is first[1] and again[1] is first[0] and again[2] is first[0]
    assert back[0] is not first[0]
    outside = binned_cells(arrays[:1], edges)  # no block: computed afresh
    assert outside[0] is not first[0]
    np.testing.assert_array_equal(outside[0], first[0])


def test_histograms_in_a_split_loop_are_those_binned_alone():
    """A histogram fitted a split on another training half, transforming the same arrays
    twice, inside cells_once: every entry the same as without the block."""
    rng = np.random.default_rng(3)
    objects = [np.round(rng.normal(size=(int(rng.integers(1, 60)), 7)), 1) for _ in range(30)]
    for split in range(4):
        train = rng.permutation(30)[:15]
        h = ChordHistogram(bins=5, edges="quantile", power=0.5).fit([objects[i] for i in train])
        plain = h.transform(objects).toarray()
        with cells_once():
            for _ in range(2):
                np.testing.assert_array_equal(h.transform(objects).toarray(), plain)


def test_quantile_edges_are_numpys_quantiles_of_each_column_to_the_bit():
    """Learnt row by row on the transposed chords: the same floats as np.quantile down
    the columns (continuous values: no tie moves an edge)."""
    rng = np.random.default_rng(4)
    objects = [rng.gamma(2.0, size=(int(rng.integers(50, 400)), 7)) for _ in range(12)]
    h = ChordHistogram(bins=7, edges="quantile").fit(objects)
    q = np.quantile(np.concatenate(objects), np.linspace(0, 1, 8), axis=0).T
    assert h.edges_[:, 1:-1].tobytes() == q[:, 1:-1].tobytes()


def test_histograms_of_counts_are_histogram_rows_of_the_cells_to_the_bit():
    """Each array's counted cells are the CellCounts of its bin_index (np.unique's
    cells and counts); rows from them (remembered in the block or not): data,
    columns, row pointers and their types those of chords.histogram_rows, normalised or
    not, with empty arrays among them and all empty."""
    edges, values = _edges_and_values(9)
    arrays = [values[:40], np.zeros((0, 4)), values[40:41], values[41:]]
    n_cells = 5 ** 4
    for got, a in zip(counted_cells(arrays, edges), arrays):
        cells, counts = np.unique(bin_index(a, edges), return_counts=True)
        assert isinstance(got, CellCounts) and got.total == len(a)
        assert got.cells.dtype == got.counts.dtype == np.int64
        np.testing.assert_array_equal(got.cells, cells)
        np.testing.assert_array_equal(got.counts, counts)
    for normalize in (True, False):
        plain = histogram_rows([bin_index(a, edges) for a in arrays], n_cells, normalize)
        with cells_once():
            for _ in range(2):
                got = histograms_of_counts(counted_cells(arrays, edges), n_cells, normalize)
                for name in ("data", "indices", "indptr"):
                    want, have = getattr(plain, name), getattr(got, name)
                    assert have.dtype == want.dtype and have.tobytes() == want.tobytes()
        assert (histograms_of_counts(counted_cells(arrays, edges), n_cells, normalize)
                != plain).nnz == 0
    empty = histograms_of_counts(counted_cells([np.zeros((0, 4))] * 2, edges), n_cells)
    assert empty.shape == (2, n_cells) and empty.nnz == 0
