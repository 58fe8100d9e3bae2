"""Report stage of Section VI.2: Lyapunov-like head tracking (Figs. 13-17) with and
without a passive joint, the isotropic contrast, the lateral-constraint criterion (Fig.
15) and the sweeps of the decay rate and of the sideways friction, each run one Dask task.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np

from ..control import LyapunovOptions
from ..manipulability import lateral_constraint_manipulability
from ..metrics import percent
from ..model import Snake
from ..params import SnakeParams
from ..runs.parallel import run_jobs
from ..runs.tracking import CRITERIA_EVERY, plot_tracking, run_tracking, tracking_friction

# the tracking run's start and robot, also by their names here (scripts/bench.py uses them)
from ..runs.tracking import initial_state as initial_state
from ..runs.tracking import tracking_params as tracking_params
from ..sim import Trajectory
from .context import Context

__all__ = ["C_Y_FACTORS", "DECAY_RATES"]

#: The stage's decay-rate sweep: lambda [1/s], mu = lambda / 2 (the default is the first run).
DECAY_RATES = (1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 14.0, 20.0, 30.0)
#: The stage's sideways-friction sweep: every link's c_y times these (1 is the first run).
C_Y_FACTORS = (0.1, 0.2, 0.4, 1.0, 2.0, 4.0, 10.0)
#: The law's own default head rate lambda [1/s] (read, not copied): the sweeps' default.
_DEFAULT_LAM: float = LyapunovOptions().lam


def lateral_comparison(traj: Trajectory, path: Path, t_max: float = 10.0) -> dict[str, float]:
    """Fig. 15: R against the lateral-constraint criterion over [0, t_max]."""
    import matplotlib.pyplot as plt

    from ..manipulability import manipulability
    from ..viz.plots import save_figure

    snake = Snake(traj.params)
    idx = np.flatnonzero(traj.t <= t_max)[::CRITERIA_EVERY]
    r = np.array([manipulability(snake, traj.q[k]).R for k in idx])
    lat = np.array([lateral_constraint_manipulability(snake, traj.q[k]).D for k in idx])
    fig, ax = plt.subplots(figsize=(8, 3.8))
    ax.semilogy(traj.t[idx], r, color="#228b22", label="R (no lateral constraint)")
    twin = ax.twinx()
    twin.semilogy(traj.t[idx], np.maximum(lat, 1e-16), "--", color="#1f4fd1",
                  label="lateral-constraint criterion")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("R", color="#228b22")
    twin.set_ylabel("lateral-constraint D", color="#1f4fd1")
    ax.grid(alpha=0.3, which="both")
    fig.legend(fontsize=8, loc="lower right")
    fig.suptitle("Fig. 15: our R against a lateral-constraint criterion (after Date et al.)",
                 fontsize=10)
    save_figure(fig, path)
    return {"R_at_0": float(r[0]), "lateral_at_0": float(lat[0]),
            "lateral_typical": float(np.median(lat))}


@dataclass(frozen=True)
class ReportRun:
    """One run of the tracking stage: label, robot, duration, law options, file stem (None:
    a sweep point), animation page or not, and its sweep point (``("lam", lambda)``, ...)."""

    label: str
    params: SnakeParams
    t_final: float
    options: Mapping[str, float] = field(default_factory=dict)
    stem: str | None = None
    animate: bool = False
    sweep: tuple[str, float] | None = None


def report_runs(robot: SnakeParams, t_final: float, own: bool) -> list[ReportRun]:
    """The tracking stage's runs: four with files (no passive joint, joint 5 passive, the
    isotropic contrast of at most 30 s, one rate for head and gait), then the two sweeps'
    points in increasing order (labelled by the factor on c_y with the robot's ``own``
    friction)."""
    c_x = robot.per_link("c_x")
    contrast = (f"isotropic (c_x = c_y = {robot.c_x})" if robot.uniform
                else "isotropic (c_y = c_x per link)")
    runs = [ReportRun("no passive joint", robot, t_final, stem="tracking", animate=True),
            ReportRun("joint 5 passive", robot.replace(passive=(5,)), t_final,
                      stem="tracking_passive5", animate=True),
            ReportRun(contrast, robot.replace(c_y=c_x), min(t_final, 30.0),
                      stem="tracking_isotropic"),
            ReportRun("one rate for head and gait (lambda = mu = 1/s)", robot, t_final,
                      {"lam": 1.0, "lam_shape": 1.0}, stem="tracking_one_rate")]
    runs += [ReportRun(f"lambda = {lam:g}/s, mu = {lam / 2:g}/s", robot, t_final,
                       {"lam": lam, "lam_shape": lam / 2}, sweep=("lam", lam))
             for lam in DECAY_RATES if lam != _DEFAULT_LAM]
    ratio = None if own else sweep_ratio(robot)
    for factor in C_Y_FACTORS:
        c_y = factor * robot.per_link("c_y")
        if factor == 1.0 or np.any(c_y <= c_x):  # Section V: c_y > c_x on every link
            continue
        label = (f"c_y x {factor:g} on every link" if ratio is None else
                 f"c_y = {c_y[0]:g} N s/m (c_y / c_x = {factor * ratio:g})")
        runs.append(ReportRun(label, robot.replace(c_y=c_y), t_final, sweep=("c_y", factor)))
    return runs


def sweep_ratio(robot: SnakeParams) -> float | None:
    """The c_y / c_x of the friction sweep's axis when all links share c_x and c_y, else None."""
    c_x, c_y = robot.per_link("c_x"), robot.per_link("c_y")
    if np.all(c_x == c_x[0]) and np.all(c_y == c_y[0]) and c_x[0] > 0:
        return float(c_y[0] / c_x[0])
    return None


#: One sweep point: (setting, RMS head error [% of the body] or None without an error
#: window, R_min along the run).
SweepPoint = tuple[float, float | None, float]


def sweep_findings(curves: Mapping[str, Sequence[SweepPoint]], target: float = 5.0
                   ) -> dict[str, dict[str, Any] | None]:
    """Per sweep: None without an error, else ``best``, ``first``, ``last`` ([setting, %,
    R_min]), ``above`` (settings above ``target`` %), ``no_window`` and ``target``."""
    out: dict[str, dict[str, Any] | None] = {}
    for axis, curve in curves.items():
        known = [point for point in curve if point[1] is not None and math.isfinite(point[1])]
        if not known:
            out[axis] = None
            continue
        best = min(known, key=lambda point: cast(float, point[1]))
        out[axis] = {"best": list(best), "first": list(known[0]), "last": list(known[-1]),
                     "above": [x for x, p, _ in known if cast(float, p) > target],
                     "no_window": [x for x, p, _ in curve
                                   if p is None or not math.isfinite(p)],
                     "target": target}
    return out


def sweep_text(found: Mapping[str, Mapping[str, Any] | None], c_y_name: str) -> str:
    """The report's paragraph on the two sweeps, from :func:`sweep_findings`."""
    parts = []
    for axis, name, unit in (("lam", "lambda", "/s"), ("c_y", c_y_name, "")):
        f = found.get(axis)
        if f is None:
            parts.append(f"No run of the {name} sweep has an error window.")
            continue

        ends = [f"{p:.2g} % at {x:g}{unit} (R min {r:.2g})"
                for x, p, r in (f["first"], f["last"]) if [x, p, r] != f["best"]]
        text = (f"Along {name}, the RMS head error is smallest at {f['best'][0]:g}{unit} "
                f"({f['best'][1]:.2g} % of the body, R min {f['best'][2]:.2g})"
                + (f", against {' and '.join(ends)}" if ends else ""))
        above = ", ".join(f"{x:g}" for x in f["above"])
        text += (f"; above the {f['target']:g} % target at {above}{unit}." if above
                 else f"; every point is within the {f['target']:g} % target.")
        if f["no_window"]:
            text += (" No error window (the run ended first) at "
                     f"{', '.join(f'{x:g}' for x in f['no_window'])}{unit}.")
        parts.append(text)
    return " ".join(parts)


def plot_sweep(curves: Mapping[str, Sequence[SweepPoint]], path: Path, *, c_y_axis: str,
               default: Mapping[str, float]) -> Path:
    """The sweeps' figure: RMS head error against each setting, the default as a star."""
    import matplotlib.pyplot as plt
    from matplotlib import ticker

    from ..viz.plots import save_figure

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4), sharey=True)
    for ax, (axis, label) in zip(axes, (("lam", "head decay rate lambda [1/s] (mu = lambda/2)"),
                                        ("c_y", c_y_axis)), strict=True):
        curve = curves.get(axis, [])
        xs = np.array([x for x, _, _ in curve], dtype=float)
        ys = np.array([np.nan if p is None else p for _, p, _ in curve], dtype=float)
        ax.set_xlabel(label)
        if not np.isfinite(ys).any():  # nothing to draw (and log scales would refuse)
            ax.text(0.5, 0.5, "no run with an error window", ha="center", va="center",
                    transform=ax.transAxes)
            continue
        ax.plot(xs, ys, "o-", color="#1f4fd1")
        at = np.flatnonzero(xs == default.get(axis, np.nan))
        if len(at):
            ax.plot(xs[at], ys[at], "*", color="#d9541a", markersize=14, label="default")
        ax.axhline(5.0, color="0.5", lw=0.8, ls="--", label="5 % target")
        ax.set_xscale("log")
        ax.set_yscale("log")
        for scale in (ax.xaxis, ax.yaxis):
            scale.set_major_formatter(ticker.FormatStrFormatter("%g"))
        ax.yaxis.set_minor_formatter(ticker.FormatStrFormatter("%g"))
        ax.grid(alpha=0.3, which="both")
    axes[0].set_ylabel("RMS head error [% of body]")
    for ax in axes:  # the legend on the first panel with something drawn
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
            break
    save_figure(fig, path)
    return path


def tracking_stage(ctx: Context) -> None:
    """Runs with and without a passive joint, the isotropic contrast, Fig. 15, the sweeps
    (each run one task on the report's cluster, the longest first)."""
    t_final = 11.0 if ctx.quick else 60.0  # quick: just past the 10 s window
    base = ctx.params.replace(passive=())
    robot, friction = tracking_friction(base)
    own = robot is base  # the robot's own friction is used
    sec = ctx.report.section("tracking", "Lyapunov-like head tracking (VI.2)")
    sec.text("Law: weighted least squares on q'' = A tau + b towards s' = -lambda s (head, "
             "weight K_w2) and phi'' = phi_r'' + mu e (joints, weight K_phi), gains (84), "
             f"lambda = {_DEFAULT_LAM:g}/s, mu = lambda / 2; V' = -2 lambda |s|^2 - 2 mu "
             "|e|^2 - 2 [s; e]^T W "
             "rho with the unreachable residual rho (derivation and the choice of the two rates "
             "in snake_pin/control/lyapunov.py). In the paper's coordinates theta_1 "
             "points from the head to the tail, so the head-first run along +x has theta_1 = pi:"
             f" w_r = [0.1 t, 0, pi], the arc of (82) turned by pi. The robot '{base.name}' with"
             f" {friction}.")
    runs = report_runs(robot, t_final, own)
    order = sorted(range(len(runs)), key=lambda i: -runs[i].t_final)  # longest first
    done = run_jobs([(run_tracking, (runs[i].params,),
                      {"t_final": runs[i].t_final, **runs[i].options}) for i in order],
                    cluster=ctx.cluster)
    results = dict(zip(order, done, strict=True))
    rows = []
    points: dict[str, list[tuple[float, str, Trajectory]]] = {"lam": [], "c_y": []}
    for index, run in enumerate(runs):
        traj = results[index]
        s = traj.summary
        if run.stem is None:  # a sweep point (report_runs sets one of the two)
            if run.sweep is not None:
                points[run.sweep[0]].append((run.sweep[1], run.label, traj))
            sec.numbers.setdefault("sweep", {})[run.label] = traj.summary_dict()
            continue
        if run.stem == "tracking":  # the default point of both sweeps
            points["lam"].append((_DEFAULT_LAM, f"lambda = {_DEFAULT_LAM:g}/s, mu = "
                                  f"{_DEFAULT_LAM / 2:g}/s (the default)", traj))
            points["c_y"].append((1.0, "c_y as the runs above (the default)", traj))
        traj.save(ctx.folder / run.stem)
        if run.animate:
            from ..viz.meshcat_view import write_html

            page = write_html(traj, ctx.folder / f"{run.stem}.html")
            sec.link(page.name, f"{run.label}: 3-D animation (meshcat, self-contained page)")
        for key, path in plot_tracking(traj, ctx.folder, run.stem).items():
            sec.figure(path, f"{run.label}: " + {"motion": "motion (Figs. 13/16)",
                                                  "criteria": "D and R (Figs. 14/17)",
                                                  "head": "head position and error"}[key])
        rows.append([run.label, s["rms_head_error"], percent(s["rms_relative"]),
                     s["max_head_error"], s["R_min"], s["g_drift"]])
        sec.numbers[run.stem] = traj.summary_dict()
        ctx.options.setdefault("trajectories", {})[run.label] = ctx.folder / f"{run.stem}.npz"
        if run.stem == "tracking":
            sec.numbers["lateral_criterion"] = lateral_comparison(
                traj, ctx.folder / "lateral_criterion.png")
    sec.table(["run", "RMS head error [m]", "% of body", "max error [m]", "R min",
               "max |g - g(0)|"], rows)
    sec.text(f"Targets: RMS <= 5 % of the {robot.body_length:.4g} m body without a passive "
             "joint, <= 10 % with joint 5 passive; R never reaches zero. With isotropic "
             "friction the head cannot follow and g of eq. (67) stays constant (Section V). "
             "The last row is the same law with one decay rate for head and gait: the head's "
             "x error then swings slowly (20-50 s) about the reference, which is why the "
             "head's rate is the faster one.")
    sweep_rows = []
    for axis, title in (("lam", "decay rate"), ("c_y", "sideways friction")):
        points[axis].sort(key=lambda point: point[0])
        for _, label, traj in points[axis]:
            s = traj.summary
            sweep_rows.append([title, label, s["rms_head_error"], percent(s["rms_relative"]),
                               s["R_min"], traj.status])
    ratio = None if own else sweep_ratio(robot)
    curves = {axis: [(value * (ratio or 1.0) if axis == "c_y" else value,
                      percent(traj.summary["rms_relative"]), traj.summary["R_min"])
                     for value, _, traj in found] for axis, found in points.items()}
    found = sweep_findings(curves)
    sec.numbers["sweep_findings"] = found
    plot_sweep(curves, ctx.folder / "tracking_sweep.png",
               c_y_axis="c_y / c_x" if ratio else "factor on every link's c_y",
               default={"lam": _DEFAULT_LAM, "c_y": ratio or 1.0})
    sec.table(["no passive joint, varied", "setting", "RMS head error [m]", "% of body",
               "R min", "status"], sweep_rows)
    sec.figure(ctx.folder / "tracking_sweep.png",
               "RMS head error against the head's decay rate (mu = lambda / 2) and against "
               "the sideways friction; the star is the default")
    sec.text(sweep_text(found, c_y_name="c_y / c_x" if ratio else "the factor on c_y"))
    sec.figure(ctx.folder / "lateral_criterion.png",
               "Fig. 15: R against the lateral-constraint criterion over [0, 10] s")
    sec.text(f"At the initial arc the lateral-constraint criterion is "
             f"{sec.numbers['lateral_criterion']['lateral_at_0']:.1e} (numerically zero: arcs are"
             f" singular for a wheeled snake) while R = "
             f"{sec.numbers['lateral_criterion']['R_at_0']:.3g}, and the robot does leave that "
             "posture and track: the lateral-constraint criterion misjudges this robot.")
