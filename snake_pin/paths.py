"""Planar paths and head references: a :class:`Path` p(s) and a :class:`Timing` s(t)
joined by :class:`PathReference`; :func:`load_path` builds one from a shape name or a
TOML/CSV file. Geometry, projection and file format: :doc:`/paths`.
"""

from __future__ import annotations

import abc
import bisect
import csv
import functools
import io
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path as FilePath
from typing import Any, NamedTuple

import numpy as np
from numpy.polynomial import Polynomial
from scipy.interpolate import CubicSpline
from scipy.spatial import cKDTree

from ._io import decode_utf8, parse_toml, read_regular_file
from ._validation import brief, finite_number
from .exceptions import ParameterError, PathFileError

__all__ = ["MAX_ANGLE", "MAX_COORDINATE", "MAX_PATH_FILE_BYTES", "MAX_PATH_SPEED", "MIN_LENGTH",
           "PATH_NAMES", "Arc", "Circle", "LaneChange", "Line", "Path", "PathFileError",
           "PathPoint", "PathReference", "Sinusoid", "Timing", "Waypoints", "along_track",
           "cross_track_error", "load_path", "make_path"]

DEFAULT_EXTENT = 20.0  # an unbounded path's default projection span is (-1, this) [m]
#: Largest path file read [bytes].
MAX_PATH_FILE_BYTES = 4 << 20
MAX_WAYPOINTS = 100_000  # most waypoints one path may have
#: Largest coordinate or length of a path, in absolute value [m].
MAX_COORDINATE = 1e6
#: Smallest positive length of a path: radius, wavelength, a lane change's length [m].
MIN_LENGTH = 1e-6
#: Largest angle of a path, in absolute value: directions, start angles, an arc's sweep [rad].
MAX_ANGLE = 1e3
#: Largest speed along a path [m/s].
MAX_PATH_SPEED = 1e3
HINT_RADIUS = 0.5  # how far from its hint a hinted projection looks [m]
SAMPLE_STEP = 1e-3  # largest spacing of the hinted projection's samples [m]
#: Shape names understood by :func:`make_path` and :func:`load_path`.
PATH_NAMES = ("line", "circle", "arc", "lane_change", "sinusoid", "waypoints")

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_HALF_PI = 0.5 * math.pi


class PathPoint(NamedTuple):
    """Geometry at arc lengths s (arrays shaped like s; ``p`` and the frames get a last axis 2).

    Parameters
    ----------
    p, gamma, kappa, dkappa : numpy.ndarray
        Point [m], tangent angle [rad] (not wrapped), curvature [1/m] (left > 0), its rate.
    """

    p: np.ndarray
    gamma: np.ndarray
    kappa: np.ndarray
    dkappa: np.ndarray

    @property
    def tangent(self) -> np.ndarray:
        """Unit tangent ``[cos gamma, sin gamma]``, shape s.shape + (2,)."""
        return np.stack((np.cos(self.gamma), np.sin(self.gamma)), axis=-1)

    @property
    def normal(self) -> np.ndarray:
        """Left unit normal ``[-sin gamma, cos gamma]``, shape s.shape + (2,)."""
        return np.stack((-np.sin(self.gamma), np.cos(self.gamma)), axis=-1)


class _Samples(NamedTuple):
    """The path sampled every ``h`` from ``s0``, with the offsets of the two searches."""

    s0: float
    h: float
    p: np.ndarray
    frame: np.ndarray
    gamma: np.ndarray
    kappa: np.ndarray
    dkappa: np.ndarray
    coarse: np.ndarray
    fine: np.ndarray

    @property
    def end(self) -> float:
        return self.s0 + self.h * (len(self.kappa) - 1)


def _length(value: object, name: str, *, positive: bool = False, non_negative: bool = False,
            bound: float = MAX_COORDINATE, unit: str = "m") -> float:
    """A coordinate or length [m] within +-``bound`` (>= MIN_LENGTH if positive)."""
    x = finite_number(value, name, positive=positive, non_negative=non_negative)
    if abs(x) > bound:
        raise ParameterError(f"{name} must lie within +-{bound:g} {unit}, got {x:g}")
    if positive and unit == "m" and x < MIN_LENGTH:
        raise ParameterError(f"{name} must be at least {MIN_LENGTH:g} m, got {x:g}")
    return x


def _angle(value: object, name: str, *, positive: bool = False) -> float:
    """An angle [rad] within +-MAX_ANGLE."""
    return _length(value, name, positive=positive, bound=MAX_ANGLE, unit="rad")


def _point(value: object, name: str) -> tuple[float, float]:
    """A finite 2-vector [x, y] within +-MAX_COORDINATE or one ParameterError line."""
    if not isinstance(value, (list, tuple, np.ndarray)) or len(value) != 2:
        raise ParameterError(f"{name} must be a point [x, y], got {brief(value)}")
    return (_length(value[0], f"{name}[0]"), _length(value[1], f"{name}[1]"))


def _set(obj: object, **values: Any) -> None:
    """Set attributes of a frozen dataclass: its checked fields and tables."""
    for name, value in values.items():
        object.__setattr__(obj, name, value)


class _ArcLength:
    """s(u) = int_{u_0}^u speed, tabulated at ``nodes`` (Gauss-Legendre), and its inverse."""

    def __init__(self, speed: Callable[[np.ndarray], np.ndarray], nodes: np.ndarray) -> None:
        self.speed = speed
        self.u = np.asarray(nodes, dtype=float)
        self.s = np.r_[0.0, np.cumsum(self._integral(self.u[:-1], self.u[1:]))]
        self.total = float(self.s[-1])
        self.du = 1.0 / speed(self.u)  # du/ds at the nodes: slopes of the Hermite start
        self.scale = max(1.0, float(abs(self.u[-1] - self.u[0])))
        # plain-float copies for the scalar path (bisect on lists beats numpy on one value)
        self._s_list, self._u_list = self.s.tolist(), self.u.tolist()
        self._du_list = self.du.tolist()
        self._gl = np.r_[0.5 * (_GL_X + 1.0), 1.0]  # quadrature points on [0, 1], and 1

    def _integral(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        half, mid = 0.5 * (b - a), 0.5 * (b + a)
        points = mid[..., None] + half[..., None] * _GL_X
        return half * (self.speed(points.reshape(-1)).reshape(points.shape) @ _GL_W)

    def length(self, u: np.ndarray) -> np.ndarray:
        """s(u) for u inside the table's range."""
        k = np.clip(np.searchsorted(self.u, u, side="right") - 1, 0, len(self.u) - 2)
        return self.s[k] + self._integral(self.u[k], u)

    def parameter(self, s: np.ndarray) -> np.ndarray:
        """u(s) for 0 <= s <= total: Newton from the Hermite start to round-off."""
        k = np.clip(np.searchsorted(self.s, s, side="right") - 1, 0, len(self.s) - 2)
        h = self.s[k + 1] - self.s[k]
        u = _hermite((s - self.s[k]) / h, h, self.u[k], self.du[k], self.u[k + 1], self.du[k + 1])
        lo, hi = self.u[0], self.u[-1]
        for _ in range(8):
            step = (self.length(u) - s) / self.speed(u)
            u = np.clip(u - step, lo, hi)
            if not np.any(np.abs(step) > 1e-7 * self.scale):
                break
        return u

    def parameter_scalar(self, s: float) -> float:
        """:meth:`parameter` for one float (the controllers' hot path)."""
        s_list, u_list, du_list = self._s_list, self._u_list, self._du_list
        last = len(s_list) - 2
        k = min(max(bisect.bisect_right(s_list, s) - 1, 0), last)
        h = s_list[k + 1] - s_list[k]
        u = _hermite((s - s_list[k]) / h, h, u_list[k], du_list[k], u_list[k + 1], du_list[k + 1])
        lo, hi = u_list[0], u_list[-1]
        for _ in range(8):
            j = min(max(bisect.bisect_right(u_list, u) - 1, 0), last)
            a = u_list[j]
            speeds = self.speed(a + (u - a) * self._gl)
            step = (s_list[j] + 0.5 * (u - a) * float(speeds[:8] @ _GL_W) - s) / float(speeds[8])
            u = min(max(u - step, lo), hi)
            if not abs(step) > 1e-7 * self.scale:
                break
        return u


def _hermite(x: Any, h: Any, u0: Any, du0: Any, u1: Any, du1: Any) -> Any:
    """Cubic Hermite interpolation at ``x`` in [0, 1] of a span ``h`` (floats or arrays)."""
    return ((1.0 + 2.0 * x) * (1.0 - x) ** 2 * u0 + x * (1.0 - x) ** 2 * h * du0
            + x * x * (3.0 - 2.0 * x) * u1 + x * x * (x - 1.0) * h * du1)


def _bend(x1: Any, y1: Any, x2: Any, y2: Any, x3: Any, y3: Any) -> tuple[Any, Any]:
    """(kappa, dkappa/ds) from p', p'', p''' in any parameter (floats or arrays)."""
    v2 = x1 * x1 + y1 * y1
    c12 = x1 * y2 - y1 * x2
    return (c12 / (v2 * v2**0.5),
            ((x1 * y3 - y1 * x3) * v2 - 3.0 * c12 * (x1 * x2 + y1 * y2)) / (v2 * v2 * v2))


def _clip_float(x: float, lo: float, hi: float) -> float:
    return min(max(x, lo), hi)


def _expansion_newton(a: Any, b: Any, kappa: Any, dkappa: Any, h: float,
                      clip: Callable[..., Any]) -> Any:
    """sigma of the cubic expansion's point about a sample closest to ``p_k + a t + b n``:
    two Newton steps within one spacing ``h`` (:doc:`/paths`), arrays or floats by ``clip``."""
    sigma = clip(a / clip(1.0 - kappa * b, 0.2, math.inf), -h, h)
    k2s = kappa * kappa * sigma
    # e = p(sigma) - x and v = p'(sigma) along t and n; slope = f'(sigma)
    e_t = sigma * (1.0 - k2s * sigma / 6.0) - a
    e_n = sigma * sigma * (0.5 * kappa + dkappa * sigma / 6.0) - b
    v_t = 1.0 - 0.5 * k2s * sigma
    v_n = sigma * (kappa + 0.5 * dkappa * sigma)
    slope = v_t * v_t + v_n * v_n - e_t * k2s + e_n * (kappa + dkappa * sigma)
    return clip(sigma - (e_t * v_t + e_n * v_n) / clip(slope, 0.2, math.inf), -h, h)


class Path(abc.ABC):
    """A planar curve parametrised by arc length s (abstract base of the shapes)."""

    #: Identifier used in file names and summaries.
    name: str = "path"

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        """Pickle by the parameters only: tables and caches (large, local functions) rebuilt."""
        return type(self), tuple(getattr(self, f.name) for f in fields(self)  # type: ignore[arg-type]
                                 if f.init)

    @property
    def length(self) -> float:
        """Length of the curve [m] (``math.inf`` if unbounded; one lap for a circle)."""
        return math.inf

    @abc.abstractmethod
    def _geometry(self, s: np.ndarray) -> PathPoint:
        """Geometry at a flat float array of arc lengths."""

    def _scalar(self, s: float) -> tuple[float, float, float, float, float]:
        """(x, y, gamma, kappa, dkappa) at one arc length (overridden by fast paths)."""
        g = self._geometry(np.array([s]))
        return (*g.p[0].tolist(), float(g.gamma[0]), float(g.kappa[0]), float(g.dkappa[0]))

    def geometry(self, s: object) -> PathPoint:
        """Return the point, tangent angle, curvature and its rate at arc length(s) ``s``.

        Parameters
        ----------
        s : float or array_like
            Arc length(s) [m], any shape.

        Returns
        -------
        PathPoint
            Arrays shaped like ``s``.

        Raises
        ------
        ParameterError
            An arc length is not finite.
        """
        arr = np.asarray(s, dtype=float)
        if not np.all(np.isfinite(arr)):
            raise ParameterError("arc lengths must be finite")
        return PathPoint(*(v.reshape(arr.shape + v.shape[1:])
                           for v in self._geometry(arr.reshape(-1))))

    def point(self, s: object) -> np.ndarray:
        """Return the point p(s) [m] of arc length(s) ``s``.

        Parameters
        ----------
        s : float or array_like
            Arc length(s) [m], any shape.

        Returns
        -------
        numpy.ndarray
            ``geometry(s).p``, shape s.shape + (2,).

        Raises
        ------
        ParameterError
            An arc length is not finite.
        """
        return self.geometry(s).p

    def default_span(self) -> tuple[float, float]:
        """Return ``(s_min, s_max)`` [m] searched by :meth:`project` unless told otherwise.

        Returns
        -------
        tuple of float
            A finite curve with margins of a quarter of its length (>= 1 m), a circle its
            first lap, a lane change its S and 2 m beyond, else ``(-1, 20)``.
        """
        return self._default_span()

    def _default_span(self) -> tuple[float, float]:
        """:meth:`default_span` of the shape (overridden by the circle and the lane change)."""
        if math.isfinite(self.length):
            margin = max(1.0, 0.25 * self.length)
            return (-margin, self.length + margin)
        return (-1.0, DEFAULT_EXTENT)

    def _step(self, lo: float, hi: float, count: int, step: float, bend: float) -> float:
        """``step``, or less where it bends: ``bend`` over the largest |kappa| of samples."""
        kappa_max = float(np.max(np.abs(self._geometry(np.linspace(lo, hi, count)).kappa)))
        return min(step, bend / kappa_max) if kappa_max > 0 else step

    def project(self, points: object, *, span: tuple[float, float] | None = None,
                hint: object = None) -> np.ndarray:
        """Return the arc length ``s*`` [m] of the closest point of the path to each point.

        Lines and circles project exactly (a circle: the lap nearest the hint, else the first
        at or after ``s_min``, capped at ``s_max``); the others as in :doc:`/paths`.

        Parameters
        ----------
        points : array_like, shape (..., 2)
            Points [m].
        span : tuple of float, optional
            ``(s_min, s_max)`` searched [m], default :meth:`default_span`; ``s*`` lies in it.
        hint : float or array_like, optional
            Arc lengths near the answer (one, or one per point): search within 0.5 m of it.

        Returns
        -------
        numpy.ndarray, shape points.shape[:-1]
            ``s*``.

        Raises
        ------
        ParameterError
            Points not a finite (..., 2) array, or a bad span or hint.
        """
        pts = _points(points)
        try:
            guess = None if hint is None else np.broadcast_to(np.asarray(hint, dtype=float),
                                                              pts.shape[:-1])
        except (TypeError, ValueError, OverflowError):
            guess = np.array(math.nan)
        if guess is not None and not np.isfinite(guess).all():
            raise ParameterError(f"hint must be finite arc lengths, one or one per point, "
                                 f"got {brief(hint)}")
        span = None if span is None else interval(span, "span")
        if pts.size == 0:
            return np.zeros(pts.shape[:-1])
        exact = self._exact_projection(pts, span, guess)
        if exact is not None:
            return exact
        lo, hi = span or ((-math.inf, math.inf) if guess is not None else self.default_span())
        flat = pts.reshape(-1, 2)
        if guess is not None:
            return self._project_near(flat, guess.reshape(-1), lo, hi).reshape(pts.shape[:-1])
        step = self._step(lo, hi, 2001, 0.005, 0.1)  # the coarse search's grid step
        count = min(math.ceil((hi - lo) / step) + 1, 1_000_001)
        grid = np.linspace(lo, hi, count)
        _, nearest = cKDTree(self._geometry(grid).p).query(flat)
        return self._newton(flat, grid[nearest], lo, hi, 2.0 * (grid[1] - grid[0])) \
            .reshape(pts.shape[:-1])

    def _exact_projection(self, pts: np.ndarray, span: tuple[float, float] | None,
                          hint: object) -> np.ndarray | None:
        """The closed-form projection of checked points, for shapes that have one."""
        return None

    def _samples(self, lo: float, hi: float) -> _Samples:
        """The path sampled every ``SAMPLE_STEP`` (finer where it bends) over at least
        [lo, hi]: a request beyond the table moves it, so its size stays bounded."""
        table: _Samples | None = self.__dict__.get("_near_table")
        if table is not None and table.s0 <= lo and table.end >= hi:
            return table
        if table is None:
            a, b = self.default_span()
            a, b = min(a, lo), max(b, hi)
        else:
            grow = max(2.0, 0.5 * (table.end - table.s0))
            a, b = lo - grow, hi + grow
        count = min(math.ceil((b - a) / self._step(a, b, 4001, SAMPLE_STEP, 0.05)) + 1,
                    4_000_001)
        s = np.linspace(a, b, count)
        g = self._geometry(s)
        h = float(s[1] - s[0])
        stride = max(1, math.ceil(HINT_RADIUS / h / 64))
        tangent = g.tangent
        # per sample [[t_x, -t_y], [t_y, t_x]]: d @ frame = [d . t, d . n]
        frame = np.stack((np.stack((tangent[:, 0], -tangent[:, 1]), -1),
                          np.stack((tangent[:, 1], tangent[:, 0]), -1)), axis=1)
        table = _Samples(a, h, g.p, frame, g.gamma, g.kappa, g.dkappa,
                         stride * np.arange(-64, 65), np.arange(-stride, stride + 1))
        object.__setattr__(self, "_near_table", table)  # a cache, not a field
        return table

    def _project_near(self, points: np.ndarray, hint: np.ndarray, lo: float,
                      hi: float) -> np.ndarray:
        """Closest point within ``HINT_RADIUS`` of each hint: the nearest sample (coarse,
        then fine), then :func:`_expansion_newton` about it; one point goes by :meth:`_track_in`."""
        table = self._samples(max(lo, float(hint.min()) - HINT_RADIUS),
                              min(hi, float(hint.max()) + HINT_RADIUS))
        h, s0, last = table.h, table.s0, len(table.kappa) - 1
        k_lo = min(max(math.ceil((lo - s0) / h - 1e-9), 0), last) if lo > s0 else 0
        k_hi = max(min(math.floor((hi - s0) / h + 1e-9), last), k_lo) if hi < table.end \
            else last
        if len(points) == 1:  # one point (a controller's step): slices and floats
            return np.array([self._track_in(table, points[0], float(hint[0]), k_lo, k_hi, lo,
                                            hi)[0]])
        rows = np.arange(len(points))
        window = np.rint((hint - s0) / h).astype(np.intp)[:, None] + table.coarse
        k_arr = window
        for offsets in (None, table.fine):  # the coarse, then the fine search
            if offsets is not None:
                window = k_arr[:, None] + offsets
            np.clip(window, k_lo, k_hi, out=window)
            diff = table.p[window] - points[:, None, :]
            k_arr = window[rows, np.einsum("ijk,ijk->ij", diff, diff).argmin(axis=1)]
        # a = d . t, b = d . n (d = x - p_k), kappa and kappa' at the samples
        a_arr, b_arr = np.einsum("ij,ijk->ki", points - table.p[k_arr], table.frame[k_arr])
        sigma_arr = _expansion_newton(a_arr, b_arr, table.kappa[k_arr], table.dkappa[k_arr],
                                      h, np.clip)
        return np.clip(s0 + k_arr * h + sigma_arr, lo, hi)

    def _track(self, x: float, y: float, hint: float) -> tuple[float, float, float, float]:
        """``(s, x_p, y_p, gamma)`` of ``project((x, y), hint=hint)``, unchecked (LOS law)."""
        table = self._samples(hint - HINT_RADIUS, hint + HINT_RADIUS)
        return self._track_in(table, np.array([x, y]), hint, 0, len(table.kappa) - 1,
                              -math.inf, math.inf)

    @staticmethod
    def _track_in(table: _Samples, point: np.ndarray, hint: float, k_lo: int, k_hi: int,
                  lo: float, hi: float) -> tuple[float, float, float, float]:
        """:meth:`_project_near` for one point, on slices of the table and in floats."""
        h, s0 = table.h, table.s0
        stride = int(table.fine[-1])
        centre = round((hint - s0) / h)
        first = min(max(centre - 64 * stride, k_lo), k_hi)
        near = table.p[first:max(min(centre + 64 * stride, k_hi), first) + 1:stride] - point
        k = first + stride * int(np.einsum("ij,ij->i", near, near).argmin())
        first = max(k - stride, k_lo)
        near = table.p[first:min(k + stride, k_hi) + 1] - point
        k = first + int(np.einsum("ij,ij->i", near, near).argmin())
        x_k, y_k = table.p[k].tolist()
        (t_x, _), (t_y, _) = table.frame[k].tolist()
        kappa, dkappa = float(table.kappa[k]), float(table.dkappa[k])
        a = (point[0] - x_k) * t_x + (point[1] - y_k) * t_y
        b = (point[1] - y_k) * t_x - (point[0] - x_k) * t_y
        base = s0 + k * h
        sigma = min(max(base + _expansion_newton(a, b, kappa, dkappa, h, _clip_float), lo),
                    hi) - base
        along = sigma - kappa * kappa * sigma**3 / 6.0
        side = sigma * sigma * (0.5 * kappa + dkappa * sigma / 6.0)
        return (base + sigma, x_k + along * t_x - side * t_y, y_k + along * t_y + side * t_x,
                float(table.gamma[k]) + sigma * (kappa + 0.5 * dkappa * sigma))

    def _newton(self, points: np.ndarray, s: np.ndarray, lo: float, hi: float,
                max_step: float) -> np.ndarray:
        """Safeguarded Newton steps on f(s) = (p(s) - x) . t(s) = 0 (f' = 1 + kappa (p - x) . n)."""
        best_s = s.copy()
        best_d = np.full(len(s), np.inf)
        for _ in range(12):
            g = self._geometry(s)
            diff = g.p - points
            dist = np.einsum("ij,ij->i", diff, diff)
            better = dist < best_d
            best_s[better], best_d[better] = s[better], dist[better]
            f = np.einsum("ij,ij->i", diff, g.tangent)
            slope = 1.0 + g.kappa * np.einsum("ij,ij->i", diff, g.normal)
            step = np.clip(-f / np.maximum(slope, 0.2), -max_step, max_step)
            s = np.clip(s + step, lo, hi)
            if not np.any(np.abs(step) > 1e-13 * max(1.0, hi - lo)):
                break
        g = self._geometry(s)
        diff = g.p - points
        dist = np.einsum("ij,ij->i", diff, diff)
        # keep the last iterate unless it is clearly worse than an earlier one (near the
        # minimum the squared distance is flat: comparing it would pick by round-off)
        worse = dist > best_d + 1e-12 * (1.0 + best_d)
        return np.where(worse, best_s, s)


class _Finite(Path):
    """A curve defined on [0, length], continued along its end tangents beyond."""

    @abc.abstractmethod
    def _inside(self, s: np.ndarray) -> PathPoint:
        """Geometry for 0 <= s <= length."""

    def _geometry(self, s: np.ndarray) -> PathPoint:
        length = self.length
        inner = np.clip(s, 0.0, length)
        g = self._inside(inner)
        beyond = s - inner
        if not np.any(beyond):
            return g
        ends = beyond != 0.0
        p = g.p + beyond[:, None] * g.tangent
        return PathPoint(p, g.gamma, np.where(ends, 0.0, g.kappa),
                         np.where(ends, 0.0, g.dkappa))

    @abc.abstractmethod
    def _inside_scalar(self, s: float) -> tuple[float, float, float, float, float]:
        """:meth:`_scalar` for 0 <= s <= length."""

    def _scalar(self, s: float) -> tuple[float, float, float, float, float]:
        inner = min(max(s, 0.0), self.length)
        x, y, gamma, kappa, dkappa = self._inside_scalar(inner)
        beyond = s - inner
        if beyond == 0.0:
            return x, y, gamma, kappa, dkappa
        return (x + beyond * math.cos(gamma), y + beyond * math.sin(gamma), gamma, 0.0, 0.0)


@dataclass(frozen=True)
class Line(Path):
    """The straight line ``p(s) = start + s [cos direction, sin direction]``.

    Parameters
    ----------
    start, direction : optional
        Point ``(x, y)`` at s = 0 [m], and heading [rad] (0: along +x).

    Raises
    ------
    ParameterError
        A value out of its domain.
    """

    start: tuple[float, float] = (0.0, 0.0)
    direction: float = 0.0
    name = "line"

    def __post_init__(self) -> None:
        _set(self, start=_point(self.start, "start"),
             direction=_angle(self.direction, "direction"))

    def _geometry(self, s: np.ndarray) -> PathPoint:
        c, d = math.cos(self.direction), math.sin(self.direction)
        p = np.stack((self.start[0] + c * s, self.start[1] + d * s), axis=-1)
        zero = np.zeros_like(s)
        return PathPoint(p, zero + self.direction, zero, zero.copy())

    def _scalar(self, s: float) -> tuple[float, float, float, float, float]:
        return (self.start[0] + math.cos(self.direction) * s,
                self.start[1] + math.sin(self.direction) * s, self.direction, 0.0, 0.0)

    def _track(self, x: float, y: float, hint: float) -> tuple[float, float, float, float]:
        s = (x - self.start[0]) * math.cos(self.direction) \
            + (y - self.start[1]) * math.sin(self.direction)
        return (s, *self._scalar(s)[:3])

    def _exact_projection(self, pts: np.ndarray, span: tuple[float, float] | None,
                          hint: object) -> np.ndarray | None:
        """Exact: the coordinate along the line (clipped to ``span``)."""
        s = (pts[..., 0] - self.start[0]) * math.cos(self.direction) \
            + (pts[..., 1] - self.start[1]) * math.sin(self.direction)
        return s if span is None else np.clip(s, span[0], span[1])


@dataclass(frozen=True)
class Circle(Path):
    """The circle of ``radius`` about ``centre``, from the polar angle ``start_angle``.

    Parameters
    ----------
    radius, centre, start_angle, clockwise : optional
        Radius [m] > 0; centre ``(x, y)`` [m] (None: the start is the origin); polar angle of
        the start [rad] (None: heading along +x, 0 with a centre); travel clockwise.

    Raises
    ------
    ParameterError
        A value out of its domain.
    """

    radius: float = 1.2
    centre: tuple[float, float] | None = None
    start_angle: float | None = None
    clockwise: bool = False
    _c: tuple[float, float] = field(init=False, repr=False, compare=False)
    _a0: float = field(init=False, repr=False, compare=False)
    name = "circle"

    def __post_init__(self) -> None:
        radius = _length(self.radius, "radius", positive=True)
        if not isinstance(self.clockwise, (bool, np.bool_)):
            raise ParameterError(f"clockwise must be true or false, got {brief(self.clockwise)}")
        side = -1.0 if self.clockwise else 1.0
        # by default the circle through the origin heading along +x
        start = (_angle(self.start_angle, "start_angle") if self.start_angle is not None
                 else -side * _HALF_PI if self.centre is None else 0.0)
        centre = (_point(self.centre, "centre") if self.centre is not None
                  else (-radius * math.cos(start), -radius * math.sin(start)))
        # _c and _a0: the same values as centre and start_angle, typed as never None
        _set(self, radius=radius, clockwise=side < 0, centre=centre, start_angle=start,
             _c=centre, _a0=start)

    @property
    def side(self) -> float:
        """+1 counter-clockwise, -1 clockwise."""
        return -1.0 if self.clockwise else 1.0

    @property
    def length(self) -> float:
        """One lap, ``2 pi radius`` [m] (s runs on over any number of laps)."""
        return 2.0 * math.pi * self.radius

    def _geometry(self, s: np.ndarray) -> PathPoint:
        side, radius = self.side, self.radius
        polar = self._a0 + side * s / radius
        p = np.stack((self._c[0] + radius * np.cos(polar),
                      self._c[1] + radius * np.sin(polar)), axis=-1)
        zero = np.zeros_like(s)
        return PathPoint(p, polar + side * _HALF_PI, zero + side / radius, zero)

    def _scalar(self, s: float) -> tuple[float, float, float, float, float]:
        side, radius = self.side, self.radius
        polar = self._a0 + side * s / radius
        return (self._c[0] + radius * math.cos(polar),
                self._c[1] + radius * math.sin(polar), polar + side * _HALF_PI,
                side / radius, 0.0)

    def _track(self, x: float, y: float, hint: float) -> tuple[float, float, float, float]:
        s = float(self.project(np.array([x, y]), hint=hint))
        return (s, *self._scalar(s)[:3])

    def _default_span(self) -> tuple[float, float]:
        return (0.0, self.length)

    def _exact_projection(self, pts: np.ndarray, span: tuple[float, float] | None,
                          hint: object) -> np.ndarray | None:
        """Exact, by the polar angle: the lap nearest ``hint``, else per ``span``, else lap 1."""
        polar = np.arctan2(pts[..., 1] - self._c[1], pts[..., 0] - self._c[0])
        lap = self.length
        s = np.mod(self.side * (polar - self._a0) * self.radius, lap)
        if hint is not None:
            ref = np.asarray(hint, dtype=float)
            s = s + lap * np.round((ref - s) / lap)
        elif span is not None:
            s = s + lap * np.ceil((span[0] - s) / lap)
            s = np.minimum(s, span[1])
        return s


@dataclass(frozen=True)
class Arc(_Finite, Circle):
    """A circular arc sweeping ``angle`` > 0 radians; straight beyond its ends.

    Parameters
    ----------
    radius, centre, start_angle, clockwise
        As :class:`Circle`'s.
    angle : float, optional
        Angle swept [rad], > 0.

    Raises
    ------
    ParameterError
        A value out of its domain.
    """

    angle: float = _HALF_PI
    name = "arc"

    def __post_init__(self) -> None:
        Circle.__post_init__(self)
        _set(self, angle=_angle(self.angle, "angle", positive=True))

    @property
    def length(self) -> float:
        """Length of the arc, ``radius angle`` [m]."""
        return self.radius * self.angle

    # the circle inside, straight beyond; the arc's own span and search (margins,
    # straight ends), not the circle's laps
    _inside, _inside_scalar = Circle._geometry, Circle._scalar
    _geometry, _scalar = _Finite._geometry, _Finite._scalar
    _default_span = Path._default_span
    _exact_projection = Path._exact_projection


class _GraphCurve(Path):
    """A curve y = f(x) in a frame at ``origin`` rotated by ``direction`` (arc length tabled)."""

    origin: tuple[float, float]
    direction: float

    def _place(self, x: Any, y: Any, f1: Any, f2: Any, f3: Any, m: Any = np) -> Any:
        """(x, f(x)) placed with gamma, kappa, kappa' from f's derivatives ``fk``: a PathPoint
        (``m`` numpy) or the floats of :meth:`Path._scalar` (``m`` math)."""
        c, s = math.cos(self.direction), math.sin(self.direction)
        p_x, p_y = c * x - s * y + self.origin[0], s * x + c * y + self.origin[1]
        terms = (m.atan(f1) + self.direction, *_bend(1.0, f1, 0.0, f2, 0.0, f3))
        return (p_x, p_y, *terms) if m is math else PathPoint(np.stack((p_x, p_y), -1), *terms)


@dataclass(frozen=True)
class LaneChange(_GraphCurve):
    """A lead-in, an S of ``length_x`` to the parallel line at ``offset``, then on (:doc:`/paths`).

    Parameters
    ----------
    offset, length_x, start : float, optional
        Lateral shift [m] (left > 0); length of the S along the lead-in [m] > 0 (``length``
        in :func:`make_path`); straight lead-in before it [m] >= 0.
    origin, direction : optional
        Start point ``(x, y)`` [m] and heading of the lead-in [rad].

    Raises
    ------
    ParameterError
        A value out of its domain.
    """

    offset: float = 0.3
    length_x: float = 2.0
    start: float = 0.5
    origin: tuple[float, float] = (0.0, 0.0)
    direction: float = 0.0
    _f: tuple[tuple[Polynomial, float], ...] = field(init=False, repr=False, compare=False)
    _table: _ArcLength = field(init=False, repr=False, compare=False)
    name = "lane_change"

    _P = Polynomial([0, 0, 0, 0, 35, -84, 70, -20])

    def __post_init__(self) -> None:
        _set(self, offset=_length(self.offset, "offset"),
             length_x=_length(self.length_x, "length", positive=True),
             start=_length(self.start, "start", non_negative=True),
             origin=_point(self.origin, "origin"), direction=_angle(self.direction, "direction"))
        scale = self.offset / self.length_x
        polys = [self._P.deriv(k) for k in range(4)]
        # derivatives in x: P^(k)(x / L) * offset / L^k
        _set(self, _f=tuple((poly, self.offset / self.length_x**k) for k, poly in enumerate(polys)),
             _table=_ArcLength(lambda x: np.sqrt(1.0 + (polys[1](x / self.length_x) * scale) ** 2),
                               np.linspace(0.0, self.length_x, 257)))

    @property
    def s_length(self) -> float:
        """Arc length of the S alone [m]."""
        return self._table.total

    def _default_span(self) -> tuple[float, float]:
        return (-1.0, max(DEFAULT_EXTENT, self.start + self.s_length + 2.0))

    def _geometry(self, s: np.ndarray) -> PathPoint:
        start, curve = self.start, self.s_length
        local = s - start
        inside = (local > 0.0) & (local < curve)
        x = np.where(local <= 0.0, s, start + self.length_x + (local - curve))
        f = [np.where(local <= 0.0, 0.0, self.offset), *np.zeros((3, len(s)))]
        if np.any(inside):
            u = self._table.parameter(local[inside])
            x[inside] = start + u
            for f_k, (poly, c) in zip(f, self._f, strict=True):
                f_k[inside] = c * poly(u / self.length_x)
        return self._place(x, *f)

    def _scalar(self, s: float) -> tuple[float, float, float, float, float]:
        local, curve = s - self.start, self._table.total
        if local <= 0.0 or local >= curve:
            x = s if local <= 0.0 else self.start + self.length_x + (local - curve)
            return self._place(x, 0.0 if local <= 0.0 else self.offset, 0.0, 0.0, 0.0, math)
        u = self._table.parameter_scalar(local)
        y, f1, f2, f3 = (c * poly(u / self.length_x) for poly, c in self._f)
        return self._place(self.start + u, y, f1, f2, f3, math)


@dataclass(frozen=True)
class Sinusoid(_GraphCurve):
    """The curve ``y = amplitude sin(2 pi x / wavelength)`` in a frame at ``origin``.

    Parameters
    ----------
    amplitude, wavelength, origin, direction : optional
        Amplitude [m] (negative: starts turning right), wavelength [m] > 0, start point
        ``(x, y)`` [m], angle of the frame's x axis [rad].

    Raises
    ------
    ParameterError
        A value out of its domain.
    """

    amplitude: float = 0.2
    wavelength: float = 2.0
    origin: tuple[float, float] = (0.0, 0.0)
    direction: float = 0.0
    _table: _ArcLength = field(init=False, repr=False, compare=False)
    name = "sinusoid"

    def __post_init__(self) -> None:
        _set(self, amplitude=_length(self.amplitude, "amplitude"),
             wavelength=_length(self.wavelength, "wavelength", positive=True),
             origin=_point(self.origin, "origin"), direction=_angle(self.direction, "direction"))
        k = 2.0 * math.pi / self.wavelength
        slope = self.amplitude * k
        _set(self, _table=_ArcLength(lambda x: np.sqrt(1.0 + (slope * np.cos(k * x)) ** 2),
                                     np.linspace(0.0, self.wavelength, 129)))

    def _graph(self, x: Any, m: Any) -> Any:
        """:meth:`_place` of the sine at x (arrays with ``m`` numpy, floats with math)."""
        k, a = 2.0 * math.pi / self.wavelength, self.amplitude
        sine, cosine = m.sin(k * x), m.cos(k * x)
        return self._place(x, a * sine, a * k * cosine, -a * k * k * sine, -a * k**3 * cosine, m)

    def _geometry(self, s: np.ndarray) -> PathPoint:
        laps = np.floor(s / self._table.total)
        return self._graph(self._table.parameter(s - laps * self._table.total)
                           + laps * self.wavelength, np)

    def _scalar(self, s: float) -> tuple[float, float, float, float, float]:
        laps = math.floor(s / self._table.total)
        return self._graph(self._table.parameter_scalar(s - laps * self._table.total)
                           + laps * self.wavelength, math)


@dataclass(frozen=True)
class Waypoints(_Finite):
    """The natural cubic spline through ``points`` (``knots_s``: their arc lengths).

    Parameters
    ----------
    points : sequence of (float, float)
        Waypoints ``[[x, y], ...]`` [m], 2 to 100000, consecutive ones distinct.

    Raises
    ------
    ParameterError
        Bad waypoints, or a spline with a cusp or turning too sharply.
    """

    points: tuple[tuple[float, float], ...] = field(default=())
    knots_s: np.ndarray = field(init=False, repr=False, compare=False)
    _spline: CubicSpline = field(init=False, repr=False, compare=False)
    _table: _ArcLength = field(init=False, repr=False, compare=False)
    _gamma_nodes: np.ndarray = field(init=False, repr=False, compare=False)
    _knots_list: list[float] = field(init=False, repr=False, compare=False)
    _coefficients: list[tuple[tuple[float, ...], tuple[float, ...]]] = field(
        init=False, repr=False, compare=False)
    _gamma_list: list[float] = field(init=False, repr=False, compare=False)
    name = "waypoints"

    def __post_init__(self) -> None:
        pts = _waypoints(self.points)
        _set(self, points=tuple(map(tuple, pts.tolist())))
        chords = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        knots = np.r_[0.0, np.cumsum(chords)]
        spline = CubicSpline(knots, pts, bc_type="natural")
        tangent = spline.derivative()
        sub = 16
        nodes = (knots[:-1, None] + np.diff(knots)[:, None] * np.arange(sub) / sub).reshape(-1)
        nodes = np.r_[nodes, knots[-1]]
        d1 = tangent(nodes)
        speed = np.linalg.norm(d1, axis=1)
        if speed.min() <= 1e-9 * max(1.0, knots[-1]):
            k = int(np.searchsorted(knots, nodes[int(np.argmin(speed))], side="right"))
            raise ParameterError(f"points: the spline through them has a cusp near waypoint {k}")
        gamma_nodes = np.unwrap(np.arctan2(d1[:, 1], d1[:, 0]))
        if np.any(np.abs(np.diff(gamma_nodes)) > 1.0):
            raise ParameterError("points: the spline turns too sharply between waypoints "
                                 "(add waypoints or space them out)")
        table = _ArcLength(lambda u: np.linalg.norm(tangent(u), axis=1), nodes)
        # _coefficients: per knot interval, the cubics of x and y (highest first) as floats
        _set(self, _spline=spline, _table=table, _gamma_nodes=gamma_nodes,
             knots_s=table.length(knots), _knots_list=knots.tolist(),
             _coefficients=[(tuple(spline.c[:, i, 0].tolist()), tuple(spline.c[:, i, 1].tolist()))
                            for i in range(len(knots) - 1)], _gamma_list=gamma_nodes.tolist())

    @property
    def length(self) -> float:
        """Arc length of the spline from the first to the last waypoint [m]."""
        return self._table.total

    @staticmethod
    def _cubic(d: Any, xs: Any, ys: Any, near: Any, m: Any) -> Any:
        """(x, y, gamma, kappa, dkappa) at ``d`` into cubics ``xs``, ``ys``, gamma near ``near``."""
        (ax, bx, cx, ex), (ay, by, cy, ey) = xs, ys
        x1, y1 = (3.0 * ax * d + 2.0 * bx) * d + cx, (3.0 * ay * d + 2.0 * by) * d + cy
        return (((ax * d + bx) * d + cx) * d + ex, ((ay * d + by) * d + cy) * d + ey,
                near + (m.atan2(y1, x1) - near + math.pi) % (2.0 * math.pi) - math.pi,
                *_bend(x1, y1, 6.0 * ax * d + 2.0 * bx, 6.0 * ay * d + 2.0 * by, 6.0 * ax,
                       6.0 * ay))

    def _inside(self, s: np.ndarray) -> PathPoint:
        u, knots, nodes = self._table.parameter(s), self._spline.x, self._table.u
        i = np.clip(np.searchsorted(knots, u, side="right") - 1, 0, len(knots) - 2)
        k = np.clip(np.searchsorted(nodes, u, side="right") - 1, 0, len(nodes) - 1)
        c = self._spline.c[:, i]
        x, y, *terms = self._cubic(u - knots[i], c[..., 0], c[..., 1], self._gamma_nodes[k], np)
        return PathPoint(np.stack((x, y), -1), *terms)

    def _inside_scalar(self, s: float) -> tuple[float, float, float, float, float]:
        u, knots, nodes = self._table.parameter_scalar(s), self._knots_list, self._table._u_list
        i = min(max(bisect.bisect_right(knots, u) - 1, 0), len(knots) - 2)
        k = min(max(bisect.bisect_right(nodes, u) - 1, 0), len(nodes) - 1)
        return self._cubic(u - knots[i], *self._coefficients[i], self._gamma_list[k], math)


def _waypoints(points: object) -> np.ndarray:
    """Waypoints as a checked (m, 2) array, or one ParameterError line."""
    try:
        pts = np.asarray(points, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ParameterError(f"points must be a list of [x, y] pairs, got {brief(points)}") \
            from exc
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ParameterError(f"points must be a list of [x, y] pairs, got shape {pts.shape}")
    if len(pts) < 2:
        raise ParameterError(f"points: a path needs at least two waypoints, got {len(pts)}")
    if len(pts) > MAX_WAYPOINTS:
        raise ParameterError(f"points: at most {MAX_WAYPOINTS} waypoints, got {len(pts)}")
    bad = ~np.all(np.isfinite(pts), axis=1)
    if bad.any():
        raise ParameterError(f"points: waypoint {int(np.argmax(bad)) + 1} is not finite")
    far = np.any(np.abs(pts) > MAX_COORDINATE, axis=1)
    if far.any():
        k = int(np.argmax(far))
        raise ParameterError(f"points: waypoint {k + 1} ({pts[k, 0]:g}, {pts[k, 1]:g}) lies "
                             f"beyond +-{MAX_COORDINATE:g} m")
    chords = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    tol = 1e-9 * max(1.0, float(np.abs(pts).max()))
    if np.any(chords <= tol):
        k = int(np.argmax(chords <= tol)) + 1
        raise ParameterError(f"points: waypoints {k} and {k + 1} coincide "
                             f"({pts[k - 1, 0]:g}, {pts[k - 1, 1]:g})")
    return pts


@dataclass(frozen=True)
class Timing:
    """The timing law s(t): ``speed`` from arc length ``start`` after a ramp (:doc:`/paths`).

    Parameters
    ----------
    speed, ramp, start : float, optional
        Cruising speed [m/s] > 0, duration of the smooth start [s] >= 0, arc length at t = 0 [m].

    Raises
    ------
    ParameterError
        A value out of its domain.
    """

    speed: float = 0.1
    ramp: float = 0.0
    start: float = 0.0

    def __post_init__(self) -> None:
        speed = finite_number(self.speed, "speed", positive=True)
        if speed > MAX_PATH_SPEED:
            raise ParameterError(f"speed must be at most {MAX_PATH_SPEED:g} m/s, got {speed:g}")
        _set(self, speed=speed, ramp=finite_number(self.ramp, "ramp", non_negative=True),
             start=_length(self.start, "start"))

    def __call__(self, t: object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (s, s', s'') at time(s) ``t`` [s], arrays shaped like ``t`` [m, m/s, m/s^2]."""
        t_arr = np.asarray(t, dtype=float)
        v, big_t = self.speed, self.ramp
        if big_t == 0.0:
            return self.start + v * t_arr, np.full_like(t_arr, v), np.zeros_like(t_arr)
        u = np.clip(t_arr / big_t, 0.0, 1.0)
        ramp_s = big_t * v * u**4 * (2.5 - 3.0 * u + u**2)
        after = t_arr > big_t
        s = np.where(after, v * (t_arr - 0.5 * big_t), ramp_s)
        ds = v * u**3 * (10.0 - 15.0 * u + 6.0 * u**2)
        dds = np.where(after, 0.0, v / big_t * 30.0 * u**2 * (1.0 - u) ** 2)
        return self.start + s, ds, dds

    def scalar(self, t: float) -> tuple[float, float, float]:
        """Return (s, s', s'') at one time ``t`` in plain floats (the controllers' hot path).

        Parameters
        ----------
        t : float
            Time [s].

        Returns
        -------
        s, ds, dds : float
            Arc length [m], speed [m/s] and acceleration [m/s^2].
        """
        v, big_t = self.speed, self.ramp
        if big_t == 0.0:
            return self.start + v * t, v, 0.0
        if t >= big_t:
            return self.start + v * (t - 0.5 * big_t), v, 0.0
        u = max(t / big_t, 0.0)
        return (self.start + big_t * v * u**4 * (2.5 - 3.0 * u + u * u),
                v * u**3 * (10.0 - 15.0 * u + 6.0 * u * u),
                v / big_t * 30.0 * u * u * (1.0 - u) ** 2)


class PathReference:
    """Head reference along a path: called at t, (w_r, w_r', w_r''), w_r = [p(s), gamma(s) + pi].

    Parameters
    ----------
    path, timing : Path, Timing or None
        The curve, and s(t) (default :class:`Timing`).

    Raises
    ------
    ParameterError
        ``path`` is not a :class:`Path` or ``timing`` not a :class:`Timing`.
    """

    def __init__(self, path: Path, timing: Timing | None = None) -> None:
        if not isinstance(path, Path):
            raise ParameterError(f"path must be a Path, got {type(path).__name__}")
        if timing is not None and not isinstance(timing, Timing):
            raise ParameterError(f"timing must be a Timing, got {type(timing).__name__}")
        self.path = path
        self.timing = timing or Timing()

    def __repr__(self) -> str:
        return f"PathReference({self.path!r}, {self.timing!r})"

    @property
    def name(self) -> str:
        """The path's name."""
        return self.path.name

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return fresh arrays (w_r, w_r', w_r'') at time ``t`` (floats: the controllers' step)."""
        t = float(t)
        if not math.isfinite(t):
            raise ParameterError("time must be finite")
        s, ds, dds = self.timing.scalar(t)
        x, y, gamma, kappa, dkappa = self.path._scalar(s)
        c, d = math.cos(gamma), math.sin(gamma)
        bend = kappa * ds * ds
        return (np.array([x, y, gamma + math.pi]),
                np.array([c * ds, d * ds, kappa * ds]),
                np.array([-d * bend + c * dds, c * bend + d * dds,
                          dkappa * ds * ds + kappa * dds]))

    def at(self, t: object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (w_r, w_r', w_r'') at many times (vectorised ``__call__``).

        Parameters
        ----------
        t : float or array_like
            Times [s], any shape.

        Returns
        -------
        w_r, dw_r, ddw_r : numpy.ndarray, shape t.shape + (3,)
            ``[x_h, y_h, theta_1]`` [m, m, rad] and its time derivatives.

        Raises
        ------
        ParameterError
            A time is not finite.
        """
        t_arr = np.asarray(t, dtype=float)
        if not np.all(np.isfinite(t_arr)):
            raise ParameterError("times must be finite")
        s, ds, dds = self.timing(t_arr)
        g = self.path.geometry(s)
        tangent, normal = g.tangent, g.normal
        w = np.concatenate((g.p, (g.gamma + math.pi)[..., None]), axis=-1)
        dw = np.concatenate((tangent * ds[..., None], (g.kappa * ds)[..., None]), axis=-1)
        ddw = np.concatenate(
            ((g.kappa * ds**2)[..., None] * normal + tangent * dds[..., None],
             (g.dkappa * ds**2 + g.kappa * dds)[..., None]), axis=-1)
        return w, dw, ddw


def cross_track_error(path: Path | PathReference, points: object, *,
                      span: tuple[float, float] | None = None) -> np.ndarray:
    """Return the signed distance [m] from each point to the path, positive on the left.

    Parameters
    ----------
    path : Path or PathReference
        The curve (a reference's own path).
    points : array_like, shape (..., 2)
        Points [m], e.g. the head positions ``traj.q[:, :2]`` of a run.
    span : tuple of float, optional
        ``(s_min, s_max)`` searched [m], as in :meth:`Path.project`.

    Returns
    -------
    numpy.ndarray, shape points.shape[:-1]
        Signed distances.

    Raises
    ------
    ParameterError
        Not a path, points not a finite (..., 2) array, or a bad span.
    """
    curve, pts = _curve(path), _points(points)
    g = curve.geometry(curve.project(pts, span=span))
    diff = pts - g.p
    side = np.einsum("...i,...i->...", diff, g.normal)
    return np.where(side < 0.0, -1.0, 1.0) * np.linalg.norm(diff, axis=-1)


def along_track(path: Path | PathReference, points: object, *,
                span: tuple[float, float] | None = None) -> np.ndarray:
    """Return the arc length [m] of the closest point of the path to each point.

    Parameters
    ----------
    path, points, span
        As in :func:`cross_track_error`.

    Returns
    -------
    numpy.ndarray, shape points.shape[:-1]
        :meth:`Path.project` of the points.

    Raises
    ------
    ParameterError
        Not a path, points not a finite (..., 2) array, or a bad span.
    """
    return _curve(path).project(points, span=span)


def _curve(path: object) -> Path:
    """The path of a distance query (a reference's own), or one ParameterError line."""
    path = path.path if isinstance(path, PathReference) else path
    if not isinstance(path, Path):
        raise ParameterError(f"path must be a Path or a PathReference, got {brief(path)}")
    return path


def _points(points: object) -> np.ndarray:
    """Points as a finite (..., 2) float array, or one ParameterError line."""
    try:
        pts = np.asarray(points, dtype=float)
    except (TypeError, ValueError, OverflowError):
        pts = np.empty(0)
    if pts.ndim == 0 or pts.shape[-1:] != (2,) or not np.isfinite(pts).all():
        raise ParameterError(f"points must be a finite (..., 2) array, got {brief(points)}")
    return pts


def interval(value: object, name: str) -> tuple[float, float]:
    """``value`` as (low, high), finite with low < high, or one ParameterError line."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)) \
            or len(value) != 2:
        raise ParameterError(f"{name} must be (low, high), got {brief(value)}")
    low, high = (finite_number(v, f"{name}[{i}]") for i, v in enumerate(value))
    if not low < high:
        raise ParameterError(f"{name} must have low < high, got ({low:g}, {high:g})")
    return low, high


_SHAPES: dict[str, type[Path]] = {
    "line": Line, "circle": Circle, "arc": Arc, "lane_change": LaneChange,
    "sinusoid": Sinusoid, "waypoints": Waypoints,
}
#: Parameter names of each shape as users write them (``length`` is LaneChange.length_x).
_RENAMED = {"lane_change": {"length": "length_x"}}
_TIMING_KEYS = ("speed", "ramp")


def _shape_keys(name: str) -> tuple[str, ...]:
    renamed = {v: k for k, v in _RENAMED.get(name, {}).items()}
    # every shape is a dataclass, but the dict's value type (type[Path]) cannot say so
    return tuple(renamed.get(f.name, f.name) for f in fields(_SHAPES[name])  # type: ignore[arg-type]
                 if f.init)


def make_path(name: str, **params: Any) -> Path:
    """Return the shape ``name`` (one of :data:`PATH_NAMES`) with its parameters.

    Parameters
    ----------
    name : str
        A shape name.
    **params
        The shape class's parameters (LaneChange's ``length_x`` as ``length``).

    Returns
    -------
    Path
        The validated shape.

    Raises
    ------
    ParameterError
        An unknown name or parameter, missing waypoints, or a value out of its domain.
    """
    if not isinstance(name, str) or name not in _SHAPES:
        raise ParameterError(f"unknown path {brief(name)}: expected one of "
                             f"{', '.join(PATH_NAMES)} or a .toml/.csv path file")
    allowed = _shape_keys(name)
    for key in params:
        if key not in allowed:
            raise ParameterError(f"unknown parameter {brief(key)} for path {name!r} "
                                 f"(expected one of {', '.join(allowed)})")
    if name == "waypoints" and "points" not in params:
        raise ParameterError("waypoints: points is required")
    renames = _RENAMED.get(name, {})
    return _SHAPES[name](**{renames.get(k, k): v for k, v in params.items()})


def _file_error(path: str | os.PathLike[str], message: str) -> PathFileError:
    return PathFileError(" ".join(f"{os.fspath(path)}: {message}".split()))


def _parse_toml(path: str | os.PathLike[str], text: str) -> dict[str, Any]:
    doc = parse_toml(text, error=functools.partial(_file_error, path))
    kind = doc.pop("type", None)
    if kind is None:
        raise _file_error(path, f"type is required (one of {', '.join(PATH_NAMES)})")
    if not isinstance(kind, str) or kind not in _SHAPES:
        raise _file_error(path, f"type: unknown path type {brief(kind)} "
                                f"(expected one of {', '.join(PATH_NAMES)})")
    allowed = (*_shape_keys(kind), *_TIMING_KEYS)
    for key, value in doc.items():
        if key not in allowed:
            raise _file_error(path, f"unknown key {brief(key)} for type {kind!r} "
                                    f"(expected one of {', '.join(allowed)})")
        if isinstance(value, dict):
            raise _file_error(path, f"{key} must be a value, not a table")
    return {"type": kind, **doc}


def _parse_csv(path: str | os.PathLike[str], text: str) -> dict[str, Any]:
    """Waypoints from CSV: two columns x, y; the first line may be a header (no numbers)."""
    rows: list[tuple[float, float]] = []
    seen_line = False
    try:
        for row in csv.reader(io.StringIO(text)):
            cells = [c.strip() for c in row]
            if not any(cells):
                continue
            first, seen_line = not seen_line, True
            if len(cells) != 2:
                raise _file_error(path, f"row {len(rows) + 1 + (not first)}: expected two "
                                        f"columns x, y, got {len(cells)}")
            try:
                x, y = float(cells[0]), float(cells[1])
            except ValueError:
                if first and not _any_number(cells):
                    continue  # the header
                raise _file_error(path, f"waypoint {len(rows) + 1}: not a number pair "
                                        f"{brief(','.join(cells))}") from None
            rows.append((x, y))
            if len(rows) > MAX_WAYPOINTS:
                raise _file_error(path, f"more than {MAX_WAYPOINTS} waypoints")
    except csv.Error as exc:
        raise _file_error(path, f"not valid CSV: {exc}") from None
    return {"type": "waypoints", "points": rows}


def _any_number(cells: list[str]) -> bool:
    for cell in cells:
        try:
            float(cell)
        except ValueError:
            continue
        return True
    return False


def load_path(spec: str | os.PathLike[str] | Path | PathReference,
              **params: Any) -> PathReference:
    """Return a head reference from a shape name and its parameters, or from a path file.

    Parameters
    ----------
    spec : str or os.PathLike or Path or PathReference
        A shape name, a ``.toml``/``.csv`` path file (:doc:`/paths`), a Path or a reference.
    **params
        Shape parameters and the timing's ``speed`` and ``ramp``, overriding a file's.

    Returns
    -------
    PathReference
        The path with its timing.

    Raises
    ------
    PathFileError
        A file problem, naming the file and the field.
    ParameterError
        A bad name or parameter.
    """
    if isinstance(spec, PathReference) and not params:
        return spec
    timing = {k: params.pop(k) for k in _TIMING_KEYS if k in params}
    if isinstance(spec, Path):
        if params:
            raise ParameterError(f"unknown parameter {next(iter(params))!r} for a Path object")
        return PathReference(spec, Timing(**timing))
    if isinstance(spec, str) and spec in _SHAPES:
        return PathReference(make_path(spec, **params), Timing(**timing))
    if not isinstance(spec, (str, os.PathLike)):
        raise ParameterError(f"path must be a name ({', '.join(PATH_NAMES)}) or a file, "
                             f"got {brief(spec)}")
    file_name = os.fspath(spec)
    suffix = FilePath(file_name).suffix.lower()
    if suffix not in (".toml", ".csv"):
        raise ParameterError(f"unknown path {brief(file_name)}: expected one of "
                             f"{', '.join(PATH_NAMES)} or a .toml/.csv path file")
    error = functools.partial(_file_error, spec)
    text = decode_utf8(read_regular_file(spec, limit=MAX_PATH_FILE_BYTES, kind="path file",
                                         error=error), error=error)
    doc = _parse_toml(spec, text) if suffix == ".toml" else _parse_csv(spec, text)
    kind = doc.pop("type")
    file_timing = {k: doc.pop(k) for k in _TIMING_KEYS if k in doc}
    doc.update(params)
    try:
        return PathReference(make_path(kind, **doc), Timing(**{**file_timing, **timing}))
    except ParameterError as exc:
        raise _file_error(spec, str(exc)) from None
