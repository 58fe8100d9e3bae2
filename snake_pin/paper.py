"""The paper's closed-form model (Section II, eqs. 3-20), independent of Pinocchio.

Everything here is written from the printed equations with plain numpy and serves as the
cross-check of :class:`snake_pin.model.Snake`. Coordinates: q = [x_h, y_h, theta_1, phi]
and q-bar = [x_h, y_h, theta] (link orientations).
"""

from __future__ import annotations

import numpy as np

from ._validation import as_vector
from .params import SnakeParams

__all__ = [
    "actuation_matrix",
    "bias",
    "coriolis",
    "friction_matrix",
    "friction_matrix_bar",
    "g2",
    "inertia_matrix",
    "inertia_matrix_bar",
    "jacobian_q",
    "jacobian_xy",
    "k_matrix",
    "l_matrix",
    "link_angles",
    "w_matrix_bar",
]


def k_matrix(n: int, half_length: float) -> np.ndarray:
    """K of eq. (4): l on the diagonal, 2l below it."""
    return half_length * (np.eye(n) + 2.0 * np.tril(np.ones((n, n)), -1))


def l_matrix(n: int) -> np.ndarray:
    """L of eq. (17): lower-triangular ones."""
    return np.tril(np.ones((n, n)))


def jacobian_q(n: int) -> np.ndarray:
    """J_{q-bar q} = blockdiag(I_2, L) of eq. (17)."""
    out = np.zeros((n + 2, n + 2))
    out[:2, :2] = np.eye(2)
    out[2:, 2:] = l_matrix(n)
    return out


def link_angles(q: np.ndarray) -> np.ndarray:
    """theta_i = theta_1 + sum_{j<i} phi_j (definition of phi)."""
    return q[2] + np.concatenate([[0.0], np.cumsum(q[3:])])


def jacobian_xy(params: SnakeParams, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """J_{q-bar x} and J_{q-bar y} of eq. (7), each n x (n + 2)."""
    n = params.n
    k = k_matrix(n, params.half_length)
    jx = np.hstack([np.ones((n, 1)), np.zeros((n, 1)), -k @ np.diag(np.sin(theta))])
    jy = np.hstack([np.zeros((n, 1)), np.ones((n, 1)), k @ np.diag(np.cos(theta))])
    return jx, jy


def inertia_matrix_bar(params: SnakeParams, theta: np.ndarray) -> np.ndarray:
    """H-bar of eq. (9): m Jx^T Jx + m Jy^T Jy + diag(0, 0, J, ..., J)."""
    jx, jy = jacobian_xy(params, theta)
    j_bar = np.diag(np.r_[0.0, 0.0, np.full(params.n, params.inertia)])
    return params.mass * (jx.T @ jx + jy.T @ jy) + j_bar


def inertia_matrix(params: SnakeParams, q: np.ndarray) -> np.ndarray:
    """H of eq. (19): J_{q-bar q}^T H-bar J_{q-bar q}."""
    q = as_vector(q, params.n + 2, "q")
    jq = jacobian_q(params.n)
    return jq.T @ inertia_matrix_bar(params, link_angles(q)) @ jq


def w_matrix_bar(params: SnakeParams, theta: np.ndarray) -> np.ndarray:
    """W-bar of eq. (16): J_{q-bar x}^T M J_x + J_{q-bar y}^T M J_y with M = m I."""
    n = params.n
    k = k_matrix(n, params.half_length)
    jx, jy = jacobian_xy(params, theta)
    j_x = np.hstack([np.zeros((n, 2)), -k @ np.diag(np.cos(theta))])
    j_y = np.hstack([np.zeros((n, 2)), -k @ np.diag(np.sin(theta))])
    return params.mass * (jx.T @ j_x + jy.T @ j_y)


def coriolis(params: SnakeParams, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """W diag(J dq) J dq of eq. (18), W = J_{q-bar q}^T W-bar."""
    q = as_vector(q, params.n + 2, "q")
    dq = as_vector(dq, params.n + 2, "dq")
    jq = jacobian_q(params.n)
    dq_bar = jq @ dq
    return jq.T @ w_matrix_bar(params, link_angles(q)) @ (dq_bar * dq_bar)


def friction_matrix_bar(params: SnakeParams, theta: np.ndarray) -> np.ndarray:
    """C-bar = C_tr + C_rot of eqs. (11)-(14)."""
    n = params.n
    c, s = np.cos(theta), np.sin(theta)
    cx, cy = params.c_x, params.c_y
    middle = np.block([[np.diag(cx * c**2 + cy * s**2), np.diag((cx - cy) * s * c)],
                       [np.diag((cx - cy) * s * c), np.diag(cx * s**2 + cy * c**2)]])
    jx, jy = jacobian_xy(params, theta)
    j_xy = np.vstack([jx, jy])  # eq. (14)
    c_rot = np.diag(np.r_[0.0, 0.0, np.full(n, params.c_theta)])
    return j_xy.T @ middle @ j_xy + c_rot


def friction_matrix(params: SnakeParams, q: np.ndarray) -> np.ndarray:
    """C = J_{q-bar q}^T C-bar J_{q-bar q} (after eq. 19); dissipation R = dq^T C dq / 2."""
    q = as_vector(q, params.n + 2, "q")
    jq = jacobian_q(params.n)
    return jq.T @ friction_matrix_bar(params, link_angles(q)) @ jq


def actuation_matrix(n: int) -> np.ndarray:
    """E = [O_{3 x (n-1)}; I_{n-1}] (after eq. 19)."""
    return np.vstack([np.zeros((3, n - 1)), np.eye(n - 1)])


def bias(params: SnakeParams, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """h of eq. (20): W diag(J dq) J dq + C dq."""
    return coriolis(params, q, dq) + friction_matrix(params, q) @ np.asarray(dq, float)


def g2(params: SnakeParams, q: np.ndarray) -> np.ndarray:
    """g_2 of eq. (67) for isotropic friction c = c_x (= c_y).

    g21 = n c x_h + c l sum_j (2n - 2j + 1) cos(theta_j), g22 likewise with y_h and sin:
    c times the sum of the links' CM coordinates.
    """
    q = as_vector(q, params.n + 2, "q")
    n, c, half = params.n, params.c_x, params.half_length
    theta = link_angles(q)
    weights = 2 * n - 2 * np.arange(1, n + 1) + 1
    return np.array([n * c * q[0] + c * half * weights @ np.cos(theta),
                     n * c * q[1] + c * half * weights @ np.sin(theta)])
