"""Quantities read off a finished run: head error, manipulability and g along the run."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, cast

import numpy as np

from .manipulability import manipulability
from .model import Snake

if TYPE_CHECKING:
    from .control.reference import HeadReference
    from .sim import Trajectory

__all__ = ["ERROR_WINDOW", "criteria_along", "error_caption", "head_error_summary",
           "head_position_error", "percent", "window"]

#: Head errors are judged over t >= this [s], after the start-up (the issues' window).
ERROR_WINDOW = 10.0


def head_position_error(traj: Trajectory, reference: HeadReference) -> np.ndarray:
    """Return the head position error ``|(x_h, y_h) - (x_h^r, y_h^r)|`` at every sample.

    Parameters
    ----------
    traj : Trajectory
        A finished (or stopped) run: ``traj.t`` has shape (N,), ``traj.q`` (N, n + 2).
    reference : HeadReference
        The head reference the run tracked (a line, or a path with its timing);
        ``reference(t)[0][:2]`` is ``(x_h^r, y_h^r)`` [m].

    Returns
    -------
    numpy.ndarray, shape (N,)
        Euclidean distance [m] at each sample time ``traj.t``.
    """
    ref = np.array([reference(t)[0][:2] for t in traj.t])
    return np.linalg.norm(traj.q[:, :2] - ref, axis=1)


def head_error_summary(traj: Trajectory, error: np.ndarray,
                       start: float = ERROR_WINDOW) -> dict[str, float | None]:
    """Return the RMS and max head error over ``t >= start`` and the relative RMS.

    The body length is the sum of the link lengths (``params.body_length``: per-link
    robots are judged against their own length, a long head included).

    Parameters
    ----------
    traj : Trajectory
        A finished (or stopped) run: ``traj.t`` has shape (N,), ``traj.q`` (N, n + 2).
    error : numpy.ndarray, shape (N,)
        Head error at every sample [m] (:func:`head_position_error`).
    start : float, optional
        Start of the judged window [s]; :data:`ERROR_WINDOW` by default.

    Returns
    -------
    dict of str to float or None
        ``rms_head_error`` [m], ``max_head_error`` [m] and ``rms_relative`` (RMS over
        the body length, a fraction); all three None when the run ends before ``start``.
    """
    late = window(traj, start)
    if not late.any():
        return {"rms_head_error": None, "max_head_error": None, "rms_relative": None}
    rms = float(np.sqrt(np.mean(error[late] ** 2)))
    return {"rms_head_error": rms, "max_head_error": float(error[late].max()),
            "rms_relative": rms / traj.params.body_length}


def percent(fraction: float | None) -> float | None:
    """Return a fraction as a percentage, passing None (no error window) through.

    Parameters
    ----------
    fraction : float or None
        A fraction (e.g. ``rms_relative``).

    Returns
    -------
    float or None
        ``100 * fraction``, or None.
    """
    return None if fraction is None else 100.0 * fraction


def error_caption(summary: Mapping[str, object]) -> str:
    """Return one line for figure titles: the RMS error of :func:`head_error_summary`.

    Parameters
    ----------
    summary : Mapping of str to object
        A run summary holding ``rms_head_error`` and ``rms_relative`` (as
        :func:`head_error_summary` returns them; ``Trajectory.summary`` does).

    Returns
    -------
    str
        ``"RMS error over t >= 10 s: 0.012 m (1.0 % of the body)"``, or a line saying
        the run was too short for the window.
    """
    rms = summary.get("rms_head_error")
    if rms is None:
        return f"run shorter than {ERROR_WINDOW:.0f} s: no RMS error window"
    relative = cast(float, summary["rms_relative"])
    return (f"RMS error over t >= {ERROR_WINDOW:.0f} s: {cast(float, rms):.3f} m "
            f"({100 * float(relative):.1f} % of the body)")


def criteria_along(traj: Trajectory, *, every: int = 1,
                   free_joint: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the manipulability criteria D and R along a run.

    Parameters
    ----------
    traj : Trajectory
        A finished (or stopped) run: ``traj.t`` has shape (N,), ``traj.q`` (N, n + 2).
    every : int, optional
        Evaluate every ``every``-th sample (1: all).
    free_joint : int or None, optional
        A 1-based joint to treat as free (D~, R~ of Section III.2) besides the robot's
        passive joints, which always count as free.

    Returns
    -------
    t : numpy.ndarray, shape (M,)
        Sample times [s], ``M = ceil(N / every)``.
    D, R : numpy.ndarray, shape (M,)
        The criteria of :func:`snake_pin.manipulability.manipulability` at those samples.
    """
    snake = Snake(traj.params)
    idx = np.arange(0, len(traj), every)
    d, r = np.empty(len(idx)), np.empty(len(idx))
    for out, k in enumerate(idx):
        res = manipulability(snake, traj.q[k], free_joint=free_joint)
        d[out], r[out] = res.D, res.R
    return traj.t[idx], d, r


def window(traj: Trajectory, start: float, stop: float | None = None) -> np.ndarray:
    """Return the mask of the samples with ``start <= t <= stop``.

    Parameters
    ----------
    traj : Trajectory
        A finished (or stopped) run: ``traj.t`` has shape (N,), ``traj.q`` (N, n + 2).
    start : float
        Window start [s].
    stop : float or None, optional
        Window end [s]; the run's last time by default.

    Returns
    -------
    numpy.ndarray of bool, shape (N,)
        True inside the window.
    """
    stop = traj.t_end if stop is None else stop
    return (traj.t >= start) & (traj.t <= stop)
