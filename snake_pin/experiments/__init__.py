"""Experiments of the paper (and beyond) as report stages of ``snake-pin reproduce``.

Each stage is a function ``stage(context) -> None`` that runs one experiment, writes its
files into ``context.folder`` and adds a section to ``context.report``. The stages are
independent of each other; the runs they share with the command line are in
:mod:`snake_pin.runs`.
"""

from .context import Context
from .reproduce import reproduce, stages

__all__ = ["Context", "reproduce", "stages"]
