"""In-place BLAS and LAPACK for the closed loop's hot path, behind named helpers.

On the hot path's tiny arrays (n + 2 = 12 to 24 rows) a call costs its overhead, not its
flops. scipy's f2py wrappers are the cheapest route when they neither parse a keyword nor
copy an array: every argument by position (a keyword costs some 0.35 us), ``overwrite_*``
set and the arrays already Fortran-ordered, contiguous float64. :func:`gemv`, :func:`syrk`
and :func:`posv` make exactly such calls, and ``*_call`` prepare them on buffers made once
(the hot path's products; :func:`solve_spd` is the copying solve of the slower paths), so
the f2py argument lists live here only. A C-ordered matrix is passed as its transpose
(``a.T`` is Fortran-ordered) with ``trans`` set accordingly. Outputs are written with beta
= 0 over whatever a buffer held (a NaN included), as BLAS specifies.

:func:`in_place_calls_hold` checks the helpers once, when the module is imported, against
numpy: a scipy whose wrappers differ fails the import with one line instead of stepping
with wrong numbers.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.linalg import blas, lapack

__all__ = ["gemv", "gemv_call", "in_place_calls_hold", "posv", "posv_call", "solve_spd", "syrk",
           "syrk_call"]

# scipy's wrappers; the helpers read these module names on each call
dgemv = blas.dgemv
dsyrk = blas.dsyrk
dposv = lapack.dposv


def gemv(alpha: float, a: np.ndarray, x: np.ndarray, beta: float, y: np.ndarray,
         trans: int = 0) -> None:
    """``y = alpha op(a) x + beta y`` in place, op(a) = a (trans 0) or a^T (trans 1).

    Parameters
    ----------
    alpha, beta : float
        The scalars.
    a : numpy.ndarray
        Fortran-ordered float64 matrix.
    x : numpy.ndarray
        Contiguous float64 vector.
    y : numpy.ndarray
        Contiguous float64 vector, overwritten (not read when beta is 0).
    trans : int, optional
        1 to apply a^T.
    """
    dgemv(alpha, a, x, beta, y, 0, 1, 0, 1, trans, 1)


def syrk(alpha: float, a: np.ndarray, beta: float, c: np.ndarray, trans: int = 0) -> None:
    """Upper triangle of ``c = alpha op(a) op(a)^T + beta c`` in place.

    Parameters
    ----------
    alpha, beta : float
        The scalars.
    a : numpy.ndarray
        Fortran-ordered float64 matrix; op(a) = a (trans 0) or a^T (trans 1).
    c : numpy.ndarray
        Fortran-ordered square float64 matrix; its strict lower triangle is not written.
    trans : int, optional
        1 to use a^T.
    """
    dsyrk(alpha, a, beta, c, trans, 0, 1)


def posv(a: np.ndarray, b: np.ndarray) -> int:
    """Solve ``a x = b`` by Cholesky from a's upper triangle, x into b, the factor into a.

    Parameters
    ----------
    a : numpy.ndarray
        Fortran-ordered square float64 matrix (overwritten).
    b : numpy.ndarray
        Contiguous float64 vector (overwritten by the solution).

    Returns
    -------
    int
        LAPACK's info: 0 on success, > 0 when a is not positive definite.
    """
    return int(dposv(a, b, 0, 1, 1)[2])


def gemv_call(alpha: float, a: np.ndarray, x: np.ndarray, beta: float, y: np.ndarray,
              trans: int = 0) -> Callable[[], Any]:
    """:func:`gemv` prepared on these buffers: calling the result (no arguments) runs it.

    The hot path's products read and write buffers made once; a prepared call passes its
    arguments from a tuple made once too (no Python frame per call).

    Parameters
    ----------
    alpha, a, x, beta, y, trans
        As for :func:`gemv`.

    Returns
    -------
    callable
        Runs ``y = alpha op(a) x + beta y`` in place.
    """
    return functools.partial(dgemv, alpha, a, x, beta, y, 0, 1, 0, 1, trans, 1)


def syrk_call(alpha: float, a: np.ndarray, beta: float, c: np.ndarray,
              trans: int = 0) -> Callable[[], Any]:
    """:func:`syrk` prepared on these buffers: calling the result runs it.

    Parameters
    ----------
    alpha, a, beta, c, trans
        As for :func:`syrk`.

    Returns
    -------
    callable
        Fills the upper triangle of ``c = alpha op(a) op(a)^T + beta c`` in place.
    """
    return functools.partial(dsyrk, alpha, a, beta, c, trans, 0, 1)


def posv_call(a: np.ndarray, b: np.ndarray) -> Callable[[], tuple[Any, Any, int]]:
    """:func:`posv` prepared on these buffers: calling the result runs it.

    Parameters
    ----------
    a, b
        As for :func:`posv`.

    Returns
    -------
    callable
        Solves in place and returns LAPACK's ``(factor, solution, info)``: info is its
        item 2.
    """
    return functools.partial(dposv, a, b, 0, 1, 1)


def solve_spd(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, int]:
    """Solve ``a x = b`` by Cholesky (a's upper triangle) into new arrays (a, b unchanged).

    Parameters
    ----------
    a : numpy.ndarray
        Symmetric positive definite matrix.
    b : numpy.ndarray
        Right-hand side(s), a vector or a matrix.

    Returns
    -------
    tuple
        The solution and LAPACK's info (0 on success, > 0 when a is not definite).
    """
    _, solution, info = dposv(a, b)
    return solution, int(info)


def in_place_calls_hold() -> bool:
    """Whether the helpers give numpy's numbers in the caller's buffers.

    Returns
    -------
    bool
        True when :func:`gemv`, :func:`syrk` and :func:`posv` work in place as documented.
    """
    rng = np.random.default_rng(5)
    a = np.asfortranarray(rng.normal(size=(5, 3)))
    x3, x5 = rng.normal(size=3), rng.normal(size=5)
    y5, y3, stale = rng.normal(size=5), rng.normal(size=3), np.full(5, np.nan)
    expected_n, expected_t = 2.0 * a @ x3 + 0.5 * y5, -(a.T @ x5) + y3
    gemv(2.0, a, x3, 0.5, y5)
    gemv(-1.0, a, x5, 1.0, y3, 1)
    gemv(1.0, a, x3, 0.0, stale)  # beta = 0: the NaN is not read
    gram, outer = np.zeros((3, 3), order="F"), np.full((5, 5), np.nan, order="F")
    syrk(1.0, a, 0.0, gram, 1)
    syrk(1.0, a, 0.0, outer)
    upper3, upper5 = np.triu_indices(3), np.triu_indices(5)
    syrk_ok = np.allclose(gram[upper3], (a.T @ a)[upper3], rtol=1e-12, atol=0.0) and \
        np.allclose(outer[upper5], (a @ a.T)[upper5], rtol=1e-12, atol=1e-14)
    spd = a.T @ a + np.eye(3)
    matrix, rhs = np.asfortranarray(spd), rng.normal(size=3)
    solution = np.linalg.solve(spd, rhs)
    info = posv(matrix, rhs)
    y_prepared = np.full(5, np.nan)
    gemv_call(1.0, a, x3, 0.0, y_prepared)()
    gram_prepared = np.zeros((3, 3), order="F")
    syrk_call(1.0, a, 0.0, gram_prepared, 1)()
    matrix2, rhs2 = np.asfortranarray(spd), rng.normal(size=3)
    solution2 = np.linalg.solve(spd, rhs2)
    prepared_ok = np.allclose(y_prepared, a @ x3, rtol=1e-12, atol=1e-14) and \
        np.allclose(gram_prepared[upper3], (a.T @ a)[upper3], rtol=1e-12, atol=0.0) and \
        posv_call(matrix2, rhs2)()[2] == 0 and np.allclose(rhs2, solution2, rtol=1e-10)
    return bool(prepared_ok and np.allclose(y5, expected_n, rtol=1e-12, atol=1e-14)
                and np.allclose(y3, expected_t, rtol=1e-12, atol=1e-14)
                and np.allclose(stale, a @ x3, rtol=1e-12, atol=1e-14) and syrk_ok
                and info == 0 and np.allclose(rhs, solution, rtol=1e-10, atol=0.0))


if not in_place_calls_hold():  # pragma: no cover - a scipy whose wrappers changed
    raise ImportError("scipy's BLAS/LAPACK wrappers do not take snake_pin's in-place "
                      "arguments (snake_pin._blas): install scipy >= 1.10, < 2")
