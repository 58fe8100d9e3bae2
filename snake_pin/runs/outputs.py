"""What the command line and the report write of an analysis (:mod:`snake_pin.sweeps` and
:mod:`snake_pin.singular` return data): a robot's facts, the files of a sweep and of a
singular-posture search.
"""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._io import atomic_group
from .._json import json_text
from ..gaits import straight
from ..model import Snake
from ..params import SnakeParams
from ..singular import SingularSearch
from ..sweeps import Sweep
from ..viz.plots import plot_postures, png_bytes

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__: list[str] = []


def write_sweep(result: Sweep, folder: str | os.PathLike[str]) -> dict[str, Path]:
    """Write ``<stem>.csv``, ``.json`` and ``.png`` of a sweep into ``folder`` together or not
    at all (an empty sweep has no figure); key ("csv", "json", "png") -> path."""
    from ..viz.plots import plot_sweep

    folder = Path(folder)
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow([result.label, "D", "R"])
    writer.writerows(result.rows())
    names = {ext: f"{result.stem}.{ext}" for ext in ("csv", "json", "png")}
    png = png_bytes(plot_sweep(result)) if result.values.size else b""
    with atomic_group(folder) as group:
        group.write_bytes(names["csv"], buf.getvalue().encode())
        group.write_bytes(names["json"], (json_text(result.to_dict()) + "\n").encode())
        if result.values.size:
            group.write_bytes(names["png"], png, figure=True)
    return {ext: folder / name for ext, name in names.items()
            if ext != "png" or result.values.size}


def write_singular(search: SingularSearch, folder: str | os.PathLike[str]) -> list[Path]:
    """Write ``singular_postures.json`` and ``.png`` of a search into ``folder`` together or
    not at all; their paths."""
    png = png_bytes(draw_singular(search, None))
    with atomic_group(Path(folder)) as group:
        data = group.write_bytes("singular_postures.json",
                                 (json_text(search.to_dict(), indent=2) + "\n").encode())
        figure = group.write_bytes("singular_postures.png", png, figure=True)
    return [data, figure]

def draw_singular(search: SingularSearch, path: str | os.PathLike[str] | None,
                  limit: int = 5) -> Figure:
    """Draw the straight posture and the representatives of the ``limit`` largest families
    (saved to ``path`` and closed, else left open)."""
    snake = Snake(search.params)
    free = f", joint {search.free_joint} free" if search.free_joint else ""
    postures = [(f"straight: R = 0 exactly{free}", straight(search.params.n))]
    for fam in search.families[:limit]:
        postures.append((f"{'straight' if fam.straight else 'non-straight'}, R = {fam.R:.1e}"
                         f" ({fam.members} start{'' if fam.members == 1 else 's'})",
                         np.r_[0.0, 0.0, 0.0, fam.phi]))
    return plot_postures(snake, postures, path, frames=False,
                         title=f"Singular postures found (|phi_i| <= {search.bound:.2f}){free}")


def info(params: SnakeParams, snake: Snake | None = None) -> dict[str, object]:
    """The robot's fields, nq, nv, total mass, body length and half length l (equal links) or
    ``com_offsets``, as JSON data (``snake-pin info``, the report's robot table)."""
    snake = snake or Snake(params)
    data: dict[str, object] = {**params.to_dict(), "nq": snake.nq, "nv": snake.nv,
                               "total_mass": params.total_mass,
                               "body_length": params.body_length}
    if params.uniform:
        data["half_length"] = params.half_length
    else:
        data["com_offsets"] = params.com_offsets.tolist()
    return data
