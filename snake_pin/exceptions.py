"""The package's error hierarchy: every error snake_pin raises on purpose is a SnakePinError."""

from __future__ import annotations

__all__ = [
    "ConfigurationError",
    "ParameterError",
    "SingularPostureError",
    "SnakePinError",
    "TrajectoryFileError",
]


class SnakePinError(Exception):
    """Base class of every error raised on purpose by snake_pin."""


class ParameterError(SnakePinError, ValueError):
    """A robot, controller or experiment parameter is out of its domain."""


class ConfigurationError(SnakePinError, ValueError):
    """A configuration or state vector has the wrong size or non-finite entries."""


class SingularPostureError(SnakePinError):
    """An algorithm is undefined at this posture (e.g. PFL where R = 0)."""


class TrajectoryFileError(SnakePinError):
    """A saved trajectory is missing, unreadable or belongs to another robot."""
