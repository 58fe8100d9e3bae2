"""The Lyapunov-like law at velocity level, for friction-dominated robots (wheels).

When friction dominates inertia (time constant m / c_y much shorter than the motion, as
on wheels, where it is effectively zero), the unactuated rows of (20) reduce to a force
balance: C_uu u' + C_ua a' = 0, u the unactuated coordinates (w, plus phi_k of a passive
joint k) and a the actuated joint angles. The head then moves with the joints through the
quasi-static connection

    u' = J(q) a',   J = -C_uu^-1 C_ua        (C of eqs. 11-13, the viscous model).

Under it, V of (83) is a quadratic function of the actuated joint velocities:

    V(a') = ||J_w a' - (w_r' + K_w1 e_w)||^2_{K_w2} + ||a' - phi_r,a'||^2_{K_phi,a}
            + ||J_k a' - phi_r,k'||^2_{K_phi,k}

(J_w, J_k: the w rows and the passive rows of J), since s = e_w' + K_w1 e_w =
w_r' + K_w1 e_w - w'. The law takes the minimiser a'* of V (normal equations, positive
definite because K_phi is), integrates it into a joint reference and lets a PD servo of
bandwidth omega_s on each actuated joint realise it (as the servo-driven joints of the
paper's V-REP robot do). Passive joints get no torque. V is not driven to zero - the
underactuation leaves a positive minimum - but each control step commands the joint
velocity of least V, and the head follows through J.

Per-link robots need nothing special in the law: C is built link by link (each link's own
c_x, c_y, c_theta at its own centre of mass), and the only gains with physical units, the
servos', scale per joint with the links it joins (:func:`servo_gains`). Every link must
have c_x, c_y > 0: a link without friction is one whose inertia is not negligible.

:class:`~snake_pin.control.lyapunov.LyapunovController` is the acceleration-level form of
the same V and gains; it needs a model that predicts accelerations, which sticking wheels
do not honour (see the engine section of the report).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

from .._validation import finite_number
from ..exceptions import ParameterError, SingularPostureError
from ..gaits import Serpenoid
from ..model import Snake
from ..params import SnakeParams
from .base import Controller, gait_for
from .gains import gain_matrix
from .lyapunov import head_first_reference
from .reference import HeadReference

__all__ = ["QuasiStaticLyapunovController", "servo_gains"]


def servo_gains(params: SnakeParams, bandwidth: float) -> tuple[np.ndarray, np.ndarray]:
    """(K_p, K_d) per joint (n - 1 each) of critically damped servos of ``bandwidth`` [rad/s].

    With ``omega = bandwidth``::

        K_p,k = omega^2 I_k,   K_d,k = 2 omega I_k,
        I_k = (m_k (2 l_k)^2 + m_k+1 (2 l_k+1)^2) / 2,

    the mean inertia scale of the two links joint k joins (each about its own end, as a
    point mass at the far end would be). It scales with each link's mass times its length
    squared; on equal links every ``I_k`` is ``m (2l)^2``.

    Parameters
    ----------
    params : SnakeParams
        The robot (link masses [kg] and full lengths 2l [m]).
    bandwidth : float
        Servo bandwidth ``omega`` [rad/s].

    Returns
    -------
    tuple of numpy.ndarray
        ``K_p`` [N m/rad] and ``K_d`` [N m s/rad], each of length n - 1.
    """
    link = params.masses * params.link_lengths**2
    inertia = 0.5 * (link[:-1] + link[1:])
    return bandwidth**2 * inertia, 2.0 * bandwidth * inertia


class QuasiStaticLyapunovController(Controller):
    """Velocity-level minimiser of V (83) through the quasi-static connection, with servos.

    Parameters
    ----------
    snake
        The robot and its viscous friction model (identified coefficients on the engine).
    reference, gait
        As for the acceleration-level controller (w_r = [0.1 t, 0, pi], serpenoid of VI.2).
    k_w1, k_w2, k_phi
        Gains of (84).
    servo_bandwidth
        omega_s [rad/s] of the joint servos: joint k gets K_p,k = omega_s^2 I_k and
        K_d,k = 2 omega_s I_k (critically damped on I_k), with I_k the mean of
        m_i (2l_i)^2 over the two links it joins (i = k, k + 1): the inertia scale of a
        link about its joint, per link, so a heavy, long head gets stiffer servos next to
        it. On equal links I_k = m (2l)^2 for every joint (the paper's robots).
    max_lead
        Largest distance [rad] the integrated joint reference may run ahead of the joint.
    control_dt
        The controller's sampling period [s] (the joint reference is integrated over it).

    Raises
    ------
    ParameterError
        Every joint is passive, a link has no lateral or longitudinal friction, or a gain
        or number is invalid.
    """

    name = "lyapunov_velocity"

    def __init__(self, snake: Snake, reference: HeadReference | None = None,
                 gait: Serpenoid | None = None, *, k_w1: object = (2.0, 2.0, 3.0),
                 k_w2: object = (400.0, 400.0, 45.0), k_phi: object | None = None,
                 servo_bandwidth: float = 20.0, max_lead: float = 0.3,
                 control_dt: float = 1e-3) -> None:
        params = snake.params
        n = params.n
        if not params.actuated:
            raise ParameterError("every joint is passive: there is nothing to control")
        for key in ("c_x", "c_y"):
            # friction must dominate inertia on every link for the force balance to hold
            for i in np.flatnonzero(params.per_link(key) <= 0):
                where = "" if not isinstance(getattr(params, key), tuple) else f"link {i + 1}: "
                raise ParameterError(f"{where}the quasi-static connection needs c_x > 0 and "
                                     f"c_y > 0 on every link, got {key} = 0")
        self.snake = snake
        self.reference = reference or head_first_reference()
        self.gait = gait_for(n, gait, Serpenoid(n, np.pi / 6, 1.5, 2.0))
        self.k_w1 = gain_matrix(k_w1, 3, "K_w1")
        k_w2_d = np.diag(gain_matrix(k_w2, 3, "K_w2"))
        k_phi_d = np.diag(gain_matrix(np.r_[10.0, np.full(n - 2, 20.0)] if k_phi is None
                                      else k_phi, n - 1, "K_phi"))
        self._u = np.array([0, 1, 2] + [2 + k for k in params.passive])
        self._a = np.array([2 + k for k in params.actuated])
        size = n + 2  # flat indices of the C_uu and C_ua blocks
        self._flat_uu = (self._u[:, None] * size + self._u[None, :]).ravel()
        self._flat_ua = (self._u[:, None] * size + self._a[None, :]).ravel()
        self._w_u = np.r_[k_w2_d, k_phi_d[self._u[3:] - 3]]
        self._w_a = k_phi_d[self._a - 3]
        omega = finite_number(servo_bandwidth, "servo_bandwidth", positive=True)
        self.k_p, self.k_d = servo_gains(params, omega)
        self._k_p_a, self._k_d_a = self.k_p[self._a - 3], self.k_d[self._a - 3]
        self.max_lead = finite_number(max_lead, "max_lead", positive=True)
        self.dt = finite_number(control_dt, "control_dt", positive=True)
        self._reference_a: np.ndarray | None = None
        self._last: dict[str, float] = {}

    def reset(self) -> None:
        """Forget the integrated joint reference before a new run."""
        self._reference_a = None

    def connection(self, q: np.ndarray) -> np.ndarray:
        """``J(q)`` with ``u' = J a'`` (rows: x_h, y_h, theta_1, passive phi; columns: actuated).

        Parameters
        ----------
        q : numpy.ndarray
            Configuration, length n + 2.

        Returns
        -------
        numpy.ndarray
            ``J``, shape (3 + passive joints, actuated joints).

        Raises
        ------
        SingularPostureError
            The friction block ``C_uu`` is singular at ``q``.
        """
        c = self.snake.friction.matrix(q)
        m, k = len(self._u), len(self._a)
        c_uu = c.take(self._flat_uu).reshape(m, m)
        c_ua = c.take(self._flat_ua).reshape(m, k)
        _, _, solved, info = lapack.dgesv(c_uu, c_ua)  # LAPACK: a third of numpy's cost
        if info != 0:
            raise SingularPostureError(f"C_uu is singular (LAPACK info {info})")
        return -solved

    def velocity_command(self, x: np.ndarray, t: float) -> tuple[np.ndarray, float]:
        """``(a'*, V(a'*))``: the actuated joint velocity of least V at (x, t), and that V.

        Parameters
        ----------
        x : numpy.ndarray
            State ``x = [q, dq]``, length 2(n + 2).
        t : float
            Time [s].

        Returns
        -------
        tuple of (numpy.ndarray, float)
            The actuated joints' velocities [rad/s] and V at them.

        Raises
        ------
        SingularPostureError
            The connection is singular or its normal equations are not positive definite.
        """
        nq = self.snake.nq
        q = x[:nq]
        jac = self.connection(q)
        w_r, dw_r, _ = self.reference(t)
        _, dphi_r, _ = self.gait.derivatives(t)
        target_u = np.concatenate((dw_r + self.k_w1 @ (w_r - q[:3]), dphi_r[self._u[3:] - 3]))
        target_a = dphi_r[self._a - 3]
        weighted = jac.T * self._w_u
        normal = weighted @ jac + np.diag(self._w_a)
        rate, info = lapack.dposv(normal, weighted @ target_u + self._w_a * target_a)[1:]
        if info != 0:
            raise SingularPostureError(f"normal equations not positive definite (info {info})")
        residual_u, residual_a = jac @ rate - target_u, rate - target_a
        value = float(residual_u @ (self._w_u * residual_u) + residual_a @ (self._w_a * residual_a))
        return rate, value

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        nq = self.snake.nq
        joints = x[self._a]
        rate, value = self.velocity_command(x, t)
        if self._reference_a is None:
            self._reference_a = joints.copy()
        lead = np.clip(self._reference_a + rate * self.dt - joints, -self.max_lead, self.max_lead)
        self._reference_a = joints + lead
        tau = np.zeros(self.snake.n - 1)
        tau[self._a - 3] = self._k_p_a * lead + self._k_d_a * (rate - x[nq + self._a])
        self._last = {"V": value}
        return tau

    def signals(self) -> dict[str, float]:
        """Diagnostics of the last call.

        Returns
        -------
        dict of str to float
            ``V``: the least V of the last call's velocity command.
        """
        return self._last
