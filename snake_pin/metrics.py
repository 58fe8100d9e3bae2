"""Quantities read off a finished run: head error, manipulability and g along the run."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .manipulability import manipulability
from .model import Snake

if TYPE_CHECKING:
    from .control.reference import LinearReference
    from .sim import Trajectory

__all__ = ["ERROR_WINDOW", "criteria_along", "error_caption", "head_error_summary",
           "head_position_error", "percent", "window"]

#: Head errors are judged over t >= this [s], after the start-up (the issues' window).
ERROR_WINDOW = 10.0


def head_position_error(traj: Trajectory, reference: LinearReference) -> np.ndarray:
    """|(x_h, y_h) - (x_h^r, y_h^r)| at every sample [m]."""
    ref = np.array([reference(t)[0][:2] for t in traj.t])
    return np.linalg.norm(traj.q[:, :2] - ref, axis=1)


def head_error_summary(traj: Trajectory, error: np.ndarray,
                       start: float = ERROR_WINDOW) -> dict[str, float | None]:
    """RMS and max head error over t >= ``start`` and the RMS relative to the body length.

    The body length is the sum of the link lengths (``params.body_length``: per-link
    robots are judged against their own length, a long head included).

    All three are None when the run ends before ``start``.
    """
    late = window(traj, start)
    if not late.any():
        return {"rms_head_error": None, "max_head_error": None, "rms_relative": None}
    rms = float(np.sqrt(np.mean(error[late] ** 2)))
    return {"rms_head_error": rms, "max_head_error": float(error[late].max()),
            "rms_relative": rms / traj.params.body_length}


def percent(fraction: float | None) -> float | None:
    """100 * fraction, passing None (no error window) through, for report tables."""
    return None if fraction is None else 100.0 * fraction


def error_caption(summary: dict[str, object]) -> str:
    """One line for figure titles: the RMS error of :func:`head_error_summary`, if any."""
    rms = summary.get("rms_head_error")
    if rms is None:
        return f"run shorter than {ERROR_WINDOW:.0f} s: no RMS error window"
    return (f"RMS error over t >= {ERROR_WINDOW:.0f} s: {rms:.3f} m "
            f"({100 * float(summary['rms_relative']):.1f} % of the body)")


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
