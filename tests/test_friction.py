"""Friction: the vectorised route equals the pin.Force external-force reference."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from snake_pin import Snake, SnakeParams
from snake_pin.friction import FrictionModel, friction_forces

from .conftest import random_state


@pytest.mark.parametrize("c", [(0.5, 0.5, 7.2e-5), (0.2, 8.0, 1e-3), (3.0, 0.1, 0.0)])
def test_vectorised_friction_equals_external_forces(c: tuple, rng: np.random.Generator) -> None:
    """Q of the twin and numpy routes equals RNEA(no fext) - RNEA(fext) with pin.Force."""
    params = SnakeParams.table1(c_x=c[0], c_y=c[1], c_theta=c[2])
    snake = Snake(params)
    numpy_route = FrictionModel(params)
    zero = np.zeros(snake.nv)
    for _ in range(20):
        q, dq = random_state(rng, params.n)
        fext = friction_forces(snake.model, snake.data, params, q, dq)
        reference = (pin.rnea(snake.model, snake.data, q, dq, zero)
                     - pin.rnea(snake.model, snake.data, q, dq, zero, fext))
        assert np.allclose(snake.friction(q, dq), reference, rtol=1e-12, atol=1e-13)
        assert np.allclose(snake.friction.of_state(np.r_[q, dq]), reference, atol=1e-13)
        assert np.allclose(numpy_route(q, dq), reference, rtol=1e-12, atol=1e-13)


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
def test_damping_twin_equals_numpy_route(c: tuple, rng: np.random.Generator) -> None:
    """Isotropic friction: the damping twin's RNEA and CRBA equal the complex-number route."""
    params = SnakeParams.table1(c_x=c[0], c_y=c[1], c_theta=c[2])
    snake = Snake(params)
    assert snake.friction.uses_twin and not snake.friction.has_wheels
    numpy_route = FrictionModel(params)
    assert not numpy_route.uses_twin
    for _ in range(20):
        q, dq = random_state(rng, params.n)
        assert np.allclose(snake.friction(q, dq), numpy_route(q, dq), rtol=1e-12, atol=1e-13)
        assert np.allclose(snake.friction.of_state(np.r_[q, dq]), numpy_route(q, dq),
                           rtol=1e-12, atol=1e-13)
        c_twin = snake.friction.matrix(q)
        assert np.allclose(c_twin, numpy_route.matrix(q), rtol=1e-12, atol=1e-13)
        assert np.allclose(c_twin, c_twin.T, atol=0.0)


@pytest.mark.parametrize("c", [(0.5, 25.0, 7.2e-5), (0.04, 61.4, 1.6e-4), (3.0, 0.1, 0.0)])
def test_twin_with_wheels_equals_numpy_route(c: tuple, rng: np.random.Generator) -> None:
    """Anisotropic friction: the twin whose wheels roll along the links gives the same Q."""
    params = SnakeParams.table1(c_x=c[0], c_y=c[1], c_theta=c[2])
    snake = Snake(params)
    assert snake.friction.uses_twin and snake.friction.has_wheels
    numpy_route = FrictionModel(params)
    for _ in range(20):
        q, dq = random_state(rng, params.n)
        expected = numpy_route(q, dq)
        scale = np.abs(expected).max()
        assert np.allclose(snake.friction(q, dq), expected, rtol=1e-12, atol=1e-13 * scale)
        assert np.allclose(snake.friction.of_state(np.r_[q, dq]), expected, rtol=1e-12,
                           atol=1e-13 * scale)
    assert np.allclose(snake.friction.matrix(q), numpy_route.matrix(q), rtol=1e-14)


def test_long_anisotropic_robots_use_numpy() -> None:
    """Beyond WHEELED_TWIN_MAX_LINKS links anisotropic friction goes through numpy."""
    from snake_pin.friction import WHEELED_TWIN_MAX_LINKS

    n = WHEELED_TWIN_MAX_LINKS + 1
    assert not Snake(SnakeParams.table1(n=n, c_y=5.0)).friction.uses_twin
    assert Snake(SnakeParams.table1(n=n)).friction.uses_twin  # isotropic: always the twin


def test_force_passes_twin_is_depth_first(rng: np.random.Generator) -> None:
    """The passes' twin (wheels appended tail first) has a right CRBA: its RNEA's columns."""
    from snake_pin.friction import ForcePasses

    params = SnakeParams.table1(c_x=0.3, c_y=(0.3, 9.0, 0.3, 4.0, 12.0, 0.3, 7.0, 0.3, 2.0, 5.0),
                                c_theta=1e-3)
    snake = Snake(params)
    passes = ForcePasses(snake.model, params)
    twin, size = passes.twin, passes.size
    assert size == snake.nq + params.n
    for _ in range(5):
        q_ext = np.zeros(size)
        q_ext[:snake.nq] = random_state(rng, params.n)[0]
        mass = pin.crba(twin, twin.createData(), q_ext, pin.Convention.WORLD)
        columns = np.column_stack([pin.rnea(twin, twin.createData(), q_ext, np.zeros(size), e)
                                   for e in np.eye(size)])
        assert np.allclose(np.triu(mass), np.triu(columns), rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("scaled_axis", [True, False], ids=["prismatic", "lever"])
def test_force_passes_wheels_weigh_minus_one(scaled_axis: bool, rng: np.random.Generator,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """The passes' wheel block M_ww is -I at any posture, for c_y above and below c_x, and
    Q is numpy's, on a scaled prismatic axis and on the lever (a Pinocchio that normalises
    axes)."""
    from snake_pin import friction

    monkeypatch.setattr(friction, "_scaled_axis_kept", lambda: scaled_axis)
    params = SnakeParams.table1(c_x=0.3, c_y=(0.3, 9.0, 0.1, 4.0, 1e-6, 0.3, 7.0, 0.3, 2.0, 5.0),
                                c_theta=1e-3)
    snake = Snake(params)
    passes = friction.ForcePasses(snake.model, params)
    numpy_route = FrictionModel(params)
    rolling = np.array([float(c != 0.3) for c in params.per_link("c_y")])[::-1]
    for _ in range(5):
        q, dq = random_state(rng, params.n)
        q_ext = np.zeros(passes.size)
        q_ext[:snake.nq] = q
        mass = pin.crba(passes.twin, passes.twin.createData(), q_ext, pin.Convention.WORLD)
        block = mass[snake.nq:, snake.nq:]
        assert np.allclose(block, -np.diag(rolling), rtol=0.0, atol=1e-12)
        expected = numpy_route(q, dq)
        assert np.allclose(passes.force(q, dq), expected, rtol=1e-12,
                           atol=1e-13 * np.abs(expected).max())


@pytest.mark.parametrize(("c_x", "c_y"), [(0.0, 25.0), (25.0, 0.0), (0.5, 5.0)])
def test_force_passes_far_from_the_origin(c_x: float, c_y: float,
                                          rng: np.random.Generator) -> None:
    """999 m from the origin Q is still numpy's to 1e-11, also where a link's smaller
    coefficient is 0 (link and wheel weigh 0 together; measured 1e-12; a wheel on a lever
    was 1e-8 off there)."""
    from snake_pin.friction import ForcePasses

    params = SnakeParams.table1(c_x=c_x, c_y=c_y, c_theta=1e-3)
    passes = ForcePasses(Snake(params).model, params)
    numpy_route = FrictionModel(params)
    for _ in range(10):
        q, dq = random_state(rng, params.n)
        q[:2] += 999.0
        expected = numpy_route(q, dq)
        assert np.abs(passes.force(q, dq) - expected).max() < 1e-11 * np.abs(expected).max()


def test_links_with_isotropic_friction_among_wheeled_ones(rng: np.random.Generator) -> None:
    """Per-link c_y equal to c_x on some links (their wheels weigh 0): the same Q."""
    params = SnakeParams.table1(c_x=0.3, c_y=(0.3, 9.0, 0.3, 4.0, 12.0, 0.3, 7.0, 0.3, 2.0, 5.0),
                                c_theta=1e-3)
    snake = Snake(params)
    numpy_route = FrictionModel(params)
    assert snake.friction.has_wheels and snake.friction.passes is not None
    for _ in range(10):
        q, dq = random_state(rng, params.n)
        expected = numpy_route(q, dq)
        scale = np.abs(expected).max()
        assert np.allclose(snake.friction(q, dq), expected, rtol=1e-12, atol=1e-13 * scale)
        x = np.r_[q, dq]
        b, _ = snake.fast_dynamics.affine(x)
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


def test_derivatives_without_the_model_are_a_parameter_error(
        rng: np.random.Generator) -> None:
    """FrictionModel(params) has no twin: its derivatives are refused in one line."""
    from snake_pin import ParameterError

    params = SnakeParams.table1(n=5)
    q, dq = random_state(rng, 5)
    with pytest.raises(ParameterError, match="model="):
        FrictionModel(params).derivatives(q, dq)
