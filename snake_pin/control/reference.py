"""Head references w_r(t) = [x_h, y_h, theta_1] with their first two derivatives."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validation import as_vector

__all__ = ["LinearReference"]


@dataclass(frozen=True)
class LinearReference:
    """w_r(t) = start + velocity * t (eq. 80 is start = 0, velocity = [0.1, 0, 0])."""

    velocity: tuple[float, float, float] = (0.1, 0.0, 0.0)
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        velocity, start = as_vector(self.velocity, 3, "velocity"), as_vector(self.start, 3, "start")
        object.__setattr__(self, "velocity", tuple(velocity))
        object.__setattr__(self, "start", tuple(start))
        object.__setattr__(self, "_arrays", (start.copy(), velocity.copy()))

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(w_r, w_r', w_r'') at time t (fresh arrays: callers may modify them)."""
        start, velocity = self._arrays
        return start + velocity * t, velocity.copy(), np.zeros(3)
