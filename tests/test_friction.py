"""Friction: the damping twin's two routes equal the pin.Force reference and the closed form."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from snake_pin import Snake, SnakeParams, paper
from snake_pin.friction import FrictionModel, friction_forces

from .conftest import random_state


def _closed_form(params: SnakeParams, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Q = -C(q) dq with C from the paper's closed form (snake_pin.paper)."""
    return -paper.friction_matrix(params, q) @ dq


def _rnea_passes(params: SnakeParams, monkeypatch: pytest.MonkeyPatch) -> FrictionModel:
    """The friction model of ``params`` on the RNEA passes' route, whatever its length."""
    from snake_pin import friction

    monkeypatch.setattr(friction, "WHEELED_TWIN_MAX_LINKS", 0)
    model = FrictionModel(params, Snake(params).model)
    assert not model.uses_twin_crba
    return model


@pytest.mark.parametrize("c", [(0.5, 0.5, 7.2e-5), (0.2, 8.0, 1e-3), (3.0, 0.1, 0.0)])
def test_friction_equals_external_forces(c: tuple, rng: np.random.Generator,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Q of both routes and the closed form equals RNEA(no fext) - RNEA(fext) with pin.Force."""
    params = SnakeParams.table1(c_x=c[0], c_y=c[1], c_theta=c[2])
    snake = Snake(params)
    passes = _rnea_passes(params, monkeypatch)
    zero = np.zeros(snake.nv)
    for _ in range(20):
        q, dq = random_state(rng, params.n)
        fext = friction_forces(snake.model, snake.data, params, q, dq)
        reference = (pin.rnea(snake.model, snake.data, q, dq, zero)
                     - pin.rnea(snake.model, snake.data, q, dq, zero, fext))
        assert np.allclose(snake.friction(q, dq), reference, rtol=1e-12, atol=1e-13)
        assert np.allclose(snake.friction_force(q, dq), reference, atol=1e-13)
        assert np.allclose(passes(q, dq), reference, rtol=1e-12, atol=1e-13)
        assert np.allclose(_closed_form(params, q, dq), reference, rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize("c_y", [0.5, 5.0])
def test_aba_with_external_forces_equals_fast_route(c_y: float,
                                                    rng: np.random.Generator) -> None:
    """ABA with the pin.Force list gives the same q'' as Snake.forward_dynamics."""
    params = SnakeParams.table1(c_y=c_y)
    snake = Snake(params)
    for _ in range(10):
        q, dq = random_state(rng, params.n)
        tau = rng.normal(size=params.n - 1)
        fext = friction_forces(snake.model, snake.data, params, q, dq)
        reference = pin.aba(snake.model, snake.data, q, dq, snake.generalized_torque(tau), fext)
        assert np.allclose(snake.forward_dynamics(q, dq, tau), reference, atol=1e-10)


def test_friction_opposes_motion(rng: np.random.Generator) -> None:
    """Dissipation: dq . Q <= 0, strictly when the body moves."""
    snake = Snake(SnakeParams.table1(c_y=5.0))
    for _ in range(20):
        q, dq = random_state(rng, snake.n)
        assert dq @ snake.friction(q, dq) < 0.0


@pytest.mark.parametrize("c", [(0.5, 0.5, 7.2e-5), (2.0, 2.0, 0.0), (0.0, 0.0, 1e-3)])
def test_isotropic_twin_equals_the_closed_form(c: tuple, rng: np.random.Generator) -> None:
    """Isotropic friction: the damping twin's RNEA and CRBA equal the paper's C(q) dq."""
    params = SnakeParams.table1(c_x=c[0], c_y=c[1], c_theta=c[2])
    snake = Snake(params)
    assert not snake.friction.uses_twin_crba and not snake.friction.has_wheels
    for _ in range(20):
        q, dq = random_state(rng, params.n)
        expected = _closed_form(params, q, dq)
        assert np.allclose(snake.friction(q, dq), expected, rtol=1e-12, atol=1e-13)
        assert np.allclose(snake.friction_force(q, dq), expected, rtol=1e-12,
                           atol=1e-13)
        c_twin = snake.friction.matrix(q)
        assert np.allclose(c_twin, paper.friction_matrix(params, q), rtol=1e-12, atol=1e-13)
        assert np.allclose(c_twin, c_twin.T, atol=0.0)


@pytest.mark.parametrize("c", [(0.5, 25.0, 7.2e-5), (0.04, 61.4, 1.6e-4), (3.0, 0.1, 0.0)])
def test_twin_with_wheels_equals_the_closed_form(c: tuple, rng: np.random.Generator,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """Anisotropic friction: the twin whose wheels roll along the links gives the closed
    form's Q by both routes (CRBA and products; RNEA passes) and its C."""
    params = SnakeParams.table1(c_x=c[0], c_y=c[1], c_theta=c[2])
    snake = Snake(params)
    assert snake.friction.uses_twin_crba and snake.friction.has_wheels
    passes = _rnea_passes(params, monkeypatch)
    for _ in range(20):
        q, dq = random_state(rng, params.n)
        expected = _closed_form(params, q, dq)
        scale = np.abs(expected).max()
        assert np.allclose(snake.friction(q, dq), expected, rtol=1e-12, atol=1e-13 * scale)
        assert np.allclose(snake.friction_force(q, dq), expected, rtol=1e-12,
                           atol=1e-13 * scale)
        assert np.allclose(passes(q, dq), expected, rtol=1e-12, atol=1e-13 * scale)
    c_closed = paper.friction_matrix(params, q)
    assert np.allclose(snake.friction.matrix(q), c_closed, rtol=1e-12,
                       atol=1e-14 * np.abs(c_closed).max())


def test_long_anisotropic_robots_use_the_rnea_passes() -> None:
    """Beyond WHEELED_TWIN_MAX_LINKS links anisotropic friction goes through RNEA passes;
    isotropic friction always does (one pass)."""
    from snake_pin.friction import WHEELED_TWIN_MAX_LINKS

    n = WHEELED_TWIN_MAX_LINKS + 1
    assert not Snake(SnakeParams.table1(n=n, c_y=5.0)).friction.uses_twin_crba
    assert Snake(SnakeParams.table1(n=n - 1, c_y=5.0)).friction.uses_twin_crba
    assert not Snake(SnakeParams.table1(n=5)).friction.uses_twin_crba


def test_twin_is_depth_first(rng: np.random.Generator) -> None:
    """The twin (wheels appended tail first) has a right CRBA: its RNEA's columns."""
    from snake_pin.friction import damping_twin

    params = SnakeParams.table1(c_x=0.3, c_y=(0.3, 9.0, 0.3, 4.0, 12.0, 0.3, 7.0, 0.3, 2.0, 5.0),
                                c_theta=1e-3)
    snake = Snake(params)
    twin = damping_twin(snake.model, params)
    size = twin.nq
    assert size == snake.nq + params.n
    for _ in range(5):
        q_ext = np.zeros(size)
        q_ext[:snake.nq] = random_state(rng, params.n)[0]
        mass = pin.crba(twin, twin.createData(), q_ext, pin.Convention.WORLD)
        columns = np.column_stack([pin.rnea(twin, twin.createData(), q_ext, np.zeros(size), e)
                                   for e in np.eye(size)])
        assert np.allclose(np.triu(mass), np.triu(columns), rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("scaled_axis", [True, False], ids=["prismatic", "lever"])
def test_wheels_weigh_minus_one(scaled_axis: bool, rng: np.random.Generator,
                                monkeypatch: pytest.MonkeyPatch) -> None:
    """The twin's wheel block M_ww is -I at any posture, for c_y above and below c_x, and
    Q is the closed form's, on a scaled prismatic axis and on the lever (a Pinocchio that
    normalises axes), by both routes."""
    from snake_pin import friction

    monkeypatch.setattr(friction, "_scaled_axis_kept", lambda: scaled_axis)
    params = SnakeParams.table1(c_x=0.3, c_y=(0.3, 9.0, 0.1, 4.0, 1e-6, 0.3, 7.0, 0.3, 2.0, 5.0),
                                c_theta=1e-3)
    crba_route = FrictionModel(params, Snake(params).model)
    passes = _rnea_passes(params, monkeypatch)
    nq = params.n + 2
    rolling = np.array([float(c != 0.3) for c in params.per_link("c_y")])[::-1]
    for _ in range(5):
        q, dq = random_state(rng, params.n)
        q_ext = np.zeros(crba_route.size)
        q_ext[:nq] = q
        mass = pin.crba(crba_route.twin, crba_route.twin.createData(), q_ext,
                        pin.Convention.WORLD)
        assert np.allclose(mass[nq:, nq:], -np.diag(rolling), rtol=0.0, atol=1e-12)
        expected = _closed_form(params, q, dq)
        for route in (crba_route, passes):
            assert np.allclose(route(q, dq), expected, rtol=1e-12,
                               atol=1e-13 * np.abs(expected).max())


@pytest.mark.parametrize(("c_x", "c_y"), [(0.0, 25.0), (25.0, 0.0), (0.5, 5.0)])
def test_twin_far_from_the_origin(c_x: float, c_y: float, rng: np.random.Generator) -> None:
    """999 m from the origin Q is still the closed form's to 1e-11, also where a link's
    smaller coefficient is 0 (link and wheel weigh 0 together; measured 1e-12; a wheel on
    a lever was 1e-8 off there)."""
    params = SnakeParams.table1(c_x=c_x, c_y=c_y, c_theta=1e-3)
    friction = FrictionModel(params, Snake(params).model)
    for _ in range(10):
        q, dq = random_state(rng, params.n)
        q[:2] += 999.0
        expected = _closed_form(params, q, dq)
        assert np.abs(friction(q, dq) - expected).max() < 1e-11 * np.abs(expected).max()


def test_links_with_isotropic_friction_among_wheeled_ones(rng: np.random.Generator) -> None:
    """Per-link c_y equal to c_x on some links (their wheels weigh 0): the same Q, and the
    free acceleration of calc_affine is forward_dynamics at zero torque."""
    params = SnakeParams.table1(c_x=0.3, c_y=(0.3, 9.0, 0.3, 4.0, 12.0, 0.3, 7.0, 0.3, 2.0, 5.0),
                                c_theta=1e-3)
    snake = Snake(params)
    assert snake.friction.has_wheels and snake.friction.uses_twin_crba
    data = snake.create_data()
    for _ in range(10):
        q, dq = random_state(rng, params.n)
        expected = _closed_form(params, q, dq)
        scale = np.abs(expected).max()
        assert np.allclose(snake.friction(q, dq), expected, rtol=1e-12, atol=1e-13 * scale)
        b, _ = snake.calc_affine(data, q, dq)
        assert np.allclose(b, snake.forward_dynamics(q, dq, np.zeros(params.n - 1)),
                           rtol=1e-10, atol=1e-10)


def test_a_foreign_model_is_a_parameter_error() -> None:
    """The damping twin of a model that is not the robot's paper model is refused with a
    ParameterError naming the model (it was a bare ValueError)."""
    from snake_pin import ParameterError
    from snake_pin.friction import damping_twin

    params = SnakeParams.table1(n=5)
    other = Snake(SnakeParams.table1(n=6)).model
    with pytest.raises(ParameterError, match="model must be the paper model of the 5-link"):
        damping_twin(other, params)
    with pytest.raises(ParameterError, match="model must be the paper model"):
        FrictionModel(params, other)
    with pytest.raises(ParameterError, match="paper model of the 8-link snake"):
        damping_twin(other, SnakeParams.table1(n=8))


def test_a_friction_model_of_its_own_equals_the_snakes(rng: np.random.Generator) -> None:
    """A FrictionModel made apart from the Snake (on its paper model) gives the same Q and
    derivatives as the snake's, also after pickling; a FrictionData needs a FrictionModel."""
    import pickle

    from snake_pin import ParameterError
    from snake_pin.friction import FrictionData

    params = SnakeParams.table1(n=5, c_y=4.0)
    snake = Snake(params)
    alone = pickle.loads(pickle.dumps(FrictionModel(params, snake.model)))
    q, dq = random_state(rng, 5)
    assert np.array_equal(alone(q, dq), snake.friction(q, dq))
    for mine, theirs in zip(alone.derivatives(q, dq), snake.friction.derivatives(q, dq),
                            strict=True):
        assert np.array_equal(mine, theirs)
    with pytest.raises(ParameterError, match="friction"):
        FrictionData(snake)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="needs the snake's Pinocchio model"):
        FrictionModel(params)


_DERIVATIVE_ROBOTS = {
    "isotropic": {"c_x": 0.5, "c_y": 0.5, "c_theta": 7.2e-5},
    "c_y > c_x": {"c_x": 0.5, "c_y": 25.0, "c_theta": 7.2e-5},
    "c_x > c_y": {"c_x": 3.0, "c_y": 0.1, "c_theta": 0.0},
    "mixed": {"c_x": 0.3, "c_y": (0.3, 9.0, 0.1, 4.0, 1e-6, 0.3, 7.0, 0.3, 2.0, 5.0),
              "c_theta": 1e-3},
}


@pytest.mark.parametrize("route", ["crba", "rnea passes"])
@pytest.mark.parametrize("scaled_axis", [True, False], ids=["prismatic", "lever"])
@pytest.mark.parametrize("robot", sorted(_DERIVATIVE_ROBOTS))
def test_calc_derivatives_match_central_differences(robot: str, scaled_axis: bool, route: str,
                                                    rng: np.random.Generator,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """calc_derivatives' Q is calc_force's and its Jacobians are central differences of it
    (Q is linear in dq: those are exact to round-off), for wheels that slide either way,
    weigh 0 or sit on a lever, on both routes; into the data's buffers, whatever that data
    evaluated before, and derivatives() gives the same numbers."""
    from snake_pin import friction

    monkeypatch.setattr(friction, "_scaled_axis_kept", lambda: scaled_axis)
    params = SnakeParams.table1(**_DERIVATIVE_ROBOTS[robot])
    model = (_rnea_passes(params, monkeypatch) if route == "rnea passes"
             else FrictionModel(params, Snake(params).model))
    data, probe = model.create_data(), model.create_data()
    nq, h = params.n + 2, 1e-6
    for _ in range(3):
        q, dq = random_state(rng, params.n)
        model.calc_force(data, *random_state(rng, params.n))  # another state before
        force, dforce_dq, dforce_dv = model.calc_derivatives(data, q, dq)
        assert force is data.force and dforce_dq is data.dforce_dq
        assert np.array_equal(data.jacobian, np.hstack([dforce_dq, dforce_dv]))
        expected = model.calc_force(probe, q, dq)
        assert np.allclose(force, expected, rtol=1e-13, atol=1e-14 * np.abs(expected).max())
        columns = []
        for k in range(2 * nq):
            step = np.zeros(2 * nq)
            step[k] = h
            plus = model.calc_force(probe, q + step[:nq], dq + step[nq:]).copy()
            minus = model.calc_force(probe, q - step[:nq], dq - step[nq:])
            columns.append((plus - minus) / (2.0 * h))
        differences = np.array(columns).T
        assert np.abs(data.jacobian - differences).max() <= 1e-7 * np.abs(differences).max()
        for mine, theirs in zip(model.derivatives(q, dq), (force, dforce_dq, dforce_dv),
                                strict=True):
            assert np.array_equal(mine, theirs)


def test_calc_force_after_calc_derivatives_is_unchanged(rng: np.random.Generator) -> None:
    """A data that evaluated derivatives gives calc_force's numbers to the bit (the closed
    loop's step shares the twin's buffers with the derivatives)."""
    for c_y in (0.5, 25.0):
        params = SnakeParams.table1(c_y=c_y)
        model = Snake(params).friction
        shared, fresh = model.create_data(), model.create_data()
        for _ in range(5):
            q, dq = random_state(rng, params.n)
            model.calc_derivatives(shared, *random_state(rng, params.n))
            assert np.array_equal(model.calc_force(shared, q, dq),
                                  model.calc_force(fresh, q, dq))
