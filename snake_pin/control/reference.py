"""Head references ``w_r(t) = [x_h, y_h, theta_1]`` with their first two derivatives."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np

from .._validation import as_vector, finite_number

#: ``HeadReference`` is a typing Protocol (importable, never instantiated), so it is not
#: listed: the public-callable checks would ask for its implicit ``*args, **kwargs``.
__all__ = ["LinearReference", "head_first_reference"]


class HeadReference(Protocol):
    """Any head reference a control law accepts: a callable of time.

    :class:`LinearReference` is one; a path's reference (``snake_pin.paths``) is another.
    """

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(w_r, w_r', w_r'')`` at time ``t``, each (3,): pose [m, m, rad], rate, acceleration."""
        ...


@dataclass(frozen=True)
class LinearReference:
    """``w_r(t) = start + velocity * t`` (eq. 80 is ``start = 0``, ``velocity = [0.1, 0, 0]``).

    Parameters
    ----------
    velocity : tuple of float, optional
        ``w_r'``, shape (3,): head velocity [m/s] in x and y and heading rate [rad/s].
    start : tuple of float, optional
        ``w_r(0)``, shape (3,): head position [m] and heading [rad] at t = 0.
    """

    velocity: tuple[float, float, float] = (0.1, 0.0, 0.0)
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    if TYPE_CHECKING:  # set in __post_init__; at run time no field (asdict is unchanged)
        _arrays: tuple[np.ndarray, np.ndarray] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        velocity, start = as_vector(self.velocity, 3, "velocity"), as_vector(self.start, 3, "start")
        object.__setattr__(self, "velocity", tuple(velocity))
        object.__setattr__(self, "start", tuple(start))
        object.__setattr__(self, "_arrays", (start.copy(), velocity.copy()))

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(w_r, w_r', w_r'') at time t (fresh arrays: callers may modify them)."""
        start, velocity = self._arrays
        return start + velocity * t, velocity.copy(), np.zeros(3)


def head_first_reference(speed: float = 0.1) -> LinearReference:
    """``w_r = [speed t, 0, pi]``: the head leads along +x, the body behind it (eq. 80).

    Parameters
    ----------
    speed : float, optional
        Head speed along +x [m/s].

    Returns
    -------
    LinearReference
        The reference.

    Raises
    ------
    ParameterError
        ``speed`` is not a finite number.
    """
    speed = finite_number(speed, "speed")
    return LinearReference(velocity=(speed, 0.0, 0.0), start=(0.0, 0.0, np.pi))
