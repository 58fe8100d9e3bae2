"""Closed loop on the engine (Section VI.3): identification, velocity filter, runs.

* :func:`identify_friction` fits the viscous coefficients the controller's model uses from
  short open-loop pushes of the straight snake on its wheels: the snake is given a speed
  v0 along (or across) its body and left to coast; the least-squares viscous fit of the
  deceleration, c = -m sum(v v') / sum(v^2) per link, is c_x (or c_y). Along the body the
  wheels roll (c_x should match the axle damping, 2 b / r^2 per link); across it they slide
  with Coulomb friction, whose viscous equivalent depends on the speed range, here
  0..v0 = 0.1 m/s, the speed of the task. c_theta is the axle damping seen by a link
  turning about its CM, 2 d^2 b / r^2. A robot with per-link values is fitted whole (its
  total mass) and the totals are shared out per link: c_x equally, c_y in proportion to
  each link's mass (the load on its wheels), c_theta from each link's own wheel offset.
* :class:`DirtyDerivative` estimates velocities from positions with 2 pi f_c s / (s + 2 pi f_c)
  (erratum 4 in docs/errata.md), discretised by backward Euler.
* :func:`run_engine` runs the Lyapunov-like controller against MuJoCo at 1 kHz.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from .._validation import finite_number
from ..control import LyapunovController, QuasiStaticLyapunovController, head_first_reference
from ..control.reference import HeadReference
from ..exceptions import ParameterError, RunInterrupted
from ..gaits import initial_state
from ..model import Snake
from ..params import SnakeParams
from ..sim import MAX_STEPS, Trajectory
from .model import GRAVITY, EngineModel, WheelSpec, build_engine_model

__all__ = ["LAWS", "DirtyDerivative", "EngineRun", "identify_friction", "run_engine"]


class DirtyDerivative:
    """y = 2 pi f_c s / (s + 2 pi f_c) x, backward Euler at period dt, per channel.

    Parameters
    ----------
    size
        Number of channels.
    cutoff
        Cut-off frequency f_c [Hz].
    dt
        Sampling period [s].
    """

    def __init__(self, size: int, cutoff: float, dt: float) -> None:
        self.omega = 2 * math.pi * finite_number(cutoff, "cutoff", positive=True)
        self.dt = finite_number(dt, "dt", positive=True)
        self._gain = 1.0 / (1.0 + self.omega * self.dt)
        self._x = np.zeros(size)
        self._y = np.zeros(size)
        self._started = False

    def reset(self, x0: np.ndarray) -> None:
        """Start from ``x0`` at rest (zero velocity estimate).

        Parameters
        ----------
        x0
            The first sample, one value per channel.
        """
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
    """Straight snake at ``heading`` given (vx, vy, yaw rate) in its own frame, coasting:
    (t, v) samples, v the head's velocity in the snake's frame."""
    q = np.zeros(engine.params.n + 2)
    q[2] = heading
    engine.set_paper_configuration(q)
    c, s = math.cos(heading), math.sin(heading)
    engine.data.qvel[0:2] = (c * velocity[0] - s * velocity[1],
                             s * velocity[0] + c * velocity[1])
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
    world = engine.data.qvel[0:2]
    for k in range(steps):
        mujoco.mj_step(engine.model, engine.data)
        t[k] = engine.data.time
        v[k] = (c * world[0] + s * world[1], c * world[1] - s * world[0])
    return t, v


def _viscous_fit(t: np.ndarray, v: np.ndarray, mass: float) -> float:
    moving = np.abs(v) > 1e-3 * np.abs(v).max()
    dv = np.gradient(v, t)
    return float(-mass * np.sum(v[moving] * dv[moving]) / np.sum(v[moving] ** 2))


def identify_friction(params: SnakeParams | None = None, wheels: WheelSpec | None = None,
                      speed: float = 0.1, heading: float = 0.0) -> dict[str, Any]:
    """Viscous c_x, c_y, c_theta per link fitted to the engine (see module docstring).

    Parameters
    ----------
    params
        The robot (default: the ``engine`` preset); its passive joints do not matter.
    wheels
        The wheels and contact settings (default :class:`WheelSpec`).
    speed
        The coasting speed v0 [m/s] along and across the body.
    heading
        The straight snake's heading [rad] while it coasts (the body's axis against the
        world x axis). A faithful Coulomb contact gives the same fit at any heading; the
        pyramidal cone does not (its friction limit is a square in the world's axes).

    Returns
    -------
    dict
        ``c_x``, ``c_y``, ``c_theta`` [N s/m, N s/m, N m s], the model checks
        ``c_x_rolling_model`` (2 b / r^2, per link) and ``c_y_coulomb_model``
        (1.5 mu M g / v0), and ``speed``.

        Equal links (``params.uniform``): each coefficient is one number, fitted per link
        (the straight snake's deceleration with the link mass m), and
        ``c_y_coulomb_model`` is per link (M = m).

        Per-link robots: the whole robot is fitted with its total mass M, giving
        ``c_x_total`` and ``c_y_total`` (also returned), and distributed over the links
        as tuples, head first: c_x,i = c_x,total / n (every link rolls on the same
        wheels), c_y,i = c_y,total m_i / M (Coulomb sliding is proportional to the load a
        link puts on its wheels), c_theta,i = 2 d_i^2 b / r^2 with link i's own wheel
        offset d_i. ``c_y_coulomb_model`` is then the whole robot's (M = total mass).

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
    if params.uniform:
        mass = float(params.mass)  # type: ignore[arg-type]  # one number: equal links
        t, v = _coast(engine, (speed, 0.0, 0.0), 2.0, heading)
        c_x = _viscous_fit(t, v[:, 0], mass)
        t, v = _coast(engine, (0.0, speed, 0.0), 0.2, heading)
        c_y = _viscous_fit(t, v[:, 1], mass)
        d = engine.wheel_offset
        return {"c_x": c_x, "c_y": c_y, "c_theta": 2 * d**2 * b / r**2,
                "c_x_rolling_model": 2 * b / r**2,
                "c_y_coulomb_model": 1.5 * wheels.friction * mass * GRAVITY / speed,
                "speed": speed}
    total = params.total_mass
    t, v = _coast(engine, (speed, 0.0, 0.0), 2.0, heading)
    c_x_total = _viscous_fit(t, v[:, 0], total)
    t, v = _coast(engine, (0.0, speed, 0.0), 0.2, heading)
    c_y_total = _viscous_fit(t, v[:, 1], total)
    offsets = np.asarray(engine.wheel_offsets, dtype=float)
    return {"c_x": tuple([c_x_total / params.n] * params.n),
            "c_y": tuple((c_y_total * params.masses / total).tolist()),
            "c_theta": tuple((2 * offsets**2 * b / r**2).tolist()),
            "c_x_rolling_model": 2 * b / r**2,
            "c_y_coulomb_model": 1.5 * wheels.friction * total * GRAVITY / speed,
            "c_x_total": c_x_total, "c_y_total": c_y_total, "speed": speed}


@dataclass
class EngineRun:
    """An engine run: the trajectory of the estimated state and the true one.

    Parameters
    ----------
    trajectory
        q read from the engine and dq estimated by the filter (what the controller saw),
        the torques, status and meta.
    true_dq
        The engine's own velocities on (x, y, yaw, phi) at the same samples.
    friction
        The viscous model the controller used (:func:`identify_friction`).
    """

    trajectory: Trajectory  # q from the engine, dq estimated (what the controller saw)
    true_dq: np.ndarray
    friction: dict[str, float]


LAWS = ("velocity", "acceleration")


def run_engine(params: SnakeParams | None = None, *, wheels: WheelSpec | None = None,
               t_final: float = 60.0, friction: dict[str, float] | None = None,
               cutoff: float = 10.0, law: str = "velocity",
               initial_offset: Sequence[float] | np.ndarray | None = None,
               reference: HeadReference | None = None,
               progress: bool = False) -> EngineRun:
    """Lyapunov-like head tracking on MuJoCo, control at 1 kHz, velocities from the filter.

    The controller's internal model is ``params`` with the identified viscous friction.
    ``law="velocity"`` uses the quasi-static, velocity-level form of V's minimisation with
    joint servos (:class:`QuasiStaticLyapunovController`); ``law="acceleration"`` the
    torque-level form of VI.2 (:class:`LyapunovController`).

    The run starts at rest on the arc of eq. (82), head first (theta_1 = pi), with
    ``initial_offset`` (n - 1 angles [rad], default zeros) added to its joint angles: the
    engine runs are chaotic, and ``snake-pin engine --seeds N`` and the report run them as
    distributions over small offsets (:mod:`snake_pin.experiments.engine`).

    The run ends like :func:`snake_pin.sim.simulate`'s, with a trajectory status:
    "diverged" if the engine state becomes non-finite or the robot leaves the floor,
    "failed" if the controller raises (any exception), "completed" otherwise. At most
    :data:`snake_pin.sim.MAX_STEPS` control steps (``t_final / wheels.control_dt``).

    Parameters
    ----------
    params
        The robot (default: the ``engine`` preset); its passive joints get no motor.
    wheels
        Wheels, contacts and time steps (default :class:`WheelSpec`).
    t_final
        Duration [s].
    friction
        The controller's viscous model (default: :func:`identify_friction` of the robot
        with every joint actuated).
    cutoff
        Cut-off of the velocity filter [Hz].
    law
        "velocity" or "acceleration" (see above).
    initial_offset
        n - 1 offsets added to the initial joint angles [rad] (see above).
    reference
        The head reference ``t -> (w_r, w_r', w_r'')`` (default
        :func:`~snake_pin.control.head_first_reference`: 0.1 m/s along +x); any path of
        :mod:`snake_pin.paths` with its timing law. The run starts with the head at the
        origin leading along +x (theta_1 = pi), so a reference should start there.
    progress
        Show a progress bar on stderr when it is a terminal.

    Returns
    -------
    EngineRun
        The run (status "completed", "diverged" or "failed").

    Raises
    ------
    RunInterrupted
        On KeyboardInterrupt during the run (Ctrl-C, or SIGTERM/SIGHUP turned into it by
        the command line): ``partial`` is the trajectory of every completed sample, with
        status "interrupted" and the time in its reason.
    ParameterError
        An unknown law, a non-positive ``t_final`` or more than ``MAX_STEPS`` steps, an
        ``initial_offset`` of the wrong size or not finite.
    """
    if law not in LAWS:
        raise ParameterError(f"law must be one of {', '.join(LAWS)}, got {law!r}")
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
    engine = build_engine_model(params, wheels)
    snake = Snake(model_params)
    head_reference = reference if reference is not None else head_first_reference()
    controller: QuasiStaticLyapunovController | LyapunovController
    if law == "velocity":
        controller = QuasiStaticLyapunovController(snake, head_reference,
                                                   control_dt=wheels.control_dt)
    else:
        controller = LyapunovController(snake, head_reference)
    q0 = initial_state(params.n, theta_1=math.pi)[: params.n + 2]
    q0[3:] += offset
    engine.set_paper_configuration(q0)
    nq = snake.nq
    filt = DirtyDerivative(nq, cutoff, dt)
    ts = np.empty(steps + 1)
    states = np.empty((steps + 1, 2 * nq))  # rows [q, dq]: the controller reads one whole
    qs, dqs = states[:, :nq], states[:, nq:]
    true_dq = np.empty((steps + 1, nq))
    taus = np.zeros((steps + 1, params.n - 1))
    yaw_prev, yaw_turns = q0[2], 0.0
    status, reason = "completed", ""
    good = 0  # samples 0 .. good - 1 are recorded whole (updated after each sample)
    bar = None
    # MuJoCo's clock adds the timestep once per engine step (from 0 after the reset), so
    # the sampling instants are these running sums exactly and the controller can
    # prepare its time-only terms (a call at another time would compute them alone)
    clock = np.cumsum(np.full(steps * wheels.substeps, wheels.timestep))
    controller.prepare(np.r_[0.0, clock[wheels.substeps - 1::wheels.substeps]][:steps])

    meta = {"controller": controller.name, "law": law, "engine": "mujoco",
            "cutoff_hz": cutoff, "control_dt": dt, "engine_timestep": wheels.timestep,
            "wheel_radius": wheels.radius, "wheel_friction": wheels.friction}
    if initial_offset is not None:
        meta["initial_offset"] = offset.tolist()
    if reference is not None:
        meta["reference"] = repr(reference)

    def collect(run_status: str, run_reason: str) -> EngineRun:
        traj = Trajectory(t=ts[:good].copy(), q=qs[:good].copy(), dq=dqs[:good].copy(),
                          tau=taus[:good].copy(), params=model_params, status=run_status,
                          reason=run_reason,
                          meta=dict(meta))
        return EngineRun(traj, true_dq[:good].copy(), friction)

    try:
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=steps, desc="engine", unit="step", leave=False, disable=None)
        # the engine's state through views of its arrays (as EngineModel reads it)
        data, mj_model, mj_step = engine.data, engine.model, mujoco.mj_step
        head = int(engine.link_bodies[0])
        head_frame, head_position = data.xmat[head], data.xpos[head]
        qpos, qvel, ctrl = data.qpos, data.qvel, data.ctrl
        hinges, chain = engine.hinge_qpos, engine.chain_dofs
        motors = np.array(engine.actuated, dtype=int) - 1
        ceiling, substeps, torque_shape = 5 * wheels.radius, wheels.substeps, (params.n - 1,)
        for k in range(steps + 1):
            q = qs[k]  # EngineModel.paper_configuration, written in place
            yaw = math.atan2(head_frame[3], head_frame[0])
            q[0], q[1] = head_position[0], head_position[1]
            qpos.take(hinges, out=q[3:])
            # unwrap the heading so the filter and the reference see a continuous angle
            jump = yaw - yaw_prev
            if math.isfinite(jump):
                yaw_turns -= 2 * math.pi * round(jump / (2 * math.pi))
            yaw_prev = yaw
            q[2] = yaw + yaw_turns
            if not (np.isfinite(q).all() and qpos[2] < ceiling):
                status = "diverged"
                reason = f"engine state left the floor at t = {data.time:.3f} s"
                break
            filt(q, dqs[k])
            t = data.time
            ts[k] = t
            qvel.take(chain, out=true_dq[k])
            good = k + 1
            if k == steps:
                break
            try:
                tau = np.asarray(controller(states[k], t), dtype=float)
            except Exception as exc:
                status = "failed"
                reason = f"controller failed at t = {t:.3f} s: {exc}"
                break
            if tau.shape != torque_shape or not np.isfinite(tau).all():
                status = "failed"
                reason = (f"controller failed at t = {t:.3f} s: torque of "
                          f"shape {tau.shape} or not finite")
                break
            taus[k] = tau
            tau.take(motors, out=ctrl)  # EngineModel.apply_torque
            mj_step(mj_model, data, substeps)
            if bar is not None and k % 500 == 0:
                bar.update(min(500, steps - bar.n))
    except KeyboardInterrupt:
        if good == 0:
            raise
        taus[good - 1] = 0.0  # the torque after the last sample was not (fully) applied
        partial = collect("interrupted", f"interrupted at t = {ts[good - 1]:.3f} s")
        raise RunInterrupted(partial.trajectory.reason, partial=partial.trajectory) from None
    finally:
        if bar is not None:
            bar.close()
    return collect(status, reason)
