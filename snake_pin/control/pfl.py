"""Partial feedback linearisation of the head (Section VI.1, eqs. 68-78), sign corrected,
with an optional climb up log R in the null space of H12 (:ref:`derivation-pfl`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._blas import gemv, posv, syrk
from .._options import documented, option
from .._symmetric import smallest_eigenvalue_3x3
from .._validation import instance
from ..exceptions import ParameterError, SingularPostureError
from ..gaits import Serpenoid
from ..manipulability import r_batch
from ..model import Snake
from ._options import check_fields
from .base import ReferenceLaw
from .gains import gain_matrix
from .reference import HeadReference, LinearReference

__all__ = ["PFLController", "PFLOptions"]

# read once: numpy's module __getattr__ keeps Python from caching ``np.<name>`` lookups
_NEGATIVE, _SUBTRACT = np.negative, np.subtract

#: The climb term's damping k_d when climb_R > 0 and none is given [1/s].
CLIMB_DAMPING = 2.0


@documented
@dataclass(frozen=True)
class PFLOptions:
    """Options of :class:`PFLController` (validated; gains are scalars, diagonals or matrices;
    ``climb_damping`` only with ``climb_R > 0``)."""

    k_v: object = option(6.0, "velocity gain on the head", unit="1/s", low=0.0, open_low=True,
                         symbol="K_v", size=3)
    k_p: object = option(6.2, "position gain on the head", unit="1/s^2", low=0.0,
                         open_low=True, symbol="K_p", size=3)
    r_v: object = option(0.041, "velocity gain on the joints", unit="1/s", low=0.0,
                         symbol="R_v")
    r_p: object = option(0.079, "position gain on the joints", unit="1/s^2", low=0.0,
                         symbol="R_p")
    r_min: float = option(1e-9, "smallest R for which the law is defined", low=0.0)
    climb_R: float = option(0.0, "gain of the singularity-aware redundancy term", low=0.0)
    climb_damping: float | None = option(None, "damping of the redundancy term", unit="1/s",
                                         low=0.0, open_low=True, default_doc="CLIMB_DAMPING, 2")

    def __post_init__(self) -> None:
        check_fields(self)
        if self.climb_damping is not None and self.climb_R == 0.0:
            raise ParameterError("climb_damping has no effect with climb_R = 0 (no climb "
                                 "term): give climb_R > 0 or leave climb_damping out")


class PFLController(ReferenceLaw):
    """Head PFL controller of Section VI.1; its signal ``R`` is the head's manipulability.

    Parameters
    ----------
    snake, reference, gait
        The plant (every joint actuated), head reference (default w_r = [0.1 t, 0, 0], eq.
        80) and serpenoid for phi_r (default alpha = pi/3, T_s = 1, v = 0.18, eq. 81).
    options, **overrides
        :class:`PFLOptions` (default: the defaults) and fields of it to change.

    Raises
    ------
    ParameterError
        A bad robot (a passive joint, n < 4), reference, gait, options, override or gain.
    """

    name = "pfl"

    def __init__(self, snake: Snake, reference: HeadReference | None = None,
                 gait: Serpenoid | None = None, options: PFLOptions | None = None,
                 **overrides: object) -> None:
        if instance(snake, Snake, "snake").params.passive:
            raise ParameterError("PFL needs every joint actuated; use the Lyapunov-like "
                                 "controller with passive joints")
        n = snake.n
        if n < 4:
            raise ParameterError(f"PFL of the head needs n >= 4 links, got {n}")
        self.options = opts = self._bind(snake, reference, gait, (np.pi / 3, 1.0, 0.18),
                                         PFLOptions, options, overrides, LinearReference)
        self.k_v = gain_matrix(opts.k_v, 3, "K_v")
        self.k_p = gain_matrix(opts.k_p, 3, "K_p")
        self.r_v = gain_matrix(opts.r_v, n - 1, "R_v", definite=False)
        self.r_p = gain_matrix(opts.r_p, n - 1, "R_p", definite=False)
        self.r_min, self.climb_R = opts.r_min, opts.climb_R
        self.climb_damping = CLIMB_DAMPING if opts.climb_damping is None else opts.climb_damping
        self._nq = nq = snake.nq
        # [a; u] = (time terms) + gain @ x, from (71) and (78) without the climb term
        m = n - 1
        law = np.zeros((nq, 3 * nq))  # columns: [w_r, phi_r, w_r', phi_r', w_r'', phi_r'']
        law[:3, :3], law[:3, nq:nq + 3], law[:3, 2 * nq:2 * nq + 3] = self.k_p, self.k_v, np.eye(3)
        law[3:, 3:nq], law[3:, nq + 3:2 * nq] = -self.r_p, -self.r_v
        law[3:, 2 * nq + 3:] = -np.eye(m)
        self._gain = np.zeros((nq, 2 * nq))  # on x = [q, q']
        self._gain[:3, :3], self._gain[:3, nq:nq + 3] = -self.k_p, -self.k_v
        self._gain[3:, 3:nq], self._gain[3:, nq + 3:] = self.r_p, self.r_v
        # the head's rows negated, so that one product gives [-a; u] (negation is exact)
        self._gain[:3] *= -1.0
        law[:3] *= -1.0
        self._law_time = law.T.copy()
        # [-a; u], then [-a; u + p], then the call's q'' = [w''; phi''] = [a; phi'']
        self._stacked = np.zeros(nq)
        self._buffers = self._allocate()

    def _allocate(self) -> tuple[Any, ...]:
        """The call's buffers, views and prepared products, in :meth:`__call__`'s order."""
        nq, snake = self._nq, self.snake
        m = nq - 3
        data = snake.create_data()
        mass, bias, stacked = data.mass, data.bias, self._stacked  # H (Fortran-ordered, whole)
        state = np.zeros(2 * nq)
        # BLAS and LAPACK in place on Fortran-ordered buffers (snake_pin._blas), H12 and H22
        # copied in per call; h (data.bias): its head's rows become z, its joints' the torque
        h12, h22 = np.zeros((3, m), order="F"), np.zeros((m, m), order="F")
        gram, p_rhs = np.zeros((3, 3), order="F"), np.zeros(m)
        minus_a, u, z, h_joints = stacked[:3], stacked[3:], bias[:3], bias[3:]
        return (
            snake.calc_mass_and_bias, data, state, state[:nq], state[nq:], h12, mass[:3, 3:],
            syrk(1.0, h12, 0.0, gram),  # H12 H12^T (upper triangle)
            gram, stacked, self._time_row,
            gemv(1.0, self._gain.T, state, 1.0, stacked, 1),  # [-a; u] (71, 78)
            minus_a, u,
            gemv(1.0, h12, minus_a, 0.0, p_rhs, 1),  # -H21 a
            h22, mass[3:, 3:],
            posv(h22, p_rhs),  # -p = -H22^-1 H21 a, in p_rhs
            p_rhs,
            gemv(1.0, mass[:, :3], stacked, -1.0, z, 1),  # z = -H11 a + H12 u - h1
            posv(gram, z),  # (H12 H12^T)^-1 z, in z
            gemv(1.0, h12, z, -1.0, u, 1),  # phi'' = H12^+ z - (u + p)
            gemv(1.0, mass[:, 3:], stacked, 1.0, h_joints, 1),  # H21 a + H22 phi'' + h2
            h_joints)

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        """Joint torques at (x, t).

        SingularPostureError if R <= r_min, or H22 or H12 H12^T is not positive definite.
        """
        (mass_and_bias, data, state, q, v, h12, h12_block, gram_of_h12, gram, stacked,
         time_row, targets, minus_a, u, minus_p, h22, h22_block, solve_p, p_rhs, z_rhs,
         solve_z, joint_rates, torque, tau) = self._buffers
        self._acceleration = None
        state[...] = x
        mass_and_bias(data, q, v)  # H (whole) and h
        h12[...] = h12_block
        gram_of_h12()
        r = math.sqrt(max(smallest_eigenvalue_3x3(gram), 0.0))  # H12's least singular value
        if not r > self.r_min:
            raise SingularPostureError(f"R = {r:.3g} <= {self.r_min:g}: PFL is undefined here")
        stacked[...] = time_row(t)
        targets()
        if self.climb_R:
            nq = self._nq
            np.subtract(u, self.climb_damping * (self.climb_R * self._grad_log_r(x[3:nq])
                                                 - x[nq + 3:]), u)
        minus_p()
        h22[...] = h22_block
        info = solve_p()[2]
        if info != 0:
            raise SingularPostureError(f"H22 is not positive definite (LAPACK info {info})")
        _SUBTRACT(u, p_rhs, u)  # stacked = [-a; p + u]
        z_rhs()
        info = solve_z()[2]
        if info != 0:
            raise SingularPostureError(
                f"H12 H12^T is not positive definite (LAPACK info {info})")
        joint_rates()
        _NEGATIVE(minus_a, minus_a)  # w'' = a: stacked is q'' now
        torque()
        self._acceleration = stacked
        self._signals = {"R": r}
        return tau.copy()

    def command(self, x: np.ndarray, t: float) -> np.ndarray:
        """The head acceleration a of eq. (71) at (x, t).

        Parameters
        ----------
        x, t : numpy.ndarray, float
            State ``x = [q, dq]`` (length 2(n + 2)) and time [s].

        Returns
        -------
        numpy.ndarray
            ``a = w''`` commanded to the head, shape (3,) [m/s^2, m/s^2, rad/s^2].
        """
        w_r, dw_r, ddw_r = self.reference(t)
        nq = self._nq
        return ddw_r + self.k_v @ (dw_r - x[nq:nq + 3]) + self.k_p @ (w_r - x[:3])

    def _grad_log_r(self, phi: np.ndarray, step: float = 1e-6) -> np.ndarray:
        """Central-difference gradient of log R over phi (one batched evaluation)."""
        dim = len(phi)
        probes = phi[None, :] + np.vstack([step * np.eye(dim), -step * np.eye(dim)])
        r = r_batch(self.snake.params, probes, (), True)  # PFL: no passive joint
        return (np.log(r[:dim]) - np.log(r[dim:])) / (2 * step)
