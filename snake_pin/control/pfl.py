"""Partial feedback linearisation of the head (Section VI.1, eqs. 68-78), sign corrected.

Derivation (eq. 70 is misprinted; the law is derived again from (27)). Solving (25) for
phi'' and substituting into (24):

    Hs w'' = -h1 + H12 H22^-1 (h2 - tau),      Hs = H11 - H12 H22^-1 H21   (27, 68)

For w'' = a we need H12 H22^-1 tau = -Hs a - h1 + H12 H22^-1 h2. With
tau = H22 [H12^+ y + (I - H12^+ H12) kappa], H12 H22^-1 tau = y whenever H12 has full
row rank (R > 0), so

    tau = H22 H12^+ (-Hs a - h1 + H12 H22^-1 h2) + H22 (I - H12^+ H12) kappa.

The printed (70) has +Hs a, which drives the head against the command. Here
a = w_r'' + K_v (w_r' - w') + K_p (w_r - w) (71), kappa = H22^-1 h2 - u with
u = -phi_r'' - R_v (phi_r' - phi') - R_p (phi_r - phi) (75, 78) and phi_r a serpenoid.

Beyond the paper, ``climb_R = gamma > 0`` uses the redundancy to climb log R: u gets
-k_d (gamma grad_phi log R - phi'), so that in the null space of H12 the joints accelerate
towards the velocity gamma grad log R (a damped gradient flow; it does not disturb
w'' = a). The report shows what it does to the breakdown.

Per-link robots: the law reads only the robot's own H and h (per-link lengths, masses,
inertias, CM offsets and friction) and the climb term the per-link closed form of R, so
w'' = a holds for any robot (tested at random states of heterogeneous robots). Its gains
are rates on accelerations (K_v, R_v [1/s], K_p, R_p [1/s^2]) with no mass or length in
them; the torque scales with the robot through H, so the gains of (79) serve every robot.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

from .._validation import finite_number
from ..exceptions import ParameterError, SingularPostureError
from ..gaits import Serpenoid
from ..manipulability import manipulability_R_batch
from ..model import Snake
from .base import Controller, gait_for
from .gains import gain_matrix
from .reference import LinearReference

__all__ = ["PFLController"]


class PFLController(Controller):
    """Head PFL controller of Section VI.1.

    Parameters
    ----------
    snake
        The plant model (all joints actuated: PFL needs every input).
    reference
        Head reference; default w_r = [0.1 t, 0, 0] (eq. 80).
    gait
        Serpenoid for phi_r; default alpha = pi/3, T_s = 1, v = 0.18 (eq. 81).
    k_v, k_p, r_v, r_p
        Gains of (79): K_v = 6 I3, K_p = 6.2 I3, R_v = 0.041 I, R_p = 0.079 I.
    r_min
        Below this R the law is undefined: a SingularPostureError is raised.
    climb_R
        Gain gamma of the singularity-aware redundancy term (0: the paper's law).
    climb_damping
        Its damping k_d [1/s].
    """

    name = "pfl"

    def __init__(self, snake: Snake, reference: LinearReference | None = None,
                 gait: Serpenoid | None = None, *, k_v: object = 6.0, k_p: object = 6.2,
                 r_v: object = 0.041, r_p: object = 0.079, r_min: float = 1e-9,
                 climb_R: float = 0.0, climb_damping: float = 2.0) -> None:
        if snake.params.passive:
            raise ParameterError("PFL needs every joint actuated; use the Lyapunov-like "
                                 "controller with passive joints")
        n = snake.n
        if n < 4:
            raise ParameterError(f"PFL of the head needs n >= 4 links, got {n}")
        self.snake = snake
        self.reference = reference or LinearReference()
        self.gait = gait_for(n, gait, Serpenoid(n, np.pi / 3, 1.0, 0.18))
        self.k_v = gain_matrix(k_v, 3, "K_v")
        self.k_p = gain_matrix(k_p, 3, "K_p")
        self.r_v = gain_matrix(r_v, n - 1, "R_v", definite=False)
        self.r_p = gain_matrix(r_p, n - 1, "R_p", definite=False)
        self.r_min = finite_number(r_min, "r_min", non_negative=True)
        self.climb_R = finite_number(climb_R, "climb_R", non_negative=True)
        self.climb_damping = finite_number(climb_damping, "climb_damping", positive=True)
        self._last: dict[str, float] = {}
        self._nq = snake.nq

    def command(self, x: np.ndarray, t: float) -> np.ndarray:
        """The head acceleration a of eq. (71) at state x and time t."""
        w_r, dw_r, ddw_r = self.reference(t)
        nq = self._nq
        return ddw_r + self.k_v @ (dw_r - x[nq:nq + 3]) + self.k_p @ (w_r - x[:3])

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        snake, nq = self.snake, self._nq
        h_mat = snake.inertia_matrix(x[:nq])
        h_vec = snake.bias_of_state(x)
        h12, h22 = h_mat[:3, 3:], h_mat[3:, 3:]
        h1, h2 = h_vec[:3], h_vec[3:]
        # H12 = U S V^T (LAPACK directly: a third of numpy.linalg's per-call cost)
        u_svd, s_svd, vt_svd, info = lapack.dgesdd(h12, full_matrices=0)
        r = s_svd[-1]
        if info != 0 or not r > self.r_min:
            raise SingularPostureError(f"R = {r:.3g} <= {self.r_min:g}: PFL is undefined here")
        h12_pinv = (vt_svd.T / s_svd) @ u_svd.T
        # H22^-1 [H21, h2] in one Cholesky solve (H22 is positive definite, Prop. 1)
        solved, info = lapack.dposv(h22, np.column_stack((h12.T, h2)))[1:]
        if info != 0:
            raise SingularPostureError(f"H22 is not positive definite (LAPACK info {info})")
        h22_inv_h21, h22_inv_h2 = solved[:, :3], solved[:, 3]
        schur = h_mat[:3, :3] - h12 @ h22_inv_h21  # eq. (68)
        a = self.command(x, t)
        y = -schur @ a - h1 + h12 @ h22_inv_h2  # = H12 H22^-1 tau required by (27)
        dphi = x[nq + 3:]
        phi_r, dphi_r, ddphi_r = self.gait.derivatives(t)
        u = -ddphi_r - self.r_v @ (dphi_r - dphi) - self.r_p @ (phi_r - x[3:nq])  # eq. (78)
        if self.climb_R:
            u = u - self.climb_damping * (self.climb_R * self._grad_log_r(x[3:nq]) - dphi)
        kappa = h22_inv_h2 - u  # eq. (75)
        null = kappa - h12_pinv @ (h12 @ kappa)  # (I - H12^+ H12) kappa
        tau = h22 @ (h12_pinv @ y + null)
        self._last = {"R": float(r)}
        return tau

    def _grad_log_r(self, phi: np.ndarray, step: float = 1e-6) -> np.ndarray:
        """Central-difference gradient of log R over phi (one batched evaluation)."""
        dim = len(phi)
        probes = phi[None, :] + np.vstack([step * np.eye(dim), -step * np.eye(dim)])
        r = manipulability_R_batch(self.snake.params, probes)
        return (np.log(r[:dim]) - np.log(r[dim:])) / (2 * step)

    def signals(self) -> dict[str, float]:
        return self._last
