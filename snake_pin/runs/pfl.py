"""Section VI.1's run: the PFL head controller (gains 79, reference 80, serpenoid 81,
initial state 82) and its analysis (:func:`run_pfl`), breakdown threshold and figures
(``plot_pfl``), for ``snake-pin simulate --controller pfl`` and the report.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .. import gaits
from ..control import LinearReference, PFLController, PFLOptions
from ..integrability import conserved_quantity_along
from ..metrics import applied, criteria_along, head_error_summary, head_position_error
from ..model import Snake
from ..params import SnakeParams
from ..sim import simulate
from ..trajectory import Trajectory

__all__ = ["TAU_BREAKDOWN", "PFLRun", "run_pfl"]

#: ``||tau||`` above this [N m] counts as PFL's breakdown on the Table 1 robot (tracking
#: needs 0.01-0.3 N m); other robots scale it (``breakdown_threshold``).
TAU_BREAKDOWN = 1.0
#: m (2l)^2 of a Table 1 link [kg m^2]: the scale of :data:`TAU_BREAKDOWN`.
_TABLE1_LINK = 0.182 * 0.12**2


def breakdown_threshold(params: SnakeParams) -> float:
    """``||tau||`` [N m] of PFL's breakdown for ``params``: :data:`TAU_BREAKDOWN` scaled by the
    mean m_i (2l_i)^2 over a Table 1 link's (a heavier robot needs larger torques)."""
    if params.uniform:
        link = float(params.masses[0] * params.link_lengths[0] ** 2)
    else:
        link = float(np.mean(params.masses * params.link_lengths**2))
    return TAU_BREAKDOWN * link / _TABLE1_LINK


def initial_state(params: SnakeParams) -> np.ndarray:
    """The state x = [q, dq] of eq. (82): w0 = 0, phi0 = pi/6 for every joint, at rest."""
    return gaits.initial_state(params.n)


@dataclass
class PFLRun:
    """A PFL run with its analysis.

    Parameters
    ----------
    trajectory
        The run (its summary filled by :func:`run_pfl`).
    D, R
        Manipulability at every sample.
    g
        (N, 2) conserved quantity of eq. (67) at every sample.
    breakdown
        Sample index of the breakdown (the last sample if none).
    """

    trajectory: Trajectory
    D: np.ndarray
    R: np.ndarray
    g: np.ndarray
    breakdown: int


def run_pfl(params: SnakeParams | None = None, *, t_final: float = 10.0,
            climb_R: float | None = None, control_dt: float = 1e-3,
            error_window: float | None = None, progress: bool = False,
            options: PFLOptions | None = None) -> PFLRun:
    """Run Section VI.1; the summary's criteria, drift and errors are taken before the
    breakdown (``||tau||`` above ``breakdown_threshold``), with the head error of
    :func:`~snake_pin.metrics.head_error_summary`.

    Parameters
    ----------
    params
        The robot (default Table 1), every joint actuated.
    t_final
        Duration [s].
    climb_R
        Gain of the singularity-aware use of the redundancy (0: the paper's law; None:
        that of ``options``).
    control_dt
        Control period and RK4 step [s].
    error_window
        Start of the head-error window [s] (None: the default of ``t_final``).
    progress
        Show a progress bar on stderr when it is a terminal.
    options
        The law's :class:`~snake_pin.control.PFLOptions` (None: the defaults, gains 79).

    Returns
    -------
    PFLRun
        The run with D, R and g at every sample.
    """
    params = params or SnakeParams.table1()
    snake = Snake(params)
    reference = LinearReference()
    if climb_R is not None and (options is None or isinstance(options, PFLOptions)):
        options = replace(PFLOptions() if options is None else options, climb_R=climb_R)
    controller = PFLController(snake, reference, options=options)
    climb_R = controller.climb_R
    traj = simulate(snake, controller, initial_state(params), t_final, dt=control_dt,
                    control_dt=control_dt, progress=progress,
                    meta={"climb_R": climb_R, "reference_velocity": [0.1, 0.0, 0.0]})
    tau_norm = np.linalg.norm(traj.tau, axis=1)
    threshold = breakdown_threshold(params)
    over = np.flatnonzero(tau_norm > threshold)
    breakdown = int(over[0]) if over.size else len(traj) - 1
    broke = bool(over.size) or traj.diverged
    _, d, r = criteria_along(traj)
    g = conserved_quantity_along(snake, traj.q, traj.dq)
    before = slice(0, breakdown + 1)
    k_min = int(np.argmin(r[before]))
    # The paper's "dip": the smallest R after R's peak, up to the breakdown (the initial
    # arc itself has a low R, so the global minimum can sit at t = 0).
    k_peak = int(np.argmax(r[before]))
    k_dip = k_peak + int(np.argmin(r[k_peak:breakdown + 1]))
    error = head_position_error(traj, reference)
    errors = head_error_summary(traj, error, start=error_window)
    traj.signals.update({"D": d, "R": r, "tau_norm": tau_norm, "g_x": g[:, 0], "g_y": g[:, 1],
                         "head_error": error})
    traj.summary.update({
        "controller": "pfl", "climb_R": climb_R, "c_x": params.c_x, "c_y": params.c_y,
        "breakdown_threshold": threshold,
        "breakdown_time": float(traj.t[breakdown]) if broke else None,
        "t_R_min": float(traj.t[k_min]), "R_min": float(r[k_min]),
        "t_R_dip": float(traj.t[k_dip]), "R_dip": float(r[k_dip]),
        "R_peak": float(r[k_peak]), "D_min": float(d[before].min()),
        "g_drift_max": float(np.abs(g[before] - g[0]).max()),
        "head_error_max": float(error[before].max()), **errors,
        "body_length": params.body_length})
    return PFLRun(traj, d, r, g, breakdown)


def plot_pfl(run: PFLRun, folder: Path, stem: str) -> dict[str, Path]:
    """Figures like Figs. 10-12 and the postures of Fig. 11: key -> ``folder/<stem>_<key>.png``."""
    import matplotlib.pyplot as plt

    from ..viz.plots import draw_snake, plot_criteria, save_figure

    traj = run.trajectory
    t, s = traj.t, traj.summary
    paths = {key: folder / f"{stem}_{key}.png" for key in ("criteria", "torque", "g", "postures")}
    bk = s.get("breakdown_time")

    def mark(ax: plt.Axes) -> None:
        if bk is not None:
            ax.axvline(bk, color="firebrick", ls=":", lw=1, label=f"breakdown {bk:.2f} s")
        ax.axvline(s["t_R_dip"], color="gray", ls="--", lw=1, label=f"R dip {s['t_R_dip']:.2f} s")

    plot_criteria(t, run.D, run.R, paths["criteria"],
                  "Manipulability criteria along the PFL run (Fig. 10a)", mark=mark)

    held = applied(traj)  # the last sample's torque of a run that did not diverge: never applied
    fig, ax = plt.subplots(figsize=(8, 3.8))
    ax.semilogy(t[held], traj.signals["tau_norm"][held], color="k", label="||tau|| [N m]")
    ax.axhline(s["breakdown_threshold"], color="firebrick", lw=0.8)
    mark(ax)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("||tau|| [N m]")
    ax.set_ylim(1e-3, 1e3)
    twin = ax.twinx()
    twin.plot(t, run.R, color="#228b22", label="R")
    twin.set_ylabel("R", color="#228b22")
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3)
    fig.suptitle("Torque norm with R (Fig. 10b)", fontsize=10)
    save_figure(fig, paths["torque"])

    fig, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    for ax, k, name in ((axes[0], 0, "g_1"), (axes[1], 1, "g_2")):
        ax.plot(t, run.g[:, k] - run.g[0, k], color="#6c3483")
        ax.set_ylabel(f"{name} - {name}(0)")
        mark(ax)
        ax.grid(alpha=0.3)
        twin = ax.twinx()
        twin.plot(t, run.R, color="#228b22", lw=0.8)
        twin.set_ylabel("R", color="#228b22")
    axes[1].set_xlabel("t [s]")
    fig.suptitle(f"Conserved quantity g of eq. (67) (Fig. 12); c_x = {s['c_x']}, "
                 f"c_y = {s['c_y']}", fontsize=10)
    save_figure(fig, paths["g"])

    snake = Snake(traj.params)
    fig, ax = plt.subplots(figsize=(7, 5))
    k_dip = int(np.searchsorted(t, s["t_R_dip"]))
    draw_snake(ax, snake, traj.q[0], color="#7f8c8d", label="t = 0 s")
    draw_snake(ax, snake, traj.q[k_dip], label=f"t = {t[k_dip]:.2f} s (R dip)")
    ax.plot(traj.q[:k_dip + 1, 0], traj.q[:k_dip + 1, 1], color="#d9541a", lw=1, label="head")
    ax.plot([0, 0.1 * t[k_dip]], [0, 0], "k--", lw=1, label="reference")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax.set_title("Postures at t = 0 and at the R dip (Fig. 11)", fontsize=10)
    save_figure(fig, paths["postures"])
    return paths
