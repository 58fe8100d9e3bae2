"""Section VI.2's run: Lyapunov-like head tracking (w_r = [0.1 t, 0, pi], gains (84)), its
robot, start and figures, for ``snake-pin simulate``, the report and the benchmark.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .. import gaits
from ..control import LyapunovController, LyapunovOptions, head_first_reference
from ..integrability import conserved_quantity_along
from ..metrics import (
    ERROR_WINDOW,
    criteria_along,
    error_caption,
    head_error_summary,
    head_position_error,
)
from ..model import Snake
from ..params import ROBOTS, SnakeParams
from ..sim import Trajectory, simulate

__all__ = ["CRITERIA_EVERY", "REFERENCE", "TRACKING_FRICTION", "run_tracking",
           "tracking_params"]

#: Friction of the tracking runs (erratum 3, :doc:`/errata`): c_x as Table 1, c_y = 50 c_x.
TRACKING_FRICTION = {"c_x": 0.5, "c_y": 25.0}
#: Manipulability is evaluated every this many samples (10 ms at 1 kHz).
CRITERIA_EVERY = 10
#: The head reference of every tracking run, as the trajectories' meta names it.
REFERENCE = "w_r = [0.1 t, 0, pi]"


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
        ``params`` with :data:`TRACKING_FRICTION`, then ``changes``.
    """
    base = (params or SnakeParams.table1()).replace(**TRACKING_FRICTION)
    return base.replace(**changes) if changes else base


def tracking_friction(params: SnakeParams) -> tuple[SnakeParams, str]:
    """The robot a tracking run uses and a sentence saying its friction: a robot of one's own
    keeps its friction when c_y > c_x on every link (Section V), the others get
    :data:`TRACKING_FRICTION`."""
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
    """The state x = [q, dq] on eq. (82)'s arc (phi = pi/6), head-first along +x (theta_1 =
    pi), at rest."""
    return gaits.initial_state(params.n, theta_1=np.pi)


def run_tracking(params: SnakeParams | None = None, *, t_final: float = 60.0,
                 error_window: float | None = None, progress: bool = False,
                 options: LyapunovOptions | None = None,
                 **controller_options: Any) -> Trajectory:
    """60 s of head tracking, w_r = [0.1 t, 0, pi], gains (84), control at 1 kHz.

    Parameters
    ----------
    params
        The robot, used as given (default: :func:`tracking_params`).
    t_final
        Duration [s].
    error_window
        Start of the head-error window [s] (None: the default of ``t_final``).
    progress
        Show a progress bar on stderr when it is a terminal.
    options
        The law's :class:`~snake_pin.control.LyapunovOptions` (None: the defaults).
    **controller_options
        Fields of :class:`~snake_pin.control.LyapunovOptions` to change (e.g. ``lam``).

    Returns
    -------
    Trajectory
        The run with ``signals["head_error"]``, ``meta["criteria"]`` (D and R every
        :data:`CRITERIA_EVERY` samples) and its summary (head errors, R_min, D_min,
        g_drift, final head pose).
    """
    params = params or tracking_params()
    snake = Snake(params)
    reference = head_first_reference()
    controller = LyapunovController(snake, reference, options=options, **controller_options)
    traj = simulate(snake, controller, initial_state(params), t_final, progress=progress,
                    meta={"reference": REFERENCE, "k_shape": controller.k_shape,
                          "lam": controller.lam, "lam_shape": controller.lam_shape})
    return summarize_tracking(traj, snake, reference, error_window, controller="lyapunov")


def summarize_tracking(traj: Trajectory, snake: Snake, line: Any,
                       error_window: float | None, **summary: Any) -> Trajectory:
    """Fill a line run's head error, criteria and summary (``summary`` first), as run_tracking."""
    params = snake.params
    error = head_position_error(traj, line)
    t_c, d, r = criteria_along(traj, every=CRITERIA_EVERY)
    g = conserved_quantity_along(snake, traj.q, traj.dq)
    traj.signals["head_error"] = error
    traj.meta["criteria"] = {"t": t_c.tolist(), "D": d.tolist(), "R": r.tolist()}
    errors = head_error_summary(traj, error, start=error_window)
    traj.summary.update({
        **summary, "c_x": params.c_x, "c_y": params.c_y,
        "passive": list(params.passive), **errors,
        "R_min": float(r.min()), "D_min": float(d.min()),
        "body_length": params.body_length,
        "g_drift": float(np.abs(g - g[0]).max()),
        "final_head": traj.q[-1, :3].tolist(),
    })
    return traj


def plot_tracking(traj: Trajectory, folder: Path, stem: str) -> dict[str, Path]:
    """Snapshots along the path (Figs. 13, 16), D and R (Figs. 14, 17), head against the
    reference: key ("motion", "criteria", "head") -> ``folder/<stem>_<key>.png``."""
    import matplotlib.pyplot as plt

    from ..viz.plots import plot_criteria, plot_head_path, save_figure

    paths = {k: Path(folder) / f"{stem}_{k}.png" for k in ("motion", "criteria", "head")}
    joints = ", ".join(str(k) for k in traj.params.passive)
    passive = f", joint {joints} passive (x)" if traj.params.passive else ""
    plot_head_path(traj, np.column_stack([0.1 * traj.t, np.zeros(len(traj))]), paths["motion"],
                   snapshots=7, title=f"Head tracking, snapshots every {traj.t_end / 6:.0f} s"
                   f"{passive}")

    crit = traj.meta["criteria"]
    plot_criteria(crit["t"], crit["D"], crit["R"], paths["criteria"],
                  f"Manipulability criteria along the run (R min {min(crit['R']):.2e})",
                  tilde="~" if traj.params.passive else "")

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
