"""Dynamic manipulability D and R of an underactuated system (Section III, eqs. 22-42), for
the snake and any Pinocchio model (:ref:`manipulability`).
"""

from __future__ import annotations

import numbers
import sys
import types
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike
from scipy.linalg import lapack

from ._symmetric import symmetric_from_upper
from ._validation import as_vector, brief, flag, instance, integer, model_data
from .exceptions import ConfigurationError, ParameterError
from .model import Snake
from .paper import k_matrix
from .params import SnakeParams

__all__ = ["TASK_ROWS", "Manipulability", "dynamic_manipulability",
           "lateral_constraint_manipulability", "manipulability"]


@dataclass(slots=True)
class Manipulability:
    """Manipulability criteria at one configuration.

    Parameters
    ----------
    D, R : float
        Least singular values of A and of H12 (eqs. 30, 31, 42); R is NaN for a task.
    sigma, lambda_, blocks : numpy.ndarray, numpy.ndarray, dict or None
        All singular values of A and H12, descending, zero-padded to the task dimension m;
        ``{"H11", "H12", "H22", "A"}`` when requested.
    """

    D: float
    R: float
    sigma: np.ndarray
    lambda_: np.ndarray
    blocks: dict[str, np.ndarray] | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, object]:
        """Return ``{"D", "R", "sigma", "lambda"}`` as plain floats and lists (CLI JSON).

        Returns
        -------
        dict of str to object
            The blocks are left out.
        """
        return {"D": float(self.D), "R": float(self.R), "sigma": self.sigma.tolist(),
                "lambda": self.lambda_.tolist()}


def task_split(n: int, free_joint: int | Sequence[int] | None = None,
               heading: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Return the task (``w``, or ``[x_h, y_h]`` without heading, plus each free joint's
    phi_k) and actuated velocity indices of an n-link snake."""
    n = integer(n, "n", low=2)
    task, actuated, _ = _split(n, free_joints(n, free_joint), flag(heading, "heading"))
    return task, actuated


def _integers(value: object, name: str) -> list[int]:
    """``value`` as a list of ints: a sequence (not text, not a mapping) of integers."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Iterable):
        raise ParameterError(f"{name} must be a sequence of integers, got {brief(value)}")
    items = list(value)
    for item in items:
        if isinstance(item, (bool, np.bool_)) or not isinstance(item, numbers.Integral):
            raise ParameterError(f"{name} must hold integers, got {brief(item)}")
    return [int(item) for item in items]


def free_joints(n: int, free_joint: int | Sequence[int] | None) -> tuple[int, ...]:
    """The free joints (1-based, sorted, distinct) of an n-link robot, or ParameterError."""
    if free_joint is None:
        return ()
    single = isinstance(free_joint, (numbers.Integral, np.ndarray)) and np.ndim(free_joint) == 0
    free = _integers([np.asarray(free_joint).item()] if single else free_joint, "free_joint")
    for k in free:
        if not 1 <= k <= n - 1:
            raise ParameterError(f"free joint {k} is outside 1..{n - 1}")
    return tuple(sorted(set(free)))


@lru_cache(maxsize=256)
def _split(n: int, free: tuple[int, ...], heading: bool
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(task, actuated, flat) indices; flat indexes the (task, actuated) block row-major."""
    needed = 4 + len(free)
    if n < needed:
        what = "no free joint" if not free else f"{len(free)} free joint(s)"
        raise ParameterError(f"manipulability needs n >= {needed} links with {what}, got n = {n}")
    task = [0, 1, 2] if heading else [0, 1]
    task += [2 + k for k in free]
    act = [i for i in range(2, n + 2) if i not in task]
    task_a, act_a = np.array(task), np.array(act)
    flat = _upper_flat(task_a, act_a, n + 2)
    for arr in (task_a, act_a, flat):
        arr.setflags(write=False)
    return task_a, act_a, flat


def _upper_flat(rows: np.ndarray, cols: np.ndarray, size: int) -> np.ndarray:
    """Flat indices of the (rows, cols) block in the upper triangle (all Pinocchio fills)."""
    lo = np.minimum(rows[:, None], cols[None, :])
    hi = np.maximum(rows[:, None], cols[None, :])
    return (lo * size + hi).ravel()


def _singular_values(a: np.ndarray, rows: int) -> np.ndarray:
    """Singular values of ``a`` (LAPACK on the transpose: no numpy overhead), zero-padded."""
    out = lapack.dgesvd(a.T, compute_uv=0)
    values, info = out[1], out[-1]
    if info != 0:
        raise ConfigurationError(f"singular value decomposition failed (LAPACK info {info})")
    if values.size < rows:  # fewer inputs than task directions: the ellipsoid is flat
        values = np.concatenate([values, np.zeros(rows - values.size)])
    return values


def manipulability(snake: Snake, q: ArrayLike, free_joint: int | Sequence[int] | None = None,
                   heading: bool = True, *, blocks: bool = False) -> Manipulability:
    """Return D and R of the snake at configuration ``q`` (eqs. 30-31, or D~, R~ of eq. 42).

    Parameters
    ----------
    snake, q : Snake, array_like
        The robot (its passive joints are free) and a configuration (n + 2).
    free_joint : int or sequence of int or None, optional
        1-based further free joint(s), applying the selection S of (33).
    heading, blocks : bool, optional
        Include theta_1 in the task (False: III.1's 2-D variant); return H11, H12, H22, A.

    Returns
    -------
    Manipulability
        ``.sigma`` and ``.lambda_`` have length 3 (2 without heading) + free joints.

    Raises
    ------
    ConfigurationError, ParameterError
        ``q`` is not n + 2 finite numbers; another bad argument, or too few links for the task.
    """
    instance(snake, Snake, "snake")
    q = snake.check_q(q).copy()
    q[:3] = 0.0  # invariant under rigid motions: removed exactly
    free = tuple(snake.params.passive) + free_joints(snake.n, free_joint)
    heading, blocks = flag(heading, "heading"), flag(blocks, "blocks")
    task, act, flat = _split(snake.n, tuple(sorted(set(free))), heading)
    # Upper triangles straight from Pinocchio (``flat`` only reads that triangle).
    h = pin.crba(snake.model, snake.data, q, pin.Convention.WORLD)
    h_inv = pin.computeMinverse(snake.model, snake.data, q)
    return _evaluate(h, h_inv, task, act, flat, blocks=blocks)


def _evaluate(h: np.ndarray, h_inv: np.ndarray, task: np.ndarray, act: np.ndarray,
              flat: np.ndarray, *, blocks: bool) -> Manipulability:
    """Criteria from H and H^-1 (only their upper triangles are read)."""
    shape = (len(task), len(act))
    a = h_inv.take(flat).reshape(shape)  # = -(Schur)^-1 H12 H22^-1, the map of eq. (29)
    h12 = h.take(flat).reshape(shape)
    sigma = _singular_values(a, len(task))
    lam = _singular_values(h12, len(task))
    extra = None
    if blocks:
        full = symmetric_from_upper(h)
        extra = {"H11": full[np.ix_(task, task)], "H12": h12, "H22": full[np.ix_(act, act)],
                 "A": a}
    return Manipulability(float(sigma[-1]), float(lam[-1]), sigma, lam, extra)


#: Task rows of a frame's 6-D Jacobian (linear x, y, z, angular x, y, z) by name.
TASK_ROWS: dict[str, tuple[int, ...]] = {
    "full": (0, 1, 2, 3, 4, 5), "planar": (0, 1, 5), "position": (0, 1, 2),
    "planar_position": (0, 1),
}


def dynamic_manipulability(model: pin.Model, data: pin.Data, q: ArrayLike,
                           unactuated: Sequence[int], task: np.ndarray | str | None = None,
                           rows: Sequence[int] | str | None = None) -> Manipulability:
    """Return the dynamic manipulability of any Pinocchio model with unactuated coordinates.

    Parameters
    ----------
    model, data, q, unactuated : pinocchio.Model, pinocchio.Data, array_like, sequence of int
        A Pinocchio model, its data (overwritten), a configuration (model.nq), and the 0-based
        velocity indices without an actuator (may be empty: fully actuated).
    task : numpy.ndarray of shape (m, model.nv), or str, or None, optional
        None: the unactuated coordinates (R defined); a Jacobian, or a frame name (its 6-D
        LOCAL_WORLD_ALIGNED Jacobian): ``A = J H^-1 B``.
    rows : sequence of int or str or None, optional
        Rows of the task Jacobian to keep, indices or a name of :data:`TASK_ROWS` (a planar
        robot needs ``"planar"``, or D is always 0). Only with a ``task``.

    Returns
    -------
    Manipulability
        ``.R`` and ``.lambda_`` are NaN when a ``task`` is given.

    Raises
    ------
    ConfigurationError, ParameterError
        A bad ``q`` or task Jacobian; another bad argument, nothing actuated, or no task.
    """
    model = instance(model, pin.Model, "model", "a pinocchio.Model")
    model_data(data, model, pin.Data)
    q = as_vector(q, model.nq, "q")
    nv = model.nv
    unact = np.array(sorted(set(_integers(unactuated, "unactuated"))), dtype=int)
    if unact.size and (unact.min() < 0 or unact.max() >= nv):
        raise ParameterError(f"unactuated indices must lie in 0..{nv - 1}")
    act = np.array([i for i in range(nv) if i not in set(unact.tolist())], dtype=int)
    if act.size == 0:
        raise ParameterError("at least one coordinate must be actuated")
    h = symmetric_from_upper(pin.crba(model, data, q, pin.Convention.WORLD))
    h_inv = symmetric_from_upper(pin.computeMinverse(model, data, q))
    if task is None and rows is not None:
        raise ParameterError("rows selects rows of a task: give task= (a Jacobian or a "
                             "frame name) or leave rows out")
    if task is None:
        if unact.size == 0:
            raise ParameterError("a fully actuated model needs a task (Jacobian or frame)")
        return _evaluate(h, h_inv, unact, act, _upper_flat(unact, act, nv), blocks=False)
    if isinstance(task, str):
        if not model.existFrame(task):
            raise ParameterError(f"task names no frame of the model: {task!r}")
        jac = pin.computeFrameJacobian(model, data, q, model.getFrameId(task),
                                       pin.LOCAL_WORLD_ALIGNED)
    else:
        jac = _matrix(task, nv, "task (a frame name or a Jacobian)")
    jac = jac[_task_rows(rows, jac.shape[0])]
    sigma = _singular_values(jac @ h_inv[:, act], jac.shape[0])
    return Manipulability(float(sigma[-1]), float("nan"), sigma, np.full(jac.shape[0], np.nan))


def manipulability_R_batch(params: SnakeParams, phi: ArrayLike, *,
                           free_joint: int | Sequence[int] | None = None,
                           heading: bool = True) -> np.ndarray:
    """Return R (or R~) of many postures ``phi`` (B, n - 1) at once, from the closed form of
    H (:ref:`manipulability`); passive joints are free beside ``free_joint``."""
    n = instance(params, SnakeParams, "params").n
    angles = _matrix(phi, n - 1, "phi", atleast_2d=True)
    free = tuple(sorted(set(params.passive) | set(free_joints(n, free_joint))))
    return r_batch(params, angles, free, flag(heading, "heading"))


def _matrix(value: object, columns: int, name: str, *, atleast_2d: bool = False) -> np.ndarray:
    """``value`` as a finite float matrix of ``columns`` columns, or one ConfigurationError."""
    try:
        matrix = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(f"{name} must be a finite matrix of {columns} columns, "
                                 f"got {brief(value)}") from exc
    matrix = np.atleast_2d(matrix) if atleast_2d else matrix
    if isinstance(value, (bool, np.bool_)) or matrix.ndim != 2 or matrix.shape[1] != columns:
        raise ConfigurationError(f"{name} must have {columns} columns, got shape {matrix.shape}")
    if not np.all(np.isfinite(matrix)):
        raise ConfigurationError(f"{name} has non-finite entries")
    return matrix


def r_batch(params: SnakeParams, phi: np.ndarray, free: tuple[int, ...],
             heading: bool) -> np.ndarray:
    """:func:`manipulability_R_batch` of checked arguments (``free`` sorted, passive joints
    included): the hot path of the singular-posture searches and of PFL's climb term."""
    n = params.n
    task, act, _ = _split(n, free, heading)
    m = params.masses
    k = k_matrix(params)
    mk = m[:, None] * k
    inertia = params.inertias
    lower = np.tril(np.ones((n, n)))
    theta = np.concatenate([np.zeros((len(phi), 1)), np.cumsum(phi, axis=1)], axis=1)
    s, c = np.sin(theta), np.cos(theta)
    weights = m @ k  # m^T K
    rows = []
    for index in task:
        if index == 0:
            row = -weights * s
        elif index == 1:
            row = weights * c
        else:
            ind = (np.arange(n) >= index - 2).astype(float)  # e_r, r = index - 2
            row = ((((s * ind) @ mk.T) @ k) * s + (((c * ind) @ mk.T) @ k) * c) \
                + inertia * ind
        rows.append(row @ lower)
    coupling = np.stack(rows, axis=1)[:, :, act - 2]  # columns theta_1, phi -> indices 2..
    if coupling.shape[2] < len(task):  # fewer inputs than task directions
        return np.zeros(len(phi))
    return np.linalg.svd(coupling, compute_uv=False)[:, -1]


def _task_rows(rows: Sequence[int] | str | None, size: int) -> list[int]:
    """The task Jacobian's rows to keep: all (None), a :data:`TASK_ROWS` name, or indices."""
    if rows is None:
        return list(range(size))
    if isinstance(rows, str) and rows not in TASK_ROWS:
        raise ParameterError(f"unknown task rows {rows!r}; choose one of "
                             f"{', '.join(TASK_ROWS)} or give indices")
    chosen = list(TASK_ROWS[rows]) if isinstance(rows, str) else _integers(rows, "task rows")
    if not chosen or len(set(chosen)) != len(chosen) or min(chosen) < 0 or max(chosen) >= size:
        raise ParameterError(f"task rows must be distinct indices in 0..{size - 1}, "
                             f"got {chosen}")
    return chosen


def lateral_constraint_manipulability(snake: Snake, q: ArrayLike,
                                      constrained: Sequence[int] | None = None
                                      ) -> Manipulability:
    """Return the head manipulability *with* lateral constraints (:ref:`manipulability`).

    Parameters
    ----------
    snake, q, constrained : Snake, array_like, sequence of int or None
        The robot, a configuration (n + 2), and the 1-based links whose CM may not slip
        sideways (default links 2..n).

    Returns
    -------
    Manipulability
        ``.D`` and ``.sigma`` (3 singular values); ``.R`` and ``.lambda_`` are NaN.

    Raises
    ------
    ParameterError
        ``constrained`` is empty or names no link.
    """
    instance(snake, Snake, "snake")
    q = snake.check_q(q)
    n = snake.n
    links = (list(range(2, n + 1)) if constrained is None
             else sorted(set(_integers(constrained, "constrained"))))
    if not links or links[0] < 1 or links[-1] > n:
        raise ParameterError(f"constrained links must be given and lie in 1..{n}")
    model, data = snake.model, snake.data
    pin.computeJointJacobians(model, data, q)
    offsets = snake.params.com_offsets
    rows = []
    for link in links:  # lateral CM velocity: v_y + omega * d_i in the link frame
        joint = int(snake.link_joints[link - 1])
        jac = pin.getJointJacobian(model, data, joint, pin.LOCAL)
        rows.append(jac[1] + offsets[link - 1] * jac[5])
    a_c = np.array(rows)
    n_inv = snake.inverse_inertia_matrix(q)
    n_at = n_inv @ a_c.T
    projected = n_inv - n_at @ np.linalg.solve(a_c @ n_at, n_at.T)
    head = projected[:3] @ snake.actuation_matrix
    sigma = _singular_values(head, 3)
    return Manipulability(float(sigma[-1]), float("nan"), sigma, np.full(3, np.nan))


class _CallableModule(types.ModuleType):
    """This module, callable as :func:`manipulability`: importing the submodule binds the
    package attribute ``snake_pin.manipulability`` to it, which would shadow the function."""

    def __call__(self, snake: Snake, q: ArrayLike,
                 free_joint: int | Sequence[int] | None = None, heading: bool = True, *,
                 blocks: bool = False) -> Manipulability:
        return manipulability(snake, q, free_joint, heading, blocks=blocks)


sys.modules[__name__].__class__ = _CallableModule
