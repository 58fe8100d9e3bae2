"""Anisotropic viscous friction of eqs. (10)-(13) as generalised forces on the Pinocchio model.

Each link i feels, at its centre of mass and in its own frame, the force
``-diag(c_x, c_y) v_cm`` and the torque ``-c_theta * omega`` (README, conventions).

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
  along the link, inserted right after its link in the tree (so every subtree stays
  contiguous in the velocity vector, as CRBA and the RNEA derivatives need). A wheel
  that rolls with the link's longitudinal speed -u takes none of the longitudinal motion
  and adds damping c_y - c_x sideways only: exactly the anisotropy. One RNEA with the
  wheels locked gives (c_y - c_x) u in the wheels' rows; a second with the wheels rolling
  at -u gives Q in the chain's rows. In matrix form, with the twin's mass matrix M split
  into chain (c) and wheel (w) blocks, C = M_cc - M_cw M_ww^-1 M_wc (a Schur complement),
  and the same two passes through ``pin.computeRNEADerivatives`` give dQ/dq exactly.
  The twin over 2n + 2 joints beats numpy only for robots up to n = 40
  (``scripts/bench.py --only friction_routes`` measures the routes), so longer
  anisotropic robots use numpy for Q (the derivatives always use the twin).
  The force alone (:class:`ForcePasses`, the simulator's hot path) runs on another twin,
  built so that the Schur complement costs two products and nothing else. Its wheels are
  appended after the whole chain, tail first (still depth-first: link k's subtree is links
  k..n and wheels n..k), so the chain's coordinates are one slice: the extended state is
  ``[q, 0_w]``, ``[q', 0_w]``. Link i carries the larger of c_x,i and c_y,i
  isotropically, and its wheel takes the difference back: "mass" -|c_y,i - c_x,i| sliding
  along the direction of the larger coefficient (a wheel sliding sideways leaves its
  negative mass acting along the link: c_y - (c_y - c_x) = c_x there). The wheel is a
  prismatic joint at the CM whose axis is 1/sqrt|c_y,i - c_x,i| long (Pinocchio keeps a
  prismatic axis as given), so the CM slides at that factor times the joint's rate and
  M_ww = -|c_y - c_x| / |c_y - c_x| = -1: the wheels roll at exactly ``M_wc q'``, and one
  CRBA and two products give Q (the rolling speeds, then ``-Q = M_cc q' + M_cw (M_wc
  q')``), cheaper than two RNEAs. (Should a Pinocchio normalise the axis, the wheel turns
  on a lever of that length instead: the same matrix, less exact far from the origin.)
  Every coefficient may differ from link to link: in the derivatives' twin link i
  carries c_x,i, c_theta,i and a wheel of c_y,i - c_x,i.
* :class:`FrictionModel` without a model -- vectorised numpy, O(n): with planar vectors
  written as complex numbers, e_i = exp(j theta_i) and the CM velocity z_i = x_i' + j y_i',
  the world force on link i is ``F_i = -cbar_i z_i - delta_i e_i^2 conj(z_i)``,
  cbar_i = (c_x,i + c_y,i)/2, delta_i = (c_x,i - c_y,i)/2, because rotating into the link
  frame, scaling by diag(c_x,i, c_y,i) and rotating back is exactly that.

Tests check the routes against each other and against eq. (11).
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pinocchio as pin

from ._symmetric import symmetric_from_upper
from ._validation import as_vector, check_params, instance
from .exceptions import ParameterError
from .params import SnakeParams

__all__ = ["WHEELED_TWIN_MAX_LINKS", "ForcePasses", "FrictionModel", "damping_twin",
           "friction_forces"]

#: Longest robot whose anisotropic friction force goes through the wheeled twin (one CRBA
#: over 2n + 2 joints and two products); numpy's cost grows more slowly with n. One
#: closed-loop evaluation (a FastDynamics evaluator) took 5.6 against 13.2 us at n = 10,
#: 14.6 against 18.5 at n = 30, 20.0 against 21.3 at n = 40 and 26.7 against 25.0 at
#: n = 50 (``python scripts/bench.py --only friction_routes``).
WHEELED_TWIN_MAX_LINKS = 40

#: Pinocchio joint index of the head link in the paper model (after base_x, base_y).
_HEAD_JOINT = 3


def _check_model(value: object, name: str = "model") -> pin.Model:
    """``value`` if it is a ``pinocchio.Model``, else ParameterError naming ``name``."""
    return instance(value, pin.Model, name, "a pinocchio.Model")


def _check_data(value: object, model: pin.Model, name: str = "data") -> pin.Data:
    """``value`` if it is a ``pinocchio.Data`` of ``model``'s size, else ParameterError."""
    data = instance(value, pin.Data, name, "a pinocchio.Data")
    if len(data.oMi) != model.njoints:
        raise ParameterError(f"{name} has {len(data.oMi)} joints, the model "
                             f"{model.njoints}: use model.createData()")
    return data


def _paper_model_of(model: object, params: object) -> tuple[pin.Model, SnakeParams]:
    """``model`` and ``params`` checked: a Pinocchio model with the joints of the paper model
    of ``params`` (:func:`snake_pin.model.paper_model`)."""
    checked = check_params(params)
    pinocchio_model = _check_model(model)
    if pinocchio_model.njoints != checked.n + _HEAD_JOINT or pinocchio_model.nv != checked.n + 2:
        raise ParameterError(f"model must be the paper model of the {checked.n}-link snake, "
                             f"got {pinocchio_model.njoints} joints")
    return pinocchio_model, checked


def damping_twin(model: pin.Model, params: SnakeParams) -> tuple[pin.Model, np.ndarray,
                                                                  np.ndarray]:
    """The snake's tree with each link's inertia replaced by its damping (module docstring).

    Link i (Pinocchio joint i + 2 of :func:`snake_pin.model.paper_model`) gets "mass"
    c_x,i at its own centre of mass and rotational "inertia" c_theta,i. When some
    c_y,i != c_x,i, a wheel joint ``wheel_i`` (prismatic along the link, at the CM)
    carrying "mass" c_y,i - c_x,i follows each link joint in the tree.

    Parameters
    ----------
    model : pinocchio.Model
        The snake's Pinocchio model (:func:`snake_pin.model.paper_model`).
    params : SnakeParams
        The robot, with its friction coefficients c_x, c_y [N s/m] and c_theta [N m s].

    Returns
    -------
    twin, chain, wheels
        The twin model, the twin's velocity indices of the snake's n + 2 coordinates, and
        those of the n wheels (empty without wheels). Every joint here has nq = nv = 1.

    Raises
    ------
    ParameterError
        ``params`` is not a SnakeParams, or ``model`` is not its paper model.
    """
    model, params = _paper_model_of(model, params)
    c_x, c_y, c_theta = (params.per_link(key) for key in ("c_x", "c_y", "c_theta"))
    extra = c_y - c_x
    with_wheels = bool(np.any(extra != 0.0))
    twin = pin.Model()
    twin.name = f"{model.name}_damping_twin"
    mapping = {0: 0}
    chain, wheels = [], []
    for joint in range(1, model.njoints):
        index = twin.addJoint(mapping[model.parents[joint]], model.joints[joint],
                              model.jointPlacements[joint], model.names[joint])
        mapping[joint] = index
        chain.append(twin.joints[index].idx_v)
        link = joint - _HEAD_JOINT
        if link < 0:
            continue  # base_x, base_y: no body
        lever = model.inertias[joint].lever.copy()
        twin.appendBodyToJoint(index, pin.Inertia(float(c_x[link]), lever,
                                                  np.eye(3) * float(c_theta[link])),
                               pin.SE3.Identity())
        if with_wheels:
            wheel = twin.addJoint(index, pin.JointModelPX(), pin.SE3(np.eye(3), lever),
                                  f"wheel_{link + 1}")
            twin.appendBodyToJoint(wheel, pin.Inertia(float(extra[link]), np.zeros(3),
                                                      np.zeros((3, 3))), pin.SE3.Identity())
            wheels.append(twin.joints[wheel].idx_v)
    twin.gravity = pin.Motion.Zero()
    return twin, np.array(chain, dtype=int), np.array(wheels, dtype=int)


class ForcePasses:
    """The damping twin's force alone, on preallocated buffers (hot path).

    The twin's chain comes first and the n wheels (anisotropic friction only) after it,
    tail first, so the extended configuration is ``[q, 0_w]`` (size :attr:`size`), a
    state is read from one slice, and the joints stay in depth-first order (link k's
    subtree is ``[link k .. link n, wheel n .. wheel k]``, contiguous, as CRBA needs).
    Without wheels one RNEA at velocity ``[q']`` gives -Q. With wheels, one CRBA gives the
    twin's mass matrix M, whose wheel block M_ww is -1 (the module docstring): with its
    chain (c) and wheel (w) blocks the wheels roll at ``w = -M_ww^-1 M_wc q' = M_wc q'``
    and ``-Q = M_cc q' + M_cw w``, the Schur complement applied by two products and
    nothing else (two RNEAs, a locked and a rolling pass, cost more).

    Parameters
    ----------
    model : pinocchio.Model
        The snake's Pinocchio model (:func:`snake_pin.model.paper_model`).
    params : SnakeParams
        The robot, with its friction coefficients c_x, c_y [N s/m] and c_theta [N m s].

    Raises
    ------
    ParameterError
        ``params`` is not a SnakeParams, or ``model`` is not its paper model.

    Attributes
    ----------
    size
        n + 2 plus the number of wheels.
    twin, twin_data
        The twin's model and workspace.
    has_wheels
        Whether the twin carries wheels (some c_y,i != c_x,i).
    zero
        A zero velocity of the twin (RNEA's v: the twin only ever sees accelerations).
    """

    def __init__(self, model: pin.Model, params: SnakeParams) -> None:
        model, params = _paper_model_of(model, params)
        c_x, c_y, c_theta = (params.per_link(key) for key in ("c_x", "c_y", "c_theta"))
        self.has_wheels = bool(np.any(c_y != c_x))
        self.twin = _appended_twin(model, c_x, c_y, c_theta, self.has_wheels)
        self.twin_data = self.twin.createData()
        self.size = self.twin.nq
        self.zero = np.zeros(self.size)
        self._nq = model.nq
        self._q = np.zeros(self.size)
        self._v = np.zeros(self.size)

    def force(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Q(q, dq) as a new array (copies the state into the extended buffers).

        Parameters
        ----------
        q : numpy.ndarray
            Configuration, length n + 2.
        dq : numpy.ndarray
            Velocity, length n + 2.

        Returns
        -------
        numpy.ndarray
            The generalised friction force ``Q``, length n + 2 [N, N, N m, N m].
        """
        nq, q_ext, v_ext = self._nq, self._q, self._v
        q_ext[:nq] = q
        v_ext[:nq] = dq
        if not self.has_wheels:
            return -pin.rnea(self.twin, self.twin_data, q_ext, self.zero, v_ext)
        mass = symmetric_from_upper(pin.crba(self.twin, self.twin_data, q_ext,
                                             pin.Convention.WORLD))
        v_ext[nq:] = mass[nq:, :nq] @ dq  # the wheels roll at M_wc q' (M_ww = -1)
        return -(mass[:nq] @ v_ext)


def _appended_twin(model: pin.Model, c_x: np.ndarray, c_y: np.ndarray, c_theta: np.ndarray,
                   wheels: bool) -> pin.Model:
    """The hot path's damping twin: links of the larger of c_x and c_y, each with a wheel
    that takes the difference back with M_ww = -1, appended after the chain, tail first
    (so that the joints stay in depth-first order), or no wheels (module docstring)."""
    twin = pin.Model()
    twin.name = f"{model.name}_damping_passes"
    larger = np.maximum(c_x, c_y) if wheels else c_x
    for joint in range(1, model.njoints):
        index = twin.addJoint(model.parents[joint], model.joints[joint],
                              model.jointPlacements[joint], model.names[joint])
        link = joint - _HEAD_JOINT
        if link >= 0:
            twin.appendBodyToJoint(index, pin.Inertia(float(larger[link]),
                                                      model.inertias[joint].lever.copy(),
                                                      np.eye(3) * float(c_theta[link])),
                                   pin.SE3.Identity())
    if wheels:
        scaled_axis = _scaled_axis_kept()
        for link in reversed(range(len(c_x))):
            joint = link + _HEAD_JOINT
            cm = model.inertias[joint].lever.copy()
            difference = abs(float(c_y[link] - c_x[link]))
            # a wheel too light to give a finite lever (below the smallest normal float)
            # adds no damping worth the name: it weighs 0 (its rows and columns vanish)
            mass = -difference if difference >= np.finfo(float).tiny else 0.0
            lever = 1.0 / math.sqrt(difference) if mass else 1.0
            # the CM slides sideways where c_y > c_x and along the link where c_x > c_y,
            # at `lever` times the wheel's rate
            axis = np.array([0.0, 1.0, 0.0] if c_y[link] > c_x[link] else [1.0, 0.0, 0.0])
            if scaled_axis:  # a prismatic joint at the CM along lever * axis
                wheel_joint, placement, centre = (pin.JointModelPrismaticUnaligned(lever * axis),
                                                  cm, np.zeros(3))
            else:  # a revolute joint whose pivot is `lever` away from the CM
                arm = lever * np.cross(axis, [0.0, 0.0, 1.0])
                wheel_joint, placement, centre = pin.JointModelRZ(), cm - arm, arm
            wheel = twin.addJoint(joint, wheel_joint, pin.SE3(np.eye(3), placement),
                                  f"wheel_{link + 1}")
            # set, not appended: appendBodyToJoint divides by max(total mass, eps) and so
            # throws a negative mass's centre far away
            twin.inertias[wheel] = pin.Inertia(mass, centre, np.zeros((3, 3)))
    twin.gravity = pin.Motion.Zero()
    return twin


@functools.cache
def _scaled_axis_kept() -> bool:
    """Whether Pinocchio keeps a prismatic joint's axis as given (4.1 does not normalise
    it): then a wheel slides at the CM itself along a scaled axis, its centre of mass is
    the link's to the last bit, and a link of zero total "mass" (c_x or c_y = 0) stays
    exact far from the origin. Otherwise (a Pinocchio that normalises) the wheel turns on
    a lever, whose centre of mass differs from the link's by rounding."""
    probe = pin.Model()
    joint = probe.addJoint(0, pin.JointModelPrismaticUnaligned(np.array([0.0, 2.0, 0.0])),
                           pin.SE3.Identity(), "probe")
    probe.inertias[joint] = pin.Inertia(-0.25, np.zeros(3), np.zeros((3, 3)))
    mass = pin.crba(probe, probe.createData(), np.zeros(1), pin.Convention.WORLD)
    return bool(mass[0, 0] == -1.0)


class FrictionModel:
    """Generalised friction force Q(q, q') = -C(q) q' in paper coordinates.

    Parameters
    ----------
    params
        The robot and its (per-link) friction coefficients.
    model
        The snake's Pinocchio model (:func:`snake_pin.model.paper_model`). With it, Q
        comes from the damping twin's RNEA (and C from its CRBA) when friction is
        isotropic, and from the wheeled twin when it is not and n <=
        :data:`WHEELED_TWIN_MAX_LINKS`; otherwise from vectorised numpy. Derivatives
        (:meth:`derivatives`) need the model.

    Raises
    ------
    ParameterError
        ``params`` is not a SnakeParams, or ``model`` is neither None nor its paper model.
    """

    def __init__(self, params: SnakeParams, model: pin.Model | None = None) -> None:
        params = check_params(params)
        if model is not None:
            model, params = _paper_model_of(model, params)
        n = params.n
        self._twin: pin.Model | None = None
        self._wheels = False
        self._force_on_twin = False
        #: The force's passes (the hot path) when Q comes from the twin, else None.
        self.passes: ForcePasses | None = None
        if model is not None:
            self._twin, self._chain, self._wheel_v = damping_twin(model, params)
            self._twin_data = self._twin.createData()
            self._nv = model.nv
            self._wheels = len(self._wheel_v) > 0
            self._zero = np.zeros(self._twin.nv)
            extra = params.per_link("c_y") - params.per_link("c_x")
            # a wheel too light to invert (below the smallest normal float, 1/extra would
            # overflow) adds no damping worth the name: it stays still (gain 0)
            with np.errstate(divide="ignore", over="ignore"):
                self._roll = np.where(np.abs(extra) >= np.finfo(float).tiny, -1.0 / extra, 0.0)
            self._force_on_twin = not self._wheels or n <= WHEELED_TWIN_MAX_LINKS
            if self._force_on_twin:
                self.passes = ForcePasses(model, params)
        lower = np.tril(np.ones((n, n)))
        # theta = L [theta_1, phi] (eq. 17), applied to q and q' at once by one matmul
        self._angles_t = lower.T.copy()
        # CM velocities: x' + j y' = (x_h' + j y_h') + K (j e theta') (eqs. 3-6), with
        # K_ij = 2l_j below the diagonal and the CM offset d_i on it
        k_matrix = np.tril(np.broadcast_to(params.link_lengths, (n, n)), -1)
        k_matrix[np.diag_indices(n)] = params.com_offsets
        c_x, c_y = params.per_link("c_x"), params.per_link("c_y")
        cbar = 0.5 * (c_x + c_y)
        self._jk = 1j * k_matrix
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(cbar > 0, (c_x - c_y) / (c_x + c_y), 0.0)
        self._ratio = ratio if np.any(ratio) else None
        # F_i = -cbar_i w_i; rows 0..n-1 give K^T F (torques about theta), row n gives
        # sum F (total force), so one matmul yields both.
        self._reduce = np.vstack([k_matrix.T, np.ones((1, n))]) * (-cbar)[None, :]
        self._upper = lower.T.copy()
        self._c_theta = params.per_link("c_theta")
        self._n = n
        self.params = params

    @property
    def uses_twin(self) -> bool:
        """Whether Q comes from the damping twin (in Pinocchio) rather than numpy."""
        return self._force_on_twin

    @property
    def has_wheels(self) -> bool:
        """Whether the twin carries the wheels of anisotropic friction."""
        return self._wheels

    def __call__(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Generalised friction force (length n + 2) at state (q, dq)."""
        if self._force_on_twin:
            return self._twin_force(q, dq)
        both = np.array((q[2:], dq[2:])) @ self._angles_t  # rows: theta, theta'
        return self._force(both[0], both[1], complex(dq[0], dq[1]))

    def of_state(self, x: np.ndarray) -> np.ndarray:
        """Same as ``self(q, dq)`` for the stacked state x = [q, dq] (hot path).

        Parameters
        ----------
        x : numpy.ndarray
            State ``x = [q, dq]``, length 2(n + 2).

        Returns
        -------
        numpy.ndarray
            The generalised friction force ``Q``, length n + 2.
        """
        n2 = self._n + 2
        if self._force_on_twin:
            return self._twin_force(x[:n2], x[n2:])
        both = x.reshape(2, n2)[:, 2:] @ self._angles_t
        return self._force(both[0], both[1], complex(x[n2], x[n2 + 1]))

    def matrix(self, q: np.ndarray) -> np.ndarray:
        """C(q) of eq. (11) such that the friction force is -C(q) dq.

        With the twin: its mass matrix by CRBA, and for anisotropic friction the Schur
        complement M_cc - M_cw M_ww^-1 M_wc over the wheels. Without a model: the force
        is linear in dq, so the columns are the responses to the unit velocities,
        computed together: theta' of the unit vectors is [0 | L] and the base velocity
        is 1 (x_h') or j (y_h').

        Parameters
        ----------
        q : numpy.ndarray
            Configuration, length n + 2.

        Returns
        -------
        numpy.ndarray
            ``C(q)``, shape (n + 2, n + 2), symmetric positive semi-definite.
        """
        if self._twin is not None:
            mass = symmetric_from_upper(pin.crba(self._twin, self._twin_data,
                                                 self._extend(q), pin.Convention.WORLD))
            chain = self._chain
            out = mass[np.ix_(chain, chain)]
            if self._wheels:
                cross = mass[np.ix_(chain, self._wheel_v)]
                out = out + (cross * self._roll) @ cross.T
            return out
        n = self._n
        theta = self._angles_t.T @ q[2:]
        theta_dot = np.zeros((n, n + 2))
        theta_dot[:, 2:] = self._angles_t.T
        base = np.zeros(n + 2, dtype=complex)
        base[0], base[1] = 1.0, 1.0j
        e = np.exp(1j * theta)
        z = self._jk @ (e[:, None] * theta_dot) + base[None, :]
        if self._ratio is not None:
            z += (self._ratio * e * e)[:, None] * z.conjugate()
        g = self._reduce @ z
        out = np.empty((n + 2, n + 2))
        out[0], out[1] = g[-1].real, g[-1].imag
        out[2:] = self._upper @ ((e.conjugate()[:, None] * g[:-1]).imag
                                 - self._c_theta[:, None] * theta_dot)
        return -out

    def derivatives(self, q: np.ndarray,
                    dq: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Q(q, dq) and its Jacobians dQ/dq and dQ/ddq, from the twin's RNEA derivatives.

        Isotropic: Q = -RNEA_twin(q, 0, dq), so dQ/dq = -dRNEA/dq and dQ/ddq = -M_twin.
        Anisotropic (module docstring): with w = roll * RNEA_w(q, 0, [dq; 0]) the wheels'
        rolling speed and Q = -RNEA_c(q, 0, [dq; w]), the chain rule over the two passes
        gives dQ/dq = -(R2_q + M_cw dw/dq) and dQ/ddq = -(M_cc + M_cw dw/ddq), with
        dw/dq = roll * R1_q (wheel rows) and dw/ddq = roll * M_wc.

        Parameters
        ----------
        q : numpy.ndarray
            Configuration, length n + 2.
        dq : numpy.ndarray
            Velocity, length n + 2.

        Returns
        -------
        tuple of numpy.ndarray
            ``Q`` (length n + 2), ``dQ/dq`` and ``dQ/ddq`` (each (n + 2, n + 2)).

        Raises
        ------
        ParameterError
            The friction model was built without the snake's Pinocchio model.
        """
        if self._twin is None:
            raise ParameterError("friction derivatives need the snake's Pinocchio model: "
                                 "build the FrictionModel with model=")
        twin, data, zero, chain = self._twin, self._twin_data, self._zero, self._chain
        q_ext, a_ext = self._extend(q), np.zeros(twin.nv)
        a_ext[chain] = dq
        if not self._wheels:
            dtau_dq, _, mass = pin.computeRNEADerivatives(twin, data, q_ext, zero, a_ext)
            mass = symmetric_from_upper(mass)
            force = -pin.rnea(twin, data, q_ext, zero, a_ext)
            return force, -dtau_dq.copy(), -mass
        wheels, roll = self._wheel_v, self._roll
        dtau_dq, _, mass = pin.computeRNEADerivatives(twin, data, q_ext, zero, a_ext)
        mass = symmetric_from_upper(mass)
        locked = pin.rnea(twin, data, q_ext, zero, a_ext)
        dw_dq = roll[:, None] * dtau_dq[np.ix_(wheels, chain)]
        cross = mass[np.ix_(chain, wheels)]
        dw_dv = roll[:, None] * cross.T
        a_ext[wheels] = roll * locked[wheels]
        dtau_dq2, _, _ = pin.computeRNEADerivatives(twin, data, q_ext, zero, a_ext)
        force = -pin.rnea(twin, data, q_ext, zero, a_ext)[chain]
        dforce_dq = -(dtau_dq2[np.ix_(chain, chain)] + cross @ dw_dq)
        dforce_dv = -(mass[np.ix_(chain, chain)] + cross @ dw_dv)
        return force, dforce_dq, dforce_dv

    def _extend(self, q: np.ndarray) -> np.ndarray:
        """The twin's configuration: q on the chain, wheels at their link's CM (0)."""
        if not self._wheels:
            return q
        q_ext = np.zeros(self._twin.nq)  # type: ignore[union-attr]
        q_ext[self._chain] = q
        return q_ext

    def _twin_force(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        return self.passes.force(q, dq)  # type: ignore[union-attr]

    def _force(self, theta: np.ndarray, theta_dot: np.ndarray, base: complex) -> np.ndarray:
        e = np.exp(1j * theta)
        z = self._jk @ (e * theta_dot)
        z += base
        if self._ratio is not None:  # world force F_i = -cbar_i w_i
            z += self._ratio * (e * e) * z.conjugate()
        g = self._reduce @ z
        out = np.empty(self._n + 2)
        out[0] = g[-1].real
        out[1] = g[-1].imag
        # torque on theta_i: Im(conj(e_i) (K^T F)_i), minus c_theta_i theta_i'; then L^T
        out[2:] = self._upper @ ((e.conjugate() * g[:-1]).imag - self._c_theta * theta_dot)
        return out


def friction_forces(model: pin.Model, data: pin.Data, params: SnakeParams,
                    q: np.ndarray, dq: np.ndarray) -> pin.StdVec_Force:
    """Per-joint friction forces in the joint frames, for ``pin.rnea``/``pin.aba`` (reference).

    Runs ``pin.forwardKinematics`` on ``data``. Joint i + 2 of the paper model carries
    link i, whose frame is at its front end; the CM sits at x = d_i on the link axis.

    Parameters
    ----------
    model : pinocchio.Model
        The snake's Pinocchio model (:func:`snake_pin.model.paper_model`).
    params : SnakeParams
        The robot, with its friction coefficients c_x, c_y [N s/m] and c_theta [N m s].
    data : pinocchio.Data
        The model's workspace (its kinematics are updated).
    q : numpy.ndarray
        Configuration, length n + 2.
    dq : numpy.ndarray
        Velocity, length n + 2.

    Returns
    -------
    pinocchio.StdVec_Force
        One spatial force per joint (zero on the joints before the first link).

    Raises
    ------
    ParameterError
        ``params`` is not a SnakeParams, ``model`` is not its paper model, or ``data``
        is not the model's.
    ConfigurationError
        ``q`` or ``dq`` does not have n + 2 finite entries.
    """
    model, params = _paper_model_of(model, params)
    _check_data(data, model)
    q = as_vector(q, params.n + 2, "q")
    dq = as_vector(dq, params.n + 2, "dq")
    c_x, c_y, c_theta = (params.per_link(key) for key in ("c_x", "c_y", "c_theta"))
    offsets = params.com_offsets
    pin.forwardKinematics(model, data, q, dq)
    forces = pin.StdVec_Force()
    for _ in range(_HEAD_JOINT):
        forces.append(pin.Force.Zero())
    for link in range(params.n):
        velocity = data.v[_HEAD_JOINT + link]
        omega = velocity.angular[2]
        v_along = velocity.linear[0]
        v_across = velocity.linear[1] + omega * offsets[link]  # v_cm = v + omega x (d, 0, 0)
        f_along, f_across = -c_x[link] * v_along, -c_y[link] * v_across
        torque = offsets[link] * f_across - c_theta[link] * omega  # about the joint origin
        forces.append(pin.Force(np.array([f_along, f_across, 0.0]),
                                np.array([0.0, 0.0, torque])))
    return forces
