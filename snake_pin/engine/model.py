"""MuJoCo model of a snake on passive wheels, built from ``SnakeParams`` with MjSpec: the
links of :mod:`snake_pin.urdf` on a floor, a wheel pair per link, contacts and motors
(:ref:`derivation-engine`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any

import mujoco
import numpy as np

from .._options import documented, option
from .._validation import finite_number, integer
from ..exceptions import ParameterError
from ..params import SnakeParams
from ..urdf import EFFORT_LIMIT, RADIUS_RATIO

__all__ = ["JACOBIAN", "EngineModel", "WheelSpec", "build_engine_model"]

GRAVITY = 9.81
#: MuJoCo friction cones by name.
CONES = {"elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC, "pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL}
#: Constraint Jacobian of the solver: sparse, set explicitly (``mjJAC_AUTO`` picks dense
#: below nv = 60, though a wheel contact touches only the chain up to its link and its axle).
JACOBIAN = mujoco.mjtJacobian.mjJAC_SPARSE


@documented
@dataclass(frozen=True)
class WheelSpec:
    """A wheel pair per link (spheres on hinge axles) and the contact and solver settings."""

    radius: float = option(0.03, "wheel radius", unit="m", low=0.0, open_low=True)
    mass: float = option(0.03, "mass of each wheel", unit="kg", low=0.0, open_low=True)
    friction: float = option(1.0, "Coulomb coefficient wheel-floor (sliding sideways)",
                             low=0.0, open_low=True)
    rolling_damping: float = option(2e-5, "viscous damping of each wheel's axle (rolling "
                                    "resistance)", unit="N m s", low=0.0)
    timestep: float = option(5e-4, "engine step", unit="s", low=0.0, open_low=True)
    substeps: int = option(2, "engine steps per control period", low=1)
    max_bend: float = option(math.pi / 3, "joint angle up to which wheels of neighbouring "
                             "links must not overlap", unit="rad", low=0.0, open_low=True)
    cone: str = option("elliptic", "MuJoCo friction cone: elliptic (Coulomb) or pyramidal "
                       "(faster, heading-dependent)")

    def __post_init__(self) -> None:
        if self.cone not in CONES:
            raise ParameterError(f"cone must be one of {', '.join(CONES)}, got {self.cone!r}")
        for f in (f for f in fields(self) if isinstance(f.default, float)):
            object.__setattr__(self, f.name, finite_number(
                getattr(self, f.name), f.name, positive=f.metadata["open_low"],
                non_negative=True))
        object.__setattr__(self, "substeps", integer(self.substeps, "substeps", low=1))

    @property
    def control_dt(self) -> float:
        """Control period [s]."""
        return self.timestep * self.substeps


@dataclass
class EngineModel:
    """A compiled MuJoCo model with the index maps to paper coordinates (from
    :func:`build_engine_model`).

    Parameters
    ----------
    params, wheels : SnakeParams, WheelSpec
        The robot the model was built from, and its wheels and solver settings.
    model, data : mujoco.MjModel, mujoco.MjData
        The compiled model and its data (the engine's state).
    hinge_qpos, hinge_dof : numpy.ndarray of int, shape (n - 1,)
        qpos and DOF addresses of ``joint_1`` .. ``joint_{n-1}``.
    link_bodies : numpy.ndarray of int, shape (n,)
        Body ids of ``link_1`` .. ``link_n``.
    actuated : tuple of int
        1-based joints with a motor, in actuator order.
    body_masses, body_inertias : numpy.ndarray, shape (n,)
        Each link's mass [kg] and yaw inertia [kg m^2] without its wheels.
    wheel_offsets : numpy.ndarray, shape (n,)
        d_i: lateral distance of link i's wheel centres from its axis [m].
    meta : dict of str to float, optional
        Build facts carried into run summaries.
    """

    params: SnakeParams
    wheels: WheelSpec
    model: mujoco.MjModel
    data: mujoco.MjData
    hinge_qpos: np.ndarray
    hinge_dof: np.ndarray
    link_bodies: np.ndarray
    actuated: tuple[int, ...]
    body_masses: np.ndarray
    body_inertias: np.ndarray
    wheel_offsets: np.ndarray
    meta: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._chain_dofs = np.concatenate(([0, 1, 5], self.hinge_dof)).astype(int)
        self._motors = np.array(self.actuated, dtype=int) - 1  # tau entries, motor order

    @property
    def body_mass(self) -> float:
        """Mass of a link body without its wheels [kg]; equal links only (ParameterError)."""
        return self._same("body_masses")

    @property
    def body_inertia(self) -> float:
        """Yaw inertia of a link body without its wheels [kg m^2]; equal links only."""
        return self._same("body_inertias")

    @property
    def wheel_offset(self) -> float:
        """Lateral distance of the wheel centres from the link axis [m]; equal links only."""
        return self._same("wheel_offsets")

    def _same(self, key: str) -> float:
        """The one value of a per-link array (ParameterError when the links differ)."""
        values = getattr(self, key)
        if not np.all(values == values[0]):
            raise ParameterError(f"the links differ: read {key} (one value per link)")
        return float(values[0])

    @property
    def chain_dofs(self) -> np.ndarray:
        """DOF addresses of the free joint's (x, y, yaw) and of the hinges, in q's order (n + 2)."""
        return self._chain_dofs

    def paper_configuration(self) -> np.ndarray:
        """Return the paper configuration read from the engine's current state.

        Returns
        -------
        numpy.ndarray, shape (n + 2,)
            The paper's ``q``, theta_1 (the head's yaw) in ``(-pi, pi]``.
        """
        head, data = self.link_bodies[0], self.data
        frame = data.xmat[head]
        return np.r_[data.xpos[head][:2], math.atan2(frame[3], frame[0]),
                     data.qpos[self.hinge_qpos]]

    def set_paper_configuration(self, q: np.ndarray) -> None:
        """Place the snake flat on its wheels at q (at rest) and run forward kinematics.

        Parameters
        ----------
        q : numpy.ndarray, shape (n + 2,)
            Paper configuration (not validated).
        """
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:3] = (q[0], q[1], self.wheels.radius)
        self.data.qpos[3:7] = (math.cos(q[2] / 2), 0.0, 0.0, math.sin(q[2] / 2))
        self.data.qpos[self.hinge_qpos] = q[3:]
        mujoco.mj_forward(self.model, self.data)

    def chain_mass_matrix(self) -> np.ndarray:
        """Return MuJoCo's mass matrix on (x, y, yaw, phi) at the current state.

        Returns
        -------
        numpy.ndarray, shape (n + 2, n + 2)
            Rows and columns :attr:`chain_dofs` of the full mass matrix; equals
            Pinocchio's H of the same robot (the wheels' spin DOFs left out).
        """
        full = np.zeros((self.model.nv, self.model.nv))
        mujoco.mj_fullM(self.model, self.data, full)
        idx = self.chain_dofs
        return full[np.ix_(idx, idx)]

    def apply_torque(self, tau: np.ndarray) -> None:
        """Set the motors from the n - 1 joint torques (passive entries are ignored).

        Parameters
        ----------
        tau : numpy.ndarray, shape (n - 1,)
            Joint torques [N m], joint 1 first.
        """
        self.data.ctrl[:] = np.asarray(tau, dtype=float)[self._motors]


def _wheel_geometry(params: SnakeParams, wheels: WheelSpec) -> np.ndarray:
    """Lateral offsets d_i of the links' wheel centres, checked: a wheel pair shorter than its
    link, and neighbouring links' wheels 2 r apart at a ``max_bend`` bend."""
    lengths, centres = params.link_lengths, params.com_offsets
    offsets = RADIUS_RATIO * lengths + wheels.radius + 0.1 * wheels.radius
    for short in np.flatnonzero(2 * wheels.radius >= lengths):
        raise ParameterError(f"link {short + 1}: wheels of radius {wheels.radius} m are longer "
                             f"than the {lengths[short]:g} m link")
    c, s = math.cos(wheels.max_bend), math.sin(wheels.max_bend)
    bend = np.array([[c, -s], [s, c]])
    for i in range(params.n - 1):
        # link i's wheels in its frame, and link i + 1's bent by max_bend about joint i
        ours = np.array([[centres[i], -offsets[i]], [centres[i], offsets[i]]])
        theirs = np.array([[centres[i + 1], -offsets[i + 1]], [centres[i + 1], offsets[i + 1]]])
        neighbours = np.array([lengths[i], 0.0]) + theirs @ bend.T
        gap = min(np.linalg.norm(a - b) for a in ours for b in neighbours)
        if gap < 2 * wheels.radius:
            where, sizes = ("", f"{params.link_length}") if params.uniform else (
                f"links {i + 1} and {i + 2}: ", f"{lengths[i]:g} and {lengths[i + 1]:g}")
            raise ParameterError(
                f"{where}wheels of radius {wheels.radius} m overlap on {sizes} m links "
                f"(closest wheel centres {gap:.3f} m apart at a "
                f"{math.degrees(wheels.max_bend):.0f} degree bend)")
    return offsets


def _split(params: SnakeParams, wheels: WheelSpec,
           offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(m_body,i, J_body,i, a wheel's inertia): what each link keeps beside its wheels."""
    body_masses = params.masses - 2 * wheels.mass
    wheel_inertia = 0.4 * wheels.mass * wheels.radius**2  # solid sphere
    body_inertias = params.inertias - 2 * (wheels.mass * offsets**2 + wheel_inertia)
    for i in np.flatnonzero((body_masses <= 0) | (body_inertias <= 0)):
        where = "" if params.uniform else f"link {i + 1}: "
        raise ParameterError(
            f"{where}wheels of {wheels.mass} kg leave no mass or inertia for the link "
            f"(m_body = {body_masses[i]:.3g} kg, J_body = {body_inertias[i]:.3g} kg m^2)")
    return body_masses, body_inertias, wheel_inertia


def _set(item: Any, **values: Any) -> Any:
    """``item`` with the attributes ``values`` set (an MjSpec element)."""
    for key, value in values.items():
        setattr(item, key, value)
    return item


def build_engine_model(params: SnakeParams | None = None,
                       wheels: WheelSpec | None = None) -> EngineModel:
    """Compile the MuJoCo model of ``params`` (default: the ``engine`` preset) on wheels.

    Every link gets its own wheel pair, sized to it (:ref:`derivation-engine`).

    Parameters
    ----------
    params, wheels : SnakeParams or WheelSpec or None, optional
        The robot (default :meth:`SnakeParams.engine`) and its wheels (default ``WheelSpec()``).

    Returns
    -------
    EngineModel
        The compiled model with its index maps, at MuJoCo's default state.

    Raises
    ------
    ParameterError
        The wheels overlap, are longer than a link, or leave a link no mass or inertia.
    """
    params = params or SnakeParams.engine()
    wheels = wheels or WheelSpec()
    offsets = _wheel_geometry(params, wheels)
    body_masses, body_inertias, wheel_inertia = _split(params, wheels, offsets)

    spec = _set(mujoco.MjSpec(), modelname=f"snake_{params.name}_wheels")
    spec.compiler.autolimits = True
    _set(spec.option, timestep=wheels.timestep, gravity=[0.0, 0.0, -GRAVITY],
         integrator=mujoco.mjtIntegrator.mjINT_IMPLICITFAST, cone=CONES[wheels.cone],
         impratio=10.0, jacobian=JACOBIAN)  # not AUTO: it picks dense here (see JACOBIAN)
    _set(spec.worldbody.add_geom(), name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE,
         size=[0.0, 0.0, 0.05], friction=[wheels.friction, 0.005, 1e-4],
         rgba=[0.8, 0.8, 0.8, 1.0])
    hinge_z = {"type": mujoco.mjtJoint.mjJNT_HINGE, "axis": [0.0, 0.0, 1.0]}
    lengths, centres = params.link_lengths, params.com_offsets
    parent = spec.worldbody
    for i in range(1, params.n + 1):
        length, centre, offset = float(lengths[i - 1]), float(centres[i - 1]), offsets[i - 1]
        body_mass, body_inertia = float(body_masses[i - 1]), float(body_inertias[i - 1])
        radius = RADIUS_RATIO * length
        # roll inertia of a rod of the capsule's radius, capped so that MuJoCo's triangle
        # inequality holds for slender links with a small yaw inertia (it is not planar)
        roll = min(0.5 * body_mass * radius**2, body_inertia)
        body = _set(parent.add_body(), name=f"link_{i}",
                    pos=[0.0, 0.0, wheels.radius] if i == 1 else [float(lengths[i - 2]), 0.0, 0.0],
                    mass=body_mass, ipos=[centre, 0.0, 0.0], iquat=[1.0, 0.0, 0.0, 0.0],
                    inertia=[roll, body_inertia, body_inertia], explicitinertial=True)
        if i == 1:
            body.add_freejoint().name = "base"
        else:
            _set(body.add_joint(), name=f"joint_{i - 1}", **hinge_z)
        _set(body.add_geom(), name=f"link_{i}_body", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
             fromto=[0.0, 0.0, 0.0, length, 0.0, 0.0], size=[radius, 0.0, 0.0], contype=0,
             conaffinity=0, mass=0.0,
             rgba=[0.85, 0.33, 0.10, 1.0] if i == 1 else [0.13, 0.55, 0.13, 1.0])
        for side, sign in (("left", 1.0), ("right", -1.0)):
            # ipos and iquat given: MjSpec does not default them with explicit inertia
            wheel = _set(body.add_body(), name=f"link_{i}_wheel_{side}",
                         pos=[centre, sign * float(offset), 0.0], mass=wheels.mass,
                         ipos=[0.0, 0.0, 0.0], iquat=[1.0, 0.0, 0.0, 0.0],
                         inertia=[wheel_inertia] * 3, explicitinertial=True)
            _set(wheel.add_joint(), name=f"link_{i}_axle_{side}",
                 type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0.0, 1.0, 0.0],
                 damping=[wheels.rolling_damping, 0.0, 0.0])
            _set(wheel.add_geom(), name=f"link_{i}_tyre_{side}",
                 type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[wheels.radius, 0.0, 0.0], mass=0.0,
                 friction=[wheels.friction, 0.005, 1e-4], condim=3, solref=[0.005, 1.0],
                 rgba=[0.15, 0.15, 0.15, 1.0])
        parent = body
    for k in params.actuated:
        _set(spec.add_actuator(), name=f"motor_{k}", target=f"joint_{k}",
             trntype=mujoco.mjtTrn.mjTRN_JOINT, gear=[1.0, 0, 0, 0, 0, 0],
             ctrlrange=[-EFFORT_LIMIT, EFFORT_LIMIT])
    model = spec.compile()
    data = mujoco.MjData(model)
    joint_ids = [model.joint(f"joint_{k}").id for k in range(1, params.n)]
    engine = EngineModel(
        params=params, wheels=wheels, model=model, data=data,
        hinge_qpos=np.array([model.jnt_qposadr[j] for j in joint_ids], dtype=int),
        hinge_dof=np.array([model.jnt_dofadr[j] for j in joint_ids], dtype=int),
        link_bodies=np.array([model.body(f"link_{i}").id for i in range(1, params.n + 1)]),
        actuated=params.actuated, body_masses=body_masses, body_inertias=body_inertias,
        wheel_offsets=offsets)
    engine.set_paper_configuration(np.zeros(params.n + 2))
    return engine
