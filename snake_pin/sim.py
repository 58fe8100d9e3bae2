"""Simulation of the viscous model: :func:`simulate` runs a controller against
:class:`ViscousPlant` (fixed-step RK4 on ABA) in the closed loop of :mod:`snake_pin.loop`.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ._blas import gemv
from ._validation import brief, finite_number, flag, mebibytes, vector
from .control.base import Controller
from .exceptions import ParameterError
from .loop import MAX_STEPS, Plant, closed_loop  # re-exported: the loop simulate runs
from .model import Snake
from .params import SnakeParams
from .trajectory import MAX_ARRAY_BYTES, MAX_TOTAL_BYTES, Trajectory
from .trajectory import STATUSES as STATUSES  # re-exported: the run statuses

__all__ = ["MAX_DISTANCE", "MAX_SPEED", "MAX_STEPS", "MAX_SUBSTEPS", "Plant", "ViscousPlant",
           "closed_loop", "simulate"]

#: Default divergence bounds: joint/base speed [m/s or rad/s] and distance [m].
MAX_SPEED = 1.0e3
MAX_DISTANCE = 1.0e3
#: Most integration steps per control step (control_dt / dt).
MAX_SUBSTEPS = 1_000

# read once: numpy's module __getattr__ keeps Python from caching ``np.<name>`` lookups
_ABSOLUTE, _LESS_EQUAL = np.absolute, np.less_equal


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
    """``controller``, a plain function wrapped (ParameterError for anything else)."""
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
    """(nq, n - 1) of a Snake or a stand-in with its nq, n, params, state_derivative."""
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


def check_steps(t_final: float, dt: float, control_dt: float) -> tuple[int, int]:
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


def check_size(samples: int, nq: int, n_tau: int, t_final: float) -> None:
    """Refuse a run whose arrays would exceed what a trajectory file may hold."""
    largest = samples * nq * 8
    total = samples * (2 * nq + n_tau + 1) * 8
    if largest > MAX_ARRAY_BYTES or total > MAX_TOTAL_BYTES:
        raise ParameterError(f"t_final = {t_final:g} s needs {samples} samples of the "
                             f"{nq - 2}-link robot ({mebibytes(total)}), beyond the "
                             f"{mebibytes(MAX_ARRAY_BYTES)} per array / "
                             f"{mebibytes(MAX_TOTAL_BYTES)} a trajectory may hold")


def simulate(snake: Snake, controller: Controller | Callable[[np.ndarray, float], Any],
             x0: np.ndarray, t_final: float, *, dt: float = 1e-3, control_dt: float = 1e-3,
             method: str = "rk4", max_speed: float = MAX_SPEED,
             max_distance: float = MAX_DISTANCE, progress: bool = False,
             meta: Mapping[str, Any] | None = None) -> Trajectory:
    """Simulate the closed loop from state ``x0 = [q0, dq0]`` up to ``t_final``.

    The controller is sampled every ``control_dt``, its torque held in between.

    Parameters
    ----------
    snake : Snake
        The plant (or any object with a Snake's ``nq``, ``n``, ``params``, ``state_derivative``).
    controller
        A :class:`~snake_pin.control.Controller` or a function ``f(x, t) -> tau``.
    x0 : numpy.ndarray
        Initial state ``x = [q, dq]``, length 2(n + 2), finite.
    t_final, dt, control_dt
        Times [s]: ``control_dt`` a multiple of ``dt``, at most :data:`MAX_STEPS` steps.
    method : {"rk4", "solve_ivp"}, optional
        Fixed RK4 steps of ``dt``, or scipy's adaptive RK45 per period (for cross-checks).
    max_speed, max_distance
        Divergence bounds [m/s, m] (``math.inf`` for none).
    progress, meta : optional
        Show a tqdm bar on a terminal; extra settings merged into the trajectory's ``meta``.

    Returns
    -------
    Trajectory
        Samples every ``control_dt`` up to t_final, or up to the last good one.

    Raises
    ------
    RunInterrupted
        On KeyboardInterrupt; ``.partial`` holds every completed sample.
    ParameterError, ConfigurationError
        Bad arguments (before anything runs).
    """
    nq, n_tau = _check_plant(snake)
    ctrl = _as_controller(controller)
    x = vector(x0, "x0", size=2 * nq)
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
    substeps, steps = check_steps(t_final, dt, control_dt)
    check_size(steps + 1, nq, n_tau, t_final)
    plant = ViscousPlant(snake, dt, substeps, control_dt=control_dt, method=method,
                         max_speed=max_speed, max_distance=max_distance)
    return closed_loop(plant, ctrl, x, steps, progress=progress,
                       meta={"controller": ctrl.name, "dt": dt, "control_dt": control_dt,
                             "method": method, **(meta or {})})


class ViscousPlant(Plant):
    """The viscous model of eq. (20), by fixed-step RK4 with the torque held (or RK45).

    Parameters
    ----------
    snake : Snake
        The robot (or a stand-in with its ``state_derivative``).
    dt, substeps : float, int
        RK4's step [s], and its steps per control period.
    control_dt : float, optional
        The control period [s] (default ``dt * substeps``).
    method : {"rk4", "solve_ivp"}, optional
        As in :func:`simulate`.
    max_speed, max_distance : float, optional
        Divergence bounds [m/s, m] (``math.inf``: none).

    Raises
    ------
    ParameterError
        ``snake`` is not a Snake or a stand-in.
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
        slopes = np.zeros((5, 2 * nq))  # Y = [Z; d1; d2; d3; d4]
        self._state = state = slopes[0]
        stages = np.zeros((4, 2 * nq))
        stages[0] = np.nan  # stage 1's state is Z itself
        # the new state right before E tau: one pass checks both (see step)
        checked = np.zeros(3 * nq)
        new, torque = checked[:2 * nq], checked[2 * nq:]
        self._joint_torque = torque[3:]
        self._passive = tuple(k - 1 for k in snake.params.passive)
        rows = [state, *stages[1:]]
        evaluate: Callable[..., np.ndarray]
        if self._own:
            data = snake.create_data()
            evaluate = snake.calc_acceleration
            arguments: list[tuple[Any, ...]] = [(data, row[:nq], row[nq:], torque)
                                                for row in rows]
        else:
            evaluate = snake.state_derivative
            arguments = [(row, self._joint_torque) for row in rows]
        # the rows of Y = [Z; d1; d2; d3; d4]: each stage state is a coefficient row times Y
        h, columns = dt, slopes.T  # Y^T: Fortran-ordered
        coefficients = [np.array(row) for row in (
            (1.0, 0.5 * h, 0.0, 0.0, 0.0), (1.0, 0.0, 0.5 * h, 0.0, 0.0),
            (1.0, 0.0, 0.0, h, 0.0), (1.0, h / 6.0, h / 3.0, h / 3.0, h / 6.0))]
        # per later stage: its state's product with Y, and where its slope goes in Y
        later = [(gemv(1.0, columns, coefficients[i - 1], 0.0, rows[i]), slopes[i + 1, :nq],
                  slopes[i + 1, nq:], rows[i][nq:]) for i in (1, 2, 3)]
        # bounds of |z|, then of |E tau|: the largest float (false for inf and NaN)
        limits = np.full(3 * nq, np.finfo(float).max)
        limits[:2] = max_distance
        limits[2:nq] = np.inf
        limits[nq:2 * nq] = max_speed
        # what an RK4 step reads, in the order step unpacks it (one unpacking of a tuple
        # costs less than a lookup per name)
        self._rk4 = (evaluate, *arguments, *later, gemv(1.0, columns, coefficients[3], 0.0, new),
                     new, slopes[1, :nq], slopes[1, nq:], state[nq:], substeps, checked,
                     np.zeros(3 * nq), limits, np.zeros(3 * nq, dtype=bool),
                     np.ones(3 * nq, dtype=bool).tobytes())

    def times(self, steps: int) -> tuple[np.ndarray, np.ndarray]:
        calls = np.arange(steps) * self._control_dt
        return calls, np.r_[0.0, calls + self._control_dt]

    def reset(self, x0: np.ndarray, out: np.ndarray) -> None:
        self._state[...] = x0
        out[...] = x0

    def step(self, tau: np.ndarray, first: np.ndarray | None, out: np.ndarray,
             t: float) -> str:
        joint_torque = self._joint_torque
        joint_torque[...] = tau
        # E tau: a passive joint's entry checked (a non-finite one ends the step before it
        # starts) and set to 0: no arithmetic, so no floating-point flag
        for joint in self._passive:
            if not math.isfinite(joint_torque[joint]):
                return "the torque is not finite"  # nothing stepped
            joint_torque[joint] = 0.0
        state = self._state
        if self._method != "rk4":
            nq = self.nq
            out[...] = _solve_ivp_step(self._rhs, state, t, self._control_dt)
            state[...] = out
            return _divergence(out, nq, self._max_speed, self._max_distance)
        (evaluate, arguments0, arguments1, arguments2, arguments3, (stage1, v1, a1, s1),
         (stage2, v2, a2, s2), (stage3, v3, a3, s3), final, new, d0, a0, velocity, substeps,
         checked, magnitude, limits, within, all_within) = self._rk4
        for sub in range(substeps):
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
        if _LESS_EQUAL(_ABSOLUTE(checked, magnitude), limits, within).tobytes() == all_within:
            return ""
        return _divergence(out, self.nq, self._max_speed, self._max_distance) or \
            "the torque is not finite"

    def _rhs(self, _t: float, x: np.ndarray) -> np.ndarray:
        """[q', q''] under the held torque, for scipy's solver."""
        nq = self.nq
        return np.concatenate((x[nq:], self.snake.state_derivative(x, self._joint_torque)))


def _divergence(x: np.ndarray, nq: int, max_speed: float, max_distance: float) -> str:
    """What is wrong with the state x ("" when nothing)."""
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
