"""Report stage: manipulability along posture families, the (alpha, T_s) map, shapes of
Figs. 6-7, and the singular-posture search over the whole joint box (its files and
drawing from :mod:`snake_pin.runs.outputs`)."""

from __future__ import annotations

import numpy as np

from ..gaits import Serpenoid
from ..model import Snake
from ..runs.outputs import draw_singular, write_sweep
from ..singular import find_singular_postures
from ..sweeps import FAMILIES, r_map, sweep
from ..viz.plots import plot_postures, plot_r_maps
from .context import Context

__all__: list[str] = []

#: The paper's example of a free joint.
FREE_JOINT = 5


def manipulability_stage(ctx: Context) -> None:
    """Figs. 2-9, the R map, and the singular-posture search."""
    snake = Snake(ctx.params.replace(passive=()))
    folder = ctx.folder
    points = 61 if ctx.quick else 201
    sec = ctx.report.section("manipulability", "Dynamic manipulability (Sections III-IV)")
    sec.text("D is the smallest singular value of (H11 - H12 H22^-1 H21)^-1 H12 H22^-1 "
             "(eq. 30), computed as the (w, phi) block of H^-1 from Pinocchio; R is the "
             "smallest singular value of H12 (eq. 31). With joint 5 free, D~ and R~ of eq. "
             "(42). Zeros are drawn at the bottom of the log axes.")
    rows = []
    for family, (_, _, description) in FAMILIES.items():
        for free in (None, FREE_JOINT):
            result = sweep(snake, family, free_joint=free, points=points)
            paths = write_sweep(result, folder)
            figure_no = {"arc": (2, 3), "alpha": (4, 8), "ts": (5, 9)}[family][free is not None]
            shown = description.split(" (Fig")[0]  # the figure numbers are the caption's
            sec.figure(paths["png"], f"Fig. {figure_no}: {shown}"
                       + (f", joint {free} free" if free else ""))
            nonzero = result.values != 0
            rows.append([family, free or "-", result.zeros().tolist(),
                         float(result.R[nonzero].min()), float(result.D[nonzero].min())])
            sec.numbers[result.stem] = {"zeros": result.zeros().tolist(),
                                        "R_min_nonzero": rows[-1][3]}
    sec.table(["family", "free joint", "R = 0 at", "smallest R elsewhere",
               "smallest D elsewhere"], rows)

    shapes = ctx.folder / "serpenoid_shapes.png"
    n = snake.n
    postures = [(f"T_s = 1.5, alpha = pi/{k}", Serpenoid(n, np.pi / k, 1.5).configuration())
                for k in (16, 8, 4, 2)]
    postures += [(f"alpha = pi/4, T_s = {t}", Serpenoid(n, np.pi / 4, t).configuration())
                 for t in (0.5, 1.0, 1.5, 2.0)]
    plot_postures(snake, postures, shapes, frames=False)
    sec.figure(shapes, "Figs. 6 and 7: serpenoid shapes")

    maps = [r_map(snake), r_map(snake, free_joint=FREE_JOINT)]
    map_png = folder / "r_map.png"
    plot_r_maps(maps, map_png)
    sec.figure(map_png, "Beyond the paper: log10 R over (alpha, T_s), without and with joint 5 "
               "free (batch path). Only the edges alpha = 0 and T_s = 0 are singular; the "
               "valleys are small but non-zero R.")
    sec.numbers["r_map_min_interior"] = [float(m.R[1:, 1:].min()) for m in maps]

    _singular_section(ctx, snake)


def _singular_section(ctx: Context, snake: Snake) -> None:
    sec = ctx.report.section("singular", "Singular postures over the whole joint box")
    starts = 60 if ctx.quick else 200
    rows = []
    for free in (None, FREE_JOINT):
        search = find_singular_postures(snake.params, starts=starts, free_joint=free)
        stem = "singular" + (f"_free{free}" if free else "")
        png = ctx.folder / f"{stem}.png"
        draw_singular(search, png)
        zeros = int((search.minima_R <= search.threshold).sum())
        rows.append([free or "-", starts, zeros, len(search.families),
                     len(search.non_straight), search.threshold,
                     float(search.minima_R.min())])
        sec.figure(png, "Representatives of the singular families found"
                   + (f" with joint {free} free" if free else ""))
        sec.numbers[stem] = search.to_dict()
        if free is None and search.non_straight:
            main = max(search.non_straight, key=lambda f: f.members)
            sec.text(
                f"Without a free joint, {zeros} of {starts} random starts ended at R <= "
                f"{search.threshold:.2g} (1e-6 of the typical R {search.R_typical:.3g}), "
                f"{main.members} of them on one connected family. Along it the joint angles "
                f"span {np.round(main.span, 2).tolist()} rad: phi_1 is free and phi_{snake.n - 1}"
                " moves while the middle joints stay almost fixed, so the family is a "
                "two-parameter sheet. This is what a dimension count predicts: 3 x (n - 1) "
                "matrices of rank <= 2 have codimension n - 3 = 7 in the 9-dimensional joint "
                "space, leaving a 2-dimensional singular set. Non-straight singular postures "
                "therefore do exist within |phi_i| <= pi/2; the paper's families (arcs, "
                "serpenoids) simply miss them. Pinocchio's CRBA route confirms R ~ 1e-14 and "
                "D ~ 1e-10 (Theorem 1) at these postures.")
    sec.table(["free joint", "starts", "minima with R = 0", "clusters", "non-straight",
               "threshold", "smallest R found"], rows)
    sec.text(f"With joint {FREE_JOINT} free, H12~ is 4 x 8 and rank-deficient matrices have "
             "codimension 5, so the singular set is 4-dimensional: most starts reach R~ = 0 "
             "and single-linkage clustering of so few samples splits it into many pieces; "
             "the clusters are samples of one large set, not separate families.")
