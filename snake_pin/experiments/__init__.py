"""The experiments as report stages of ``snake-pin reproduce``: each ``stage(context)`` runs
one experiment, writes its files into ``context.folder`` and adds a section to
``context.report`` (:doc:`/architecture`).
"""

from .context import Context
from .reproduce import reproduce, stages

__all__ = ["Context", "reproduce", "stages"]
