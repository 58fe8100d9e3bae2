"""Closed-loop simulation: fixed-step RK4 on ABA with zero-order-hold control.

:func:`simulate` runs a controller against a plant and returns a
:class:`~snake_pin.trajectory.Trajectory` (defined, with its file format, in
:mod:`snake_pin.trajectory`; also importable from here). Every run ends with a
:attr:`~snake_pin.trajectory.Trajectory.status`:

- ``"completed"``: it reached ``t_final``;
- ``"diverged"``: the state left its bounds (non-finite, speed or distance beyond a bound);
- ``"failed"``: the controller raised (any exception) or returned a torque of the wrong
  size, type or a non-finite one;
- ``"interrupted"``: a KeyboardInterrupt (Ctrl-C, or SIGTERM/SIGHUP converted by the
  command line) arrived; :func:`simulate` then raises
  :class:`~snake_pin.exceptions.RunInterrupted` carrying the partial trajectory.

In each case the samples up to the last good one are kept, and ``reason`` says when and
why. ``diverged`` is True for the two faults ("diverged", "failed").

The loop (zero-order hold, torque checks, signals, interrupts, divergence) is written
once, over a :class:`Plant`: one control period of a robot under a held torque.
:class:`ViscousPlant` is the viscous model by fixed-step RK4 on buffers made once (the
robot's ``calc_acceleration`` over a :class:`~snake_pin.model.SnakeData` of its own), its
first stage taken from the controller when the controller computed it
(:meth:`~snake_pin.control.Controller.plant_acceleration`), or by scipy's adaptive RK45
for cross-checks; the MuJoCo plant is :class:`snake_pin.engine.run.EnginePlant`.
"""

from __future__ import annotations

import abc
import functools
import math
import numbers
import re
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from threadpoolctl import ThreadpoolController

from ._blas import gemv
from ._validation import brief, finite_number, flag, one_line
from .control.base import Controller
from .exceptions import ConfigurationError, ParameterError, RunInterrupted, SnakePinError
from .model import Snake
from .params import SnakeParams
from .trajectory import MAX_ARRAY_BYTES, MAX_TOTAL_BYTES, Trajectory, _mib
from .trajectory import STATUSES as STATUSES  # re-exported: the run statuses

# Trajectory, STATUSES and the size bounds are defined (and documented) in
# snake_pin.trajectory; they stay importable from here.
__all__ = ["MAX_DISTANCE", "MAX_SPEED", "MAX_STEPS", "MAX_SUBSTEPS", "Plant", "ViscousPlant",
           "closed_loop", "simulate"]

#: Default divergence bounds: joint/base speed [m/s or rad/s] and distance [m].
MAX_SPEED = 1.0e3
MAX_DISTANCE = 1.0e3
#: Most control steps one run may take (t_final <= 1000 s at the default 1 kHz).
MAX_STEPS = 1_000_000
#: Most integration steps per control step (control_dt / dt).
MAX_SUBSTEPS = 1_000


# ----------------------------------------------------------------------- simulate
class _FunctionController(Controller):
    """A plain callable ``f(x, t) -> tau`` used as a controller (named after it)."""

    def __init__(self, function: Callable[[np.ndarray, float], Any]) -> None:
        self.function = function
        label = getattr(function, "__name__", None) or type(function).__name__
        self.name = re.sub(r"\W+", "", str(label)) or "function"

    def reset(self) -> None:
        reset = getattr(self.function, "reset", None)
        if callable(reset):
            reset()

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        return self.function(x, t)

    def signals(self) -> dict[str, float]:
        signals = getattr(self.function, "signals", None)
        return signals() if callable(signals) else {}


def _as_controller(controller: object) -> Controller:
    if isinstance(controller, Controller):
        return controller
    if callable(controller):
        return _FunctionController(controller)
    raise ParameterError("controller must be a Controller or a function f(x, t) -> tau, "
                         f"got {brief(controller)}")


def _number(value: object, name: str, *, allow_inf: bool = False) -> float:
    """``value`` as a positive float (finite unless ``allow_inf``) or ParameterError."""
    if allow_inf and isinstance(value, numbers.Real) and not isinstance(value, bool) \
            and value == math.inf:
        return math.inf
    return finite_number(value, name, positive=True)


def _check_plant(snake: object) -> tuple[int, int]:
    """(nq, n - 1) of the plant: a :class:`~snake_pin.model.Snake`, or an object with a
    Snake's ``nq``, ``n``, ``params`` and ``state_derivative``; else ParameterError."""
    if isinstance(snake, Snake):
        return snake.nq, snake.n - 1
    wanted = "snake must be a Snake (or a plant with its nq, n, params and state_derivative)"
    try:
        nq, n, params = snake.nq, snake.n, snake.params  # type: ignore[attr-defined]
        dynamics = snake.state_derivative  # type: ignore[attr-defined]
    except AttributeError:
        raise ParameterError(f"{wanted}, got {brief(snake)}") from None
    if not isinstance(params, SnakeParams) or not callable(dynamics) or \
            isinstance(n, bool) or not isinstance(n, numbers.Integral) or \
            isinstance(nq, bool) or not isinstance(nq, numbers.Integral) or \
            n != params.n or nq != n + 2:
        raise ParameterError(f"{wanted}, got {brief(snake)} whose nq, n or params disagree")
    return int(nq), int(n) - 1


def _state(x0: object, size: int) -> np.ndarray:
    """``x0`` as a finite float vector of ``size`` entries or ConfigurationError."""
    try:
        x = np.asarray(x0)
    except Exception as exc:
        raise ConfigurationError(f"x0 must be a vector of {size} numbers") from exc
    if x.dtype.kind not in "fiu" or x.dtype.names is not None:
        raise ConfigurationError(f"x0 must be a vector of {size} numbers, got dtype {x.dtype}")
    if x.shape != (size,):
        raise ConfigurationError(f"x0 must have shape ({size},) = [q, dq], got {x.shape}")
    x = x.astype(float)
    if not np.all(np.isfinite(x)):
        raise ConfigurationError("x0 has non-finite entries")
    return x


def _check_steps(t_final: float, dt: float, control_dt: float) -> tuple[int, int]:
    """(integration steps per control step, control steps), within the bounds."""
    ratio = control_dt / dt
    if ratio > MAX_SUBSTEPS + 0.5:
        raise ParameterError(f"control_dt / dt = {ratio:.4g} exceeds MAX_SUBSTEPS = "
                             f"{MAX_SUBSTEPS}")
    substeps = round(ratio)
    if substeps < 1 or abs(substeps * dt - control_dt) > 1e-9 * control_dt:
        raise ParameterError(f"control_dt ({control_dt}) must be a multiple of dt ({dt})")
    span = t_final / control_dt
    if span > MAX_STEPS + 1e-6:
        raise ParameterError(f"t_final = {t_final:g} s needs more than MAX_STEPS = {MAX_STEPS} "
                             f"control steps of {control_dt:g} s (t_final <= "
                             f"{MAX_STEPS * control_dt:g} s)")
    return substeps, max(1, math.ceil(span - 1e-9))


def _check_size(samples: int, nq: int, n_tau: int, t_final: float) -> None:
    """Refuse a run whose arrays would exceed what a trajectory file may hold."""
    largest = samples * nq * 8
    total = samples * (2 * nq + n_tau + 1) * 8
    if largest > MAX_ARRAY_BYTES or total > MAX_TOTAL_BYTES:
        raise ParameterError(f"t_final = {t_final:g} s needs {samples} samples of the "
                             f"{nq - 2}-link robot ({_mib(total)}), beyond the "
                             f"{_mib(MAX_ARRAY_BYTES)} per array / {_mib(MAX_TOTAL_BYTES)} "
                             "a trajectory may hold")


def _torque(raw: object, size: int) -> tuple[np.ndarray | None, str]:
    """The controller's output as ``size`` finite floats, or None and what is wrong."""
    tau = raw if type(raw) is np.ndarray else np.asarray(raw)
    if tau.dtype.kind not in "fiu" or tau.dtype.names is not None:
        return None, f"controller returned a torque of dtype {tau.dtype}, not numbers"
    if tau.shape != (size,):
        if tau.ndim == 0 and size == 1:
            tau = tau.reshape(1)
        elif tau.ndim <= 1:
            return None, (f"controller returned {tau.size} torque{'' if tau.size == 1 else 's'}"
                          f", expected {size}")
        else:
            return None, f"controller returned torques of shape {tau.shape}, expected {size}"
    if tau.dtype != np.float64:
        tau = tau.astype(float)
    if not np.isfinite(tau).all():
        return None, "controller returned a non-finite torque"
    return tau, ""


class _TorqueCheck:
    """:func:`_torque` for one run, with a cheap path for n - 1 finite float64 values."""

    def __init__(self, size: int) -> None:
        self._size, self._shape = size, (size,)
        self._finite = np.zeros(size, dtype=bool)
        self._all_finite = np.ones(size, dtype=bool).tobytes()

    def __call__(self, raw: object) -> tuple[np.ndarray | None, str]:
        if type(raw) is np.ndarray and raw.dtype is _FLOAT and raw.shape == self._shape and \
                np.isfinite(raw, self._finite).tobytes() == self._all_finite:
            return raw, ""
        return _torque(raw, self._size)


_FLOAT = np.dtype(np.float64)


def _failure(t: float, exc: BaseException) -> str:
    detail = one_line(str(exc))
    return f"controller failed at t = {t:.4f} s: {type(exc).__name__}" + \
        (f": {detail}" if detail else "")


def simulate(snake: Snake, controller: Controller | Callable[[np.ndarray, float], Any],
             x0: np.ndarray, t_final: float, *, dt: float = 1e-3, control_dt: float = 1e-3,
             method: str = "rk4", max_speed: float = MAX_SPEED,
             max_distance: float = MAX_DISTANCE, progress: bool = False,
             meta: Mapping[str, Any] | None = None) -> Trajectory:
    """Simulate the closed loop from state ``x0 = [q0, dq0]`` up to ``t_final``.

    The controller is sampled every ``control_dt`` and its torque held in between (zero-
    order hold, as on a real robot). ``method="rk4"`` integrates with fixed RK4 steps of
    ``dt``; ``method="solve_ivp"`` uses scipy's adaptive RK45 over each control period
    (tight tolerances; slower, for cross-checks).

    Parameters
    ----------
    snake : Snake
        The plant (any object with a Snake's ``nq``, ``n``, ``params`` and
        ``state_derivative``).
    controller
        A :class:`~snake_pin.control.Controller`, or any function ``f(x, t) -> tau``
        (wrapped in an adapter named after the function). It must return exactly
        n - 1 finite torques; any exception it raises ends the run as "failed".
    x0 : numpy.ndarray
        Initial state ``x = [q, dq]``, length 2(n + 2), finite.
    t_final, dt, control_dt
        Times [s]: positive, finite; ``control_dt`` a multiple of ``dt`` (at most
        :data:`MAX_SUBSTEPS` times), at most :data:`MAX_STEPS` control steps, and arrays
        within :data:`~snake_pin.trajectory.MAX_ARRAY_BYTES`/
        :data:`~snake_pin.trajectory.MAX_TOTAL_BYTES`.
    method : {"rk4", "solve_ivp"}, optional
        The integrator (see above).
    max_speed, max_distance
        Divergence bounds [m/s, m] (positive; ``math.inf`` for none).
    progress
        Show a tqdm bar, on a terminal only (never drawn into a non-TTY stderr).
    meta : mapping, optional
        Extra run settings merged into the trajectory's ``meta``.

    Returns
    -------
    Trajectory
        Samples at t = 0, control_dt, 2 control_dt, ... up to t_final, or up to the last
        good sample of a diverged or failed run (see the module docstring).

    Raises
    ------
    RunInterrupted
        On KeyboardInterrupt during the run; ``.partial`` is the trajectory of every
        completed sample, with status "interrupted".
    ParameterError, ConfigurationError
        Bad arguments (before anything runs).
    """
    nq, n_tau = _check_plant(snake)
    ctrl = _as_controller(controller)
    x = _state(x0, 2 * nq)
    t_final = _number(t_final, "t_final")
    dt = _number(dt, "dt")
    control_dt = _number(control_dt, "control_dt")
    max_speed = _number(max_speed, "max_speed", allow_inf=True)
    max_distance = _number(max_distance, "max_distance", allow_inf=True)
    if not isinstance(method, str) or method not in ("rk4", "solve_ivp"):
        raise ParameterError(f"method must be 'rk4' or 'solve_ivp', got {brief(method)}")
    progress = flag(progress, "progress")
    if meta is not None and not isinstance(meta, Mapping):
        raise ParameterError(f"meta must be a mapping, got {brief(meta)}")
    substeps, steps = _check_steps(t_final, dt, control_dt)
    _check_size(steps + 1, nq, n_tau, t_final)
    plant = ViscousPlant(snake, dt, substeps, control_dt=control_dt, method=method,
                         max_speed=max_speed, max_distance=max_distance)
    return closed_loop(plant, ctrl, x, steps, progress=progress,
                       meta={"controller": ctrl.name, "dt": dt, "control_dt": control_dt,
                             "method": method, **(meta or {})})


def closed_loop(plant: Plant, controller: Controller, x0: np.ndarray, steps: int, *,
                progress: bool = False, meta: Mapping[str, Any] | None = None,
                label: str | None = None, record_signals: bool = True) -> Trajectory:
    """The closed loop: ``steps`` control periods of ``plant`` under ``controller``.

    The controller is called at each sampling instant (:meth:`Plant.times`) on the
    plant's sample and its torque held over the period (zero-order hold). The run ends
    as the module docstring says; :func:`simulate` and
    :func:`snake_pin.engine.run.run_engine` are this loop over their plants.

    Parameters
    ----------
    plant : Plant
        The robot being controlled.
    controller : Controller
        The law (its torques checked at each call).
    x0 : numpy.ndarray
        The initial state, as :meth:`Plant.reset` takes it.
    steps : int
        Control periods.
    progress : bool, optional
        Show a tqdm bar on a terminal.
    meta : mapping, optional
        The trajectory's ``meta``.
    label : str, optional
        The progress bar's label (default: the controller's name).
    record_signals : bool, optional
        Whether to record the controller's :meth:`~snake_pin.control.Controller.signals`.

    Returns
    -------
    Trajectory
        The samples up to the last good one, with the run's status and reason.

    Raises
    ------
    RunInterrupted
        On KeyboardInterrupt during the run; ``.partial`` is the trajectory of every
        completed sample, with status "interrupted".
    ParameterError
        Not enough memory for the samples.
    """
    ctrl, nq, n_tau = controller, plant.nq, plant.params.n - 1
    try:
        xs = np.zeros((steps + 1, 2 * nq))
        taus = np.zeros((steps + 1, n_tau))
    except MemoryError:
        raise ParameterError(f"not enough memory for {steps + 1} samples") from None
    times, ts = plant.times(steps)
    plant.reset(x0, xs[0])
    x = xs[0]
    check_torque, torque_shape = _TorqueCheck(n_tau), (n_tau,)
    # a plant that checks whether the torque is finite (with the new state) refuses a
    # non-finite one as if it had been checked first: no torque, no signals at t
    late_check = plant.checks_torque
    signals: dict[str, np.ndarray] = {}
    status, reason = "completed", ""
    good = 1  # samples 0 .. good - 1 are recorded whole; updated last, after each sample
    bar = None

    def refuse(k: int, t: float, known: int) -> str:
        """The reason for a non-finite torque at sample k, its torque and signals undone
        (``known``: how many signals there were before the call)."""
        taus[k] = 0.0
        for name in list(signals)[known:]:
            del signals[name]
        for series in signals.values():
            series[k] = np.nan
        return f"controller returned a non-finite torque at t = {t:.4f} s"

    def collect(run_status: str, run_reason: str) -> Trajectory:
        return Trajectory(t=ts[:good].copy(), q=xs[:good, :nq].copy(),
                          dq=xs[:good, nq:].copy(), tau=taus[:good].copy(),
                          params=plant.params,
                          signals={k: v[:good].copy() for k, v in signals.items()},
                          status=run_status, reason=run_reason, meta=dict(meta or {}))

    try:
        bar = _progress(steps, bool(progress), label or ctrl.name)
        try:
            ctrl.reset()
            ctrl.prepare(times)
        except Exception as exc:
            status, reason = "failed", _failure(0.0, exc)
        # the controller's methods, found once
        call = ctrl.__call__
        signals_of = ctrl.signals if record_signals else dict
        plant_acceleration = ctrl.plant_acceleration if plant.takes_first_stage else None
        # one BLAS thread for the run's tiny matrices, entered once (not per step)
        with _thread_pools().limit(limits=1):
            for k, t in enumerate(times.tolist() if status == "completed" else ()):
                tau, known = None, len(signals)
                try:
                    raw = call(x, t)
                    if late_check and type(raw) is np.ndarray and raw.dtype is _FLOAT \
                            and raw.shape == torque_shape:
                        tau = raw  # whether it is finite: checked with the new state
                    else:
                        checked, problem = check_torque(raw)
                        if checked is None:
                            status, reason = "failed", f"{problem} at t = {t:.4f} s"
                            break
                        tau = checked
                    for name, value in signals_of().items():
                        series = signals.get(name)
                        if series is None:
                            series = signals[name] = np.full(steps + 1, np.nan)
                        series[k] = value
                    first = plant_acceleration(plant.snake) if plant_acceleration else None
                except Exception as exc:
                    if tau is not None and not np.isfinite(tau).all():
                        status, reason = "failed", refuse(k, t, known)
                    else:
                        status, reason = "failed", _failure(t, exc)
                    break
                taus[k] = tau
                after = xs[k + 1]
                try:
                    problem = plant.step(tau, first, after, t)
                except (SnakePinError, ArithmeticError, np.linalg.LinAlgError) as exc:
                    problem = f"the dynamics failed ({type(exc).__name__}: " \
                              f"{one_line(str(exc))})"
                if problem:
                    if late_check and not np.isfinite(tau).all():
                        status, reason = "failed", refuse(k, t, known)
                        break
                    status = "diverged"
                    reason = f"diverged at t = {ts[k + 1]:.4f} s: {problem}"
                    break
                x = after
                good = k + 2
                if bar is not None and k % 100 == 0:
                    bar.update(min(100, steps - bar.n))
        if bar is not None:
            bar.close()
        # Samples 0..good-1 are good. tau[good-1] is the torque held after the last one:
        # on divergence the one applied when the state blew up (kept as evidence); at the
        # end of a completed run, or when the controller failed, none was applied: zero.
        return collect(status, reason)
    except KeyboardInterrupt:
        if bar is not None:
            bar.close()
        # Samples 0 .. good - 1 are whole; the torque after the last one was not (fully)
        # applied, so it is recorded as zero, as at the end of a completed run.
        taus[good - 1] = 0.0
        partial = collect("interrupted", f"interrupted at t = {ts[good - 1]:.4f} s")
        raise RunInterrupted(partial.reason, partial=partial) from None


class Plant(abc.ABC):
    """What :func:`simulate` steps: one control period of a robot under a held torque.

    Attributes
    ----------
    nq, params
        n + 2, and the robot's parameters (the trajectory's).
    snake
        The model the plant integrates, for the laws'
        :meth:`~snake_pin.control.Controller.plant_acceleration` (when
        :attr:`takes_first_stage`).
    checks_torque
        Whether :meth:`step` itself finds a non-finite torque (with the new state), so
        that the loop need not check it first.
    takes_first_stage
        Whether :meth:`step` takes the controller's q'' as its first stage
        (:meth:`~snake_pin.control.Controller.plant_acceleration` of the robot).
    """

    nq: int
    params: SnakeParams
    snake: Any = None
    checks_torque: bool = False
    takes_first_stage: bool = False

    @abc.abstractmethod
    def times(self, steps: int) -> tuple[np.ndarray, np.ndarray]:
        """The run's instants: of the controller's calls, and of the samples.

        Parameters
        ----------
        steps : int
            Control periods.

        Returns
        -------
        tuple of numpy.ndarray
            The ``steps`` calls' times and the ``steps + 1`` samples' times [s].
        """

    @abc.abstractmethod
    def reset(self, x0: np.ndarray, out: np.ndarray) -> None:
        """Start a run from ``x0`` and write the first sample ``[q, q']`` into ``out``.

        Parameters
        ----------
        x0 : numpy.ndarray
            The initial state, length 2(n + 2).
        out : numpy.ndarray
            Where the first sample goes.
        """

    @abc.abstractmethod
    def step(self, tau: np.ndarray, first: np.ndarray | None, out: np.ndarray,
             t: float) -> str:
        """Advance one control period from time ``t`` under ``tau``, held.

        Parameters
        ----------
        tau : numpy.ndarray
            Joint torques (n - 1); finite unless :attr:`checks_torque`.
        first : numpy.ndarray or None
            q'' at the current state under ``tau``, if known (see
            :attr:`takes_first_stage`).
        out : numpy.ndarray
            Where the new state ``[q, q']`` goes.
        t : float
            The time of the current state [s].

        Returns
        -------
        str
            What is wrong with the new state or the torque ("" when nothing).
        """


class ViscousPlant(Plant):
    """The viscous model of eq. (20), by fixed-step RK4 with the torque held (or RK45).

    RK4's stage states and slopes are the rows of buffers made once: with the step's state
    Z and its slopes d1..d4 as the rows of Y = [Z; d1; d2; d3; d4], each stage state is one
    product of a coefficient row with Y (Z + h/2 d1, Z + h/2 d2, Z + h d3, and the new
    state Z + h/6 (d1 + 2 d2 + 2 d3 + d4)). The accelerations come from the robot's
    :meth:`~snake_pin.model.Snake.calc_acceleration` on a data object of the plant's own,
    or from ``state_derivative`` for a plant that replaces it (any object with a Snake's
    ``nq``, ``n``, ``params`` and ``state_derivative``).

    Parameters
    ----------
    snake : Snake
        The robot (or a stand-in with its ``state_derivative``).
    dt : float
        RK4's step [s].
    substeps : int
        RK4 steps per control period.
    control_dt : float, optional
        The control period [s] (default ``dt * substeps``).
    method : {"rk4", "solve_ivp"}, optional
        Fixed-step RK4, or scipy's adaptive RK45 over each period (tight tolerances).
    max_speed, max_distance : float, optional
        Divergence bounds [m/s, m] (``math.inf``: none).

    Raises
    ------
    ParameterError
        ``snake`` is not a Snake or a stand-in with its nq, n, params and state_derivative.
    """

    def __init__(self, snake: Snake, dt: float, substeps: int, *, control_dt: float | None = None,
                 method: str = "rk4", max_speed: float = MAX_SPEED,
                 max_distance: float = MAX_DISTANCE) -> None:
        nq = _check_plant(snake)[0]
        self.snake, self.nq, self.params, self._method = snake, nq, snake.params, method
        self._control_dt = dt * substeps if control_dt is None else control_dt
        self._dt, self._substeps = dt, substeps
        self._max_speed, self._max_distance = max_speed, max_distance
        self.checks_torque = method == "rk4"
        self._own = isinstance(snake, Snake) and \
            type(snake).state_derivative is Snake.state_derivative
        self.takes_first_stage = self._own and method == "rk4"
        self._slopes = np.zeros((5, 2 * nq))  # Y = [Z; d1; d2; d3; d4]
        self._state = self._slopes[0]
        stages = np.zeros((4, 2 * nq))
        stages[0] = np.nan  # stage 1's state is Z itself
        # the new state right before E tau: one pass checks both (see step)
        self._checked = np.zeros(3 * nq)
        self._new, torque = self._checked[:2 * nq], self._checked[2 * nq:]
        self._joint_torque = torque[3:]
        self._passive = tuple(k - 1 for k in snake.params.passive)
        rows = [self._state, *stages[1:]]
        if self._own:
            data = snake.create_data()
            self._evaluate: Callable[..., np.ndarray] = snake.calc_acceleration
            self._arguments: list[tuple[Any, ...]] = [(data, row[:nq], row[nq:], torque)
                                                      for row in rows]
        else:
            self._evaluate = snake.state_derivative
            self._arguments = [(row, self._joint_torque) for row in rows]
        h, columns = dt, self._slopes.T  # Y^T: Fortran-ordered
        coefficients = [np.array(row) for row in (
            (1.0, 0.5 * h, 0.0, 0.0, 0.0), (1.0, 0.0, 0.5 * h, 0.0, 0.0),
            (1.0, 0.0, 0.0, h, 0.0), (1.0, h / 6.0, h / 3.0, h / 3.0, h / 6.0))]
        # per later stage: its state's product with Y, and where its slope goes in Y; then
        # the new state's product
        self._stages = [(gemv(1.0, columns, coefficients[i - 1], 0.0, rows[i]),
                         self._slopes[i + 1, :nq], self._slopes[i + 1, nq:], rows[i][nq:])
                        for i in (1, 2, 3)]
        self._final = gemv(1.0, columns, coefficients[3], 0.0, self._new)
        # bounds of |z|, then of |E tau|: the largest float (false for inf and NaN)
        self._limits = np.full(3 * nq, np.finfo(float).max)
        self._limits[:2] = max_distance
        self._limits[2:nq] = np.inf
        self._limits[nq:2 * nq] = max_speed
        self._magnitude = np.zeros(3 * nq)
        self._within = np.zeros(3 * nq, dtype=bool)
        self._all_within = np.ones(3 * nq, dtype=bool).tobytes()

    def times(self, steps: int) -> tuple[np.ndarray, np.ndarray]:
        """Calls at k control_dt; sample k + 1 at t_k + control_dt.

        Parameters
        ----------
        steps : int
            Control periods.

        Returns
        -------
        tuple of numpy.ndarray
            The calls' and the samples' times [s].
        """
        calls = np.arange(steps) * self._control_dt
        return calls, np.r_[0.0, calls + self._control_dt]

    def reset(self, x0: np.ndarray, out: np.ndarray) -> None:
        """Start a run from the state ``x0``, which is the first sample.

        Parameters
        ----------
        x0 : numpy.ndarray
            The initial state ``[q, q']``, length 2(n + 2).
        out : numpy.ndarray
            Where the first sample goes.
        """
        self._state[...] = x0
        out[...] = x0

    def step(self, tau: np.ndarray, first: np.ndarray | None, out: np.ndarray,
             t: float) -> str:
        """Advance one control period from time ``t`` under ``tau``, held.

        Parameters
        ----------
        tau : numpy.ndarray
            Joint torques (n - 1), finite or not (a non-finite one is reported).
        first : numpy.ndarray or None
            q'' at the current state under ``tau``, if known.
        out : numpy.ndarray
            Where the new state ``[q, q']`` goes.
        t : float
            The time of the current state [s].

        Returns
        -------
        str
            What is wrong with the new state or the torque ("" when nothing).
        """
        joint_torque = self._joint_torque
        joint_torque[...] = tau
        # E tau: a passive joint's entry checked (a non-finite one ends the step before it
        # starts) and set to 0: no arithmetic, so no floating-point flag
        for joint in self._passive:
            if not math.isfinite(joint_torque[joint]):
                return "the torque is not finite"  # nothing stepped
            joint_torque[joint] = 0.0
        state, nq = self._state, self.nq
        if self._method != "rk4":
            out[...] = _solve_ivp_step(self._rhs, state, t, self._control_dt)
            state[...] = out
            return _divergence(out, nq, self._max_speed, self._max_distance)
        evaluate, new, final, slopes = self._evaluate, self._new, self._final, self._slopes
        d0, a0, velocity = slopes[1, :nq], slopes[1, nq:], state[nq:]
        (stage1, v1, a1, s1), (stage2, v2, a2, s2), (stage3, v3, a3, s3) = self._stages
        arguments0, arguments1, arguments2, arguments3 = self._arguments
        for sub in range(self._substeps):
            d0[...] = velocity
            a0[...] = evaluate(*arguments0) if sub or first is None else first
            stage1()
            v1[...] = s1
            a1[...] = evaluate(*arguments1)
            stage2()
            v2[...] = s2
            a2[...] = evaluate(*arguments2)
            stage3()
            v3[...] = s3
            a3[...] = evaluate(*arguments3)
            final()
            state[...] = new
        out[...] = new
        # every |z| and |E tau| within its bound (NaN is not), in one pass over the new
        # state and the torque: compared as bytes, cheaper than .all()
        if np.less_equal(np.absolute(self._checked, self._magnitude), self._limits,
                         self._within).tobytes() == self._all_within:
            return ""
        return _divergence(out, nq, self._max_speed, self._max_distance) or \
            "the torque is not finite"

    def _rhs(self, _t: float, x: np.ndarray) -> np.ndarray:
        """[q', q''] under the held torque, for scipy's solver."""
        nq = self.nq
        return np.concatenate((x[nq:], self.snake.state_derivative(x, self._joint_torque)))


def _divergence(x: np.ndarray, nq: int, max_speed: float, max_distance: float) -> str:
    speed = np.abs(x[nq:]).max()  # NaN propagates and fails both comparisons below
    distance = np.abs(x[:2]).max()
    if speed <= max_speed and distance <= max_distance:
        return ""
    if not np.all(np.isfinite(x)):
        return "state is not finite"
    if speed > max_speed:
        return f"speed {speed:.3g} exceeds {max_speed:g}"
    return f"head is {distance:.3g} m away, beyond {max_distance:g} m"


def _solve_ivp_step(rhs: Callable[[float, np.ndarray], np.ndarray], x: np.ndarray,
                    t: float, span: float) -> np.ndarray:
    """The state after ``span`` seconds by scipy's RK45 (NaN if it fails)."""
    from scipy.integrate import solve_ivp

    sol = solve_ivp(rhs, (t, t + span), x, method="RK45", rtol=1e-10, atol=1e-12)
    return sol.y[:, -1] if sol.success else np.full_like(x, np.nan)


@functools.cache
def _thread_pools() -> ThreadpoolController:
    """The process's BLAS/OpenMP pools, found once: ``threadpool_limits`` looks them up
    again on every entry (0.75 ms), a kept controller's ``limit`` takes 10 us."""
    return ThreadpoolController()


def _progress(total: int, enabled: bool, label: str):
    """A tqdm bar when ``enabled`` and stderr is a terminal (``disable=None``), else None."""
    if not enabled:
        return None
    from tqdm import tqdm

    bar = tqdm(total=total, desc=f"simulate {label}", unit="step", leave=False, disable=None)
    return None if bar.disable else bar
