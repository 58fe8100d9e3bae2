"""Quantities read off a finished run: head error, manipulability and g along the run."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .manipulability import manipulability
from .model import Snake

if TYPE_CHECKING:
    from .control.reference import LinearReference
    from .sim import Trajectory

__all__ = ["criteria_along", "head_position_error", "window"]


def head_position_error(traj: Trajectory, reference: LinearReference) -> np.ndarray:
    """|(x_h, y_h) - (x_h^r, y_h^r)| at every sample [m]."""
    ref = np.array([reference(t)[0][:2] for t in traj.t])
    return np.linalg.norm(traj.q[:, :2] - ref, axis=1)


def criteria_along(traj: Trajectory, *, every: int = 1,
                   free_joint: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, D, R) at every ``every``-th sample; the robot's passive joints count as free."""
    snake = Snake(traj.params)
    idx = np.arange(0, len(traj), every)
    d, r = np.empty(len(idx)), np.empty(len(idx))
    for out, k in enumerate(idx):
        res = manipulability(snake, traj.q[k], free_joint=free_joint)
        d[out], r[out] = res.D, res.R
    return traj.t[idx], d, r


def window(traj: Trajectory, start: float, stop: float | None = None) -> np.ndarray:
    """Boolean mask of samples with start <= t <= stop."""
    stop = traj.t_end if stop is None else stop
    return (traj.t >= start) & (traj.t <= stop)
