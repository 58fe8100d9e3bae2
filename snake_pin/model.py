"""The Pinocchio model of a snake in the paper's coordinates q = [x_h, y_h, theta_1, phi].

The URDF's tree (:mod:`snake_pin.urdf`) hangs from three single-DoF root joints (:ref:`concepts`),
so nq = nv = n + 2; the equation of motion is eq. (20), ``H(q) q'' + h(q, q') = E tau``
with friction in h (:mod:`snake_pin.friction`). As Pinocchio's Model/Data, the unchecked
``calc_*`` methods work on a caller's :class:`SnakeData`; the checked methods validate
their inputs and call them.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import pinocchio as pin

from ._symmetric import crba_mirrors, symmetric_from_upper, whole
from ._validation import as_vector, check_params, instance
from .exceptions import ConfigurationError
from .friction import FrictionModel
from .params import SnakeParams
from .urdf import urdf_string

__all__ = ["BASE_JOINTS", "DynamicsDerivatives", "Snake", "SnakeData"]

#: Names of the three root joints, in order: they carry x_h, y_h and theta_1.
BASE_JOINTS = ("base_x", "base_y", "base_yaw")

_WORLD = pin.Convention.WORLD
_ABA = pin.aba
_NONLINEAR_EFFECTS = pin.nonLinearEffects
# read once: numpy's module __getattr__ keeps Python from caching ``np.<name>`` lookups
_SUBTRACT = np.subtract


def paper_model(params: SnakeParams) -> pin.Model:
    """The robot's Pinocchio model in paper coordinates (the URDF on a PX -> PY -> RZ chain):
    ``base_yaw`` carries link 1, joint i + 3 is the paper's joint i (passive: zero effort)."""
    check_params(params)
    fixed = pin.buildModelFromXML(urdf_string(params, floating_base=False))
    model = pin.Model()
    model.name = fixed.name
    parent = 0
    joint_frames = {}
    for name, joint in zip(BASE_JOINTS, (pin.JointModelPX(), pin.JointModelPY(),
                                         pin.JointModelRZ()), strict=True):
        parent = model.addJoint(parent, joint, pin.SE3.Identity(), name)
        joint_frames[parent] = model.addJointFrame(parent)
    # Pinocchio puts the fixed root link's inertia on the universe joint
    model.appendBodyToJoint(parent, fixed.inertias[0], pin.SE3.Identity())
    mapping = {0: parent}
    for j in range(1, fixed.njoints):
        mapping[j] = model.addJoint(mapping[fixed.parents[j]], fixed.joints[j],
                                    fixed.jointPlacements[j], fixed.names[j])
        joint_frames[mapping[j]] = model.addJointFrame(mapping[j])
        model.appendBodyToJoint(mapping[j], fixed.inertias[j], pin.SE3.Identity())
    for frame in fixed.frames:
        if frame.type == pin.FrameType.BODY:
            joint = mapping[frame.parentJoint]
            model.addBodyFrame(frame.name, joint, frame.placement, joint_frames[joint])
    effort = np.full(model.nv, np.inf)
    effort[3:] = [0.0 if k in params.passive else 10.0 for k in range(1, params.n)]
    model.effortLimit = effort
    model.gravity = pin.Motion.Zero()  # planar: gravity is normal to the plane
    return model


@dataclass(frozen=True)
class DynamicsDerivatives:
    """Partial derivatives of q'' = H^-1 (E tau - h(q, q')) (friction included).

    Parameters
    ----------
    ddq_dq, ddq_dv, ddq_dtau, ddq : numpy.ndarray
        ``d q''/d q``, ``d q''/d q'``, ``d q''/d tau = H^-1 E`` and ``q''`` itself.
    """

    ddq_dq: np.ndarray
    ddq_dv: np.ndarray
    ddq_dtau: np.ndarray
    ddq: np.ndarray


class Snake:
    """Rigid-body model of an n-link planar snake with viscous friction (Section II).

    Checked methods raise :class:`~snake_pin.exceptions.ConfigurationError` for an input
    that is not a finite vector of its length: q, dq (n + 2), tau (n - 1), x (2(n + 2)).

    Parameters
    ----------
    params : SnakeParams or None, optional
        Robot parameters; defaults to the Table 1 robot.

    Raises
    ------
    ConfigurationError
        ``params`` is not a SnakeParams.

    Attributes
    ----------
    model, data, nq, nv
        Pinocchio model (joint layout: ``paper_model``), its workspace, nq = nv = n + 2.
    link_joints
        Pinocchio joint index carrying each link (length n, head first).
    """

    def __init__(self, params: SnakeParams | None = None) -> None:
        if params is None:
            params = SnakeParams.table1()
        if not isinstance(params, SnakeParams):
            raise ConfigurationError(
                f"Snake needs SnakeParams (or use Snake.from_urdf for a URDF), "
                f"got {type(params).__name__}")
        self.params = params
        self.n = params.n
        self.model: pin.Model = paper_model(params)
        self.data: pin.Data = self.model.createData()
        self.nq = self.model.nq
        self.nv = self.model.nv
        self.link_joints = np.arange(3, 3 + self.n)
        self.friction = FrictionModel(self.params, self.model)
        self._actuated = np.array([k - 1 for k in self.params.actuated], dtype=int)
        # 1 on actuated joints, 0 on passive ones (None: all actuated, skip the product)
        self._mask = (np.isin(np.arange(self.n - 1), self._actuated).astype(float)
                      if self.params.passive else None)

    def __repr__(self) -> str:
        return f"Snake({self.params!r})"

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without its own buffers (made again on use)."""
        state = self.__dict__.copy()
        state.pop("_data", None)
        return state

    @cached_property
    def _data(self) -> SnakeData:
        """The buffers of the checked methods, on :attr:`data`."""
        return SnakeData(self, self.data)

    @cached_property
    def binding_mirrors(self) -> bool:
        """Whether Pinocchio's bindings return H and H^-1 whole (checked once)."""
        return _binding_mirrors(self.model)

    @classmethod
    def from_urdf(cls, path: str | os.PathLike[str],
                  friction: Mapping[str, Any] | None = None) -> Snake:
        """The snake described by any URDF of a planar serial chain of revolute z joints.

        Parameters
        ----------
        path
            The URDF file (generated by snake_pin or not).
        friction
            ``c_x``, ``c_y``, ``c_theta`` (as :func:`~snake_pin.robot_file.read_urdf`).

        Raises
        ------
        RobotFileError
            The file is missing or not a planar serial chain (naming the element at fault).
        """
        from .robot_file import read_urdf

        return cls(read_urdf(path, friction=friction))

    # ------------------------------------------------------------ validation
    def check_q(self, q: object, name: str = "q") -> np.ndarray:
        """``q`` (configuration) as n + 2 finite floats, or ConfigurationError.

        Parameters
        ----------
        q, name : array_like, str
            The value to check, and its name in the error message.

        Returns
        -------
        numpy.ndarray
            ``q`` as floats.
        """
        return _vector(q, self.nq, name)

    def check_dq(self, dq: object, name: str = "dq") -> np.ndarray:
        """``dq`` (velocity) as n + 2 finite floats, or ConfigurationError.

        Parameters
        ----------
        dq, name : array_like, str
            The value to check, and its name in the error message.

        Returns
        -------
        numpy.ndarray
            ``dq`` as floats.
        """
        return _vector(dq, self.nv, name)

    def check_tau(self, tau: object, name: str = "tau") -> np.ndarray:
        """``tau`` (joint torques, never broadcast) as n - 1 finite floats, or ConfigurationError.

        Parameters
        ----------
        tau, name : array_like, str
            The value to check, and its name in the error message.

        Returns
        -------
        numpy.ndarray
            ``tau`` as floats.
        """
        return _vector(tau, self.n - 1, name)

    def check_state(self, x: object, name: str = "x") -> np.ndarray:
        """``x`` (the stacked state [q, dq]) as 2(n + 2) finite floats, or ConfigurationError.

        Parameters
        ----------
        x, name : array_like, str
            The value to check, and its name in the error message.

        Returns
        -------
        numpy.ndarray
            ``x`` as floats.
        """
        return _vector(x, self.nq + self.nv, name)

    # -------------------------------------------------------------- dynamics
    @cached_property
    def actuation_matrix(self) -> np.ndarray:
        """E of eq. (18), (n + 2) x (n - 1); columns of passive joints are zero."""
        e_matrix = np.zeros((self.nv, self.n - 1))
        e_matrix[3 + self._actuated, self._actuated] = 1.0
        return e_matrix

    def create_data(self) -> SnakeData:
        """New buffers for the unchecked ``calc_*`` methods (see :class:`SnakeData`).

        Returns
        -------
        SnakeData
            Buffers made once, for one caller (a law, a plant).
        """
        return SnakeData(self)

    def calc_acceleration(self, data: SnakeData, q: np.ndarray, v: np.ndarray,
                          torque: np.ndarray) -> np.ndarray:
        """q'' of eq. (20) under ``E tau``: ``ABA(q, v, E tau + Q(q, v))`` (unchecked hot path).

        Parameters
        ----------
        data : SnakeData
            Buffers of this robot.
        q, v, torque : numpy.ndarray
            Configuration, velocity and ``E tau``, length n + 2 each.

        Returns
        -------
        numpy.ndarray
            ``q''``, a new array.
        """
        model, pin_data, calc_force, friction = data.dynamics
        return _ABA(model, pin_data, q, v, calc_force(friction, q, v, torque), _WORLD)

    def calc_affine(self, data: SnakeData, q: np.ndarray,
                    v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(b, H^-1)``: q'' at zero torque (``-H^-1 h``) and the inverse inertia (unchecked).

        Parameters
        ----------
        data : SnakeData
            Buffers of this robot.
        q, v : numpy.ndarray
            Configuration and velocity, length n + 2 each.

        Returns
        -------
        tuple of numpy.ndarray
            ``b`` (new) and ``H^-1`` whole (``data.inverse_mass``, until the next call).
        """
        model, pin_data, calc_force, friction = data.dynamics
        b = _ABA(model, pin_data, q, v, calc_force(friction, q, v), _WORLD)
        data.minverse(model, pin_data)
        return b, data.inverse_mass

    def calc_mass_and_bias(self, data: SnakeData, q: np.ndarray,
                           v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(H, h)`` of eq. (20): H by CRBA and h = Coriolis/centrifugal - Q (unchecked).

        Parameters
        ----------
        data : SnakeData
            Buffers of this robot.
        q, v : numpy.ndarray
            Configuration and velocity, length n + 2 each.

        Returns
        -------
        tuple of numpy.ndarray
            ``H`` whole (``data.mass``) and ``h`` (``data.bias``), until the next call.
        """
        model, pin_data, calc_force, friction = data.dynamics
        force = calc_force(friction, q, v)
        data.crba(model, pin_data, q, _WORLD)
        bias = data.bias
        _SUBTRACT(_NONLINEAR_EFFECTS(model, pin_data, q, v), force, bias)
        return data.mass, bias

    def calc_torque(self, data: SnakeData, tau: np.ndarray) -> np.ndarray:
        """``E tau`` into ``data.torque`` (passive joints' entries 0; unchecked).

        Parameters
        ----------
        data : SnakeData
            Buffers of this robot.
        tau : numpy.ndarray
            Joint torques [N m], length n - 1.

        Returns
        -------
        numpy.ndarray
            ``data.torque`` (length n + 2).
        """
        torque = data.torque
        if self._mask is None:
            torque[3:] = tau
        else:
            np.multiply(tau, self._mask, torque[3:])
        return torque

    def inertia_matrix(self, q: np.ndarray) -> np.ndarray:
        """H(q) of eq. (19) by CRBA, symmetric (n + 2) x (n + 2).

        Parameters
        ----------
        q : numpy.ndarray
            Configuration (n + 2, paper coordinates).

        Returns
        -------
        numpy.ndarray
            ``H(q)``, shape (n + 2, n + 2).
        """
        q = self.check_q(q)
        # CRBA fills the upper triangle; the WORLD convention is 2x faster at n = 100
        return symmetric_from_upper(pin.crba(self.model, self.data, q, _WORLD))

    def inverse_inertia_matrix(self, q: np.ndarray) -> np.ndarray:
        """``H(q)^-1`` by Pinocchio's computeMinverse (symmetric).

        Parameters
        ----------
        q : numpy.ndarray
            Configuration (n + 2, paper coordinates).

        Returns
        -------
        numpy.ndarray
            ``H(q)^-1``, shape (n + 2, n + 2).
        """
        q = self.check_q(q)
        return symmetric_from_upper(pin.computeMinverse(self.model, self.data, q))

    def coriolis(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Coriolis/centrifugal term ``W diag(J dq) J dq`` of eq. (18) by RNEA.

        Parameters
        ----------
        q, dq : numpy.ndarray
            Configuration and velocity ``q'`` (n + 2 each, paper coordinates).

        Returns
        -------
        numpy.ndarray
            The term, length n + 2 [N, N, N m, N m].
        """
        q, dq = self.check_q(q), self.check_dq(dq)
        return pin.nonLinearEffects(self.model, self.data, q, dq).copy()

    def friction_force(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Generalised viscous friction force ``-C(q) dq`` (eqs. 11-13).

        Parameters
        ----------
        q, dq : numpy.ndarray
            Configuration and velocity ``q'`` (n + 2 each, paper coordinates).

        Returns
        -------
        numpy.ndarray
            The force, length n + 2 [N, N, N m, N m].
        """
        q, dq = self.check_q(q), self.check_dq(dq)
        return self.friction.calc_force(self._data.friction, q, dq).copy()

    def bias(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """``h(q, dq)`` of eq. (20): Coriolis/centrifugal plus friction, ``H q'' + h = E tau``.

        Parameters
        ----------
        q, dq : numpy.ndarray
            Configuration and velocity ``q'`` (n + 2 each, paper coordinates).

        Returns
        -------
        numpy.ndarray
            ``h``, length n + 2.
        """
        q, dq = self.check_q(q), self.check_dq(dq)
        return self.calc_mass_and_bias(self._data, q, dq)[1].copy()

    def generalized_torque(self, tau: np.ndarray) -> np.ndarray:
        """``E tau`` with passive joints' entries dropped (their torque is zero).

        Parameters
        ----------
        tau : numpy.ndarray
            Joint torques [N m] (n - 1).

        Returns
        -------
        numpy.ndarray
            The generalised torque, length n + 2 (zero on x, y, theta_1).
        """
        return self.calc_torque(self._data, self.check_tau(tau)).copy()

    def forward_dynamics(self, q: np.ndarray, dq: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """``q'' = H^-1 (E tau - h)`` by ABA; torques on passive joints are ignored.

        Parameters
        ----------
        q, dq, tau : numpy.ndarray
            Configuration and velocity (n + 2 each), joint torques [N m] (n - 1).

        Returns
        -------
        numpy.ndarray
            ``q''``, length n + 2.
        """
        q, dq, tau = self.check_q(q), self.check_dq(dq), self.check_tau(tau)
        data = self._data
        return self.calc_acceleration(data, q, dq, self.calc_torque(data, tau))

    def dynamics_derivatives(self, q: np.ndarray, dq: np.ndarray,
                             tau: np.ndarray) -> DynamicsDerivatives:
        """Analytical derivatives of q'' = H^-1 (E tau - h), friction included.

        ``d q''/d q = ABA_q + H^-1 dQ/dq`` (likewise for q') and ``d q''/d tau = H^-1 E``:
        ``pin.computeABADerivatives`` and :meth:`~snake_pin.friction.FrictionModel.derivatives`.

        Parameters
        ----------
        q, dq, tau : numpy.ndarray
            Configuration and velocity (n + 2 each), joint torques [N m] (n - 1).

        Returns
        -------
        DynamicsDerivatives
            The three Jacobians and ``q''`` itself.
        """
        q, dq, tau = self.check_q(q), self.check_dq(dq), self.check_tau(tau)
        force, dforce_dq, dforce_dv = self.friction.derivatives(q, dq)
        generalized = force + self.calc_torque(self._data, tau)
        model, data = self.model, self.data
        ddq_dq, ddq_dv, minv = pin.computeABADerivatives(model, data, q, dq, generalized)
        minv = symmetric_from_upper(minv)
        return DynamicsDerivatives(ddq_dq=ddq_dq + minv @ dforce_dq,
                                   ddq_dv=ddq_dv + minv @ dforce_dv,
                                   ddq_dtau=minv @ self.actuation_matrix,
                                   ddq=data.ddq.copy())

    def state_derivative(self, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """q'' for the stacked state x = [q, dq] (as :meth:`forward_dynamics`).

        Parameters
        ----------
        x, tau : numpy.ndarray
            State ``[q, dq]`` (2(n + 2)) and joint torques [N m] (n - 1).

        Returns
        -------
        numpy.ndarray
            ``q''``, length n + 2.
        """
        x, tau = self.check_state(x), self.check_tau(tau)
        data = self._data
        return self.calc_acceleration(data, x[:self.nq], x[self.nq:],
                                      self.calc_torque(data, tau))

    def kinetic_energy(self, q: np.ndarray, dq: np.ndarray) -> float:
        """T of eq. (8).

        Parameters
        ----------
        q, dq : numpy.ndarray
            Configuration and velocity ``q'`` (n + 2 each, paper coordinates).

        Returns
        -------
        float
            The kinetic energy [J].
        """
        q, dq = self.check_q(q), self.check_dq(dq)
        return float(pin.computeKineticEnergy(self.model, self.data, q, dq))

    # ------------------------------------------------------------- geometry
    def head_pose(self, q: np.ndarray) -> np.ndarray:
        """``w = [x_h, y_h, theta_1]``: the head point and the head link's orientation.

        Parameters
        ----------
        q : numpy.ndarray
            Configuration (n + 2, paper coordinates).

        Returns
        -------
        numpy.ndarray
            ``w`` [m, m, rad], length 3.
        """
        return self.check_q(q)[:3].copy()

    def link_poses(self, q: np.ndarray) -> np.ndarray:
        """(n, 3) array of ``[x_i, y_i, theta_i]``: CM position and orientation of each link.

        Parameters
        ----------
        q : numpy.ndarray
            Configuration (n + 2, paper coordinates).

        Returns
        -------
        numpy.ndarray
            Shape (n, 3) [m, m, rad], head link first.
        """
        theta, ends = self._chain(self.check_q(q))
        offsets = self.params.com_offsets
        return np.column_stack([ends[:-1, 0] + offsets * np.cos(theta),
                                ends[:-1, 1] + offsets * np.sin(theta), theta])

    def joint_points(self, q: np.ndarray) -> np.ndarray:
        """(n + 1, 2) array: head point, the n - 1 joints, then the tail end, for drawing.

        Parameters
        ----------
        q : numpy.ndarray
            Configuration (n + 2, paper coordinates).

        Returns
        -------
        numpy.ndarray
            Shape (n + 1, 2) [m].
        """
        return self._chain(self.check_q(q))[1]

    def _chain(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Link angles (n,) and the n + 1 link end points, from Pinocchio's kinematics."""
        pin.forwardKinematics(self.model, self.data, q)
        ends = np.empty((self.n + 1, 2))
        theta = np.empty(self.n)
        for i, joint in enumerate(self.link_joints):
            placement = self.data.oMi[int(joint)]
            rotation = placement.rotation
            ends[i] = placement.translation[:2]
            theta[i] = np.arctan2(rotation[1, 0], rotation[0, 0])
        last = self.params.link_lengths[-1]
        ends[-1] = ends[-2] + last * np.array([np.cos(theta[-1]), np.sin(theta[-1])])
        return theta, ends


class SnakeData:
    """Buffers of one caller of a :class:`Snake`'s ``calc_*`` methods, as Pinocchio's Data.

    Parameters
    ----------
    snake : Snake
        The robot.
    pin_data : pinocchio.Data, optional
        The Pinocchio workspace to use (a new one by default).

    Raises
    ------
    ParameterError
        ``snake`` is not a Snake.

    Attributes
    ----------
    pin, mass, inverse_mass
        The Pinocchio workspace, and views of its M and Minv filled whole by ``calc_*``.
    bias, torque
        h and ``E tau`` (length n + 2 each).
    friction
        The friction route's buffers (:class:`~snake_pin.friction.FrictionData`).
    """

    def __init__(self, snake: Snake, pin_data: pin.Data | None = None) -> None:
        instance(snake, Snake, "snake")
        self._snake = snake
        self.pin = snake.model.createData() if pin_data is None else pin_data
        self.mass, self.inverse_mass = self.pin.M, self.pin.Minv
        nq = snake.nq
        self.bias, self.torque = np.zeros(nq), np.zeros(nq)
        self.friction = snake.friction.create_data()
        # what the calc_* methods read, in one tuple (one attribute lookup per call)
        self.dynamics = (snake.model, self.pin, snake.friction.calc_force, self.friction)
        mirrors = snake.binding_mirrors
        self.crba = whole(pin.crba, self.mass, mirrors)
        self.minverse = whole(pin.computeMinverse, self.inverse_mass, mirrors)

    def __reduce__(self) -> tuple[Any, tuple[Snake]]:
        """Pickled as its robot's."""
        return SnakeData, (self._snake,)


def _binding_mirrors(model: pin.Model) -> bool:
    """Whether ``pin.crba`` and ``pin.computeMinverse`` (after ABA) fill M and Minv whole."""
    data = model.createData()
    inverse = data.Minv  # the view the callers read, not the returned copy
    q = np.linspace(0.3, 0.9, model.nq)
    pin.aba(model, data, q, q, np.zeros(model.nv), _WORLD)
    returned = pin.computeMinverse(model, data)
    whole_inverse = np.array_equal(inverse, returned) and np.array_equal(inverse, inverse.T)
    return bool(crba_mirrors(model) and whole_inverse)


def _vector(value: object, size: int, name: str) -> np.ndarray:
    """Fast path of :func:`as_vector` for float64 arrays of the right shape."""
    if value.__class__ is np.ndarray and value.shape == (size,) and value.dtype == np.float64:
        if not np.isfinite(value).all():
            raise ConfigurationError(f"{name} has non-finite entries")
        return value
    return as_vector(value, size, name)
