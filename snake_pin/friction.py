"""Anisotropic viscous friction of eqs. (10)-(13) as generalised forces on the Pinocchio model.

Each link i feels, at its centre of mass and in its own frame, the force
``-diag(c_x, c_y) v_cm`` and the torque ``-c_theta * omega`` (DESIGN §2).

Three routes compute the same thing:

* :func:`friction_forces` -- the reference: one ``pin.Force`` per joint, expressed in the
  joint frame as Pinocchio's RNEA/ABA expect, built from Pinocchio's own link velocities.
  It is clear but builds Python objects per link (about 50 us at n = 10).
* :class:`FrictionModel` with the snake's model -- the hot path, in Pinocchio's C++: the
  *damping twin*. With isotropic friction (c_x = c_y = c, the Table 1 robot) a link's
  friction wrench is its spatial velocity times a rigid-body inertia: force -c v_cm at
  the CM and torque -c_theta omega are the momentum of a body of "mass" c centred at the
  link's CM with rotational "inertia" c_theta. So C(q) is the mass matrix of a twin of
  the model with those inertias: Q = -C(q) q' = -RNEA_twin(q, 0, q') and C = CRBA_twin(q).
  A rigid-body inertia is isotropic in translation, so with c_x != c_y each link of the
  twin also carries a *wheel*: a body of "mass" c_y - c_x at the CM on a prismatic joint
  along the link. A wheel that rolls with the link's longitudinal speed -u takes none of
  the longitudinal motion and adds damping c_y - c_x sideways only: exactly the
  anisotropy. One RNEA with the wheels locked gives (c_y - c_x) u in the wheels' rows; a
  second with the wheels rolling at -u gives Q in the chain's rows. These two passes over
  2n joints beat numpy only for short robots (n <= 14; ``scripts/bench.py`` measures the
  routes), so longer anisotropic robots use numpy.
* :class:`FrictionModel` without a model -- vectorised numpy, O(n): with planar vectors
  written as complex numbers, e_i = exp(j theta_i) and the CM velocity z_i = x_i' + j y_i',
  the world force on link i is ``F_i = -cbar z_i - delta e_i^2 conj(z_i)``,
  cbar = (c_x + c_y)/2, delta = (c_x - c_y)/2, because rotating into the link frame,
  scaling by diag(c_x, c_y) and rotating back is exactly that. It also gives C(q) in one
  pass for anisotropic friction (the wheeled twin's C is a Schur complement).

Tests check the routes against each other and against eq. (11).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ._symmetric import symmetric_from_upper
from .params import SnakeParams

__all__ = ["WHEELED_TWIN_MAX_LINKS", "FrictionModel", "damping_twin", "friction_forces"]

#: Longest robot whose anisotropic friction goes through the wheeled twin (two RNEAs over
#: 2n joints); numpy's cost grows more slowly with n (about 13 us at n = 10 and 16 against
#: 9.5 and 12.5 us for the twin, 17 against 31 us at n = 50).
WHEELED_TWIN_MAX_LINKS = 14


def damping_twin(model: pin.Model, params: SnakeParams) -> pin.Model:
    """The snake's tree with each link's inertia replaced by its damping (module docstring).

    Link j (joint j >= 1) gets "mass" c_x at its own centre of mass and rotational
    "inertia" c_theta; with c_y != c_x, a wheel joint ``wheel_j`` (prismatic along the
    link, at the CM) carrying "mass" c_y - c_x is appended for every link, after the
    chain: velocity rows nv .. nv + n - 1. The wheels' subtrees are then not contiguous in
    the velocity vector, which RNEA does not need (CRBA would).
    """
    twin = pin.Model(model)
    rotational = np.eye(3) * params.c_theta
    levers = [model.inertias[joint].lever.copy() for joint in range(1, model.njoints)]
    for joint, lever in enumerate(levers, start=1):
        twin.inertias[joint] = pin.Inertia(params.c_x, lever, rotational)
    extra = params.c_y - params.c_x
    if extra != 0.0:
        for joint, lever in enumerate(levers, start=1):
            wheel = twin.addJoint(joint, pin.JointModelPX(), pin.SE3(np.eye(3), lever),
                                  f"wheel_{joint}")
            twin.appendBodyToJoint(wheel, pin.Inertia(extra, np.zeros(3), np.zeros((3, 3))),
                                   pin.SE3.Identity())
    twin.gravity = pin.Motion.Zero()
    return twin


class FrictionModel:
    """Generalised friction force Q(q, q') = -C(q) q' in paper coordinates.

    Parameters
    ----------
    params
        The robot and its friction coefficients.
    model
        The snake's Pinocchio model (paper coordinates). With it, Q comes from the damping
        twin's RNEA (and C from its CRBA) when c_x = c_y, and from the wheeled twin when
        c_x != c_y and n <= :data:`WHEELED_TWIN_MAX_LINKS`; otherwise from vectorised numpy.
    """

    def __init__(self, params: SnakeParams, model: pin.Model | None = None) -> None:
        n, half = params.n, params.half_length
        self._twin: pin.Model | None = None
        self._wheels = False
        isotropic = params.c_x == params.c_y
        if model is not None and (isotropic or n <= WHEELED_TWIN_MAX_LINKS):
            self._twin = damping_twin(model, params)
            self._twin_data = self._twin.createData()
            self._nv = model.nv
            self._wheels = self._twin.nv > model.nv
            self._zero = np.zeros(self._twin.nv)
            self._q_ext = np.zeros(self._twin.nq)  # wheels at the CM (their q stays 0)
            self._a_ext = np.zeros(self._twin.nv)
            self._roll = -1.0 / (params.c_y - params.c_x) if self._wheels else 0.0
        lower = np.tril(np.ones((n, n)))
        # theta = L [theta_1, phi] (eq. 17), applied to q and q' at once by one matmul
        self._angles_t = lower.T.copy()
        # CM velocities: x' + j y' = (x_h' + j y_h') + K (j e theta') (eqs. 3-6)
        k_matrix = half * (2.0 * np.tril(np.ones((n, n)), -1) + np.eye(n))
        cbar = 0.5 * (params.c_x + params.c_y)
        self._jk = 1j * k_matrix
        self._ratio = (params.c_x - params.c_y) / (params.c_x + params.c_y) if cbar > 0 else 0.0
        # F = -cbar w; rows 0..n-1 give -cbar K^T w (torques about theta), row n gives
        # -cbar sum(w) (total force), so one matmul yields both.
        self._reduce = -cbar * np.vstack([k_matrix.T, np.ones((1, n))])
        self._upper = lower.T.copy()
        self._c_theta = params.c_theta
        self._n = n
        self.params = params

    @property
    def uses_twin(self) -> bool:
        """Whether Q comes from the damping twin (in Pinocchio) rather than numpy."""
        return self._twin is not None

    @property
    def has_wheels(self) -> bool:
        """Whether the twin carries the wheels of anisotropic friction."""
        return self._wheels

    def __call__(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Generalised friction force (length n + 2) at state (q, dq)."""
        if self._twin is not None:
            return self._twin_force(q, dq)
        both = np.array((q[2:], dq[2:])) @ self._angles_t  # rows: theta, theta'
        return self._force(both[0], both[1], complex(dq[0], dq[1]))

    def of_state(self, x: np.ndarray) -> np.ndarray:
        """Same as ``self(q, dq)`` for the stacked state x = [q, dq] (hot path)."""
        n2 = self._n + 2
        if self._twin is not None:
            return self._twin_force(x[:n2], x[n2:])
        both = x.reshape(2, n2)[:, 2:] @ self._angles_t
        return self._force(both[0], both[1], complex(x[n2], x[n2 + 1]))

    def matrix(self, q: np.ndarray) -> np.ndarray:
        """C(q) of eq. (11) such that the friction force is -C(q) dq (all columns at once).

        The force is linear in dq, so the columns are the responses to the unit velocities,
        computed together: theta' of the unit vectors is [0 | L] and the base velocity is 1
        (x_h') or j (y_h').
        """
        if self._twin is not None and not self._wheels:
            # the twin's mass matrix (CRBA fills the upper triangle)
            return symmetric_from_upper(pin.crba(self._twin, self._twin_data, q,
                                                 pin.Convention.WORLD))
        n = self._n
        theta = self._angles_t.T @ q[2:]
        theta_dot = np.zeros((n, n + 2))
        theta_dot[:, 2:] = self._angles_t.T
        base = np.zeros(n + 2, dtype=complex)
        base[0], base[1] = 1.0, 1.0j
        e = np.exp(1j * theta)
        z = self._jk @ (e[:, None] * theta_dot) + base[None, :]
        if self._ratio:
            z += self._ratio * (e * e)[:, None] * z.conjugate()
        g = self._reduce @ z
        out = np.empty((n + 2, n + 2))
        out[0], out[1] = g[-1].real, g[-1].imag
        out[2:] = self._upper @ ((e.conjugate()[:, None] * g[:-1]).imag
                                 - self._c_theta * theta_dot)
        return -out

    def _twin_force(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        twin, data, zero = self._twin, self._twin_data, self._zero
        if not self._wheels:
            return -pin.rnea(twin, data, q, zero, dq)
        nv, q_ext, a_ext = self._nv, self._q_ext, self._a_ext
        q_ext[:nv] = q
        a_ext[:nv] = dq
        a_ext[nv:] = 0.0
        locked = pin.rnea(twin, data, q_ext, zero, a_ext)  # wheel rows: (c_y - c_x) u
        a_ext[nv:] = locked[nv:] * self._roll  # each wheel rolls at -u
        return -pin.rnea(twin, data, q_ext, zero, a_ext)[:nv]

    def _force(self, theta: np.ndarray, theta_dot: np.ndarray, base: complex) -> np.ndarray:
        e = np.exp(1j * theta)
        z = self._jk @ (e * theta_dot)
        z += base
        if self._ratio:  # world force F_i = -cbar w_i
            z += self._ratio * (e * e) * z.conjugate()
        g = self._reduce @ z
        out = np.empty(self._n + 2)
        out[0] = g[-1].real
        out[1] = g[-1].imag
        # torque on theta_i: Im(conj(e_i) (K^T F)_i), minus c_theta theta_i'; then L^T
        out[2:] = self._upper @ ((e.conjugate() * g[:-1]).imag - self._c_theta * theta_dot)
        return out


def friction_forces(model: pin.Model, data: pin.Data, params: SnakeParams,
                    q: np.ndarray, dq: np.ndarray) -> pin.StdVec_Force:
    """Per-joint friction forces in the joint frames, for ``pin.rnea``/``pin.aba`` (reference).

    Runs ``pin.forwardKinematics`` on ``data``. Joint j >= 1 carries link j, whose frame
    is at its front end; the CM sits at x = l on the link axis.
    """
    half = params.half_length
    pin.forwardKinematics(model, data, q, dq)
    forces = pin.StdVec_Force()
    forces.append(pin.Force.Zero())
    for joint in range(1, model.njoints):
        velocity = data.v[joint]
        omega = velocity.angular[2]
        v_along = velocity.linear[0]
        v_across = velocity.linear[1] + omega * half  # v_cm = v + omega x (l, 0, 0)
        f_along, f_across = -params.c_x * v_along, -params.c_y * v_across
        torque = half * f_across - params.c_theta * omega  # moment about the joint origin
        forces.append(pin.Force(np.array([f_along, f_across, 0.0]),
                                np.array([0.0, 0.0, torque])))
    return forces
