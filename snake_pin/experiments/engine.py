"""Report stage of Section VI.3 on MuJoCo (Figs. 19-21): the Lyapunov-like law on a wheeled
snake beside the viscous model, and the MPC along the benchmark's line and circle, as
distributions over perturbed starts (the engine is chaotic; :mod:`snake_pin.runs.engine`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..control import LyapunovController, QuasiStaticLyapunovController, head_first_reference
from ..engine.model import WheelSpec
from ..engine.run import ENGINE_TORQUE_BOUND, identify_friction
from ..gaits import initial_state
from ..metrics import default_error_window
from ..model import Snake
from ..params import ROBOTS, SnakeParams
from ..runs.benchmark import SPEED, make_scenario
from ..runs.engine import (
    METRICS,
    PERTURBATION,
    Draws,
    distribution,
    engine_draw,
    engine_robot,
    perturbations,
    plot_engine,
    summarize,
)
from ..runs.parallel import run_jobs
from ..sim import Trajectory, simulate
from .context import Context

__all__ = ["DRAWS", "MPC_DRAWS", "MPC_SCENARIOS", "MPC_T_FINAL", "QUICK_DRAWS",
           "QUICK_MPC_T_FINAL", "QUICK_T_FINAL", "SENSITIVE", "T_FINAL", "VISCOUS_DRAWS"]

#: Draws per configuration in the report (full run, ``--quick``) and of the viscous check.
DRAWS, QUICK_DRAWS, VISCOUS_DRAWS = 11, 3, 3
#: Duration of the engine runs (full run, ``--quick``: just past the 10 s error window) [s].
T_FINAL, QUICK_T_FINAL = 60.0, 11.0
#: A run counts as sensitive when offsets of :data:`PERTURBATION` rad move its RMS error by
#: more than this fraction of itself: a run that keeps small offsets small moves it by
#: about the offset (1e-6 .. 1e-5), a chaotic one by percents.
SENSITIVE = 1e-3
#: The MPC on the engine: the benchmark's paths it follows (scaled to the engine robot's
#: body length), its duration (full report, ``--quick``) [s] and its perturbed starts. The
#: MPC re-solves its horizon every 40 ms, several times slower than the other laws.
MPC_SCENARIOS = ("line", "circle_1L")
MPC_T_FINAL, QUICK_MPC_T_FINAL = 25.0, 1.0
MPC_DRAWS = 3


def _cell(dist: dict[str, Any], low: str = "p10", high: str = "p90", digits: int = 4) -> str:
    """A report table cell: median [low, high] of a distribution, "-" without values."""
    if dist["median"] is None:
        return "-"
    return f"{dist['median']:.{digits}g} [{dist[low]:.{digits}g}, {dist[high]:.{digits}g}]"


def viscous_twin(params: SnakeParams, t_final: float, law: str = "velocity",
                 offset: np.ndarray | None = None, error_window: float | None = None
                 ) -> Trajectory:
    """The same law ("velocity" or "acceleration") on the viscous model of ``params`` from
    the engine runs' start offset by ``offset``, passed through ``summarize``."""
    snake = Snake(params)
    controller = (QuasiStaticLyapunovController(snake, head_first_reference())
                  if law == "velocity" else LyapunovController(snake, head_first_reference()))
    x0 = initial_state(params.n, theta_1=np.pi)
    if offset is not None:
        x0[3:params.n + 2] += np.asarray(offset, dtype=float)
    traj = simulate(snake, controller, x0, t_final)
    summarize(traj, start=error_window)
    return traj


def _friction_section(sec: Any, base: SnakeParams, wheels: WheelSpec,
                      friction: dict[str, Any]) -> None:
    """The engine robot, its wheels and the identified friction against its models."""
    built = (f"a pair of free-spinning wheels (r = {wheels.radius} m, {wheels.mass} kg each) on "
             "each link" + ("" if base.uniform else ", sized to that link")
             + f", Coulomb friction mu = {wheels.friction} with the floor, motors on the active "
             "joints. Its chain mass matrix equals Pinocchio's H (tested). The controller "
             "reads positions from the engine and estimates velocities with "
             "2 pi f_c s / (s + 2 pi f_c), f_c = 10 Hz.")
    if base.uniform:
        sec.text(f"The engine robot (n = {base.n}, 2l = {base.link_length} m, m = {base.mass} "
                 f"kg, J = {base.inertia} kg m^2) is built for MuJoCo from the same SnakeParams:"
                 f" {built}")
        sec.table(["identified (per link)", "value", "model check"],
                  [["c_x [N s/m]", friction["c_x"],
                    f"rolling 2b/r^2 = {friction['c_x_rolling_model']:.4g}"],
                   ["c_y [N s/m]", friction["c_y"],
                    f"Coulomb 1.5 mu m g / v0 = {friction['c_y_coulomb_model']:.4g}"],
                   ["c_theta [N m s]", friction["c_theta"], "2 d^2 b / r^2"]])
        return
    lengths, masses = base.link_lengths, base.masses
    sec.text(f"The robot '{base.name}' (n = {base.n}, links {lengths.min():.3g}..."
             f"{lengths.max():.3g} m long and {masses.min():.3g}..{masses.max():.3g} kg, "
             f"{base.body_length:.3g} m and {base.total_mass:.3g} kg in all) is built for "
             f"MuJoCo from its own SnakeParams: {built}")
    sec.table(["identified", "whole robot", "model check", "per link (head first)"],
              [["c_x [N s/m]", friction["c_x_total"],
                f"n x rolling 2b/r^2 = {base.n * friction['c_x_rolling_model']:.4g}",
                "c_x,total / n"],
               ["c_y [N s/m]", friction["c_y_total"],
                f"Coulomb 1.5 mu M g / v0 = {friction['c_y_coulomb_model']:.4g}",
                "c_y,total m_i / M: " + ", ".join(f"{c:.4g}" for c in friction["c_y"])],
               ["c_theta [N m s]", "-", "2 d_i^2 b / r^2",
                ", ".join(f"{c:.3g}" for c in friction["c_theta"])]])


def engine_stage(ctx: Context) -> None:
    """Identification, the engine runs as distributions (both forms of the law), the
    viscous twin and its sensitivity check, and the MPC's runs along the line and the
    circle (:data:`MPC_SCENARIOS`) from perturbed starts."""
    from ..viz.meshcat_view import write_html

    t_final = QUICK_T_FINAL if ctx.quick else T_FINAL
    base = engine_robot(ctx.params)
    own = base.name not in ROBOTS
    wheels = WheelSpec()
    friction = identify_friction(base, wheels)
    sec = ctx.report.section("engine", "Physics engine: MuJoCo with wheels (VI.3)"
                             + (f", robot '{base.name}'" if own else ""))
    if not own and ctx.params.name != "engine":
        sec.text(f"This stage runs the 8-link robot of Section VI.3 (the 'engine' preset), not "
                 f"the '{ctx.params.name}' robot of the other stages: the paper gives no "
                 "wheeled model of it. Give a robot file (--robot FILE.toml) to run your own "
                 "robot here.")
    _friction_section(sec, base, wheels, friction)
    sec.numbers["friction"] = friction
    sec.text("The controller is the Lyapunov-like law of VI.2 (same V, gains (84), reference "
             "and serpenoid) with the identified viscous model. On wheels its velocity-level "
             "form runs: friction dominates inertia, so the model's force balance "
             "C_uu u' + C_ua a' = 0 gives the head velocity as J a', V of (83) becomes a "
             "quadratic in the joint velocities, and each step commands its minimiser "
             "through joint servos (snake_pin/control/quasistatic.py). The torque-level form "
             "of VI.2 is run as the contrast.")
    model_params = base.replace(c_x=friction["c_x"], c_y=friction["c_y"],
                                c_theta=friction["c_theta"])
    count = QUICK_DRAWS if ctx.quick else DRAWS
    offsets = perturbations(count, base.n - 1, PERTURBATION, seed=0)
    viscous_offsets = perturbations(VISCOUS_DRAWS, base.n - 1, PERTURBATION, seed=1)
    joint = 5 if base.n >= 6 else max(1, base.n // 2)  # the paper's, or the middle joint
    configs = [("velocity law, no passive joint", base, "engine"),
               (f"velocity law, joint {joint} passive", base.replace(passive=(joint,)),
                f"engine_passive{joint}")]
    error_window = default_error_window(t_final)
    options = {"wheels": wheels, "t_final": t_final, "friction": friction,
               "error_window": error_window}
    jobs: list[tuple[Any, tuple[Any, ...], dict[str, Any]]] = [
        (engine_draw, (params, offset), options)
        for _, params, _ in configs for offset in offsets]
    jobs.append((viscous_twin, (model_params, t_final), {"error_window": error_window}))
    jobs += [(viscous_twin, (model_params, t_final), {"offset": offset,
                                                      "error_window": error_window})
             for offset in viscous_offsets]
    jobs.append((engine_draw, (base, None), {**options, "t_final": min(t_final, 20.0),
                                             "law": "acceleration"}))
    mpc_t = QUICK_MPC_T_FINAL if ctx.quick else MPC_T_FINAL
    mpc_window = default_error_window(mpc_t)
    mpc_offsets = perturbations(MPC_DRAWS, base.n - 1, PERTURBATION, seed=0)
    mpc_references = {name: make_scenario(name, base.body_length) for name in MPC_SCENARIOS}
    # the MPC's runs are the longest: first, so that the others fill the workers behind them
    mpc_jobs: list[tuple[Any, tuple[Any, ...], dict[str, Any]]] = [
        (engine_draw, (base, offset), {**options, "t_final": mpc_t, "law": "mpc",
                                       "reference": mpc_references[name],
                                       "error_window": mpc_window})
        for name in MPC_SCENARIOS for offset in mpc_offsets]
    results = run_jobs(mpc_jobs + jobs, cluster=ctx.cluster)
    mpc_results, results = results[:len(mpc_jobs)], results[len(mpc_jobs):]
    engine_results = results[:len(configs) * count]
    twin, *viscous = results[len(configs) * count:-1]
    contrast = results[-1]

    dist_rows, target_rows, engine_spreads = [], [], []
    for c, (label, _, stem) in enumerate(configs):
        runs = engine_results[c * count:(c + 1) * count]
        draws = Draws(label, PERTURBATION, 0, offsets, [r.trajectory.summary_dict() for r in runs])
        median = runs[draws.median_draw() or 0]
        median.trajectory.meta["draw"] = (draws.median_draw() or 0) + 1
        median.trajectory.save(ctx.folder / stem)
        figures = plot_engine(median, twin if stem == "engine" else None, ctx.folder, stem)
        for key, path in figures.items():
            sec.figure(path, f"{label}, the median of {count} runs: {key.replace('_', ' ')}")
        if stem == "engine":
            page = write_html(median.trajectory, ctx.folder / f"{stem}.html")
            sec.link(page.name, "engine run (the median draw): 3-D animation (meshcat, "
                     "self-contained page)")
        dists = draws.distributions()
        dist_rows.append([f"MuJoCo, {label}", f"{len(draws.done)}"
                          + (f" ({len(draws.faults())} diverged)" if draws.faults() else ""),
                          *(_cell(dists[key]) for key in METRICS)])
        rms = dists["rms_percent"]["median"]
        target_rows.append((label, rms))
        engine_spreads.append(dists["rms_percent"]["p90"] - dists["rms_percent"]["p10"]
                              if rms is not None else math.nan)
        sec.numbers[stem] = {**median.trajectory.summary_dict(), "draws": draws.to_dict()}
    sec.text(f"The engine runs are chaotic, so each configuration is run {count} times from "
             f"the arc of (82) with every initial joint angle offset by a draw uniform in "
             f"[-{PERTURBATION:g}, {PERTURBATION:g}] rad (seed 0; the same offsets for both "
             "configurations), and each metric is given as the median [10 %, 90 %] over the "
             "runs (percentiles interpolated linearly). Figures and files show the median run "
             f"by RMS error. Head errors and torques over t >= {error_window:g} s; torque "
             "RMS over the applied torques of the actuated joints.")
    sec.table(["run", "runs", *METRICS.values()], dist_rows)

    single_rows = []
    for label, traj in (("MuJoCo, acceleration law (contrast, unperturbed)",
                         contrast.trajectory),
                        ("Pinocchio viscous model, velocity law (unperturbed)", twin)):
        s = traj.summary
        if traj.diverged:
            sec.text(f"{label}: stopped early, {traj.reason}.")
        single_rows.append([label, traj.t_end, s["rms_head_error"], s["rms_percent"],
                            s["max_percent"], s["R_min"], s["torque_rms"]])
    sec.numbers.update(engine_acceleration_law=contrast.trajectory.summary_dict(),
                       viscous_twin=twin.summary_dict())
    sec.table(["run", "simulated [s]", "RMS head error [m]", "RMS [% of body]",
               "max [% of body]", "R min", "torque RMS [N m]"], single_rows)

    nominal = twin.summary["rms_percent"]
    perturbed = [traj.summary["rms_percent"] for traj in viscous]
    if nominal is not None and all(v is not None for v in perturbed):
        spread = max(abs(v - nominal) for v in perturbed)
        relative = spread / max(abs(nominal), 1e-300)
        sensitive = relative > SENSITIVE
        engine_range = engine_spreads[0]
        sec.text(f"Sensitivity of the viscous model: the velocity-law run on the viscous model "
                 f"was repeated {VISCOUS_DRAWS} times with its initial joint angles offset by "
                 f"U(-{PERTURBATION:g}, {PERTURBATION:g}) rad (seed 1). Its RMS error, "
                 f"{nominal:.6g} % of the body unperturbed, moved by at most {spread:.2g} "
                 f"percentage points ({relative:.1e} of itself; runs: "
                 + ", ".join(f"{v:.9g}" for v in perturbed) + "), against a 10-90 % range of "
                 f"{engine_range:.3g} points over the engine runs without a passive joint: "
                 + (f"more than {SENSITIVE:g} of itself, so it is sensitive too and would need "
                    "the same treatment as the engine." if sensitive else
                    "a change of the order of the offset, so the viscous model is not "
                    "sensitive (small offsets stay small) and its single run stands for its "
                    "result."))
        sec.numbers["viscous_sensitivity"] = {
            "perturbation": PERTURBATION, "seed": 1, "rms_percent_unperturbed": nominal,
            "rms_percent_perturbed": perturbed, "max_change": spread, "relative_change": relative,
            "engine_range": engine_range, "sensitive": bool(sensitive)}
    verdicts = "; ".join(
        f"{label}: median {rms:.3g} % ({'met' if rms <= 10.0 else 'missed'})"
        if rms is not None else f"{label}: no error window" for label, rms in target_rows)
    sec.text(f"Target: RMS <= 10 % of the {base.body_length:.4g} m body over t >= "
             f"{error_window:g} s, judged on the median of the runs, R never zero. {verdicts}."
             " The torque-level law does not track on the engine: it chooses torques from the "
             "accelerations its viscous model predicts, which sticking wheels (Coulomb "
             "friction below mu N) do not produce, and wheels of neighbouring links collide "
             "beyond about 80 degrees of bend. Checked while finding this (results only): the "
             "engine loop matches the Pinocchio closed loop on a frictionless floor to 1e-4 "
             "over 1 s; exact velocities, mu = 0.05..1, model c_y from 0.01x to 3x, a shape "
             "spring up to 200, a heading weight down to 1 %, a regularised-Coulomb model and "
             "the no-slip limit c_y -> infinity as the controller's model all fail with the "
             "torque-level law.")
    sec.numbers["target_met"] = {label: (rms is not None and rms <= 10.0)
                                 for label, rms in target_rows}
    _mpc_section(sec, mpc_results, mpc_references, mpc_offsets, mpc_t, mpc_window, ctx)


def _mpc_section(sec: Any, runs: list[Any], references: dict[str, Any], offsets: np.ndarray,
                 t_final: float, error_window: float, ctx: Context) -> None:
    """The MPC's engine runs: per path, the status of each draw and the median [min, max]
    of the head error and the peak torque, and the median draw's head path."""
    from ..viz.plots import plot_head_path

    sec.text(f"The MPC on the engine: the receding-horizon Box-FDDP of "
             "snake_pin/control/mpc.py, its "
             "internal model the same identified viscous model as the law above, reading the "
             f"filtered velocities, its torques bounded by {ENGINE_TORQUE_BOUND:g} N m (the "
             "saturation of the engine robot's motors: the MPC plans within what they "
             "deliver), every joint actuated. It follows the benchmark's line and circle of "
             f"radius L at {SPEED:g} m/s for {t_final:g} s from {len(offsets)} starts, the arc of "
             f"(82) with its joint angles offset by U(-{PERTURBATION:g}, {PERTURBATION:g}) "
             f"rad (seed 0, the first {len(offsets)} offsets above). Head errors over t >= "
             f"{error_window:g} s against the timed reference, in % of the body; the peak "
             "torque over the whole run. Each cell is the median [min, max] over the runs.")
    rows, numbers = [], {}
    for k, name in enumerate(MPC_SCENARIOS):
        batch = runs[k * len(offsets):(k + 1) * len(offsets)]
        draws = Draws(f"MPC, {name}", PERTURBATION, 0, offsets,
                      [run.trajectory.summary_dict() for run in batch])
        statuses = [str(run.trajectory.status) for run in batch]
        dists = {key: distribution(draws.values(key))
                 for key in ("rms_percent", "max_percent", "torque_max")}
        rows.append([name, ", ".join(statuses),
                     *(_cell(dists[key], "min", "max", 3) for key in dists)])
        median = batch[draws.median_draw() or 0].trajectory
        reference = references[name]
        figure = ctx.folder / f"engine_mpc_{name}.png"
        plot_head_path(median, reference.at(median.t)[0][:, :2], figure,
                       title=f"MPC on the engine, {name}: the median of {len(batch)} runs")
        sec.figure(figure, f"MPC on the engine along the {name} path: the head of the median "
                           "run (by RMS error) against its reference, with body snapshots")
        numbers[name] = {"t_final": t_final, "error_window": error_window,
                         "torque_bound": ENGINE_TORQUE_BOUND, "statuses": statuses,
                         "distribution": dists, "draws": draws.to_dict(),
                         "solves": [run.trajectory.meta.get("mpc", {}) for run in batch]}
    sec.table(["path", "status of each run", "RMS head error [% of body]",
               "max head error [% of body]", "peak torque [N m]"], rows)
    sec.numbers["mpc"] = numbers
