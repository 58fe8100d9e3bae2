"""The optimal-control model: Crocoddyl's dynamics against Snake, derivatives, costs."""

from __future__ import annotations

import crocoddyl
import numpy as np
import pytest

from snake_pin import ParameterError, Snake, SnakeParams
from snake_pin.gaits import Serpenoid
from snake_pin.ocp import (
    ChainRootActuation,
    CostWeights,
    TrackingProblem,
    differential_model,
    reference_states,
)
from snake_pin.paths import Circle, PathReference

from .conftest import head_first_state, heterogeneous_params

ROBOTS = {
    "tracking": SnakeParams.table1(c_y=25.0),
    "passive5": SnakeParams.table1(c_y=25.0, passive=(5,)),
    "isotropic": SnakeParams.table1(),
}


@pytest.fixture(scope="module", params=sorted(ROBOTS))
def snake(request: pytest.FixtureRequest) -> Snake:
    return Snake(ROBOTS[request.param])


def _torques(snake: Snake, u: np.ndarray) -> np.ndarray:
    """The n - 1 joint torques of inputs u (passive joints 0)."""
    tau = np.zeros(snake.n - 1)
    tau[np.array(snake.params.actuated) - 1] = u
    return tau


def test_acceleration_is_snakes_forward_dynamics(snake: Snake,
                                                 rng: np.random.Generator) -> None:
    model = differential_model(snake)
    data = model.createData()
    for _ in range(5):
        x, u = head_first_state(rng, snake.n, speed=1.0), rng.normal(size=model.nu)
        model.calc(data, x, u)
        expected = snake.forward_dynamics(x[:snake.nq], x[snake.nq:], _torques(snake, u))
        assert np.allclose(data.xout, expected, rtol=0.0, atol=1e-12 * np.abs(expected).max())


def test_derivatives_are_snakes(snake: Snake, rng: np.random.Generator) -> None:
    """Crocoddyl's chain rule over the actuation's friction Jacobians equals the core's
    analytic derivatives (computeABADerivatives + the twin's RNEA derivatives)."""
    model = differential_model(snake)
    data = model.createData()
    nq = snake.nq
    for _ in range(3):
        x, u = head_first_state(rng, snake.n, speed=1.0), rng.normal(size=model.nu)
        model.calc(data, x, u)
        model.calcDiff(data, x, u)
        d = snake.dynamics_derivatives(x[:nq], x[nq:], _torques(snake, u))
        expected = np.hstack((d.ddq_dq, d.ddq_dv))
        scale = np.abs(expected).max()
        assert np.abs(data.Fx - expected).max() <= 1e-11 * scale
        actuated = np.array(snake.params.actuated) - 1
        assert np.abs(data.Fu - d.ddq_dtau[:, actuated]).max() <= 1e-12 * np.abs(data.Fu).max()


def test_derivatives_match_numdiff(snake: Snake, rng: np.random.Generator) -> None:
    """Dynamics and cost derivatives against Crocoddyl's finite differences."""
    model = differential_model(snake, CostWeights(joint_limit=0.0))
    problem = TrackingProblem(snake, 2, weights=CostWeights(joint_limit=0.0))
    gait = Serpenoid(snake.n, np.pi / 6, 1.5, 2.0)
    reference = PathReference(Circle(radius=1.2))
    row = reference_states(reference, gait, np.array([0.7]))[0]
    problem.set_reference(np.tile(row, (3, 1)))
    model = problem.running[0].differential
    numdiff = crocoddyl.DifferentialActionModelNumDiff(model, False)
    data, nd_data = model.createData(), numdiff.createData()
    x, u = head_first_state(rng, snake.n, speed=0.3), rng.normal(size=model.nu)
    model.calc(data, x, u)
    model.calcDiff(data, x, u)
    numdiff.calc(nd_data, x, u)
    numdiff.calcDiff(nd_data, x, u)
    for name in ("Fx", "Fu", "Lx", "Lu"):
        exact, approx = getattr(data, name), getattr(nd_data, name)
        assert np.abs(exact - approx).max() <= 1e-5 * max(1.0, np.abs(exact).max()), name


def test_friction_jacobians_match_central_differences(rng: np.random.Generator) -> None:
    """The actuation's ``dtau_dx`` against central differences of its force, per-link
    robots (anisotropic and isotropic friction), three states each."""
    for friction in ("anisotropic", "isotropic"):
        snake = Snake(heterogeneous_params(rng, 7, friction))
        actuation = ChainRootActuation(crocoddyl.StateMultibody(snake.model), snake)
        data = actuation.createData()
        for _ in range(3):
            _check_against_central_differences(actuation, data,
                                               head_first_state(rng, snake.n, speed=1.0))


def _check_against_central_differences(actuation: ChainRootActuation, data: object,
                                       x: np.ndarray) -> None:
    """``dtau_dx`` at ``x`` against central differences of the actuation's force."""
    h, columns = 1e-6, []
    for k in range(len(x)):
        step = np.zeros(len(x))
        step[k] = h
        actuation.calc(data, x + step)
        plus = data.tau.copy()
        actuation.calc(data, x - step)
        columns.append((plus - data.tau) / (2.0 * h))
    actuation.calc(data, x)
    actuation.calcDiff(data, x)
    expected = np.array(columns).T
    assert np.abs(data.dtau_dx - expected).max() <= 1e-7 * np.abs(expected).max()


def test_each_actuation_data_holds_its_friction(rng: np.random.Generator) -> None:
    """Two datas of one actuation, evaluated in turn at two states, each hold the core's
    friction force and Jacobians at its own state to the bit (the model's friction buffers,
    which both share, are copied out at once)."""
    snake = Snake(ROBOTS["tracking"])
    actuation = ChainRootActuation(crocoddyl.StateMultibody(snake.model), snake)
    datas = [actuation.createData(), actuation.createData()]
    nq = snake.nq
    states = [head_first_state(rng, snake.n, speed=1.0) for _ in datas]
    for data, x in zip(datas, states, strict=True):
        actuation.calc(data, x)
        actuation.calcDiff(data, x)
    for data, x in zip(datas, states, strict=True):
        _, dforce_dq, dforce_dv = snake.friction.derivatives(x[:nq], x[nq:])
        assert np.array_equal(data.tau, snake.friction(x[:nq], x[nq:]))
        assert np.array_equal(data.dtau_dx, np.hstack((dforce_dq, dforce_dv)))
    frictionless = ChainRootActuation(crocoddyl.StateMultibody(snake.model), snake,
                                      friction=False)
    data = frictionless.createData()
    frictionless.calc(data, states[0])
    frictionless.calcDiff(data, states[0])
    assert frictionless.friction_data is None
    assert not data.tau.any() and not data.dtau_dx.any()


def test_passive_joint_gets_no_torque(rng: np.random.Generator) -> None:
    snake = Snake(ROBOTS["passive5"])
    model = differential_model(snake)
    assert model.nu == snake.n - 2
    data = model.createData()
    x = head_first_state(rng, snake.n)
    model.calc(data, x, np.zeros(model.nu))
    friction = data.multibody.actuation.tau.copy()
    model.calc(data, x, rng.normal(size=model.nu) * 10.0)
    applied = data.multibody.actuation.tau - friction
    assert applied[3 + 4] == 0.0 and np.all(applied[:3] == 0.0)
    assert np.all(data.multibody.actuation.dtau_du[3 + 4] == 0.0)


def test_rk4_node_steps_like_rk4_of_snake(rng: np.random.Generator) -> None:
    snake = Snake(ROBOTS["tracking"])
    problem = TrackingProblem(snake, 1, node_dt=0.01)
    node, nq = problem.running[0], snake.nq
    data = node.createData()
    x, u = head_first_state(rng, snake.n), rng.normal(size=node.nu)
    node.calc(data, x, u)

    def f(z: np.ndarray) -> np.ndarray:
        return np.r_[z[nq:], snake.forward_dynamics(z[:nq], z[nq:], u)]

    h = 0.01
    k1 = f(x)
    k2 = f(x + h / 2 * k1)
    k3 = f(x + h / 2 * k2)
    k4 = f(x + h * k3)
    assert np.allclose(data.xnext, x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), atol=1e-13)


def test_costs_vanish_on_the_reference() -> None:
    """At the reference state with zero torque every cost is 0; off it, each is positive."""
    snake = Snake(ROBOTS["tracking"])
    problem = TrackingProblem(snake, 1)
    gait = Serpenoid(snake.n, np.pi / 6, 1.5, 2.0)
    rows = reference_states(PathReference(Circle(radius=1.2)), gait, problem.node_times(3.0))
    problem.set_reference(rows)
    model = problem.running[0].differential
    data = model.createData()
    model.calc(data, rows[0], np.zeros(model.nu))
    assert data.cost == pytest.approx(0.0, abs=1e-12)
    shifted = rows[0].copy()
    shifted[0] += 0.01
    model.calc(data, shifted, np.zeros(model.nu))
    assert data.cost == pytest.approx(0.5 * CostWeights().head_position * 1e-4)


@pytest.mark.parametrize(("make", "message"), [
    (lambda s: CostWeights(torque=-1.0), "torque"),
    (lambda s: CostWeights(gait=float("nan")), "gait"),
    (lambda s: differential_model(s, torque_bound=0.0), "torque_bound"),
    (lambda s: differential_model(s, weights="heavy"), "weights"),
    (lambda s: TrackingProblem(s, 0), "nodes"),
    (lambda s: TrackingProblem(s, 5, node_dt=-0.01), "node_dt"),
    (lambda s: differential_model(Snake(SnakeParams.table1(n=3, passive=(1, 2)))), "passive"),
    (lambda s: differential_model("snake"), "snake"),
])
def test_bad_settings_are_one_line(make: object, message: str) -> None:
    snake = Snake(ROBOTS["tracking"])
    with pytest.raises(ParameterError, match=message) as info:
        make(snake)  # type: ignore[operator]
    assert "\n" not in str(info.value)
