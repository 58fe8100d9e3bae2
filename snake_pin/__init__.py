"""snake_pin: planar snake robots without a lateral constraint, on Pinocchio.

Implements Ariizumi & Tanaka, "Manipulability analysis of a snake robot without a lateral
constraint for head position control", and more. Heavy modules load on first use of a
name, so ``import snake_pin`` and the command line start quickly.
"""

from __future__ import annotations

import importlib
import os
from importlib import metadata as _metadata
from typing import Any

# Pinocchio's parallel algorithms use OpenMP, whose default spinning wait makes two threads
# slower than one when the other core is busy. libgomp reads this once, when it loads, so
# it is set before anything imports Pinocchio (a user's own value wins).
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from .params import SnakeParams

#: Module -> the public names it defines (imported lazily).
_LAZY_MODULES = {
    ".exceptions": ("ConfigurationError", "ParameterError", "PathFileError", "RobotFileError",
                    "RunInterrupted", "SingularPostureError", "SnakePinError", "StudyError",
                    "TrajectoryFileError"),
    ".paper": ("paper",),
    ".control": ("Controller", "LOSController", "LinearReference", "LyapunovController",
                 "LyapunovOptions", "MPCController", "MPCOptions", "OpenLoop", "PFLController",
                 "PFLOptions", "head_first_reference"),
    ".gaits": ("Serpenoid", "arc", "straight"),
    ".manipulability": ("Manipulability", "dynamic_manipulability", "manipulability"),
    ".paths": ("PathReference", "along_track", "cross_track_error", "load_path"),
    ".model": ("DynamicsDerivatives", "Snake"),
    ".robot_file": ("load_robot", "read_robot_file", "read_urdf", "robot_paths",
                    "write_robot_file"),
    ".trajectory": ("Trajectory",), ".sim": ("simulate",), ".urdf": ("build_urdf", "write_urdf"),
}
_LAZY = {name: module for module, names in _LAZY_MODULES.items() for name in names}

__all__ = ["ConfigurationError", "Controller", "DynamicsDerivatives", "LOSController",
           "LinearReference", "LyapunovController", "LyapunovOptions", "MPCController",
           "MPCOptions", "Manipulability", "OpenLoop", "PFLController", "PFLOptions",
           "ParameterError", "PathFileError", "PathReference", "RobotFileError", "RunInterrupted",
           "Serpenoid", "SingularPostureError", "Snake", "SnakeParams", "SnakePinError",
           "StudyError", "Trajectory", "TrajectoryFileError", "along_track", "arc", "build_urdf",
           "cross_track_error", "dynamic_manipulability", "head_first_reference", "load_path",
           "load_robot", "manipulability", "paper", "read_robot_file", "read_urdf", "robot_paths",
           "simulate", "straight", "write_robot_file", "write_urdf"]
try:  # one version number: pyproject.toml's, read from the installed metadata
    __version__: str = _metadata.version("snake_pin")
except _metadata.PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'snake_pin' has no attribute {name!r}")
    loaded = importlib.import_module(module, __name__)
    value = loaded if name == "paper" else getattr(loaded, name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
