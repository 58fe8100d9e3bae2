"""Integrability of the unactuated rows (Section V, Theorems 2-3, eqs. 44-67): Theorem 2's
conditions, the g2 they imply, the conserved g of eq. (67) and Theorem 3 by Lie brackets
(:ref:`integrability`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import paper
from ._validation import brief, finite_number, instance, integer, vector
from .exceptions import ParameterError
from .model import Snake

__all__ = ["Involutivity", "PartialIntegrability", "conserved_quantity", "implied_g2",
           "involutivity", "partial_integrability"]

_STEP = 1e-6


@dataclass
class PartialIntegrability:
    """Theorem 2 for the split ``q1 = q[:k]``, as :func:`partial_integrability` found it.

    Parameters
    ----------
    k, tolerance : int, float
        Number of leading coordinates in q1 (1, 2 or 3); a relative defect below
        ``tolerance`` counts as zero.
    cyclic_defect, gradient_defect : float
        ``max abs(d/dq1 (dq^T H dq)) / dq^T H dq`` and
        ``max abs(dC1[a,i]/dq_j - dC1[a,j]/dq_i) / max abs(dC1/dq)`` over the samples.
    """

    k: int
    cyclic_defect: float
    gradient_defect: float
    tolerance: float

    @property
    def cyclic(self) -> bool:
        """Condition (1): the elements of q1 are cyclic."""
        return self.cyclic_defect < self.tolerance

    @property
    def gradient(self) -> bool:
        """Condition (2): C1 = d g2 / dq for some g2."""
        return self.gradient_defect < self.tolerance

    @property
    def integrable(self) -> bool:
        """Both conditions: (44) is partially integrable without integrating factor."""
        return self.cyclic and self.gradient


def _friction_matrix(snake: Snake, q: np.ndarray) -> np.ndarray:
    """C(q) from the friction map: Q(q, dq) = -C(q) dq, column by column."""
    eye = np.eye(snake.nv)
    return -np.column_stack([snake.friction(q, eye[j]) for j in range(snake.nv)])


def _central(f: Callable[[np.ndarray], Any], x: np.ndarray, j: int, step: float) -> Any:
    """Central difference of ``f`` at ``x`` along coordinate ``j``."""
    e = np.zeros(len(x))
    e[j] = step
    return (f(x + e) - f(x - e)) / (2 * step)


def _random_state(snake: Snake, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A random (q, dq): joint angles within +-1.5 rad, unit normal velocities."""
    q = np.r_[rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi),
              rng.uniform(-1.5, 1.5, snake.n - 1)]
    return q, rng.normal(size=snake.nv)


def partial_integrability(snake: Snake, k: int, *, samples: int = 10, seed: int = 0,
                          tolerance: float = 1e-6) -> PartialIntegrability:
    """Check Theorem 2's conditions for ``q1 = q[:k]`` at ``samples`` random states.

    Parameters
    ----------
    snake, k : Snake, int
        The robot; q1 holds the first k coordinates (1: x_h; 2: and y_h; 3: and theta_1).
    samples, seed, tolerance : int, int, float, optional
        Number and seed of the random states (joint angles within +-1.5 rad); the relative
        defect below which a condition holds.

    Returns
    -------
    PartialIntegrability
        The largest relative defects of both conditions over the samples.

    Raises
    ------
    ParameterError
        An argument is out of its range or of the wrong type.
    """
    instance(snake, Snake, "snake")
    k = integer(k, "k", low=1, high=3)
    samples = integer(samples, "samples", low=1)
    seed = integer(seed, "seed", low=0)
    tolerance = finite_number(tolerance, "tolerance", positive=True)
    rng = np.random.default_rng(seed)
    nv = snake.nv
    cyclic, gradient = 0.0, 0.0
    for _ in range(samples):
        q, dq = _random_state(snake, rng)
        energy = dq @ snake.inertia_matrix(q) @ dq
        for j in range(k):
            d = _central(lambda p: dq @ snake.inertia_matrix(p) @ dq, q, j, _STEP)  # noqa: B023
            cyclic = max(cyclic, abs(d) / energy)
        # dC1[a, i] / dq_j for all a < k, i, j
        jac = np.empty((k, nv, nv))
        for j in range(nv):
            jac[:, :, j] = _central(lambda p: _friction_matrix(snake, p)[:k], q, j, _STEP)
        scale = max(np.abs(jac).max(), 1e-300)
        gradient = max(gradient, np.abs(jac - jac.transpose(0, 2, 1)).max() / scale)
    return PartialIntegrability(k, cyclic, gradient, tolerance)


def implied_g2(snake: Snake, q: np.ndarray, q0: np.ndarray | None = None,
               nodes: int = 32) -> np.ndarray:
    """Return ``g2(q) - g2(q0)``: C1 dq (C's first two rows) integrated along q0 -> q.

    Parameters
    ----------
    snake, q, q0, nodes : Snake, array_like, array_like or None, int
        The robot; end and start (default zero) of the segment; Gauss-Legendre nodes.

    Returns
    -------
    numpy.ndarray, shape (2,)
        The integral [N s].

    Raises
    ------
    ConfigurationError, ParameterError
        ``q`` or ``q0`` is not n + 2 finite numbers; a bad ``snake`` or ``nodes``.
    """
    instance(snake, Snake, "snake")
    nodes = integer(nodes, "nodes", low=1)
    q = snake.check_q(q)
    q0 = np.zeros(snake.nq) if q0 is None else snake.check_q(q0, "q0")
    s, w = np.polynomial.legendre.leggauss(nodes)
    s, w = 0.5 * (s + 1.0), 0.5 * w
    delta = q - q0
    return sum(wi * _friction_matrix(snake, q0 + si * delta)[:2] @ delta
               for si, wi in zip(s, w, strict=True))


def conserved_quantity(snake: Snake, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Return ``g = H1 dq + g2`` of eq. (67): constant along any motion with isotropic friction.

    Parameters
    ----------
    snake, q, dq : Snake, array_like, array_like
        The robot, a configuration and a velocity (n + 2 each).

    Returns
    -------
    numpy.ndarray, shape (2,)
        g [N s] (momentum plus friction-weighted position).

    Raises
    ------
    ConfigurationError, ParameterError
        ``q`` or ``dq`` is not n + 2 finite numbers; a bad ``snake`` or anisotropic friction.
    """
    instance(snake, Snake, "snake")
    q, dq = snake.check_q(q), snake.check_dq(dq)
    return snake.inertia_matrix(q)[:2] @ dq + paper.g2(snake.params, q)


def conserved_quantity_along(snake: Snake, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """g of eq. (67), (N, 2) [N s], along a run's ``q``, ``dq`` (vectorised, unchecked):
    ``H1 dq = sum m_i p_i'`` and ``g2 = sum c_i p_i`` with c = c_x."""
    params = snake.params
    m, c = params.masses, params.per_link("c_x")
    k = paper.k_matrix(params)
    theta, theta_dot = (v[:, 2:3] + np.cumsum(np.pad(v[:, 3:], ((0, 0), (1, 0))), axis=1)
                        for v in (q, dq))
    # weighted sums over links of the CM coordinates p_i = p_h + sum_j K_ij e_j
    def weighted(w: np.ndarray) -> tuple[np.ndarray, ...]:
        a = w @ k  # w^T K
        return (w.sum() * q[:, 0] + np.cos(theta) @ a, w.sum() * q[:, 1] + np.sin(theta) @ a,
                w.sum() * dq[:, 0] - (np.sin(theta) * theta_dot) @ a,
                w.sum() * dq[:, 1] + (np.cos(theta) * theta_dot) @ a)

    _, _, mdx, mdy = weighted(m)
    cx, cy, _, _ = weighted(c)
    return np.column_stack([mdx + cx, mdy + cy])


def lie_bracket_defect(forms: Callable[[np.ndarray], np.ndarray], z: np.ndarray,
                       step: float = 1e-5) -> float:
    """Largest component of a bracket ``[X_i, X_j]`` of ``X_i = (I - A^+ A) e_i`` outside
    ``ker A(z)``, relative to ``max abs(A)``: zero iff ``ker A`` is involutive at z."""
    if not callable(forms):
        raise ParameterError(f"forms must be a callable z -> A(z), got {brief(forms)}")
    z = vector(z, "z")
    step = finite_number(step, "step", positive=True)
    d = z.size
    try:
        shape = np.shape(forms(z))
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"forms(z) must return an (r, {d}) array: {exc}") from exc
    if len(shape) != 2 or shape[1] != d:
        raise ParameterError(f"forms(z) must return an (r, {d}) array, got shape {shape}")

    def fields(point: np.ndarray) -> np.ndarray:
        a = forms(point)
        return np.eye(d) - np.linalg.pinv(a) @ a  # column i is X_i

    x0 = fields(z)
    deriv = np.empty((d, d, d))  # deriv[:, i, l] = d X_i / d z_l
    for l_idx in range(d):
        deriv[:, :, l_idx] = _central(fields, z, l_idx, step)
    a = forms(z)
    worst = 0.0
    for i in range(d):
        for j in range(i + 1, d):
            bracket = deriv[:, j, :] @ x0[:, i] - deriv[:, i, :] @ x0[:, j]
            worst = max(worst, float(np.abs(a @ bracket).max()))
    return worst / np.abs(a).max()


@dataclass
class Involutivity:
    """Theorem 3 tested numerically at random points of (q, t)-space.

    Parameters
    ----------
    n, samples, defect, noise : int, int, float, float
        Links and random points tested; the largest relative bracket component outside
        ``ker [H1 g2]``, and an exact system's (the noise floor).
    """

    n: int
    samples: int
    defect: float
    noise: float

    @property
    def involutive(self) -> bool:
        """Defect at the noise level (within a factor 100)."""
        return self.defect <= 100 * max(self.noise, 1e-14)


def involutivity(snake: Snake, *, samples: int = 10, seed: int = 0) -> Involutivity:
    """Test the involutivity of ``Delta = ker [H1(q) g2(q)]`` (eq. 60) on (q, t) by Lie brackets.

    Parameters
    ----------
    snake, samples, seed : Snake, int, int
        The robot (isotropic friction), and number and seed of the random points (q, t).

    Returns
    -------
    Involutivity
        The largest defect and the noise floor; ``.involutive`` compares them.

    Raises
    ------
    ParameterError
        Its friction is not isotropic, or a bad argument.
    """
    instance(snake, Snake, "snake")
    samples = integer(samples, "samples", low=1)
    seed = integer(seed, "seed", low=0)
    if not snake.params.isotropic:
        raise ParameterError("Theorem 3 applies to the partial integral, which needs c_x = c_y")
    rng = np.random.default_rng(seed)
    params = snake.params

    def forms(z: np.ndarray) -> np.ndarray:
        q = z[:-1]
        return np.column_stack([snake.inertia_matrix(q)[:2], paper.g2(params, q)])

    weights = rng.uniform(0.5, 2.0, (2, snake.nq + 1))
    magnitude = np.abs(forms(np.zeros(snake.nq + 1))).max()

    def exact(z: np.ndarray) -> np.ndarray:
        # gradients of sum sin(w_1 z), sum cos(w_2 z): exact, same size and scale (noise floor)
        return magnitude * np.vstack([weights[0] * np.cos(weights[0] * z),
                                      -weights[1] * np.sin(weights[1] * z)])

    defect, noise = 0.0, 0.0
    for _ in range(samples):
        q, _ = _random_state(snake, rng)
        z = np.r_[q, rng.uniform(0, 5)]
        defect = max(defect, lie_bracket_defect(forms, z))
        noise = max(noise, lie_bracket_defect(exact, z))
    return Involutivity(snake.n, samples, defect, noise)
