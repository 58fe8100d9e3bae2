"""The Pinocchio model of a snake in the paper's coordinates q = [x_h, y_h, theta_1, phi].

``Snake`` owns the ``pin.Model``/``pin.Data`` built from the generated URDF (see
:mod:`snake_pin.urdf`) under a root made of three single-DoF joints in a chain: ``base_x``
(prismatic x, no body), ``base_y`` (prismatic y, no body) and ``base_yaw`` (revolute z,
carrying the head link). Its configuration is exactly (x_h, y_h, theta_1) and its velocity
their plain time derivatives, so nq = nv = n + 2 and no conversion is needed at the
boundary. (A composite PX·PY·RZ joint gives the same H but wrong analytical derivatives in
Pinocchio; the chain gives correct ones: ``tests/test_model.py``.)

The equation of motion is eq. (20): H(q) q'' + h(q, q') = E tau, with h the Coriolis and
centrifugal terms plus viscous friction (:mod:`snake_pin.friction`).

Public methods validate their inputs (shape, finiteness) and raise
:class:`~snake_pin.exceptions.ConfigurationError`; the ``*_of_state`` methods,
``state_derivative`` and :class:`FastDynamics` (``Snake.fast_dynamics``: the simulator's and
the controllers' preallocated step) are the unchecked hot path.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import pinocchio as pin

from ._blas import gemv
from ._symmetric import symmetric_from_upper
from ._validation import as_vector, check_params, instance, integer
from .exceptions import ConfigurationError
from .friction import FrictionModel
from .params import SnakeParams
from .urdf import urdf_string

__all__ = ["BASE_JOINTS", "DynamicsDerivatives", "FastDynamics", "RK4Tableau", "Snake",
           "paper_model"]

#: Names of the three root joints, in order: they carry x_h, y_h and theta_1.
BASE_JOINTS = ("base_x", "base_y", "base_yaw")

_WORLD = pin.Convention.WORLD


def paper_model(params: SnakeParams) -> pin.Model:
    """The robot's Pinocchio model in paper coordinates (PX -> PY -> RZ root chain).

    The fixed-base URDF of ``params`` is parsed by Pinocchio (so the URDF stays the one
    description of the robot); its tree is then re-rooted on the three single-DoF joints.
    Joint ``base_yaw`` (index 3) carries link 1; joint i + 3 carries link i + 1 and is the
    paper's joint i. Each link also gets a body frame named ``link_i``. Passive joints get
    a zero effort limit, as in the URDF.

    Parameters
    ----------
    params : SnakeParams
        The robot.

    Returns
    -------
    pinocchio.Model
        The model, with nq = nv = n + 2.

    Raises
    ------
    ParameterError
        ``params`` is not a SnakeParams.
    """
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
    ddq_dq, ddq_dv : numpy.ndarray
        (n + 2, n + 2): ``d q'' / d q`` and ``d q'' / d q'``.
    ddq_dtau : numpy.ndarray
        (n + 2, n - 1): ``d q'' / d tau = H^-1 E`` (zero columns for passive joints).
    ddq : numpy.ndarray
        (n + 2,): ``q''`` itself at the point.
    """

    ddq_dq: np.ndarray
    ddq_dv: np.ndarray
    ddq_dtau: np.ndarray
    ddq: np.ndarray


class Snake:
    """Rigid-body model of an n-link planar snake with viscous friction (Section II).

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
    model, data
        Pinocchio model and its workspace (see :func:`paper_model` for the joint layout).
    nq, nv
        Both n + 2.
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
        self._cache_key = b""  # bytes of the last state whose friction is cached
        self._cache_q = np.zeros(self.nv)
        self._actuated = np.array([k - 1 for k in self.params.actuated], dtype=int)
        # 1 on actuated joints, 0 on passive ones (None: all actuated, skip the product)
        self._mask: np.ndarray | None = None
        if self.params.passive:
            self._mask = np.zeros(self.n - 1)
            self._mask[self._actuated] = 1.0

    def __repr__(self) -> str:
        return f"Snake({self.params!r})"

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without the cached :attr:`fast_dynamics` (closures; rebuilt on use)."""
        state = self.__dict__.copy()
        state.pop("fast_dynamics", None)
        return state

    @classmethod
    def from_urdf(cls, path: str | os.PathLike[str],
                  friction: Mapping[str, Any] | None = None) -> Snake:
        """The snake described by any URDF of a planar serial chain of revolute z joints.

        Parameters
        ----------
        path
            The URDF file (generated by snake_pin or not).
        friction
            ``{"c_x", "c_y", "c_theta"}`` (each one number or n numbers). Values given here
            win; the rest come from the file's ``<snake_pin>`` element if it has one, else
            they are zero: URDF itself has no viscous ground friction.

        Raises
        ------
        RobotFileError
            The file is missing or is not a planar serial chain (one line naming the
            element at fault; see :func:`snake_pin.robot_file.read_urdf`).
        """
        from .robot_file import read_urdf

        return cls(read_urdf(path, friction=friction))

    @classmethod
    def from_file(cls, spec: str | os.PathLike[str], **overrides: Any) -> Snake:
        """The snake a ``--robot`` value names: a preset, a ``.toml`` robot file or a URDF.

        Parameters
        ----------
        spec : str or os.PathLike
            A preset's name, a ``.toml`` robot file or a URDF.
        **overrides
            Fields of the robot to change (e.g. ``passive=(5,)``); see
            :func:`snake_pin.robot_file.load_robot`.

        Returns
        -------
        Snake
            The robot's model.
        """
        from .robot_file import load_robot

        return cls(load_robot(spec, **overrides))

    @cached_property
    def fast_dynamics(self) -> FastDynamics:
        """This robot's preallocated hot path (see :class:`FastDynamics`), made once."""
        return FastDynamics(self)

    # ------------------------------------------------------------ validation
    def check_q(self, q: object, name: str = "q") -> np.ndarray:
        """``q`` as a finite vector of length n + 2, or ConfigurationError.

        Parameters
        ----------
        q : array_like
            The configuration to check.
        name : str, optional
            The argument's name in the error message.

        Returns
        -------
        numpy.ndarray
            ``q`` as floats, length n + 2.

        Raises
        ------
        ConfigurationError
            Not a finite vector of that length.
        """
        return _vector(q, self.nq, name)

    def check_dq(self, dq: object, name: str = "dq") -> np.ndarray:
        """``dq`` as a finite vector of length n + 2, or ConfigurationError.

        Parameters
        ----------
        dq : array_like
            The velocity to check.
        name : str, optional
            The argument's name in the error message.

        Returns
        -------
        numpy.ndarray
            ``dq`` as floats, length n + 2.

        Raises
        ------
        ConfigurationError
            Not a finite vector of that length.
        """
        return _vector(dq, self.nv, name)

    def check_tau(self, tau: object, name: str = "tau") -> np.ndarray:
        """``tau`` as a finite vector of length n - 1 (never broadcast), or ConfigurationError.

        Parameters
        ----------
        tau : array_like
            The joint torques to check.
        name : str, optional
            The argument's name in the error message.

        Returns
        -------
        numpy.ndarray
            ``tau`` as floats, length n - 1.

        Raises
        ------
        ConfigurationError
            Not a finite vector of that length.
        """
        return _vector(tau, self.n - 1, name)

    def check_state(self, x: object, name: str = "x") -> np.ndarray:
        """The stacked state ``x = [q, dq]`` (length 2(n + 2)), or ConfigurationError.

        Parameters
        ----------
        x : array_like
            The state to check.
        name : str, optional
            The argument's name in the error message.

        Returns
        -------
        numpy.ndarray
            ``x`` as floats, length 2(n + 2).

        Raises
        ------
        ConfigurationError
            Not a finite vector of that length.
        """
        return _vector(x, self.nq + self.nv, name)

    # -------------------------------------------------------------- dynamics
    @cached_property
    def actuation_matrix(self) -> np.ndarray:
        """E of eq. (18), (n + 2) x (n - 1); columns of passive joints are zero."""
        e_matrix = np.zeros((self.nv, self.n - 1))
        e_matrix[3 + self._actuated, self._actuated] = 1.0
        return e_matrix

    def inertia_matrix(self, q: np.ndarray) -> np.ndarray:
        """H(q) of eq. (19) by CRBA, symmetric (n + 2) x (n + 2).

        Parameters
        ----------
        q : numpy.ndarray
            Configuration ``[x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad],
            length n + 2.

        Returns
        -------
        numpy.ndarray
            ``H(q)``, shape (n + 2, n + 2).
        """
        q = self.check_q(q)
        # CRBA fills the upper triangle; the WORLD convention is 2x faster at n = 100
        return symmetric_from_upper(pin.crba(self.model, self.data, q, pin.Convention.WORLD))

    def inverse_inertia_matrix(self, q: np.ndarray) -> np.ndarray:
        """``H(q)^-1`` by Pinocchio's computeMinverse (symmetric).

        Parameters
        ----------
        q : numpy.ndarray
            Configuration ``[x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad],
            length n + 2.

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
        q : numpy.ndarray
            Configuration ``[x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad],
            length n + 2.
        dq : numpy.ndarray
            Velocity ``q'`` [m/s, m/s, rad/s, rad/s], length n + 2.

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
        q : numpy.ndarray
            Configuration ``[x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad],
            length n + 2.
        dq : numpy.ndarray
            Velocity ``q'`` [m/s, m/s, rad/s, rad/s], length n + 2.

        Returns
        -------
        numpy.ndarray
            The force, length n + 2 [N, N, N m, N m].
        """
        q, dq = self.check_q(q), self.check_dq(dq)
        return self.friction(q, dq)

    def bias(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """``h(q, dq)`` of eq. (20): Coriolis/centrifugal plus friction, ``H q'' + h = E tau``.

        Parameters
        ----------
        q : numpy.ndarray
            Configuration ``[x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad],
            length n + 2.
        dq : numpy.ndarray
            Velocity ``q'`` [m/s, m/s, rad/s, rad/s], length n + 2.

        Returns
        -------
        numpy.ndarray
            ``h``, length n + 2.
        """
        q, dq = self.check_q(q), self.check_dq(dq)
        return pin.nonLinearEffects(self.model, self.data, q, dq) - self.friction(q, dq)

    def generalized_torque(self, tau: np.ndarray) -> np.ndarray:
        """``E tau`` with passive joints' entries dropped (their torque is zero).

        Parameters
        ----------
        tau : numpy.ndarray
            Joint torques [N m], length n - 1 (entries of passive joints ignored).

        Returns
        -------
        numpy.ndarray
            The generalised torque, length n + 2 (zero on x, y, theta_1).
        """
        tau = self.check_tau(tau)
        out = np.zeros(self.nv)
        out[3 + self._actuated] = tau[self._actuated]
        return out

    def forward_dynamics(self, q: np.ndarray, dq: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """``q'' = H^-1 (E tau - h)`` by ABA; torques on passive joints are ignored.

        Parameters
        ----------
        q : numpy.ndarray
            Configuration ``[x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad],
            length n + 2.
        dq : numpy.ndarray
            Velocity ``q'`` [m/s, m/s, rad/s, rad/s], length n + 2.
        tau : numpy.ndarray
            Joint torques [N m], length n - 1 (entries of passive joints ignored).

        Returns
        -------
        numpy.ndarray
            ``q''``, length n + 2.
        """
        q, dq, tau = self.check_q(q), self.check_dq(dq), self.check_tau(tau)
        generalized = self.friction(q, dq)
        generalized[3:] += tau if self._mask is None else tau * self._mask
        return pin.aba(self.model, self.data, q, dq, generalized).copy()

    def dynamics_derivatives(self, q: np.ndarray, dq: np.ndarray,
                             tau: np.ndarray) -> DynamicsDerivatives:
        """Analytical derivatives of q'' = H^-1 (E tau - h), friction included.

        With ``Q(q, q')`` the friction force, ``q'' = ABA(q, q', E tau + Q)``, so::

            d q''/d q  = ABA_q + H^-1 dQ/dq,   d q''/d q' = ABA_v + H^-1 dQ/dq',
            d q''/d tau = H^-1 E,

        where ABA_q, ABA_v and H^-1 come from ``pin.computeABADerivatives`` and the
        friction's Jacobians from the damping twin's RNEA derivatives
        (:meth:`snake_pin.friction.FrictionModel.derivatives`), all in Pinocchio's C++.

        Parameters
        ----------
        q : numpy.ndarray
            Configuration ``[x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad],
            length n + 2.
        dq : numpy.ndarray
            Velocity ``q'`` [m/s, m/s, rad/s, rad/s], length n + 2.
        tau : numpy.ndarray
            Joint torques [N m], length n - 1 (entries of passive joints ignored).

        Returns
        -------
        DynamicsDerivatives
            The three Jacobians and ``q''`` itself.
        """
        q, dq, tau = self.check_q(q), self.check_dq(dq), self.check_tau(tau)
        force, dforce_dq, dforce_dv = self.friction.derivatives(q, dq)
        generalized = force
        generalized[3:] += tau if self._mask is None else tau * self._mask
        model, data = self.model, self.data
        ddq_dq, ddq_dv, minv = pin.computeABADerivatives(model, data, q, dq, generalized)
        minv = symmetric_from_upper(minv)
        return DynamicsDerivatives(ddq_dq=ddq_dq + minv @ dforce_dq,
                                   ddq_dv=ddq_dv + minv @ dforce_dv,
                                   ddq_dtau=minv @ self.actuation_matrix,
                                   ddq=data.ddq.copy())

    def friction_of_state(self, x: np.ndarray) -> np.ndarray:
        """Friction force at the stacked state x = [q, dq], remembering the last state.

        A controller evaluates h at the sampled state and the integrator's first stage
        evaluates q'' at the same state: the second call is served from the cache.
        Unchecked (hot path).

        Parameters
        ----------
        x : numpy.ndarray
            State ``x = [q, dq]``, length 2(n + 2).

        Returns
        -------
        numpy.ndarray
            The friction force, length n + 2 (a new array).
        """
        key = x.tobytes()  # bitwise equality: 15x cheaper than comparing arrays
        if key == self._cache_key:
            return self._cache_q.copy()
        out = self.friction.of_state(x)
        self._cache_key = key
        self._cache_q[:] = out
        return out

    def bias_of_state(self, x: np.ndarray) -> np.ndarray:
        """h at the stacked state x = [q, dq] (same as ``bias(q, dq)``; unchecked).

        Parameters
        ----------
        x : numpy.ndarray
            State ``x = [q, dq]``, length 2(n + 2).

        Returns
        -------
        numpy.ndarray
            ``h``, length n + 2.
        """
        nq = self.nq
        return pin.nonLinearEffects(self.model, self.data, x[:nq], x[nq:]) \
            - self.friction_of_state(x)

    def state_derivative(self, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """q'' for the stacked state x = [q, dq] (the simulator's hot path; unchecked).

        Parameters
        ----------
        x : numpy.ndarray
            State ``x = [q, dq]``, length 2(n + 2).
        tau : numpy.ndarray
            Joint torques [N m], length n - 1 (entries of passive joints ignored).

        Returns
        -------
        numpy.ndarray
            ``q''``, length n + 2.
        """
        nq = self.nq
        generalized = self.friction_of_state(x)
        generalized[3:] += tau if self._mask is None else tau * self._mask
        return pin.aba(self.model, self.data, x[:nq], x[nq:], generalized).copy()

    def kinetic_energy(self, q: np.ndarray, dq: np.ndarray) -> float:
        """T of eq. (8).

        Parameters
        ----------
        q : numpy.ndarray
            Configuration ``[x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad],
            length n + 2.
        dq : numpy.ndarray
            Velocity ``q'`` [m/s, m/s, rad/s, rad/s], length n + 2.

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
            Configuration ``[x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad],
            length n + 2.

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
            Configuration ``[x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad],
            length n + 2.

        Returns
        -------
        numpy.ndarray
            Shape (n, 3) [m, m, rad], head link first.
        """
        theta, ends = self._chain(self.check_q(q))
        offsets = self.params.com_offsets
        out = np.empty((self.n, 3))
        out[:, 0] = ends[:-1, 0] + offsets * np.cos(theta)
        out[:, 1] = ends[:-1, 1] + offsets * np.sin(theta)
        out[:, 2] = theta
        return out

    def joint_points(self, q: np.ndarray) -> np.ndarray:
        """(n + 1, 2) array: head point, the n - 1 joints, then the tail end, for drawing.

        Parameters
        ----------
        q : numpy.ndarray
            Configuration ``[x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad],
            length n + 2.

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


class FastDynamics:
    """The closed loop's hot path: q'' and the affine map of q'' in tau, unchecked.

    States are the rows of :attr:`states`, laid out as the friction passes read them
    (:class:`~snake_pin.friction.ForcePasses`): ``z = [q, 0_w, q', 0_w]``, 2 :attr:`size`
    long, where the w slots are the wheels of anisotropic friction (none for isotropic
    friction or the numpy route); :attr:`select` picks ``[q, q']`` out of a row. A run
    steps with a :class:`RK4Tableau` of its own (:meth:`tableau`): it writes a stage state
    whole (w slots 0) and also its q' into the stage's slope row before evaluating it: with
    wheels, that ``[q', 0_w]`` gives their rolling speeds, which go into the state's wheel
    velocity slots (so evaluating a row twice gives the same q''). The stage states, the
    torque and the workspace are shared by the robot's runs and calls, and written before
    each use; a run's state between its steps lives in its own tableau, so runs of one
    robot may nest (a controller that simulates its robot). Every ABA is in Pinocchio's
    WORLD convention: faster than LOCAL here, and the one after which the two-argument
    ``pin.computeMinverse`` is right (after a LOCAL ABA it silently returns a wrong
    matrix).

    Parameters
    ----------
    snake : Snake
        The robot.
    rows : int, optional
        Number of stage states (rows of :attr:`states`; 4 for RK4).

    Raises
    ------
    ParameterError
        ``snake`` is not a Snake, or ``rows`` is not a positive integer.

    Attributes
    ----------
    states
        (rows, 2 size) stage states, written by the caller.
    torque
        E tau (length n + 2; passive rows stay 0), written by the caller, used by the
        tableaux' evaluators.
    checked
        The buffer whose tail is :attr:`torque` (length 2 size + n + 2); its head is free
        for the caller's new state, so that one pass over it checks the state and the
        torque it was reached with.
    affine
        ``affine(x) -> (b, M)`` at the plain state ``x = [q, q']``: b = q'' at zero torque
        (-H^-1 h, a new array) and M = H^-1, whole (both triangles), which is
        :attr:`inverse_mass`.
    mass_and_bias
        ``mass_and_bias(x) -> (H, h)`` at the plain state x: H by CRBA, whole (both
        triangles), which is :attr:`mass`, and h = Coriolis/centrifugal minus friction, as
        :meth:`Snake.bias`, which is :attr:`bias`.
    mass, inverse_mass, bias
        The arrays :attr:`mass_and_bias` and :attr:`affine` fill (views of a workspace of
        their own, made once: a controller may keep slices of them); valid until the next
        call, read only. They are Pinocchio's: :attr:`mass` is stored column-major
        (Fortran-ordered), :attr:`inverse_mass` row-major; both are symmetric, so BLAS
        reads their rows or columns without a copy.
    """

    def __init__(self, snake: Snake, rows: int = 4) -> None:
        _check_snake(snake)
        rows = integer(rows, "rows", low=1)
        self._snake = snake
        model, data, nq = snake.model, snake.data, snake.nq
        passes = snake.friction.passes
        size = passes.size if passes is not None else nq
        self.size = size
        self.states = np.zeros((rows, 2 * size))
        self.checked = np.zeros(2 * size + nq)
        self.torque = self.checked[2 * size:]
        self.select = np.r_[np.arange(nq), size + np.arange(nq)]
        gen, damping = np.zeros(nq), np.zeros(nq)
        torque = self.torque
        rnea, aba, nle = pin.rnea, pin.aba, pin.nonLinearEffects
        # The controllers' calls run on a workspace of their own, whose M and Minv are read
        # through views made once (Pinocchio returns copies: slicing those costs per call).
        data = model.createData()
        self.mass, self.inverse_mass = mass, inverse_mass = data.M, data.Minv
        self.bias = bias = np.zeros(nq)
        # crba and minverse fill H and H^-1 whole: Pinocchio's own functions where its
        # bindings mirror the triangle they compute (these do), else wrappers that mirror
        crba = _whole(pin.crba, mass, _crba_mirrors(model))
        minverse = _whole(pin.computeMinverse, inverse_mass, _binding_mirrors(model))
        negative, subtract, add = np.negative, np.subtract, np.add
        # outputs are passed by position below: numpy parses an out= keyword for some 40 ns
        world = _WORLD

        def views(z: np.ndarray) -> tuple[np.ndarray, ...]:
            """[q, 0_w], [q', 0_w], q and q' of a state z (views made once)."""
            return z[:size], z[size:], z[:nq], z[size:size + nq]

        # Each call below is made by a factory over the views of the state it reads: a
        # stage (its evaluator), the plain calls' own state, or a run's state Z (the first
        # row of its RK4Tableau). The routes' factories repeat their skeleton on purpose:
        # a shared helper would cost a Python call per evaluation
        if passes is None:  # long anisotropic robots: Q by numpy on [q, q'] (size == nq)
            of_state = snake.friction.of_state

            def evaluate_at(z: np.ndarray, rate: np.ndarray) -> Callable[[], np.ndarray]:
                _, _, q, v = views(z)

                def evaluate() -> np.ndarray:
                    add(torque, of_state(z), gen)
                    return aba(model, data, q, v, gen, world)
                return evaluate

            def affine_at(z: np.ndarray) -> Callable[[np.ndarray], Any]:
                _, _, q, v = views(z)

                def affine(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                    b = aba(model, data, q, v, of_state(z), world)
                    minverse(model, data)
                    return b, inverse_mass
                return affine

            def mass_and_bias_at(z: np.ndarray) -> Callable[[np.ndarray], Any]:
                _, _, q, v = views(z)

                def mass_and_bias(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                    crba(model, data, q, world)
                    return mass, subtract(nle(model, data, q, v), of_state(z), bias)
                return mass_and_bias

        elif not passes.has_wheels:  # isotropic: one RNEA of the twin gives -Q
            twin, twin_data, zero = passes.twin, passes.twin_data, passes.zero

            def evaluate_at(z: np.ndarray, rate: np.ndarray) -> Callable[[], np.ndarray]:
                zq, zv, q, v = views(z)  # size == nq: the twin's rows are Q's

                def evaluate() -> np.ndarray:
                    subtract(torque, rnea(twin, twin_data, zq, zero, zv), gen)
                    return aba(model, data, q, v, gen, world)
                return evaluate

            def affine_at(z: np.ndarray) -> Callable[[np.ndarray], Any]:
                zq, zv, q, v = views(z)

                def affine(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                    negative(rnea(twin, twin_data, zq, zero, zv), gen)
                    b = aba(model, data, q, v, gen, world)
                    minverse(model, data)
                    return b, inverse_mass
                return affine

            def mass_and_bias_at(z: np.ndarray) -> Callable[[np.ndarray], Any]:
                zq, zv, q, v = views(z)

                def mass_and_bias(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                    minus_q = rnea(twin, twin_data, zq, zero, zv)
                    crba(model, data, q, world)
                    return mass, add(nle(model, data, q, v), minus_q, bias)
                return mass_and_bias

        else:  # wheels: the twin's CRBA and the Schur complement (ForcePasses)
            twin, twin_data = passes.twin, passes.twin_data
            twin_mass = twin_data.M
            twin_crba = _whole(pin.crba, twin_mass, _crba_mirrors(twin))
            # -Q at [zq, zv]: [M_cc, M_cw] [q'; w] with the wheels rolling at w = M_wc q'
            # (M_ww = -1, see ForcePasses), by BLAS's dgemv on M's columns (Fortran-
            # ordered, and M is symmetric: columns are rows), in place (see _blas). A stage
            # reads [q'; 0_w] from its slope row and writes w into its own wheel slots
            # (no copy), then E tau + Q on a copy of E tau; the other states keep their
            # wheel slots 0 (Z is a row of RK4's tableau) and roll in a buffer of their own
            chain_columns, wheel_columns = twin_mass[:, :nq], twin_mass[:, nq:]
            rolled = np.zeros(size)  # [q', w]
            rolled_v, rolled_w = rolled[:nq], rolled[nq:]

            def evaluate_at(z: np.ndarray, rate: np.ndarray) -> Callable[[], np.ndarray]:
                zq, zv, q, v = views(z)
                rolling = zv[nq:]

                def evaluate() -> np.ndarray:
                    twin_crba(twin, twin_data, zq, world)
                    gemv(1.0, wheel_columns, rate, 0.0, rolling, 1)
                    gen[...] = torque
                    gemv(-1.0, chain_columns, zv, 1.0, gen, 1)
                    return aba(model, data, q, v, gen, world)
                return evaluate

            def affine_at(z: np.ndarray) -> Callable[[np.ndarray], Any]:
                zq, zv, q, v = views(z)

                def affine(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                    twin_crba(twin, twin_data, zq, world)
                    rolled_v[...] = v
                    gemv(1.0, wheel_columns, zv, 0.0, rolled_w, 1)
                    gemv(-1.0, chain_columns, rolled, 0.0, gen, 1)  # Q
                    b = aba(model, data, q, v, gen, world)
                    minverse(model, data)
                    return b, inverse_mass
                return affine

            def mass_and_bias_at(z: np.ndarray) -> Callable[[np.ndarray], Any]:
                zq, zv, q, v = views(z)

                def mass_and_bias(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                    twin_crba(twin, twin_data, zq, world)
                    rolled_v[...] = v
                    gemv(1.0, wheel_columns, zv, 0.0, rolled_w, 1)
                    gemv(1.0, chain_columns, rolled, 0.0, damping, 1)  # -Q
                    crba(model, data, q, world)
                    return mass, add(nle(model, data, q, v), damping, bias)
                return mass_and_bias

        self._evaluate_at, self._affine_at, self._mass_and_bias_at = (
            evaluate_at, affine_at, mass_and_bias_at)
        own = np.zeros(2 * size)  # the plain calls' own state, so that they never clobber
        own_q, own_v = own[:nq], own[size:size + nq]  # a stage or a run's state
        own_affine, own_mass_and_bias = affine_at(own), mass_and_bias_at(own)

        def affine(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            own_q[...] = x[:nq]
            own_v[...] = x[nq:]
            return own_affine(x)

        def mass_and_bias(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            own_q[...] = x[:nq]
            own_v[...] = x[nq:]
            return own_mass_and_bias(x)

        self.affine, self.mass_and_bias = affine, mass_and_bias

    def tableau(self) -> RK4Tableau:
        """A new RK4 tableau on this robot, for one run (see :class:`RK4Tableau`).

        Returns
        -------
        RK4Tableau
            Zeroed, with its evaluators and its calls at its state Z.
        """
        size, rows = self.size, len(self.states)
        slopes = np.zeros((rows + 1, 2 * size))
        step = slopes[0]
        return RK4Tableau(
            dynamics=self, slopes=slopes,
            evaluators=[self._evaluate_at(row, rate[:size])
                        for row, rate in zip(self.states, slopes[1:], strict=True)],
            affine=self._affine_at(step), mass_and_bias=self._mass_and_bias_at(step))

    def __reduce__(self) -> tuple[Any, tuple[Snake]]:
        """Pickled as its robot's (the closures are rebuilt by the robot on use)."""
        return _fast_dynamics_of, (self._snake,)


@dataclass(frozen=True, eq=False)
class RK4Tableau:
    """One run's RK4 tableau on a robot's :class:`FastDynamics` (:meth:`FastDynamics.tableau`).

    Parameters
    ----------
    dynamics : FastDynamics
        The robot's fast dynamics.
    slopes : numpy.ndarray
        (rows + 1, 2 size): ``[Z; d_1; ...]``, the run's state Z (layout of
        :attr:`FastDynamics.states`) and per stage i its slope ``[q', 0_w, q'', 0_w]`` in
        row i + 1, whose first half the run writes before evaluating stage i.
    evaluators : list of callable
        ``evaluators[i]() -> q''`` (a new array) at ``dynamics.states[i]`` under
        ``dynamics.torque``: one closure per stage, over its views.
    affine, mass_and_bias : callable
        :attr:`FastDynamics.affine` and :attr:`FastDynamics.mass_and_bias` at Z, read in
        place (their argument is not read): for a law in the run, whose x is Z.
    """

    dynamics: FastDynamics
    slopes: np.ndarray
    evaluators: list[Callable[[], np.ndarray]]
    affine: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
    mass_and_bias: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def _fast_dynamics_of(snake: Snake) -> FastDynamics:
    return snake.fast_dynamics


def _whole(algorithm: Callable[..., Any], matrix: np.ndarray,
           mirrors: bool) -> Callable[..., Any]:
    """``algorithm`` (``pin.crba`` or ``pin.computeMinverse``) itself when the bindings
    return ``matrix`` (the view of the Data's M or Minv) whole, else a wrapper of the same
    signature that mirrors its upper triangle into the lower one in place."""
    if mirrors:
        return algorithm
    lower = np.tril(np.ones(matrix.shape, dtype=bool), -1)

    def whole(*arguments: Any) -> np.ndarray:
        algorithm(*arguments)
        np.copyto(matrix, matrix.T, where=lower)
        return matrix

    return whole


def _binding_mirrors(model: pin.Model) -> bool:
    """Whether ``pin.crba`` and ``pin.computeMinverse`` (after ABA) return H and H^-1 whole.

    Pinocchio's own algorithms fill the upper triangle only; its Python bindings mirror it
    (this one does). Checked once per robot on a configuration away from symmetries.
    """
    data = model.createData()
    inverse = data.Minv  # the view FastDynamics reads, not the returned copy
    q = np.linspace(0.3, 0.9, model.nq)
    pin.aba(model, data, q, q, np.zeros(model.nv), _WORLD)
    returned = pin.computeMinverse(model, data)
    whole_inverse = np.array_equal(inverse, returned) and np.array_equal(inverse, inverse.T)
    return bool(_crba_mirrors(model) and whole_inverse)


def _crba_mirrors(model: pin.Model) -> bool:
    """Whether ``pin.crba`` fills ``data.M`` whole (both triangles); see
    :func:`_binding_mirrors`. Alone for the damping twin, whose ABA may be singular (a
    wheel of zero "mass" where c_y = c_x on some links)."""
    data = model.createData()
    mass = data.M  # the view FastDynamics reads, not the returned copy
    returned = pin.crba(model, data, np.linspace(0.3, 0.9, model.nq), _WORLD)
    return bool(np.array_equal(mass, returned) and np.array_equal(mass, mass.T))


def _check_snake(value: object, name: str = "snake") -> Snake:
    """``value`` if it is a :class:`Snake`, else ParameterError naming ``name``."""
    return instance(value, Snake, name)


def _vector(value: object, size: int, name: str) -> np.ndarray:
    """Fast path of :func:`as_vector` for float64 arrays of the right shape."""
    if value.__class__ is np.ndarray and value.shape == (size,) and value.dtype == np.float64:
        if not np.isfinite(value).all():
            raise ConfigurationError(f"{name} has non-finite entries")
        return value
    return as_vector(value, size, name)
