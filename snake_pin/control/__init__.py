"""Head-trajectory controllers sharing the interface of :class:`Controller`."""

from .base import Controller, OpenLoop
from .los import LOSController, LOSParams
from .lyapunov import LyapunovController, LyapunovOptions
from .mpc import MPCController, MPCOptions
from .pfl import PFLController, PFLOptions
from .quasistatic import QuasiStaticLyapunovController, QuasiStaticOptions
from .reference import LinearReference, head_first_reference

__all__ = ["Controller", "LOSController", "LOSParams", "LinearReference", "LyapunovController",
           "LyapunovOptions", "MPCController", "MPCOptions", "OpenLoop", "PFLController",
           "PFLOptions", "QuasiStaticLyapunovController", "QuasiStaticOptions",
           "head_first_reference"]
