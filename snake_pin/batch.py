"""Lockstep batches of closed-loop runs: B runs of one robot layout stepped together.

:func:`simulate_batch` is :func:`snake_pin.sim.simulate` for B runs at once. Every run
keeps its own robot friction, passive (failed) joints, controller (gains, gait,
reference), initial state and final time; the runs share the robot's *layout*
(:data:`~snake_pin.control.batched.LAYOUT_FIELDS`: n, link lengths, masses, inertias and
CM offsets), which fixes the one Pinocchio model they are integrated on. Passive joints
are masks on the torque, not different models.

Each control step does what :func:`~snake_pin.sim.simulate` does for one run, for the m
runs still going:

1. the controllers' torques for all m runs (vectorised laws of
   :mod:`snake_pin.control.batched`; other controllers run by run), held over the
   control period (zero-order hold);
2. ``control_dt / dt`` classical RK4 steps of ``dt`` (simulate's arithmetic), whose
   stage accelerations come, for the whole batch at once, from one of two routes
   (``dynamics``):

   - ``"closed_form"`` (default): the closed-form model over the batch
     (:meth:`~snake_pin.control.batched.BatchTerms.forward_dynamics`: in link-angle
     coordinates with the head eliminated, one batched n x n solve per stage), with
     every run's friction (per-run, per-link coefficients; the complex-number route of
     :mod:`snake_pin.friction`) and its masked torques as the generalised force. When
     every run's torque-level controller models its plant exactly, the first stage is
     the q'' the controller already solved for;
   - ``"aba"``: ``pin.abaInParallel`` over a ``pin.ModelPool`` (Pinocchio's C++ ABA for
     the batch), friction and masked torques as the joint torque.

   Measured at n = 10 (``scripts/bench_batch.py``; one process on this 2-core machine,
   a busy neighbour): about 8 us per run and control step at B = 256..1024 for the
   closed form (120+ simulated seconds per wall second, 10x the single run of commit
   dc0b889 timed alongside), 30-50 us with ``abaInParallel`` (whose ABA alone costs
   ~4-5 us per run and evaluation);
3. the divergence test on each run.

A run that diverges, whose controller raises or returns a bad torque, or that reaches its
final time, leaves the batch on its own, with :func:`~snake_pin.sim.simulate`'s status
and reason; the others go on. The results equal :func:`~snake_pin.sim.simulate`'s run
by run up to rounding (closed-form model terms and batched solves instead of Pinocchio's
and LAPACK's per-run calls; ``tests/test_batch.py`` checks 1e-9 over 3 s). Small batches
pay numpy's per-call overhead: below B of about 16, :func:`~snake_pin.sim.simulate` is
faster.

OpenMP: ``abaInParallel`` runs on ``threads`` OpenMP threads (default 1, one process per
core being the usual layout). With more than one thread, start the process with
``OMP_WAIT_POLICY=PASSIVE`` (before Pinocchio is imported): with OpenMP's default spinning
wait and a busy neighbour core, 2 threads ran 5-10x slower than 1 here.

Memory: samples are kept every ``stride`` control steps (plus each run's last one), as
arrays with the sample first; :meth:`BatchResult.trajectory` gives a run as a
:class:`~snake_pin.sim.Trajectory`.
"""

from __future__ import annotations

import math
import numbers
import os
import reprlib
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pinocchio as pin

from .control.base import Controller
from .control.batched import (
    LAYOUT_FIELDS,
    BatchedController,
    BatchTerms,
    FrictionCoefficients,
    batch_controller,
    layout_key,
)
from .exceptions import ConfigurationError, ParameterError, RunInterrupted
from .model import Snake, paper_model
from .params import SnakeParams
from .sim import (
    MAX_DISTANCE,
    MAX_SPEED,
    Trajectory,
    _as_controller,
    _check_size,
    _check_steps,
    _divergence,
    _failure,
    _number,
    _progress,
    _torque,
)

__all__ = ["DYNAMICS", "LAYOUT_FIELDS", "MAX_BATCH", "MAX_RECORD_BYTES", "BatchResult",
           "layout_key", "simulate_batch"]

#: The forward-dynamics routes of :func:`simulate_batch` (see the module docstring).
DYNAMICS = ("closed_form", "aba")

#: Most runs one batch may hold.
MAX_BATCH = 65_536
#: Largest total of the recorded arrays of one batch [bytes] (use ``stride`` beyond it).
MAX_RECORD_BYTES = 4 * 2**30


@dataclass
class BatchResult:
    """The runs of a batch: samples on a shared grid plus each run's last sample.

    Built by :func:`simulate_batch`; B runs, S grid samples, n links. Configurations
    are the paper's ``q = [x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad...].

    Parameters
    ----------
    params : list of SnakeParams
        Each run's robot (B).
    t : numpy.ndarray, shape (S,)
        Times of the grid samples [s]: every ``stride``-th control step from t = 0.
    q, dq : numpy.ndarray, shape (S, B, n + 2)
        Grid samples of q and its time derivative, sample first. Entries of run b are
        meaningful for grid steps before its last sample ``last_step[b]``; the rest are
        zero.
    tau : numpy.ndarray, shape (S, B, n - 1)
        Joint torques [N m] held after each grid sample.
    signals : dict of str to numpy.ndarray
        Controller diagnostics on the grid, shape (S, B) each, NaN where missing.
    status, reason : list of str
        Each run's status (:data:`snake_pin.sim.STATUSES`) and reason.
    last_step : numpy.ndarray of int, shape (B,)
        Control step of each run's last good sample; its time is ``last_t``.
    last_t : numpy.ndarray, shape (B,)
        Time of each run's last good sample [s].
    last_q, last_dq : numpy.ndarray, shape (B, n + 2)
        Each run's last good configuration and velocity.
    last_tau : numpy.ndarray, shape (B, n - 1)
        The torque held after each run's last sample (zero unless the run diverged, as in
        :func:`~snake_pin.sim.simulate`).
    last_signals : dict of str to numpy.ndarray, optional
        Signal name -> each run's last value, shape (B,).
    signal_runs : dict of str to numpy.ndarray, optional
        For each signal, which runs' controllers gave it (bool, shape (B,)); the others'
        trajectories have no such signal, as from :func:`~snake_pin.sim.simulate`.
    stride : int, optional
        Control steps between grid samples.
    meta : list of dict, optional
        Each run's :attr:`Trajectory.meta <snake_pin.sim.Trajectory.meta>`.
    wall_time : float, optional
        Wall-clock time of the whole batch [s].
    """

    params: list[SnakeParams]
    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    signals: dict[str, np.ndarray]
    status: list[str]
    reason: list[str]
    last_step: np.ndarray
    last_t: np.ndarray
    last_q: np.ndarray
    last_dq: np.ndarray
    last_tau: np.ndarray
    last_signals: dict[str, np.ndarray] = field(default_factory=dict)
    signal_runs: dict[str, np.ndarray] = field(default_factory=dict)
    stride: int = 1
    meta: list[dict[str, Any]] = field(default_factory=list)
    wall_time: float = math.nan

    def __len__(self) -> int:
        return len(self.params)

    @property
    def t_end(self) -> np.ndarray:
        """Time of each run's last sample (B,)."""
        return self.last_t.copy()

    def trajectory(self, run: int) -> Trajectory:
        """Return run ``run`` as a :class:`~snake_pin.sim.Trajectory` (grid samples + last one).

        With ``stride = 1`` it holds exactly the samples :func:`~snake_pin.sim.simulate`
        records; otherwise every ``stride``-th one and the last.

        Parameters
        ----------
        run : int
            Index of the run, ``-B <= run < B``.

        Returns
        -------
        Trajectory
            The run's samples, robot, status, reason, signals and meta.

        Raises
        ------
        ParameterError
            If ``run`` is not an integer index of a run.
        """
        if isinstance(run, bool) or not isinstance(run, numbers.Integral) \
                or not -len(self) <= run < len(self):
            raise ParameterError(f"run must be an index in 0..{len(self) - 1}, "
                                 f"got {reprlib.repr(run)}")
        b = int(run) % len(self)
        rows = -(-int(self.last_step[b]) // self.stride)  # grid samples before the last
        signals = {}
        for name, series in self.signals.items():
            given = self.signal_runs.get(name)
            if given is not None and not given[b]:
                continue
            last = self.last_signals.get(name)
            tail = np.nan if last is None else last[b]
            signals[name] = np.r_[series[:rows, b], tail]
        return Trajectory(
            t=np.r_[self.t[:rows], self.last_t[b]],
            q=np.vstack((self.q[:rows, b], self.last_q[b])),
            dq=np.vstack((self.dq[:rows, b], self.last_dq[b])),
            tau=np.vstack((self.tau[:rows, b], self.last_tau[b])),
            params=self.params[b], signals=signals, status=self.status[b],
            reason=self.reason[b], meta=dict(self.meta[b]))

    def trajectories(self) -> list[Trajectory]:
        """Return every run as a :class:`~snake_pin.sim.Trajectory`, in order.

        Returns
        -------
        list of Trajectory
            ``[self.trajectory(b) for b in range(B)]``.
        """
        return [self.trajectory(b) for b in range(len(self))]


class _Plant:
    """The batch's plant: q'' of every run, friction as a generalised force.

    ``route="closed_form"``: H(q) q'' = E tau + Q - Coriolis with the closed-form terms
    (:class:`~snake_pin.control.batched.BatchTerms`) and one batched LU solve;
    ``route="aba"``: ``pin.abaInParallel`` on a ``pin.ModelPool`` with E tau + Q as the
    joint torque.
    """

    def __init__(self, robots: Sequence[SnakeParams], threads: int, route: str) -> None:
        first = robots[0]
        self.nq = first.n + 2
        self.threads = threads
        self.route = route
        self.pool = pin.ModelPool(paper_model(first), threads) if route == "aba" else None
        self.terms = BatchTerms(first)
        self._layout = layout_key(first)
        self.friction = FrictionCoefficients(robots)
        actuated = np.array([[0.0 if k in p.passive else 1.0 for k in range(1, first.n)]
                             for p in robots]).reshape(len(robots), first.n - 1)
        self.mask: np.ndarray | None = None if actuated.all() else actuated

    def terms_for(self, params: SnakeParams) -> BatchTerms:
        """The plant's model terms for a controller of the same layout (shared), else new."""
        return self.terms if layout_key(params) == self._layout else BatchTerms(params)

    def keep(self, rows: np.ndarray) -> None:
        self.friction = self.friction.take(rows)
        if self.mask is not None:
            self.mask = self.mask[rows]

    def acceleration(self, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """q'' (m, n + 2) at the states x (m, 2(n + 2)) under the torques tau (m, n - 1)."""
        nq = self.nq
        torque = tau if self.mask is None else tau * self.mask
        if self.pool is None:
            return self.terms.forward_dynamics(x, self.friction, torque)
        force = self.terms.friction(x, self.friction).copy()
        force[:, 3:] += torque
        out = np.empty((nq, len(x)), order="F")
        pin.abaInParallel(self.threads, self.pool, x[:, :nq].T, x[:, nq:].T, force.T, out)
        return out.T


def _robots(robots: object, size: int | None) -> list[SnakeParams]:
    """The runs' robots: one robot for all, or one per run, all of one layout."""
    if isinstance(robots, (SnakeParams, Snake)):
        robots = [robots] * (1 if size is None else size)
    if isinstance(robots, (str, bytes)) or not isinstance(robots, Sequence):
        raise ParameterError("robots must be a SnakeParams/Snake or a list of them, "
                             f"got {reprlib.repr(robots)}")
    out = []
    for b, robot in enumerate(robots):
        if isinstance(robot, Snake):
            robot = robot.params
        if not isinstance(robot, SnakeParams):
            raise ParameterError(f"robots[{b}] must be a SnakeParams or Snake, "
                                 f"got {reprlib.repr(robot)}")
        out.append(robot)
    if not out:
        raise ParameterError("a batch needs at least one run")
    layout = layout_key(out[0])
    for b, robot in enumerate(out):
        if layout_key(robot) != layout:
            differ = [name for name, a, c in zip(LAYOUT_FIELDS, layout, layout_key(robot),
                                                 strict=True) if a != c]
            raise ParameterError(f"robots[{b}] has another layout than robots[0] "
                                 f"({', '.join(differ)} differ); a batch shares "
                                 f"{', '.join(LAYOUT_FIELDS)}")
    return out


def _initial_states(x0s: object, size: int, width: int) -> np.ndarray:
    try:
        x = np.array(x0s, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(f"x0s must be {size} state vectors of {width} numbers") from exc
    if x.shape != (size, width):
        raise ConfigurationError(f"x0s must have shape ({size}, {width}) = one [q, dq] per "
                                 f"run, got {x.shape}")
    bad = np.flatnonzero(~np.isfinite(x).all(axis=1))
    if len(bad):
        raise ConfigurationError(f"x0s[{bad[0]}] has non-finite entries")
    return x


def _final_times(t_final: object, size: int) -> np.ndarray:
    if isinstance(t_final, numbers.Real) and not isinstance(t_final, bool):
        return np.full(size, _number(t_final, "t_final"))
    if isinstance(t_final, (str, bytes)) or not isinstance(t_final, (Sequence, np.ndarray)):
        raise ParameterError(f"t_final must be a number or {size} numbers, "
                             f"got {reprlib.repr(t_final)}")
    values = list(t_final)
    if len(values) != size:
        raise ParameterError(f"t_final must be a number or {size} numbers, got {len(values)}")
    return np.array([_number(v, f"t_final[{b}]") for b, v in enumerate(values)])


def _positive_int(value: object, name: str, upper: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) \
            or not 1 <= int(value) <= upper:
        raise ParameterError(f"{name} must be an integer in 1..{upper}, "
                             f"got {reprlib.repr(value)}")
    return int(value)


def simulate_batch(robots: SnakeParams | Snake | Sequence[SnakeParams | Snake],
                   controllers: Sequence[Controller | Callable[[np.ndarray, float], Any]],
                   x0s: np.ndarray | Sequence[np.ndarray],
                   t_final: float | Sequence[float], *, dt: float = 1e-3,
                   control_dt: float = 1e-3, stride: int = 1, max_speed: float = MAX_SPEED,
                   max_distance: float = MAX_DISTANCE, dynamics: str = "closed_form",
                   threads: int = 1, progress: bool = False,
                   meta: Mapping[str, Any] | Sequence[Mapping[str, Any] | None] | None = None
                   ) -> BatchResult:
    """Simulate B closed-loop runs of one robot layout in lockstep (module docstring).

    Parameters
    ----------
    robots : SnakeParams or Snake or sequence of them
        One robot for every run, or one per run (B). They must share
        :data:`~snake_pin.control.batched.LAYOUT_FIELDS`; friction and passive joints may
        differ.
    controllers : sequence of Controller or callable
        One controller per run (B), as :func:`~snake_pin.sim.simulate` takes them, each
        with its own state: :class:`~snake_pin.control.LyapunovController`,
        :class:`~snake_pin.control.QuasiStaticLyapunovController` and
        :class:`~snake_pin.control.PFLController` run vectorised (their model may be
        another robot, of any one layout per kind); anything else run by run.
    x0s : array_like, shape (B, 2(n + 2))
        Initial states ``x = [q, dq]``, one per run.
    t_final : float or sequence of float
        Final time of every run [s], or one per run (B).
    dt : float, optional
        Integration step [s] (RK4), as for :func:`~snake_pin.sim.simulate`.
    control_dt : float, optional
        Control period [s], a whole multiple of ``dt``.
    stride : int, optional
        Keep every ``stride``-th control step's sample (and each run's last one).
    max_speed, max_distance : float, optional
        Divergence limits on the velocity entries [m/s, rad/s] and on the head's distance
        [m], as for :func:`~snake_pin.sim.simulate` (``inf`` allowed).
    dynamics : {"closed_form", "aba"}, optional
        The forward-dynamics route (module docstring).
    threads : int, optional
        OpenMP threads of ``pin.abaInParallel`` (1..cpu count; see the module docstring).
    progress : bool, optional
        A tqdm bar over the control steps, on a terminal only.
    meta : Mapping or sequence of (Mapping or None) or None, optional
        Extra entries for every run's ``Trajectory.meta``: one mapping for all, or one
        (or None) per run.

    Returns
    -------
    BatchResult
        ``result.trajectory(b)`` is run b as :func:`~snake_pin.sim.simulate` returns it.

    Raises
    ------
    RunInterrupted
        On KeyboardInterrupt; ``.partial`` is the BatchResult so far, the runs still
        going marked "interrupted" at their last whole sample.
    ParameterError
        A bad argument (before anything runs): robots of different layouts, the wrong
        number of controllers, a shared controller object, bad steps, an unknown
        ``dynamics``, records beyond :data:`MAX_RECORD_BYTES`.
    ConfigurationError
        Initial states of the wrong shape or with non-finite entries.
    """
    size_hint = None if isinstance(controllers, (str, bytes)) or \
        not isinstance(controllers, Sequence) else len(controllers)
    params = _robots(robots, size_hint)
    size = len(params)
    if size > MAX_BATCH:
        raise ParameterError(f"a batch holds at most {MAX_BATCH} runs, got {size}")
    if size_hint != size:
        raise ParameterError(f"controllers must be a list of {size} controllers (one per run), "
                             f"got {reprlib.repr(controllers)}")
    n = params[0].n
    nq, n_tau = n + 2, n - 1
    ctrls = [_as_controller(c) for c in controllers]
    if len({id(c) for c in ctrls}) != size:
        raise ParameterError("each run needs its own controller object (they hold state)")
    x = _initial_states(x0s, size, 2 * nq)
    finals = _final_times(t_final, size)
    dt = _number(dt, "dt")
    control_dt = _number(control_dt, "control_dt")
    max_speed = _number(max_speed, "max_speed", allow_inf=True)
    max_distance = _number(max_distance, "max_distance", allow_inf=True)
    stride = _positive_int(stride, "stride", 10**9)
    if not isinstance(dynamics, str) or dynamics not in DYNAMICS:
        raise ParameterError(f"dynamics must be one of {', '.join(DYNAMICS)}, "
                             f"got {reprlib.repr(dynamics)}")
    threads = _positive_int(threads, "threads", os.cpu_count() or 1)
    if not isinstance(progress, (bool, np.bool_)):
        raise ParameterError(f"progress must be True or False, got {reprlib.repr(progress)}")
    metas = _metas(meta, size)
    substeps = 1
    steps = np.empty(size, dtype=int)
    for value in np.unique(finals):
        substeps, count = _check_steps(float(value), dt, control_dt)
        steps[finals == value] = count
    longest = int(steps.max())
    samples = longest // stride + 1
    _check_size(samples + 1, nq, n_tau, float(finals.max()))
    record_bytes = samples * size * (2 * nq + n_tau + 2) * 8
    if record_bytes > MAX_RECORD_BYTES:
        raise ParameterError(f"{size} runs of {longest} steps keep {record_bytes / 2**30:.1f} "
                             f"GiB of samples at stride {stride}, beyond "
                             f"{MAX_RECORD_BYTES / 2**30:.0f} GiB: raise the stride")
    plant = _Plant(params, threads, dynamics)
    controller = batch_controller(ctrls, n_tau, _torque, plant.terms_for)
    if dynamics == "closed_form":
        controller.mark_exact(np.array([_models_plant(c, p) for c, p in zip(ctrls, params,
                                                                            strict=True)]))
    run = _Run(params, ctrls, metas, x, steps, longest, stride, samples, nq, n_tau,
               dt=dt, control_dt=control_dt, substeps=substeps)
    return run.go(controller, plant, max_speed, max_distance, bool(progress))


def _models_plant(ctrl: Controller, plant: SnakeParams) -> bool:
    """Whether ``ctrl`` models ``plant`` exactly: same layout, friction and passive joints."""
    model = getattr(ctrl, "snake", None)
    params = getattr(model, "params", None)
    if not isinstance(params, SnakeParams):
        return False
    return (layout_key(params) == layout_key(plant) and params.passive == plant.passive
            and all(np.array_equal(params.per_link(key), plant.per_link(key))
                    for key in ("c_x", "c_y", "c_theta")))


def _metas(meta: object, size: int) -> list[dict[str, Any]]:
    if meta is None:
        return [{} for _ in range(size)]
    if isinstance(meta, Mapping):
        return [dict(meta) for _ in range(size)]
    if isinstance(meta, Sequence) and not isinstance(meta, (str, bytes)) and len(meta) == size \
            and all(m is None or isinstance(m, Mapping) for m in meta):
        return [dict(m or {}) for m in meta]
    raise ParameterError(f"meta must be a mapping or {size} mappings, got {reprlib.repr(meta)}")


class _Run:
    """The state of a batch while it runs: the runs still going and what is recorded."""

    def __init__(self, params: list[SnakeParams], ctrls: list[Controller],
                 metas: list[dict[str, Any]], x: np.ndarray, steps: np.ndarray, longest: int,
                 stride: int, samples: int, nq: int, n_tau: int, *, dt: float,
                 control_dt: float, substeps: int) -> None:
        size = len(params)
        self.params, self.x0 = params, x
        self.steps, self.longest, self.stride = steps, longest, stride
        self.nq, self.n_tau = nq, n_tau
        self.dt, self.control_dt, self.substeps = dt, control_dt, substeps
        self.metas = [{"controller": c.name, "dt": dt, "control_dt": control_dt,
                       "method": "rk4", **({"stride": stride} if stride > 1 else {}), **m}
                      for c, m in zip(ctrls, metas, strict=True)]
        # times as simulate computes them: t[k + 1] = k control_dt + control_dt
        times = np.r_[0.0, np.arange(longest) * control_dt + control_dt]
        self.times = times
        try:
            self.q = np.zeros((samples, size, nq))
            self.dq = np.zeros((samples, size, nq))
            self.tau = np.zeros((samples, size, n_tau))
        except MemoryError:
            raise ParameterError(f"not enough memory for {samples} samples of {size} runs: "
                                 "raise the stride") from None
        self.q[0], self.dq[0] = x[:, :nq], x[:, nq:]
        self.signals: dict[str, np.ndarray] = {}
        self.status = ["completed"] * size
        self.reason = [""] * size
        self.ended = np.zeros(size, dtype=bool)
        self.last_step = np.zeros(size, dtype=int)
        self.last_x = x.copy()
        self.last_tau = np.zeros((size, n_tau))
        self.last_signals: dict[str, np.ndarray] = {}
        self.signal_runs: dict[str, np.ndarray] = {}

    # ------------------------------------------------------------------ stopping
    def stop(self, ids: np.ndarray, rows: np.ndarray, status: str, reasons: Sequence[str],
             step: int, x: np.ndarray, tau: np.ndarray | None = None,
             signals: Mapping[str, np.ndarray] | None = None) -> None:
        """Runs ``ids[rows]`` end at control step ``step`` in state ``x[rows]``."""
        for row, reason in zip(rows, reasons, strict=True):
            b = int(ids[row])
            self.status[b], self.reason[b] = status, reason
            self.ended[b] = True
            self.last_step[b] = step
            self.last_x[b] = x[row]
            if tau is not None:
                self.last_tau[b] = tau[row]
            for name, values in (signals or {}).items():
                self._last_signal(name)[b] = values[row]

    def _last_signal(self, name: str) -> np.ndarray:
        series = self.last_signals.get(name)
        if series is None:
            series = self.last_signals[name] = np.full(len(self.params), np.nan)
        return series

    def _signal(self, name: str) -> np.ndarray:
        series = self.signals.get(name)
        if series is None:
            series = self.signals[name] = np.full(self.q.shape[:2], np.nan)
        return series

    def result(self, wall_time: float) -> BatchResult:
        nq = self.nq
        return BatchResult(
            params=self.params, t=self.times[::self.stride].copy(), q=self.q, dq=self.dq,
            tau=self.tau, signals=self.signals, status=self.status, reason=self.reason,
            last_step=self.last_step.copy(), last_t=self.times[self.last_step],
            last_q=self.last_x[:, :nq].copy(), last_dq=self.last_x[:, nq:].copy(),
            last_tau=self.last_tau, last_signals=self.last_signals,
            signal_runs=self.signal_runs, stride=self.stride,
            meta=self.metas, wall_time=wall_time)

    # ------------------------------------------------------------------ the loop
    def go(self, controller: BatchedController, plant: _Plant, max_speed: float,
           max_distance: float, progress: bool) -> BatchResult:
        start = time.perf_counter()
        nq, stride, h, control_dt = self.nq, self.stride, self.dt, self.control_dt
        ids = np.arange(len(self.params))
        x = self.x0.copy()
        good_ids, good_x, good_step = ids, x, 0
        bar = None
        try:
            bar = _progress(self.longest, progress, "batch")
            failed = controller.reset()
            if failed:
                rows = np.array(sorted(failed))
                self.stop(ids, rows, "failed", [_reason(0.0, failed[r]) for r in rows], 0, x)
                ids, x = self._compact(ids, x, rows, controller, plant)
            k = 0
            size = len(self.params)
            next_end = int(self.steps[ids].min()) if len(ids) else 0
            while len(ids):
                # the runs' rows in the recorded arrays (a slice while none has stopped)
                where: slice | np.ndarray = slice(None) if len(ids) == size else ids
                t = k * control_dt
                tau, failures = controller(x, t)
                finite = np.isfinite(tau).all(axis=1)
                if not finite.all():
                    for row in np.flatnonzero(~finite):
                        failures.setdefault(int(row), "controller returned a non-finite torque")
                signals = controller.signals()
                if failures:
                    rows = np.array(sorted(failures))
                    reasons = [_reason(t, failures[r]) for r in rows]
                    self.stop(ids, rows, "failed", reasons, k, x)
                    keep = np.setdiff1d(np.arange(len(ids)), rows)
                    tau = tau[keep]
                    signals = {name: values[keep] for name, values in signals.items()}
                    ids, x = self._compact(ids, x, rows, controller, plant)
                    where = ids
                    if not len(ids):
                        break
                for name, values in signals.items():
                    given = self.signal_runs.get(name)
                    if given is None:
                        given = self.signal_runs[name] = np.zeros(size, dtype=bool)
                    given[where] |= ~np.isnan(values)
                if k % stride == 0:
                    j = k // stride
                    self.tau[j, where] = tau
                    for name, values in signals.items():
                        self._signal(name)[j, where] = values
                with np.errstate(all="ignore"):
                    new = x
                    first = controller.predicted(x)
                    for _ in range(self.substeps):
                        new = _rk4_step(plant.acceleration, new, tau, h, nq, first)
                        first = None
                speed = np.abs(new[:, nq:]).max(axis=1)
                distance = np.abs(new[:, :2]).max(axis=1)
                fine = (speed <= max_speed) & (distance <= max_distance)
                if not fine.all():
                    bad = np.flatnonzero(~fine)
                    reasons = [f"diverged at t = {t + control_dt:.4f} s: "
                               f"{_divergence(new[r], nq, max_speed, max_distance)}"
                               for r in bad]
                    self.stop(ids, bad, "diverged", reasons, k, x, tau, signals)
                    keep = np.setdiff1d(np.arange(len(ids)), bad)
                    new = new[keep]
                    ids, x = self._compact(ids, x, bad, controller, plant)
                    where = ids
                k += 1
                if k % stride == 0:
                    j = k // stride
                    self.q[j, where] = new[:, :nq]
                    self.dq[j, where] = new[:, nq:]
                x = new
                good_ids, good_x, good_step = ids, x, k
                if k == next_end or k >= self.longest:
                    done = np.flatnonzero(self.steps[ids] == k)
                    if len(done):
                        self.stop(ids, done, "completed", [""] * len(done), k, x)
                        ids, x = self._compact(ids, x, done, controller, plant)
                    next_end = int(self.steps[ids].min()) if len(ids) else 0
                if bar is not None and k % 100 == 0:
                    bar.update(min(100, self.longest - bar.n))
            if bar is not None:
                bar.close()
            return self.result(time.perf_counter() - start)
        except KeyboardInterrupt:
            if bar is not None:
                bar.close()
            t_good = self.times[good_step]
            rows = np.flatnonzero(~self.ended[good_ids])
            self.stop(good_ids, rows, "interrupted",
                      [f"interrupted at t = {t_good:.4f} s"] * len(rows), good_step, good_x,
                      np.zeros((len(good_ids), self.n_tau)))
            partial = self.result(time.perf_counter() - start)
            raise RunInterrupted(f"batch interrupted at t = {t_good:.4f} s "
                                 f"({len(rows)} of {len(self.params)} runs still going)",
                                 partial=partial) from None

    @staticmethod
    def _compact(ids: np.ndarray, x: np.ndarray, rows: np.ndarray,
                 controller: BatchedController, plant: _Plant) -> tuple[np.ndarray, np.ndarray]:
        """Drop ``rows`` from the runs still going (ids, states, controller, plant)."""
        keep = np.setdiff1d(np.arange(len(ids)), rows)
        controller.keep(keep)
        plant.keep(keep)
        return ids[keep], x[keep]


def _reason(t: float, failure: BaseException | str) -> str:
    """A controller failure as :func:`~snake_pin.sim.simulate` words it."""
    if isinstance(failure, BaseException):
        return _failure(t, failure)
    return f"{failure} at t = {t:.4f} s"


def _rk4_step(accel: Callable[[np.ndarray, np.ndarray], np.ndarray], x: np.ndarray,
              tau: np.ndarray, h: float, nq: int, first: np.ndarray | None = None) -> np.ndarray:
    """One classical RK4 step for every row, with :func:`snake_pin.sim`'s arithmetic.

    ``first`` is q'' at x when already known (the controller's exact prediction).
    """
    d1 = np.concatenate((x[:, nq:], accel(x, tau) if first is None else first), axis=1)
    x2 = x + (0.5 * h) * d1
    d2 = np.concatenate((x2[:, nq:], accel(x2, tau)), axis=1)
    x3 = x + (0.5 * h) * d2
    d3 = np.concatenate((x3[:, nq:], accel(x3, tau)), axis=1)
    x4 = x + h * d3
    d4 = np.concatenate((x4[:, nq:], accel(x4, tau)), axis=1)
    return x + (h / 6.0) * (d1 + d4 + 2.0 * (d2 + d3))
