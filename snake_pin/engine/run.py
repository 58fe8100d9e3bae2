"""Closed loop on the engine (Section VI.3): identification, velocity filter, runs.

* :func:`identify_friction` fits the viscous coefficients the controller's model uses from
  short open-loop pushes of the straight snake on its wheels: the snake is given a speed
  v0 along (or across) its body and left to coast; the least-squares viscous fit of the
  deceleration, c = -m sum(v v') / sum(v^2) per link, is c_x (or c_y). Along the body the
  wheels roll (c_x should match the axle damping, 2 b / r^2 per link); across it they slide
  with Coulomb friction, whose viscous equivalent depends on the speed range, here
  0..v0 = 0.1 m/s, the speed of the task. c_theta is the axle damping seen by a link
  turning about its CM, 2 d^2 b / r^2.
* :class:`DirtyDerivative` estimates velocities from positions with 2 pi f_c s / (s + 2 pi f_c)
  (DESIGN §3 erratum 4), discretised by backward Euler.
* :func:`run_engine` runs the Lyapunov-like controller against MuJoCo at 1 kHz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from .._validation import finite_number
from ..control import LyapunovController, QuasiStaticLyapunovController, head_first_reference
from ..exceptions import ParameterError, SnakePinError
from ..gaits import initial_state
from ..model import Snake
from ..params import SnakeParams
from ..sim import Trajectory
from .model import GRAVITY, EngineModel, WheelSpec, build_engine_model

__all__ = ["LAWS", "DirtyDerivative", "EngineRun", "identify_friction", "run_engine"]


class DirtyDerivative:
    """y = 2 pi f_c s / (s + 2 pi f_c) x, backward Euler at period dt, per channel."""

    def __init__(self, size: int, cutoff: float, dt: float) -> None:
        self.omega = 2 * math.pi * finite_number(cutoff, "cutoff", positive=True)
        self.dt = finite_number(dt, "dt", positive=True)
        self._gain = 1.0 / (1.0 + self.omega * self.dt)
        self._x = np.zeros(size)
        self._y = np.zeros(size)
        self._started = False

    def reset(self, x0: np.ndarray) -> None:
        """Start from x0 at rest."""
        self._x = np.asarray(x0, dtype=float).copy()
        self._y[:] = 0.0
        self._started = True

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Feed the next sample, return the velocity estimate."""
        if not self._started:
            self.reset(x)
        # y' = -w y + w x'  ->  y_k = (y_{k-1} + w (x_k - x_{k-1})) / (1 + w dt)
        self._y = self._gain * (self._y + self.omega * (x - self._x))
        self._x = np.array(x, dtype=float)
        return self._y.copy()


def _coast(engine: EngineModel, velocity: tuple[float, float, float],
           duration: float) -> tuple[np.ndarray, np.ndarray]:
    """Straight snake given (vx, vy, yaw rate) in its own frame, coasting: (t, v) samples."""
    engine.set_paper_configuration(np.zeros(engine.params.n + 2))
    engine.data.qvel[0:2] = velocity[:2]
    engine.data.qvel[5] = velocity[2]
    # wheels spin as if rolling (no initial slip along the link)
    for b in range(engine.model.nbody):
        name = engine.model.body(b).name
        if "_wheel_" in name:
            dof = engine.model.jnt_dofadr[engine.model.body_jntadr[b]]
            engine.data.qvel[dof] = velocity[0] / engine.wheels.radius
    mujoco.mj_forward(engine.model, engine.data)
    steps = int(duration / engine.model.opt.timestep)
    t, v = np.empty(steps), np.empty((steps, 2))
    for k in range(steps):
        mujoco.mj_step(engine.model, engine.data)
        t[k] = engine.data.time
        v[k] = engine.data.qvel[0:2]
    return t, v


def _viscous_fit(t: np.ndarray, v: np.ndarray, mass: float) -> float:
    moving = np.abs(v) > 1e-3 * np.abs(v).max()
    dv = np.gradient(v, t)
    return float(-mass * np.sum(v[moving] * dv[moving]) / np.sum(v[moving] ** 2))


def identify_friction(params: SnakeParams | None = None, wheels: WheelSpec | None = None,
                      speed: float = 0.1) -> dict[str, float]:
    """Viscous c_x, c_y, c_theta per link fitted to the engine (see module docstring)."""
    params = params or SnakeParams.engine()
    wheels = wheels or WheelSpec()
    engine = build_engine_model(params, wheels)
    t, v = _coast(engine, (speed, 0.0, 0.0), 2.0)
    c_x = _viscous_fit(t, v[:, 0], params.mass)
    t, v = _coast(engine, (0.0, speed, 0.0), 0.2)
    c_y = _viscous_fit(t, v[:, 1], params.mass)
    b, r, d = wheels.rolling_damping, wheels.radius, engine.wheel_offset
    return {"c_x": c_x, "c_y": c_y, "c_theta": 2 * d**2 * b / r**2,
            "c_x_rolling_model": 2 * b / r**2,
            "c_y_coulomb_model": 1.5 * wheels.friction * params.mass * GRAVITY / speed,
            "speed": speed}


@dataclass
class EngineRun:
    """An engine run: the trajectory of the estimated state and the true one."""

    trajectory: Trajectory  # q from the engine, dq estimated (what the controller saw)
    true_dq: np.ndarray
    friction: dict[str, float]


LAWS = ("velocity", "acceleration")


def run_engine(params: SnakeParams | None = None, *, wheels: WheelSpec | None = None,
               t_final: float = 60.0, friction: dict[str, float] | None = None,
               cutoff: float = 10.0, law: str = "velocity", progress: bool = False) -> EngineRun:
    """Lyapunov-like head tracking on MuJoCo, control at 1 kHz, velocities from the filter.

    The controller's internal model is ``params`` with the identified viscous friction.
    ``law="velocity"`` uses the quasi-static, velocity-level form of V's minimisation with
    joint servos (:class:`QuasiStaticLyapunovController`); ``law="acceleration"`` the
    torque-level form of VI.2 (:class:`LyapunovController`). Stops early (``diverged``) if
    the engine state becomes non-finite or the robot leaves the floor.
    """
    if law not in LAWS:
        raise ParameterError(f"law must be one of {', '.join(LAWS)}, got {law!r}")
    params = params or SnakeParams.engine()
    wheels = wheels or WheelSpec()
    friction = friction or identify_friction(params.replace(passive=()), wheels)
    model_params = params.replace(c_x=friction["c_x"], c_y=friction["c_y"],
                                  c_theta=friction["c_theta"])
    engine = build_engine_model(params, wheels)
    snake = Snake(model_params)
    if law == "velocity":
        controller = QuasiStaticLyapunovController(snake, head_first_reference(),
                                                   control_dt=wheels.control_dt)
    else:
        controller = LyapunovController(snake, head_first_reference())
    q0 = initial_state(params.n, theta_1=math.pi)[: params.n + 2]
    engine.set_paper_configuration(q0)
    dt = wheels.control_dt
    steps = round(t_final / dt)
    nq = snake.nq
    filt = DirtyDerivative(nq, cutoff, dt)
    ts = np.empty(steps + 1)
    qs = np.empty((steps + 1, nq))
    dqs = np.empty((steps + 1, nq))
    true_dq = np.empty((steps + 1, nq))
    taus = np.zeros((steps + 1, params.n - 1))
    yaw_prev, yaw_turns = q0[2], 0.0
    diverged, reason, k = False, "", 0
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=steps, desc="engine", unit="step", leave=False)
    chain = engine.chain_dofs
    for k in range(steps + 1):
        q = engine.paper_configuration()
        # unwrap the heading so the filter and the reference see a continuous angle
        jump = q[2] - yaw_prev
        yaw_turns -= 2 * math.pi * round(jump / (2 * math.pi))
        yaw_prev = q[2]
        q[2] += yaw_turns
        dq = filt(q)
        ts[k], qs[k], dqs[k] = engine.data.time, q, dq
        true_dq[k] = engine.data.qvel[chain]
        if not (np.all(np.isfinite(q)) and engine.data.qpos[2] < 5 * wheels.radius):
            diverged, reason = True, f"engine state left the floor at t = {engine.data.time:.3f} s"
            break
        if k == steps:
            break
        try:
            tau = controller(np.concatenate((q, dq)), engine.data.time)
        except SnakePinError as exc:
            diverged, reason = True, f"controller failed at t = {engine.data.time:.3f} s: {exc}"
            break
        taus[k] = tau
        engine.apply_torque(tau)
        for _ in range(wheels.substeps):
            mujoco.mj_step(engine.model, engine.data)
        if bar is not None and k % 500 == 0:
            bar.update(min(500, steps - bar.n))
    if bar is not None:
        bar.close()
    last = k + 1
    traj = Trajectory(t=ts[:last], q=qs[:last], dq=dqs[:last], tau=taus[:last],
                      params=model_params, diverged=diverged, reason=reason,
                      meta={"controller": controller.name, "law": law, "engine": "mujoco",
                            "cutoff_hz": cutoff,
                            "control_dt": dt, "engine_timestep": wheels.timestep,
                            "wheel_radius": wheels.radius, "wheel_friction": wheels.friction})
    return EngineRun(traj, true_dq[:last], friction)
