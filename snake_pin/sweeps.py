"""Manipulability along posture families (Section IV, Figs. 2-9) and the (alpha, T_s) map.

A :class:`Sweep` holds one family: the swept parameter, D and R at each value, and the
free joint if any. It writes itself as CSV, JSON and a PNG like the paper's figures.
"""

from __future__ import annotations

import csv
import io
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._io import atomic_write_bytes
from .exceptions import ParameterError
from .gaits import Serpenoid, arc
from .manipulability import manipulability, manipulability_R_batch, task_split
from .model import Snake

__all__ = ["FAMILIES", "RMap", "Sweep", "r_map", "sweep"]

#: Family name -> (parameter label, default range, description).
FAMILIES: dict[str, tuple[str, tuple[float, float], str]] = {
    "arc": ("phi0 [rad]", (-np.pi / 5, np.pi / 5), "all joints at phi0 (Figs. 2, 3)"),
    "alpha": ("alpha [rad]", (0.0, np.pi / 2), "serpenoid, T_s = 1.5 (Figs. 4, 8)"),
    "ts": ("T_s", (0.0, 2.0), "serpenoid, alpha = pi/4 (Figs. 5, 9)"),
}


@dataclass
class Sweep:
    """D and R along one posture family."""

    family: str
    label: str
    values: np.ndarray
    D: np.ndarray
    R: np.ndarray
    free_joint: int | None
    robot: str
    meta: dict[str, float] = field(default_factory=dict)

    @property
    def stem(self) -> str:
        """File stem, e.g. ``sweep_arc`` or ``sweep_arc_free5``."""
        return f"sweep_{self.family}" + (f"_free{self.free_joint}" if self.free_joint else "")

    def zeros(self, relative: float = 1e-9) -> np.ndarray:
        """Parameter values where R is numerically zero (relative to the largest R)."""
        return self.values[self.R <= relative * self.R.max()]

    def to_dict(self) -> dict[str, object]:
        """JSON-friendly dict."""
        return {"family": self.family, "parameter": self.label, "robot": self.robot,
                "free_joint": self.free_joint, "values": self.values.tolist(),
                "D": self.D.tolist(), "R": self.R.tolist(), **self.meta}

    def write(self, folder: str | os.PathLike[str]) -> dict[str, Path]:
        """Write ``<stem>.csv``, ``<stem>.json`` and ``<stem>.png`` into ``folder``."""
        from .viz.plots import plot_sweep

        folder = Path(folder)
        buf = io.StringIO()
        writer = csv.writer(buf)
        writer.writerow([self.label, "D", "R"])
        writer.writerows(zip(self.values.tolist(), self.D.tolist(), self.R.tolist(),
                             strict=True))
        paths = {ext: folder / f"{self.stem}.{ext}" for ext in ("csv", "json", "png")}
        atomic_write_bytes(paths["csv"], buf.getvalue().encode())
        atomic_write_bytes(paths["json"], (json.dumps(self.to_dict()) + "\n").encode())
        plot_sweep(self, paths["png"])
        return paths


def _family_configuration(family: str, n: int, value: float) -> np.ndarray:
    if family == "arc":
        return arc(n, value)
    if family == "alpha":
        return Serpenoid(n, value, 1.5).configuration()
    return Serpenoid(n, np.pi / 4, value).configuration()


def sweep(snake: Snake, family: str, *, free_joint: int | None = None, points: int = 201,
          bounds: tuple[float, float] | None = None, progress: bool = False) -> Sweep:
    """D and R along a posture family ("arc", "alpha" or "ts"), ``points`` values."""
    if family not in FAMILIES:
        raise ParameterError(f"unknown family {family!r}; choose one of {', '.join(FAMILIES)}")
    if points < 2:
        raise ParameterError(f"points must be at least 2, got {points}")
    task_split(snake.n, free_joint)  # validate before any output (progress bar)
    label, default, _ = FAMILIES[family]
    low, high = bounds or default
    values = np.linspace(low, high, points)
    d, r = np.empty(points), np.empty(points)
    iterator = range(points)
    if progress:
        from tqdm import tqdm

        iterator = tqdm(iterator, desc=f"sweep {family}", unit="posture", leave=False)
    for i in iterator:
        res = manipulability(snake, _family_configuration(family, snake.n, values[i]),
                             free_joint=free_joint)
        d[i], r[i] = res.D, res.R
    return Sweep(family, label, values, d, r, free_joint, snake.params.name)


@dataclass
class RMap:
    """R over a grid of serpenoid parameters (alpha, T_s)."""

    alpha: np.ndarray
    ts: np.ndarray
    R: np.ndarray  # shape (len(ts), len(alpha))
    free_joint: int | None


def r_map(snake: Snake, *, free_joint: int | None = None, alpha_points: int = 121,
          ts_points: int = 101, alpha_max: float = np.pi / 2, ts_max: float = 2.0) -> RMap:
    """R of the serpenoid (43) over alpha in [0, alpha_max] x T_s in [0, ts_max] (batch path)."""
    alpha = np.linspace(0.0, alpha_max, alpha_points)
    ts = np.linspace(0.0, ts_max, ts_points)
    n = snake.n
    a_grid, t_grid = np.meshgrid(alpha, ts)
    k = 2 * np.pi * t_grid.ravel()[:, None] / n
    phi = k * a_grid.ravel()[:, None] * np.sin(-k * np.arange(1, n)[None, :])  # eq. (43), t = 0
    r = manipulability_R_batch(snake.params, phi, free_joint=free_joint)
    return RMap(alpha, ts, r.reshape(t_grid.shape), free_joint)
