"""Manipulability along posture families (Section IV, Figs. 2-9) and the (alpha, T_s) map, as
data (figures and files: a layer up); BLAS on one thread meanwhile (:doc:`/performance`).
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from ._json import json_safe
from ._validation import brief, finite_number, flag, instance, integer
from .exceptions import ParameterError, RunInterrupted
from .gaits import Serpenoid, arc
from .manipulability import free_joints, manipulability, manipulability_R_batch, task_split
from .model import Snake
from .paths import interval

__all__ = ["FAMILIES", "MAX_POINTS", "RMap", "Sweep", "r_map", "sweep"]

#: Family name -> (parameter label, default range, description).
FAMILIES: dict[str, tuple[str, tuple[float, float], str]] = {
    "arc": ("phi0 [rad]", (-np.pi / 5, np.pi / 5), "all joints at phi0 (Figs. 2, 3)"),
    "alpha": ("alpha [rad]", (0.0, np.pi / 2), "serpenoid, T_s = 1.5 (Figs. 4, 8)"),
    "ts": ("T_s", (0.0, 2.0), "serpenoid, alpha = pi/4 (Figs. 5, 9)"),
}

#: Most postures one sweep evaluates: about 2 s at n = 10 and 30 s at n = 200, three
#: arrays of 0.8 MB; the figure's resolution gains nothing beyond it.
MAX_POINTS = 100_000

FreeJoints = int | tuple[int, ...] | None


@dataclass
class Sweep:
    """D and R along one posture family.

    Parameters
    ----------
    family, label
        One of :data:`FAMILIES`, and its parameter with its unit (e.g. ``"phi0 [rad]"``).
    values, D, R
        The parameter values and the criteria there, (N,) each (D~ and R~ with free joints).
    free_joint, robot, meta, status
        The free joint(s) or None, the robot's name, extra settings written with the data,
        ``"completed"`` or ``"interrupted"``.
    """

    family: str
    label: str
    values: np.ndarray
    D: np.ndarray
    R: np.ndarray
    free_joint: FreeJoints
    robot: str
    meta: dict[str, float] = field(default_factory=dict)
    status: str = "completed"

    @property
    def stem(self) -> str:
        """File stem, e.g. ``sweep_arc``, ``sweep_arc_free5`` or ``sweep_arc_free3_5``."""
        free = self.free_joint
        joints = (free,) if isinstance(free, (int, numbers.Integral)) else tuple(free or ())
        return f"sweep_{self.family}" + (f"_free{'_'.join(map(str, joints))}" if joints else "")

    def zeros(self, relative: float = 1e-9) -> np.ndarray:
        """Parameter values where R is numerically zero.

        Parameters
        ----------
        relative
            ``R <= relative * (largest R of the sweep)`` counts as zero.

        Returns
        -------
        numpy.ndarray
            Those values of :attr:`values`.
        """
        if self.R.size == 0:
            return self.values[:0]
        return self.values[self.R <= relative * self.R.max()]

    def rows(self) -> list[tuple[float, float, float]]:
        """The sweep as rows, in order (the CSV's rows).

        Returns
        -------
        list of tuple
            (parameter value, D, R) at every posture.
        """
        return list(zip(self.values.tolist(), self.D.tolist(), self.R.tolist(), strict=True))

    def to_dict(self) -> dict[str, object]:
        """Plain JSON data of the sweep (non-finite entries as None).

        Returns
        -------
        dict
            family, parameter (the label), robot, free_joint, status, values, D, R, meta.
        """
        free = self.free_joint
        return {"family": self.family, "parameter": self.label, "robot": self.robot,
                "free_joint": list(free) if isinstance(free, tuple) else free,
                "status": self.status, "values": self.values.tolist(),
                "D": json_safe(self.D), "R": json_safe(self.R), **self.meta}


def _family_configuration(family: str, n: int, value: float) -> np.ndarray:
    """The posture of ``family`` at parameter ``value``."""
    if family == "arc":
        return arc(n, value)
    alpha, ts = (value, 1.5) if family == "alpha" else (np.pi / 4, value)
    return Serpenoid(n, alpha, ts).configuration()


def sweep(snake: Snake, family: str, *, free_joint: int | Sequence[int] | None = None,
          points: int = 201, bounds: tuple[float, float] | None = None,
          progress: bool = False) -> Sweep:
    """D and R along a posture family ("arc", "alpha" or "ts") at ``points`` values.

    Parameters
    ----------
    snake, family
        The robot (its passive joints are free beside ``free_joint``), a :data:`FAMILIES` name.
    free_joint, progress
        Joint(s) without an actuator (D~ and R~ of eq. 42); show a progress bar on stderr
        when it is a terminal.
    points, bounds
        Number of values, 2 .. :data:`MAX_POINTS` (0, singular, is inserted if inside), and
        the parameter range (default: the family's in :data:`FAMILIES`).

    Returns
    -------
    Sweep
        D and R at every value.

    Raises
    ------
    RunInterrupted, ParameterError
        On Ctrl-C or SIGTERM (``partial``: the sweep so far); a bad argument, or free joints
        that leave the task no actuated joint.
    """
    instance(snake, Snake, "snake")
    if not isinstance(family, str) or family not in FAMILIES:
        raise ParameterError(f"unknown family {brief(family)}; choose one of "
                             f"{', '.join(FAMILIES)}")
    points = integer(points, "points", low=2, high=MAX_POINTS)
    progress = flag(progress, "progress")
    task_split(snake.n, free_joint)  # validate before any output (progress bar)
    free = tuple(sorted(set(snake.params.passive) | set(free_joints(snake.n, free_joint))))
    label, default, _ = FAMILIES[family]
    low, high = default if bounds is None else interval(bounds, "bounds")
    values = _with_zero(np.linspace(low, high, int(points)))
    requested, points = int(points), len(values)
    d, r = np.empty(points), np.empty(points)
    kept = free[0] if len(free) == 1 else (free or None)
    iterator = range(points)
    if progress:
        from tqdm import tqdm

        iterator = tqdm(iterator, desc=f"sweep {family}", unit="posture", leave=False,
                        disable=None)
    done = 0
    try:
        with threadpool_limits(limits=1):  # small matrices: BLAS threads only cost (module doc)
            for i in iterator:
                res = manipulability(snake, _family_configuration(family, snake.n, values[i]),
                                     free_joint=free)
                d[i], r[i] = res.D, res.R
                done = i + 1
    except KeyboardInterrupt as exc:
        partial = Sweep(family, label, values[:done], d[:done], r[:done], kept,
                        snake.params.name, meta={"points_requested": requested},
                        status="interrupted")
        raise RunInterrupted(f"sweep {family} interrupted after {done} of {points} postures",
                             partial=partial) from exc
    return Sweep(family, label, values, d, r, kept, snake.params.name)


def _with_zero(values: np.ndarray) -> np.ndarray:
    """``values`` (ascending) with exactly 0 in it when they straddle 0."""
    if not values[0] < 0.0 < values[-1]:
        return values
    nearest = int(np.argmin(np.abs(values)))
    if abs(values[nearest]) <= 1e-12 * (values[-1] - values[0]):
        values[nearest] = 0.0
        return values
    return np.insert(values, int(np.searchsorted(values, 0.0)), 0.0)


@dataclass
class RMap:
    """R over a grid of serpenoid parameters (alpha, T_s).

    Parameters
    ----------
    alpha, ts, R, free_joint
        The grid's axes, R at every (T_s, alpha) (shape (len(ts), len(alpha))), the free joint.
    """

    alpha: np.ndarray
    ts: np.ndarray
    R: np.ndarray  # shape (len(ts), len(alpha))
    free_joint: int | None


def r_map(snake: Snake, *, free_joint: int | None = None, alpha_points: int = 121,
          ts_points: int = 101, alpha_max: float = np.pi / 2, ts_max: float = 2.0) -> RMap:
    """R of the serpenoid (43) over alpha in [0, alpha_max] x T_s in [0, ts_max] (batch path).

    Parameters
    ----------
    snake, free_joint, alpha_points, ts_points, alpha_max, ts_max
        The robot, a free joint (R~) or None, the grid's sizes along alpha and T_s
        (1 .. :data:`MAX_POINTS`) and its upper ends.

    Returns
    -------
    RMap
        R over the grid.

    Raises
    ------
    ParameterError
        A bad argument, or a free joint that leaves the task no actuated joint.
    """
    instance(snake, Snake, "snake")
    alpha_points = integer(alpha_points, "alpha_points", low=1, high=MAX_POINTS)
    ts_points = integer(ts_points, "ts_points", low=1, high=MAX_POINTS)
    alpha_max = finite_number(alpha_max, "alpha_max", positive=True)
    ts_max = finite_number(ts_max, "ts_max", positive=True)
    task_split(snake.n, free_joint)  # before the grid is made
    alpha = np.linspace(0.0, alpha_max, alpha_points)
    ts = np.linspace(0.0, ts_max, ts_points)
    n = snake.n
    a_grid, t_grid = np.meshgrid(alpha, ts)
    k = 2 * np.pi * t_grid.ravel()[:, None] / n
    phi = k * a_grid.ravel()[:, None] * np.sin(-k * np.arange(1, n)[None, :])  # eq. (43), t = 0
    with threadpool_limits(limits=1):
        r = manipulability_R_batch(snake.params, phi, free_joint=free_joint)
    return RMap(alpha, ts, r.reshape(t_grid.shape), free_joint)
