"""Head-trajectory controllers sharing the interface of :class:`Controller`."""

from .base import Controller, OpenLoop
from .los import LOSController, LOSParams
from .lyapunov import LyapunovController
from .pfl import PFLController
from .quasistatic import QuasiStaticLyapunovController
from .reference import LinearReference, head_first_reference

__all__ = ["Controller", "LOSController", "LOSParams", "LinearReference", "LyapunovController",
           "OpenLoop", "PFLController", "QuasiStaticLyapunovController", "head_first_reference"]
