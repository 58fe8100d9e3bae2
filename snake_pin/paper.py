"""The paper's closed-form model (Section II, eqs. 3-20), independent of Pinocchio.

Plain numpy, the cross-check of :class:`snake_pin.model.Snake`, with the printed
equations generalised to per-link parameters as derived in :ref:`derivation-paper`.
Configurations are ``q = [x_h, y_h, theta_1, phi]`` and ``q-bar = [x_h, y_h, theta]``
(eq. 17). Every function raises :class:`~snake_pin.exceptions.ParameterError` for a
``params`` that is not a SnakeParams or an ``n`` that is not an integer >= 2, and
:class:`~snake_pin.exceptions.ConfigurationError` for a ``q``, ``dq`` or ``theta`` that is
not a vector of n + 2 (n for theta) finite numbers.
"""

from __future__ import annotations

import numpy as np

from ._validation import as_vector, check_params, integer, vector
from .exceptions import ConfigurationError, ParameterError
from .params import SnakeParams

__all__ = ["actuation_matrix", "bias", "coriolis", "friction_matrix", "friction_matrix_bar",
           "g2", "inertia_matrix", "inertia_matrix_bar", "jacobian_q", "jacobian_xy",
           "k_matrix", "l_matrix", "link_angles", "w_matrix_bar"]


def _theta(params: object, theta: object) -> tuple[SnakeParams, np.ndarray]:
    """``params`` checked and ``theta`` as its n finite link angles."""
    checked = check_params(params)
    return checked, as_vector(theta, checked.n, "theta")


def _q(params: object, q: object, name: str = "q") -> tuple[SnakeParams, np.ndarray]:
    """``params`` checked and ``q`` as its n + 2 finite coordinates."""
    checked = check_params(params)
    return checked, as_vector(q, checked.n + 2, name)


def k_matrix(params: SnakeParams) -> np.ndarray:
    """K of eq. (4): ``K_ij = 2l_j`` (j < i), ``d_i`` (j = i), 0 above the diagonal.

    Parameters
    ----------
    params : SnakeParams
        The robot.

    Returns
    -------
    numpy.ndarray, shape (n, n)
        K [m], lower-triangular.
    """
    check_params(params)
    lengths = params.link_lengths
    k = np.tril(np.broadcast_to(lengths, (params.n, params.n)), -1)
    k[np.diag_indices(params.n)] = params.com_offsets
    return k


def l_matrix(n: int) -> np.ndarray:
    """L of eq. (17): lower-triangular ones, ``theta = L [theta_1, phi]``.

    Parameters
    ----------
    n : int
        Number of links, >= 2.

    Returns
    -------
    numpy.ndarray, shape (n, n)
        L.
    """
    n = integer(n, "n", low=2)
    return np.tril(np.ones((n, n)))


def jacobian_q(n: int) -> np.ndarray:
    """``J_{q-bar q} = blockdiag(I_2, L)`` of eq. (17), mapping q' to q-bar' (constant).

    Parameters
    ----------
    n : int
        Number of links, >= 2.

    Returns
    -------
    numpy.ndarray, shape (n + 2, n + 2)
        The Jacobian.
    """
    n = integer(n, "n", low=2)
    out = np.zeros((n + 2, n + 2))
    out[:2, :2] = np.eye(2)
    out[2:, 2:] = l_matrix(n)
    return out


def link_angles(q: np.ndarray) -> np.ndarray:
    """Return the absolute link angles ``theta_i = theta_1 + sum_{j<i} phi_j``.

    Parameters
    ----------
    q : array_like, shape (n + 2,)
        Configuration (n >= 2).

    Returns
    -------
    numpy.ndarray, shape (n,)
        theta_1 .. theta_n [rad], head first.

    Raises
    ------
    ConfigurationError
        ``q`` is not a vector of at least 4 finite numbers.
    """
    checked = vector(q, "q")
    if checked.size < 4:
        raise ConfigurationError(f"q must be a vector of n + 2 >= 4 numbers, got {checked.size}")
    return _link_angles(checked)


def _link_angles(q: np.ndarray) -> np.ndarray:
    """:func:`link_angles` of a checked q."""
    return q[2] + np.concatenate([[0.0], np.cumsum(q[3:])])


def jacobian_xy(params: SnakeParams, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``J_{q-bar x}``, ``J_{q-bar y}`` of eq. (7): row i maps q-bar' to link i's CM velocity
    along world x and y.

    Parameters
    ----------
    params, theta : SnakeParams, array_like
        The robot and its n absolute link angles [rad].

    Returns
    -------
    tuple of numpy.ndarray, shape (n, n + 2) each
        ``(J_{q-bar x}, J_{q-bar y})``.
    """
    params, theta = _theta(params, theta)
    n = params.n
    k = k_matrix(params)
    jx = np.hstack([np.ones((n, 1)), np.zeros((n, 1)), -k @ np.diag(np.sin(theta))])
    jy = np.hstack([np.zeros((n, 1)), np.ones((n, 1)), k @ np.diag(np.cos(theta))])
    return jx, jy


def inertia_matrix_bar(params: SnakeParams, theta: np.ndarray) -> np.ndarray:
    """H-bar of eq. (9): ``Jx^T M Jx + Jy^T M Jy + diag(0, 0, J_i)``, M = diag(m_i).

    Parameters
    ----------
    params, theta : SnakeParams, array_like
        The robot and its n absolute link angles [rad].

    Returns
    -------
    numpy.ndarray, shape (n + 2, n + 2)
        H-bar, symmetric positive definite.
    """
    params, theta = _theta(params, theta)
    jx, jy = jacobian_xy(params, theta)
    m = params.masses[:, None]
    j_bar = np.diag(np.r_[0.0, 0.0, params.inertias])
    return jx.T @ (m * jx) + jy.T @ (m * jy) + j_bar


def inertia_matrix(params: SnakeParams, q: np.ndarray) -> np.ndarray:
    """Return H of eq. (19), ``J_{q-bar q}^T H-bar J_{q-bar q}`` (paper coordinates).

    Parameters
    ----------
    params : SnakeParams
        The robot.
    q : array_like, shape (n + 2,)
        Configuration [m, m, rad, rad...].

    Returns
    -------
    numpy.ndarray, shape (n + 2, n + 2)
        Symmetric positive definite H.
    """
    params, q = _q(params, q)
    jq = jacobian_q(params.n)
    return jq.T @ inertia_matrix_bar(params, _link_angles(q)) @ jq


def w_matrix_bar(params: SnakeParams, theta: np.ndarray) -> np.ndarray:
    """W-bar of eq. (16), ``J_{q-bar x}^T M J_x + J_{q-bar y}^T M J_y``: the Coriolis term is
    ``W-bar (q-bar')^2``, with ``J_x = -K diag(cos theta)``, ``J_y = -K diag(sin theta)``
    (two zero columns first) mapping ``theta'^2`` to the centripetal CM accelerations.

    Parameters
    ----------
    params, theta : SnakeParams, array_like
        The robot and its n absolute link angles [rad].

    Returns
    -------
    numpy.ndarray, shape (n + 2, n + 2)
        W-bar.
    """
    params, theta = _theta(params, theta)
    n = params.n
    k = k_matrix(params)
    m = params.masses[:, None]
    jx, jy = jacobian_xy(params, theta)
    j_x = np.hstack([np.zeros((n, 2)), -k @ np.diag(np.cos(theta))])
    j_y = np.hstack([np.zeros((n, 2)), -k @ np.diag(np.sin(theta))])
    return jx.T @ (m * j_x) + jy.T @ (m * j_y)


def coriolis(params: SnakeParams, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Return the Coriolis term ``W diag(J dq) J dq`` of eq. (18), W = J^T W-bar, J = J_{q-bar q}.

    Parameters
    ----------
    params : SnakeParams
        The robot.
    q, dq : array_like, shape (n + 2,)
        Configuration [m, m, rad, rad...] and its time derivative.

    Returns
    -------
    numpy.ndarray, shape (n + 2,)
        Generalised forces [N, N, N m, N m...] (friction excluded).
    """
    params, q = _q(params, q)
    dq = as_vector(dq, params.n + 2, "dq")
    jq = jacobian_q(params.n)
    dq_bar = jq @ dq
    return jq.T @ w_matrix_bar(params, _link_angles(q)) @ (dq_bar * dq_bar)


def friction_matrix_bar(params: SnakeParams, theta: np.ndarray) -> np.ndarray:
    """``C-bar = C_tr + C_rot`` of eqs. (11)-(14) in q-bar coordinates.

    Parameters
    ----------
    params, theta : SnakeParams, array_like
        The robot and its n absolute link angles [rad].

    Returns
    -------
    numpy.ndarray, shape (n + 2, n + 2)
        C-bar, symmetric positive semi-definite.
    """
    params, theta = _theta(params, theta)
    c, s = np.cos(theta), np.sin(theta)
    cx, cy = params.per_link("c_x"), params.per_link("c_y")
    middle = np.block([[np.diag(cx * c**2 + cy * s**2), np.diag((cx - cy) * s * c)],
                       [np.diag((cx - cy) * s * c), np.diag(cx * s**2 + cy * c**2)]])
    jx, jy = jacobian_xy(params, theta)
    j_xy = np.vstack([jx, jy])  # eq. (14)
    c_rot = np.diag(np.r_[0.0, 0.0, params.per_link("c_theta")])
    return j_xy.T @ middle @ j_xy + c_rot


def friction_matrix(params: SnakeParams, q: np.ndarray) -> np.ndarray:
    """Return C of eq. (19), ``J_{q-bar q}^T C-bar J_{q-bar q}``: the friction force is -C dq.

    Parameters
    ----------
    params : SnakeParams
        The robot.
    q : array_like, shape (n + 2,)
        Configuration [m, m, rad, rad...].

    Returns
    -------
    numpy.ndarray, shape (n + 2, n + 2)
        Symmetric positive semi-definite C.
    """
    params, q = _q(params, q)
    jq = jacobian_q(params.n)
    return jq.T @ friction_matrix_bar(params, _link_angles(q)) @ jq


def actuation_matrix(n: int) -> np.ndarray:
    """Return the actuation matrix ``E = [O_{3 x (n-1)}; I_{n-1}]`` (after eq. 19).

    Parameters
    ----------
    n : int
        Number of links.

    Returns
    -------
    numpy.ndarray, shape (n + 2, n - 1)
        Maps the joint torques tau to generalised forces (every joint actuated).
    """
    n = integer(n, "n", low=2)
    return np.vstack([np.zeros((3, n - 1)), np.eye(n - 1)])


def bias(params: SnakeParams, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Return the bias h of eq. (20), ``W diag(J dq) J dq + C dq`` (``H q'' + h = E tau``).

    Parameters
    ----------
    params : SnakeParams
        The robot.
    q, dq : array_like, shape (n + 2,)
        Configuration [m, m, rad, rad...] and its time derivative.

    Returns
    -------
    numpy.ndarray, shape (n + 2,)
        Coriolis/centrifugal plus viscous-friction generalised forces [N, N, N m, N m...].
    """
    coriolis_term = coriolis(params, q, dq)  # checks params, q and dq
    return coriolis_term + friction_matrix(params, q) @ as_vector(dq, params.n + 2, "dq")


def g2(params: SnakeParams, q: np.ndarray) -> np.ndarray:
    """Return g_2 of eq. (67) for isotropic friction (``c_x,i = c_y,i = c_i`` on every link).

    ``g_2 = sum_i c_i p_i`` (CM positions p_i): momentum plus g_2 is conserved. For equal
    links, the printed ``g21 = n c x_h + c l sum_j (2n - 2j + 1) cos(theta_j)`` (g22: y, sin).

    Parameters
    ----------
    params : SnakeParams
        The robot; its friction must be isotropic.
    q : array_like, shape (n + 2,)
        Configuration [m, m, rad, rad...].

    Returns
    -------
    numpy.ndarray, shape (2,)
        ``[g21, g22]`` [N s].

    Raises
    ------
    ParameterError
        The robot's friction is not isotropic.
    """
    params, q = _q(params, q)
    if not params.isotropic:
        raise ParameterError("g_2 of eq. (67) needs isotropic friction (c_x = c_y on every link)")
    c = params.per_link("c_x")
    theta = _link_angles(q)
    k = k_matrix(params)
    x = q[0] + k @ np.cos(theta)
    y = q[1] + k @ np.sin(theta)
    return np.array([c @ x, c @ y])
