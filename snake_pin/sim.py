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

Speed: with the robot's own :class:`~snake_pin.model.Snake` the RK4 step runs on
preallocated buffers (:class:`_FastRK4`, :class:`~snake_pin.model.FastDynamics`), takes its
first stage from the controller when the controller computed it
(:meth:`~snake_pin.control.Controller.plant_acceleration`), and the loop holds BLAS to one
thread; the stages, weights and hold are those of :func:`_rk4_step` (the plain step, kept
for other plants), so results agree to rounding (``tests/test_speed_equivalence.py``).
"""

from __future__ import annotations

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
from .control.base import Controller, _sampler
from .exceptions import ConfigurationError, ParameterError, RunInterrupted, SnakePinError
from .model import Snake
from .params import SnakeParams
from .trajectory import MAX_ARRAY_BYTES, MAX_TOTAL_BYTES, Trajectory, _mib
from .trajectory import STATUSES as STATUSES  # re-exported: the run statuses

# Trajectory, STATUSES and the size bounds are defined (and documented) in
# snake_pin.trajectory; they stay importable from here.
__all__ = ["MAX_DISTANCE", "MAX_SPEED", "MAX_STEPS", "MAX_SUBSTEPS", "simulate"]

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
    try:
        ts = np.zeros(steps + 1)
        xs = np.zeros((steps + 1, 2 * nq))
        taus = np.zeros((steps + 1, n_tau))
    except MemoryError:
        raise ParameterError(f"not enough memory for {steps + 1} samples "
                             f"(t_final = {t_final:g} s)") from None
    accel = snake.state_derivative

    def rhs(state: np.ndarray, tau: np.ndarray) -> np.ndarray:
        return np.concatenate([state[nq:], accel(state, tau)])

    # The fast RK4 (same stages and hold, preallocated; see _FastRK4) needs the robot's own
    # dynamics: a plant that replaces state_derivative keeps the plain step.
    check_torque, torque_shape = _TorqueCheck(n_tau), (n_tau,)
    fast = None
    if method == "rk4" and isinstance(snake, Snake) and \
            type(snake).state_derivative is Snake.state_derivative:
        fast = _FastRK4(snake, x, dt, substeps, max_speed, max_distance)
    # the fast step checks whether the torque is finite, with the new state; a non-finite
    # one is then refused as if it had been checked first: no torque, no signals at t
    late_check = fast is not None
    xs[0] = x
    ts[1:] = np.arange(steps) * control_dt + control_dt  # sample k + 1 at t_k + control_dt
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
                          params=snake.params,
                          signals={k: v[:good].copy() for k, v in signals.items()},
                          status=run_status, reason=run_reason,
                          meta={"controller": ctrl.name, "dt": dt, "control_dt": control_dt,
                                "method": method, **(meta or {})})

    try:
        bar = _progress(steps, bool(progress), ctrl.name)
        try:
            ctrl.reset()
            ctrl.prepare(np.arange(steps) * control_dt)  # the loop's t = k * control_dt
        except Exception as exc:
            status, reason = "failed", _failure(0.0, exc)
        # the controller's methods, found once
        call = _sampler(ctrl, fast.tableau if fast is not None else None)
        signals_of, plant_acceleration = ctrl.signals, ctrl.plant_acceleration
        # one BLAS thread for the run's tiny matrices, entered once (not per step)
        with _thread_pools().limit(limits=1):
            for k in range(steps if status == "completed" else 0):
                t = k * control_dt
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
                    first = plant_acceleration(snake) if fast is not None else None
                except Exception as exc:
                    if tau is not None and not np.isfinite(tau).all():
                        status, reason = "failed", refuse(k, t, known)
                    else:
                        status, reason = "failed", _failure(t, exc)
                    break
                taus[k] = tau
                after = xs[k + 1]
                try:
                    if fast is not None:
                        problem = fast.step(tau, first, after)
                    else:
                        if method == "rk4":
                            for _ in range(substeps):
                                x = _rk4_step(accel, x, tau, dt, nq)
                        else:
                            x = _solve_ivp_step(rhs, x, tau, t, control_dt)
                        problem = _divergence(x, nq, max_speed, max_distance)
                except (SnakePinError, ArithmeticError, np.linalg.LinAlgError) as exc:
                    problem = f"the dynamics failed ({type(exc).__name__}: " \
                              f"{one_line(str(exc))})"
                if problem:
                    if late_check and not np.isfinite(tau).all():
                        status, reason = "failed", refuse(k, t, known)
                        break
                    status = "diverged"
                    reason = f"diverged at t = {t + control_dt:.4f} s: {problem}"
                    break
                if fast is not None:
                    x = after
                else:
                    after[...] = x
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


class _FastRK4:
    """RK4 with the torque held, as :func:`_rk4_step`, on preallocated buffers (hot path).

    The same stages and weights: with the step's state Z and the stage slopes d1..d4 as
    the rows of one array Y = [Z; d1; d2; d3; d4] (the run's own
    :class:`~snake_pin.model.RK4Tableau`), each stage state is one product of a
    coefficient row with Y (Z + h/2 d1, Z + h/2 d2, Z + h d3, and the new state
    Z + h/6 (d1 + 2 d2 + 2 d3 + d4)), written straight into the rows of the robot's
    :class:`~snake_pin.model.FastDynamics` (its layout [q, 0_w, q', 0_w]). The first stage
    reuses the controller's q'' when it offers it (``Controller.plant_acceleration``), and
    the divergence check is vectorised (the exact :func:`_divergence` words a fault).
    """

    def __init__(self, snake: Snake, x0: np.ndarray, h: float, substeps: int,
                 max_speed: float, max_distance: float) -> None:
        dynamics = snake.fast_dynamics
        nq, size = snake.nq, dynamics.size
        self._nq, self._substeps = nq, substeps
        self._max_speed, self._max_distance = max_speed, max_distance
        # the run's own tableau [Z; d1; d2; d3; d4] (a run nested in a controller's call
        # has its own), its stage evaluators and its calls at Z for the law
        self.tableau = dynamics.tableau()
        self._evaluators, self._torque, self._select = (self.tableau.evaluators,
                                                        dynamics.torque, dynamics.select)
        self._joint_torque = self._torque[3:]
        self._slopes = self.tableau.slopes
        self._state = self._slopes[0]
        self._state[self._select] = x0
        # the new state goes right before the torque: one pass checks both (see step)
        self._checked = dynamics.checked
        self._next = self._checked[:2 * size]
        # per stage: its coefficient row, its state (a row of the dynamics' buffer), and
        # where its slope goes in Y: q' (the stage state's velocity) and q''
        coefficients = [np.array(row) for row in (
            (0.0, 0.0, 0.0, 0.0, 0.0), (1.0, 0.5 * h, 0.0, 0.0, 0.0),
            (1.0, 0.0, 0.5 * h, 0.0, 0.0), (1.0, 0.0, 0.0, h, 0.0))]
        stages = [(i, coefficients[i], dynamics.states[i], self._slopes[i + 1, :nq],
                   self._slopes[i + 1, size:size + nq],
                   dynamics.states[i, size:size + nq]) for i in range(4)]
        self._first_stage, self._later_stages = stages[0][2:5], stages[1:]
        self._final = np.array((1.0, h / 6.0, h / 3.0, h / 3.0, h / 6.0))
        self._velocity = self._state[size:size + nq]
        self._plain = size == nq  # no wheel slots: the layout is [q, q'] itself
        # bounds of |z|, then of |E tau|: the largest float (false for inf and NaN)
        self._limits = np.full(len(self._checked), np.finfo(float).max)
        self._limits[2:size] = np.inf
        self._limits[:2] = max_distance
        self._limits[size:2 * size] = np.inf
        self._limits[size:size + nq] = max_speed
        self._magnitude = np.zeros(len(self._checked))
        self._within = np.zeros(len(self._checked), dtype=bool)
        self._all_within = np.ones(len(self._checked), dtype=bool).tobytes()
        # E tau: tau copied whole, then a passive joint's entry checked (a non-finite one
        # ends the step before it starts) and set to 0: no arithmetic, so no
        # floating-point flag whatever numpy's error settings
        self._passive = tuple(k - 1 for k in snake.params.passive)
        self.step = self._make_step()

    def _make_step(self) -> Callable[[np.ndarray, np.ndarray | None, np.ndarray], str]:
        """:attr:`step`, with everything it reads in its closure (cheaper than attributes),
        its three later stages unrolled and every output passed by position (numpy parses
        ``out=`` keywords for some 40 ns a call)."""
        passive, joint_torque, isfinite = self._passive, self._joint_torque, math.isfinite
        state = self._state
        evaluate0, evaluate1, evaluate2, evaluate3 = self._evaluators
        slopes = self._slopes.T  # Fortran-ordered: Y^T c by dgemv, in place (see _blas)
        row0, d0, a0 = self._first_stage
        (c1, r1, v1, a1, s1), (c2, r2, v2, a2, s2), (c3, r3, v3, a3, s3) = (
            stage[1:] for stage in self._later_stages)
        substeps, velocity, final, new = self._substeps, self._velocity, self._final, self._next
        plain, select, checked = self._plain, self._select, self._checked
        magnitude, limits, within, all_within = (self._magnitude, self._limits, self._within,
                                                 self._all_within)
        less_equal, absolute = np.less_equal, np.absolute
        nq, max_speed, max_distance = self._nq, self._max_speed, self._max_distance

        def step(tau: np.ndarray, first: np.ndarray | None, out: np.ndarray) -> str:
            """Advance one control period under ``tau``; write [q, q'] into ``out``.

            ``first`` is q'' at the current state under ``tau`` if known; ``tau`` need not
            be finite. Returns what is wrong with the new state or the torque ("" when
            both are within bounds, see :func:`_divergence`).
            """
            joint_torque[...] = tau  # view[...] = x: the cheapest copy
            for joint in passive:
                if not isfinite(joint_torque[joint]):
                    return "the torque is not finite"  # nothing stepped
                joint_torque[joint] = 0.0
            for sub in range(substeps):
                d0[...] = velocity  # each stage's q' in its slope first (see FastDynamics)
                if sub or first is None:
                    row0[...] = state
                    first = evaluate0()
                a0[...] = first
                gemv(1.0, slopes, c1, 0.0, r1)
                v1[...] = s1
                a1[...] = evaluate1()
                gemv(1.0, slopes, c2, 0.0, r2)
                v2[...] = s2
                a2[...] = evaluate2()
                gemv(1.0, slopes, c3, 0.0, r3)
                v3[...] = s3
                a3[...] = evaluate3()
                gemv(1.0, slopes, final, 0.0, new)
                state[...] = new
            if plain:
                out[...] = state
            else:
                state.take(select, None, out)
            # every |z| and |E tau| within its bound (NaN is not), in one pass over the new
            # state and the torque: compared as bytes, cheaper than .all()
            if less_equal(absolute(checked, magnitude), limits, within).tobytes() == all_within:
                return ""
            return _divergence(out, nq, max_speed, max_distance) or "the torque is not finite"

        return step


def _rk4_step(accel, x: np.ndarray, tau: np.ndarray, h: float,
              nq: int) -> np.ndarray:
    """One classical RK4 step of x' = [dq, accel(x, tau)] (the stage slopes d1..d4)."""
    d1 = np.concatenate((x[nq:], accel(x, tau)))
    x2 = x + (0.5 * h) * d1
    d2 = np.concatenate((x2[nq:], accel(x2, tau)))
    x3 = x + (0.5 * h) * d2
    d3 = np.concatenate((x3[nq:], accel(x3, tau)))
    x4 = x + h * d3
    d4 = np.concatenate((x4[nq:], accel(x4, tau)))
    return x + (h / 6.0) * (d1 + d4 + 2.0 * (d2 + d3))


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


def _solve_ivp_step(rhs, x: np.ndarray, tau: np.ndarray, t: float,
                    span: float) -> np.ndarray:
    from scipy.integrate import solve_ivp

    sol = solve_ivp(lambda _t, y: rhs(y, tau), (t, t + span), x, method="RK45",
                    rtol=1e-10, atol=1e-12)
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
