"""The Pinocchio model of a snake in the paper's coordinates q = [x_h, y_h, theta_1, phi].

``Snake`` owns the ``pin.Model``/``pin.Data`` built from the generated URDF (see
:mod:`snake_pin.urdf`) with the planar base replaced by a composite PX·PY·RZ root joint:
its configuration is exactly (x_h, y_h, theta_1) and its velocity their plain time
derivatives, so nq = nv = n + 2 and no conversion is needed at the boundary.
The equation of motion is eq. (20): H(q) q'' + h(q, q') = E tau.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import pinocchio as pin

from ._symmetric import symmetric_from_upper
from ._validation import as_vector
from .friction import FrictionModel
from .params import SnakeParams
from .urdf import urdf_string

__all__ = ["Snake"]


def _root_joint() -> pin.JointModelComposite:
    root = pin.JointModelComposite(3)
    root.addJoint(pin.JointModelPX())
    root.addJoint(pin.JointModelPY())
    root.addJoint(pin.JointModelRZ())
    return root


class Snake:
    """Rigid-body model of an n-link planar snake with viscous friction (Section II).

    Parameters
    ----------
    params
        Robot parameters; defaults to the Table 1 robot.

    Attributes
    ----------
    model, data
        Pinocchio model and its workspace; joint 1 is the root (head link), joint i + 1
        is the paper's joint i.
    nq, nv
        Both n + 2.
    """

    def __init__(self, params: SnakeParams | None = None) -> None:
        self.params = params if params is not None else SnakeParams.table1()
        self.n = self.params.n
        xml = urdf_string(self.params, floating_base=False)
        self.model: pin.Model = pin.buildModelFromXML(xml, _root_joint(), "root")
        self.model.gravity = pin.Motion.Zero()  # planar: gravity is normal to the plane
        self.data: pin.Data = self.model.createData()
        self.nq = self.model.nq
        self.nv = self.model.nv
        self.friction = FrictionModel(self.params, self.model)
        self._cache_key = b""  # bytes of the last state whose friction is cached
        self._cache_q = np.zeros(self.nv)
        self._actuated = np.array([k - 1 for k in self.params.actuated], dtype=int)
        # 1 on actuated joints, 0 on passive ones (None: all actuated, skip the product)
        self._mask = None
        if self.params.passive:
            self._mask = np.zeros(self.n - 1)
            self._mask[self._actuated] = 1.0

    def __repr__(self) -> str:
        return f"Snake({self.params!r})"

    # ------------------------------------------------------------ validation
    def check_q(self, q: object, name: str = "q") -> np.ndarray:
        """``q`` as a finite vector of length n + 2, or ConfigurationError."""
        return as_vector(q, self.nq, name)

    def check_tau(self, tau: object) -> np.ndarray:
        """``tau`` as a finite vector of length n - 1, or ConfigurationError."""
        return as_vector(tau, self.n - 1, "tau")

    # -------------------------------------------------------------- dynamics
    @cached_property
    def actuation_matrix(self) -> np.ndarray:
        """E of eq. (18), (n + 2) x (n - 1); columns of passive joints are zero."""
        e_matrix = np.zeros((self.nv, self.n - 1))
        e_matrix[3 + self._actuated, self._actuated] = 1.0
        return e_matrix

    def inertia_matrix(self, q: np.ndarray) -> np.ndarray:
        """H(q) of eq. (19) by CRBA, symmetric (n + 2) x (n + 2)."""
        # CRBA fills the upper triangle; the WORLD convention is 2x faster at n = 100
        return symmetric_from_upper(pin.crba(self.model, self.data, q, pin.Convention.WORLD))

    def inverse_inertia_matrix(self, q: np.ndarray) -> np.ndarray:
        """H(q)^-1 by Pinocchio's computeMinverse (symmetric)."""
        return symmetric_from_upper(pin.computeMinverse(self.model, self.data, q))

    def coriolis(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Coriolis/centrifugal term W diag(J dq) J dq of eq. (18) by RNEA."""
        return pin.nonLinearEffects(self.model, self.data, q, dq).copy()

    def friction_force(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Generalised viscous friction force -C(q) dq (eqs. 11-13)."""
        return self.friction(q, dq)

    def bias(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """h(q, dq) of eq. (20): Coriolis/centrifugal plus friction, so H q'' + h = E tau."""
        return pin.nonLinearEffects(self.model, self.data, q, dq) - self.friction(q, dq)

    def generalized_torque(self, tau: np.ndarray) -> np.ndarray:
        """E tau with passive joints' entries dropped (their torque is zero)."""
        out = np.zeros(self.nv)
        out[3 + self._actuated] = np.asarray(tau)[self._actuated]
        return out

    def forward_dynamics(self, q: np.ndarray, dq: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """q'' = H^-1 (E tau - h) by ABA; torques on passive joints are ignored."""
        generalized = self.friction(q, dq)
        generalized[3:] += tau if self._mask is None else tau * self._mask
        return pin.aba(self.model, self.data, q, dq, generalized).copy()

    def friction_of_state(self, x: np.ndarray) -> np.ndarray:
        """Friction force at the stacked state x = [q, dq], remembering the last state.

        A controller evaluates h at the sampled state and the integrator's first stage
        evaluates q'' at the same state: the second call is served from the cache.
        """
        key = x.tobytes()  # bitwise equality: 15x cheaper than comparing arrays
        if key == self._cache_key:
            return self._cache_q.copy()
        out = self.friction.of_state(x)
        self._cache_key = key
        self._cache_q[:] = out
        return out

    def bias_of_state(self, x: np.ndarray) -> np.ndarray:
        """h at the stacked state x = [q, dq] (same as ``bias(q, dq)``)."""
        nq = self.nq
        return pin.nonLinearEffects(self.model, self.data, x[:nq], x[nq:]) \
            - self.friction_of_state(x)

    def state_derivative(self, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """q'' for the stacked state x = [q, dq] (the simulator's hot path)."""
        nq = self.nq
        generalized = self.friction_of_state(x)
        generalized[3:] += tau if self._mask is None else tau * self._mask
        return pin.aba(self.model, self.data, x[:nq], x[nq:], generalized).copy()

    def kinetic_energy(self, q: np.ndarray, dq: np.ndarray) -> float:
        """T of eq. (8)."""
        return float(pin.computeKineticEnergy(self.model, self.data, q, dq))

    # ------------------------------------------------------------- geometry
    def head_pose(self, q: np.ndarray) -> np.ndarray:
        """w = [x_h, y_h, theta_1]: the head point and the head link's orientation."""
        return np.asarray(q, dtype=float)[:3].copy()

    def link_poses(self, q: np.ndarray) -> np.ndarray:
        """(n, 3) array of [x_i, y_i, theta_i]: CM position and orientation of each link."""
        pin.forwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        out = np.empty((self.n, 3))
        half = self.params.half_length
        for i in range(self.n):
            placement = self.data.oMi[i + 1]
            rotation = placement.rotation
            out[i, :2] = placement.translation[:2] + half * rotation[:2, 0]
            out[i, 2] = np.arctan2(rotation[1, 0], rotation[0, 0])
        return out

    def joint_points(self, q: np.ndarray) -> np.ndarray:
        """(n + 1, 2) array: head point, the n - 1 joints, then the tail end, for drawing."""
        poses = self.link_poses(q)
        half = self.params.half_length
        ends = poses[:, :2] - half * np.c_[np.cos(poses[:, 2]), np.sin(poses[:, 2])]
        tail = poses[-1, :2] + half * np.array([np.cos(poses[-1, 2]), np.sin(poses[-1, 2])])
        return np.vstack([ends, tail])
