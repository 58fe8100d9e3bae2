"""Full symmetric matrices from the upper triangles that Pinocchio's CRBA and
computeMinverse fill (their strict lower triangles are not computed)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["symmetric_from_upper"]


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
