"""Report stage: the robot of Table 1, its parameters and drawings like Fig. 1."""

from __future__ import annotations

import numpy as np

from ..gaits import Serpenoid, arc, straight
from ..model import Snake
from ..params import SnakeParams
from ..runs.outputs import info
from ..viz.plots import plot_postures
from .context import Context

__all__: list[str] = []


def robot_stage(ctx: Context) -> None:
    """Parameters, model sizes and three postures with link frames."""
    params = ctx.params
    snake = Snake(params)
    n = params.n
    postures = [("straight (phi = 0)", straight(n)),
                (f"arc (phi_i = pi/{n})", arc(n, np.pi / n)),
                ("serpenoid (alpha = pi/4, T_s = 1.5)",
                 Serpenoid(n, np.pi / 4, 1.5).configuration())]
    figure = ctx.folder / "robot_postures.png"
    plot_postures(snake, postures, figure, title=f"{params.name}: link frames O_i - x_i y_i")
    sec = ctx.report.section("robot", f"Robot '{params.name}'")
    sec.text("Generalised coordinates q = [x_h, y_h, theta_1, phi_1..phi_{n-1}] (paper "
             "coordinates; in Pinocchio a chain of three single-DoF root joints PX -> PY -> "
             "RZ). Links are numbered from the head; each link frame sits at its front end "
             "with x towards the tail."
             + ("" if params.uniform else " Per-link values are listed head first."))
    sec.table(["quantity", "value"], info_rows(params, snake))
    sec.figure(figure, "Postures of the robot with the link frames (red: x_i along the link, "
               "blue: y_i), head in orange, like Fig. 1")
    sec.numbers.update(info(params, snake))


def info_rows(params: SnakeParams, snake: Snake) -> list[list[object]]:
    """Rows of the parameter table: lists as plain text, the passive joints as a list of
    joints or "none"."""
    rows: list[list[object]] = []
    for key, value in info(params, snake).items():
        if key == "passive":
            value = ", ".join(map(str, params.passive)) or "none"
        elif isinstance(value, list):
            value = ", ".join(f"{v:.6g}" if isinstance(v, float) else str(v) for v in value)
        rows.append([key, value])
    return rows
