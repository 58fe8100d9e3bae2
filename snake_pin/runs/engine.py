"""Section VI.3's runs on MuJoCo (Figs. 19-21): the summary and figures of a head-tracking
run on the engine or the viscous model, and, since the engine runs are chaotic, their
distributions over seeded perturbed starts (:func:`perturbations`, ``engine_draw``,
``Draws``) for ``snake-pin engine --seeds N``, the report and the benchmark.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._validation import finite_number, integer
from ..control import MPCOptions, head_first_reference
from ..control.reference import HeadReference
from ..engine.model import WheelSpec
from ..engine.run import EngineRun, run_engine
from ..metrics import (
    applied,
    criteria_along,
    error_caption,
    head_error_summary,
    head_position_error,
    percent,
    torque_max,
    window,
)
from ..params import ROBOTS, SnakeParams
from ..sim import Trajectory

__all__ = ["METRICS", "PERTURBATION", "distribution", "perturbations"]

#: Default half-width of the uniform offsets of the initial joint angles [rad].
PERTURBATION = 1e-6

#: The metrics reported as distributions (summary keys of ``summarize``), with their
#: labels; errors and torques over the error window, R~ with a passive joint.
METRICS: dict[str, str] = {
    "rms_percent": "RMS head error [% of body]",
    "max_percent": "max head error [% of body]",
    "R_min": "R min (R~ with a passive joint)",
    "torque_rms": "torque RMS [N m]",
}


def summarize(traj: Trajectory, *, every: int = 10,
              reference: HeadReference | None = None,
              start: float | None = None) -> dict[str, object]:
    """Fill ``traj``'s head error, criteria (D, R every ``every`` samples) and summary (head
    errors and torques over t >= ``start``, the :data:`METRICS`, R_min, D_min) and return it."""
    error = head_position_error(
        traj, head_first_reference() if reference is None else reference)
    t_c, d, r = criteria_along(traj, every=every)
    traj.signals["head_error"] = error
    traj.meta["criteria"] = {"t": t_c.tolist(), "D": d.tolist(), "R": r.tolist()}
    errors = head_error_summary(traj, error, start=start)
    late = window(traj, float(errors["error_window"] or 0.0)) & applied(traj)
    actuated = np.array([k - 1 for k in traj.params.actuated], dtype=int)
    torque = (float(np.sqrt(np.mean(traj.tau[np.ix_(late, actuated)] ** 2)))
              if late.any() and actuated.size else None)
    body = traj.params.body_length
    max_error = errors["max_head_error"]
    traj.summary.update({
        **errors, "rms_percent": percent(errors["rms_relative"]),
        "max_percent": None if max_error is None else 100.0 * max_error / body,
        "torque_rms": torque, "torque_max": torque_max(traj),
        "R_min": float(r.min()), "D_min": float(d.min()), "body_length": body,
        "passive": list(traj.params.passive), "final_head": traj.q[-1, :3].tolist()})
    return traj.summary


def perturbations(count: int, joints: int, size: float = PERTURBATION,
                  seed: int = 0) -> np.ndarray:
    """``count`` offsets of ``joints`` initial joint angles, uniform in [-size, size] [rad],
    seeded: the same arguments give the same offsets (``run_engine(initial_offset=...)``).

    Parameters
    ----------
    count
        Number of draws (rows).
    joints
        Joint angles per draw (n - 1).
    size
        Half-width of the uniform distribution [rad].
    seed
        Seed of ``numpy.random.default_rng``.

    Returns
    -------
    numpy.ndarray
        (count, joints) offsets [rad].

    Raises
    ------
    ParameterError
        ``count`` or ``joints`` not a positive integer, ``size`` negative or not finite.
    """
    shape = (integer(count, "count", low=1), integer(joints, "joints", low=1))
    size = finite_number(size, "size", non_negative=True)
    return np.random.default_rng(seed).uniform(-size, size, shape)


def distribution(values: Sequence[float | None]) -> dict[str, Any]:
    """Median, 10 % and 90 % percentiles, min and max of the values that are numbers.

    Parameters
    ----------
    values
        One metric of several runs (None and non-finite entries are left out).

    Returns
    -------
    dict
        ``median``, ``p10``, ``p90`` (linear interpolation), ``min``, ``max`` (None when
        no value is left) and ``count``.
    """
    finite = np.array([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    if finite.size == 0:
        return {**dict.fromkeys(("median", "p10", "p90", "min", "max")), "count": 0}
    return {"median": float(np.median(finite)), "p10": float(np.percentile(finite, 10)),
            "p90": float(np.percentile(finite, 90)), "min": float(finite.min()),
            "max": float(finite.max()), "count": int(finite.size)}


@dataclass
class Draws:
    """Runs of one configuration from the perturbed starts ``offsets`` (:func:`perturbations`
    of ``perturbation`` and ``seed``), each draw's summary (None until it finishes) and
    files, and their distribution."""

    label: str
    perturbation: float
    seed: int
    offsets: np.ndarray
    summaries: list[dict[str, Any] | None] = field(default_factory=list)
    files: list[list[str]] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.summaries:
            self.summaries = [None] * len(self.offsets)
        if not self.files:
            self.files = [[] for _ in self.offsets]

    def record(self, index: int, summary: dict[str, Any], files: Sequence[str] = ()) -> None:
        """Keep the summary (and files) of finished draw ``index``."""
        self.summaries[index] = summary
        self.files[index] = [str(f) for f in files]

    @property
    def done(self) -> list[int]:
        """Indices of the finished draws."""
        return [i for i, s in enumerate(self.summaries) if s is not None]

    def values(self, metric: str) -> list[float | None]:
        """One summary key of every finished draw, in draw order (None where it has none)."""
        return [self.summaries[i].get(metric) for i in self.done]  # type: ignore[union-attr]

    def distributions(self) -> dict[str, dict[str, Any]]:
        """Metric of :data:`METRICS` -> its :func:`distribution` over the finished draws."""
        return {key: distribution(self.values(key)) for key in METRICS}

    def faults(self) -> list[int]:
        """The finished draws that diverged or failed."""
        return [i for i in self.done
                if (self.summaries[i] or {}).get("status") in ("diverged", "failed")]

    def median_draw(self) -> int | None:
        """The draw of the (lower) median RMS head error, else the first finished, None if
        none finished: it stands for the distribution in figures and files."""
        done = self.done
        if not done:
            return None
        rms = [(v, i) for i, v in zip(done, self.values("rms_percent"), strict=True)
               if v is not None and math.isfinite(v)]
        if not rms:
            return done[0]
        rms.sort()
        return rms[(len(rms) - 1) // 2][1]

    def to_dict(self) -> dict[str, Any]:
        """The draws as plain JSON data, with every draw's offset, summary and files."""
        return {"label": self.label, "draws": len(self.offsets), "finished": len(self.done),
                "perturbation": self.perturbation, "seed": self.seed,
                "distribution": self.distributions(), "median_draw": self.median_draw(),
                "runs": [{"offset": offset.tolist(), "summary": summary, "files": files}
                         for offset, summary, files in zip(self.offsets, self.summaries,
                                                           self.files, strict=True)]}

    def text(self) -> str:
        """The draws and each metric's median and 10-90 % range, as lines for a terminal."""
        lines = [f"{self.label}: {len(self.done)} of {len(self.offsets)} runs, initial joint "
                 f"angles offset by U(-{self.perturbation:g}, {self.perturbation:g}) rad "
                 f"(seed {self.seed})"]
        for key, dist in self.distributions().items():
            lines.append(f"  {METRICS[key]}: " + (
                "no value (no samples in the error window)" if dist["median"] is None else
                f"median {dist['median']:.4g}, 10-90 %: {dist['p10']:.4g} .. {dist['p90']:.4g} "
                f"({dist['count']} runs)"))
        faults = self.faults()
        if faults:
            lines.append(f"  {len(faults)} run(s) diverged or failed: draws "
                         f"{', '.join(str(i + 1) for i in faults)}")
        return "\n".join(lines)


def engine_draw(params: SnakeParams, offset: Sequence[float] | np.ndarray | None, *,
                wheels: WheelSpec, t_final: float, friction: dict[str, Any],
                law: str = "velocity", reference: HeadReference | None = None,
                error_window: float | None = None,
                mpc_options: MPCOptions | None = None) -> EngineRun:
    """One engine run from the arc of (82) with ``offset`` [rad] added to its joint angles,
    summarised (:func:`run_engine`'s arguments; a picklable job for ``runs.parallel``)."""
    run = run_engine(params, wheels=wheels, t_final=t_final, friction=friction, law=law,
                     initial_offset=offset, reference=reference, mpc_options=mpc_options)
    summarize(run.trajectory, reference=reference, start=error_window)
    return run


def plot_engine(run: EngineRun | Trajectory, twin: Trajectory | None, folder: Path,
                stem: str, reference: HeadReference | None = None) -> dict[str, Path]:
    """Figs. 19 (head), 20 (D, R), 21 (snapshots) of a ``summarize``-d run, and beside
    the viscous ``twin`` if given: key -> ``folder/<stem>_<key>.png``."""
    import matplotlib.pyplot as plt

    from ..viz.plots import plot_criteria, plot_head_path, save_figure

    traj = run.trajectory if isinstance(run, EngineRun) else run
    paths = {k: folder / f"{stem}_{k}.png" for k in ("head", "criteria", "snapshots")}
    fig, ax = plt.subplots(figsize=(8, 4))
    reference = head_first_reference() if reference is None else reference
    target = np.array([reference(float(t))[0][:2] for t in traj.t])
    for k, (style, colour) in enumerate((("-", "k"), ("--", "gray"))):
        ax.plot(traj.t, traj.q[:, k], style, label=f"{'xy'[k]}_h")
        ax.plot(traj.t, target[:, k], ":", color=colour, label=f"{'xy'[k]}_h^r")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("[m]")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax.set_title(f"Head on the engine (Fig. 19): {error_caption(traj.summary)}", fontsize=10)
    save_figure(fig, paths["head"])

    crit = traj.meta["criteria"]
    plot_criteria(crit["t"], crit["D"], crit["R"], paths["criteria"],
                  "D and R from the estimated engine state (Fig. 20)")

    plot_head_path(traj, target, paths["snapshots"], snapshots=7,
                   title="Snapshots of the engine run (Fig. 21)")

    if twin is not None:
        paths["side_by_side"] = folder / f"{stem}_vs_viscous.png"
        fig, axes = plt.subplots(1, 2, figsize=(12, 4))
        axes[0].plot(traj.q[:, 0], traj.q[:, 1], label="MuJoCo, wheels (Coulomb)")
        axes[0].plot(twin.q[:, 0], twin.q[:, 1], label="Pinocchio, viscous (identified)")
        axes[0].plot(target[:, 0], target[:, 1], "k--", lw=1, label="reference")
        axes[0].set_xlabel("x [m]")
        axes[0].set_ylabel("y [m]")
        axes[0].set_aspect("equal", adjustable="datalim")
        axes[0].legend(fontsize=8)
        tc = twin.meta["criteria"]
        axes[1].semilogy(crit["t"], crit["R"], label="MuJoCo")
        axes[1].semilogy(tc["t"], tc["R"], label="viscous model")
        axes[1].set_xlabel("t [s]")
        axes[1].set_ylabel("R")
        axes[1].legend(fontsize=8)
        for a in axes:
            a.grid(alpha=0.3)
        fig.suptitle("Same controller, same robot: engine vs viscous model", fontsize=10)
        save_figure(fig, paths["side_by_side"])
    return paths


def engine_robot(params: SnakeParams) -> SnakeParams:
    """The engine stage's robot for a report on ``params``: the ``engine`` preset for a preset
    (the paper has no wheeled Table 1 robot), else ``params`` with every joint actuated."""
    if params.name in ROBOTS:
        return SnakeParams.engine()
    return params.replace(passive=())
