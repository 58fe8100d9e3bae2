"""Posture families of Section IV: straight, arcs (all joints equal) and the serpenoid (43).

Configurations are the paper's ``q = [x_h, y_h, theta_1, phi_1 .. phi_{n-1}]``, states
``x = [q, dq]``. Every function refuses a bad argument with one line naming it:
:class:`~snake_pin.exceptions.ParameterError` (``n`` not an integer >= 2, a number not
finite, an unknown head keyword) or :class:`~snake_pin.exceptions.ConfigurationError`
(joint angles that are not a non-empty finite vector).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ._validation import finite_number, integer
from .exceptions import ConfigurationError, ParameterError

__all__ = ["Serpenoid", "arc", "configuration", "initial_state", "straight"]


#: Keyword arguments of the head pose (``**head`` of the posture functions).
_HEAD = ("x_h", "y_h", "theta_1")


def _head(head: Mapping[str, object]) -> dict[str, float]:
    """The head pose keywords, each a finite number; unknown keywords are refused."""
    unknown = sorted(set(head) - set(_HEAD))
    if unknown:
        raise ParameterError(f"unknown head pose argument {unknown[0]!r} "
                             f"(expected {', '.join(_HEAD)})")
    return {key: finite_number(value, key) for key, value in head.items()}


def _angles(phi: object) -> np.ndarray:
    """``phi`` as a non-empty finite float vector (any length), or ConfigurationError."""
    try:
        angles = np.asarray(phi, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigurationError("phi must be a vector of joint angles (numbers)") from exc
    if angles.ndim != 1 or angles.size == 0:
        raise ConfigurationError(f"phi must be a non-empty vector of joint angles, "
                                 f"got shape {angles.shape}")
    if not np.all(np.isfinite(angles)):
        raise ConfigurationError("phi has non-finite entries")
    return angles


def configuration(phi: np.ndarray, *, x_h: float = 0.0, y_h: float = 0.0,
                  theta_1: float = 0.0) -> np.ndarray:
    """Return ``q = [x_h, y_h, theta_1, phi]`` from joint angles and a head pose.

    Parameters
    ----------
    phi : array_like, shape (n - 1,)
        Joint angles [rad].
    x_h, y_h, theta_1 : float, optional
        Head position [m] (the head link's front end) and head link angle [rad].

    Returns
    -------
    numpy.ndarray, shape (n + 2,)
        The configuration q.

    Raises
    ------
    ConfigurationError
        ``phi`` is not a non-empty vector of finite numbers.
    ParameterError
        A head coordinate is not a finite number.
    """
    head = _head({"x_h": x_h, "y_h": y_h, "theta_1": theta_1})
    return np.r_[head["x_h"], head["y_h"], head["theta_1"], _angles(phi)]


def straight(n: int, **head: float) -> np.ndarray:
    """Return the straight posture, all joint angles zero (Section IV.1): singular (R = 0).

    Parameters
    ----------
    n : int
        Number of links, >= 2.
    **head : float
        Head pose ``x_h``, ``y_h`` [m], ``theta_1`` [rad], each 0 by default.

    Returns
    -------
    numpy.ndarray, shape (n + 2,)
        The configuration q.

    Raises
    ------
    ParameterError
        A bad argument (see the module docstring).
    """
    return configuration(np.zeros(integer(n, "n", low=2) - 1), **_head(head))


def arc(n: int, phi0: float, **head: float) -> np.ndarray:
    """Return the arc posture, all joints at the same angle phi0 (Section IV.2).

    ``abs(phi0) = 2 pi / n`` closes the body into a regular polygon.

    Parameters
    ----------
    n : int
        Number of links, >= 2.
    phi0 : float
        Angle of every joint [rad].
    **head : float
        Head pose ``x_h``, ``y_h`` [m], ``theta_1`` [rad], each 0 by default.

    Returns
    -------
    numpy.ndarray, shape (n + 2,)
        The configuration q.

    Raises
    ------
    ParameterError
        A bad argument (see the module docstring).
    """
    count = integer(n, "n", low=2) - 1
    phi0 = finite_number(phi0, "phi0")
    return configuration(np.full(count, phi0), **_head(head))


@dataclass(frozen=True)
class Serpenoid:
    """The serpenoid curve of eq. (43) for an n-link robot.

    Joint i follows::

        phi_i(t) = (2 pi T_s / n) alpha sin(v t - (2 pi T_s / n) i),   i = 1 .. n-1

    Parameters
    ----------
    n : int
        Number of links, >= 2.
    alpha : float
        Winding angle [rad].
    ts : float
        Number of periods T_s along the body.
    v : float, optional
        Temporal frequency [rad/s]; 0 (default) gives a still posture.

    Raises
    ------
    ParameterError
        A bad argument (see the module docstring).
    """

    n: int
    alpha: float
    ts: float
    v: float = 0.0

    def __post_init__(self) -> None:
        integer(self.n, "n", low=2)
        for name in ("alpha", "ts", "v"):
            object.__setattr__(self, name, finite_number(getattr(self, name), name))

    # constant parts of the phase and amplitudes, computed once (controllers' hot path);
    # cached_property stores them in the instance dict, which a frozen dataclass allows
    @cached_property
    def _offsets(self) -> np.ndarray:
        offsets = self.spatial_frequency * np.arange(1, self.n)
        offsets.flags.writeable = False
        return offsets

    @cached_property
    def _amplitudes(self) -> tuple[float, float, float]:
        amplitude = self.spatial_frequency * self.alpha
        return amplitude, amplitude * self.v, -amplitude * self.v**2

    @property
    def spatial_frequency(self) -> float:
        """The spatial frequency ``2 pi T_s / n`` [rad per link]."""
        return 2.0 * math.pi * self.ts / self.n

    def _phase(self, t: float) -> np.ndarray:
        return self.v * t - self._offsets

    def angles(self, t: float = 0.0) -> np.ndarray:
        """Return the joint angles phi(t) [rad] of eq. (43).

        Parameters
        ----------
        t : float, optional
            Time [s].

        Returns
        -------
        numpy.ndarray, shape (n - 1,)
            phi_1 .. phi_{n-1}.
        """
        return self.spatial_frequency * self.alpha * np.sin(self._phase(t))

    def velocities(self, t: float = 0.0) -> np.ndarray:
        """Return the joint velocities phi'(t) [rad/s].

        Parameters
        ----------
        t : float, optional
            Time [s].

        Returns
        -------
        numpy.ndarray, shape (n - 1,)
            phi'.
        """
        return self.spatial_frequency * self.alpha * self.v * np.cos(self._phase(t))

    def accelerations(self, t: float = 0.0) -> np.ndarray:
        """Return the joint accelerations phi''(t) [rad/s^2].

        Parameters
        ----------
        t : float, optional
            Time [s].

        Returns
        -------
        numpy.ndarray, shape (n - 1,)
            phi''.
        """
        return -self.spatial_frequency * self.alpha * self.v**2 * np.sin(self._phase(t))

    def derivatives(self, t: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (phi, phi', phi'') at time t with one sine and one cosine (a hot path).

        Parameters
        ----------
        t : float, optional
            Time [s].

        Returns
        -------
        phi, dphi, ddphi : numpy.ndarray, shape (n - 1,)
            :meth:`angles`, :meth:`velocities` and :meth:`accelerations` at t.
        """
        phase = self._phase(t)
        amplitude, velocity, acceleration = self._amplitudes
        sine = np.sin(phase)
        return amplitude * sine, velocity * np.cos(phase), acceleration * sine

    def configuration(self, t: float = 0.0, **head: float) -> np.ndarray:
        """Return the configuration q with the serpenoid joint angles at time t.

        Parameters
        ----------
        t : float, optional
            Time [s].
        **head : float
            Head pose ``x_h``, ``y_h`` [m], ``theta_1`` [rad], each 0 by default.

        Returns
        -------
        numpy.ndarray, shape (n + 2,)
            The configuration q.

        Raises
        ------
        ParameterError
            A head keyword is unknown or not a finite number.
        """
        return configuration(self.angles(t), **_head(head))


def initial_state(n: int, theta_1: float = 0.0) -> np.ndarray:
    """Return the initial state of eq. (82): head at the origin, every joint at pi/6, at rest.

    ``theta_1 = pi`` gives the head-first orientation used for tracking along +x.

    Parameters
    ----------
    n : int
        Number of links, >= 2.
    theta_1 : float, optional
        Head link angle [rad].

    Returns
    -------
    numpy.ndarray, shape (2(n + 2),)
        ``x = [q, dq]``, ``q = [0, 0, theta_1, pi/6 .. pi/6]``, ``dq = 0``.

    Raises
    ------
    ParameterError
        A bad argument (see the module docstring).
    """
    return np.r_[arc(n, math.pi / 6, theta_1=theta_1), np.zeros(integer(n, "n", low=2) + 2)]
