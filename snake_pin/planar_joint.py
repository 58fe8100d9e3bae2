"""Conversion between Pinocchio's planar-joint model of a snake URDF and paper coordinates.

A plain ``pin.buildModelFromUrdf`` of our URDFs gives a ``JointModelPlanar`` base whose
coordinates are not the paper's; the maps (``v_planar = T q'``, ``H = T^T M T``, ...) are
derived in :ref:`concepts` (Pinocchio's planar joint). Also accepted: ``continuous`` joints
(cos q_i, sin q_i; angles read back in ``(-pi, pi]``) and revolute joints about -z; a model
of another shape (root joint, rotated joint placement, branch) is refused naming the joint.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ._symmetric import symmetric_from_upper
from ._validation import as_vector, brief, instance, integer, model_data
from .exceptions import ParameterError

__all__ = ["paper_to_planar", "paper_to_planar_acceleration", "paper_to_planar_force",
           "planar_layout", "planar_to_paper", "planar_to_paper_acceleration"]

#: Pinocchio's joints about +z, and whether each is unbounded (stored as cos, sin).
_ABOUT_Z = {"JointModelRZ": False, "JointModelRUBZ": True}
_TOLERANCE = 1e-12


@dataclass(frozen=True)
class PlanarLayout:
    """Where a planar-joint snake model keeps each coordinate (:func:`planar_layout` builds it):
    sizes, each joint's first planar index, its (cos, sin) storage and its axis sign s_i."""

    n: int
    nq: int
    nv: int
    idx_q: np.ndarray
    unbounded: np.ndarray
    signs: np.ndarray

    def __post_init__(self) -> None:
        n = integer(self.n, "n", low=2)
        nv = integer(self.nv, "nv", low=n + 2, high=n + 2)
        nq = integer(self.nq, "nq", low=nv + 1)
        for name, kind in (("idx_q", "i"), ("unbounded", "b"), ("signs", "f")):
            value = getattr(self, name)
            if not isinstance(value, np.ndarray) or value.shape != (n - 1,) \
                    or value.dtype.kind != kind:
                what = {"i": "integers", "b": "bools", "f": "floats"}[kind]
                raise ParameterError(f"{name} must be a numpy array of {n - 1} {what}, "
                                     f"got {brief(value)}")
        if np.any((self.idx_q < 0) | (self.idx_q >= nq)):
            raise ParameterError(f"idx_q must index the {nq} planar coordinates")
        if not np.all(np.abs(self.signs) == 1.0):
            raise ParameterError("signs must be +1 or -1")


def _axis_sign(joint: pin.JointModel, name: str) -> tuple[float, bool]:
    """(s_i, unbounded) of a revolute joint about +-z, or ParameterError."""
    kind = joint.shortname()
    if kind in _ABOUT_Z:
        return 1.0, _ABOUT_Z[kind]
    if kind in ("JointModelRevoluteUnaligned", "JointModelRevoluteUnboundedUnaligned"):
        axis = np.asarray(joint.extract().axis, dtype=float)
        if np.allclose(axis[:2], 0.0, atol=_TOLERANCE) and abs(abs(axis[2]) - 1.0) < 1e-9:
            return float(np.sign(axis[2])), kind.endswith("UnboundedUnaligned")
        raise ParameterError(f"joint {name!r} turns about {axis.tolist()}, not z")
    raise ParameterError(f"joint {name!r} is a {kind}, not a revolute joint about z")


def planar_layout(model: pin.Model) -> PlanarLayout:
    """Check that ``model`` is a planar-root serial snake and say where its coordinates are.

    Parameters
    ----------
    model : pinocchio.Model
        E.g. ``pin.buildModelFromUrdf`` of a URDF of :func:`snake_pin.urdf.write_urdf`.

    Returns
    -------
    PlanarLayout
        Sizes, coordinate indices, storage and axis signs of its joints.

    Raises
    ------
    ParameterError
        ``model`` is not a ``pinocchio.Model``, or naming the joint that is not as said.
    """
    instance(model, pin.Model, "model", "a pinocchio.Model")
    if model.njoints < 3:
        raise ParameterError(f"a snake model needs a planar joint and at least one "
                             f"revolute joint, got {model.njoints - 1} joint(s)")
    if model.joints[1].shortname() != "JointModelPlanar":
        raise ParameterError(f"joint {model.names[1]!r} is a {model.joints[1].shortname()}, "
                             f"not the planar base joint (JointModelPlanar)")
    if not model.jointPlacements[1].isIdentity(1e-12):
        raise ParameterError(f"joint {model.names[1]!r} is not placed at the world origin")
    idx_q, unbounded, signs = [], [], []
    for j in range(2, model.njoints):
        name = model.names[j]
        if model.parents[j] != j - 1:
            raise ParameterError(f"joint {name!r} hangs from joint "
                                 f"{model.names[model.parents[j]]!r}: not a serial chain")
        rotation = np.asarray(model.jointPlacements[j].rotation)
        if np.max(np.abs(rotation - np.eye(3))) > 1e-9:
            raise ParameterError(f"joint {name!r}: its placement rotates the next link")
        sign, free = _axis_sign(model.joints[j], name)
        idx_q.append(model.idx_qs[j])
        unbounded.append(free)
        signs.append(sign)
    return PlanarLayout(n=model.njoints - 1, nq=model.nq, nv=model.nv,
                        idx_q=np.asarray(idx_q, dtype=int),
                        unbounded=np.asarray(unbounded, dtype=bool),
                        signs=np.asarray(signs, dtype=float))


def _layout(model: pin.Model | PlanarLayout) -> PlanarLayout:
    if isinstance(model, PlanarLayout):
        return model
    if not isinstance(model, pin.Model):
        raise ParameterError(f"model must be a pinocchio.Model or a PlanarLayout, "
                             f"got {brief(model)}")
    return planar_layout(model)


def velocity_map(model: pin.Model | PlanarLayout, q: np.ndarray) -> np.ndarray:
    """``T = blockdiag(R(theta_1)^T, 1, S)`` with ``v_planar = T q'`` (orthogonal: T^-1 = T^T)."""
    layout = _layout(model)
    q = as_vector(q, layout.n + 2, "q")
    c, s = np.cos(q[2]), np.sin(q[2])
    t_map = np.diag(np.r_[1.0, 1.0, 1.0, layout.signs])
    t_map[:2, :2] = [[c, s], [-s, c]]
    return t_map


def _rate_term(dq: np.ndarray, v_planar: np.ndarray) -> np.ndarray:
    """T' q' = theta' [v_y, -v_x, 0, ...]: the head frame turning under the base velocity."""
    out = np.zeros_like(dq)
    out[0], out[1] = dq[2] * v_planar[1], -dq[2] * v_planar[0]
    return out


def paper_to_planar(model: pin.Model | PlanarLayout, q: np.ndarray, dq: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Convert the paper state (q, q') to the planar model's (q_planar, v_planar).

    Parameters
    ----------
    model : pinocchio.Model or PlanarLayout
        The planar model or its :func:`planar_layout`.
    q, dq : array_like, shape (n + 2,)
        Paper configuration and velocity.

    Returns
    -------
    q_planar : numpy.ndarray, shape (nq,)
        ``[x_h, y_h, cos theta_1, sin theta_1, s_i phi_i ..]``.
    v_planar : numpy.ndarray, shape (n + 2,)
        ``T q'``.

    Raises
    ------
    ParameterError, ConfigurationError
        ``model`` is not a planar-root serial snake; a vector is of the wrong size or not finite.
    """
    layout = _layout(model)
    q = as_vector(q, layout.n + 2, "q")
    dq = as_vector(dq, layout.n + 2, "dq")
    q_planar = np.empty(layout.nq)
    q_planar[:4] = q[0], q[1], np.cos(q[2]), np.sin(q[2])
    angles = layout.signs * q[3:]
    bounded = ~layout.unbounded
    q_planar[layout.idx_q[bounded]] = angles[bounded]
    q_planar[layout.idx_q[layout.unbounded]] = np.cos(angles[layout.unbounded])
    q_planar[layout.idx_q[layout.unbounded] + 1] = np.sin(angles[layout.unbounded])
    return q_planar, velocity_map(layout, q) @ dq


def planar_to_paper(model: pin.Model | PlanarLayout, q_planar: np.ndarray,
                    v_planar: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Convert the planar model's state (q_planar, v_planar) to the paper's (q, q').

    theta_1 (and the angle of a continuous joint) comes back in ``(-pi, pi]``.

    Parameters
    ----------
    model : pinocchio.Model or PlanarLayout
        The planar model or its :func:`planar_layout`.
    q_planar, v_planar : array_like, shapes (nq,) and (n + 2,)
        The planar model's configuration and velocity.

    Returns
    -------
    q, dq : numpy.ndarray, shape (n + 2,)
        Paper configuration and ``T^T v_planar``.

    Raises
    ------
    ParameterError, ConfigurationError
        ``model`` is not a planar-root serial snake; a vector is of the wrong size or not finite.
    """
    layout = _layout(model)
    q_planar = as_vector(q_planar, layout.nq, "q_planar")
    v_planar = as_vector(v_planar, layout.nv, "v_planar")
    angles = np.empty(layout.n - 1)
    bounded = ~layout.unbounded
    angles[bounded] = q_planar[layout.idx_q[bounded]]
    free = layout.idx_q[layout.unbounded]
    angles[layout.unbounded] = np.arctan2(q_planar[free + 1], q_planar[free])
    q = np.r_[q_planar[:2], np.arctan2(q_planar[3], q_planar[2]), layout.signs * angles]
    # T is orthogonal on the base block and a sign flip on the joints: T^-1 = T^T
    return q, velocity_map(layout, q).T @ v_planar


def paper_to_planar_acceleration(model: pin.Model | PlanarLayout, q: np.ndarray,
                                 dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
    """Return ``a_planar = T q'' + T' q'`` (what ``pin.aba`` on the planar model returns).

    Parameters
    ----------
    model : pinocchio.Model or PlanarLayout
        The planar model or its :func:`planar_layout`.
    q, dq, ddq : array_like, shape (n + 2,)
        Paper configuration, velocity and acceleration.

    Returns
    -------
    numpy.ndarray, shape (n + 2,)
        The planar model's acceleration.

    Raises
    ------
    ParameterError, ConfigurationError
        ``model`` is not a planar-root serial snake; a vector is of the wrong size or not finite.
    """
    layout = _layout(model)
    _, v_planar = paper_to_planar(layout, q, dq)
    ddq = as_vector(ddq, layout.n + 2, "ddq")
    dq = np.asarray(dq, dtype=float).reshape(-1)
    return velocity_map(layout, q) @ ddq + _rate_term(dq, v_planar)


def planar_to_paper_acceleration(model: pin.Model | PlanarLayout, q_planar: np.ndarray,
                                 v_planar: np.ndarray, a_planar: np.ndarray) -> np.ndarray:
    """Return ``q'' = T^-1 (a_planar - T' q')`` of the planar model's acceleration.

    Parameters
    ----------
    model : pinocchio.Model or PlanarLayout
        The planar model or its :func:`planar_layout`.
    q_planar, v_planar, a_planar : array_like, shapes (nq,), (n + 2,), (n + 2,)
        The planar model's configuration, velocity and acceleration (e.g. ``pin.aba``'s).

    Returns
    -------
    numpy.ndarray, shape (n + 2,)
        Paper acceleration q''.

    Raises
    ------
    ParameterError, ConfigurationError
        ``model`` is not a planar-root serial snake; a vector is of the wrong size or not finite.
    """
    layout = _layout(model)
    q, dq = planar_to_paper(layout, q_planar, v_planar)
    a_planar = as_vector(a_planar, layout.nv, "a_planar")
    v_planar = np.asarray(v_planar, dtype=float).reshape(-1)
    return velocity_map(layout, q).T @ (a_planar - _rate_term(dq, v_planar))


def paper_to_planar_force(model: pin.Model | PlanarLayout, q: np.ndarray,
                          force: np.ndarray) -> np.ndarray:
    """Return the planar model's generalised force of a paper one: ``T^-T f = T f``.

    For joint torques, ``force = E tau`` gives ``[0, 0, 0, s_i tau_i]``, the ``tau`` to
    pass to ``pin.aba`` on the planar model.

    Parameters
    ----------
    model : pinocchio.Model or PlanarLayout
        The planar model or its :func:`planar_layout`.
    q, force : array_like, shape (n + 2,)
        Paper configuration and generalised force.

    Returns
    -------
    numpy.ndarray, shape (n + 2,)
        The same force for the planar model (equal power).

    Raises
    ------
    ParameterError, ConfigurationError
        ``model`` is not a planar-root serial snake; a vector is of the wrong size or not finite.
    """
    layout = _layout(model)
    force = as_vector(force, layout.n + 2, "force")
    return velocity_map(layout, q) @ force


def paper_dynamics(model: pin.Model, data: pin.Data, q: np.ndarray, dq: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """H(q) and the friction-free h(q, q') of eq. (20) on the planar model: ``H = T^T M T`` and
    ``h = T^T (b + M T' q')`` (M by CRBA, b = ``nonLinearEffects``); Snake's cross-check."""
    layout = planar_layout(model)
    model_data(data, model, pin.Data)
    q_planar, v_planar = paper_to_planar(layout, q, dq)
    mass = symmetric_from_upper(pin.crba(model, data, q_planar))
    bias = pin.nonLinearEffects(model, data, q_planar, v_planar)
    t_map = velocity_map(layout, q)
    dq = np.asarray(dq, dtype=float).reshape(-1)
    return t_map.T @ mass @ t_map, t_map.T @ (bias + mass @ _rate_term(dq, v_planar))
