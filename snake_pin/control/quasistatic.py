"""The Lyapunov-like law at velocity level, for friction-dominated robots (wheels): the
joint velocities of least V through the quasi-static connection, realised by PD servos
(:ref:`derivation-quasistatic`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.linalg import lapack

from .._blas import posv, syrk
from .._options import documented, option
from .._validation import check_params, finite_number, instance
from ..exceptions import ParameterError, SingularPostureError
from ..gaits import Serpenoid
from ..model import Snake
from ..params import SnakeParams
from ._options import check_fields, tracking_gain
from .base import ReferenceLaw
from .gains import default_k_phi, gain_matrix
from .reference import HeadReference, head_first_reference

__all__ = ["QuasiStaticLyapunovController", "QuasiStaticOptions", "servo_gains"]

@documented
@dataclass(frozen=True)
class QuasiStaticOptions:
    """Options of :class:`QuasiStaticLyapunovController` (validated; gains as in
    :class:`~snake_pin.control.lyapunov.LyapunovOptions`)."""

    k_w1: object = tracking_gain("k_w1")
    k_w2: object = tracking_gain("k_w2")
    k_phi: object = tracking_gain("k_phi")
    servo_bandwidth: float = option(20.0, "joint servo bandwidth", unit="rad/s", low=0.0,
                                    open_low=True)
    max_lead: float = option(0.3, "largest lead of the servo reference", unit="rad", low=0.0,
                             open_low=True)
    control_dt: float = option(1e-3, "control period", unit="s", low=0.0, open_low=True)

    def __post_init__(self) -> None:
        check_fields(self)


def servo_gains(params: SnakeParams, bandwidth: float) -> tuple[np.ndarray, np.ndarray]:
    """(K_p, K_d) per joint of critically damped servos (:ref:`derivation-quasistatic`).

    Parameters
    ----------
    params, bandwidth : SnakeParams, float
        The robot and the servo bandwidth ``omega`` [rad/s].

    Returns
    -------
    tuple of numpy.ndarray
        ``K_p`` [N m/rad] and ``K_d`` [N m s/rad], each of length n - 1.

    Raises
    ------
    ParameterError
        ``params`` is not a SnakeParams or ``bandwidth`` is not a positive number.
    """
    check_params(params)
    bandwidth = finite_number(bandwidth, "bandwidth", positive=True)
    link = params.masses * params.link_lengths**2
    inertia = 0.5 * (link[:-1] + link[1:])
    return bandwidth**2 * inertia, 2.0 * bandwidth * inertia


class QuasiStaticLyapunovController(ReferenceLaw):
    """Velocity-level minimiser of V (83) through the quasi-static connection, with servos;
    its signal ``V`` is the least V of each call's command (NaN before a call).

    Parameters
    ----------
    snake, reference, gait
        The robot with its viscous friction; the others as for
        :class:`~snake_pin.control.lyapunov.LyapunovController`.
    options, **overrides
        :class:`QuasiStaticOptions` (default: the defaults) and fields of it to change.

    Raises
    ------
    ParameterError
        A bad robot (no motor, a link without c_x or c_y), reference, gait or options.
    """

    name = "lyapunov_velocity"

    def __init__(self, snake: Snake, reference: HeadReference | None = None,
                 gait: Serpenoid | None = None, options: QuasiStaticOptions | None = None,
                 **overrides: object) -> None:
        params = instance(snake, Snake, "snake").params
        for key in ("c_x", "c_y"):
            # friction must dominate inertia on every link for the force balance to hold
            for i in np.flatnonzero(params.per_link(key) <= 0):
                where = "" if not isinstance(getattr(params, key), tuple) else f"link {i + 1}: "
                raise ParameterError(f"{where}the quasi-static connection needs c_x > 0 and "
                                     f"c_y > 0 on every link, got {key} = 0")
        self.options = opts = self._bind(snake, reference, gait, (np.pi / 6, 1.5, 2.0),
                                         QuasiStaticOptions, options, overrides,
                                         head_first_reference)
        n = params.n
        self.k_w1 = gain_matrix(opts.k_w1, 3, "K_w1")
        k_w2_d = np.diag(gain_matrix(opts.k_w2, 3, "K_w2"))
        k_phi_d = np.diag(gain_matrix(default_k_phi(n - 1) if opts.k_phi is None
                                      else opts.k_phi, n - 1, "K_phi"))
        self._u = np.array([0, 1, 2] + [2 + k for k in params.passive])
        self._a = np.array([2 + k for k in params.actuated])
        self._w_u = np.r_[k_w2_d, k_phi_d[self._u[3:] - 3]]
        self._w_a = k_phi_d[self._a - 3]
        self.k_p, self.k_d = servo_gains(params, opts.servo_bandwidth)
        self._k_p_a, self._k_d_a = self.k_p[self._a - 3], self.k_d[self._a - 3]
        self.max_lead, self.dt = opts.max_lead, opts.control_dt
        self.reset()
        self._build_law()

    def _build_law(self) -> None:
        """Constant arrays of the hot path (friction twin, gathers, weights, time map)."""
        params, nq = self.snake.params, self.snake.nq
        u, a = self._u, self._a
        m, k = len(u), len(a)
        # C_uu^-1 C_ua = -J: one CRBA of the damping twin and one solve (the upper triangle
        # Pinocchio fills; :ref:`derivation-quasistatic`); massless wheels are left out
        twin = self.snake.friction.twin
        self._twin, self._twin_data = twin, twin.createData()
        self._twin_q = np.zeros(twin.nq)  # [q, 0_w]
        chain = np.arange(nq)
        wheels = np.array([v for v in range(nq, twin.nv) if twin.inertias[v + 1].mass != 0.0],
                          dtype=int)  # joint v + 1 moves velocity v
        rows = np.r_[chain[u], wheels]
        cols = np.r_[rows, chain[a]]
        self._gather = (np.minimum.outer(rows, cols) * twin.nv
                        + np.maximum.outer(rows, cols)).ravel()
        self._block = len(rows)
        # V's weights as square roots (J enters as -sqrt(W_u) C_uu^-1 C_ua) and the normal
        # matrix's diagonal, in LAPACK's column order
        self._sqrt_w_u = np.sqrt(self._w_u)
        self._neg_sqrt_w_u = -self._sqrt_w_u[:, None]
        self._diag_w_a = np.asfortranarray(np.diag(self._w_a))
        # the time-only terms of :meth:`_time_terms` from reference rows, weights applied once
        sqrt_w = self._sqrt_w_u
        law = np.zeros((3 * nq, m + 2 * k))
        law[:3, :3] = self.k_w1.T * sqrt_w[:3]
        law[nq:nq + 3, :3] = np.diag(sqrt_w[:3])
        law[nq + u[3:], np.arange(3, m)] = sqrt_w[3:]
        law[nq + a, np.arange(m, m + k)] = self._w_a
        law[nq + a, np.arange(m + k, m + 2 * k)] = 1.0
        self._k_w1_weighted = sqrt_w[:3, None] * self.k_w1  # sqrt(W_w) K_w1
        self._joint_rates = nq + a  # indices of the actuated joints' velocities in x
        self._law_time = law
        self._m = m
        self._all_actuated = k == params.n - 1

    def _time_terms(self, times: np.ndarray) -> np.ndarray:
        """Rows ``[sqrt(W_u) [w_r' + K_w1 w_r, phi_r,passive'], W_a phi_r,actuated',
        phi_r,actuated']``, one per time (one time directly: cheaper than a block)."""
        if len(times) != 1:
            return super()._time_terms(times)
        t = float(times[0])
        w_r, dw_r, _ = self.reference(t)
        dphi_r = self.gait.derivatives(t)[1]
        m, k, sqrt_w = self._m, len(self._a), self._sqrt_w_u
        row = np.empty((1, m + 2 * k))
        row[0, :3] = sqrt_w[:3] * (self.k_w1 @ w_r + dw_r)
        row[0, 3:m] = sqrt_w[3:] * dphi_r[self._u[3:] - 3]
        row[0, m + k:] = dphi_r[self._a - 3]
        row[0, m:m + k] = self._w_a * row[0, m + k:]
        return row

    def reset(self) -> None:
        """Forget the integrated joint reference and the last call before a new run."""
        self._reference_a: np.ndarray | None = None
        self._last: tuple[np.ndarray, ...] | None = None

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
        return -self._solved(q)

    def _solved(self, q: np.ndarray) -> np.ndarray:
        """``C_uu^-1 C_ua`` at q (``-J``)."""
        twin_q = self._twin_q
        twin_q[:self.snake.nq] = q
        mass = pin.crba(self._twin, self._twin_data, twin_q, pin.Convention.WORLD)
        block = self._block
        system = mass.take(self._gather).reshape(block, -1)
        _, _, solved, info = lapack.dgesv(system[:, :block], system[:, block:],
                                          overwrite_a=1, overwrite_b=1)
        if info != 0:
            raise SingularPostureError(f"C_uu is singular (LAPACK info {info})")
        return solved[:self._m]

    def _rate(self, x: np.ndarray, t: float) -> np.ndarray:
        """``a'*`` at (x, t); keeps what V needs for :meth:`signals`."""
        m, k = self._m, len(self._a)
        weighted = self._solved(x[:self.snake.nq]) * self._neg_sqrt_w_u  # sqrt(W_u) J
        time = self._time_row(t)
        target_u = time[:m].copy()  # sqrt(W_u) [w_r' + K_w1 (w_r - w), phi_r,passive']
        target_u[:3] -= self._k_w1_weighted @ x[:3]
        normal = self._diag_w_a.copy(order="F")
        syrk(1.0, weighted, 1.0, normal, 1)()
        rhs = weighted.T @ target_u
        rhs += time[m:m + k]  # W_a phi_r,actuated'
        target_a = time[m + k:]
        info = posv(normal, rhs)()[2]
        rate = rhs
        if info != 0:
            raise SingularPostureError(f"normal equations not positive definite (info {info})")
        self._last = (weighted, rate, target_u, target_a)
        return rate

    def _value(self) -> float:
        """V at the last call's command (the weighted residuals' squared norm)."""
        if self._last is None:
            return float("nan")
        weighted, rate, target_u, target_a = self._last
        residual_u, residual_a = weighted @ rate - target_u, rate - target_a
        return float(residual_u @ residual_u + residual_a @ (self._w_a * residual_a))

    def velocity_command(self, x: np.ndarray, t: float) -> tuple[np.ndarray, float]:
        """``(a'*, V(a'*))``: the actuated joint velocity of least V at (x, t), and that V.

        Parameters
        ----------
        x, t : numpy.ndarray, float
            State ``x = [q, dq]`` (length 2(n + 2)) and time [s].

        Returns
        -------
        tuple of (numpy.ndarray, float)
            The actuated joints' velocities [rad/s] and V at them.

        Raises
        ------
        SingularPostureError
            The connection or its normal equations are singular.
        """
        rate = self._rate(x, t)
        return rate.copy(), self._value()

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        a = self._a
        joints = x[a]
        rate = self._rate(x, t)
        if self._reference_a is None:
            self._reference_a = joints
        lead = self._reference_a + rate * self.dt
        lead -= joints
        max_lead = self.max_lead
        np.minimum(lead, max_lead, out=lead)
        np.maximum(lead, -max_lead, out=lead)
        self._reference_a = joints + lead
        servo = rate - x[self._joint_rates]  # a new array: rate is kept for signals()
        servo *= self._k_d_a
        lead *= self._k_p_a
        lead += servo  # K_p (phi_ref - phi) + K_d (a'* - phi')
        if self._all_actuated:
            return lead
        tau = np.zeros(self.snake.n - 1)
        tau[a - 3] = lead
        return tau

    def signals(self) -> dict[str, float]:
        return {"V": self._value()}
