"""The controllers vectorised over a lockstep batch of runs, and the closed-form terms they use.

:func:`snake_pin.batch.simulate_batch` steps B runs of one robot layout together; this
module computes their B torques at once. A batched controller is built from the per-run
controllers a user would pass to :func:`snake_pin.sim.simulate` (:func:`batch_controller`):
it reads each run's public settings (reference, gait, gains, rates, passive joints and
friction of the controller's own model) into arrays with the batch first, and evaluates
the same law on (B, ...) arrays in numpy.

Vectorised laws (exact types only; a subclass may change the law, so it runs per run):

- :class:`~snake_pin.control.lyapunov.LyapunovController` -> :class:`BatchedLyapunov`;
- :class:`~snake_pin.control.quasistatic.QuasiStaticLyapunovController` ->
  :class:`BatchedQuasiStatic`;
- :class:`~snake_pin.control.pfl.PFLController` -> :class:`BatchedPFL`.

Any other controller (or plain function) is called run by run (:class:`PerRunControllers`),
so a batch may hold anything :func:`~snake_pin.sim.simulate` accepts. Runs of different
kinds, or whose controllers model different layouts, form separate groups
(:class:`GroupedControllers`). A :class:`~snake_pin.control.reference.LinearReference`
and a :class:`~snake_pin.gaits.Serpenoid` are evaluated for the whole batch at once; any
other reference or gait object is called run by run.

**The model terms over a batch** (:class:`BatchTerms`). Per run, the laws need H(q) and
h(q, q') (torque level, PFL) or the friction matrix C(q) (velocity level), from the
controller's own model. ``pin.computeMinverse`` has no batched form, so these come from
the closed form of :mod:`snake_pin.paper`, vectorised over the batch. With
``theta = L [theta_1, phi]`` (eq. 17), ``c = cos theta``, ``s = sin theta``,
``a = m^T K`` (per-link masses m, K of eq. 4) and ``G = K^T diag(m) K`` (constant per
layout)::

    H-bar:  [0,0] = [1,1] = sum m,  [0, theta_j] = -a_j s_j,  [1, theta_j] = a_j c_j,
            [theta_i, theta_j] = G_ij cos(theta_i - theta_j) + delta_ij J_i
    W-bar (theta')^2:  x: -sum_j a_j c_j theta_j'^2,  y: -sum_j a_j s_j theta_j'^2,
            theta_i: sum_j G_ij sin(theta_i - theta_j) theta_j'^2

and ``H = J_q^T H-bar J_q``, ``Coriolis = J_q^T W-bar (theta')^2``
(``J_q = blockdiag(I_2, L)``: products with L are suffix sums). Friction follows
:class:`snake_pin.friction.FrictionModel`'s complex-number route with per-run, per-link
coefficients: with ``e_i = exp(j theta_i)`` and the CM velocities z_i, link i's world force
is ``F_i = -cbar_i z_i - delta_i e_i^2 conj(z_i)``. Its matrix C(q) is the same map applied
to the unit velocities. The plant's q'' (:meth:`BatchTerms.forward_dynamics`) is solved in
q-bar coordinates with the head eliminated: one n x n solve of
``S = (G - a a^T / M) o cos(theta_i - theta_j) + diag(J)`` per run.
``tests/test_batch.py`` checks every term against Pinocchio on heterogeneous robots. A
:class:`BatchTerms` remembers the last state array it saw, so the plant and the
controllers of its layout share the terms at the sampled states.

Solves are batched LU (``numpy.linalg.solve`` on (B, k, k)). A run whose solve fails or
gives non-finite values is evaluated again alone - by its own scalar controller
(torque level), or with the scalar law's LAPACK routine (velocity level, PFL) - so it
fails (or not) with the scalar law's message while the others go on.

Passive joints are masks, not different models: the torque-level law solves a KKT system
whose constraint rows hold the passive torques at zero (:class:`BatchedLyapunov`); the
velocity-level law zeroes a passive column and replaces its normal-equation row by the
identity with a zero right-hand side, which gives the reduced system's solution on the
actuated joints and exactly 0 on the passive ones.

Interface (:class:`BatchedController`): ``ctrl(x, t) -> (tau, failures)`` with x of shape
(m, 2(n + 2)) the states ``[q, dq]`` of the m runs still going, tau (m, n - 1) [N m], and
failures mapping a row to the exception (or the torque problem text) that stops that run;
``keep(rows)`` drops the runs that stopped; ``signals()`` gives per-row diagnostics of the
last call (V, R).
"""

from __future__ import annotations

import abc
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from scipy.linalg import lapack

from .._validation import brief, check_params, integer
from ..exceptions import ParameterError, SingularPostureError
from ..gaits import Serpenoid
from ..manipulability import _r_batch
from ..paper import k_matrix
from ..params import SnakeParams
from .base import Controller
from .lyapunov import LyapunovController
from .pfl import PFLController
from .quasistatic import QuasiStaticLyapunovController
from .reference import LinearReference

__all__ = [
    "LAYOUT_FIELDS",
    "BatchTerms",
    "BatchedController",
    "BatchedLyapunov",
    "BatchedPFL",
    "BatchedQuasiStatic",
    "FrictionCoefficients",
    "GroupedControllers",
    "PerRunControllers",
    "batch_controller",
    "layout_key",
]

#: The fields of :class:`~snake_pin.params.SnakeParams` that every run of a batch shares:
#: they fix the Pinocchio model (its joints and inertias). Friction and passive joints
#: may differ from run to run.
LAYOUT_FIELDS = ("n", "link_length", "mass", "inertia", "com_offset")

#: A run's failure: the exception its law raised, or the torque problem (text).
Failure = BaseException | str


def _items(value: object, name: str) -> list[Any]:
    """``value`` as a non-empty list: a sequence (not text, not a mapping), or ParameterError."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, (Sequence, np.ndarray)):
        raise ParameterError(f"{name} must be a non-empty sequence, got {brief(value)}")
    items = list(value)
    if not items:
        raise ParameterError(f"{name} must be a non-empty sequence, got an empty one")
    return items


def _callable(value: object, name: str) -> Any:
    """``value`` if it is callable, else ParameterError naming ``name``."""
    if not callable(value):
        raise ParameterError(f"{name} must be callable, got {brief(value)}")
    return value


def layout_key(params: SnakeParams) -> tuple[Any, ...]:
    """Return the layout fields of ``params`` (equal for robots that share a Pinocchio model).

    Parameters
    ----------
    params : SnakeParams
        A robot.

    Returns
    -------
    tuple
        The values of :data:`LAYOUT_FIELDS`, in that order (hashable: a dict key).

    Raises
    ------
    ParameterError
        ``params`` is not a SnakeParams.
    """
    check_params(params)
    return tuple(getattr(params, name) for name in LAYOUT_FIELDS)


# --------------------------------------------------------------------- model terms
class BatchTerms:
    """Closed-form H, Coriolis and friction of one layout over a batch of states.

    Methods take stacked states x (m, 2(n + 2)) and remember the last x they saw (by
    identity: the simulator never changes a state array in place), so a controller and the
    plant's first RK4 stage evaluated at the same states share H, the Coriolis term and,
    when their friction coefficients are equal, the friction force.

    Parameters
    ----------
    params : SnakeParams
        Any robot of the layout (only the fields of :data:`LAYOUT_FIELDS` are used).

    Raises
    ------
    ParameterError
        ``params`` is not a SnakeParams.
    """

    def __init__(self, params: SnakeParams) -> None:
        n = check_params(params).n
        self._layout = layout_key(params)
        self.n, self.nq = n, n + 2
        k = k_matrix(params)
        masses = params.masses
        lower = np.tril(np.ones((n, n)))
        self._lower = lower  # x @ L: suffix sums along the last axis
        self._upper = np.ascontiguousarray(lower.T)  # phi -> theta: theta = [theta_1, phi] L^T
        self._k = k
        self._kt = np.ascontiguousarray(k.T)
        self._a = masses @ k  # a_j = sum_i m_i K_ij
        self._gram = k.T @ (masses[:, None] * k)  # G = K^T diag(m) K
        self._rotational_bar = np.diag(params.inertias)
        self._inertias = params.inertias
        self._diagonal = np.arange(n)
        self._reduced_gram = self._gram - np.outer(masses @ k, masses @ k) / masses.sum()
        self._total_mass = float(masses.sum())
        self._x: np.ndarray | None = None
        self._cache: dict[str, Any] = {}

    def _suffix(self, values: np.ndarray) -> np.ndarray:
        """Sums from each index to the end along the last axis (a product with L)."""
        if values.ndim == 2:
            return values @ self._lower
        shape = values.shape
        return (values.reshape(-1, shape[-1]) @ self._lower).reshape(shape)

    def _entry(self, x: np.ndarray) -> dict[str, Any]:
        if x is not self._x:
            self._x = x
            self._cache = {}
        return self._cache

    def _angles(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(theta, theta', cos theta, sin theta) of every link, each (m, n)."""
        cache = self._entry(x)
        angles = cache.get("angles")
        if angles is None:
            nq = self.nq
            theta = x[:, 2:nq] @ self._upper
            rate = x[:, nq + 2:] @ self._upper
            angles = cache["angles"] = (theta, rate, np.cos(theta), np.sin(theta))
        return angles

    def _link_inertia(self, x: np.ndarray) -> np.ndarray:
        """H-bar of eq. (9) in q-bar = [x_h, y_h, theta_1..theta_n]: (m, n + 2, n + 2)."""
        cache = self._entry(x)
        out = cache.get("H-bar")
        if out is not None:
            return out
        _, _, c, s = self._angles(x)
        out = np.empty((len(x), self.nq, self.nq))
        block = out[:, 2:, 2:]
        np.multiply(c[:, :, None], c[:, None, :], out=block)
        block += s[:, :, None] * s[:, None, :]
        block *= self._gram
        block += self._rotational_bar
        row_x, row_y = -self._a * s, self._a * c
        out[:, 0, 2:] = row_x
        out[:, 2:, 0] = row_x
        out[:, 1, 2:] = row_y
        out[:, 2:, 1] = row_y
        out[:, 0, 0] = out[:, 1, 1] = self._total_mass
        out[:, 0, 1] = out[:, 1, 0] = 0.0
        cache["H-bar"] = out
        return out

    def inertia(self, x: np.ndarray) -> np.ndarray:
        """Return ``H(q) = J_q^T H-bar J_q`` for each state (cached: do not modify it).

        Parameters
        ----------
        x : numpy.ndarray, shape (m, 2(n + 2))
            Stacked states ``[q, dq]``, one run per row.

        Returns
        -------
        numpy.ndarray, shape (m, n + 2, n + 2)
            Inertia matrices in paper coordinates.
        """
        cache = self._entry(x)
        out = cache.get("H")
        if out is not None:
            return out
        n = self.n
        bar = self._link_inertia(x)
        m = len(x)
        out = np.empty_like(bar)
        out[:, :2, :2] = bar[:, :2, :2]
        rows = self._suffix(bar[:, :2, 2:])
        out[:, :2, 2:] = rows
        out[:, 2:, :2] = rows.transpose(0, 2, 1)
        # L^T X L: suffix sums along the columns, then (X L)^T L (X symmetric)
        half = self._suffix(bar[:, 2:, 2:]).transpose(0, 2, 1)
        out[:, 2:, 2:] = (half.reshape(-1, n) @ self._lower).reshape(m, n, n)
        cache["H"] = out
        return out

    def _link_coriolis(self, x: np.ndarray) -> np.ndarray:
        """W-bar (theta')^2 in q-bar coordinates: (m, n + 2)."""
        cache = self._entry(x)
        out = cache.get("coriolis-bar")
        if out is not None:
            return out
        _, rate, c, s = self._angles(x)
        rate2 = rate * rate
        cw, sw = c * rate2, s * rate2
        out = np.empty((len(x), self.nq))
        out[:, 0] = -(cw @ self._a)
        out[:, 1] = -(sw @ self._a)
        # sum_j G_ij sin(theta_i - theta_j) w_j = s_i (G c w)_i - c_i (G s w)_i
        out[:, 2:] = s * (cw @ self._gram) - c * (sw @ self._gram)
        cache["coriolis-bar"] = out
        return out

    def coriolis(self, x: np.ndarray) -> np.ndarray:
        """Return the Coriolis term ``W diag(J dq) J dq`` of eq. (18) for each state (cached).

        Parameters
        ----------
        x : numpy.ndarray, shape (m, 2(n + 2))
            Stacked states ``[q, dq]``, one run per row.

        Returns
        -------
        numpy.ndarray, shape (m, n + 2)
            Generalised forces [N, N, N m, N m...]; do not modify them.
        """
        cache = self._entry(x)
        out = cache.get("coriolis")
        if out is None:
            out = cache["coriolis"] = self._to_paper(self._link_coriolis(x))
        return out

    def _link_friction(self, x: np.ndarray, coeffs: FrictionCoefficients) -> np.ndarray:
        """The friction force in q-bar coordinates (force on the head, torque per link)."""
        cache = self._entry(x)
        known = cache.get("friction-bar")
        if known is not None and known[0].equals(coeffs):
            return known[1]
        nq = self.nq
        _, rate, c, s = self._angles(x)
        e = c + 1j * s
        z = (1j * e * rate) @ self._kt  # z_i = sum_j K_ij (j e_j theta_j')
        z += (x[:, nq] + 1j * x[:, nq + 1])[:, None]
        if coeffs.ratio is not None:
            z += coeffs.ratio * (e * e) * z.conj()
        force = -coeffs.cbar * z  # world force on each link
        total = force.sum(axis=1)
        out = np.empty((len(x), nq))
        out[:, 0] = total.real
        out[:, 1] = total.imag
        out[:, 2:] = (e.conj() * (force @ self._k)).imag - coeffs.c_theta * rate
        cache["friction-bar"] = (coeffs, out)
        return out

    def friction(self, x: np.ndarray, coeffs: FrictionCoefficients) -> np.ndarray:
        """Return the generalised friction force ``-C(q) dq`` for each state (cached).

        Parameters
        ----------
        x : numpy.ndarray, shape (m, 2(n + 2))
            Stacked states ``[q, dq]``, one run per row.
        coeffs : FrictionCoefficients
            Friction coefficients of the same m runs.

        Returns
        -------
        numpy.ndarray, shape (m, n + 2)
            Friction forces [N, N, N m, N m...]; do not modify them.
        """
        cache = self._entry(x)
        known = cache.get("friction")
        if known is not None and known[0].equals(coeffs):
            return known[1]
        out = self._to_paper(self._link_friction(x, coeffs))
        cache["friction"] = (coeffs, out)
        return out

    def _to_paper(self, bar: np.ndarray) -> np.ndarray:
        """J_q^T f-bar: a q-bar force in paper coordinates (suffix sums over the links)."""
        out = bar.copy()
        out[:, 2:] = bar[:, 2:] @ self._lower
        return out

    def _reduced_inertia(self, x: np.ndarray) -> np.ndarray:
        """S = (G - a a^T / M) o cos(theta_i - theta_j) + diag(J): H-bar's Schur complement
        over the head position (its xy block is M I): (m, n, n)."""
        cache = self._entry(x)
        out = cache.get("S")
        if out is None:
            _, _, c, s = self._angles(x)
            out = np.multiply(c[:, :, None], c[:, None, :])
            out += s[:, :, None] * s[:, None, :]
            out *= self._reduced_gram
            out[:, self._diagonal, self._diagonal] += self._inertias
            cache["S"] = out
        return out

    def forward_dynamics(self, x: np.ndarray, coeffs: FrictionCoefficients,
                         tau: np.ndarray) -> np.ndarray:
        """Return the plant's q'' under the joint torques tau and the friction ``coeffs``.

        In q-bar coordinates, ``H-bar (J_q q'') = J_q^-T (E tau + Q - Coriolis) =: f`` (no
        products with L; joint torque k pushes link k + 1 and pulls link k). H-bar's xy
        block is ``M I`` with the rows ``b_x = -a o sin theta``, ``b_y = a o cos theta``
        beside it, so the head's acceleration is eliminated::

            S theta'' = f_theta - (b_x f_x + b_y f_y) / M          (an n x n solve)
            [x_h'', y_h''] = (f_xy - [b_x; b_y] theta'') / M

        and phi'' are the differences of theta''.

        Parameters
        ----------
        x : numpy.ndarray, shape (m, 2(n + 2))
            Stacked states ``[q, dq]``, one run per row.
        coeffs : FrictionCoefficients
            Friction coefficients of the same m runs.
        tau : numpy.ndarray, shape (m, n - 1)
            Joint torques [N m].

        Returns
        -------
        numpy.ndarray, shape (m, n + 2)
            q'' [m/s^2, m/s^2, rad/s^2, rad/s^2...] (NaN rows where S is singular).
        """
        mass = self._total_mass
        _, _, c, s = self._angles(x)
        force = self._link_friction(x, coeffs) - self._link_coriolis(x)
        force[:, 2:-1] -= tau
        force[:, 3:] += tau
        b_x, b_y = -self._a * s, self._a * c
        f_x, f_y = force[:, :1], force[:, 1:2]
        rhs = force[:, 2:] - (b_x * f_x + b_y * f_y) / mass
        theta = _solve_or_nan(self._reduced_inertia(x), rhs)
        out = np.empty_like(force)
        out[:, 0] = (f_x[:, 0] - np.einsum("bi,bi->b", b_x, theta)) / mass
        out[:, 1] = (f_y[:, 0] - np.einsum("bi,bi->b", b_y, theta)) / mass
        out[:, 2] = theta[:, 0]
        np.subtract(theta[:, 1:], theta[:, :-1], out=out[:, 3:])
        return out

    def bias(self, x: np.ndarray, coeffs: FrictionCoefficients) -> np.ndarray:
        """Return ``h = Coriolis - friction force`` for each state (a new array).

        Parameters
        ----------
        x : numpy.ndarray, shape (m, 2(n + 2))
            Stacked states ``[q, dq]``, one run per row.
        coeffs : FrictionCoefficients
            Friction coefficients of the same m runs.

        Returns
        -------
        numpy.ndarray, shape (m, n + 2)
            h of ``H q'' + h = E tau`` [N, N, N m, N m...].
        """
        return self.coriolis(x) - self.friction(x, coeffs)

    def friction_matrix(self, x: np.ndarray, coeffs: FrictionCoefficients) -> np.ndarray:
        """Return the friction matrix C(q) of eq. (11) for each state (friction force -C dq).

        Columns 0 and 1 answer unit base velocities (z = 1, j); column 2 + k the unit rate
        of the k-th angle coordinate, which turns links k.. (theta' = 1 there).

        Parameters
        ----------
        x : numpy.ndarray, shape (m, 2(n + 2))
            Stacked states ``[q, dq]``, one run per row.
        coeffs : FrictionCoefficients
            Friction coefficients of the same m runs.

        Returns
        -------
        numpy.ndarray, shape (m, n + 2, n + 2)
            C(q) of each run (a new array).
        """
        m, n = len(x), self.n
        _, _, c, s = self._angles(x)
        e = c + 1j * s
        z = np.empty((m, n, self.nq), dtype=complex)
        z[:, :, 0] = 1.0
        z[:, :, 1] = 1.0j
        # z_i(col k) = sum_{j >= k} K_ij j e_j: suffix sums over j of K_ij j e_j
        z[:, :, 2:] = np.flip(np.cumsum(np.flip(self._k[None, :, :] * (1j * e)[:, None, :], 2),
                                        axis=2), 2)
        if coeffs.ratio is not None:
            z += (coeffs.ratio * (e * e))[:, :, None] * z.conj()
        force = -coeffs.cbar[:, :, None] * z
        out = np.empty((m, self.nq, self.nq))
        total = force.sum(axis=1)
        out[:, 0] = total.real
        out[:, 1] = total.imag
        torque = (e.conj()[:, :, None] * (self._kt @ force)).imag
        torque[:, :, 2:] -= coeffs.c_theta[:, :, None] * self._lower
        out[:, 2:] = self._suffix(torque.transpose(0, 2, 1)).transpose(0, 2, 1)
        return -out


class FrictionCoefficients:
    """Per-run, per-link friction coefficients in the form the complex route uses.

    Attributes ``cbar`` (``(c_x + c_y) / 2``), ``ratio`` (``(c_x - c_y) / (c_x + c_y)``,
    None when isotropic everywhere) and ``c_theta`` are (B, n) arrays.

    Parameters
    ----------
    robots : sequence of SnakeParams
        One robot per run (B of them), all with the same number of links.

    Raises
    ------
    ParameterError
        ``robots`` is not a non-empty sequence of SnakeParams of one n.
    """

    def __init__(self, robots: Sequence[SnakeParams]) -> None:
        robots = [check_params(p, "robots[]") for p in _items(robots, "robots")]
        if len({p.n for p in robots}) > 1:
            raise ParameterError("robots must all have the same number of links")
        c_x = np.array([p.per_link("c_x") for p in robots]).reshape(len(robots), -1)
        c_y = np.array([p.per_link("c_y") for p in robots]).reshape(len(robots), -1)
        self.cbar = 0.5 * (c_x + c_y)
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(self.cbar > 0, (c_x - c_y) / (c_x + c_y), 0.0)
        self.ratio: np.ndarray | None = ratio if np.any(ratio) else None
        self.c_theta = np.array([p.per_link("c_theta") for p in robots]).reshape(
            len(robots), -1)

    def equals(self, other: FrictionCoefficients) -> bool:
        """Tell whether ``other`` holds the same coefficients, run by run.

        Parameters
        ----------
        other : FrictionCoefficients
            Coefficients to compare with.

        Returns
        -------
        bool
            True when every array is equal (exactly).
        """
        if other is self:
            return True
        if not (np.array_equal(self.cbar, other.cbar)
                and np.array_equal(self.c_theta, other.c_theta)):
            return False
        if self.ratio is None or other.ratio is None:
            return self.ratio is None and other.ratio is None
        return np.array_equal(self.ratio, other.ratio)

    def take(self, rows: np.ndarray) -> FrictionCoefficients:
        """Return the coefficients of ``rows`` only.

        Parameters
        ----------
        rows : numpy.ndarray of int
            Positions of the runs to keep.

        Returns
        -------
        FrictionCoefficients
            A new object; ``self`` is unchanged.
        """
        out = object.__new__(FrictionCoefficients)
        out.cbar, out.c_theta = self.cbar[rows], self.c_theta[rows]
        out.ratio = None if self.ratio is None else self.ratio[rows]
        return out


# ------------------------------------------------------------ references and gaits
class _References:
    """Head references of the runs: (w_r, w_r', w_r'') as (m, 3) arrays."""

    def __init__(self, references: Sequence[Any]) -> None:
        self._linear = np.array([type(r) is LinearReference for r in references], dtype=bool)
        self._objects = list(references)
        self._start = np.array([r.start if lin else (0.0,) * 3
                                for r, lin in zip(references, self._linear, strict=True)],
                               dtype=float).reshape(-1, 3)
        self._velocity = np.array([r.velocity if lin else (0.0,) * 3
                                   for r, lin in zip(references, self._linear, strict=True)],
                                  dtype=float).reshape(-1, 3)
        self._all_linear = bool(self._linear.all())

    def take(self, rows: np.ndarray) -> None:
        self._linear = self._linear[rows]
        self._objects = [self._objects[r] for r in rows]
        self._start, self._velocity = self._start[rows], self._velocity[rows]

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        w_r = self._start + self._velocity * t
        dw_r = self._velocity.copy()
        ddw_r = np.zeros_like(w_r)
        if not self._all_linear:
            for row in np.flatnonzero(~self._linear):
                w_r[row], dw_r[row], ddw_r[row] = self._objects[row](t)
        return w_r, dw_r, ddw_r


class _Gaits:
    """Joint references of the runs: (phi_r, phi_r', phi_r'') as (m, n - 1) arrays."""

    def __init__(self, gaits: Sequence[Any], n: int) -> None:
        self._serpenoid = np.array([type(g) is Serpenoid for g in gaits], dtype=bool)
        self._objects = list(gaits)
        rows = [(g.spatial_frequency * g.alpha, g.v) if s else (0.0, 0.0)
                for g, s in zip(gaits, self._serpenoid, strict=True)]
        values = np.array(rows, dtype=float).reshape(-1, 2)
        amplitude, self._v = values[:, 0], values[:, 1]
        # the amplitudes as Serpenoid computes them (amplitude, amplitude v, -amplitude v^2)
        self._amp = amplitude[:, None]
        self._amp_v = (amplitude * self._v)[:, None]
        self._amp_a = (-amplitude * self._v**2)[:, None]
        self._offsets = np.array([g.spatial_frequency * np.arange(1, n) if s else np.zeros(n - 1)
                                  for g, s in zip(gaits, self._serpenoid, strict=True)],
                                 dtype=float).reshape(-1, n - 1)
        self._all_serpenoid = bool(self._serpenoid.all())

    def take(self, rows: np.ndarray) -> None:
        self._serpenoid = self._serpenoid[rows]
        self._objects = [self._objects[r] for r in rows]
        for name in ("_v", "_amp", "_amp_v", "_amp_a", "_offsets"):
            setattr(self, name, getattr(self, name)[rows])

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        phase = self._v[:, None] * t - self._offsets
        sine = np.sin(phase)
        out = (self._amp * sine, self._amp_v * np.cos(phase), self._amp_a * sine)
        if not self._all_serpenoid:
            for row in np.flatnonzero(~self._serpenoid):
                for target, value in zip(out, self._objects[row].derivatives(t), strict=True):
                    target[row] = value
        return out


# -------------------------------------------------------------------- solves
def _solve(matrices: np.ndarray, rhs: np.ndarray, scalar: Callable[[np.ndarray, np.ndarray],
                                                                    np.ndarray],
           failures: dict[int, Failure], rows: np.ndarray | None = None) -> np.ndarray:
    """Batched LU solve; runs whose solve fails or is non-finite go through ``scalar``.

    ``scalar(a, b)`` is the scalar law's own routine for one run: it returns the solution
    or raises the scalar law's exception, which is recorded in ``failures`` under the run's
    row (``rows[i]`` when the matrices are a subset of the batch).
    """
    vectors = rhs.ndim == matrices.ndim - 1
    try:
        out = np.linalg.solve(matrices, rhs[..., None] if vectors else rhs)
        if vectors:
            out = out[..., 0]
        bad = np.flatnonzero(~np.isfinite(out).reshape(len(out), -1).all(axis=1))
    except np.linalg.LinAlgError:
        out = np.empty(rhs.shape)
        bad = np.arange(len(matrices))
    for i in bad:
        row = int(i if rows is None else rows[i])
        try:
            out[i] = scalar(matrices[i], rhs[i])
        except Exception as exc:
            failures.setdefault(row, exc)  # a run's first failure is the one it reports
            out[i] = 0.0
    return out


def _solve_or_nan(matrices: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Batched LU solve of matrix-vector systems; a singular run's solution is NaN."""
    try:
        return np.linalg.solve(matrices, vectors[..., None])[..., 0]
    except np.linalg.LinAlgError:
        out = np.full(vectors.shape, np.nan)
        for row in range(len(matrices)):
            try:
                out[row] = np.linalg.solve(matrices[row], vectors[row])
            except np.linalg.LinAlgError:
                pass
        return out


def _posv(message: str) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """A scalar Cholesky solve (LAPACK dposv) that raises the scalar law's message."""
    def solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        solution, info = lapack.dposv(a, b)[1:]
        if info != 0:
            raise SingularPostureError(message.format(info=info))
        return solution
    return solve


def _gesv(message: str) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """A scalar LU solve (LAPACK dgesv) that raises the scalar law's message."""
    def solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        _, _, solution, info = lapack.dgesv(a, b)
        if info != 0:
            raise SingularPostureError(message.format(info=info))
        return solution
    return solve


def _mat_vec(matrices: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Row-wise matrix-vector products: (m, i, j) x (m, j) -> (m, i)."""
    return (matrices @ vectors[:, :, None])[:, :, 0]


# ---------------------------------------------------------------- controllers
class BatchedController(abc.ABC):
    """A controller for the m runs still going of a lockstep batch (module docstring)."""

    #: Number of runs currently held.
    size: int

    def reset(self) -> dict[int, Failure]:
        """Forget internal state before the runs start.

        Returns
        -------
        dict of int to BaseException or str
            Rows that failed to reset, with their failure (empty by default).
        """
        return {}

    @abc.abstractmethod
    def __call__(self, x: np.ndarray, t: float) -> tuple[np.ndarray, dict[int, Failure]]:
        """Return the torques for the states x at time t, and the failures.

        Parameters
        ----------
        x : numpy.ndarray, shape (m, 2(n + 2))
            States ``[q, dq]`` of the m runs held.
        t : float
            Time [s].

        Returns
        -------
        tau : numpy.ndarray, shape (m, n - 1)
            Joint torques [N m] (rows that failed hold anything).
        failures : dict of int to BaseException or str
            Row -> the exception its law raised, or the torque problem (text).
        """

    @abc.abstractmethod
    def keep(self, rows: np.ndarray) -> None:
        """Keep only the runs at ``rows``.

        Parameters
        ----------
        rows : numpy.ndarray of int
            Sorted positions among the runs held.
        """

    def signals(self) -> dict[str, np.ndarray]:
        """Return the per-row diagnostics of the last call.

        Returns
        -------
        dict of str to numpy.ndarray
            Signal name (``V``, ``R``, ...) -> values of shape (m,) (NaN for rows that
            failed); empty by default.
        """
        return {}

    def predicted(self, x: np.ndarray) -> np.ndarray | None:
        """Return the plant's q'' at the last call's states x, if the law knows it exactly.

        Parameters
        ----------
        x : numpy.ndarray, shape (m, 2(n + 2))
            The states array of the last call (compared by identity).

        Returns
        -------
        numpy.ndarray of shape (m, n + 2) or None
            q'' under the last torques, or None (by default, or for other states).
        """
        return None

    def mark_exact(self, exact: np.ndarray) -> None:  # noqa: B027 - optional hook
        """Tell which runs' controllers model their plant exactly.

        Same layout, friction and passive joints: :meth:`predicted` may then serve the
        plant's first stage. Ignored by default.

        Parameters
        ----------
        exact : numpy.ndarray of bool, shape (m,)
            One flag per run held.
        """


class _Vectorised(BatchedController):
    """Shared parts of the vectorised laws: model terms, references, gaits, per-run arrays."""

    #: Names of the per-run arrays (batch first) that :meth:`keep` selects.
    _per_run: tuple[str, ...] = ()
    #: The one controller type a subclass vectorises (set below its definition).
    _law: type

    def __init__(self, controllers: Sequence[Any], terms: BatchTerms | None = None) -> None:
        controllers = _items(controllers, "controllers")
        law = self._law
        for controller in controllers:
            if type(controller) is not law:
                raise ParameterError(f"controllers must all be {law.__name__} (exactly), "
                                     f"got {brief(controller)}")
        layout = layout_key(controllers[0].snake.params)
        if any(layout_key(c.snake.params) != layout for c in controllers):
            raise ParameterError("controllers must all model robots of one layout "
                                 f"({', '.join(LAYOUT_FIELDS)})")
        if terms is not None and (not isinstance(terms, BatchTerms)
                                  or terms._layout != layout):
            raise ParameterError(f"terms must be None or the BatchTerms of the controllers' "
                                 f"layout, got {brief(terms)}")
        first = controllers[0]
        params = [c.snake.params for c in controllers]
        self.n = first.snake.n
        self.nq = self.n + 2
        self.size = len(controllers)
        self.terms = BatchTerms(params[0]) if terms is None else terms
        self.friction = FrictionCoefficients(params)
        self.references = _References([c.reference for c in controllers])
        self.gaits = _Gaits([c.gait for c in controllers], self.n)
        self.actuated = np.array([[0.0 if k in p.passive else 1.0 for k in range(1, self.n)]
                                  for p in params]).reshape(self.size, self.n - 1)
        self._last: dict[str, np.ndarray] = {}

    def keep(self, rows: np.ndarray) -> None:
        rows = np.asarray(rows, dtype=int)
        self.size = len(rows)
        self.friction = self.friction.take(rows)
        self.references.take(rows)
        self.gaits.take(rows)
        self.actuated = self.actuated[rows]
        for name in self._per_run:
            setattr(self, name, getattr(self, name)[rows])
        self._last = {k: v[rows] for k, v in self._last.items()}

    def __call__(self, x: np.ndarray, t: float) -> tuple[np.ndarray, dict[int, Failure]]:
        # a run's NaN or overflow stays in its own row (and is judged there), unwarned
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            return self._evaluate(x, t)

    @abc.abstractmethod
    def _evaluate(self, x: np.ndarray, t: float) -> tuple[np.ndarray, dict[int, Failure]]:
        """The law for every row (see :meth:`BatchedController.__call__`)."""

    def bias(self, x: np.ndarray) -> np.ndarray:
        """h = Coriolis - friction force for each state (the controllers' model)."""
        return self.terms.bias(x, self.friction)

    def signals(self) -> dict[str, np.ndarray]:
        return self._last


class BatchedLyapunov(_Vectorised):
    """:class:`~snake_pin.control.lyapunov.LyapunovController` over a batch.

    The same least squares, solved without ``H^-1``. Split H and h at the base (w: rows
    0..2) and the joints (phi): with ``F = H11^-1 [H12, h1]`` (``H11 = [[M I, p], [p^T, w]]``
    inverts in closed form), ``S = H22 - H21 F_12`` and ``r2 = h2 - H21 F_h``, the
    dynamics read::

        phi'' = S^-1 (E_a tau_a - r2),   w'' = -F_12 phi'' - F_h.

    Taking ``y = phi''`` as the unknown, ``q'' = Z y + c`` with ``Z = [-F_12; I]``,
    ``c = [-F_h; 0]``, and the law's argmin over tau_a is the argmin over y of
    ``||Z y + c - q''*||_W`` subject to ``(S y + r2)_k = 0`` on the passive joints k (a
    bijection: ``tau = S y + r2``). Without passive joints that is one (n - 1) x (n - 1)
    solve, ``(Z^T W Z) y = Z^T W (q''* - c)``; with them, the KKT system::

        [[Z^T W Z, (P S)^T], [P S, U]] [y; nu] = [Z^T W (q''* - c); -P r2]

    of size n - 1 + p, p the most passive joints of any run in the batch: P's rows pick a
    run's passive joints, rows beyond its own count are zero with a 1 on U's diagonal
    (their multiplier is 0). Then ``tau = S y + r2``. A run whose result is not finite is
    evaluated again by its own scalar controller, so it fails (or not) exactly as in
    :func:`~snake_pin.sim.simulate`.

    Parameters
    ----------
    controllers : sequence of LyapunovController
        One controller per run, all of one layout (exactly this type).
    terms : BatchTerms or None, optional
        Model terms to share (the plant's); default: a new one for the layout.

    Raises
    ------
    ParameterError
        ``controllers`` is not a non-empty sequence of LyapunovController of one layout, or
        ``terms`` is not None nor the BatchTerms of that layout.
    """

    _per_run = ("k_w1", "k_w2", "k_phi", "lam", "lam_shape", "k_shape", "_kkt_fixed",
                "_pick", "_scalar", "exact")
    _law = LyapunovController

    def __init__(self, controllers: Sequence[LyapunovController],
                 terms: BatchTerms | None = None) -> None:
        super().__init__(controllers, terms)
        k = self.n - 1
        self.k_w1 = np.array([c.k_w1 for c in controllers])
        self.k_w2 = np.array([np.diag(c.k_w2) for c in controllers])
        self.k_phi = np.array([np.diag(c.k_phi) for c in controllers])
        self.lam = np.array([c.lam for c in controllers])[:, None]
        self.lam_shape = np.array([c.lam_shape for c in controllers])[:, None]
        self.k_shape = np.array([c.k_shape for c in controllers])[:, None]
        self._scalar = np.empty(len(controllers), dtype=object)
        self._scalar[:] = list(controllers)
        #: Whether each run's controller models its plant exactly (set by the simulator).
        self.exact = np.zeros(self.size, dtype=bool)
        self._predicted: tuple[np.ndarray, np.ndarray] | None = None
        passive = [np.flatnonzero(row == 0.0) for row in self.actuated]
        width = max(len(joints) for joints in passive)
        self._passive = width > 0
        # P picks each run's passive joints; the KKT matrix's constant blocks: W_phi on the
        # top-left diagonal, U (1 on the rows P leaves empty) on the bottom-right one
        self._pick = np.zeros((self.size, width, k))
        self._kkt_fixed = np.zeros((self.size, k + width, k + width))
        diagonal = np.arange(k)
        self._kkt_fixed[:, diagonal, diagonal] = self.k_phi
        for row, joints in enumerate(passive):
            self._pick[row, np.arange(len(joints)), joints] = 1.0
            for slot in range(len(joints), width):
                self._kkt_fixed[row, k + slot, k + slot] = 1.0

    def _evaluate(self, x: np.ndarray, t: float) -> tuple[np.ndarray, dict[int, Failure]]:
        nq, k = self.nq, self.n - 1
        failures: dict[int, Failure] = {}
        q, dq = x[:, :nq], x[:, nq:]
        h_mat = self.terms.inertia(x)
        h_vec = self.bias(x)
        # F = H11^-1 [H12, h1] in closed form: H11 = [[M I, p], [p^T, w]]
        mass = h_mat[:, 0, 0][:, None]
        p_x, p_y, w = (h_mat[:, i, 2][:, None] for i in range(3))
        right = np.concatenate((h_mat[:, :3, 3:], h_vec[:, :3, None]), axis=2)
        sigma = w - (p_x * p_x + p_y * p_y) / mass
        f_theta = (right[:, 2] - (p_x * right[:, 0] + p_y * right[:, 1]) / mass) / sigma
        f_all = np.stack(((right[:, 0] - p_x * f_theta) / mass,
                          (right[:, 1] - p_y * f_theta) / mass, f_theta), axis=1)
        f_12, f_h = f_all[:, :, :k], f_all[:, :, k]
        h21 = h_mat[:, 3:, :3]
        schur = h_mat[:, 3:, 3:] - h21 @ f_12
        r2 = h_vec[:, 3:] - _mat_vec(h21, f_h)
        # targets, as LyapunovController.targets
        w_r, dw_r, ddw_r = self.references(t)
        de_w = dw_r - dq[:, :3]
        s = de_w + _mat_vec(self.k_w1, w_r - q[:, :3])
        phi_r, dphi_r, ddphi_r = self.gaits(t)
        e = dphi_r - dq[:, 3:]
        shape = ddphi_r + self.lam_shape * e + self.k_shape * (phi_r - q[:, 3:])
        target_w = ddw_r + _mat_vec(self.k_w1, de_w) + self.lam * s
        weighted = f_12.transpose(0, 2, 1) * self.k_w2[:, None, :]  # F_12^T W_w
        gradient = self.k_phi * shape - _mat_vec(weighted, target_w + f_h)
        if self._passive:
            kkt = self._kkt_fixed.copy()
            kkt[:, :k, :k] += weighted @ f_12
            constraint = self._pick @ schur
            kkt[:, k:, :k] = constraint
            kkt[:, :k, k:] = constraint.transpose(0, 2, 1)
            rhs = np.concatenate((gradient, -_mat_vec(self._pick, r2)), axis=1)
            y = _solve_or_nan(kkt, rhs)[:, :k]
        else:
            normal = weighted @ f_12
            normal[:, np.arange(k), np.arange(k)] += self.k_phi
            y = _solve_or_nan(normal, gradient)
        tau = (_mat_vec(schur, y) + r2) * self.actuated
        bad = np.flatnonzero(~np.isfinite(tau).all(axis=1))
        for row in bad:  # the scalar law decides: its value, or its exception
            try:
                tau[row] = self._scalar[row](x[row], t)
            except Exception as exc:
                failures[int(row)] = exc
        self._last = {"V": np.einsum("bi,bi->b", s * self.k_w2, s)
                      + np.einsum("bi,bi->b", e * self.k_phi, e)}
        self._predicted = None
        if len(bad) == 0 and self.exact.all():
            predicted = np.empty((len(x), nq))
            predicted[:, :3] = -_mat_vec(f_12, y) - f_h
            predicted[:, 3:] = y
            self._predicted = (x, predicted)
        return tau, failures

    def mark_exact(self, exact: np.ndarray) -> None:
        """Record which runs' controllers model their plant exactly (for :meth:`predicted`).

        Parameters
        ----------
        exact : numpy.ndarray of bool, shape (m,)
            One flag per run held.
        """
        self.exact = np.asarray(exact, dtype=bool).copy()

    def predicted(self, x: np.ndarray) -> np.ndarray | None:
        """Return the plant's q'' at the last call's states under its torques, if known.

        Known when every run's controller models its plant exactly: ``y = phi''`` and
        ``w'' = -F_12 y - F_h``.

        Parameters
        ----------
        x : numpy.ndarray, shape (m, 2(n + 2))
            The states array of the last call (compared by identity).

        Returns
        -------
        numpy.ndarray of shape (m, n + 2) or None
            q'' [m/s^2, rad/s^2], or None.
        """
        known = self._predicted
        return known[1] if known is not None and known[0] is x else None


class BatchedQuasiStatic(_Vectorised):
    """:class:`~snake_pin.control.quasistatic.QuasiStaticLyapunovController` over a batch.

    Per run: C(q) from the closed form; the connection ``J = -C_uu^-1 C_ua`` from one
    batched solve with the actuated rows of C_uu replaced by the identity; the rate of
    least V by the normal equations; the integrated joint reference and the PD servos.

    Parameters
    ----------
    controllers : sequence of QuasiStaticLyapunovController
        One controller per run, all of one layout (exactly this type).
    terms : BatchTerms or None, optional
        Model terms to share (the plant's); default: a new one for the layout.

    Raises
    ------
    ParameterError
        ``controllers`` is not a non-empty sequence of QuasiStaticLyapunovController
        of one layout, or ``terms`` is not None nor the BatchTerms of that layout.
    """

    _per_run = ("k_w1", "_w_u", "_w_a", "_normal_diag", "_umask", "_k_p", "_k_d",
                "max_lead", "dt", "_reference", "_started", "_uu", "_ua", "_eye_a")
    _law = QuasiStaticLyapunovController

    def __init__(self, controllers: Sequence[QuasiStaticLyapunovController],
                 terms: BatchTerms | None = None) -> None:
        super().__init__(controllers, terms)
        n, nq, size = self.n, self.nq, self.size
        passive = 1.0 - self.actuated
        self.k_w1 = np.array([c.k_w1 for c in controllers])
        # the scalar law's weights: K_w2 and K_phi of the passive rows (u), K_phi (actuated)
        w_u = np.zeros((size, nq))
        w_a = np.zeros((size, n - 1))
        for row, c in enumerate(controllers):
            u_rows, a_cols = c._u, c._a - 3
            w_u[row, u_rows] = c._w_u
            w_a[row, a_cols] = c._w_a
        self._w_u, self._w_a = w_u, w_a
        self._normal_diag = np.einsum("bi,ij->bij", w_a + passive, np.eye(n - 1))
        self._umask = np.concatenate((np.ones((size, 3)), passive), axis=1)
        self._uu = self._umask[:, :, None] * self._umask[:, None, :]
        self._ua = self._umask[:, :, None] * self.actuated[:, None, :]
        self._eye_a = np.einsum("bi,ij->bij", 1.0 - self._umask, np.eye(nq))
        self._k_p = np.array([c.k_p for c in controllers]) * self.actuated
        self._k_d = np.array([c.k_d for c in controllers]) * self.actuated
        self.max_lead = np.array([c.max_lead for c in controllers])[:, None]
        self.dt = np.array([c.dt for c in controllers])[:, None]
        self._reference = np.zeros((size, n - 1))
        self._started = np.zeros(size, dtype=bool)

    def reset(self) -> dict[int, Failure]:
        """Restart every run's integrated joint reference at its next state.

        Returns
        -------
        dict of int to BaseException or str
            Always empty (nothing can fail).
        """
        self._started[:] = False
        return {}

    def _evaluate(self, x: np.ndarray, t: float) -> tuple[np.ndarray, dict[int, Failure]]:
        nq = self.nq
        failures: dict[int, Failure] = {}
        q = x[:, :nq]
        c = self.terms.friction_matrix(x, self.friction)
        # J = -C_uu^-1 C_ua on the u rows (zero on the actuated rows and passive columns)
        jac = -_solve(c * self._uu + self._eye_a, c[:, :, 3:] * self._ua,
                      _gesv("C_uu is singular (LAPACK info {info})"), failures)
        w_r, dw_r, _ = self.references(t)
        _, dphi_r, _ = self.gaits(t)
        target_u = np.concatenate((dw_r + _mat_vec(self.k_w1, w_r - q[:, :3]),
                                   dphi_r * self._umask[:, 3:]), axis=1)
        target_a = dphi_r * self.actuated
        weighted = jac.transpose(0, 2, 1) * self._w_u[:, None, :]
        normal = weighted @ jac + self._normal_diag
        rate = _solve(normal, _mat_vec(weighted, target_u) + self._w_a * target_a,
                      _posv("normal equations not positive definite (info {info})"), failures)
        rate *= self.actuated
        residual_u = _mat_vec(jac, rate) - target_u
        residual_a = rate - target_a
        value = np.einsum("bi,bi->b", residual_u * self._w_u, residual_u) \
            + np.einsum("bi,bi->b", residual_a * self._w_a, residual_a)
        joints = x[:, 3:nq]
        fresh = ~self._started
        if fresh.any():
            self._reference[fresh] = joints[fresh]
            self._started[fresh] = True
        lead = np.clip(self._reference + rate * self.dt - joints, -self.max_lead, self.max_lead)
        self._reference = joints + lead
        tau = (self._k_p * lead + self._k_d * (rate - x[:, nq + 3:])) * self.actuated
        self._last = {"V": value}
        return tau, failures


class BatchedPFL(_Vectorised):
    """:class:`~snake_pin.control.pfl.PFLController` over a batch (every joint actuated).

    Per run: H12 = U S V^T by a batched SVD (R = the smallest singular value, checked
    against r_min), H22^-1 [H21, h2] by one batched solve, then eqs. (70)-(78) as in the
    scalar law; the optional climb term takes its R probes for all climbing runs in one
    call of :func:`~snake_pin.manipulability.manipulability_R_batch`.

    Parameters
    ----------
    controllers : sequence of PFLController
        One controller per run, all of one layout (exactly this type).
    terms : BatchTerms or None, optional
        Model terms to share (the plant's); default: a new one for the layout.

    Raises
    ------
    ParameterError
        ``controllers`` is not a non-empty sequence of PFLController of one layout, or
        ``terms`` is not None nor the BatchTerms of that layout.
    """

    _per_run = ("k_v", "k_p", "r_v", "r_p", "r_min", "climb_R", "climb_damping")
    _law = PFLController

    def __init__(self, controllers: Sequence[PFLController],
                 terms: BatchTerms | None = None) -> None:
        super().__init__(controllers, terms)
        self.k_v = np.array([c.k_v for c in controllers])
        self.k_p = np.array([c.k_p for c in controllers])
        self.r_v = np.array([c.r_v for c in controllers])
        self.r_p = np.array([c.r_p for c in controllers])
        self.r_min = np.array([c.r_min for c in controllers])
        self.climb_R = np.array([c.climb_R for c in controllers])
        self.climb_damping = np.array([c.climb_damping for c in controllers])
        self._params = controllers[0].snake.params

    def _evaluate(self, x: np.ndarray, t: float) -> tuple[np.ndarray, dict[int, Failure]]:
        nq = self.nq
        failures: dict[int, Failure] = {}
        q, dq = x[:, :nq], x[:, nq:]
        h_mat = self.terms.inertia(x)
        h_vec = self.bias(x)
        h12, h22 = h_mat[:, :3, 3:], h_mat[:, 3:, 3:]
        h1, h2 = h_vec[:, :3], h_vec[:, 3:]
        u_svd, s_svd, vt_svd = self._svd(h12)
        r = s_svd[:, -1]
        for row in np.flatnonzero(~(r > self.r_min)):
            failures[int(row)] = SingularPostureError(
                f"R = {r[row]:.3g} <= {self.r_min[row]:g}: PFL is undefined here")
        with np.errstate(divide="ignore", invalid="ignore"):
            h12_pinv = (vt_svd.transpose(0, 2, 1) / s_svd[:, None, :]) @ u_svd.transpose(0, 2, 1)
        rhs = np.concatenate((h12.transpose(0, 2, 1), h2[:, :, None]), axis=2)
        solved = _solve(h22, rhs, _posv("H22 is not positive definite (LAPACK info {info})"),
                        failures)
        h22_inv_h21, h22_inv_h2 = solved[:, :, :3], solved[:, :, 3]
        schur = h_mat[:, :3, :3] - h12 @ h22_inv_h21
        w_r, dw_r, ddw_r = self.references(t)
        a = ddw_r + _mat_vec(self.k_v, dw_r - dq[:, :3]) + _mat_vec(self.k_p, w_r - q[:, :3])
        y = -_mat_vec(schur, a) - h1 + _mat_vec(h12, h22_inv_h2)
        dphi = dq[:, 3:]
        phi_r, dphi_r, ddphi_r = self.gaits(t)
        u = -ddphi_r - _mat_vec(self.r_v, dphi_r - dphi) - _mat_vec(self.r_p, phi_r - q[:, 3:])
        climbing = np.flatnonzero(self.climb_R > 0)
        if len(climbing):
            grad = self._grad_log_r(q[climbing, 3:])
            u[climbing] -= self.climb_damping[climbing, None] * (
                self.climb_R[climbing, None] * grad - dphi[climbing])
        kappa = h22_inv_h2 - u
        null = kappa - _mat_vec(h12_pinv, _mat_vec(h12, kappa))
        tau = _mat_vec(h22, _mat_vec(h12_pinv, y) + null)
        self._last = {"R": r.copy()}
        return tau, failures

    @staticmethod
    def _svd(h12: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        try:
            return np.linalg.svd(h12, full_matrices=False)
        except np.linalg.LinAlgError:  # one run did not converge: the others still can
            m, k = h12.shape[0], h12.shape[1]
            u = np.full((m, k, k), np.nan)
            s = np.full((m, k), np.nan)
            vt = np.full((m, k, h12.shape[2]), np.nan)
            for row in range(m):
                u_r, s_r, vt_r, info = lapack.dgesdd(h12[row], full_matrices=0)
                if info == 0:
                    u[row], s[row], vt[row] = u_r, s_r, vt_r
            return u, s, vt

    def _grad_log_r(self, phi: np.ndarray, step: float = 1e-6) -> np.ndarray:
        """Central-difference gradient of log R over phi for each row (one batched call)."""
        m, dim = phi.shape
        probes = phi[:, None, :] + np.vstack([step * np.eye(dim), -step * np.eye(dim)])[None]
        # unchecked: a diverging run's NaN stays in its own row (PFL: no passive joint)
        r = _r_batch(self._params, probes.reshape(-1, dim), (), True).reshape(m, 2 * dim)
        return (np.log(r[:, :dim]) - np.log(r[:, dim:])) / (2 * step)


class PerRunControllers(BatchedController):
    """Any controllers, called run by run (the fallback for laws without a batched form).

    Parameters
    ----------
    controllers : sequence of Controller
        One :class:`~snake_pin.control.base.Controller` per run (plain functions are
        wrapped by the caller).
    validate : callable
        ``validate(raw, size) -> (tau or None, problem)``: the simulator's torque check.
    n_tau : int
        n - 1, the number of torques each controller returns.

    Raises
    ------
    ParameterError
        ``controllers`` is not a non-empty sequence of callables, ``validate`` is not
        callable or ``n_tau`` is not a positive integer.
    """

    def __init__(self, controllers: Sequence[Controller],
                 validate: Callable[[object, int], tuple[np.ndarray | None, str]],
                 n_tau: int) -> None:
        self._controllers = [_callable(c, "controllers[]")
                             for c in _items(controllers, "controllers")]
        self._validate = _callable(validate, "validate")
        self._n_tau = integer(n_tau, "n_tau", low=1)
        self.size = len(controllers)
        self._last: dict[str, np.ndarray] = {}

    def reset(self) -> dict[int, Failure]:
        """Reset every run's controller.

        Returns
        -------
        dict of int to BaseException or str
            Rows whose ``reset()`` raised, with the exception.
        """
        failures: dict[int, Failure] = {}
        for row, ctrl in enumerate(self._controllers):
            try:
                ctrl.reset()
            except Exception as exc:
                failures[row] = exc
        return failures

    def keep(self, rows: np.ndarray) -> None:
        """Keep only the runs at ``rows``.

        Parameters
        ----------
        rows : numpy.ndarray of int
            Sorted positions among the runs held.
        """
        self._controllers = [self._controllers[r] for r in rows]
        self.size = len(rows)
        self._last = {k: v[rows] for k, v in self._last.items()}

    def __call__(self, x: np.ndarray, t: float) -> tuple[np.ndarray, dict[int, Failure]]:
        tau = np.zeros((len(x), self._n_tau))
        failures: dict[int, Failure] = {}
        last: dict[str, np.ndarray] = {}
        for row, ctrl in enumerate(self._controllers):
            try:
                value, problem = self._validate(ctrl(x[row], t), self._n_tau)
                if value is None:
                    failures[row] = problem
                    continue
                for name, signal in ctrl.signals().items():
                    series = last.get(name)
                    if series is None:
                        series = last[name] = np.full(len(x), np.nan)
                    series[row] = signal
            except Exception as exc:
                failures[row] = exc
                continue
            tau[row] = value
        self._last = last
        return tau, failures

    def signals(self) -> dict[str, np.ndarray]:
        """Return the per-row diagnostics of the last call.

        Returns
        -------
        dict of str to numpy.ndarray
            Signal name -> values of shape (m,), NaN for rows without that signal.
        """
        return self._last


class GroupedControllers(BatchedController):
    """Several batched controllers, each over its own runs of the batch.

    Parameters
    ----------
    groups : sequence of (numpy.ndarray, BatchedController)
        ``(rows, controller)`` pairs: the batch positions (sorted) each controller holds;
        together they cover 0..B-1 once.
    n_tau : int
        n - 1, the number of torques per run.

    Raises
    ------
    ParameterError
        ``groups`` is not a non-empty sequence of (rows, BatchedController) pairs whose
        rows cover 0..B-1 once, or ``n_tau`` is not a positive integer.
    """

    def __init__(self, groups: Sequence[tuple[np.ndarray, BatchedController]],
                 n_tau: int) -> None:
        checked = []
        for group in _items(groups, "groups"):
            if not isinstance(group, tuple) or len(group) != 2 \
                    or not isinstance(group[1], BatchedController):
                raise ParameterError(f"groups must hold (rows, BatchedController) pairs, "
                                     f"got {brief(group)}")
            rows = np.asarray(group[0])
            if rows.ndim != 1 or rows.dtype.kind not in "iu" or len(rows) != group[1].size:
                raise ParameterError("groups' rows must be integer arrays, one row per run "
                                     "of their controller")
            checked.append((rows.astype(int), group[1]))
        every = np.sort(np.concatenate([rows for rows, _ in checked]))
        if not np.array_equal(every, np.arange(len(every))):
            raise ParameterError("groups' rows must cover 0..B-1 once")
        self.size = len(every)
        self._n_tau = integer(n_tau, "n_tau", low=1)
        self._groups = checked
        self._last: dict[str, np.ndarray] = {}

    def reset(self) -> dict[int, Failure]:
        """Reset every group.

        Returns
        -------
        dict of int to BaseException or str
            Batch rows that failed to reset, with their failure.
        """
        failures: dict[int, Failure] = {}
        for rows, ctrl in self._groups:
            for row, failure in ctrl.reset().items():
                failures[int(rows[row])] = failure
        return failures

    def keep(self, rows: np.ndarray) -> None:
        """Keep only the runs at ``rows``.

        Parameters
        ----------
        rows : numpy.ndarray of int
            Sorted positions among the runs held.
        """
        position = np.full(self.size, -1)
        position[np.asarray(rows, dtype=int)] = np.arange(len(rows))
        groups = []
        for members, ctrl in self._groups:
            new = position[members]
            kept = np.flatnonzero(new >= 0)
            if len(kept) == 0:
                continue
            if len(kept) < len(members):
                ctrl.keep(kept)
            groups.append((new[kept], ctrl))
        self._groups = groups
        self.size = len(rows)
        self._last = {k: v[rows] for k, v in self._last.items()}

    def __call__(self, x: np.ndarray, t: float) -> tuple[np.ndarray, dict[int, Failure]]:
        tau = np.zeros((len(x), self._n_tau))
        failures: dict[int, Failure] = {}
        last: dict[str, np.ndarray] = {}
        for rows, ctrl in self._groups:
            part, failed = ctrl(x[rows], t)
            tau[rows] = part
            for row, failure in failed.items():
                failures[int(rows[row])] = failure
            for name, values in ctrl.signals().items():
                series = last.get(name)
                if series is None:
                    series = last[name] = np.full(len(x), np.nan)
                series[rows] = values
        self._last = last
        return tau, failures

    def signals(self) -> dict[str, np.ndarray]:
        """Return the per-row diagnostics of the last call.

        Returns
        -------
        dict of str to numpy.ndarray
            Signal name -> values of shape (m,), NaN for rows without that signal.
        """
        return self._last


_VECTORISED: dict[type, type[_Vectorised]] = {
    LyapunovController: BatchedLyapunov,
    QuasiStaticLyapunovController: BatchedQuasiStatic,
    PFLController: BatchedPFL,
}
#: The same types as a tuple, for ``isinstance`` (each keeps its robot as ``snake``).
_VECTORISED_TYPES = (LyapunovController, QuasiStaticLyapunovController, PFLController)


def batch_controller(controllers: Sequence[Controller], n_tau: int,
                     validate: Callable[[object, int], tuple[np.ndarray | None, str]],
                     terms: Callable[[SnakeParams], BatchTerms] | None = None
                     ) -> BatchedController:
    """Return one batched controller for per-run controllers (module docstring).

    Runs whose controllers are of a vectorised type (exactly) and model the same layout
    are one vectorised group; every other run is called on its own.

    Parameters
    ----------
    controllers : sequence of Controller
        One controller per run.
    n_tau : int
        The plant's n - 1 (every controller must return that many torques).
    validate : callable
        The simulator's torque check, ``validate(raw, size) -> (tau or None, problem)``,
        for the per-run group.
    terms : callable or None, optional
        ``terms(params)`` gives the :class:`BatchTerms` to use for a layout (the plant's,
        to share its evaluations); default: a new one per group.

    Returns
    -------
    BatchedController
        One vectorised or per-run controller, or a :class:`GroupedControllers` of them.

    Raises
    ------
    ParameterError
        ``controllers`` is not a non-empty sequence of callables, ``n_tau`` not a
        positive integer, ``validate`` (or ``terms``, when given) not callable, or a
        vectorised controller models a robot with another number of joints.
    """
    controllers = [_callable(c, "controllers[]") for c in _items(controllers, "controllers")]
    n_tau = integer(n_tau, "n_tau", low=1)
    _callable(validate, "validate")
    if terms is not None:
        _callable(terms, "terms")
    groups: dict[tuple[Any, ...], list[int]] = {}
    models: dict[tuple[Any, ...], SnakeParams] = {}
    for row, ctrl in enumerate(controllers):
        kind = type(ctrl)
        if kind in _VECTORISED and isinstance(ctrl, _VECTORISED_TYPES):
            if ctrl.snake.n - 1 != n_tau:
                raise ParameterError(f"run {row}: the controller models the "
                                     f"{ctrl.snake.n}-link robot, the plant has "
                                     f"{n_tau + 1} links")
            key: tuple[Any, ...] = (kind, layout_key(ctrl.snake.params))
            models.setdefault(key, ctrl.snake.params)
        else:
            key = (None,)
        groups.setdefault(key, []).append(row)
    built: list[tuple[np.ndarray, BatchedController]] = []
    for key, rows in groups.items():
        members = [controllers[r] for r in rows]
        if key[0] is None:
            built.append((np.array(rows), PerRunControllers(members, validate, n_tau)))
        else:
            shared = None if terms is None else terms(models[key])
            built.append((np.array(rows), _VECTORISED[key[0]](members, shared)))
    if len(built) == 1:
        return built[0][1]
    return GroupedControllers(built, n_tau)
