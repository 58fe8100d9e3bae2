"""The report's tracking runs on the batched path, stepped as lockstep batches (issue 14,
item 8).

:func:`run_tracking_batch` takes the runs the tracking stage would hand to
:func:`~snake_pin.experiments.tracking.run_tracking` one by one - (robot, duration,
controller options) - and steps those of one robot layout together through
:func:`snake_pin.batch.simulate_batch` (same RK4, zero-order hold, reference, gait, gains
and initial arc). Each trajectory then gets :func:`tracking_summary`, the summary
``run_tracking`` computes, so the report's sweep rows (label, RMS head error, % of body,
R min) are the same numbers up to the batch's rounding (``tests/test_failure_map.py``
checks 1e-9).

When it pays: a lockstep batch costs less per run as it grows (on this 2-core machine,
per process: parity with one :func:`~snake_pin.sim.simulate` per run near 6-8 runs,
about 2x at 20, 4x at 64), but it runs on one core, where the report's pool
(:func:`~snake_pin.experiments.parallel.run_jobs`) uses both. The report's own sweeps (4
runs) are below that size; the batched path is what lets a sweep grow to tens of values
for the time of a few single runs.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..control import LyapunovController, head_first_reference
from ..control.reference import LinearReference
from ..exceptions import ParameterError
from ..integrability import conserved_quantity_along
from ..metrics import criteria_along, head_error_summary, head_position_error
from ..model import Snake
from ..params import SnakeParams
from ..sim import Trajectory
from .tracking import CRITERIA_EVERY, initial_state

__all__ = ["run_tracking_batch", "tracking_summary"]

#: One run: (robot, t_final [s], LyapunovController options such as ``lam``).
TrackingJob = tuple[SnakeParams, float, Mapping[str, float]]


#: The LyapunovController keywords a job's options may set (the numeric ones).
_OPTIONS = frozenset({"lam", "lam_shape", "k_shape"})
#: The controller's own default of ``lam`` (read, not copied).
_DEFAULT_LAM: float = inspect.signature(LyapunovController).parameters["lam"].default


def _controller(snake: Snake, reference: LinearReference, options: Mapping[str, float],
                index: int) -> LyapunovController:
    """The job's LyapunovController, its options passed as explicit keywords."""
    unknown = set(options) - _OPTIONS
    if unknown:
        raise ParameterError(f"job {index}: unknown controller options {sorted(unknown)}; "
                             f"allowed: {sorted(_OPTIONS)}")
    return LyapunovController(snake, reference, lam=options.get("lam", _DEFAULT_LAM),
                              lam_shape=options.get("lam_shape"),
                              k_shape=options.get("k_shape"))


def run_tracking_batch(jobs: Sequence[TrackingJob], *, progress: bool = False
                       ) -> list[Trajectory]:
    """:func:`~snake_pin.experiments.tracking.run_tracking` of each job, in lockstep batches.

    Parameters
    ----------
    jobs : sequence of tuple
        (params, t_final [s], controller_options) per run, as ``run_tracking(params,
        t_final=..., **controller_options)`` takes them; the options may set ``lam``,
        ``lam_shape`` and ``k_shape`` of the LyapunovController. Runs of one robot layout
        (:data:`snake_pin.batch.LAYOUT_FIELDS`) form one batch; friction, passive joints,
        durations and options may differ.
    progress : bool, optional
        A tqdm bar per batch (terminal only).

    Returns
    -------
    list[Trajectory]
        In job order, each with the ``summary``, ``signals["head_error"]`` and
        ``meta["criteria"]`` that ``run_tracking`` gives.

    Raises
    ------
    ParameterError
        If a job is not ``(SnakeParams, t_final, options)`` or its options name a
        keyword other than ``lam``, ``lam_shape`` and ``k_shape``.
    """
    from ..batch import layout_key, simulate_batch

    jobs = list(jobs)
    groups: dict[tuple[Any, ...], list[int]] = {}
    for index, job in enumerate(jobs):
        if not isinstance(job, tuple) or len(job) != 3 or not isinstance(job[0], SnakeParams):
            raise ParameterError(f"job {index} must be (SnakeParams, t_final, options)")
        groups.setdefault(layout_key(job[0]), []).append(index)
    out: list[Trajectory | None] = [None] * len(jobs)
    reference = head_first_reference()
    for members in groups.values():
        snakes = [Snake(jobs[i][0]) for i in members]
        controllers = [_controller(snake, reference, jobs[i][2], i)
                       for snake, i in zip(snakes, members, strict=True)]
        metas = [{"reference": "w_r = [0.1 t, 0, pi]", "k_shape": c.k_shape, "lam": c.lam,
                  "lam_shape": c.lam_shape} for c in controllers]
        result = simulate_batch([s.params for s in snakes], controllers,
                                [initial_state(jobs[i][0]) for i in members],
                                [float(jobs[i][1]) for i in members], progress=progress,
                                meta=metas)
        for b, (snake, i) in enumerate(zip(snakes, members, strict=True)):
            out[i] = tracking_summary(result.trajectory(b), snake, reference)
    return [traj for traj in out if traj is not None]


def tracking_summary(traj: Trajectory, snake: Snake,
                     reference: LinearReference | None = None) -> Trajectory:
    """Add ``run_tracking``'s summary to a tracking run.

    Head error against ``reference`` as ``signals["head_error"]``; D and R every
    :data:`~snake_pin.experiments.tracking.CRITERIA_EVERY` samples as
    ``meta["criteria"]``; the summary: controller, friction, passive joints, the head
    error over t >= 10 s, R_min, D_min, body length, g_drift (max abs(g - g(0)) of eq. 67)
    and the final head pose.

    Parameters
    ----------
    traj
        The run (changed in place).
    snake
        Its robot.
    reference
        The head reference; None: w_r = [0.1 t, 0, pi].

    Returns
    -------
    Trajectory
        ``traj``.
    """
    params = snake.params
    reference = reference or head_first_reference()
    error = head_position_error(traj, reference)
    t_c, d, r = criteria_along(traj, every=CRITERIA_EVERY)
    g = conserved_quantity_along(snake, traj.q, traj.dq)
    traj.signals["head_error"] = error
    traj.meta["criteria"] = {"t": t_c.tolist(), "D": d.tolist(), "R": r.tolist()}
    traj.summary.update({
        "controller": "lyapunov", "c_x": params.c_x, "c_y": params.c_y,
        "passive": list(params.passive), **head_error_summary(traj, error),
        "R_min": float(r.min()), "D_min": float(d.min()),
        "body_length": params.body_length,
        "g_drift": float(np.abs(g - g[0]).max()),
        "final_head": traj.q[-1, :3].tolist(),
    })
    return traj
