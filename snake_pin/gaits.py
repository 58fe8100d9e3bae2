"""Posture families of Section IV: straight, arcs (all joints equal) and the serpenoid (43),
as configurations ``q = [x_h, y_h, theta_1, phi]``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ._validation import finite_number, integer, vector
from .exceptions import ParameterError

__all__ = ["Serpenoid", "arc", "configuration", "initial_state", "straight"]

_HEAD = ("x_h", "y_h", "theta_1")


def _head(head: Mapping[str, object]) -> dict[str, float]:
    """The head pose keywords, each a finite number; unknown keywords are refused."""
    unknown = sorted(set(head) - set(_HEAD))
    if unknown:
        raise ParameterError(f"unknown head pose argument {unknown[0]!r} "
                             f"(expected {', '.join(_HEAD)})")
    return {key: finite_number(value, key) for key, value in head.items()}


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
    ConfigurationError, ParameterError
        ``phi`` is not a non-empty finite vector; a head coordinate is not a finite number.
    """
    head = _head({"x_h": x_h, "y_h": y_h, "theta_1": theta_1})
    return np.r_[head["x_h"], head["y_h"], head["theta_1"], vector(phi, "phi")]


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
        A bad argument.
    """
    return configuration(np.zeros(integer(n, "n", low=2) - 1), **_head(head))


def arc(n: int, phi0: float, **head: float) -> np.ndarray:
    """Return the arc posture, all joints at phi0 (Section IV.2; ``2 pi / n`` closes it).

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
        A bad argument.
    """
    count = integer(n, "n", low=2) - 1
    return configuration(np.full(count, finite_number(phi0, "phi0")), **_head(head))


@dataclass(frozen=True)
class Serpenoid:
    """The serpenoid curve of eq. (43): ``phi_i(t) = k alpha sin(v t - k i)``, k = 2 pi T_s / n.

    Parameters
    ----------
    n : int
        Number of links, >= 2.
    alpha, ts : float
        Winding angle [rad]; number of periods T_s along the body.
    v : float, optional
        Temporal frequency [rad/s]; 0 (default) gives a still posture.

    Raises
    ------
    ParameterError
        A bad argument.
    """

    n: int
    alpha: float
    ts: float
    v: float = 0.0

    def __post_init__(self) -> None:
        integer(self.n, "n", low=2)
        for name in ("alpha", "ts", "v"):
            object.__setattr__(self, name, finite_number(getattr(self, name), name))

    # constant parts of the phase and the amplitudes, once
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
        return self._amplitudes[0] * np.sin(self.v * t - self._offsets)

    def derivatives(self, t: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (phi, phi', phi'') at time t with one sine and one cosine (a hot path).

        Parameters
        ----------
        t : float, optional
            Time [s].

        Returns
        -------
        phi, dphi, ddphi : numpy.ndarray, shape (n - 1,)
            phi at t (as :meth:`angles`) and its first and second time derivatives.
        """
        phase = self.v * t - self._offsets
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
        """
        return configuration(self.angles(t), **_head(head))


def initial_state(n: int, theta_1: float = 0.0) -> np.ndarray:
    """Return the initial state of eq. (82): head at the origin, every joint at pi/6, at rest.

    Parameters
    ----------
    n : int
        Number of links, >= 2.
    theta_1 : float, optional
        Head link angle [rad] (pi: head first along +x, for tracking).

    Returns
    -------
    numpy.ndarray, shape (2(n + 2),)
        ``x = [q, dq]``, ``q = [0, 0, theta_1, pi/6 .. pi/6]``, ``dq = 0``.

    Raises
    ------
    ParameterError
        A bad argument.
    """
    return np.r_[arc(n, math.pi / 6, theta_1=theta_1), np.zeros(integer(n, "n", low=2) + 2)]
