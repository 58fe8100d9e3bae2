"""The closed loop: :func:`closed_loop` runs a controller against a :class:`Plant`, each
torque checked and held over its period; how a run ends: :doc:`/architecture` (statuses).
"""

from __future__ import annotations

import abc
import functools
from collections.abc import Mapping
from typing import Any

import numpy as np
from threadpoolctl import ThreadpoolController

from ._validation import integer, one_line
from .control.base import Controller, inherit_docstrings
from .exceptions import ParameterError, RunInterrupted, SnakePinError
from .params import SnakeParams
from .trajectory import Trajectory

__all__ = ["MAX_STEPS", "Plant", "closed_loop"]

#: Most control steps one run may take (t_final <= 1000 s at the default 1 kHz).
MAX_STEPS = 1_000_000


def closed_loop(plant: Plant, controller: Controller, x0: np.ndarray, steps: int, *,
                progress: bool = False, meta: Mapping[str, Any] | None = None,
                label: str | None = None, record_signals: bool = True) -> Trajectory:
    """The closed loop: ``steps`` control periods of ``plant`` under ``controller``.

    Parameters
    ----------
    plant : Plant
        The robot being controlled.
    controller : Controller
        The law, called at each instant of :meth:`Plant.times`.
    x0 : numpy.ndarray
        The initial state, as :meth:`Plant.reset` takes it.
    steps : int
        Control periods, at most :data:`MAX_STEPS`.
    progress, label : optional
        Show a tqdm bar on a terminal, and its label (default: the controller's name).
    meta, record_signals : optional
        The trajectory's ``meta``; record :meth:`~snake_pin.control.Controller.signals`.

    Returns
    -------
    Trajectory
        The samples up to the last good one, with the run's status and reason.

    Raises
    ------
    RunInterrupted
        On KeyboardInterrupt; ``.partial`` holds every completed sample.
    ParameterError
        ``steps`` is not a whole number in 0 .. :data:`MAX_STEPS`, or memory is short.
    """
    steps = integer(steps, "steps", low=0, high=MAX_STEPS)
    ctrl, nq, n_tau = controller, plant.nq, plant.params.n - 1
    try:
        xs = np.zeros((steps + 1, 2 * nq))
        taus = np.zeros((steps + 1, n_tau))
    except MemoryError:
        raise ParameterError(f"not enough memory for {steps + 1} samples") from None
    times, ts = plant.times(steps)
    plant.reset(x0, xs[0])
    x = xs[0]
    check_torque, torque_shape = _TorqueCheck(n_tau), (n_tau,)
    # a plant that checks whether the torque is finite (with the new state) refuses a
    # non-finite one as if it had been checked first: no torque, no signals at t
    late_check = plant.checks_torque
    signals: dict[str, np.ndarray] = {}
    status, reason = "completed", ""
    good = 1  # samples 0 .. good - 1 are recorded whole; updated last, after each sample
    bar = None

    def refuse(k: int, t: float, known: int) -> str:
        """Why sample k failed, its torque and signals undone (``known``: signals before)."""
        taus[k] = 0.0
        for name in list(signals)[known:]:
            del signals[name]
        for series in signals.values():
            series[k] = np.nan
        return f"controller returned a non-finite torque at t = {t:.4f} s"

    def collect(run_status: str, run_reason: str) -> Trajectory:
        """The good samples as a trajectory."""
        return Trajectory(t=ts[:good].copy(), q=xs[:good, :nq].copy(),
                          dq=xs[:good, nq:].copy(), tau=taus[:good].copy(),
                          params=plant.params,
                          signals={k: v[:good].copy() for k, v in signals.items()},
                          status=run_status, reason=run_reason, meta=dict(meta or {}))

    try:
        bar = _progress(steps, bool(progress), label or ctrl.name)
        try:
            ctrl.reset()
            ctrl.prepare(times)
        except Exception as exc:
            status, reason = "failed", _failure(0.0, exc)
        # the controller's methods, found once
        call = ctrl.__call__
        signals_of = ctrl.signals if record_signals else dict
        plant_acceleration = ctrl.plant_acceleration if plant.takes_first_stage else None
        robot, step = plant.snake, plant.step
        # one BLAS thread for the run's tiny matrices, entered once (not per step)
        with _thread_pools().limit(limits=1):
            for k, t in enumerate(times.tolist() if status == "completed" else ()):
                tau, known = None, len(signals)
                try:
                    raw = call(x, t)
                    if late_check and type(raw) is _NDARRAY and raw.dtype is _FLOAT \
                            and raw.shape == torque_shape:
                        tau = raw  # whether it is finite: checked with the new state
                    else:
                        checked, problem = check_torque(raw)
                        if checked is None:
                            status, reason = "failed", f"{problem} at t = {t:.4f} s"
                            break
                        tau = checked
                    for name, value in signals_of().items():
                        series = signals.get(name)
                        if series is None:
                            series = signals[name] = np.full(steps + 1, np.nan)
                        series[k] = value
                    first = plant_acceleration(robot) if plant_acceleration else None
                except Exception as exc:
                    if tau is not None and not np.isfinite(tau).all():
                        status, reason = "failed", refuse(k, t, known)
                    else:
                        status, reason = "failed", _failure(t, exc)
                    break
                taus[k] = tau
                after = xs[k + 1]
                try:
                    problem = step(tau, first, after, t)
                except (SnakePinError, ArithmeticError, np.linalg.LinAlgError) as exc:
                    problem = f"the dynamics failed ({type(exc).__name__}: " \
                              f"{one_line(str(exc))})"
                if problem:
                    if late_check and not np.isfinite(tau).all():
                        status, reason = "failed", refuse(k, t, known)
                        break
                    status = "diverged"
                    reason = f"diverged at t = {ts[k + 1]:.4f} s: {problem}"
                    break
                x = after
                good = k + 2
                if bar is not None and k % 100 == 0:
                    bar.update(min(100, steps - bar.n))
        if bar is not None:
            bar.close()
        # Samples 0..good-1 are good. tau[good-1] is the torque held after the last one:
        # on divergence the one applied when the state blew up (kept as evidence); at the
        # end of a completed run, or when the controller failed, none was applied: zero.
        return collect(status, reason)
    except KeyboardInterrupt:
        if bar is not None:
            bar.close()
        # Samples 0 .. good - 1 are whole; the torque after the last one was not (fully)
        # applied, so it is recorded as zero, as at the end of a completed run.
        taus[good - 1] = 0.0
        partial = collect("interrupted", f"interrupted at t = {ts[good - 1]:.4f} s")
        raise RunInterrupted(partial.reason, partial=partial) from None


class Plant(abc.ABC):
    """What :func:`closed_loop` steps: one control period of a robot under a held torque.

    Attributes
    ----------
    nq, params
        n + 2, and the robot's parameters (the trajectory's).
    snake
        The model the plant integrates (what the laws' ``plant_acceleration`` is asked of).
    checks_torque, takes_first_stage
        Whether :meth:`step` finds a non-finite torque itself; takes the law's q'' as stage 1.
    """

    nq: int
    params: SnakeParams
    snake: Any = None
    checks_torque: bool = False
    takes_first_stage: bool = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """A plant's methods without a docstring take the ones written here, once."""
        super().__init_subclass__(**kwargs)
        inherit_docstrings(cls)

    @abc.abstractmethod
    def times(self, steps: int) -> tuple[np.ndarray, np.ndarray]:
        """The run's instants: of the controller's calls, and of the samples.

        Parameters
        ----------
        steps : int
            Control periods.

        Returns
        -------
        tuple of numpy.ndarray
            The ``steps`` calls' times and the ``steps + 1`` samples' times [s].
        """

    @abc.abstractmethod
    def reset(self, x0: np.ndarray, out: np.ndarray) -> None:
        """Start a run from ``x0`` (length 2(n + 2)); write the first sample into ``out``.

        Parameters
        ----------
        x0, out : numpy.ndarray
            The initial state, and where the first sample ``[q, q']`` goes.
        """

    @abc.abstractmethod
    def step(self, tau: np.ndarray, first: np.ndarray | None, out: np.ndarray,
             t: float) -> str:
        """Advance one control period from time ``t`` under ``tau``, held.

        Parameters
        ----------
        tau : numpy.ndarray
            Joint torques (n - 1); finite unless :attr:`checks_torque`.
        first : numpy.ndarray or None
            q'' at the current state under ``tau``, if known (:attr:`takes_first_stage`).
        out : numpy.ndarray
            Where the new state ``[q, q']`` goes.
        t : float
            The time of the current state [s].

        Returns
        -------
        str
            What is wrong with the new state or the torque ("" when nothing).
        """


def _torque(raw: object, size: int) -> tuple[np.ndarray | None, str]:
    """The controller's output as ``size`` finite floats, or None and what is wrong."""
    tau = raw if type(raw) is np.ndarray else np.asarray(raw)
    if tau.dtype.kind not in "fiu" or tau.dtype.names is not None:
        return None, f"controller returned a torque of dtype {tau.dtype}, not numbers"
    if tau.shape != (size,):
        if tau.ndim == 0 and size == 1:
            tau = tau.reshape(1)
        elif tau.ndim <= 1:
            return None, (f"controller returned {tau.size} torque{'' if tau.size == 1 else 's'}"
                          f", expected {size}")
        else:
            return None, f"controller returned torques of shape {tau.shape}, expected {size}"
    if tau.dtype != np.float64:
        tau = tau.astype(float)
    if not np.isfinite(tau).all():
        return None, "controller returned a non-finite torque"
    return tau, ""


class _TorqueCheck:
    """:func:`_torque` for one run, with a cheap path for n - 1 finite float64 values."""

    def __init__(self, size: int) -> None:
        self._size, self._shape = size, (size,)
        self._finite = np.zeros(size, dtype=bool)
        self._all_finite = np.ones(size, dtype=bool).tobytes()

    def __call__(self, raw: object) -> tuple[np.ndarray | None, str]:
        if type(raw) is np.ndarray and raw.dtype is _FLOAT and raw.shape == self._shape and \
                np.isfinite(raw, self._finite).tobytes() == self._all_finite:
            return raw, ""
        return _torque(raw, self._size)


_FLOAT = np.dtype(np.float64)
# read once: numpy's module __getattr__ keeps Python from caching ``np.<name>`` lookups
_NDARRAY = np.ndarray


def _failure(t: float, exc: BaseException) -> str:
    """The reason of a run whose controller raised ``exc`` at t."""
    detail = one_line(str(exc))
    return f"controller failed at t = {t:.4f} s: {type(exc).__name__}" + \
        (f": {detail}" if detail else "")


@functools.cache
def _thread_pools() -> ThreadpoolController:
    """The process's BLAS/OpenMP pools, found once (not on every ``threadpool_limits``)."""
    return ThreadpoolController()


def _progress(total: int, enabled: bool, label: str):
    """A tqdm bar when ``enabled`` and stderr is a terminal (``disable=None``), else None."""
    if not enabled:
        return None
    from tqdm import tqdm

    bar = tqdm(total=total, desc=f"simulate {label}", unit="step", leave=False, disable=None)
    return None if bar.disable else bar
