"""In-place BLAS and LAPACK for the closed loop's hot path, through scipy's f2py wrappers.

On the hot path's tiny arrays (n + 2 = 12 to 24 rows) a call costs its overhead, not its
flops. scipy's wrappers are the cheapest route when they are called so that they neither
parse a keyword nor copy an array (``python scripts/bench.py --only runs`` measures the
step; scratch timings on this machine, us per call):

* every argument by position: a keyword costs some 0.35 us (``dgemv`` 0.23 against 0.62);
* ``overwrite_*`` set and the arrays already Fortran-ordered, contiguous float64: the
  wrapper then works in the caller's buffer (``dposv`` of a 3 x 3 system: 0.18 against
  0.68 when it copies both arguments; ``np.dot`` with ``out=``: 0.37 to 0.46 against 0.23
  for ``dgemv``, which also folds a following addition into its ``beta``).

A C-ordered matrix is passed as its transpose (``a.T`` is Fortran-ordered) with the
``trans`` flag set accordingly; of the symmetric matrices, H and the twin's M (which
Pinocchio stores column-major) are read by columns, H^-1 (stored row-major) by rows.
Outputs are written with beta = 0 over whatever a buffer held (a NaN from a run that blew
up included), as BLAS specifies. The wrappers' argument orders, as called here:

* ``dgemv(alpha, a, x, beta, y, offx, incx, offy, incy, trans, overwrite_y)``:
  y = alpha op(a) x + beta y, op(a) = a (trans 0) or a^T (trans 1);
* ``dsyrk(alpha, a, beta, c, trans, lower, overwrite_c)``: the upper (lower 0) triangle
  of c = alpha op(a) op(a)^T + beta c, op(a) = a (trans 0) or a^T (trans 1);
* ``dposv(a, b, lower, overwrite_a, overwrite_b) -> (c, x, info)``: a x = b by Cholesky
  from a's upper triangle (lower 0), x in b and the factor in a when overwritten.

:func:`in_place_calls_hold` checks exactly these calls once, when the module is
imported, against numpy: a scipy whose wrappers differ fails the import with one line
instead of stepping with wrong numbers.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import blas, lapack

__all__ = ["dgemv", "dposv", "dsyrk", "in_place_calls_hold"]

dgemv = blas.dgemv
dsyrk = blas.dsyrk
dposv = lapack.dposv


def in_place_calls_hold() -> bool:
    """Whether scipy's wrappers, called as the hot path calls them, give numpy's numbers in
    the caller's buffers.

    Returns
    -------
    bool
        True when ``dgemv``, ``dsyrk`` and ``dposv`` take their arguments in the order the
        module docstring lists and work in place.
    """
    rng = np.random.default_rng(5)
    a = np.asfortranarray(rng.normal(size=(5, 3)))
    x3, x5 = rng.normal(size=3), rng.normal(size=5)
    y5, y3, stale = rng.normal(size=5), rng.normal(size=3), np.full(5, np.nan)
    expected_n, expected_t = 2.0 * a @ x3 + 0.5 * y5, -(a.T @ x5) + y3
    dgemv(2.0, a, x3, 0.5, y5, 0, 1, 0, 1, 0, 1)
    dgemv(-1.0, a, x5, 1.0, y3, 0, 1, 0, 1, 1, 1)
    dgemv(1.0, a, x3, 0.0, stale, 0, 1, 0, 1, 0, 1)  # beta = 0: the NaN is not read
    gram, outer = np.zeros((3, 3), order="F"), np.full((5, 5), np.nan, order="F")
    dsyrk(1.0, a, 0.0, gram, 1, 0, 1)
    dsyrk(1.0, a, 0.0, outer, 0, 0, 1)
    upper3, upper5 = np.triu_indices(3), np.triu_indices(5)
    syrk_ok = np.allclose(gram[upper3], (a.T @ a)[upper3], rtol=1e-12, atol=0.0) and \
        np.allclose(outer[upper5], (a @ a.T)[upper5], rtol=1e-12, atol=1e-14)
    spd = a.T @ a + np.eye(3)
    matrix, rhs = np.asfortranarray(spd), rng.normal(size=3)
    solution = np.linalg.solve(spd, rhs)
    _, returned, info = dposv(matrix, rhs, 0, 1, 1)
    return bool(np.allclose(y5, expected_n, rtol=1e-12, atol=1e-14)
                and np.allclose(y3, expected_t, rtol=1e-12, atol=1e-14)
                and np.allclose(stale, a @ x3, rtol=1e-12, atol=1e-14) and syrk_ok
                and info == 0 and np.shares_memory(returned, rhs)
                and np.allclose(rhs, solution, rtol=1e-10, atol=0.0))


if not in_place_calls_hold():  # pragma: no cover - a scipy whose wrappers changed
    raise ImportError("scipy's BLAS/LAPACK wrappers do not take snake_pin's in-place "
                      "arguments (snake_pin._blas): install scipy >= 1.10, < 2")
