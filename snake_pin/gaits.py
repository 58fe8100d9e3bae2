"""Posture families of Section IV: straight, arcs (all joints equal) and the serpenoid (43)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._validation import finite_number
from .exceptions import ParameterError

__all__ = ["Serpenoid", "arc", "configuration", "initial_state", "straight"]


def _check_n(n: int) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
        raise ParameterError(f"n must be an integer >= 2, got {n!r}")
    return int(n)


def configuration(phi: np.ndarray, *, x_h: float = 0.0, y_h: float = 0.0,
                  theta_1: float = 0.0) -> np.ndarray:
    """q = [x_h, y_h, theta_1, phi] from joint angles and a head pose."""
    return np.r_[x_h, y_h, theta_1, np.asarray(phi, dtype=float)]


def straight(n: int, **head: float) -> np.ndarray:
    """All joint angles zero (Section IV.1): the known singular posture."""
    return configuration(np.zeros(_check_n(n) - 1), **head)


def arc(n: int, phi0: float, **head: float) -> np.ndarray:
    """All joints at the same angle phi0 (Section IV.2); |phi0| = 2 pi / n closes a polygon."""
    phi0 = finite_number(phi0, "phi0")
    return configuration(np.full(_check_n(n) - 1, phi0), **head)


@dataclass(frozen=True)
class Serpenoid:
    """The serpenoid curve of eq. (43) for an n-link robot.

    phi_i(t) = (2 pi T_s / n) alpha sin(v t - (2 pi T_s / n) i), i = 1..n-1.

    Parameters
    ----------
    n
        Number of links.
    alpha
        Winding angle [rad].
    ts
        Number of periods T_s along the body.
    v
        Temporal frequency [rad/s].
    """

    n: int
    alpha: float
    ts: float
    v: float = 0.0

    def __post_init__(self) -> None:
        _check_n(self.n)
        for name in ("alpha", "ts", "v"):
            object.__setattr__(self, name, finite_number(getattr(self, name), name))
        # constant parts of the phase and amplitudes, computed once (controllers' hot path)
        offsets = self.spatial_frequency * np.arange(1, self.n)
        offsets.flags.writeable = False
        object.__setattr__(self, "_offsets", offsets)
        amplitude = self.spatial_frequency * self.alpha
        object.__setattr__(self, "_amplitudes",
                           (amplitude, amplitude * self.v, -amplitude * self.v**2))

    @property
    def spatial_frequency(self) -> float:
        """2 pi T_s / n."""
        return 2.0 * math.pi * self.ts / self.n

    def _phase(self, t: float) -> np.ndarray:
        return self.v * t - self._offsets

    def angles(self, t: float = 0.0) -> np.ndarray:
        """phi(t) of eq. (43)."""
        return self.spatial_frequency * self.alpha * np.sin(self._phase(t))

    def velocities(self, t: float = 0.0) -> np.ndarray:
        """phi'(t)."""
        return self.spatial_frequency * self.alpha * self.v * np.cos(self._phase(t))

    def accelerations(self, t: float = 0.0) -> np.ndarray:
        """phi''(t)."""
        return -self.spatial_frequency * self.alpha * self.v**2 * np.sin(self._phase(t))

    def derivatives(self, t: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(phi, phi', phi'') at time t with one sine and one cosine (controllers' hot path)."""
        phase = self._phase(t)
        amplitude, velocity, acceleration = self._amplitudes
        sine = np.sin(phase)
        return amplitude * sine, velocity * np.cos(phase), acceleration * sine

    def configuration(self, t: float = 0.0, **head: float) -> np.ndarray:
        """q with the serpenoid joint angles at time t."""
        return configuration(self.angles(t), **head)


def initial_state(n: int, theta_1: float = 0.0) -> np.ndarray:
    """Eq. (82): head at the origin, every joint at pi/6, at rest; x = [q, dq].

    ``theta_1 = pi`` gives the head-first orientation used for tracking along +x.
    """
    return np.r_[arc(n, math.pi / 6, theta_1=theta_1), np.zeros(_check_n(n) + 2)]
