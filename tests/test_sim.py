"""Simulation core: RK4/ZOH accuracy, divergence handling, Trajectory files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from snake_pin import (
    OpenLoop,
    ParameterError,
    Snake,
    SnakeParams,
    SnakePinError,
    Trajectory,
    TrajectoryFileError,
    simulate,
)
from snake_pin.control import Controller


def _x0(n: int) -> np.ndarray:
    x0 = np.zeros(2 * (n + 2))
    x0[3:n + 2] = np.pi / 6
    return x0


def _wave(n: int) -> OpenLoop:
    return OpenLoop(lambda t: 0.01 * np.sin(2 * t + np.arange(n - 1)))


def test_rk4_agrees_with_solve_ivp(table1: Snake) -> None:
    """Fixed-step RK4 at 1 ms matches scipy's adaptive RK45 (tight tolerances) to 1e-7."""
    a = simulate(table1, _wave(10), _x0(10), 0.2)
    b = simulate(table1, _wave(10), _x0(10), 0.2, method="solve_ivp")
    assert np.max(np.abs(a.q - b.q)) < 1e-7
    assert len(a) == 201 and a.t[-1] == pytest.approx(0.2)


def test_zero_order_hold(table1: Snake) -> None:
    """The recorded torque is the one sampled at each control instant and held."""
    traj = simulate(table1, _wave(10), _x0(10), 0.05, dt=5e-4, control_dt=1e-2)
    assert np.allclose(traj.tau[0], 0.01 * np.sin(np.arange(9)))
    assert np.allclose(traj.tau[1], 0.01 * np.sin(0.02 + np.arange(9)))
    assert np.allclose(traj.t, np.arange(6) * 1e-2)


def test_divergence_stops_and_keeps_the_run(table1: Snake, tmp_path: Path) -> None:
    """A run that blows up stops with a reason naming the time; earlier samples are kept."""
    def blow_up(t: float) -> np.ndarray:
        return np.full(9, 0.0 if t < 0.1 else 1e6)
    traj = simulate(table1, OpenLoop(blow_up), _x0(10), 1.0)
    assert traj.diverged and "t = 0.1" in traj.reason
    assert 0.1 <= traj.t_end < 0.2 and np.all(np.isfinite(traj.q))
    assert traj.tau[-1, 0] == 1e6  # the torque that blew the state up is kept
    npz, js = traj.save(tmp_path / "run")
    summary = json.loads(js.read_text())
    assert summary["diverged"] is True and summary["t_end"] == pytest.approx(traj.t_end)
    assert Trajectory.load(npz).t_end == traj.t_end


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


def test_save_load_round_trip(table1: Snake, tmp_path: Path) -> None:
    """Arrays, signals, params and summary survive save/load exactly."""
    traj = simulate(table1, _wave(10), _x0(10), 0.05)
    traj.signals["R"] = np.linspace(0, 1, len(traj))
    traj.summary["rms"] = 0.25
    traj.save(tmp_path / "run.npz")
    back = Trajectory.load(tmp_path / "run")
    assert np.array_equal(back.q, traj.q) and np.array_equal(back.signals["R"], traj.signals["R"])
    assert back.params == traj.params and back.summary == {"rms": 0.25}


def test_load_refuses_missing_and_foreign_files(tmp_path: Path) -> None:
    """A missing file or a foreign .npz is a TrajectoryFileError."""
    with pytest.raises(TrajectoryFileError):
        Trajectory.load(tmp_path / "nothing.npz")
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(TrajectoryFileError):
        Trajectory.load(tmp_path / "other.npz")


@pytest.mark.parametrize("kwargs", [{"t_final": -1.0}, {"t_final": float("nan")},
                                    {"dt": 3e-3}, {"method": "euler"}])
def test_bad_settings(table1: Snake, kwargs: dict) -> None:
    """Bad time settings or methods are ParameterErrors."""
    settings = {"t_final": 0.1, **kwargs}
    with pytest.raises(ParameterError):
        simulate(table1, _wave(10), _x0(10), **settings)


def test_passive_snake_runs(rng: np.random.Generator) -> None:
    """A snake with a passive joint simulates; the passive joint's torque is recorded as given."""
    snake = Snake(SnakeParams.table1(passive=(5,)))
    traj = simulate(snake, _wave(10), _x0(10), 0.05)
    assert not traj.diverged
