"""The engine's DOP853 tableau (``tensegrity.engine.dop853_tableau``, written out so that a run
does not import ``scipy.integrate``) against ``scipy.integrate.DOP853``'s public class attributes,
bit for bit, and against the method's defining conditions (independent of scipy)."""

from __future__ import annotations

import numpy as np
from scipy.integrate import DOP853

from tensegrity.engine import dop853_tableau as tableau


def test_the_tableau_is_scipys_bit_for_bit():
    n = tableau.N_STAGES
    assert n == DOP853.n_stages == 12
    np.testing.assert_array_equal(tableau.A[:n, :n], DOP853.A)
    np.testing.assert_array_equal(tableau.A[n, :n], DOP853.B)  # the 13th stage: f at the end
    np.testing.assert_array_equal(tableau.A[n, n:], 0.0)
    np.testing.assert_array_equal(tableau.A[n + 1 :], DOP853.A_EXTRA)
    np.testing.assert_array_equal(tableau.B, DOP853.B)
    np.testing.assert_array_equal(tableau.C[:n], DOP853.C)
    assert tableau.C[n] == 1.0
    np.testing.assert_array_equal(tableau.C[n + 1 :], DOP853.C_EXTRA)
    np.testing.assert_array_equal(tableau.E3, DOP853.E3)
    np.testing.assert_array_equal(tableau.E5, DOP853.E5)
    np.testing.assert_array_equal(tableau.D, DOP853.D)
    assert tableau.INTERPOLATOR_POWER == 7


def test_the_tableau_is_an_explicit_method_of_order_eight():
    """Explicit (strictly lower triangular), row sums equal to the stage times, and the
    quadrature conditions ``sum b_i c_i^(k-1) = 1/k`` up to ``k = 8``."""
    A, B, C = tableau.A, tableau.B, tableau.C
    assert np.all(np.triu(A) == 0.0)
    np.testing.assert_allclose(A.sum(axis=1), C, rtol=0, atol=1e-14)
    c = C[: tableau.N_STAGES]
    for k in range(1, 9):
        assert abs(np.sum(B * c ** (k - 1)) - 1.0 / k) < 1e-14
