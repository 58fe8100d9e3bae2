"""Validation of gain matrices: scalars, vectors (diagonals) or square matrices."""

from __future__ import annotations

import numpy as np

from .._validation import brief, flag, integer
from ..exceptions import ParameterError

__all__ = ["K_PHI_FIRST", "K_PHI_REST", "default_k_phi", "gain_matrix"]

#: K_phi of (84), shared by the Lyapunov-like laws: joint 1, then every other joint.
K_PHI_FIRST, K_PHI_REST = 10.0, 20.0


def default_k_phi(joints: int) -> np.ndarray:
    """K_phi's diagonal of (84) for ``joints`` joints: 10, then 20 on the others.

    Parameters
    ----------
    joints : int
        The number of joints, n - 1.

    Returns
    -------
    numpy.ndarray
        ``[10, 20, ..., 20]`` of length ``joints``.

    Raises
    ------
    ParameterError
        ``joints`` is not a positive integer.
    """
    return np.r_[K_PHI_FIRST, np.full(integer(joints, "joints", low=1) - 1, K_PHI_REST)]


def gain_matrix(value: object, size: int, name: str, *, definite: bool = True) -> np.ndarray:
    """A symmetric size x size gain, positive definite (or semi-definite if not ``definite``).

    Parameters
    ----------
    value : float, array_like of shape (size,) or (size, size)
        The gain: a scalar (times identity), a vector (the diagonal) or a matrix.
    size : int
        The matrix's order (3 for a head gain, n - 1 for a joint gain).
    name : str
        The gain's name in error messages (e.g. ``"K_w1"``).
    definite : bool, optional
        Require positive definite (True) or only positive semi-definite (False).

    Returns
    -------
    numpy.ndarray
        The gain as a float matrix of shape (size, size).

    Raises
    ------
    ParameterError
        ``value`` is not numeric (a bool or text is not a gain), has the wrong shape, is not
        finite, not symmetric, or not (semi-)definite; ``size`` is not a positive
        integer, ``name`` not a string or ``definite`` not a bool.
    """
    if not isinstance(name, str):
        raise ParameterError(f"name must be the gain's name (a string), got {brief(name)}")
    size = integer(size, "size", low=1)
    definite = flag(definite, "definite")
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
