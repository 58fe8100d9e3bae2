"""How the report's tracking runs are executed: single runs on every core, or lockstep
batches.

A tracking job is what :func:`~snake_pin.experiments.tracking.run_tracking` takes:
(robot, duration, controller options). :func:`run_tracking_batch` steps jobs of one robot
layout together through :func:`snake_pin.batch.simulate_batch` (same RK4, zero-order hold,
reference, gait, gains and initial arc); :func:`iter_tracking_runs` runs a list of jobs on
the machine's cores (:func:`snake_pin.experiments.parallel.iter_jobs`) by the faster of the
two routes and hands each trajectory over as it finishes. Either way each run gets
:func:`~snake_pin.experiments.tracking.tracking_summary`, so the report's rows are the same
numbers up to the batch's rounding (``tests/test_batched_sweeps.py`` checks 1e-9).

Which route: a lockstep batch has a large fixed cost per control step (numpy calls over
the batch) and a small one per run, while a single run pays only Pinocchio's per-run
calls. Measured on this 2-core machine (one process, 5 s tracking runs): a batch of B
runs costs 2.9x a single run per run at B = 2, 1.6x at 4, 0.9x at 8, 0.6x at 16. A batch
also runs on one core where single runs fill every core, so lockstep pays only from
:data:`snake_pin.study.work.MIN_LOCKSTEP` (8) runs per worker, the study's own rule
(medians of 3 interleaved rounds, 2 workers, 10 s runs: 16 runs as two batches of 8 took
0.92x the time of the runs one by one; 24 runs as two batches of 12, 0.69x; 8 runs as
two batches of 4, 1.53x). The tracking stage's 18 runs (four with files, the two sweeps'
14 points) therefore run as two lockstep batches of 9 on this machine: 0.86x (0.85-0.86)
the time of the same runs one by one (``python scripts/bench.py --only sweeps``, 20 s runs,
3 interleaved rounds).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Generator, Mapping, Sequence
from typing import Any, cast

from ..control import LyapunovController, head_first_reference
from ..control.reference import LinearReference
from ..exceptions import ParameterError
from ..model import Snake
from ..params import SnakeParams
from ..sim import Trajectory
from .parallel import Job, iter_jobs
from .tracking import _DEFAULT_LAM, initial_state, run_tracking, tracking_meta, tracking_summary

__all__ = ["iter_tracking_runs", "run_tracking_batch"]

#: One run: (robot, t_final [s], LyapunovController options such as ``lam``). Not in
#: ``__all__``: autodoc cannot document a ``tuple[...]`` alias (the functions show it).
TrackingJob = tuple[SnakeParams, float, Mapping[str, float]]


#: The LyapunovController keywords a job's options may set (the numeric ones).
_OPTIONS = frozenset({"lam", "lam_shape", "k_shape"})


def _checked(jobs: Sequence[TrackingJob]) -> list[TrackingJob]:
    """The jobs as a list; ParameterError for one that is not (SnakeParams, t_final,
    options) or whose options name another keyword than ``lam``, ``lam_shape``,
    ``k_shape``."""
    jobs = list(jobs)
    for index, job in enumerate(jobs):
        if not isinstance(job, tuple) or len(job) != 3 or not isinstance(job[0], SnakeParams) \
                or not isinstance(job[2], Mapping):
            raise ParameterError(f"job {index} must be (SnakeParams, t_final, options)")
        unknown = set(job[2]) - _OPTIONS
        if unknown:
            raise ParameterError(f"job {index}: unknown controller options {sorted(unknown)}; "
                                 f"allowed: {sorted(_OPTIONS)}")
    return jobs


def _controller(snake: Snake, reference: LinearReference,
                options: Mapping[str, float]) -> LyapunovController:
    """The job's LyapunovController, its options passed as explicit keywords."""
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

    jobs = _checked(jobs)
    groups: dict[tuple[Any, ...], list[int]] = {}
    for index, job in enumerate(jobs):
        groups.setdefault(layout_key(job[0]), []).append(index)
    out: list[Trajectory | None] = [None] * len(jobs)
    reference = head_first_reference()
    for members in groups.values():
        snakes = [Snake(jobs[i][0]) for i in members]
        controllers = [_controller(snake, reference, jobs[i][2])
                       for snake, i in zip(snakes, members, strict=True)]
        result = simulate_batch([s.params for s in snakes], controllers,
                                [initial_state(jobs[i][0]) for i in members],
                                [float(jobs[i][1]) for i in members], progress=progress,
                                meta=[tracking_meta(c) for c in controllers])
        for b, (snake, i) in enumerate(zip(snakes, members, strict=True)):
            out[i] = tracking_summary(result.trajectory(b), snake, reference)
    return [traj for traj in out if traj is not None]


def iter_tracking_runs(jobs: Sequence[TrackingJob], *, workers: int | None = None,
                       lockstep_from: int | None = None
                       ) -> Generator[tuple[int, Trajectory], None, None]:
    """``(index, trajectory)`` of each job as it finishes, on up to ``workers`` cores.

    The jobs of one robot layout run as one lockstep batch per worker
    (:func:`run_tracking_batch`) when each worker gets at least ``lockstep_from`` of them,
    else one by one (:func:`~snake_pin.experiments.tracking.run_tracking`), the longest
    first. Both routes give the same trajectories up to rounding.

    Parameters
    ----------
    jobs : sequence of tuple
        (params, t_final [s], controller_options) per run, as for
        :func:`run_tracking_batch`.
    workers : int, optional
        Processes (default: one per core); 1 runs everything here, in order.
    lockstep_from : int, optional
        Fewest runs per worker that go as a lockstep batch (default
        :data:`snake_pin.study.work.MIN_LOCKSTEP`).

    Returns
    -------
    generator of tuple of (int, Trajectory)
        Yields the job's index in ``jobs`` and its run (with
        :func:`~snake_pin.experiments.tracking.tracking_summary`'s summary); a batch's runs
        come together when the batch is done.

    Raises
    ------
    ParameterError
        A bad job (as for :func:`run_tracking_batch`), ``workers`` or ``lockstep_from``
        not a positive integer.
    BaseException
        What a job raises, or a KeyboardInterrupt while waiting: the workers are
        terminated first (:func:`~snake_pin.experiments.parallel.iter_jobs`). Closing the
        generator (as ``contextlib.closing`` does when the caller's loop raises)
        terminates them too.
    """
    from ..batch import layout_key
    from ..study.work import MIN_LOCKSTEP

    jobs = _checked(jobs)
    for name, value in (("workers", workers), ("lockstep_from", lockstep_from)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int)
                                  or value < 1):
            raise ParameterError(f"{name} must be a positive integer, got {value!r}")
    cores = workers or os.cpu_count() or 1
    least = lockstep_from or MIN_LOCKSTEP
    # longest first: single runs then fill the cores evenly, and batches get equal shares
    order = sorted(range(len(jobs)), key=lambda i: -float(jobs[i][1]))
    groups: dict[tuple[Any, ...], list[int]] = {}
    for index in order:
        groups.setdefault(layout_key(jobs[index][0]), []).append(index)
    tasks: list[tuple[list[int], bool, Job]] = []  # (job indices, lockstep?, task)
    for members in groups.values():
        if len(members) >= least * cores:
            for first in range(cores):
                share = members[first::cores]
                tasks.append((share, True,
                              (run_tracking_batch, ([jobs[i] for i in share],), {})))
        else:
            tasks += [([i], False, (run_tracking, (jobs[i][0],),
                                    {"t_final": jobs[i][1], **jobs[i][2]})) for i in members]
    return _finished(tasks, cores)  # the arguments are checked now, not at the first next()


def _finished(tasks: list[tuple[list[int], bool, Job]],
              cores: int) -> Generator[tuple[int, Trajectory], None, None]:
    """(job index, trajectory) of the tasks as they finish (see iter_tracking_runs)."""
    # closed with this generator (an exception in the caller's loop): the pool goes too
    results = cast(Generator[tuple[int, Any], None, None],  # iter_jobs is a generator
                   iter_jobs([job for _, _, job in tasks], cores))
    with contextlib.closing(results) as finished:
        for task, result in finished:
            members, lockstep, _ = tasks[task]
            yield from zip(members, result if lockstep else [result], strict=True)
