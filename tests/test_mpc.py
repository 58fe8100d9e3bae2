"""Model-predictive head tracking: options, a short closed loop, passive joint, pickling."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from snake_pin import ParameterError, Snake, SnakeParams, simulate
from snake_pin.control.mpc import MPCController, MPCOptions
from snake_pin.experiments.tracking import initial_state
from snake_pin.ocp import CostWeights
from snake_pin.paths import Line, PathReference

#: The default law with a shorter first solve (the tests' closed loops last 1 s or less).
QUICK = MPCOptions(first_iterations=20)
#: Fewer iterations where only the law's mechanics are checked.
BRIEF = MPCOptions(first_iterations=3, iterations=1)


def _robot(**changes: object) -> SnakeParams:
    return SnakeParams.table1(c_y=25.0, **changes)


@pytest.fixture(scope="module")
def line_run() -> tuple[Snake, PathReference, object, MPCController]:
    snake = Snake(_robot())
    reference = PathReference(Line())
    controller = MPCController(snake, reference, options=QUICK)
    traj = simulate(snake, controller, initial_state(snake.params), 0.8, control_dt=2e-3)
    return snake, reference, traj, controller


def test_tracks_the_line_within_bounds(line_run: tuple) -> None:
    """The head follows the timed reference far better than standing still (zero torque
    keeps the snake at rest: its error is the reference's own travel), within the bound."""
    _, reference, traj, controller = line_run
    assert traj.status == "completed"
    assert np.abs(traj.tau).max() <= QUICK.torque_bound + 1e-12
    error = np.linalg.norm(traj.q[:, :2] - reference.at(traj.t)[0][:, :2], axis=1)
    standing = np.linalg.norm(reference.at(traj.t)[0][:, :2], axis=1)
    assert np.sqrt(np.mean(error**2)) < 0.5 * np.sqrt(np.mean(standing**2))
    assert controller.stats.solves == pytest.approx(0.8 / QUICK.resolve_period, abs=1)
    assert set(controller.signals()) == {"solve_cost", "solve_iterations"}


def test_passive_joint_gets_exactly_zero(rng: np.random.Generator) -> None:
    snake = Snake(_robot(passive=(5,)))
    controller = MPCController(snake, PathReference(Line()), options=BRIEF)
    traj = simulate(snake, controller, initial_state(snake.params), 0.1, control_dt=2e-3)
    assert traj.status == "completed"
    assert np.all(traj.tau[:, 4] == 0.0)
    assert np.abs(traj.tau[:, [0, 1, 2, 3, 5, 6, 7, 8]]).max() > 0.0
    assert np.abs(traj.tau).max() <= QUICK.torque_bound + 1e-12


def test_feedback_between_solves(line_run: tuple) -> None:
    """Between re-solves the torque follows the state through the Riccati gains."""
    snake, reference, traj, _ = line_run
    controller = MPCController(snake, reference, options=BRIEF)
    x = np.r_[traj.q[100], traj.dq[100]]
    first = controller(x, 0.2)
    assert np.array_equal(controller(x, 0.2), first)  # no re-solve: the same plan
    pushed = x.copy()
    pushed[snake.nq + 3] += 0.5  # joint 1 faster
    assert not np.allclose(controller(pushed, 0.2), first)
    open_loop = MPCController(snake, reference, options=MPCOptions(
        first_iterations=3, iterations=1, feedback=False))
    plan = open_loop(x, 0.2)
    assert np.array_equal(open_loop(pushed, 0.2), plan)


def test_pickles_and_rebuilds(line_run: tuple) -> None:
    snake, reference, _, _ = line_run
    controller = MPCController(snake, reference, options=BRIEF)
    copy = pickle.loads(pickle.dumps(controller))
    copy.reset()
    controller.reset()
    x = initial_state(snake.params)
    assert np.array_equal(copy(x, 0.0), controller(x, 0.0))


@pytest.mark.parametrize(("changes", "message"), [
    ({"horizon": 0.005}, "shorter than one node"),
    ({"resolve_period": 0.015}, "whole number of nodes"),
    ({"resolve_period": 0.6}, "exceeds the horizon"),
    ({"torque_bound": 0.0}, "torque_bound"),
    ({"torque_bound": -1.0}, "torque_bound"),
    ({"node_dt": float("inf")}, "node_dt"),
    ({"iterations": 0}, "iterations"),
    ({"step_halvings": -1}, "step_halvings"),
    ({"feedback": "yes"}, "feedback"),
    ({"weights": {"torque": 1.0}}, "weights"),
])
def test_bad_options_are_one_line(changes: dict, message: str) -> None:
    with pytest.raises(ParameterError, match=message) as info:
        MPCOptions(**changes)
    assert "\n" not in str(info.value)


def test_bad_arguments_are_one_line() -> None:
    snake = Snake(_robot())
    for make, message in (
            (lambda: CostWeights(head_position=-1.0), "head_position"),
            (lambda: MPCController(snake, options={"horizon": 1.0}), "options"),
            (lambda: MPCController(snake, reference=3.0), "reference"),
            (lambda: MPCController("snake"), "snake"),
            (lambda: MPCController(Snake(_robot(n=3, passive=(1, 2)))), "passive"),
            (lambda: MPCController(Snake(_robot(passive=(10,)))), "passive"),
    ):
        with pytest.raises(ParameterError, match=message) as info:
            make()
        assert "\n" not in str(info.value)
