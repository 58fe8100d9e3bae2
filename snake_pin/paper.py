"""The paper's closed-form model (Section II, eqs. 3-20), independent of Pinocchio.

Plain numpy, the cross-check of :class:`snake_pin.model.Snake`: ``tests/test_paper.py``
compares the two on random states of random heterogeneous robots. The printed equations
(identical links, CM in the middle) are generalised to per-link lengths, masses,
inertias, CM offsets and friction (eqs. 3-4, 5-7, 8-9, 10-14, 15-16, 19, 20) as derived in
:ref:`derivation-paper`. Configurations are the paper's ``q = [x_h, y_h, theta_1, phi]``
(n + 2 numbers, m and rad), ``q-bar = [x_h, y_h, theta]`` (eq. 17), velocities their plain
time derivatives. Every function raises :class:`~snake_pin.exceptions.ParameterError`
for a ``params`` that is not a SnakeParams or an ``n`` that is not an integer >= 2, and
:class:`~snake_pin.exceptions.ConfigurationError` for a ``q``, ``dq`` or ``theta`` that is
not a vector of n + 2 (n for theta) finite numbers.
"""

from __future__ import annotations

import numpy as np

from ._validation import as_vector, check_params, integer
from .exceptions import ConfigurationError, ParameterError
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


def _theta(params: object, theta: object) -> tuple[SnakeParams, np.ndarray]:
    """``params`` checked and ``theta`` as its n finite link angles."""
    checked = check_params(params)
    return checked, as_vector(theta, checked.n, "theta")


def _q(params: object, q: object, name: str = "q") -> tuple[SnakeParams, np.ndarray]:
    """``params`` checked and ``q`` as its n + 2 finite coordinates."""
    checked = check_params(params)
    return checked, as_vector(q, checked.n + 2, name)


def k_matrix(params: SnakeParams) -> np.ndarray:
    """Return K of eq. (4), per link: ``K_ij = 2l_j`` (j < i), ``d_i`` (j = i), else 0.

    Link i's CM is ``p_i = p_h + sum_j K_ij e_j``, ``e_j = (cos theta_j, sin theta_j)``.

    Parameters
    ----------
    params : SnakeParams
        The robot (link lengths 2l_j and CM offsets d_i are read).

    Returns
    -------
    numpy.ndarray, shape (n, n)
        Lower-triangular K [m].
    """
    check_params(params)
    lengths = params.link_lengths
    k = np.tril(np.broadcast_to(lengths, (params.n, params.n)), -1)
    k[np.diag_indices(params.n)] = params.com_offsets
    return k


def l_matrix(n: int) -> np.ndarray:
    """Return L of eq. (17): lower-triangular ones, ``theta = L [theta_1, phi]``.

    Parameters
    ----------
    n : int
        Number of links.

    Returns
    -------
    numpy.ndarray, shape (n, n)
        Ones on and below the diagonal, zeros above.
    """
    n = integer(n, "n", low=2)
    return np.tril(np.ones((n, n)))


def jacobian_q(n: int) -> np.ndarray:
    """Return ``J_{q-bar q} = blockdiag(I_2, L)`` of eq. (17), mapping q' to q-bar'.

    Parameters
    ----------
    n : int
        Number of links.

    Returns
    -------
    numpy.ndarray, shape (n + 2, n + 2)
        The constant Jacobian from paper coordinates to ``[x_h, y_h, theta_1 .. theta_n]``.
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
        Configuration ``[x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad...]
        (n >= 2).

    Returns
    -------
    numpy.ndarray, shape (n,)
        theta_1 .. theta_n [rad], head first.

    Raises
    ------
    ConfigurationError
        ``q`` is not a vector of at least 4 finite numbers.
    """
    try:
        vector = np.asarray(q, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigurationError("q must be a vector of numbers") from exc
    if vector.ndim != 1 or vector.size < 4:
        raise ConfigurationError(f"q must be a vector of n + 2 >= 4 numbers, "
                                 f"got shape {vector.shape}")
    if not np.all(np.isfinite(vector)):
        raise ConfigurationError("q has non-finite entries")
    return _link_angles(vector)


def _link_angles(q: np.ndarray) -> np.ndarray:
    """:func:`link_angles` of a checked q."""
    return q[2] + np.concatenate([[0.0], np.cumsum(q[3:])])


def jacobian_xy(params: SnakeParams, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return ``J_{q-bar x}`` and ``J_{q-bar y}`` of eq. (7): q-bar' to the CM velocities.

    Parameters
    ----------
    params : SnakeParams
        The robot.
    theta : numpy.ndarray, shape (n,)
        Link angles [rad] (:func:`link_angles`).

    Returns
    -------
    jx, jy : numpy.ndarray, shape (n, n + 2)
        Rows i map ``q-bar' = [x_h', y_h', theta']`` to link i's CM velocity along the
        world x and y axes [m/s].
    """
    params, theta = _theta(params, theta)
    n = params.n
    k = k_matrix(params)
    jx = np.hstack([np.ones((n, 1)), np.zeros((n, 1)), -k @ np.diag(np.sin(theta))])
    jy = np.hstack([np.zeros((n, 1)), np.ones((n, 1)), k @ np.diag(np.cos(theta))])
    return jx, jy


def inertia_matrix_bar(params: SnakeParams, theta: np.ndarray) -> np.ndarray:
    """Return H-bar of eq. (9), the inertia matrix in q-bar coordinates.

    ``H-bar = Jx^T M Jx + Jy^T M Jy + diag(0, 0, J_1, ..., J_n)`` with ``M = diag(m_i)``.

    Parameters
    ----------
    params : SnakeParams
        The robot.
    theta : numpy.ndarray, shape (n,)
        Link angles [rad].

    Returns
    -------
    numpy.ndarray, shape (n + 2, n + 2)
        Symmetric positive definite H-bar [kg, kg m, kg m^2 blocks].
    """
    params, theta = _theta(params, theta)
    jx, jy = jacobian_xy(params, theta)
    m = params.masses[:, None]
    j_bar = np.diag(np.r_[0.0, 0.0, params.inertias])
    return jx.T @ (m * jx) + jy.T @ (m * jy) + j_bar


def inertia_matrix(params: SnakeParams, q: np.ndarray) -> np.ndarray:
    """Return H of eq. (19), the inertia matrix in paper coordinates.

    ``H = J_{q-bar q}^T H-bar J_{q-bar q}``; Pinocchio's CRBA in
    :meth:`snake_pin.model.Snake.inertia_matrix` must agree with it.

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
    """Return W-bar of eq. (16), the centripetal matrix in q-bar coordinates.

    ``W-bar = J_{q-bar x}^T M J_x + J_{q-bar y}^T M J_y`` with ``M = diag(m_i)``;
    ``J_x = -K diag(cos theta)`` and ``J_y = -K diag(sin theta)`` (padded with two zero
    columns) map ``theta'^2`` to the centripetal part of the CM accelerations.

    Parameters
    ----------
    params : SnakeParams
        The robot.
    theta : numpy.ndarray, shape (n,)
        Link angles [rad].

    Returns
    -------
    numpy.ndarray, shape (n + 2, n + 2)
        W-bar; the Coriolis term is ``W-bar (q-bar')^2`` (elementwise square).
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
    """Return the Coriolis/centrifugal term ``W diag(J dq) J dq`` of eq. (18).

    ``W = J_{q-bar q}^T W-bar`` and ``J = J_{q-bar q}``.

    Parameters
    ----------
    params : SnakeParams
        The robot.
    q : array_like, shape (n + 2,)
        Configuration [m, m, rad, rad...].
    dq : array_like, shape (n + 2,)
        Its time derivative [m/s, m/s, rad/s, rad/s...].

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
    """Return the friction matrix ``C-bar = C_tr + C_rot`` of eqs. (11)-(14).

    Parameters
    ----------
    params : SnakeParams
        The robot (c_x, c_y, c_theta per link).
    theta : numpy.ndarray, shape (n,)
        Link angles [rad].

    Returns
    -------
    numpy.ndarray, shape (n + 2, n + 2)
        Symmetric positive semi-definite C-bar in q-bar coordinates.
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
    """Return the friction matrix C in paper coordinates (after eq. 19).

    ``C = J_{q-bar q}^T C-bar J_{q-bar q}``; the dissipation function is
    ``dq^T C dq / 2`` and the friction forces are ``-C dq``.

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
    """Return the bias h of eq. (20): ``W diag(J dq) J dq + C dq``.

    The dynamics read ``H q'' + h = E tau``; Pinocchio's
    :meth:`snake_pin.model.Snake.bias` must agree with it.

    Parameters
    ----------
    params : SnakeParams
        The robot.
    q : array_like, shape (n + 2,)
        Configuration [m, m, rad, rad...].
    dq : array_like, shape (n + 2,)
        Its time derivative [m/s, m/s, rad/s, rad/s...].

    Returns
    -------
    numpy.ndarray, shape (n + 2,)
        Coriolis/centrifugal plus viscous-friction generalised forces [N, N, N m, N m...].
    """
    coriolis_term = coriolis(params, q, dq)  # checks params, q and dq
    return coriolis_term + friction_matrix(params, q) @ as_vector(dq, params.n + 2, "dq")


def g2(params: SnakeParams, q: np.ndarray) -> np.ndarray:
    """Return g_2 of eq. (67) for isotropic friction (``c_x,i = c_y,i = c_i`` on every link).

    ``g_2 = sum_i c_i p_i``, the friction-weighted sum of the links' CM positions: total
    momentum plus g_2 is conserved, since ``d/dt sum_i m_i p_i' = -sum_i c_i p_i'``. For
    equal links this is the printed ``g21 = n c x_h + c l sum_j (2n - 2j + 1) cos(theta_j)``
    (and g22 with y_h and sin).

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
