"""The compiled projection (learning.projection) against numpy's sum of each row's products
over the first axis and scipy's sparse product, compared as bytes: zero signs included."""

import numpy as np
import scipy.sparse as sp

from drake_continuum.learning.projection import project_rows


def test_each_row_is_numpys_sum_and_scipys_product_to_the_bit_zero_signs_included():
    """Rows whose products are all -0.0 (a component of -0.0, a value of -1 times 0.0): both
    sums start from 0.0, so they give 0.0; a zero or unkept described value is no product;
    a row with neither entries nor described values is zeros."""
    rng = np.random.default_rng(0)
    components_t = rng.normal(size=(6, 4))
    components_t[2] = -0.0
    components_t[3, 1] = 0.0
    row_ptr = np.array([0, 2, 3, 3, 3, 5])
    positions = np.array([2, 0, 2, 5, 1])
    values = np.array([1.5, 0.3, 2.0, 0.7, 0.2])
    described_at = np.array([4, -1, 3])
    described = np.array([[0.0, 0.0, 0.4], [0.0, 0.0, 0.0], [0.0, 5.0, -1.0],
                          [0.0, 9.0, 0.0], [1.0, 2.0, 3.0]])
    got = project_rows(row_ptr, positions, values, described=described,
                       described_at=described_at, components_t=components_t)
    data, indices, indptr = [], [], [0]
    for i in range(len(row_ptr) - 1):
        entries = [(values[a], positions[a]) for a in range(row_ptr[i], row_ptr[i + 1])]
        entries += [(v, p) for v, p in zip(described[i], described_at) if v != 0.0 and p >= 0]
        products = [v * components_t[p] for v, p in entries]
        want = np.array(products).sum(axis=0) if products else np.zeros(4)
        assert got[i].tobytes() == want.tobytes(), i
        data += [v for v, _ in entries]
        indices += [p for _, p in entries]
        indptr.append(len(data))
    X = sp.csr_matrix((data, indices, indptr), shape=(len(got), len(components_t)))
    assert np.asarray(X @ components_t).tobytes() == got.tobytes()
    assert not np.signbit(got[1]).any() and got[1].tobytes() == np.zeros(4).tobytes()
    assert not np.signbit(got[2, 1]) and got[3].tobytes() == np.zeros(4).tobytes()
