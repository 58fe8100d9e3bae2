"""The controller family's interface ``controller(x, t) -> tau`` and the laws' shared parts.

``x = [q, dq]`` is the state in paper coordinates, ``tau`` the n - 1 joint torques (zero
on passive joints); per-step ``signals`` (e.g. R, V) are recorded beside the state.
"""

from __future__ import annotations

import abc
import inspect
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

from .._validation import brief, instance
from ..exceptions import ParameterError
from ..gaits import Serpenoid
from ..model import Snake
from ._options import merged
from .reference import LinearReference

__all__ = ["Controller", "OpenLoop", "ReferenceLaw"]

T = TypeVar("T")

#: Time-only terms are computed for this many coming calls at once (see TimeTerms).
_BLOCK = 1024


def gait_for(n: int, gait: Serpenoid | None, default: Serpenoid) -> Serpenoid:
    """``gait`` (``default`` for None), checked to be a serpenoid for n links (ParameterError)."""
    chosen = default if gait is None else instance(gait, Serpenoid, "gait")
    if chosen.n != n:
        raise ParameterError(f"gait is for {chosen.n} links, the robot has {n}")
    return chosen


def _reference_rows(reference: Callable[[float], tuple[np.ndarray, ...]], gait: Serpenoid,
                    times: np.ndarray) -> np.ndarray:
    """One row ``[w_r, phi_r, w_r', phi_r', w_r'', phi_r'']`` per time (a LinearReference and
    the serpenoid evaluated for all times at once)."""
    column = np.asarray(times, dtype=float)[:, None]
    if isinstance(reference, LinearReference):
        w_r, dw_r, ddw_r = (np.broadcast_to(part, (len(column), 3))
                            for part in reference(column))  # type: ignore[arg-type]
    else:
        w_r, dw_r, ddw_r = (np.array(part, dtype=float).reshape(len(column), 3) for part in
                            zip(*(reference(float(t)) for t in column[:, 0]), strict=True))
    phi_r, dphi_r, ddphi_r = gait.derivatives(column)  # type: ignore[arg-type]
    return np.hstack((w_r, phi_r, dw_r, dphi_r, ddw_r, ddphi_r))


def inherit_docstrings(cls: type) -> None:
    """Give ``cls``'s own public methods without a docstring the docstring of the base
    method they override (one text per method; numpydoc and Sphinx read ``__doc__``)."""
    for name, method in vars(cls).items():
        if not name.startswith("_") and inspect.isfunction(method) and method.__doc__ is None:
            method.__doc__ = next((base.__dict__[name].__doc__ for base in cls.__mro__[1:]
                                   if name in base.__dict__), None)


class TimeTerms:
    """A controller's time-only terms ``rows(times)``, served one time at a time: the
    announced times' (:meth:`prepare`) in vectorised blocks, any other alone."""

    def __init__(self, rows: Callable[[np.ndarray], np.ndarray]) -> None:
        self._rows = rows
        self.prepare(np.zeros(0))

    def prepare(self, times: np.ndarray) -> None:
        """The times of the coming calls, in order."""
        self._times = np.asarray(times, dtype=float)
        self._start = 0  # where the next block starts
        self._next = float(self._times[0]) if len(self._times) else None
        self._rows_left: list[np.ndarray] = []
        self._times_left: list[float] = []  # the block's times, popped from the end

    def __call__(self, t: float) -> np.ndarray:
        """The row at time t (read only)."""
        if t == self._next:
            rows_left = self._rows_left
            if not rows_left:  # t is times[start]: the block from there
                start, times = self._start, self._times
                block = self._rows(times[start:start + _BLOCK])
                rows_left = self._rows_left = list(block[::-1])  # popped from the end
                self._times_left = times[start + 1:start + 1 + _BLOCK].tolist()[::-1]
                self._start = start + _BLOCK
            times_left = self._times_left
            self._next = times_left.pop() if times_left else None
            return rows_left.pop()
        return self._rows(np.array([float(t)]))[0]


class Controller(abc.ABC):
    """Abstract base of every controller."""

    #: Short identifier used in file names and summaries.
    name: str = "controller"

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """A law's methods without a docstring take the ones written here, once."""
        super().__init_subclass__(**kwargs)
        inherit_docstrings(cls)

    def reset(self) -> None:  # noqa: B027 - optional hook, empty by default
        """Forget internal state (filters, integrators) before a new run."""

    def prepare(self, times: np.ndarray) -> None:  # noqa: B027 - optional hook
        """Learn the times of the coming calls (after :meth:`reset`; the output may not
        depend on it). Empty by default.

        Parameters
        ----------
        times : numpy.ndarray
            The run's sampling instants [s], shape (T,), in order.
        """

    @abc.abstractmethod
    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        """Joint torques (length n - 1) at state ``x`` and time ``t``."""

    def signals(self) -> dict[str, float]:
        """Diagnostics of the last call, recorded by the simulator (empty by default).

        Returns
        -------
        dict of str to float
            Signal name to value at the last call (e.g. ``R``, ``V``).
        """
        return {}

    def plant_acceleration(self, snake: object) -> np.ndarray | None:
        """q'' of ``snake`` at the last call's state under its torque, if the controller
        evaluated exactly that (the simulator's first RK4 stage), else None.

        Parameters
        ----------
        snake : object
            The plant being simulated (a :class:`~snake_pin.model.Snake` or a stand-in).

        Returns
        -------
        numpy.ndarray or None
            ``q''`` (length n + 2) of the last call, or None.
        """
        return None


class OpenLoop(Controller):
    """Torques as a function of time only: ``tau = schedule(t)``.

    Parameters
    ----------
    schedule : callable
        ``schedule(t) -> tau``: the n - 1 joint torques [N m] at time ``t`` [s].

    Raises
    ------
    ParameterError
        ``schedule`` is not callable.
    """

    name = "open_loop"

    def __init__(self, schedule: Callable[[float], np.ndarray]) -> None:
        if not callable(schedule):
            raise ParameterError(f"schedule must be a callable t -> tau, "
                                 f"got {brief(schedule)}")
        self.schedule = schedule

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        return np.asarray(self.schedule(t), dtype=float)


class ReferenceLaw(Controller):
    """Base of the laws that follow a head reference with a serpenoid gait.

    A subclass sets ``_law_time`` (reference rows to time-only terms); its buffers, if any,
    come from :meth:`_allocate`, again on unpickling (views do not survive pickling).
    """

    reference: Any
    gait: Serpenoid
    _time_row: TimeTerms
    _law_time: np.ndarray
    _buffers: Any = None
    _acceleration: np.ndarray | None
    _signals: dict[str, float]

    def _bind(self, snake: Snake, reference: Any, gait: Serpenoid | None,
              default_gait: tuple[float, float, float], options_type: type[T], options: Any,
              overrides: dict[str, object], default_reference: Callable[[], Any]) -> T:
        """Keep ``snake``, ``reference`` and ``gait`` (defaults for None) and return the options
        merged with ``overrides``; ParameterError for a bad one or a robot with no motor."""
        if not instance(snake, Snake, "snake").params.actuated:
            raise ParameterError("every joint is passive: there is nothing to control")
        self.snake = snake
        self.reference = (default_reference() if reference is None
                          else self.checked_reference(reference))
        self.gait = gait_for(snake.n, gait, Serpenoid(snake.n, *default_gait))
        self._acceleration = None  # the last call's q'' (None: failed)
        self._signals = {}
        self._time_row = TimeTerms(self._time_terms)
        return merged(options_type, options, overrides)

    @staticmethod
    def checked_reference(value: object, name: str = "reference") -> Any:
        """``value`` if it is callable (a head reference ``t -> (w_r, w_r', w_r'')``).

        Parameters
        ----------
        value, name : object, str
            The head reference, and the argument's name in the error message.

        Returns
        -------
        callable
            ``value``.

        Raises
        ------
        ParameterError
            ``value`` is not callable.
        """
        if not callable(value):
            raise ParameterError(f"{name} must be a head reference (a callable of time), "
                                 f"got {brief(value)}")
        return value

    def plant_acceleration(self, snake: object) -> np.ndarray | None:
        return self._acceleration if snake is self.snake else None

    def signals(self) -> dict[str, float]:
        return self._signals

    def prepare(self, times: np.ndarray) -> None:
        self._time_row.prepare(times)

    def _time_terms(self, times: np.ndarray) -> np.ndarray:
        """The time-only terms at ``times``, one row per time."""
        return _reference_rows(self.reference, self.gait, times) @ self._law_time

    def _allocate(self) -> Any:
        """The call's buffers (None: none)."""
        return None

    def __getstate__(self) -> dict[str, Any]:
        """The attributes to pickle: all but the buffers and the last call's outputs."""
        state = self.__dict__.copy()
        for name in ("_buffers", "_acceleration", "_signals"):
            state.pop(name, None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickled (or copied): the buffers are made again."""
        self.__dict__.update(state)
        self._acceleration = None
        self._signals = {}
        self._buffers = self._allocate()
