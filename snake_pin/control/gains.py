"""Validation of gain matrices: scalars, vectors (diagonals) or square matrices."""

from __future__ import annotations

import numpy as np

from .._validation import brief, integer
from ..exceptions import ParameterError

__all__ = ["K_PHI_FIRST", "K_PHI_REST"]

#: K_phi of (84), shared by the Lyapunov-like laws: joint 1, then every other joint.
K_PHI_FIRST, K_PHI_REST = 10.0, 20.0


def default_k_phi(joints: int) -> np.ndarray:
    """K_phi's diagonal of (84) for ``joints`` (n - 1) joints: ``[10, 20, ..., 20]``."""
    return np.r_[K_PHI_FIRST, np.full(integer(joints, "joints", low=1) - 1, K_PHI_REST)]


def gain_matrix(value: object, size: int, name: str, *, definite: bool = True) -> np.ndarray:
    """A symmetric size x size gain from a scalar (times I), a diagonal or a matrix.

    Positive definite (semi-definite unless ``definite``); ParameterError naming ``name``.
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be numeric, got {brief(value)}") from exc
    if value is None or np.asarray(value).dtype.kind in "bSUO":  # text is not a gain
        raise ParameterError(f"{name} must be numeric, got {brief(value)}")
    if arr.ndim == 0:
        arr = float(arr) * np.eye(size)
    elif arr.ndim == 1:
        if arr.size != size:
            raise ParameterError(f"{name} needs {size} diagonal entries, got {arr.size}")
        arr = np.diag(arr)
    if arr.shape != (size, size):
        raise ParameterError(f"{name} must be {size} x {size}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} has non-finite entries")
    if not np.allclose(arr, arr.T, atol=1e-12 * max(1.0, np.abs(arr).max())):
        raise ParameterError(f"{name} must be symmetric")
    low = np.linalg.eigvalsh(arr).min()
    if (definite and low <= 0) or (not definite and low < -1e-12 * max(1.0, np.abs(arr).max())):
        kind = "positive definite" if definite else "positive semi-definite"
        raise ParameterError(f"{name} must be {kind} (smallest eigenvalue {low:.3g})")
    return arr
