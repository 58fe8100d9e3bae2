"""Line-of-sight (LOS) path following of the centre of mass after Liljebäck et al.: a
steered serpenoid gait, LOS guidance, heading control and joint PFL (:ref:`derivation-los`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from scipy.linalg import expm

from .._blas import solve_spd
from .._options import documented, option
from .._validation import brief, finite_number, instance
from ..exceptions import ParameterError, SingularPostureError
from ..model import Snake
from ..paths import Line, Path, PathReference
from ._options import merged
from .base import Controller

__all__ = ["LOSController", "LOSParams"]

_STEERING = ("cascaded", "pd")
#: The fields only one steering law reads: a value other than the default given with the
#: other law would have no effect, so it is refused.
_ONLY_FOR = {"cascaded": ("k_theta", "lambda1", "lambda2", "v_min"), "pd": ("k_p", "k_d")}
_POSITIVE: dict[str, Any] = {"low": 0.0, "open_low": True}


@documented
@dataclass(frozen=True)
class LOSParams:
    """Parameters of :class:`LOSController` (validated; the fields only one steering law
    reads keep their defaults under the other)."""

    alpha: float = option(0.5, "gait amplitude", unit="rad", low=0.0)
    omega: float = option(0.8, "gait frequency", unit="rad/s", **_POSITIVE)
    delta: float = option(0.94, "phase lag between joints", unit="rad")
    look_ahead: float = option(0.6, "LOS look-ahead distance Delta", unit="m", **_POSITIVE)
    steering: str = option("cascaded", "the published model-based heading law (cascaded) or "
                           "the PD law (pd)")
    k_theta: float = option(10.0, "heading gain of the cascaded law", unit="1/s^2", **_POSITIVE)
    lambda1: float = option(20.0, "turning constant of the averaged model (cascaded law)",
                            unit="1/s", **_POSITIVE)
    lambda2: float = option(186.0, "second turning constant of the averaged model (cascaded "
                            "law)", unit="1/(m s)", **_POSITIVE)
    v_min: float = option(0.03, "floor of the averaged forward speed (cascaded law)",
                          unit="m/s", **_POSITIVE)
    k_p: float = option(1.0, "gain of the PD steering law", unit="rad/rad", low=0.0)
    k_d: float = option(0.2, "damping of the PD steering law", unit="rad s/rad", low=0.0)
    phi0_max: float = option(0.35, "saturation of the joint offset", unit="rad", **_POSITIVE)
    phi0_rate: float = option(0.3, "saturation of the offset's rate", unit="rad/s", **_POSITIVE)
    ref_period: float = option(1.0, "period 2 pi / omega_c of the filter on theta_ref",
                               unit="s", **_POSITIVE)
    offset_period: float = option(0.5, "period of the filter on phi_0", unit="s", **_POSITIVE)
    speed_period: float = option(0.0, "period of the filter averaging v_t (0: one gait period)",
                                 unit="s")
    k_joint_p: float = option(100.0, "stiffness of the feedback-linearised joint law",
                              unit="1/s^2", **_POSITIVE)
    k_joint_d: float = option(20.0, "damping of the feedback-linearised joint law", unit="1/s",
                              **_POSITIVE)

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name != "steering":
                object.__setattr__(self, f.name, finite_number(
                    getattr(self, f.name), f"LOS parameter {f.name}",
                    positive=f.metadata["open_low"], non_negative=f.metadata["low"] == 0.0))
        if not isinstance(self.steering, str) or self.steering not in _STEERING:
            raise ParameterError(f"LOS parameter steering must be one of {', '.join(_STEERING)}, "
                                 f"got {brief(self.steering)}")
        defaults = {f.name: f.default for f in fields(self)}
        for law, names in _ONLY_FOR.items():
            for name in names if law != self.steering else ():
                if getattr(self, name) != defaults[name]:
                    raise ParameterError(f"LOS parameter {name} has no effect with steering = "
                                         f"{self.steering!r} (it is the {law!r} law's)")


def los_heading(gamma: float, cross_track: float, look_ahead: float) -> float:
    """The LOS angle ``gamma - atan(e / Delta)`` [rad] (cross-track e left positive, Delta > 0);
    ParameterError for a value that is not a finite number or a non-positive ``look_ahead``."""
    return _los_heading(finite_number(gamma, "gamma"), finite_number(cross_track, "cross_track"),
                        finite_number(look_ahead, "look_ahead", positive=True))


def _los_heading(gamma: float, cross_track: float, look_ahead: float) -> float:
    """:func:`los_heading` of checked numbers (the law's per-step call)."""
    return gamma - math.atan(cross_track / look_ahead)


def body_kinematics(snake: Snake, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
    """``(p_cm, v_cm, psi, psi')``: the CM's position and velocity and the mean heading of
    travel ``psi = mean(theta_i) + pi``; ParameterError, ConfigurationError for bad input."""
    x = instance(snake, Snake, "snake").check_state(x)
    return _kinematics(_cm_lever(snake), snake.nq, x)


def _cm_lever(snake: Snake) -> np.ndarray:
    """a_k with p_cm = p_head + sum_k a_k [cos theta_k, sin theta_k]:
    a_k = w_k c_k + L_k sum_{i > k} w_i, w_i = m_i / M."""
    params = snake.params
    weights = params.masses / params.masses.sum()
    behind = weights[::-1].cumsum()[::-1] - weights  # sum of w_i over i > k
    return weights * params.com_offsets + params.link_lengths * behind


def _kinematics(lever: np.ndarray, nq: int, x: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """:func:`body_kinematics` of checked arguments."""
    theta = np.cumsum(x[2:nq])  # theta_1, theta_1 + phi_1, ...
    dtheta = np.cumsum(x[nq + 2:])
    c, s = np.cos(theta), np.sin(theta)
    p_cm = np.array([x[0] + lever @ c, x[1] + lever @ s])
    spin = lever * dtheta
    v_cm = np.array([x[nq] - spin @ s, x[nq + 1] + spin @ c])
    count = len(theta)
    return p_cm, v_cm, float(theta.sum()) / count + math.pi, float(dtheta.sum()) / count


class ReferenceFilter:
    """Third-order low-pass ``y / r = omega_c^3 / ((s + omega_c)(s^2 + 2 zeta omega_c s +
    omega_c^2))``, ``omega_c = 2 pi / period``, giving y, y', y'' (ParameterError if not > 0).
    """

    def __init__(self, period: float, zeta: float = 1.0) -> None:
        period = finite_number(period, "period", positive=True)
        zeta = finite_number(zeta, "zeta", positive=True)
        wc = 2.0 * math.pi / period
        k = 2.0 * zeta + 1.0
        aug = np.zeros((4, 4))
        aug[0, 1] = aug[1, 2] = 1.0
        aug[2, :3] = (-wc**3, -k * wc**2, -k * wc)
        aug[2, 3] = wc**3
        self._aug = aug
        self._cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self.state: np.ndarray | None = None

    def reset(self, value: float | None = None) -> None:
        """Start at rest at ``value`` (None: at the next update's input)."""
        self.state = None if value is None else np.array([value, 0.0, 0.0])

    def update(self, r: float, dt: float) -> np.ndarray:
        """``[y, y', y'']`` (a fresh array) after ``dt`` [s] with ``r`` held: exact (a matrix
        exponential cached per step length)."""
        if self.state is None:
            self.state = np.array([r, 0.0, 0.0])
            return self.state.copy()
        if dt > 0.0:
            key = round(dt, 12)
            step = self._cache.get(key)
            if step is None:
                full = expm(self._aug * dt)
                step = self._cache[key] = (full[:3, :3].copy(), full[:3, 3].copy())
            self.state = step[0] @ self.state + step[1] * r
        return self.state.copy()


class LOSController(Controller):
    """CM path following by LOS guidance and a steered serpenoid (Liljebäck et al.); its
    signals: ``e_ct``, ``theta_ref``, ``theta_avg``, ``phi_0``, ``v_t``, ``v_avg``, ``s_cm``
    (:ref:`derivation-los`).

    Parameters
    ----------
    snake, path : Snake, Path or PathReference or None
        The plant (passive joints get no torque) and the CM's path (default the x axis; a
        PathReference's timing is ignored).
    params, **overrides
        :class:`LOSParams` (default: the defaults) and fields of it to change.

    Raises
    ------
    ParameterError
        A bad robot (every joint passive), ``params``, override or ``path``.
    """

    name = "los"

    def __init__(self, snake: Snake, path: Path | PathReference | None = None,
                 params: LOSParams | None = None, **overrides: object) -> None:
        if not instance(snake, Snake, "snake").params.actuated:
            raise ParameterError("every joint is passive: there is nothing to control")
        self.params = merged(LOSParams, params, overrides, argument="params",
                             field_word="LOS parameter")
        path = Line() if path is None else path.path if isinstance(path, PathReference) else path
        if not isinstance(path, Path):
            raise ParameterError(f"path must be a Path, got {type(path).__name__}")
        self.snake, self.path, p = snake, path, self.params
        self._lags = np.arange(snake.n - 1) * p.delta
        act = self._act = np.array([2 + k for k in snake.params.actuated])  # velocity indices
        unact = self._unact = np.setdiff1d(np.arange(snake.nv), act)
        self._blocks = tuple(np.ix_(rows, cols) for rows in (unact, act) for cols in (unact, act))
        self._lever = _cm_lever(snake)
        self._ref_filter, self._offset_filter, self._speed_filter = (
            ReferenceFilter(period) for period in
            (p.ref_period, p.offset_period, p.speed_period or 2.0 * math.pi / p.omega))
        self.reset()

    def reset(self) -> None:
        """Forget the filters, the tracked path point and the offset before a new run."""
        self._t_last: float | None = None
        self._s_cm: float | None = None
        self._raw_last = 0.0
        self._ddq: np.ndarray | None = None
        self._ref_filter.reset()
        self._offset_filter.reset(0.0)
        self._speed_filter.reset(0.0)
        self._last: dict[str, float] = {}
        self._gait: tuple[float, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None

    def gait(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the undulation ``alpha sin(omega t - (i - 1) delta)`` without offset.

        Parameters
        ----------
        t : float
            Time [s].

        Returns
        -------
        phi, dphi, ddphi : numpy.ndarray, shape (n - 1,)
            The undulation [rad] and its two derivatives (read-only).
        """
        if self._gait is not None and self._gait[0] == t:  # asked twice per step
            return self._gait[1]
        p = self.params
        phase = p.omega * t - self._lags
        sine = np.sin(phase)
        gait = (p.alpha * sine, p.alpha * p.omega * np.cos(phase), -p.alpha * p.omega**2 * sine)
        for part in gait:
            part.flags.writeable = False  # a caller cannot change the cached values
        self._gait = (t, gait)
        return gait

    def guidance(self, x: np.ndarray) -> dict[str, float]:
        """Return the LOS quantities at state x (the CM's closest path point tracked).

        Parameters
        ----------
        x : numpy.ndarray, shape (2(n + 2),)
            State ``x = [q, dq]``.

        Returns
        -------
        dict of str to float
            ``e_ct``, ``s_cm``, ``theta_los``, ``theta_avg``, ``dtheta_avg``, ``v_t``.
        """
        p_cm, v_cm, psi, dpsi = _kinematics(self._lever, self.snake.nq, x)
        path = self.path
        if self._s_cm is None:  # a global search, then track the closest point
            s_cm = float(path.project(p_cm))
            x_p, y_p, gamma, _, _ = path._scalar(s_cm)
        else:
            s_cm, x_p, y_p, gamma = path._track(float(p_cm[0]), float(p_cm[1]), self._s_cm)
        self._s_cm = s_cm
        cross = (p_cm[0] - x_p) * -math.sin(gamma) + (p_cm[1] - y_p) * math.cos(gamma)
        v_t = float(v_cm[0] * math.cos(psi) + v_cm[1] * math.sin(psi))
        return {"e_ct": cross, "s_cm": s_cm, "theta_los": _los_heading(gamma, cross,
                                                                      self.params.look_ahead),
                "theta_avg": psi, "dtheta_avg": dpsi, "v_t": v_t}

    def steering_offset(self, t: float, g: dict[str, float], ref: np.ndarray) -> float:
        """Return the joint offset phi_0 the heading law asks for (before saturation and filtering).

        Parameters
        ----------
        t, g, ref : float, dict of str to float, numpy.ndarray
            Time [s]; :meth:`guidance`'s quantities plus the averaged forward speed
            ``v_avg`` [m/s]; the filtered ``[theta_ref, theta_ref', theta_ref'']``.

        Returns
        -------
        float
            phi_0 [rad].
        """
        p = self.params
        error = (ref[0] - g["theta_avg"] + math.pi) % (2.0 * math.pi) - math.pi
        if p.steering == "pd":
            return -(p.k_p * error + p.k_d * (ref[1] - g["dtheta_avg"]))
        speed = max(g["v_avg"], p.v_min)
        fade = min(max(g["v_avg"] / p.v_min, 0.0), 1.0)  # no steering before moving forward
        mean_gait = float(self.gait(t)[0].sum()) / (self.snake.n - 1)
        return -fade * (ref[2] + p.lambda1 * ref[1] + p.k_theta * error) / (p.lambda2 * speed) \
            - mean_gait

    def joint_torques(self, x: np.ndarray, phi_r: np.ndarray, dphi_r: np.ndarray,
                      ddphi_r: np.ndarray) -> np.ndarray:
        """Return the torques making the actuated joints follow ``v = phi_r'' + k_d e' + k_p e``.

        Parameters
        ----------
        x, phi_r, dphi_r, ddphi_r : numpy.ndarray
            State ``x = [q, dq]``; the joint references [rad] and their two derivatives.

        Returns
        -------
        numpy.ndarray, shape (n - 1,)
            Joint torques tau [N m] (zero on passive joints); q'' under them is kept.

        Raises
        ------
        SingularPostureError
            If ``H_uu`` is not positive definite.
        """
        snake, nq, p = self.snake, self.snake.nq, self.params
        v = ddphi_r + p.k_joint_d * (dphi_r - x[nq + 3:]) + p.k_joint_p * (phi_r - x[3:nq])
        h_mat = snake.inertia_matrix(x[:nq])
        h_vec = snake.bias(x[:nq], x[nq:])
        act, unact = self._act, self._unact
        uu, ua, au, aa = self._blocks
        solved, info = solve_spd(h_mat[uu], np.column_stack((h_mat[ua], h_vec[unact])))
        if info != 0:
            raise SingularPostureError(f"H_uu is not positive definite (LAPACK info {info})")
        h_au = h_mat[au]
        reduced = h_mat[aa] - h_au @ solved[:, :-1]
        tau = np.zeros(snake.n - 1)
        v_act = v[act - 3]
        tau[act - 3] = reduced @ v_act + h_vec[act] - h_au @ solved[:, -1]
        # the plant's q'' under this tau: v on the actuated joints, the rest from the u rows
        ddq = np.empty(snake.nv)
        ddq[act] = v_act
        ddq[unact] = -solved[:, :-1] @ v_act - solved[:, -1]
        self._ddq = ddq
        return tau

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        p = self.params
        dt = 0.0 if self._t_last is None else max(t - self._t_last, 0.0)
        self._t_last = t
        g = self.guidance(x)
        ref = self._ref_filter.update(g["theta_los"], dt)
        g["v_avg"] = float(self._speed_filter.update(g["v_t"], dt)[0])
        raw = min(max(self.steering_offset(t, g, ref), -p.phi0_max), p.phi0_max)
        step = p.phi0_rate * dt  # slew-rate limit, from phi_0 = 0 at the start
        raw = min(max(raw, self._raw_last - step), self._raw_last + step)
        self._raw_last = raw
        offset = self._offset_filter.update(raw, dt)
        phi, dphi, ddphi = self.gait(t)
        tau = self.joint_torques(x, phi + offset[0], dphi + offset[1], ddphi + offset[2])
        self._last = {"e_ct": g["e_ct"], "theta_ref": float(ref[0]),
                      "theta_avg": g["theta_avg"], "phi_0": float(offset[0]),
                      "v_t": g["v_t"], "v_avg": g["v_avg"], "s_cm": g["s_cm"]}
        return tau

    def signals(self) -> dict[str, float]:
        return self._last

    def plant_acceleration(self, snake: object) -> np.ndarray | None:
        return self._ddq if snake is self.snake else None
