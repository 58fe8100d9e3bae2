"""Quantities read off a finished run (head error, manipulability along it) for summaries
by the command line, the experiments and the studies (not public API)."""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from typing import TYPE_CHECKING, cast

import numpy as np

from ._validation import brief, finite_number, instance, integer, vector
from .exceptions import ParameterError
from .manipulability import manipulability, task_split
from .model import Snake

if TYPE_CHECKING:
    from .control.reference import HeadReference
    from .trajectory import Trajectory

__all__: list[str] = []

#: Head errors are judged over t >= this [s] in runs of at least twice its length, after
#: the start-up; shorter runs are judged over their second half (:func:`default_error_window`).
ERROR_WINDOW = 10.0


def _check_traj(value: object) -> Trajectory:
    """``value`` if it is a :class:`~snake_pin.trajectory.Trajectory`, else ParameterError."""
    from .trajectory import Trajectory

    return instance(value, Trajectory, "traj")


def _check_summary(value: object) -> Mapping[str, object]:
    """``value`` if it is a mapping whose window and error entries are numbers or None."""
    if not isinstance(value, Mapping):
        raise ParameterError(f"summary must be a mapping (a run summary), got {brief(value)}")
    for key in ("error_window", "rms_head_error", "rms_relative", "t_end"):
        entry = value.get(key)
        if entry is not None and (isinstance(entry, (bool, np.bool_))
                                  or not isinstance(entry, numbers.Real)):
            raise ParameterError(f"summary[{key!r}] must be a number, got {brief(entry)}")
    return value


def default_error_window(t_final: float) -> float:
    """Return ``min(ERROR_WINDOW, t_final / 2)``: every run has a head-error window."""
    return min(ERROR_WINDOW, 0.5 * finite_number(t_final, "t_final", non_negative=True))


def head_position_error(traj: Trajectory, reference: HeadReference) -> np.ndarray:
    """Return ``|(x_h, y_h) - reference(t)[0][:2]|`` [m] at every sample of ``traj``."""
    _check_traj(traj)
    if not callable(reference):
        raise ParameterError(f"reference must be a head reference (a callable of time), "
                             f"got {brief(reference)}")
    ref = np.array([reference(t)[0][:2] for t in traj.t])
    return np.linalg.norm(traj.q[:, :2] - ref, axis=1)


def head_error_summary(traj: Trajectory, error: np.ndarray,
                       start: float | None = None) -> dict[str, float | None]:
    """Return the RMS and max head error over ``t >= start`` (default
    :func:`default_error_window`) in m and in % of the body length, and ``rms_relative``;
    all but ``error_window`` None when no sample lies in the window."""
    _check_traj(traj)
    error = vector(error, "error", size=len(traj), finite=False)  # a diverged run's NaN kept
    start = (default_error_window(traj.t_end) if start is None
             else finite_number(start, "start"))
    late = window(traj, start)
    if not late.any():
        return {"error_window": start, **dict.fromkeys(
            ("rms_head_error", "max_head_error", "rms_head_error_pct", "max_head_error_pct",
             "rms_relative"))}
    rms = float(np.sqrt(np.mean(error[late] ** 2)))
    peak = float(error[late].max())
    body = traj.params.body_length
    return {"error_window": start, "rms_head_error": rms, "max_head_error": peak,
            "rms_head_error_pct": 100.0 * rms / body, "max_head_error_pct": 100.0 * peak / body,
            "rms_relative": rms / body}


def window_note(summary: Mapping[str, object]) -> str:
    """Return one line saying that a run's head-error window is empty, or ""."""
    start = _check_summary(summary).get("error_window")
    if start is None or "rms_head_error" not in summary \
            or summary.get("rms_head_error") is not None:
        return ""
    end = summary.get("t_end")
    ends = f" (the run ends at {float(cast(float, end)):g} s)" if end is not None else ""
    return (f"no samples in the head-error window t >= {float(cast(float, start)):g} s{ends}: "
            "the head-error metrics are null")


def percent(fraction: float | None) -> float | None:
    """Return a fraction as a percentage, passing None (no error window) through."""
    return None if fraction is None else 100.0 * finite_number(fraction, "fraction")


def error_caption(summary: Mapping[str, object]) -> str:
    """Return one line for figure titles: the RMS error of :func:`head_error_summary`."""
    start = float(cast(float, _check_summary(summary).get("error_window", ERROR_WINDOW)))
    rms = summary.get("rms_head_error")
    if rms is None:
        return f"no samples in the error window t >= {start:g} s: no RMS error"
    relative = cast(float, summary["rms_relative"])
    return (f"RMS error over t >= {start:g} s: {cast(float, rms):.3f} m "
            f"({100 * float(relative):.1f} % of the body)")


def criteria_along(traj: Trajectory, *, every: int = 1,
                   free_joint: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return ``(t, D, R)`` every ``every``-th sample; passive joints free, ``free_joint`` too."""
    snake = Snake(_check_traj(traj).params)
    every = integer(every, "every", low=1)
    task_split(snake.n, free_joint)  # the free joint checked before the first sample
    idx = np.arange(0, len(traj), every)
    d, r = np.empty(len(idx)), np.empty(len(idx))
    for out, k in enumerate(idx):
        res = manipulability(snake, traj.q[k], free_joint=free_joint)
        d[out], r[out] = res.D, res.R
    return traj.t[idx], d, r


def applied(traj: Trajectory) -> np.ndarray:
    """Return the mask of the samples whose torque was applied (not the last, unless diverged)."""
    mask = np.ones(len(_check_traj(traj)), dtype=bool)
    if traj.status != "diverged" and mask.size:
        mask[-1] = False
    return mask


def window(traj: Trajectory, start: float, stop: float | None = None) -> np.ndarray:
    """Return the mask of the samples with ``start <= t <= stop``."""
    _check_traj(traj)
    start = finite_number(start, "start")
    stop = traj.t_end if stop is None else finite_number(stop, "stop")
    return (traj.t >= start) & (traj.t <= stop)


def torque_max(traj: Trajectory) -> float | None:
    """Return the peak ``|tau_i|`` [N m] over all applied samples, or None if none is finite."""
    tau = np.abs(_check_traj(traj).tau[applied(traj)])
    tau = tau[np.isfinite(tau)]
    return float(tau.max()) if tau.size else None
