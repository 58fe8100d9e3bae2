"""In-place BLAS and LAPACK for the closed loop's hot path, behind named helpers.

On tiny arrays a call costs its overhead, so :func:`gemv`, :func:`syrk` and :func:`posv`
prepare scipy's f2py call once (arguments by position, Fortran-ordered buffers,
``overwrite_*`` set) and return it: calling the result runs it in place. The f2py argument
lists live here only; :func:`in_place_calls_hold` checks them against numpy at import.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.linalg import blas, lapack

__all__ = ["gemv", "in_place_calls_hold", "posv", "solve_spd", "syrk"]

# scipy's wrappers; the helpers read these module names when they prepare a call
dgemv = blas.dgemv
dsyrk = blas.dsyrk
dposv = lapack.dposv


def gemv(alpha: float, a: np.ndarray, x: np.ndarray, beta: float, y: np.ndarray,
         trans: int = 0) -> Callable[[], Any]:
    """Prepared ``y = alpha op(a) x + beta y`` in place (op(a) = a^T with ``trans=1``)."""
    return functools.partial(dgemv, alpha, a, x, beta, y, 0, 1, 0, 1, trans, 1)


def syrk(alpha: float, a: np.ndarray, beta: float, c: np.ndarray,
         trans: int = 0) -> Callable[[], Any]:
    """Prepared upper triangle of ``c = alpha op(a) op(a)^T + beta c`` in place."""
    return functools.partial(dsyrk, alpha, a, beta, c, trans, 0, 1)


def posv(a: np.ndarray, b: np.ndarray) -> Callable[[], tuple[Any, Any, int]]:
    """Prepared Cholesky solve of ``a x = b`` into ``b``; returns ``(factor, x, info)``."""
    return functools.partial(dposv, a, b, 0, 1, 1)


def solve_spd(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, int]:
    """``a x = b`` by Cholesky into new arrays: the solution and LAPACK's info (> 0: not SPD)."""
    _, solution, info = dposv(a, b)
    return solution, int(info)


def in_place_calls_hold() -> bool:
    """Whether :func:`gemv`, :func:`syrk` and :func:`posv` give numpy's numbers in place."""
    rng = np.random.default_rng(5)
    a = np.asfortranarray(rng.normal(size=(5, 3)))
    x3, x5 = rng.normal(size=3), rng.normal(size=5)
    y5, y3, stale = rng.normal(size=5), rng.normal(size=3), np.full(5, np.nan)
    expected_n, expected_t = 2.0 * a @ x3 + 0.5 * y5, -(a.T @ x5) + y3
    gemv(2.0, a, x3, 0.5, y5)()
    gemv(-1.0, a, x5, 1.0, y3, 1)()
    gemv(1.0, a, x3, 0.0, stale)()  # beta = 0: the NaN is not read
    gram, outer = np.zeros((3, 3), order="F"), np.full((5, 5), np.nan, order="F")
    syrk(1.0, a, 0.0, gram, 1)()
    syrk(1.0, a, 0.0, outer)()
    upper3, upper5 = np.triu_indices(3), np.triu_indices(5)
    syrk_ok = np.allclose(gram[upper3], (a.T @ a)[upper3], rtol=1e-12, atol=0.0) and \
        np.allclose(outer[upper5], (a @ a.T)[upper5], rtol=1e-12, atol=1e-14)
    spd = a.T @ a + np.eye(3)
    matrix, rhs = np.asfortranarray(spd), rng.normal(size=3)
    solution = np.linalg.solve(spd, rhs)
    info = posv(matrix, rhs)()[2]
    return bool(np.allclose(y5, expected_n, rtol=1e-12, atol=1e-14)
                and np.allclose(y3, expected_t, rtol=1e-12, atol=1e-14)
                and np.allclose(stale, a @ x3, rtol=1e-12, atol=1e-14) and syrk_ok
                and info == 0 and np.allclose(rhs, solution, rtol=1e-10, atol=0.0))


if not in_place_calls_hold():  # pragma: no cover - a scipy whose wrappers changed
    raise ImportError("scipy's BLAS/LAPACK wrappers do not take snake_pin's in-place "
                      "arguments (snake_pin._blas): install scipy >= 1.10, < 2")
