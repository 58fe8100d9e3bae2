"""Section VI.2: Lyapunov-like head tracking on the Table 1 robot (Figs. 13-17), with and
without a passive joint, the isotropic contrast, and the lateral-constraint criterion.

Owns one tracking run (:func:`run_tracking`) and its summary (:func:`tracking_summary`),
the stage's runs (:func:`report_runs`) and the report stage (:func:`tracking_stage`), which
runs them one per task on Dask (:func:`snake_pin.experiments.parallel.run_jobs`).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np

from .. import gaits
from ..control import LyapunovController, head_first_reference
from ..control.reference import LinearReference
from ..integrability import conserved_quantity_along
from ..manipulability import lateral_constraint_manipulability
from ..metrics import (
    ERROR_WINDOW,
    criteria_along,
    error_caption,
    head_error_summary,
    head_position_error,
    percent,
)
from ..model import Snake
from ..params import ROBOTS, SnakeParams
from ..sim import Trajectory, simulate

__all__ = ["CRITERIA_EVERY", "C_Y_FACTORS", "DECAY_RATES", "REFERENCE", "TRACKING_FRICTION",
           "ReportRun", "initial_state", "plot_sweep", "plot_tracking", "report_runs",
           "run_tracking", "sweep_findings", "sweep_ratio", "sweep_text", "tracking_friction",
           "tracking_meta", "tracking_params", "tracking_stage", "tracking_summary"]

#: Friction of the tracking runs (erratum 3, docs/errata.md): c_x as Table 1, c_y = 50 c_x.
#: Section V rules out isotropic friction; the open-loop serpenoid of VI.2 reaches
#: 0.10 m/s at c_y = 10 c_x and 0.16 m/s at 50 c_x, and 50 tracked best of 10..100.
TRACKING_FRICTION = {"c_x": 0.5, "c_y": 25.0}
#: Manipulability is evaluated every this many samples (10 ms at 1 kHz).
CRITERIA_EVERY = 10
#: The head reference of every tracking run, as the trajectories' meta names it.
REFERENCE = "w_r = [0.1 t, 0, pi]"
#: The stage's decay-rate sweep: the head's rate lambda [1/s], with the gait's mu = lambda / 2
#: (the law's default, lambda = 10/s, is the stage's first run: not run twice).
DECAY_RATES = (1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 14.0, 20.0, 30.0)
#: The stage's sideways-friction sweep: every link's c_y times these (1 is the stage's first
#: run; with the tracking friction, c_y / c_x = 5 ... 500).
C_Y_FACTORS = (0.1, 0.2, 0.4, 1.0, 2.0, 4.0, 10.0)
#: The law's own default head rate lambda [1/s] (read, not copied): the sweeps' default.
_DEFAULT_LAM: float = inspect.signature(LyapunovController).parameters["lam"].default


def tracking_params(params: SnakeParams | None = None, **changes: object) -> SnakeParams:
    """A robot with the tracking friction of erratum 3.

    Parameters
    ----------
    params
        The robot (default Table 1).
    **changes
        Further field changes (friction given here wins).

    Returns
    -------
    SnakeParams
        ``params`` with c_x = 0.5, c_y = 25 N s/m (:data:`TRACKING_FRICTION`), then
        ``changes``.
    """
    base = (params or SnakeParams.table1()).replace(**TRACKING_FRICTION)
    return base.replace(**changes) if changes else base


def tracking_friction(params: SnakeParams) -> tuple[SnakeParams, str]:
    """The robot with the friction a tracking run uses, and a sentence saying which.

    A robot of one's own (its name is not a preset's: a robot file, a URDF) keeps its
    friction when it is anisotropic on every link (c_y > c_x, as wheels give; Section V
    rules out isotropic friction). Presets (Table 1's friction is isotropic) and other
    robots get :data:`TRACKING_FRICTION` (erratum 3).

    Parameters
    ----------
    params
        The robot.

    Returns
    -------
    tuple of (SnakeParams, str)
        The robot to run (``params`` itself when it keeps its friction) and a sentence
        for the report saying which friction it has.
    """
    own = params.name not in ROBOTS
    if own and np.all(params.per_link("c_y") > params.per_link("c_x")):
        ratio = params.per_link("c_y") / params.per_link("c_x")
        return params, ("the robot's own friction (anisotropic on every link, c_y > c_x; "
                        f"c_y / c_x from {ratio.min():.3g} to {ratio.max():.3g})")
    sentence = (f"friction c_x = {TRACKING_FRICTION['c_x']}, c_y = {TRACKING_FRICTION['c_y']} "
                "N s/m (erratum 3)")
    if own:
        sentence += (", which replaces the robot's own friction: it is not anisotropic on "
                     "every link, and Section V rules out tracking with isotropic friction")
    return tracking_params(params), sentence


def initial_state(params: SnakeParams) -> np.ndarray:
    """Eq. (82)'s arc (phi = pi/6), head-first along +x: theta_1 = pi, at rest.

    Parameters
    ----------
    params
        The robot.

    Returns
    -------
    numpy.ndarray
        The state x = [q, dq], 2 (n + 2) values.
    """
    return gaits.initial_state(params.n, theta_1=np.pi)


def tracking_meta(controller: LyapunovController) -> dict[str, Any]:
    """The entries a tracking run adds to its trajectory's meta.

    Parameters
    ----------
    controller
        The run's law.

    Returns
    -------
    dict
        ``reference`` (:data:`REFERENCE`), ``k_shape``, ``lam`` and ``lam_shape`` of the law.
    """
    return {"reference": REFERENCE, "k_shape": controller.k_shape, "lam": controller.lam,
            "lam_shape": controller.lam_shape}


def run_tracking(params: SnakeParams | None = None, *, t_final: float = 60.0,
                 error_window: float | None = None,
                 progress: bool = False, **controller_options: Any) -> Trajectory:
    """60 s of head tracking, w_r = [0.1 t, 0, pi], gains (84), control at 1 kHz.

    Parameters
    ----------
    params
        The robot, used as given (pass :func:`tracking_params` for the anisotropic
        default; default: Table 1 with it).
    t_final
        Duration [s].
    error_window
        Start of the head-error window [s] (None: 10 s, or the second half of a run
        shorter than 20 s).
    progress
        Show a progress bar on stderr when it is a terminal.
    **controller_options
        Options of :class:`~snake_pin.control.LyapunovController` (e.g. ``lam``,
        ``lam_shape``).

    Returns
    -------
    Trajectory
        The run with :func:`tracking_summary`'s summary, head error and criteria.
    """
    params = params or tracking_params()
    snake = Snake(params)
    reference = head_first_reference()
    controller = LyapunovController(snake, reference, **controller_options)
    traj = simulate(snake, controller, initial_state(params), t_final, progress=progress,
                    meta=tracking_meta(controller))
    return tracking_summary(traj, snake, reference, start=error_window)


def tracking_summary(traj: Trajectory, snake: Snake,
                     reference: LinearReference | None = None, *,
                     start: float | None = None) -> Trajectory:
    """Add a tracking run's head error, criteria and summary to its trajectory.

    The one summary of a tracking run (:func:`run_tracking` adds it).

    Parameters
    ----------
    traj
        The run (changed in place).
    snake
        Its robot.
    reference
        The head reference; None: w_r = [0.1 t, 0, pi].
    start
        Start of the head-error window [s]; None: the default of
        :func:`~snake_pin.metrics.head_error_summary` (10 s, or the second half of a
        run shorter than 20 s).

    Returns
    -------
    Trajectory
        ``traj``, with ``signals["head_error"]`` [m] at every sample, ``meta["criteria"]``
        (D and R, eqs. 30 and 31, every :data:`CRITERIA_EVERY` samples; R~ with the passive
        joints free, eq. 42) and in its summary: the
        controller, friction and passive joints, the head error over t >= ``start``
        (error_window, rms_head_error, max_head_error [m], their _pct, rms_relative),
        R_min, D_min, body_length,
        g_drift (max |g - g(0)| of eq. 67) and the final head pose.
    """
    params = snake.params
    reference = reference or head_first_reference()
    error = head_position_error(traj, reference)
    t_c, d, r = criteria_along(traj, every=CRITERIA_EVERY)
    g = conserved_quantity_along(snake, traj.q, traj.dq)
    traj.signals["head_error"] = error
    traj.meta["criteria"] = {"t": t_c.tolist(), "D": d.tolist(), "R": r.tolist()}
    errors = head_error_summary(traj, error) if start is None \
        else head_error_summary(traj, error, start=start)
    traj.summary.update({
        "controller": "lyapunov", "c_x": params.c_x, "c_y": params.c_y,
        "passive": list(params.passive), **errors,
        "R_min": float(r.min()), "D_min": float(d.min()),
        "body_length": params.body_length,
        "g_drift": float(np.abs(g - g[0]).max()),
        "final_head": traj.q[-1, :3].tolist(),
    })
    return traj


def plot_tracking(traj: Trajectory, folder: Path, stem: str) -> dict[str, Path]:
    """Snapshots along the path (Figs. 13, 16), D and R (Figs. 14, 17), head vs reference.

    Parameters
    ----------
    traj
        A run of :func:`run_tracking`.
    folder
        Where the PNGs go.
    stem
        Their file-name prefix.

    Returns
    -------
    dict
        Figure key ("motion", "criteria", "head") -> PNG path.
    """
    import matplotlib.pyplot as plt

    from ..viz.plots import draw_snake, save_figure

    folder = Path(folder)
    snake = Snake(traj.params)
    paths = {k: folder / f"{stem}_{k}.png" for k in ("motion", "criteria", "head")}
    fig, ax = plt.subplots(figsize=(10, 4.2))
    t_end = traj.t_end
    ax.plot([0, 0.1 * t_end], [0, 0], "k--", lw=1, label="reference path")
    ax.plot(traj.q[:, 0], traj.q[:, 1], color="#d9541a", lw=0.8, label="head")
    times = np.linspace(0, t_end, 7)
    for k, t in enumerate(times):
        i = int(np.searchsorted(traj.t, t))
        draw_snake(ax, snake, traj.q[min(i, len(traj) - 1)], alpha=0.35 + 0.65 * k / 6)
    joints = ", ".join(str(k) for k in traj.params.passive)
    passive = f", joint {joints} passive (x)" if traj.params.passive else ""
    ax.set_title(f"Head tracking, snapshots every {times[1]:.0f} s{passive}", fontsize=10)
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    save_figure(fig, paths["motion"])

    crit = traj.meta["criteria"]
    tilde = "~" if traj.params.passive else ""
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    axes[0].semilogy(crit["t"], crit["D"], color="#1f4fd1")
    axes[0].set_ylabel(f"D{tilde}")
    axes[1].semilogy(crit["t"], crit["R"], color="#228b22")
    axes[1].set_ylabel(f"R{tilde}")
    axes[1].set_xlabel("t [s]")
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
    fig.suptitle(f"Manipulability criteria along the run (R min {min(crit['R']):.2e})",
                 fontsize=10)
    save_figure(fig, paths["criteria"])

    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    axes[0].plot(traj.t, traj.q[:, 0], label="x_h")
    axes[0].plot(traj.t, 0.1 * traj.t, "k:", label="x_h^r")
    axes[0].plot(traj.t, traj.q[:, 1], label="y_h")
    axes[0].legend(fontsize=8)
    axes[0].set_ylabel("[m]")
    axes[1].plot(traj.t, traj.signals["head_error"], color="firebrick")
    axes[1].axvspan(0, traj.summary.get("error_window", ERROR_WINDOW), color="0.9")
    axes[1].set_ylabel("head error [m]")
    axes[1].set_xlabel("t [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(error_caption(traj.summary), fontsize=10)
    save_figure(fig, paths["head"])
    return paths


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
    """One run of the tracking stage.

    Parameters
    ----------
    label
        Its row label in the report.
    params
        The robot, friction and passive joints included.
    t_final
        Duration [s].
    options
        Options of :class:`~snake_pin.control.LyapunovController` (``lam``,
        ``lam_shape``, ``k_shape``).
    stem
        File-name stem of its saved trajectory and figures; None: a sweep point (a table
        row and a point of the sweep's figure only).
    animate
        Whether it also gets a self-contained 3-D animation page.
    sweep
        The sweep point it is: ``("lam", lambda)`` or ``("c_y", factor)``; None for the
        runs with files (the first of which is the default point of both sweeps).
    """

    label: str
    params: SnakeParams
    t_final: float
    options: Mapping[str, float] = field(default_factory=dict)
    stem: str | None = None
    animate: bool = False
    sweep: tuple[str, float] | None = None


def report_runs(robot: SnakeParams, t_final: float, own: bool) -> list[ReportRun]:
    """The runs of the tracking stage: four with files, then the two sweeps' points.

    With files: no passive joint and joint 5 passive (both animated), the isotropic
    contrast (at most 30 s: failure and a constant g show by then) and one decay rate for
    head and gait (lambda = mu = 1/s). The sweeps, each changing one setting of the first
    run (which is their default point, not run again): the decay rates
    :data:`DECAY_RATES` along mu = lambda / 2, and every link's c_y times
    :data:`C_Y_FACTORS`.

    Parameters
    ----------
    robot
        The tracking robot (:func:`tracking_friction`), no passive joint.
    t_final
        Duration of the runs [s].
    own
        Whether ``robot`` keeps its own friction (the labels then give the factor on c_y,
        not c_y itself).

    Returns
    -------
    list of ReportRun
        The runs with files (``stem`` set) first, in report order, then the sweeps' points
        (``sweep`` set), decay rates first, each sweep in increasing order.
    """
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
    """The c_y / c_x the sideways-friction sweep is drawn against, if there is one.

    Parameters
    ----------
    robot
        The tracking robot.

    Returns
    -------
    float or None
        c_y / c_x when every link has the same c_x and the same c_y; None otherwise (the
        sweep is then read as a factor on every link's c_y).
    """
    c_x, c_y = robot.per_link("c_x"), robot.per_link("c_y")
    if np.all(c_x == c_x[0]) and np.all(c_y == c_y[0]) and c_x[0] > 0:
        return float(c_y[0] / c_x[0])
    return None


#: One sweep point: (setting, RMS head error [% of the body] or None without an error
#: window, R_min along the run).
SweepPoint = tuple[float, float | None, float]


def sweep_findings(curves: Mapping[str, Sequence[SweepPoint]], target: float = 5.0
                   ) -> dict[str, dict[str, Any] | None]:
    """Where each sweep's head error is smallest, its two ends and its points off target.

    Parameters
    ----------
    curves
        Per sweep (``"lam"``, ``"c_y"``): its points (setting, % of the body or None,
        R_min), in increasing setting.
    target
        The RMS head error the runs should stay under [% of the body] (5: no passive
        joint).

    Returns
    -------
    dict
        Per sweep, None when no point has an error, else ``best``, ``first`` and ``last``
        (each [setting, %, R_min]: the smallest error and the two ends of the points with
        an error), ``above`` (the settings whose error exceeds ``target``), ``no_window``
        (those whose run ended before its error window: no error) and ``target``.
    """
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
    """The report's sentences on the two sweeps, from :func:`sweep_findings`.

    Parameters
    ----------
    found
        :func:`sweep_findings`' result.
    c_y_name
        What the sideways-friction sweep's settings are (``"c_y / c_x"`` or ``"the factor
        on c_y"``).

    Returns
    -------
    str
        One paragraph.
    """
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
    """The sweeps' figure: RMS head error (% of the body) against each sweep's setting.

    Parameters
    ----------
    curves
        As for :func:`sweep_findings`.
    path
        The PNG to write.
    c_y_axis
        Label of the sideways-friction axis.
    default
        Each sweep's default setting (drawn as a star).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
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


def tracking_stage(ctx) -> None:
    """Runs with and without a passive joint, the isotropic contrast, Fig. 15, the sweeps.

    Every run of the stage (:func:`report_runs`: 18) is one :func:`run_tracking` task of
    :func:`~snake_pin.experiments.parallel.run_jobs` (one worker per core, the longest
    runs submitted first). The sweeps (decay rate, sideways friction) are a table,
    ``tracking_sweep.png`` (:func:`plot_sweep`) and sentences from the numbers
    (:func:`sweep_findings`, :func:`sweep_text`).

    Parameters
    ----------
    ctx
        The report's :class:`~snake_pin.experiments.reproduce.Context`: output folder,
        robot, report and quick mode.
    """
    from .parallel import run_jobs

    t_final = 11.0 if ctx.quick else 60.0  # quick: just past the 10 s window
    base = ctx.params.replace(passive=())
    robot, friction = tracking_friction(base)
    own = robot is base  # the robot's own friction is used
    sec = ctx.report.section("tracking", "Lyapunov-like head tracking (VI.2)")
    sec.text("Law: weighted least squares on q'' = A tau + b towards s' = -lambda s (head, "
             "weight K_w2) and phi'' = phi_r'' + mu e (joints, weight K_phi), gains (84), "
             "lambda = 10/s, mu = lambda / 2; V' = -2 lambda |s|^2 - 2 mu |e|^2 - 2 [s; e]^T W "
             "rho with the unreachable residual rho (derivation and the choice of the two rates "
             "in snake_pin/control/lyapunov.py). In the paper's coordinates theta_1 "
             "points from the head to the tail, so the head-first run along +x has theta_1 = pi:"
             f" w_r = [0.1 t, 0, pi], the arc of (82) turned by pi. The robot '{base.name}' with"
             f" {friction}.")
    runs = report_runs(robot, t_final, own)
    order = sorted(range(len(runs)), key=lambda i: -runs[i].t_final)  # longest first
    done = run_jobs([(run_tracking, (runs[i].params,),
                      {"t_final": runs[i].t_final, **runs[i].options}) for i in order])
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
            lateral = lateral_comparison(traj, ctx.folder / "lateral_criterion.png")
            sec.numbers["lateral_criterion"] = lateral
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
