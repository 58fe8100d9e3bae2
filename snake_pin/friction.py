"""Anisotropic viscous friction of eqs. (10)-(13) as generalised forces on the Pinocchio model.

Q = -C(q) q' is computed in Pinocchio's C++ by the *damping twin* (:ref:`friction`: its
wheels, ``C = M_cc + M_cw M_wc``, the two routes of :data:`WHEELED_TWIN_MAX_LINKS` and
the derivatives). :func:`friction_forces` (one ``pin.Force`` per link) is the reference
route and :func:`snake_pin.paper.friction_matrix` the independent closed form.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
import pinocchio as pin

from ._blas import gemv
from ._symmetric import crba_mirrors, symmetric_from_upper, whole
from ._validation import as_vector, check_params, instance, model_data
from .exceptions import ParameterError
from .params import SnakeParams

__all__ = ["WHEELED_TWIN_MAX_LINKS", "FrictionData", "FrictionModel", "damping_twin",
           "friction_forces"]

#: Longest robot with anisotropic friction whose Q goes through the twin's CRBA and two
#: products; longer robots (and every isotropic one) use the RNEA passes, whose cost grows
#: more slowly with n.
WHEELED_TWIN_MAX_LINKS = 40

_WORLD = pin.Convention.WORLD
_RNEA, _RNEA_DERIVATIVES = pin.rnea, pin.computeRNEADerivatives
# read once: numpy's module __getattr__ keeps Python from caching ``np.<name>`` lookups
_NEGATIVE, _SUBTRACT, _ADD, _MATMUL = np.negative, np.subtract, np.add, np.matmul

#: Pinocchio joint index of the head link in the paper model (after base_x, base_y).
_HEAD_JOINT = 3


def _paper_model_of(model: object, params: object) -> tuple[pin.Model, SnakeParams]:
    """``model`` and ``params`` checked: the paper model of ``params`` and the robot."""
    checked = check_params(params)
    pinocchio_model = instance(model, pin.Model, "model", "a pinocchio.Model")
    if pinocchio_model.njoints != checked.n + _HEAD_JOINT or pinocchio_model.nv != checked.n + 2:
        raise ParameterError(f"model must be the paper model of the {checked.n}-link snake, "
                             f"got {pinocchio_model.njoints} joints")
    return pinocchio_model, checked


def damping_twin(model: pin.Model, params: SnakeParams) -> pin.Model:
    """The snake's tree with each link's inertia replaced by its damping (:ref:`friction`).

    Joints 1 .. n + 2 of the twin are the snake's (same names and placements); with
    anisotropic friction the n wheels ``wheel_n`` .. ``wheel_1`` follow, tail first.

    Parameters
    ----------
    model : pinocchio.Model
        The snake's Pinocchio model (``snake_pin.model.paper_model``).
    params : SnakeParams
        The robot, with its friction coefficients.

    Returns
    -------
    pinocchio.Model
        The twin, nq = nv = n + 2 plus the number of wheels (0 or n).

    Raises
    ------
    ParameterError
        ``params`` is not a SnakeParams, or ``model`` is missing or not its paper model.
    """
    model, params = _paper_model_of(model, params)
    c_x, c_y, c_theta = (params.per_link(key) for key in ("c_x", "c_y", "c_theta"))
    return _appended_twin(model, c_x, c_y, c_theta, bool(np.any(c_y != c_x)))


def _appended_twin(model: pin.Model, c_x: np.ndarray, c_y: np.ndarray, c_theta: np.ndarray,
                   wheels: bool) -> pin.Model:
    """The damping twin of ``model``, with wheels (M_ww = -1) if ``wheels``, appended after the
    chain tail first (depth-first, as CRBA and the RNEA derivatives need): q_twin = [q, 0_w]."""
    twin = pin.Model()
    twin.name = f"{model.name}_damping_twin"
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
    """Whether Pinocchio keeps a prismatic axis as given (then a wheel slides at the CM
    exactly; else it turns on a lever, whose centre of mass is off by rounding)."""
    probe = pin.Model()
    joint = probe.addJoint(0, pin.JointModelPrismaticUnaligned(np.array([0.0, 2.0, 0.0])),
                           pin.SE3.Identity(), "probe")
    probe.inertias[joint] = pin.Inertia(-0.25, np.zeros(3), np.zeros((3, 3)))
    mass = pin.crba(probe, probe.createData(), np.zeros(1), pin.Convention.WORLD)
    return bool(mass[0, 0] == -1.0)


class FrictionData:
    """Buffers of one evaluation of a :class:`FrictionModel` (:meth:`FrictionModel.create_data`).

    Parameters
    ----------
    friction : FrictionModel
        The friction model.

    Attributes
    ----------
    twin_data
        The twin's Pinocchio workspace.
    force
        The last Q (length n + 2).
    jacobian
        ``[dQ/dq, dQ/dq']`` of the last :meth:`FrictionModel.calc_derivatives`, Fortran-ordered;
        ``dforce_dq`` and ``dforce_dv`` are its halves.
    """

    def __init__(self, friction: FrictionModel) -> None:
        instance(friction, FrictionModel, "friction")
        self._friction = friction
        size, nq = friction.size, friction.nq
        self.twin_data = friction.twin.createData()
        self.force = np.zeros(nq)
        self.q = np.zeros(size)  # [q, 0_w]
        self.head = self.q[:nq]
        self.velocity = np.zeros(size)  # [q', 0_w]
        self.velocity_head = self.velocity[:nq]
        self.rolled = np.zeros(size)  # [q', w]
        self.rolled_v, self.rolled_w = self.rolled[:nq], self.rolled[nq:]
        mass = self.twin_data.M  # column-major and symmetric: its columns are its rows
        self.chain_columns, self.wheel_columns = mass[:, :nq], mass[:, nq:]
        self.crba = whole(pin.crba, mass, friction.crba_mirrors)
        # the route's products, prepared: w = M_wc q'; Q = -[M_cc M_cw] [q'; w], + base
        rolling = gemv(1.0, self.wheel_columns, self.velocity, 0.0, self.rolled_w, 1)
        alone = gemv(-1.0, self.chain_columns, self.rolled, 0.0, self.force, 1)
        added = gemv(-1.0, self.chain_columns, self.rolled, 1.0, self.force, 1)
        self.rnea_route = (friction.twin, self.twin_data, friction.zero)
        # what the CRBA route reads, in one tuple (one attribute lookup per call)
        self.crba_route = (self.head, self.velocity_head, self.rolled_v, self.force,
                           self.crba, friction.twin, self.twin_data, self.q, rolling, alone,
                           added)
        # calc_derivatives: Pinocchio's buffers (the bindings return views of these and
        # mirror M), the Jacobians written into one block that copies whole
        self.jacobian = np.zeros((nq, 2 * nq), order="F")
        self.dforce_dq, self.dforce_dv = self.jacobian[:, :nq], self.jacobian[:, nq:]
        dtau_dq, tau = self.twin_data.dtau_dq, self.twin_data.tau
        chain_mass, cross = mass[:nq, :nq], mass[:nq, nq:]  # M_cc, M_cw
        # with wheels, the chain's rows of d(M a)/dq at a = [q', w], the wheels' rows
        # dw/dq (M_ww is constant), the chain's Q = -(M a)_c and the wheels' w = (M a)_w
        self.derivative_route = (
            friction.twin, self.twin_data, friction.zero, self.q, self.head, self.rolled,
            self.rolled_v, self.rolled_w, tau[:nq], tau[nq:], dtau_dq[:nq, :nq],
            dtau_dq[nq:, :nq], chain_mass, cross, cross.T, self.force, self.dforce_dq,
            self.dforce_dv)

    def __reduce__(self) -> tuple[Any, tuple[FrictionModel]]:
        """Pickled as its model's (the buffers and views are made again)."""
        return FrictionData, (self._friction,)


class FrictionModel:
    """Generalised friction force Q(q, q') = -C(q) q' in paper coordinates, on the twin.

    Parameters
    ----------
    params : SnakeParams
        The robot and its (per-link) friction coefficients.
    model : pinocchio.Model
        The snake's Pinocchio model (``snake_pin.model.paper_model``); required.

    Raises
    ------
    ParameterError
        ``params`` is not a SnakeParams, or ``model`` is missing or not its paper model.

    Attributes
    ----------
    twin
        The damping twin (:func:`damping_twin`).
    nq, size
        n + 2, and the twin's nq (n + 2 plus the wheels).
    has_wheels
        Whether some c_y,i != c_x,i (the twin carries wheels).
    uses_twin_crba
        Whether Q comes from the twin's CRBA and two products (else from RNEA passes).
    """

    def __init__(self, params: SnakeParams, model: pin.Model | None = None) -> None:
        if model is None:
            raise ParameterError("FrictionModel needs the snake's Pinocchio model: use "
                                 "Snake(params).friction or model=paper_model(params)")
        model, params = _paper_model_of(model, params)
        self.params, self._model = params, model
        self.twin = damping_twin(model, params)
        self.nq, self.size = model.nq, self.twin.nq
        self.has_wheels = self.size > self.nq
        self.uses_twin_crba = self.has_wheels and params.n <= WHEELED_TWIN_MAX_LINKS
        self.crba_mirrors = crba_mirrors(self.twin)
        self.zero = np.zeros(self.size)
        self._data = FrictionData(self)

    def __getstate__(self) -> dict[str, Any]:
        """The attributes to pickle (the twin rebuilt from the robot on unpickling)."""
        return {"params": self.params, "model": self._model}

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Rebuilt from the pickled robot."""
        self.__init__(state["params"], state["model"])  # type: ignore[misc]

    def create_data(self) -> FrictionData:
        """New buffers for :meth:`calc_force` and :meth:`calc_derivatives`.

        Returns
        -------
        FrictionData
            Buffers made once, for one caller.
        """
        return FrictionData(self)

    @property
    def twin_data(self) -> pin.Data:
        """The twin's workspace of the plain calls."""
        return self._data.twin_data

    def calc_force(self, data: FrictionData, q: np.ndarray, v: np.ndarray,
                   base: np.ndarray | None = None) -> np.ndarray:
        """``base + Q(q, v)`` (or Q alone) into ``data.force`` (unchecked: the hot path).

        Parameters
        ----------
        data : FrictionData
            Buffers of this model.
        q, v : numpy.ndarray
            Configuration and velocity, length n + 2 each.
        base : numpy.ndarray, optional
            A generalised force to add Q to (E tau in the dynamics), length n + 2.

        Returns
        -------
        numpy.ndarray
            ``data.force``, valid until the next call with ``data``.
        """
        if self.uses_twin_crba:  # w = M_wc q', -Q = M_cc q' + M_cw w
            (head, velocity_head, rolled_v, force, crba, twin, twin_data, q_ext, rolling,
             alone, added) = data.crba_route
            head[...] = q
            crba(twin, twin_data, q_ext, _WORLD)
            velocity_head[...] = v
            rolled_v[...] = v
            rolling()
            if base is None:
                alone()
            else:
                force[...] = base
                added()
            return force
        force = data.force
        if self.has_wheels:  # the locked pass gives w, the rolling pass -Q
            data.head[...] = q
            rolled, nq = data.rolled, self.nq
            data.rolled_v[...] = v
            data.rolled_w[...] = 0.0
            data.rolled_w[...] = pin.rnea(self.twin, data.twin_data, data.q, self.zero,
                                          rolled)[nq:]
            minus = pin.rnea(self.twin, data.twin_data, data.q, self.zero, rolled)[:nq]
        else:  # -Q = RNEA(q, 0, v)
            twin, twin_data, zero = data.rnea_route
            minus = _RNEA(twin, twin_data, q, zero, v)
        if base is None:
            _NEGATIVE(minus, force)
        else:
            _SUBTRACT(base, minus, force)
        return force

    def __call__(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Generalised friction force Q (a new array, length n + 2) at state (q, dq)."""
        return self.calc_force(self._data, q, dq).copy()

    def matrix(self, q: np.ndarray) -> np.ndarray:
        """C(q) of eq. (11) such that the friction force is -C(q) dq (the twin's CRBA).

        Parameters
        ----------
        q : numpy.ndarray
            Configuration, length n + 2.

        Returns
        -------
        numpy.ndarray
            ``C(q)``, shape (n + 2, n + 2), symmetric positive semi-definite.
        """
        nq = self.nq
        q_ext = np.zeros(self.size)  # [q, 0_w]
        q_ext[:nq] = q
        mass = symmetric_from_upper(pin.crba(self.twin, self.twin_data, q_ext, _WORLD))
        cross = mass[:nq, nq:]
        return mass[:nq, :nq] + cross @ cross.T

    def calc_derivatives(self, data: FrictionData, q: np.ndarray,
                         v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Q(q, v) and its Jacobians into ``data`` (unchecked: the hot path of the OCP).

        A locked RNEA pass for w, then one pass of the twin's RNEA derivatives (:ref:`friction`).

        Parameters
        ----------
        data : FrictionData
            Buffers of this model.
        q, v : numpy.ndarray
            Configuration and velocity, length n + 2 each.

        Returns
        -------
        tuple of numpy.ndarray
            ``data.force``, ``data.dforce_dq`` and ``data.dforce_dv``: Q (length n + 2),
            dQ/dq and dQ/dv (each (n + 2, n + 2)), valid until the next call with ``data``.
        """
        (twin, twin_data, zero, q_ext, head, rolled, rolled_v, rolled_w, tau_chain,
         tau_wheels, dtau_chain, dw_dq, chain_mass, cross, cross_t, force, dforce_dq,
         dforce_dv) = data.derivative_route
        if not self.has_wheels:  # M(q) v: -Q, d/dq and M
            _RNEA_DERIVATIVES(twin, twin_data, q, zero, v)
            _NEGATIVE(tau_chain, force)
            _NEGATIVE(dtau_chain, dforce_dq)
            _NEGATIVE(chain_mass, dforce_dv)
            return force, dforce_dq, dforce_dv
        head[...] = q
        rolled_v[...] = v
        rolled_w[...] = 0.0
        _RNEA(twin, twin_data, q_ext, zero, rolled)  # the locked pass: w = M_wc v
        rolled_w[...] = tau_wheels
        _RNEA_DERIVATIVES(twin, twin_data, q_ext, zero, rolled)
        _NEGATIVE(tau_chain, force)
        _MATMUL(cross, dw_dq, dforce_dq)
        _ADD(dtau_chain, dforce_dq, dforce_dq)
        _NEGATIVE(dforce_dq, dforce_dq)
        _MATMUL(cross, cross_t, dforce_dv)
        _ADD(chain_mass, dforce_dv, dforce_dv)
        _NEGATIVE(dforce_dv, dforce_dv)
        return force, dforce_dq, dforce_dv

    def derivatives(self, q: np.ndarray,
                    dq: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Q(q, dq) and its Jacobians dQ/dq and dQ/ddq (new arrays; :meth:`calc_derivatives`).

        Parameters
        ----------
        q, dq : numpy.ndarray
            Configuration and velocity, length n + 2 each.

        Returns
        -------
        tuple of numpy.ndarray
            ``Q`` (length n + 2), ``dQ/dq`` and ``dQ/ddq`` (each (n + 2, n + 2)).
        """
        force, dforce_dq, dforce_dv = self.calc_derivatives(self._data, q, dq)
        return force.copy(), dforce_dq.copy(), dforce_dv.copy()


def friction_forces(model: pin.Model, data: pin.Data, params: SnakeParams,
                    q: np.ndarray, dq: np.ndarray) -> pin.StdVec_Force:
    """Per-joint friction forces in the joint frames, for ``pin.rnea``/``pin.aba`` (reference).

    Link i's frame is at its front end; its CM sits at x = d_i on the link axis.

    Parameters
    ----------
    model : pinocchio.Model
        The snake's Pinocchio model (``snake_pin.model.paper_model``).
    data : pinocchio.Data
        The model's workspace (``pin.forwardKinematics`` updates it).
    params : SnakeParams
        The robot, with its friction coefficients.
    q, dq : numpy.ndarray
        Configuration and velocity, length n + 2 each.

    Returns
    -------
    pinocchio.StdVec_Force
        One spatial force per joint (zero on the joints before the first link).

    Raises
    ------
    ParameterError, ConfigurationError
        ``params``, ``model`` or ``data`` is not the robot's; ``q``/``dq`` not n + 2 finite numbers.
    """
    model, params = _paper_model_of(model, params)
    model_data(data, model, pin.Data)
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
