"""Symmetric matrices: whole ones from the upper triangles Pinocchio's CRBA and
computeMinverse fill, and the smallest eigenvalue of a 3x3 one in closed form (PFL's R)."""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

__all__ = ["crba_mirrors", "smallest_eigenvalue_3x3", "symmetric_from_upper", "whole"]

#: Beyond this |cos(3 phi)| two eigenvalues nearly coincide and acos loses digits.
_NEAR_DOUBLE = 1.0 - 1e-6
#: Below this fraction of the largest eigenvalue the smallest is left to LAPACK.
_SMALL = 1e-6
_TWO_THIRDS_PI = 2.0 * math.pi / 3.0
#: A spread p^2 below this (p^3 would underflow) is left to LAPACK.
_TINY_SPREAD = 1e-200


@lru_cache(maxsize=32)
def _strict_lower(size: int) -> np.ndarray:
    mask = np.tril(np.ones((size, size), dtype=bool), -1)
    mask.flags.writeable = False
    return mask


def symmetric_from_upper(upper: np.ndarray) -> np.ndarray:
    """A new symmetric matrix: ``upper``'s upper triangle (diagonal included) mirrored into
    the lower one; ``upper`` is unchanged."""
    out = upper.copy()
    np.copyto(out, upper.T, where=_strict_lower(upper.shape[0]))
    return out


def smallest_eigenvalue_3x3(upper: np.ndarray) -> float:
    """The smallest eigenvalue of a symmetric 3x3 matrix (upper triangle), NaN if one is.

    The characteristic cubic's trigonometric form (q = tr/3, ``p^2 = ||G - q I||_F^2 / 6``,
    ``cos(3 phi) = det(G - q I) / (2 p^3)``, smallest ``q + 2 p cos(phi + 2 pi / 3)``); LAPACK's
    ``dsyev`` where it would lose digits (near-double or near-zero eigenvalues, tiny p).
    """
    (a, b, c), (_, d, e), (_, _, f) = upper.tolist()
    q = (a + d + f) / 3.0
    aq, dq, fq = a - q, d - q, f - q
    p2 = (aq * aq + dq * dq + fq * fq + 2.0 * (b * b + c * c + e * e)) / 6.0
    if p2 > _TINY_SPREAD:
        p = math.sqrt(p2)
        r = (aq * (dq * fq - e * e) - b * (b * fq - e * c) + c * (b * e - dq * c)) / \
            (2.0 * p2 * p)
        if abs(r) <= _NEAR_DOUBLE:
            smallest = q + 2.0 * p * math.cos(math.acos(r) / 3.0 + _TWO_THIRDS_PI)
            if smallest >= _SMALL * (q + 2.0 * p):  # q + 2p bounds the largest
                return smallest
    if not math.isfinite(q + p2):  # NaN or inf: LAPACK would refuse it
        return math.nan
    eigenvalues, _, _ = lapack.dsyev(np.asarray(upper, dtype=float), compute_v=0)
    return float(eigenvalues[0])


def whole(algorithm: Callable[..., Any], matrix: np.ndarray,
           mirrors: bool) -> Callable[..., Any]:
    """``algorithm`` (``pin.crba``, ``pin.computeMinverse``) if it fills ``matrix`` (the Data's
    view) whole, else a wrapper that also mirrors its upper triangle in place."""
    if mirrors:
        return algorithm
    lower = _strict_lower(matrix.shape[0])

    def whole(*arguments: Any) -> np.ndarray:
        algorithm(*arguments)
        np.copyto(matrix, matrix.T, where=lower)
        return matrix

    return whole


def crba_mirrors(model: pin.Model) -> bool:
    """Whether ``pin.crba`` fills ``data.M`` whole (the bindings mirror the upper triangle)."""
    data = model.createData()
    mass = data.M  # the view the callers read, not the returned copy
    returned = pin.crba(model, data, np.linspace(0.3, 0.9, model.nq), pin.Convention.WORLD)
    return bool(np.array_equal(mass, returned) and np.array_equal(mass, mass.T))
