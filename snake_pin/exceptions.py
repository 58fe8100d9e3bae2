"""The package's error hierarchy: every error snake_pin raises on purpose is a SnakePinError.

One more class sits beside it: :class:`RunInterrupted`, a ``KeyboardInterrupt`` (so a
bare ``except Exception`` never swallows Ctrl-C) that carries what an interrupted run
had computed.
"""

from __future__ import annotations

from typing import Any

__all__ = ["ConfigurationError", "ParameterError", "PathFileError", "RobotFileError",
           "RunInterrupted", "SingularPostureError", "SnakePinError", "StudyError",
           "TrajectoryFileError"]


class SnakePinError(Exception):
    """Base class of every error raised on purpose by snake_pin."""


class ParameterError(SnakePinError, ValueError):
    """A robot, controller or experiment parameter is out of its domain."""


class ConfigurationError(SnakePinError, ValueError):
    """A configuration or state vector has the wrong size, type or non-finite entries."""


class SingularPostureError(SnakePinError):
    """An algorithm is undefined at this posture (e.g. PFL where R = 0)."""


class TrajectoryFileError(SnakePinError):
    """A saved trajectory is missing, unreadable, hostile or belongs to another robot."""


class PathFileError(ParameterError):
    """A path file (TOML or CSV of waypoints) is missing, malformed or describes a bad path."""


class RobotFileError(SnakePinError):
    """A robot description (TOML robot file or URDF) is missing, malformed or unsupported."""


class StudyError(SnakePinError, ValueError):
    """A study file, its output folder or the scheduler address is not usable."""


class RunInterrupted(KeyboardInterrupt):
    """A run stopped by SIGINT/SIGTERM/SIGHUP (a ``KeyboardInterrupt``, as Ctrl-C is), with
    ``partial``, what it had computed.

    Parameters
    ----------
    message
        One line saying what was interrupted and when (e.g. ``"interrupted at t = 3.2 s"``).
    partial
        The partial result (a :class:`~snake_pin.trajectory.Trajectory`, a sweep, ...), or None.
    """

    def __init__(self, message: str, partial: Any = None) -> None:
        super().__init__(message)
        self.partial = partial

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else "interrupted"
