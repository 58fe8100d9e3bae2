"""The controller family's interface: ``controller(x, t) -> tau``.

``x = [q, dq]`` is the full state (length 2(n + 2)) in paper coordinates and ``tau`` the
n - 1 joint torques (entries of passive joints are ignored by the plant and set to zero
by well-behaved controllers). Controllers may expose per-step diagnostic ``signals``
(e.g. R, V) which :func:`snake_pin.sim.simulate` records beside the state.
"""

from __future__ import annotations

import abc
from collections.abc import Callable

import numpy as np

from ..exceptions import ParameterError
from ..gaits import Serpenoid

__all__ = ["Controller", "OpenLoop", "gait_for"]


def gait_for(n: int, gait: Serpenoid | None, default: Serpenoid) -> Serpenoid:
    """``gait`` (or ``default``) after checking it is a serpenoid for n links."""
    chosen = default if gait is None else gait
    if chosen.n != n:
        raise ParameterError(f"gait is for {chosen.n} links, the robot has {n}")
    return chosen


class Controller(abc.ABC):
    """Abstract base of every controller."""

    #: Short identifier used in file names and summaries.
    name: str = "controller"

    def reset(self) -> None:  # noqa: B027 - optional hook, empty by default
        """Forget internal state (filters, integrators) before a new run."""

    @abc.abstractmethod
    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        """Joint torques (length n - 1) at state ``x`` and time ``t``."""

    def signals(self) -> dict[str, float]:
        """Diagnostics of the last call, recorded by the simulator (empty by default)."""
        return {}


class OpenLoop(Controller):
    """Torques as a function of time only: ``tau = schedule(t)``."""

    name = "open_loop"

    def __init__(self, schedule: Callable[[float], np.ndarray]) -> None:
        self.schedule = schedule

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        return np.asarray(self.schedule(t), dtype=float)
