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
* :func:`run_engine` runs the Lyapunov-like controller (either form) or the MPC against
  MuJoCo at 1 kHz: the :class:`EnginePlant` in :func:`snake_pin.loop.closed_loop`, the
  loop :func:`snake_pin.sim.simulate` runs over the viscous model. Each law's internal
  model is the identified viscous one.
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

__all__ = ["ENGINE_TORQUE_BOUND", "LAWS", "DirtyDerivative", "EnginePlant", "EngineRun",
           "identify_friction", "run_engine"]


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
    """Head tracking on MuJoCo, control at 1 kHz, velocities from the filter.

    The controller's internal model is ``params`` with the identified viscous friction.
    ``law="velocity"`` uses the quasi-static, velocity-level form of V's minimisation with
    joint servos (:class:`QuasiStaticLyapunovController`); ``law="acceleration"`` the
    torque-level form of VI.2 (:class:`LyapunovController`); ``law="mpc"`` the
    receding-horizon Box-FDDP (:class:`MPCController`) on that same viscous model, its
    torques bounded by :data:`ENGINE_TORQUE_BOUND` (the motors' saturation) unless
    ``mpc_options`` says otherwise. Every law reads the filtered velocities.

    The run starts at rest on the arc of eq. (82), head first (theta_1 = pi), with
    ``initial_offset`` (n - 1 angles [rad], default zeros) added to its joint angles: the
    engine runs are chaotic, and ``snake-pin engine --seeds N`` and the report run them as
    distributions over small offsets (:mod:`snake_pin.experiments.engine`).

    The run ends like :func:`snake_pin.sim.simulate`'s, with a trajectory status:
    "diverged" if the engine state becomes non-finite or the robot leaves the floor,
    "failed" if the controller raises (any exception), "completed" otherwise. At most
    :data:`snake_pin.loop.MAX_STEPS` control steps (``t_final / wheels.control_dt``).

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
        "velocity", "acceleration" or "mpc" (see above).
    initial_offset
        n - 1 offsets added to the initial joint angles [rad] (see above).
    reference
        The head reference ``t -> (w_r, w_r', w_r'')`` (default
        :func:`~snake_pin.control.head_first_reference`: 0.1 m/s along +x); any path of
        :mod:`snake_pin.paths` with its timing law. The run starts with the head at the
        origin leading along +x (theta_1 = pi), so a reference should start there.
    mpc_options
        The MPC's settings with ``law="mpc"`` (default :class:`MPCOptions` with
        ``torque_bound`` = :data:`ENGINE_TORQUE_BOUND`); a torque bound above the motors'
        saturation is refused (the engine would clip what the MPC plans).
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
        ``initial_offset`` of the wrong size or not finite, ``mpc_options`` not
        MPCOptions, with a torque bound above the motors', or given to another law.
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
        controller = QuasiStaticLyapunovController(snake, head_reference,
                                                   control_dt=wheels.control_dt)
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
        o = controller.options
        meta["mpc"] = {"torque_bound": o.torque_bound, "horizon": o.horizon,
                       "node_dt": o.node_dt, "resolve_period": o.resolve_period}
    traj = closed_loop(plant, controller, np.r_[q0, np.zeros(len(q0))], steps,
                       progress=progress, meta=meta, label="engine", record_signals=False)
    if isinstance(controller, MPCController):
        stats = controller.stats
        traj.meta["mpc"].update(solves=stats.solves, iterations=stats.iterations,
                                solver_wall=stats.wall)
    return EngineRun(traj, plant.true_dq[:len(traj)].copy(), friction)


class EnginePlant(Plant):
    """The MuJoCo robot as a :class:`~snake_pin.loop.Plant`: the torque held over
    ``wheels.substeps`` engine steps, the sample read from the engine and its velocity
    from a :class:`DirtyDerivative` (what a robot's encoders give).

    The heading is unwrapped so that the filter and the reference see a continuous angle.
    A sample whose configuration is not finite, or whose body left the floor (its root
    above five wheel radii), ends the run as diverged. The engine's own velocities at the
    samples are kept in :attr:`true_dq`.

    Parameters
    ----------
    engine : EngineModel
        The MuJoCo robot.
    params : SnakeParams
        The controller's model of it (the trajectory's parameters).
    cutoff : float
        The velocity filter's cut-off [Hz].

    Attributes
    ----------
    true_dq
        (samples, n + 2): the engine's velocities on (x, y, yaw, phi) at each sample.
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
        """MuJoCo's clock: it adds the timestep once per engine step from 0 after the
        reset, so the sampling instants are these running sums exactly.

        Parameters
        ----------
        steps : int
            Control periods.

        Returns
        -------
        tuple of numpy.ndarray
            The calls' and the samples' times [s].
        """
        wheels = self.engine.wheels
        clock = np.cumsum(np.full(steps * wheels.substeps, wheels.timestep))
        samples = np.r_[0.0, clock[wheels.substeps - 1::wheels.substeps]]
        self.true_dq = np.zeros((steps + 1, self.nq))
        return samples[:steps], samples

    def reset(self, x0: np.ndarray, out: np.ndarray) -> None:
        """Put the robot at rest at the configuration of ``x0`` and read the first sample.

        Parameters
        ----------
        x0 : numpy.ndarray
            The initial state (its velocities are not used: the robot starts at rest).
        out : numpy.ndarray
            Where the first sample goes.
        """
        q0 = x0[:self.nq]
        self.engine.set_paper_configuration(q0)
        self._yaw, self._turns, self._sample = float(q0[2]), 0.0, 0
        self._read(out)

    def step(self, tau: np.ndarray, first: np.ndarray | None, out: np.ndarray,
             t: float) -> str:
        """Hold ``tau`` over the engine's substeps, then read the next sample.

        Parameters
        ----------
        tau : numpy.ndarray
            Joint torques (n - 1), finite; passive joints have no motor.
        first : None
            Unused (the engine computes its own accelerations).
        out : numpy.ndarray
            Where the new sample goes.
        t : float
            The time of the current sample [s].

        Returns
        -------
        str
            "the engine state left the floor" when it did, else "".
        """
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
