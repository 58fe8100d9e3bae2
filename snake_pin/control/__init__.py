"""Head-trajectory controllers sharing the interface of :class:`Controller`."""

from .base import Controller, OpenLoop
from .lyapunov import LyapunovController, head_first_reference
from .pfl import PFLController
from .quasistatic import QuasiStaticLyapunovController
from .reference import LinearReference

__all__ = ["Controller", "LinearReference", "LyapunovController", "OpenLoop", "PFLController",
           "QuasiStaticLyapunovController", "head_first_reference"]
