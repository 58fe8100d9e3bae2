"""Small helpers for symmetric matrices: full matrices from the upper triangles that
Pinocchio's CRBA and computeMinverse fill (their strict lower triangles are not computed),
and the smallest eigenvalue of a 3x3 one in closed form (PFL's R, every step)."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy.linalg import lapack

__all__ = ["smallest_eigenvalue_3x3", "symmetric_from_upper"]

#: Beyond this |cos(3 phi)| two eigenvalues nearly coincide, where acos loses digits.
_NEAR_DOUBLE = 1.0 - 1e-4
_TWO_THIRDS_PI = 2.0 * math.pi / 3.0


@lru_cache(maxsize=32)
def _strict_lower(size: int) -> np.ndarray:
    mask = np.tril(np.ones((size, size), dtype=bool), -1)
    mask.flags.writeable = False
    return mask


def symmetric_from_upper(upper: np.ndarray) -> np.ndarray:
    """Return a new symmetric matrix: ``upper``'s upper triangle mirrored into the lower one.

    Parameters
    ----------
    upper : numpy.ndarray, shape (k, k)
        A square matrix whose upper triangle (diagonal included) is meaningful.

    Returns
    -------
    numpy.ndarray, shape (k, k)
        The symmetric matrix; ``upper`` is unchanged.
    """
    out = upper.copy()
    np.copyto(out, upper.T, where=_strict_lower(upper.shape[0]))
    return out


def smallest_eigenvalue_3x3(upper: np.ndarray) -> float:
    """The smallest eigenvalue of a symmetric 3x3 matrix given by its upper triangle.

    The trigonometric closed form of the characteristic cubic: with q = tr(G)/3,
    p^2 = ||G - q I||_F^2 / 6 and cos(3 phi) = det(G - q I) / (2 p^3), the eigenvalues are
    q + 2 p cos(phi + 2 pi k / 3), the smallest at k = 1 (phi in [0, pi/3]). Its error is
    about 1e-15 of the largest eigenvalue, as LAPACK's, except where two eigenvalues nearly
    coincide (|cos(3 phi)| near 1, where acos loses half the digits): there it is LAPACK's
    ``dsyev``. Twice as fast as ``dsyev`` alone through scipy.

    Parameters
    ----------
    upper : numpy.ndarray, shape (3, 3)
        A symmetric matrix; only its upper triangle (diagonal included) is read.

    Returns
    -------
    float
        Its smallest eigenvalue (NaN if an entry is NaN).
    """
    (a, b, c), (_, d, e), (_, _, f) = upper.tolist()
    q = (a + d + f) / 3.0
    aq, dq, fq = a - q, d - q, f - q
    p2 = (aq * aq + dq * dq + fq * fq + 2.0 * (b * b + c * c + e * e)) / 6.0
    if p2 == 0.0:  # G = q I
        return q
    p = math.sqrt(p2)
    r = (aq * (dq * fq - e * e) - b * (b * fq - e * c) + c * (b * e - dq * c)) / (2.0 * p2 * p)
    if not abs(r) <= _NEAR_DOUBLE:  # near a double eigenvalue (or NaN): LAPACK
        eigenvalues, _, _ = lapack.dsyev(np.asarray(upper, dtype=float), compute_v=0)
        return float(eigenvalues[0])
    return q + 2.0 * p * math.cos(math.acos(r) / 3.0 + _TWO_THIRDS_PI)
