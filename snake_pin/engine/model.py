"""MuJoCo model of a snake on passive wheels, built from ``SnakeParams`` with MjSpec.

One source of truth: the link frames, lengths, masses and inertias are those of
:mod:`snake_pin.urdf` / ``SnakeParams``; this module only adds what the engine needs on
top (a floor, gravity, a wheel pair per link, contacts, motors). Layout:

* the head link is a free body whose frame is the head point (as in Pinocchio);
  link i + 1 hangs from link i by a hinge about z at x = 2l (``joint_i``);
* each link carries two free-spinning wheels at its CM, one on each side, on axles along
  the link's y: they roll along the link and must slide sideways, so the floor's Coulomb
  friction is anisotropic as in the paper's V-REP robot;
* the link's mass m and yaw inertia J are shared between the link body and its wheels
  (``m = m_body + 2 m_w``, ``J = J_body + 2 (m_w d^2 + I_w)``), so the chain's mass matrix
  equals Pinocchio's H of the same ``SnakeParams``;
* every active joint has a motor (``motor_i``); passive joints have none;
* only wheels touch the floor; link bodies do not collide, wheels of neighbouring links
  do (beyond about 80 degrees of bend with the default wheels), as on a real robot.

Solver settings: 1 ms control period split into ``substeps`` engine steps (default 2,
0.5 ms), implicit-fast integration, elliptic friction cones with impratio 10 (stiffer,
less creeping tangential constraints than the pyramidal default; coasting then gives the
Coulomb-equivalent c_y to 0.1 %), condim 3 wheel
contacts (sliding friction only; rolling about the axle is the hinge), soft contacts
with solref (0.005, 1): critically damped at 5 ms, well above the step.

``WheelSpec(cone="pyramidal")`` trades fidelity for speed: MuJoCo's step is about three
times cheaper, but the pyramid's sideways friction is weaker (coasting gives c_y 8 % above
the Coulomb equivalent) and the tracking with a passive joint is worse (see the closing
notes of the engine issue and ``scripts/bench.py --only engine``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from .._validation import finite_number
from ..exceptions import ParameterError
from ..params import SnakeParams
from ..urdf import EFFORT_LIMIT, RADIUS_RATIO

__all__ = ["EngineModel", "WheelSpec", "build_engine_model"]

GRAVITY = 9.81
#: MuJoCo friction cones by name.
CONES = {"elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC, "pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL}


@dataclass(frozen=True)
class WheelSpec:
    """A wheel pair per link and the contact and solver settings.

    Parameters
    ----------
    radius, mass
        Wheel radius [m] and mass [kg] (each); wheels are spheres on hinge axles.
    friction
        Coulomb coefficient wheel-floor (sliding sideways).
    rolling_damping
        Viscous damping of each wheel's axle [N m s] (rolling resistance).
    timestep
        Engine step [s]; the controller runs every ``substeps`` steps.
    substeps
        Engine steps per 1 ms control period.
    max_bend
        Joint angle [rad] up to which wheels of neighbouring links must not overlap.
    cone
        MuJoCo friction cone, ``"elliptic"`` (default) or ``"pyramidal"`` (faster).
    """

    radius: float = 0.03
    mass: float = 0.03
    friction: float = 1.0
    rolling_damping: float = 2e-5
    timestep: float = 5e-4
    substeps: int = 2
    max_bend: float = math.pi / 3
    cone: str = "elliptic"

    def __post_init__(self) -> None:
        if self.cone not in CONES:
            raise ParameterError(f"cone must be one of {', '.join(CONES)}, got {self.cone!r}")
        for name in ("radius", "mass", "friction", "timestep", "max_bend"):
            object.__setattr__(self, name, finite_number(getattr(self, name), name,
                                                         positive=True))
        object.__setattr__(self, "rolling_damping",
                           finite_number(self.rolling_damping, "rolling_damping",
                                         non_negative=True))
        if isinstance(self.substeps, bool) or int(self.substeps) != self.substeps \
                or self.substeps < 1:
            raise ParameterError(f"substeps must be a positive integer, got {self.substeps}")

    @property
    def control_dt(self) -> float:
        """Control period [s]."""
        return self.timestep * self.substeps


@dataclass
class EngineModel:
    """A compiled MuJoCo model with the index maps to paper coordinates."""

    params: SnakeParams
    wheels: WheelSpec
    model: mujoco.MjModel
    data: mujoco.MjData
    hinge_qpos: np.ndarray  # qpos addresses of joint_1..joint_{n-1}
    hinge_dof: np.ndarray  # dof addresses of the same
    link_bodies: np.ndarray  # body ids of link_1..link_n
    actuated: tuple[int, ...]  # 1-based joints with a motor, in actuator order
    body_mass: float
    body_inertia: float
    wheel_offset: float
    meta: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._chain_dofs = np.concatenate(([0, 1, 5], self.hinge_dof)).astype(int)

    @property
    def chain_dofs(self) -> np.ndarray:
        """DOF addresses of (x, y, yaw) of the free joint and the hinges: paper's q order."""
        return self._chain_dofs

    def paper_configuration(self) -> np.ndarray:
        """q = [x_h, y_h, theta_1, phi] read from the engine (yaw in (-pi, pi])."""
        head = self.data.xmat[self.link_bodies[0]].reshape(3, 3)
        pos = self.data.xpos[self.link_bodies[0]]
        yaw = math.atan2(head[1, 0], head[0, 0])
        out = np.empty(len(self.hinge_qpos) + 3)
        out[0], out[1], out[2] = pos[0], pos[1], yaw
        out[3:] = self.data.qpos[self.hinge_qpos]
        return out

    def set_paper_configuration(self, q: np.ndarray) -> None:
        """Place the snake flat on its wheels at q (at rest) and run forward kinematics."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:3] = (q[0], q[1], self.wheels.radius)
        self.data.qpos[3:7] = (math.cos(q[2] / 2), 0.0, 0.0, math.sin(q[2] / 2))
        self.data.qpos[self.hinge_qpos] = q[3:]
        mujoco.mj_forward(self.model, self.data)

    def chain_mass_matrix(self) -> np.ndarray:
        """MuJoCo's mass matrix on (x, y, yaw, phi) at the current state."""
        full = np.zeros((self.model.nv, self.model.nv))
        mujoco.mj_fullM(self.model, self.data, full)
        idx = self.chain_dofs
        return full[np.ix_(idx, idx)]

    def apply_torque(self, tau: np.ndarray) -> None:
        """Set the motors from the n - 1 joint torques (passive entries are ignored)."""
        self.data.ctrl[:] = [tau[k - 1] for k in self.actuated]


def _wheel_geometry(params: SnakeParams, wheels: WheelSpec) -> float:
    """Lateral offset of the wheel centres, after checking wheels cannot overlap."""
    half = params.half_length
    link_radius = RADIUS_RATIO * params.link_length
    offset = link_radius + wheels.radius + 0.1 * wheels.radius
    # Neighbouring links bent by max_bend: the inner wheels come closest.
    wheels_i = np.array([[half, -offset], [half, offset]])  # wheels of link i, its frame
    joint = np.array([2 * half, 0.0])
    c, s = math.cos(wheels.max_bend), math.sin(wheels.max_bend)
    neighbours = joint + wheels_i @ np.array([[c, -s], [s, c]]).T
    gap = min(np.linalg.norm(a - b) for a in wheels_i for b in neighbours)
    if gap < 2 * wheels.radius or wheels.radius >= half:
        raise ParameterError(
            f"wheels of radius {wheels.radius} m overlap on {params.link_length} m links "
            f"(closest wheel centres {gap:.3f} m apart at a {math.degrees(wheels.max_bend):.0f}"
            " degree bend)")
    return offset


def build_engine_model(params: SnakeParams | None = None,
                       wheels: WheelSpec | None = None) -> EngineModel:
    """Compile the MuJoCo model of ``params`` (default: the ``engine`` preset) on wheels."""
    params = params or SnakeParams.engine()
    wheels = wheels or WheelSpec()
    offset = _wheel_geometry(params, wheels)
    body_mass = params.mass - 2 * wheels.mass
    wheel_inertia = 0.4 * wheels.mass * wheels.radius**2  # solid sphere
    body_inertia = params.inertia - 2 * (wheels.mass * offset**2 + wheel_inertia)
    if body_mass <= 0 or body_inertia <= 0:
        raise ParameterError(
            f"wheels of {wheels.mass} kg leave no mass or inertia for the link "
            f"(m_body = {body_mass:.3g} kg, J_body = {body_inertia:.3g} kg m^2)")

    spec = mujoco.MjSpec()
    spec.modelname = f"snake_{params.name}_wheels"
    spec.compiler.autolimits = True
    spec.option.timestep = wheels.timestep
    spec.option.gravity = [0.0, 0.0, -GRAVITY]
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = CONES[wheels.cone]
    spec.option.impratio = 10.0
    floor = spec.worldbody.add_geom()
    floor.name = "floor"
    floor.type = mujoco.mjtGeom.mjGEOM_PLANE
    floor.size = [0.0, 0.0, 0.05]
    floor.friction = [wheels.friction, 0.005, 1e-4]
    floor.rgba = [0.8, 0.8, 0.8, 1.0]

    half = params.half_length
    radius = RADIUS_RATIO * params.link_length
    parent = spec.worldbody
    for i in range(1, params.n + 1):
        body = parent.add_body()
        body.name = f"link_{i}"
        body.pos = [0.0, 0.0, wheels.radius] if i == 1 else [params.link_length, 0.0, 0.0]
        body.mass = body_mass
        body.ipos = [half, 0.0, 0.0]
        body.iquat = [1.0, 0.0, 0.0, 0.0]
        body.inertia = [0.5 * body_mass * radius**2, body_inertia, body_inertia]
        body.explicitinertial = True
        if i == 1:
            free = body.add_freejoint()
            free.name = "base"
        else:
            hinge = body.add_joint()
            hinge.name = f"joint_{i - 1}"
            hinge.type = mujoco.mjtJoint.mjJNT_HINGE
            hinge.axis = [0.0, 0.0, 1.0]
        shape = body.add_geom()
        shape.name = f"link_{i}_body"
        shape.type = mujoco.mjtGeom.mjGEOM_CAPSULE
        shape.fromto = [0.0, 0.0, 0.0, params.link_length, 0.0, 0.0]
        shape.size = [radius, 0.0, 0.0]
        shape.contype = 0
        shape.conaffinity = 0
        shape.mass = 0.0
        shape.rgba = [0.85, 0.33, 0.10, 1.0] if i == 1 else [0.13, 0.55, 0.13, 1.0]
        for side, sign in (("left", 1.0), ("right", -1.0)):
            wheel = body.add_body()
            wheel.name = f"link_{i}_wheel_{side}"
            wheel.pos = [half, sign * offset, 0.0]
            wheel.mass = wheels.mass
            wheel.ipos = [0.0, 0.0, 0.0]  # MjSpec does not default these with explicit inertia
            wheel.iquat = [1.0, 0.0, 0.0, 0.0]
            wheel.inertia = [wheel_inertia] * 3
            wheel.explicitinertial = True
            axle = wheel.add_joint()
            axle.name = f"link_{i}_axle_{side}"
            axle.type = mujoco.mjtJoint.mjJNT_HINGE
            axle.axis = [0.0, 1.0, 0.0]
            axle.damping = [wheels.rolling_damping, 0.0, 0.0]
            tyre = wheel.add_geom()
            tyre.name = f"link_{i}_tyre_{side}"
            tyre.type = mujoco.mjtGeom.mjGEOM_SPHERE
            tyre.size = [wheels.radius, 0.0, 0.0]
            tyre.mass = 0.0
            tyre.friction = [wheels.friction, 0.005, 1e-4]
            tyre.condim = 3
            tyre.solref = [0.005, 1.0]
            tyre.rgba = [0.15, 0.15, 0.15, 1.0]
        parent = body
    for k in params.actuated:
        motor = spec.add_actuator()
        motor.name = f"motor_{k}"
        motor.target = f"joint_{k}"
        motor.trntype = mujoco.mjtTrn.mjTRN_JOINT
        motor.gear = [1.0, 0, 0, 0, 0, 0]
        motor.ctrlrange = [-EFFORT_LIMIT, EFFORT_LIMIT]
    model = spec.compile()
    data = mujoco.MjData(model)
    joint_ids = [model.joint(f"joint_{k}").id for k in range(1, params.n)]
    engine = EngineModel(
        params=params, wheels=wheels, model=model, data=data,
        hinge_qpos=np.array([model.jnt_qposadr[j] for j in joint_ids], dtype=int),
        hinge_dof=np.array([model.jnt_dofadr[j] for j in joint_ids], dtype=int),
        link_bodies=np.array([model.body(f"link_{i}").id for i in range(1, params.n + 1)]),
        actuated=params.actuated, body_mass=body_mass, body_inertia=body_inertia,
        wheel_offset=offset)
    engine.set_paper_configuration(np.zeros(params.n + 2))
    return engine
