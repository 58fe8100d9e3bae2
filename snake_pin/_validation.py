"""Boundary checks shared by the public functions: sizes and finiteness of vectors."""

from __future__ import annotations

import math

import numpy as np

from .exceptions import ConfigurationError, ParameterError

__all__ = ["as_vector", "finite_number"]


def as_vector(value: object, size: int, name: str) -> np.ndarray:
    """Return ``value`` as a finite float vector of length ``size``.

    Parameters
    ----------
    value : array_like
        Anything numpy reads as ``size`` numbers (flattened).
    size : int
        The length required.
    name : str
        The vector's name in the error message (e.g. ``"q"``).

    Returns
    -------
    numpy.ndarray, shape (size,)
        A float array (a view of ``value`` when it already is one).

    Raises
    ------
    ConfigurationError
        If ``value`` is not numeric, has another size, or has non-finite entries.
    """
    try:
        vec = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(f"{name} must be a vector of {size} numbers") from exc
    if vec.size != size:
        raise ConfigurationError(f"{name} must have {size} entries, got {vec.size}")
    if not np.all(np.isfinite(vec)):
        raise ConfigurationError(f"{name} has non-finite entries")
    return vec


def finite_number(value: object, name: str, *, positive: bool = False,
                  non_negative: bool = False) -> float:
    """Return ``value`` as a finite float, optionally > 0 or >= 0.

    Parameters
    ----------
    value : object
        A real number (a bool is refused).
    name : str
        The parameter's name in the error message.
    positive : bool, optional
        Require ``value > 0``.
    non_negative : bool, optional
        Require ``value >= 0``.

    Returns
    -------
    float
        The value.

    Raises
    ------
    ParameterError
        If ``value`` is not a finite number, or breaks the sign requirement.
    """
    if isinstance(value, bool):
        raise ParameterError(f"{name} must be a number, got {value!r}")
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be a number, got {value!r}") from exc
    if not math.isfinite(x):
        raise ParameterError(f"{name} must be finite, got {x}")
    if positive and x <= 0.0:
        raise ParameterError(f"{name} must be positive, got {x}")
    if non_negative and x < 0.0:
        raise ParameterError(f"{name} must be non-negative, got {x}")
    return x
