"""Closed loop on the engine (Section VI.3): friction identification, velocity filter, runs.

How and why: :ref:`engine`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from .._validation import brief, finite_number
from ..control import (
    LyapunovController,
    MPCController,
    MPCOptions,
    QuasiStaticLyapunovController,
    head_first_reference,
)
from ..control.reference import HeadReference
from ..exceptions import ParameterError
from ..gaits import initial_state
from ..loop import MAX_STEPS, Plant, closed_loop
from ..model import Snake
from ..params import SnakeParams
from ..trajectory import Trajectory
from ..urdf import EFFORT_LIMIT
from .model import GRAVITY, EngineModel, WheelSpec, build_engine_model

__all__ = ["ENGINE_TORQUE_BOUND", "LAWS", "EnginePlant", "EngineRun", "identify_friction",
           "run_engine"]


class DirtyDerivative:
    """The velocity filter y = 2 pi f_c s / (s + 2 pi f_c) x (``cutoff`` f_c [Hz]), backward
    Euler at period ``dt`` [s], on ``size`` channels (erratum 4)."""

    def __init__(self, size: int, cutoff: float, dt: float) -> None:
        self.omega = 2 * math.pi * finite_number(cutoff, "cutoff", positive=True)
        self.dt = finite_number(dt, "dt", positive=True)
        self._gain = 1.0 / (1.0 + self.omega * self.dt)
        self._x = np.zeros(size)
        self._y = np.zeros(size)
        self._started = False

    def reset(self, x0: np.ndarray) -> None:
        """Start from the sample ``x0`` at rest (zero velocity estimate)."""
        self._x = np.array(x0, dtype=float)
        self._y[:] = 0.0
        self._started = True

    def __call__(self, x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Feed the next sample, return the velocity estimate (in ``out`` if given)."""
        if not self._started:
            self.reset(x)
        # y' = -w y + w x'  ->  y_k = (y_{k-1} + w (x_k - x_{k-1})) / (1 + w dt), in place
        y = self._y
        step = np.subtract(x, self._x)
        step *= self.omega
        y += step
        y *= self._gain
        self._x[:] = x
        if out is None:
            return y.copy()
        out[:] = y
        return out


def _coast(engine: EngineModel, velocity: tuple[float, float, float], duration: float,
           heading: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(t, v) of the straight snake at ``heading`` coasting from (vx, vy, yaw rate) in its
    own frame, v the head's velocity in that frame."""
    q = np.zeros(engine.params.n + 2)
    q[2] = heading
    engine.set_paper_configuration(q)
    c, s = math.cos(heading), math.sin(heading)
    engine.data.qvel[0:2] = (c * velocity[0] - s * velocity[1],
                             s * velocity[0] + c * velocity[1])
    engine.data.qvel[5] = velocity[2]
    # wheels spin as if rolling (no initial slip along the link)
    for b in range(engine.model.nbody):
        if "_wheel_" in engine.model.body(b).name:
            dof = engine.model.jnt_dofadr[engine.model.body_jntadr[b]]
            engine.data.qvel[dof] = velocity[0] / engine.wheels.radius
    mujoco.mj_forward(engine.model, engine.data)
    steps = int(duration / engine.model.opt.timestep)
    t, v = np.empty(steps), np.empty((steps, 2))
    world = engine.data.qvel[0:2]
    for k in range(steps):
        mujoco.mj_step(engine.model, engine.data)
        t[k] = engine.data.time
        v[k] = (c * world[0] + s * world[1], c * world[1] - s * world[0])
    return t, v


def _viscous_fit(t: np.ndarray, v: np.ndarray, mass: float) -> float:
    """The least-squares viscous coefficient ``-m sum(v v') / sum(v^2)`` of a coast."""
    moving = np.abs(v) > 1e-3 * np.abs(v).max()
    dv = np.gradient(v, t)
    return float(-mass * np.sum(v[moving] * dv[moving]) / np.sum(v[moving] ** 2))


def identify_friction(params: SnakeParams | None = None, wheels: WheelSpec | None = None,
                      speed: float = 0.1, heading: float = 0.0) -> dict[str, Any]:
    """Viscous c_x, c_y, c_theta per link fitted to the engine's coasting snake (:ref:`engine`).

    Parameters
    ----------
    params, wheels
        The robot (default: the ``engine`` preset) and its wheels (default :class:`WheelSpec`).
    speed, heading
        The coasting speed v0 [m/s] along and across the body, and the heading [rad].

    Returns
    -------
    dict
        ``c_x``, ``c_y``, ``c_theta`` (numbers on equal links, else per-link tuples), the
        model checks ``c_x_rolling_model`` (2 b / r^2) and ``c_y_coulomb_model``
        (1.5 mu M g / v0, M the link's mass or the robot's), ``speed``, and on per-link
        robots ``c_x_total`` and ``c_y_total``.

    Raises
    ------
    ParameterError
        ``heading`` is not a finite number, or the wheels do not fit the robot.
    """
    params = params or SnakeParams.engine()
    wheels = wheels or WheelSpec()
    heading = finite_number(heading, "heading")
    engine = build_engine_model(params, wheels)
    b, r = wheels.rolling_damping, wheels.radius
    # equal links: fitted per link with its mass m; else the whole robot with its mass M
    mass = float(params.mass) if params.uniform else params.total_mass  # type: ignore[arg-type]
    t, v = _coast(engine, (speed, 0.0, 0.0), 2.0, heading)
    c_x = _viscous_fit(t, v[:, 0], mass)
    t, v = _coast(engine, (0.0, speed, 0.0), 0.2, heading)
    c_y = _viscous_fit(t, v[:, 1], mass)
    checks = {"c_x_rolling_model": 2 * b / r**2,
              "c_y_coulomb_model": 1.5 * wheels.friction * mass * GRAVITY / speed}
    if params.uniform:
        d = engine.wheel_offset
        return {"c_x": c_x, "c_y": c_y, "c_theta": 2 * d**2 * b / r**2, **checks,
                "speed": speed}
    offsets = np.asarray(engine.wheel_offsets, dtype=float)
    return {"c_x": tuple([c_x / params.n] * params.n),
            "c_y": tuple((c_y * params.masses / mass).tolist()),
            "c_theta": tuple((2 * offsets**2 * b / r**2).tolist()), **checks,
            "c_x_total": c_x, "c_y_total": c_y, "speed": speed}


@dataclass
class EngineRun:
    """An engine run: the trajectory of the estimated state and the true one.

    Parameters
    ----------
    trajectory, true_dq, friction
        What the controller saw (dq from the filter), the engine's own velocities, and the
        viscous model the controller used (:func:`identify_friction`).
    """

    trajectory: Trajectory
    true_dq: np.ndarray
    friction: dict[str, float]


LAWS = ("velocity", "acceleration", "mpc")
#: The MPC's torque bound on the engine [N m]: the engine robot's motors saturate at
#: EFFORT_LIMIT (their ``ctrlrange``), so the MPC plans within exactly what they deliver.
ENGINE_TORQUE_BOUND = EFFORT_LIMIT


def run_engine(params: SnakeParams | None = None, *, wheels: WheelSpec | None = None,
               t_final: float = 60.0, friction: dict[str, float] | None = None,
               cutoff: float = 10.0, law: str = "velocity",
               initial_offset: Sequence[float] | np.ndarray | None = None,
               reference: HeadReference | None = None,
               mpc_options: MPCOptions | None = None,
               progress: bool = False) -> EngineRun:
    """Head tracking on MuJoCo, control at 1 kHz, velocities from the filter (:ref:`engine`).

    Parameters
    ----------
    params, wheels
        The robot (default: the ``engine`` preset; passive joints get no motor) and its
        wheels, contacts and time steps (default :class:`WheelSpec`).
    t_final, cutoff
        Duration [s] (:data:`~snake_pin.loop.MAX_STEPS` steps at most), filter cut-off [Hz].
    friction
        The law's viscous model (default: :func:`identify_friction`, every joint actuated).
    law
        "velocity", "acceleration" (the Lyapunov-like law's two forms) or "mpc".
    initial_offset
        n - 1 offsets added to the initial joint angles [rad].
    reference
        The head reference, from the origin heading +x (default: head first).
    mpc_options
        The MPC's settings (default: ``torque_bound`` at the motors' saturation, its maximum).
    progress
        Show a progress bar on stderr when it is a terminal.

    Returns
    -------
    EngineRun
        The run (status "completed", "diverged" or "failed").

    Raises
    ------
    RunInterrupted, ParameterError
        On Ctrl-C (``partial`` holds every completed sample); an unknown law, a bad argument,
        or ``mpc_options`` with a torque bound above the motors' or given to another law.
    """
    if law not in LAWS:
        raise ParameterError(f"law must be one of {', '.join(LAWS)}, got {law!r}")
    if mpc_options is not None:
        if law != "mpc":
            raise ParameterError(f"mpc_options are for law 'mpc', not {law!r}")
        if not isinstance(mpc_options, MPCOptions):
            raise ParameterError(f"mpc_options must be MPCOptions, got {brief(mpc_options)}")
        if mpc_options.torque_bound > ENGINE_TORQUE_BOUND:
            raise ParameterError(f"the MPC's torque_bound {mpc_options.torque_bound:g} N m "
                                 f"exceeds the engine motors' {ENGINE_TORQUE_BOUND:g} N m")
    params = params or SnakeParams.engine()
    wheels = wheels or WheelSpec()
    t_final = finite_number(t_final, "t_final", positive=True)
    dt = wheels.control_dt
    steps = round(t_final / dt)
    if steps > MAX_STEPS:
        raise ParameterError(f"t_final = {t_final:g} s is {steps} control steps of {dt:g} s; "
                             f"at most {MAX_STEPS} ({MAX_STEPS * dt:g} s)")
    offset = np.zeros(params.n - 1)
    if initial_offset is not None:
        try:
            offset = np.asarray(initial_offset, dtype=float).reshape(params.n - 1).copy()
        except (TypeError, ValueError):
            raise ParameterError(f"initial_offset must be {params.n - 1} joint angles, got "
                                 f"{np.shape(initial_offset)}") from None
        if not np.all(np.isfinite(offset)):
            raise ParameterError("initial_offset must be finite")
    friction = friction or identify_friction(params.replace(passive=()), wheels)
    model_params = params.replace(c_x=friction["c_x"], c_y=friction["c_y"],
                                  c_theta=friction["c_theta"])
    snake = Snake(model_params)
    head_reference = reference if reference is not None else head_first_reference()
    controller: QuasiStaticLyapunovController | LyapunovController | MPCController
    if law == "velocity":
        controller = QuasiStaticLyapunovController(snake, head_reference, control_dt=dt)
    elif law == "mpc":
        controller = MPCController(snake, head_reference, options=mpc_options or MPCOptions(
            torque_bound=ENGINE_TORQUE_BOUND))
    else:
        controller = LyapunovController(snake, head_reference)
    q0 = initial_state(params.n, theta_1=math.pi)[: params.n + 2]
    q0[3:] += offset
    plant = EnginePlant(build_engine_model(params, wheels), model_params, cutoff)
    meta = {"controller": controller.name, "law": law, "engine": "mujoco",
            "cutoff_hz": cutoff, "control_dt": dt, "engine_timestep": wheels.timestep,
            "wheel_radius": wheels.radius, "wheel_friction": wheels.friction}
    if initial_offset is not None:
        meta["initial_offset"] = offset.tolist()
    if reference is not None:
        meta["reference"] = repr(reference)
    if isinstance(controller, MPCController):
        meta["mpc"] = {key: getattr(controller.options, key) for key in
                       ("torque_bound", "horizon", "node_dt", "resolve_period")}
    traj = closed_loop(plant, controller, np.r_[q0, np.zeros(len(q0))], steps,
                       progress=progress, meta=meta, label="engine", record_signals=False)
    if isinstance(controller, MPCController):
        stats = controller.stats
        traj.meta["mpc"].update(solves=stats.solves, iterations=stats.iterations,
                                solver_wall=stats.wall)
    return EngineRun(traj, plant.true_dq[:len(traj)].copy(), friction)


class EnginePlant(Plant):
    """The MuJoCo robot as a :class:`~snake_pin.loop.Plant`: the torque held over the
    engine's substeps, q read from it (heading unwrapped) and q' from the velocity filter;
    a sample not finite or whose body left the floor (five wheel radii up) diverges.

    Parameters
    ----------
    engine, params, cutoff : EngineModel, SnakeParams, float
        The MuJoCo robot, the controller's model of it, the velocity filter's cut-off [Hz].

    Attributes
    ----------
    true_dq
        (samples, n + 2): the engine's own velocities on (x, y, yaw, phi) at each sample.
    """

    def __init__(self, engine: EngineModel, params: SnakeParams, cutoff: float) -> None:
        self.engine, self.params = engine, params
        self.nq = params.n + 2
        wheels = engine.wheels
        self._filter = DirtyDerivative(self.nq, cutoff, wheels.control_dt)
        self._motors = np.array(engine.actuated, dtype=int) - 1
        self._ceiling = 5 * wheels.radius
        self.true_dq = np.zeros((0, self.nq))
        self._sample = 0
        self._yaw, self._turns = 0.0, 0.0

    def times(self, steps: int) -> tuple[np.ndarray, np.ndarray]:
        # MuJoCo's clock: running sums of its timestep
        wheels = self.engine.wheels
        clock = np.cumsum(np.full(steps * wheels.substeps, wheels.timestep))
        samples = np.r_[0.0, clock[wheels.substeps - 1::wheels.substeps]]
        self.true_dq = np.zeros((steps + 1, self.nq))
        return samples[:steps], samples

    def reset(self, x0: np.ndarray, out: np.ndarray) -> None:
        q0 = x0[:self.nq]
        self.engine.set_paper_configuration(q0)
        self._yaw, self._turns, self._sample = float(q0[2]), 0.0, 0
        self._read(out)

    def step(self, tau: np.ndarray, first: np.ndarray | None, out: np.ndarray,
             t: float) -> str:
        engine = self.engine
        tau.take(self._motors, out=engine.data.ctrl)  # EngineModel.apply_torque
        mujoco.mj_step(engine.model, engine.data, engine.wheels.substeps)
        return self._read(out)

    def _read(self, out: np.ndarray) -> str:
        """The sample into ``out`` (EngineModel.paper_configuration, then the filter)."""
        engine, nq = self.engine, self.nq
        data = engine.data
        q = out[:nq]
        head = int(engine.link_bodies[0])
        frame, position = data.xmat[head], data.xpos[head]
        yaw = math.atan2(frame[3], frame[0])
        q[0], q[1] = position[0], position[1]
        data.qpos.take(engine.hinge_qpos, out=q[3:])
        jump = yaw - self._yaw
        if math.isfinite(jump):
            self._turns -= 2 * math.pi * round(jump / (2 * math.pi))
        self._yaw = yaw
        q[2] = yaw + self._turns
        if not (np.isfinite(q).all() and data.qpos[2] < self._ceiling):
            return "the engine state left the floor"
        self._filter(q, out[nq:])
        data.qvel.take(engine.chain_dofs, out=self.true_dq[self._sample])
        self._sample += 1
        return ""
