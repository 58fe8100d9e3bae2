"""Matplotlib figures: robot drawings like Fig. 1 and time series of a run.

Every plot function returns its figure; given a ``path`` it writes the PNG whole or not at
all and closes the figure (:func:`save_figure`), else it keeps the figure open.
"""

from __future__ import annotations

import io
import os
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from .._io import atomic_write_bytes

if TYPE_CHECKING:
    from ..model import Snake
    from ..trajectory import Trajectory

__all__ = ["draw_snake"]

BODY_COLOR = "#228b22"
HEAD_COLOR = "#d9541a"
PASSIVE_COLOR = "#1f4fd1"


def png_bytes(fig: plt.Figure, dpi: int = 110) -> bytes:
    """``fig`` as PNG bytes, then closed; a figure without a layout engine gets the
    constrained one (one draw, where a tight bounding box takes two)."""
    if fig.get_layout_engine() is None:
        fig.set_layout_engine("constrained")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    return buf.getvalue()


def save_figure(fig: plt.Figure, path: str | os.PathLike[str] | None) -> plt.Figure:
    """Save ``fig`` as PNG to ``path`` (whole or not at all) and close it (:func:`png_bytes`)."""
    if path is not None:
        atomic_write_bytes(path, png_bytes(fig))
    return fig


def draw_snake(ax: plt.Axes, snake: Snake, q: np.ndarray, *, frames: bool = False,
               color: str = BODY_COLOR, alpha: float = 1.0, label: str | None = None) -> None:
    """Draw the snake at ``q`` on ``ax``: links, head dot, passive joints as crosses.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw (its aspect is set equal).
    snake : Snake
        The robot.
    q : array_like, shape (n + 2,)
        Configuration ``[x_h, y_h, theta_1, phi_1 .. phi_{n-1}]`` [m, m, rad, rad...].
    frames : bool, optional
        Draw each link's frame ``O_i - x_i y_i`` at its CM (as in Fig. 1).
    color : str, optional
        Colour of the links.
    alpha : float, optional
        Opacity (below 1 the links are drawn thinner, for ghosts of earlier postures).
    label : str or None, optional
        Legend label of the body line.
    """
    points = snake.joint_points(q)
    width = 4.0 if alpha == 1.0 else 2.0
    ax.plot(points[:, 0], points[:, 1], "-", color=color, lw=width, alpha=alpha,
            solid_capstyle="round", label=label)
    ax.plot(points[1:-1, 0], points[1:-1, 1], "o", color="k", ms=2.5, alpha=alpha)
    ax.plot(points[0, 0], points[0, 1], "o", color=HEAD_COLOR, ms=7, alpha=alpha)
    for k in snake.params.passive:
        ax.plot(points[k, 0], points[k, 1], "x", color=PASSIVE_COLOR, ms=10, mew=2.5,
                alpha=alpha)
    if frames:
        poses = snake.link_poses(q)
        sizes = 0.6 * (0.5 * snake.params.link_lengths)  # each frame 0.3 of its own link
        for (x, y, th), size in zip(poses, sizes, strict=True):
            for (dx, dy), colour in (((np.cos(th), np.sin(th)), "#c0392b"),
                                     ((-np.sin(th), np.cos(th)), "#2874a6")):
                ax.arrow(x, y, size * dx, size * dy, color=colour, width=size * 0.06,
                         length_includes_head=True, zorder=4)
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.08)


def plot_postures(snake: Snake, postures: Sequence[tuple[str, np.ndarray]],
                  path: str | os.PathLike[str] | None = None, *, frames: bool = True,
                  title: str | None = None) -> plt.Figure:
    """Draw one panel per ``(label, q)``: the robot drawn with its link frames."""
    count = len(postures)
    cols = min(count, 3)
    rows = int(np.ceil(count / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.6 * rows), squeeze=False,
                             layout="constrained")
    for ax, (label, q) in zip(axes.flat, postures, strict=False):
        draw_snake(ax, snake, q, frames=frames)
        ax.set_title(label, fontsize=10)
        ax.set(xlabel="x [m]", ylabel="y [m]")
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[count:]:
        ax.axis("off")
    if title:
        fig.suptitle(title)
    return save_figure(fig, path)


def plot_trajectory(traj: Trajectory, path: str | os.PathLike[str] | None = None) -> plt.Figure:
    """Plot the head pose, the joint angles and the norm of the applied torques over time."""
    fig, axes = plt.subplots(3, 1, figsize=(8, 7.5), sharex=True, layout="constrained")
    for i, label in enumerate(("x_h [m]", "y_h [m]", "theta_1 [rad]")):
        axes[0].plot(traj.t, traj.q[:, i], label=label)
    axes[0].legend(loc="best", fontsize=8)
    axes[1].plot(traj.t, traj.q[:, 3:], lw=0.8)
    axes[1].set_ylabel("phi [rad]")
    from ..metrics import applied

    held = applied(traj)
    norm = np.linalg.norm(traj.tau[held], axis=1)
    if np.any(norm > 0):  # log scale; exact zeros are left out, not drawn at a floor
        axes[2].semilogy(traj.t[held], norm)
    else:
        axes[2].plot(traj.t[held], norm)
    axes[2].set(ylabel="||tau|| [N m]", xlabel="t [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    if traj.diverged:
        fig.suptitle(traj.reason, fontsize=9, color="firebrick")
    return save_figure(fig, path)


def plot_head_path(traj: Trajectory, reference: np.ndarray,
                   path: str | os.PathLike[str] | None = None, *, snapshots: int = 5,
                   title: str | None = None) -> plt.Figure:
    """Plot the head against its reference in the plane (x-y), with body snapshots."""
    from ..model import Snake

    reference = np.asarray(reference, dtype=float)
    fig, ax = plt.subplots(figsize=(8, 6), layout="constrained")
    ax.plot(reference[:, 0], reference[:, 1], "k--", lw=1, label="reference")
    ax.plot(traj.q[:, 0], traj.q[:, 1], color=HEAD_COLOR, lw=1.2, label="head")
    if len(traj):
        snake = Snake(traj.params)
        for k, t in enumerate(np.linspace(traj.t[0], traj.t_end, max(snapshots, 1))):
            i = min(int(np.searchsorted(traj.t, t)), len(traj) - 1)
            draw_snake(ax, snake, traj.q[i], alpha=0.3 + 0.7 * k / max(snapshots - 1, 1))
        ax.plot(reference[-1, 0], reference[-1, 1], "s", color="k", ms=5,
                label=f"reference at t = {traj.t_end:.3g} s")
    ax.set(xlabel="x [m]", ylabel="y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    text = title or "Head and reference"
    if traj.diverged:
        text += f"\n{traj.reason}"
    ax.set_title(text, fontsize=10, color="firebrick" if traj.diverged else "black")
    return save_figure(fig, path)


def plot_criteria(t: Any, d: Any, r: Any, path: str | os.PathLike[str] | None, title: str, *,
                  tilde: str = "", mark: Callable[[plt.Axes], None] | None = None) -> plt.Figure:
    """Plot D and R along a run, one log panel each; ``mark(ax)`` adds to both panels."""
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True, layout="constrained")
    for ax, values, name, color in zip(axes, (d, r), "DR", (PASSIVE_COLOR, BODY_COLOR),
                                       strict=True):
        ax.semilogy(t, values, color=color)
        ax.set_ylabel(name + tilde)
        ax.grid(alpha=0.3, which="both")
        if mark is not None:
            mark(ax)
    if axes[0].get_legend_handles_labels()[0]:
        axes[0].legend(fontsize=8)
    axes[1].set_xlabel("t [s]")
    fig.suptitle(title, fontsize=10)
    return save_figure(fig, path)


def plot_sweep(sweep: Any, path: str | os.PathLike[str] | None = None) -> plt.Figure:
    """Plot D and R against the swept parameter, log scale (zeros drawn at the floor)."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6), layout="constrained")
    suffix = f", joint {sweep.free_joint} free" if sweep.free_joint else ""
    for ax, name in zip(axes, "DR", strict=True):
        values = getattr(sweep, name)
        positive = values[values > 0]
        floor = positive.min() / 10 if positive.size else 1e-20
        ax.semilogy(sweep.values, np.maximum(values, floor), "-", color="#1f4fd1")
        zero = values <= 1e-9 * values.max()
        if np.any(zero):
            ax.semilogy(sweep.values[zero], np.full(zero.sum(), floor), "v", color="firebrick",
                        label="numerically 0")
            ax.legend(fontsize=8)
        ax.set(xlabel=sweep.label, ylabel=f"{name}{'~' if sweep.free_joint else ''}")
        ax.set_title(f"{name} along '{sweep.family}'{suffix}", fontsize=10)
        ax.grid(alpha=0.3, which="both")
    return save_figure(fig, path)


def plot_r_maps(maps: Sequence[Any], path: str | os.PathLike[str] | None = None
                ) -> plt.Figure:
    """Plot log10 R over (alpha, T_s), one panel per map."""
    fig, axes = plt.subplots(1, len(maps), figsize=(5.2 * len(maps), 4.2), squeeze=False,
                             layout="constrained")
    for ax, rmap in zip(axes[0], maps, strict=True):
        floor = 1e-8 * rmap.R.max()  # exact zeros (alpha = 0, T_s = 0) would swamp the scale
        image = ax.pcolormesh(rmap.alpha, rmap.ts, np.log10(np.maximum(rmap.R, floor)),
                              shading="auto", cmap="viridis")
        fig.colorbar(image, ax=ax, label="log10 R")
        ax.set(xlabel="alpha [rad]", ylabel="T_s")
        free = f", joint {rmap.free_joint} free" if rmap.free_joint else ""
        ax.set_title(f"R of the serpenoid{free}", fontsize=10)
    return save_figure(fig, path)
