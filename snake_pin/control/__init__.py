"""Head-trajectory controllers sharing the interface of :class:`Controller`."""

from .base import Controller, OpenLoop
from .pfl import PFLController
from .reference import LinearReference

__all__ = ["Controller", "LinearReference", "OpenLoop", "PFLController"]
