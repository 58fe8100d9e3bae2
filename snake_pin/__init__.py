"""snake_pin: planar snake robots without a lateral constraint, on Pinocchio.

Implements Ariizumi & Tanaka, "Manipulability analysis of a snake robot without a
lateral constraint for head position control": the model in paper coordinates, its
closed form, dynamic manipulability, integrability, head controllers and experiments.
"""

from . import paper
from .control import Controller, OpenLoop
from .exceptions import (
    ConfigurationError,
    ParameterError,
    SingularPostureError,
    SnakePinError,
    TrajectoryFileError,
)
from .gaits import Serpenoid, arc, straight
from .model import Snake
from .params import SnakeParams
from .sim import Trajectory, simulate
from .urdf import build_urdf, write_urdf

__all__ = [
    "ConfigurationError",
    "Controller",
    "OpenLoop",
    "ParameterError",
    "Serpenoid",
    "SingularPostureError",
    "Snake",
    "SnakeParams",
    "SnakePinError",
    "Trajectory",
    "TrajectoryFileError",
    "arc",
    "build_urdf",
    "paper",
    "simulate",
    "straight",
    "write_urdf",
]
__version__ = "0.1.0"
