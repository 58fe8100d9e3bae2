"""Lyapunov-like head tracking (Section VI.2, eqs. 83-84), designed here (erratum 5): the
torques whose accelerations come closest to making V decrease (:ref:`derivation-lyapunov`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .._blas import gemv, posv, syrk
from .._options import documented, option
from ..exceptions import ParameterError, SingularPostureError
from ..gaits import Serpenoid
from ..model import Snake
from ._options import check_fields, tracking_gain
from .base import ReferenceLaw
from .gains import default_k_phi, gain_matrix
from .reference import HeadReference, head_first_reference

__all__ = ["LyapunovController", "LyapunovOptions"]

# read once: numpy's module __getattr__ keeps Python from caching ``np.<name>`` lookups
_MULTIPLY = np.multiply

#: The shape spring k_s when the robot has a passive (or failed) joint [1/s^2].
K_SHAPE_PASSIVE = 0.3


@documented
@dataclass(frozen=True)
class LyapunovOptions:
    """Options of :class:`LyapunovController` (validated; gains are scalars, diagonals or
    matrices, K_w2 and K_phi diagonal)."""

    k_w1: object = tracking_gain("k_w1")
    k_w2: object = tracking_gain("k_w2")
    k_phi: object = tracking_gain("k_phi")
    lam: float = option(10.0, "decay rate of the head's error", unit="1/s", low=0.0,
                        open_low=True)
    lam_shape: float | None = option(None, "decay rate of the joints' error", unit="1/s",
                                     low=0.0, open_low=True, default_doc="lam / 2")
    k_shape: float | None = option(None, "shape spring", unit="1/s^2", low=0.0,
                                   default_doc="0; 0.3 with a passive or failed joint")

    def __post_init__(self) -> None:
        check_fields(self)

    def resolved(self, joints: int | None = None, passive: bool = False) -> LyapunovOptions:
        """These options with the robot-dependent defaults (None fields) filled in.

        Parameters
        ----------
        joints, passive : int or None, bool, optional
            The robot's n - 1 (None: ``k_phi`` stays) and whether a joint gives no torque.

        Returns
        -------
        LyapunovOptions
            The None fields filled in as the class describes.
        """
        k_phi = self.k_phi
        if k_phi is None and joints is not None:
            k_phi = tuple(default_k_phi(joints))
        return replace(self, k_phi=k_phi,
                       lam_shape=self.lam / 2 if self.lam_shape is None else self.lam_shape,
                       k_shape=(K_SHAPE_PASSIVE if passive else 0.0) if self.k_shape is None
                       else self.k_shape)


class LyapunovController(ReferenceLaw):
    """Head tracking that reduces V of (83) by weighted least squares on q'' (signal ``V``).

    Parameters
    ----------
    snake, reference, gait
        The plant (passive joints get no torque), head reference (default head first) and
        serpenoid for phi_r (default alpha = pi/6, T_s = 1.5, v = 2, Section VI.2).
    options, **overrides
        :class:`LyapunovOptions` (default: the defaults) and fields of it to change.

    Raises
    ------
    ParameterError
        A bad robot (no motor), reference, gait, options, override or gain.
    """

    name = "lyapunov"

    def __init__(self, snake: Snake, reference: HeadReference | None = None,
                 gait: Serpenoid | None = None, options: LyapunovOptions | None = None,
                 **overrides: object) -> None:
        self.options = opts = self._bind(
            snake, reference, gait, (np.pi / 6, 1.5, 2.0), LyapunovOptions, options, overrides,
            head_first_reference).resolved(snake.n - 1, bool(snake.params.passive))
        self.k_w1 = gain_matrix(opts.k_w1, 3, "K_w1")
        self.k_w2 = gain_matrix(opts.k_w2, 3, "K_w2")
        self.k_phi = gain_matrix(opts.k_phi, snake.n - 1, "K_phi")
        self._k_w2_diag, self._k_phi_diag = np.diag(self.k_w2).copy(), np.diag(self.k_phi).copy()
        if not (np.allclose(self.k_w2, np.diag(self._k_w2_diag))
                and np.allclose(self.k_phi, np.diag(self._k_phi_diag))):
            raise ParameterError("K_w2 and K_phi must be diagonal (they weight rows)")
        self._weights = np.r_[self._k_w2_diag, self._k_phi_diag]
        assert opts.lam_shape is not None and opts.k_shape is not None  # resolved
        self.lam, self.lam_shape, self.k_shape = opts.lam, opts.lam_shape, opts.k_shape
        self._act = np.array([2 + k for k in snake.params.actuated])  # velocity indices
        self._build_law()
        self._buffers = self._allocate()

    def _build_law(self) -> None:
        """Constant matrices of the hot path (:ref:`derivation-lyapunov`)."""
        snake, nq, n = self.snake, self.snake.nq, self.snake.n
        m, eye3 = n - 1, np.eye(3)
        k_w1, lam, mu, k_s = self.k_w1, self.lam, self.lam_shape, self.k_shape
        sqrt_w = np.sqrt(self._weights)
        # rows: [W^(1/2) (q''* - b); s; e]; columns: [w_r, phi_r, w_r', phi_r', w_r'',
        # phi_r'', q, q', b], each block nq wide (eqs. of docs/equations.rst)
        law = np.zeros((2 * nq, 6 * nq))
        r, dr, ddr, q, v, b = (slice(k * nq, (k + 1) * nq) for k in range(6))
        rows_w, rows_phi = slice(0, 3), slice(3, nq)
        head, shape = (lambda block: slice(block.start, block.start + 3),
                       lambda block: slice(block.start + 3, block.stop))
        s_rows, e_rows, eye_m = slice(nq, nq + 3), slice(nq + 3, 2 * nq), np.eye(m)
        # each row block's blocks on [w_r, w_r', w_r'', q, q'] (head) or their joint parts
        for rows, part, blocks in (
                (rows_w, head, (lam * k_w1, k_w1 + lam * eye3, eye3, -lam * k_w1,
                                -(k_w1 + lam * eye3))),
                (rows_phi, shape, (k_s * eye_m, mu * eye_m, eye_m, -k_s * eye_m, -mu * eye_m)),
                (s_rows, head, (k_w1, eye3, None, -k_w1, -eye3)),
                (e_rows, shape, (None, eye_m, None, None, -eye_m))):
            for column, block in zip((r, dr, ddr, q, v), blocks, strict=True):
                if block is not None:
                    law[rows, part(column)] = block
        law[:nq, b] = -np.eye(nq)
        law[:nq] *= sqrt_w[:, None]
        law[nq:] *= sqrt_w[:, None]  # [s; e] weighted: V is their squared norm
        self._law_time = law[:, :3 * nq].T.copy()  # applied to rows of references
        # a passive joint's row of A^T weighs 0 and has a 1 in a column of its own: tau_j = 0
        # exactly (:ref:`derivation-lyapunov`); the error rows have 0 there
        passive = [k - 1 for k in snake.params.passive]  # tau's entries
        width = nq + len(passive)
        # applied to [q, q', b, time row]: the time terms enter the same product
        state = np.hstack((law[:, 3 * nq:], np.eye(2 * nq)))
        self._law_state = np.zeros((2 * width, 5 * nq))
        self._law_state[:nq], self._law_state[width:width + nq] = state[:nq], state[nq:]
        # rows: (W^(1/2) A)^T, then the errors [W^(1/2) (q''* - b); W^(1/2) [s; e]]; times
        # its own transpose it gives A^T W A, the right-hand side and V in one product
        self._stack = np.zeros((m + 2, width))
        self._stack[passive, nq + np.arange(len(passive))] = 1.0
        # W^(1/2) scales A^T's columns, by a whole matrix of weights (numpy broadcasting
        # costs more here); a passive joint's row weighs 0
        self._sqrt_w = np.tile(sqrt_w, (m, 1))
        self._sqrt_w[passive] = 0.0

    def _allocate(self) -> tuple[Any, ...]:
        """The call's buffers, views and prepared products, in :meth:`__call__`'s order."""
        snake = self.snake
        nq, m = snake.nq, snake.n - 1
        inputs, stack = np.zeros(5 * nq), self._stack.copy()  # a copy's own buffers
        data = snake.create_data()
        # BLAS and LAPACK in place on Fortran-ordered buffers (snake_pin._blas); A^T: the
        # joints' rows of H^-1, a contiguous view of the data's (row-major, symmetric)
        normal = np.zeros((m + 2, m + 2), order="F")
        gram = np.zeros((m, m), order="F")
        rows = data.inverse_mass[3:]
        b, tau = inputs[2 * nq:3 * nq], normal[:m, m]  # tau: solved in place of the rhs
        return (
            snake.calc_affine, data, inputs[:2 * nq], inputs[:nq], inputs[nq:2 * nq], b,
            inputs[3 * nq:], self._time_row,
            # [W^(1/2) (q''* - b); W^(1/2) [s; e]] from [q, q', b, time row]
            gemv(1.0, self._law_state.T, inputs, 0.0, stack[m:].reshape(-1), 1),
            rows, self._sqrt_w, stack[:m, :nq],
            syrk(1.0, stack.T, 0.0, normal, 1),  # [A^T W A, rhs, V]
            gram, normal[:m, :m], tau,
            posv(gram, tau),  # its upper triangle; tau in place of the rhs
            gemv(1.0, rows.T, tau, 1.0, b),  # q'' = b + A tau_a, in b
            normal, m + 1)

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        """Joint torques at (x, t), 0 on passive joints.

        SingularPostureError if A^T W A is not positive definite.
        """
        (affine, data, x_slot, q, v, b, time_slot, time_row, errors, rows, sqrt_w,
         weighted_t, normal_equations, gram, gram_block, tau, solve, acceleration, normal,
         last) = self._buffers
        self._acceleration = None
        x_slot[...] = x
        b[...] = affine(data, q, v)[0]  # and H^-1, read through rows
        time_slot[...] = time_row(t)
        errors()
        _MULTIPLY(rows, sqrt_w, weighted_t)  # (W^(1/2) A)^T
        normal_equations()
        gram[...] = gram_block
        info = solve()[2]
        if info != 0:
            raise SingularPostureError(f"A^T W A is not positive definite (LAPACK info {info})")
        acceleration()
        self._acceleration = b
        self._signals = {"V": normal.item(last, last)}
        return tau.copy()

    def targets(self, x: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(q''*, s, e)``: the target accelerations and the errors of V at (x, t).

        Parameters
        ----------
        x, t : numpy.ndarray, float
            State ``x = [q, dq]`` (length 2(n + 2)) and time [s].

        Returns
        -------
        tuple of numpy.ndarray
            ``q''*`` (n + 2), ``s`` (3) and ``e`` (n - 1).
        """
        nq = self.snake.nq
        w_r, dw_r, ddw_r = self.reference(t)
        de_w = dw_r - x[nq:nq + 3]
        s = de_w + self.k_w1 @ (w_r - x[:3])
        phi_r, dphi_r, ddphi_r = self.gait.derivatives(t)
        e = dphi_r - x[nq + 3:]
        shape = ddphi_r + self.lam_shape * e
        if self.k_shape:
            shape += self.k_shape * (phi_r - x[3:nq])
        target = np.concatenate((ddw_r + self.k_w1 @ de_w + self.lam * s, shape))
        return target, s, e

    def affine_map(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(A, b)`` with ``q'' = A tau_a + b`` at state x: ``A = H^-1 E_a``, ``b = -H^-1 h``.

        Parameters
        ----------
        x : numpy.ndarray
            State ``x = [q, dq]``, length 2(n + 2).

        Returns
        -------
        tuple of numpy.ndarray
            ``A`` of shape (n + 2, number of actuated joints) and ``b`` of length n + 2.
        """
        snake = self.snake
        x = snake.check_state(x)
        h_inv = snake.inverse_inertia_matrix(x[:snake.nq])
        return h_inv[:, self._act], -h_inv @ snake.bias(x[:snake.nq], x[snake.nq:])

    def lyapunov(self, x: np.ndarray, t: float) -> float:
        """V of eq. (83) at (x, t).

        Parameters
        ----------
        x, t : numpy.ndarray, float
            State ``x = [q, dq]`` (length 2(n + 2)) and time [s].

        Returns
        -------
        float
            ``V = s' K_w2 s + e' K_phi e``.
        """
        _, s, e = self.targets(x, t)
        return float(s @ self.k_w2 @ s + e @ self.k_phi @ e)
