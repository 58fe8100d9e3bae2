"""In-place BLAS and LAPACK calls: the probe that guards their argument orders."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import blas, lapack

from snake_pin import _blas


def test_in_place_calls_hold_on_this_scipy() -> None:
    """scipy's wrappers take the hot path's positional, in-place arguments."""
    assert _blas.in_place_calls_hold()


def test_syrk_and_posv_work_in_place() -> None:
    """Prepared syrk fills the upper triangle of a^T a; posv solves into b, reports info;
    solve_spd leaves its arguments alone."""
    rng = np.random.default_rng(1)
    a = np.asfortranarray(rng.normal(size=(6, 4)))
    gram = np.zeros((4, 4), order="F")
    _blas.syrk(1.0, a, 0.0, gram, 1)()
    upper = np.triu_indices(4)
    np.testing.assert_allclose(gram[upper], (a.T @ a)[upper], rtol=1e-13)
    matrix, rhs = np.asfortranarray(a.T @ a + np.eye(4)), rng.normal(size=4)
    expected = np.linalg.solve(matrix, rhs)
    assert _blas.posv(matrix, rhs)()[2] == 0
    np.testing.assert_allclose(rhs, expected, rtol=1e-10)
    assert _blas.posv(np.asfortranarray(-np.eye(2)), np.ones(2))()[2] > 0  # not definite
    spd, rhs = a.T @ a + np.eye(4), rng.normal(size=(4, 2))
    before = rhs.copy()
    solution, info = _blas.solve_spd(spd, rhs)
    assert info == 0 and np.array_equal(rhs, before)
    np.testing.assert_allclose(solution, np.linalg.solve(spd, rhs), rtol=1e-10)


def test_gemv_folds_beta_and_transposes_like_numpy() -> None:
    """gemv on a C matrix's transpose gives numpy's product plus beta y, in y itself."""
    rng = np.random.default_rng(0)
    c_ordered, x, y = rng.normal(size=(4, 7)), rng.normal(size=7), rng.normal(size=4)
    expected = c_ordered @ x - y
    _blas.gemv(1.0, c_ordered.T, x, -1.0, y, 1)()
    np.testing.assert_allclose(y, expected, rtol=1e-13, atol=1e-14)


def _copying_dgemv(alpha, a, x, beta, y, offx, incx, offy, incy, trans, overwrite_y):
    """A dgemv that returns its result instead of writing it into y."""
    return blas.dgemv(alpha, a, x, beta, y.copy(), offx, incx, offy, incy, trans, 1)


def _nan_reading_dgemv(alpha, a, x, beta, y, offx, incx, offy, incy, trans, overwrite_y):
    """A dgemv that reads y even when beta is 0 (0 * NaN stays NaN)."""
    with np.errstate(invalid="ignore"):
        y[...] = alpha * ((a.T if trans else a) @ x) + beta * y
    return y


def _copying_dposv(a, b, lower, overwrite_a, overwrite_b):
    """A dposv that leaves b alone and returns the solution in a new array."""
    return lapack.dposv(a, b, lower, overwrite_a, 0)


def _lower_dsyrk(alpha, a, beta, c, trans, lower, overwrite_c):
    """A dsyrk whose wrapper would read the triangle flag the other way round."""
    return blas.dsyrk(alpha, a, beta, c, trans, 1 - lower, overwrite_c)


@pytest.mark.parametrize(("name", "stand_in"), [("dgemv", _copying_dgemv),
                                                 ("dgemv", _nan_reading_dgemv),
                                                 ("dposv", _copying_dposv),
                                                 ("dsyrk", _lower_dsyrk)])
def test_probe_catches_a_changed_wrapper(monkeypatch, name, stand_in) -> None:
    """A wrapper that copies instead of working in place, reads y at beta = 0 or fills the
    other triangle, fails the probe."""
    monkeypatch.setattr(_blas, name, stand_in)
    assert not _blas.in_place_calls_hold()
