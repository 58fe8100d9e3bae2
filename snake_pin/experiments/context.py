"""What a report stage is given: :class:`Context`, made by the runner
(:mod:`snake_pin.experiments.reproduce`) so that the stages never import it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..params import SnakeParams
from ..report import Report
from ..runs.parallel import SharedCluster

__all__ = ["Context"]


@dataclass
class Context:
    """What every stage gets: the output folder, the robot, the report, options.

    Parameters
    ----------
    folder
        The staging folder the stage writes its files into.
    params
        The report's robot.
    report
        The report the stage adds its section to.
    quick
        Shorter runs (``--quick``).
    options
        What stages pass on to later ones (e.g. the tracking runs' files).
    cluster
        The report's Dask cluster for the stages' jobs; None: each call starts its own.
    """

    folder: Path
    params: SnakeParams
    report: Report
    quick: bool = False
    options: dict[str, Any] = field(default_factory=dict)
    cluster: SharedCluster | None = None
