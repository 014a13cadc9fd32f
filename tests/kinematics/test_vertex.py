"""The vertex of least summed miss (vertex.py) against scipy's linear program."""

import numpy as np
import pytest
from scipy.optimize import linprog

from drake_continuum.kinematics.vertex import free_coordinates


@pytest.mark.parametrize("k", [1, 2, 3])
def test_free_coordinates_are_the_linear_programs_support(k):
    """min |y|_1 subject to W^T y = W^T r - g (W = J^-T G^T), solved as a linear program in
    (y+, y-) by HiGHS: its optimum is non-zero on exactly the k coordinates chosen."""
    rng = np.random.default_rng(k)
    for _ in range(20):
        J, G = rng.normal(size=(9, 9)), rng.normal(size=(k, 9))
        r, g = rng.normal(scale=1e-3, size=9), rng.uniform(1e-3, 1e-2, k)
        W = np.linalg.solve(J.T, G.T)
        b = W.T @ r - g
        lp = linprog(np.ones(18), A_eq=np.hstack([W.T, -W.T]), b_eq=b, bounds=(0, None),
                     method="highs")
        assert lp.status == 0
        y = lp.x[:9] - lp.x[9:]
        support = np.flatnonzero(np.abs(y) > 1e-9 * np.abs(y).max())
        np.testing.assert_array_equal(free_coordinates(J, r, (g, G)), support)


def test_a_singular_problem_has_no_vertex():
    """Limits whose gradients vanish leave every choice singular: None, not a guess."""
    assert free_coordinates(np.eye(9), np.zeros(9), (np.ones(2), np.zeros((2, 9)))) is None
