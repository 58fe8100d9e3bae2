"""The viscous plant: RK4/ZOH accuracy, divergence, simulate's argument checks, Trajectory files.

What the closed loop itself does (torque checks, signals, interrupts) is in test_loop.py.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from snake_pin import (
    ConfigurationError,
    OpenLoop,
    ParameterError,
    Snake,
    SnakeParams,
    Trajectory,
    TrajectoryFileError,
    simulate,
)
from snake_pin.exceptions import RunInterrupted
from snake_pin.model import SnakeData


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


# ------------------------------------------------- plants and controllers at the boundary
def _reference(plant: Snake, t_final: float = 0.1) -> Trajectory:
    return simulate(plant, _wave(10), _x0(10), t_final)


def _is_prefix(part: Trajectory, whole: Trajectory) -> bool:
    """``part`` holds exactly the first samples of ``whole`` (torque after the last: zero)."""
    k = len(part)
    return (np.array_equal(part.t, whole.t[:k]) and np.array_equal(part.q, whole.q[:k])
            and np.array_equal(part.dq, whole.dq[:k])
            and np.array_equal(part.tau[:-1], whole.tau[: k - 1]) and not part.tau[-1].any())


def test_plain_function_is_a_controller(table1: Snake) -> None:
    """A plain f(x, t) runs exactly like the same torques through OpenLoop, named after it."""
    def wiggle(x: np.ndarray, t: float) -> np.ndarray:
        return 0.01 * np.sin(2 * t + np.arange(9))

    traj = simulate(table1, wiggle, _x0(10), 0.05)
    assert np.array_equal(traj.q, simulate(table1, _wave(10), _x0(10), 0.05).q)
    assert traj.meta["controller"] == "wiggle" and traj.status == "completed"
    assert simulate(table1, lambda x, t: np.zeros(9), _x0(10), 0.01).meta["controller"] == "lambda"
    with pytest.raises(ParameterError, match="controller"):
        simulate(table1, 3, _x0(10), 0.01)


class _Plant:
    """A Snake whose dynamics raise ``error`` at call number ``at`` (4 calls per RK4 step)."""

    def __init__(self, snake: Snake, at: int, error: BaseException) -> None:
        self._snake, self._at, self._error, self.calls = snake, at, error, 0

    def __getattr__(self, name: str):
        return getattr(self._snake, name)

    def state_derivative(self, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        self.calls += 1
        if self.calls == self._at:
            raise self._error
        return self._snake.state_derivative(x, tau)


@settings(max_examples=25, deadline=None)
@given(at=st.integers(1, 80))
def test_interrupt_anywhere_in_the_dynamics(table1: Snake, at: int) -> None:
    """Ctrl-C inside any RK4 stage keeps exactly the samples completed before it."""
    with pytest.raises(RunInterrupted) as info:
        simulate(_Plant(table1, at, KeyboardInterrupt()), _wave(10), _x0(10), 0.02)
    partial = info.value.partial
    assert len(partial) == (at - 1) // 4 + 1 and partial.status == "interrupted"
    assert _is_prefix(partial, _reference(_Plant(table1, 0, KeyboardInterrupt()), 0.02))


@settings(max_examples=15, deadline=None)
@given(at=st.integers(1, 80))
def test_interrupt_anywhere_in_the_fast_step(at: int) -> None:
    """Ctrl-C inside any stage of the robot's own (fast) RK4 keeps the samples before it."""
    snake = Snake(SnakeParams.table1())
    evaluate, calls = snake.calc_acceleration, []

    def interrupted(data: SnakeData, q: np.ndarray, v: np.ndarray,
                    torque: np.ndarray) -> np.ndarray:
        calls.append(q.__array_interface__["data"][0])  # which stage state
        if len(calls) == at:
            raise KeyboardInterrupt
        return evaluate(data, q, v, torque)

    snake.calc_acceleration = interrupted  # type: ignore[method-assign]
    with pytest.raises(RunInterrupted) as info:
        simulate(snake, _wave(10), _x0(10), 0.02)
    partial = info.value.partial
    # open loop: four stages evaluated per step, on four stage states in turn
    assert len(set(calls[:4])) == min(at, 4) and calls[4:8] == calls[:4][:len(calls[4:8])]
    assert len(partial) == (at - 1) // 4 + 1 and partial.status == "interrupted"
    assert _is_prefix(partial, _reference(Snake(SnakeParams.table1()), 0.02))


def test_dynamics_errors_end_as_divergence(table1: Snake) -> None:
    """A SnakePinError from the dynamics (e.g. a non-finite stage) is a divergence, not a crash."""
    plant = _Plant(table1, 42, ConfigurationError("x has non-finite entries"))
    traj = simulate(plant, _wave(10), _x0(10), 0.1)
    assert traj.status == "diverged" and len(traj) == 11 and "dynamics failed" in traj.reason
    assert traj.reason.startswith("diverged at t = 0.0110 s")


def test_max_steps(table1: Snake) -> None:
    """More than MAX_STEPS samples is a ParameterError naming t_final and the limit."""
    for t_final in (1000.5, 1e12, 1e300):
        with pytest.raises(ParameterError, match=r"t_final = .*MAX_STEPS = 1000000"):
            simulate(table1, _wave(10), _x0(10), t_final)
    with pytest.raises(ParameterError, match="MAX_SUBSTEPS"):
        simulate(table1, _wave(10), _x0(10), 1.0, dt=1e-9)


def test_runs_beyond_a_file_are_refused() -> None:
    """A run whose arrays a trajectory file could not hold is refused before allocating."""
    snake = Snake(SnakeParams.table1(n=50))
    x0 = np.zeros(2 * snake.nq)
    with pytest.raises(ParameterError, match="1000001 samples of the 50-link robot"):
        simulate(snake, lambda x, t: np.zeros(49), x0, 1000.0)


_BAD = [("x0", np.zeros((2, 12)), ConfigurationError), ("x0", np.zeros(23), ConfigurationError),
        ("x0", np.r_[np.nan, np.zeros(23)], ConfigurationError),
        ("x0", ["a"] * 24, ConfigurationError), ("t_final", True, ParameterError),
        ("t_final", "1", ParameterError), ("t_final", math.inf, ParameterError),
        ("t_final", 0.0, ParameterError), ("dt", -1e-3, ParameterError),
        ("control_dt", math.nan, ParameterError), ("max_speed", math.nan, ParameterError),
        ("max_speed", -1.0, ParameterError), ("max_distance", "far", ParameterError),
        ("method", 3, ParameterError), ("progress", "yes", ParameterError),
        ("meta", [1], ParameterError)]


@pytest.mark.parametrize(("name", "value", "error"), _BAD)
def test_arguments_are_checked(table1: Snake, name: str, value: object,
                               error: type[Exception]) -> None:
    """Every argument of simulate is checked: shapes, finiteness, types, signs."""
    kwargs = {"x0": _x0(10), "t_final": 0.01, name: value}
    with pytest.raises(error, match=name if name != "x0" else "x0"):
        simulate(table1, _wave(10), **kwargs)


class _Wrong:
    """A Snake's attributes with one replaced: not a consistent plant."""

    def __init__(self, snake: Snake, **changed: object) -> None:
        self._snake, self._changed = snake, changed

    def __getattr__(self, name: str) -> object:
        return self._changed.get(name, getattr(self._snake, name))


@pytest.mark.parametrize("plant", [None, "abc", [1.0], True, {}, np.zeros(10)])
def test_the_plant_is_checked_at_entry(plant: object) -> None:
    """Anything without a Snake's attributes is a ParameterError naming snake, in one line."""
    with pytest.raises(ParameterError, match=r"^snake must be a Snake") as info:
        simulate(plant, _wave(10), _x0(10), 0.01)  # type: ignore[arg-type]
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("changed", [{"nq": 11}, {"n": 9}, {"n": 10.0}, {"params": {}},
                                     {"state_derivative": None}])
def test_an_inconsistent_plant_is_refused(table1: Snake, changed: dict) -> None:
    """A plant whose nq, n, params or dynamics disagree is refused before anything runs."""
    with pytest.raises(ParameterError, match="disagree"):
        simulate(_Wrong(table1, **changed), _wave(10), _x0(10), 0.01)  # type: ignore[arg-type]


def test_a_consistent_plant_runs_as_the_snake(table1: Snake) -> None:
    """A plant with a Snake's attributes (not a Snake) runs, on the plain RK4 step."""
    plain = simulate(_Wrong(table1), _wave(10), _x0(10), 0.02)  # type: ignore[arg-type]
    fast = simulate(table1, _wave(10), _x0(10), 0.02)
    assert plain.status == "completed" and np.allclose(plain.q, fast.q, atol=1e-12)


def test_unbounded_divergence_limits(table1: Snake) -> None:
    """math.inf switches a divergence bound off."""
    traj = simulate(table1, _wave(10), _x0(10), 0.01, max_speed=math.inf, max_distance=math.inf)
    assert traj.status == "completed"


def _torque_line(traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    from snake_pin.viz.plots import plot_trajectory

    fig = plot_trajectory(traj)
    line = fig.axes[2].lines[0]
    return np.asarray(line.get_xdata()), np.asarray(line.get_ydata())


def test_the_torque_plot_shows_the_applied_torques_only(table1: Snake) -> None:
    """plot_trajectory's torque panel: a completed run's last sample (no torque applied,
    recorded as 0) is left out instead of drawn as a drop to a floor; a diverged run's
    last torque (the one that blew it up) is drawn."""
    done = simulate(table1, _wave(10), _x0(10), 0.05)
    t, norm = _torque_line(done)
    assert np.array_equal(t, done.t[:-1]) and np.all(norm > 1e-3)
    assert np.allclose(norm, np.linalg.norm(done.tau[:-1], axis=1), rtol=0, atol=0)
    blown = simulate(table1, OpenLoop(lambda t: np.full(9, 0.0 if t < 0.1 else 1e6)),
                     _x0(10), 1.0)
    t, norm = _torque_line(blown)
    assert blown.diverged and np.array_equal(t, blown.t) and norm[-1] == pytest.approx(3e6)


def test_head_path_figure_draws_the_head_against_its_reference(table1: Snake,
                                                              tmp_path: Path) -> None:
    """plot_head_path draws the reference and the head in the plane (x-y, equal axes) and
    writes the PNG."""
    from snake_pin.viz.plots import plot_head_path

    traj = simulate(table1, _wave(10), _x0(10), 0.05)
    reference = np.c_[0.1 * traj.t, np.zeros(len(traj))]
    fig = plot_head_path(traj, reference, title="line")
    lines = fig.axes[0].lines
    assert np.array_equal(np.c_[lines[0].get_xdata(), lines[0].get_ydata()], reference)
    assert np.array_equal(np.c_[lines[1].get_xdata(), lines[1].get_ydata()], traj.q[:, :2])
    assert fig.axes[0].get_aspect() == 1.0
    png = tmp_path / "head.png"
    plot_head_path(traj, reference, png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
