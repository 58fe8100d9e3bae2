"""``snake-pin reproduce``: run every report stage in order and write the report."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..params import SnakeParams
from ..report import Report

__all__ = ["Context", "reproduce", "stages"]


@dataclass
class Context:
    """What every stage gets: the output folder, the robot, the report, options."""

    folder: Path
    params: SnakeParams
    report: Report
    quick: bool = False
    options: dict[str, Any] = field(default_factory=dict)


def stages() -> list[tuple[str, Callable[[Context], None]]]:
    """The report stages in order (imported lazily: each pulls in its own tools)."""
    from .engine import engine_stage
    from .integrability import integrability_stage
    from .manipulability import manipulability_stage
    from .pfl import pfl_stage
    from .robot import robot_stage
    from .tracking import tracking_stage

    return [("robot", robot_stage), ("manipulability", manipulability_stage),
            ("integrability", integrability_stage), ("pfl", pfl_stage),
            ("tracking", tracking_stage), ("engine", engine_stage)]


def reproduce(folder: str | Path, params: SnakeParams | None = None, *, quick: bool = False,
              only: list[str] | None = None, log: Callable[[str], None] = print) -> Path:
    """Run the stages (all, or those named in ``only``) and write ``folder/index.html``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    params = params or SnakeParams.table1()
    report = Report(f"snake_pin report: {params.name} robot "
                    "(Ariizumi & Tanaka, manipulability without a lateral constraint)")
    ctx = Context(folder=folder, params=params, report=report, quick=quick)
    chosen = [(name, fn) for name, fn in stages() if only is None or name in only]
    timings = {}
    for index, (name, fn) in enumerate(chosen, start=1):
        log(f"[{index}/{len(chosen)}] {name} ...")
        start = time.perf_counter()
        fn(ctx)
        timings[name] = time.perf_counter() - start
        log(f"[{index}/{len(chosen)}] {name} done in {timings[name]:.1f} s")
    report.section("timing", "Timing").table(
        ["stage", "wall time [s]"], [[k, v] for k, v in timings.items()]).numbers.update(timings)
    return report.write(folder)
