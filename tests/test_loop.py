"""The closed loop: zero-order hold, torque checks, signals, interrupts, run statuses.

The loop is run over a small plant of its own (joint velocities set by the held torque),
which shows what the loop itself does with a plant's samples, faults and interrupts, and
over the viscous model through :func:`snake_pin.simulate`, the plant users run it on.
"""

from __future__ import annotations

import fcntl
import os
import pty
import select
import signal
import struct
import sys
import termios

import numpy as np
import pytest

from snake_pin import (
    OpenLoop,
    ParameterError,
    Snake,
    SnakeParams,
    SnakePinError,
    Trajectory,
    simulate,
)
from snake_pin.control import Controller
from snake_pin.exceptions import RunInterrupted
from snake_pin.loop import MAX_STEPS, Plant, closed_loop


def _x0(n: int) -> np.ndarray:
    x0 = np.zeros(2 * (n + 2))
    x0[3:n + 2] = np.pi / 6
    return x0


def _wave(n: int) -> OpenLoop:
    return OpenLoop(lambda t: 0.01 * np.sin(2 * t + np.arange(n - 1)))


def _reference(plant: Snake, t_final: float = 0.1) -> Trajectory:
    return simulate(plant, _wave(10), _x0(10), t_final)


def _is_prefix(part: Trajectory, whole: Trajectory) -> bool:
    """``part`` holds exactly the first samples of ``whole`` (torque after the last: zero)."""
    k = len(part)
    return (np.array_equal(part.t, whole.t[:k]) and np.array_equal(part.q, whole.q[:k])
            and np.array_equal(part.dq, whole.dq[:k])
            and np.array_equal(part.tau[:-1], whole.tau[: k - 1]) and not part.tau[-1].any())


# ------------------------------------------------------------------- a plant of its own
class _Joints(Plant):
    """Three links whose joint velocities are the held torque, over periods of 10 ms;
    ``fault`` (a message, or an exception to raise) comes at period ``at``."""

    def __init__(self, at: int = -1, fault: str | BaseException = "") -> None:
        self.params = SnakeParams.table1(n=3)
        self.nq = 5
        self._at, self._fault, self._k = at, fault, 0
        self.applied: list[np.ndarray] = []

    def times(self, steps: int) -> tuple[np.ndarray, np.ndarray]:
        calls = np.arange(steps) * 0.01
        return calls, np.r_[0.0, calls + 0.01]

    def reset(self, x0: np.ndarray, out: np.ndarray) -> None:
        self._x = np.array(x0, dtype=float)
        self._k = 0
        out[...] = self._x

    def step(self, tau: np.ndarray, first: np.ndarray | None, out: np.ndarray,
             t: float) -> str:
        self.applied.append(tau.copy())
        k, self._k = self._k, self._k + 1
        if k == self._at and isinstance(self._fault, BaseException):
            raise self._fault
        self._x[8:] = tau
        self._x[3:5] += 0.01 * tau
        out[...] = self._x
        return self._fault if k == self._at else ""


def _ramp(x: np.ndarray, t: float) -> np.ndarray:
    return np.array([t, -2.0 * t])


class _Ramp(Controller):
    name = "ramp"

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        return _ramp(x, t)


def test_the_loop_holds_each_torque_over_its_period() -> None:
    """The controller is called at the plant's instants and its torque held over the period:
    recorded at its instant, applied once, the last sample's torque zero."""
    plant = _Joints()
    traj = closed_loop(plant, _Ramp(), np.zeros(10), 5, meta={"run": "ramp"})
    assert traj.status == "completed" and traj.reason == "" and len(traj) == 6
    assert np.allclose(traj.t, np.arange(6) * 0.01) and traj.meta == {"run": "ramp"}
    calls = np.c_[traj.t[:-1], -2.0 * traj.t[:-1]]
    assert np.array_equal(traj.tau[:-1], calls) and not traj.tau[-1].any()
    assert np.array_equal(np.array(plant.applied), calls)
    assert np.array_equal(traj.dq[1:, 3:], calls) and np.allclose(traj.q[-1, 3:],
                                                                  0.01 * calls.sum(axis=0))


def test_a_plant_fault_ends_the_run_as_diverged() -> None:
    """What the plant reports at period 3 ends the run there with the samples before it and
    the torque that was applied, in the reason with the time of the bad sample."""
    traj = closed_loop(_Joints(3, "too far"), _Ramp(), np.zeros(10), 10)
    assert traj.status == "diverged" and traj.diverged and len(traj) == 4
    assert traj.reason == "diverged at t = 0.0400 s: too far"
    assert np.array_equal(traj.tau[-1], _ramp(np.zeros(10), 0.03))


@pytest.mark.parametrize("error", [SnakePinError("singular"), ZeroDivisionError("by zero"),
                                   np.linalg.LinAlgError("not positive definite")])
def test_dynamics_errors_of_a_plant_are_a_divergence(error: Exception) -> None:
    """The package's, arithmetic and linear-algebra errors of a plant end the run as
    diverged, named; the samples before them are kept."""
    traj = closed_loop(_Joints(2, error), _Ramp(), np.zeros(10), 10)
    assert traj.status == "diverged" and len(traj) == 3
    assert traj.reason == (f"diverged at t = 0.0300 s: the dynamics failed "
                           f"({type(error).__name__}: {error})")


def test_other_plant_errors_propagate() -> None:
    """A plant's own bug (not a dynamics error) is not hidden as a run status."""
    with pytest.raises(KeyError):
        closed_loop(_Joints(2, KeyError("bug")), _Ramp(), np.zeros(10), 10)


def test_an_interrupt_in_the_plant_keeps_the_samples_before_it() -> None:
    """Ctrl-C in period 4: RunInterrupted with samples 0..4, the last torque zero."""
    with pytest.raises(RunInterrupted) as info:
        closed_loop(_Joints(4, KeyboardInterrupt()), _Ramp(), np.zeros(10), 10)
    partial = info.value.partial
    assert partial.status == "interrupted" and len(partial) == 5
    assert partial.reason == "interrupted at t = 0.0400 s" == str(info.value)
    assert np.array_equal(partial.tau[:-1], np.c_[partial.t[:-1], -2.0 * partial.t[:-1]])
    assert not partial.tau[-1].any()


@pytest.mark.parametrize("steps", [-1, 1.5, True, "3", None, MAX_STEPS + 1])
def test_steps_are_checked(steps: object) -> None:
    """Control periods: a whole number in 0 .. MAX_STEPS, or a ParameterError naming it."""
    with pytest.raises(ParameterError, match=r"^steps must (be an integer|lie in 0\.\.1000000),"):
        closed_loop(_Joints(), _Ramp(), np.zeros(10), steps)  # type: ignore[arg-type]


def test_no_steps_is_the_first_sample() -> None:
    """Zero periods: the initial sample alone, completed, with no controller call."""
    plant = _Joints()
    traj = closed_loop(plant, _Ramp(), np.r_[np.zeros(3), 0.5, 0.0, np.zeros(5)], 0)
    assert traj.status == "completed" and len(traj) == 1 and traj.q[0, 3] == 0.5
    assert plant.applied == [] and not traj.tau.any()


# ------------------------------------------------------------ over the viscous model
class _Refuses(Controller):
    name = "refuses"

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        if t >= 0.05:
            raise SnakePinError("posture is singular")
        return np.zeros(9)


def test_controller_error_stops_the_run(table1: Snake) -> None:
    """A controller raising SnakePinError ends the run with its message as the reason."""
    traj = simulate(table1, _Refuses(), _x0(10), 1.0)
    assert traj.diverged and "singular" in traj.reason and traj.t_end == pytest.approx(0.05)


def test_any_controller_exception_keeps_the_run(table1: Snake) -> None:
    """A ValueError at t = 0.05 ends the run as 'failed' with samples 0..50 kept."""
    def fragile(x: np.ndarray, t: float) -> np.ndarray:
        if t >= 0.05 - 1e-12:
            raise ValueError("gain matrix\nis singular")
        return 0.01 * np.sin(2 * t + np.arange(9))

    traj = simulate(table1, fragile, _x0(10), 0.1)
    assert traj.status == "failed" and traj.diverged and len(traj) == 51
    assert traj.reason == "controller failed at t = 0.0500 s: ValueError: gain matrix is singular"
    assert _is_prefix(traj, _reference(table1))


@pytest.mark.parametrize(("output", "expected"), [
    (np.zeros(8), "controller returned 8 torques, expected 9"),
    (np.zeros(1), "controller returned 1 torque, expected 9"),
    (0.5, "controller returned 1 torque, expected 9"),
    (np.zeros((9, 1)), "controller returned torques of shape (9, 1), expected 9"),
    (np.full(9, np.inf), "controller returned a non-finite torque"),
    (np.zeros(9, dtype=complex), "controller returned a torque of dtype complex128, not numbers"),
    (["a"] * 9, "controller returned a torque of dtype <U1, not numbers"),
])
def test_wrong_torques_are_named(table1: Snake, output: object, expected: str) -> None:
    """Wrong sizes (one element included: never broadcast), types and non-finite torques."""
    def controller(x: np.ndarray, t: float) -> object:
        return output if t >= 0.02 - 1e-12 else np.zeros(9)

    traj = simulate(table1, controller, _x0(10), 0.1)
    assert traj.status == "failed" and len(traj) == 21
    assert traj.reason == f"{expected} at t = 0.0200 s"


def test_keyboard_interrupt_in_the_controller(table1: Snake) -> None:
    """Ctrl-C inside the controller at t = 0.05: RunInterrupted with samples 0..50."""
    def controller(x: np.ndarray, t: float) -> np.ndarray:
        if t >= 0.05 - 1e-12:
            raise KeyboardInterrupt
        return 0.01 * np.sin(2 * t + np.arange(9))

    with pytest.raises(RunInterrupted) as info:
        simulate(table1, controller, _x0(10), 0.1)
    partial = info.value.partial
    assert str(info.value) == "interrupted at t = 0.0500 s" and not isinstance(info.value,
                                                                                Exception)
    assert partial.status == "interrupted" and not partial.diverged and len(partial) == 51
    assert partial.reason == str(info.value) and _is_prefix(partial, _reference(table1))


def test_sigint_during_a_run(table1: Snake) -> None:
    """A real SIGINT raised at t = 0.03 gives a consistent partial run ending there."""
    def controller(x: np.ndarray, t: float) -> np.ndarray:
        if abs(t - 0.03) < 1e-9:
            signal.raise_signal(signal.SIGINT)
        return 0.01 * np.sin(2 * t + np.arange(9))

    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(RunInterrupted) as info:
            simulate(table1, controller, _x0(10), 0.1)
    finally:
        signal.signal(signal.SIGINT, previous)
    partial = info.value.partial
    assert 0.03 - 1e-9 <= partial.t_end <= 0.031 + 1e-9
    assert _is_prefix(partial, _reference(table1))


def test_signals_stay_aligned(table1: Snake) -> None:
    """A signal that first appears at t = 0.01 is NaN before, aligned with t after."""
    class Late(Controller):
        name = "late"

        def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
            self._t = t
            return np.zeros(9)

        def signals(self) -> dict[str, float]:
            return {"t": self._t} if self._t >= 0.01 - 1e-12 else {}

    traj = simulate(table1, Late(), _x0(10), 0.02)
    late = traj.signals["t"]
    assert np.all(np.isnan(late[:10])) and np.allclose(late[10:-1], traj.t[10:-1])
    assert np.isnan(late[-1])  # no controller call at the last sample


def test_progress_only_on_a_terminal(table1: Snake, capfd: pytest.CaptureFixture[str],
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """progress=True draws nothing into a non-TTY stderr, and a bar on a terminal."""
    simulate(table1, _wave(10), _x0(10), 0.05, progress=True)
    assert capfd.readouterr().err == ""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("4H", 24, 80, 0, 0))  # a 24x80 terminal
    try:
        with os.fdopen(slave, "w") as tty:
            monkeypatch.setattr(sys, "stderr", tty)
            simulate(table1, _wave(10), _x0(10), 0.05, progress=True)
            tty.flush()
            ready, _, _ = select.select([master], [], [], 5.0)
            drawn = os.read(master, 1 << 16).decode(errors="replace") if ready else ""
    finally:
        os.close(master)
    assert "simulate open_loop" in drawn
