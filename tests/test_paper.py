"""Pinocchio model against the paper's closed form (eqs. 3-20), generalised per link."""

from __future__ import annotations

import numpy as np
import pytest

from snake_pin import ConfigurationError, ParameterError, Snake, SnakeParams, paper

from .conftest import heterogeneous_params, random_state

FRICTIONS = {
    "none": {"c_x": 0.0, "c_y": 0.0, "c_theta": 0.0},
    "isotropic": {"c_x": 0.5, "c_y": 0.5, "c_theta": 7.2e-5},
    "anisotropic": {"c_x": 0.3, "c_y": 6.0, "c_theta": 2e-3},
}


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


@pytest.mark.parametrize("n", [4, 10, 30])
@pytest.mark.parametrize("friction", sorted(FRICTIONS))
def test_inertia_and_bias_match_closed_form(n: int, friction: str,
                                            rng: np.random.Generator) -> None:
    """H (19) and h (20) from Pinocchio equal the closed form to 1e-10 relative, 50 states."""
    params = SnakeParams.table1(n=n, **FRICTIONS[friction])
    snake = Snake(params)
    for _ in range(50):
        q, dq = random_state(rng, n)
        assert _rel(snake.inertia_matrix(q), paper.inertia_matrix(params, q)) < 1e-10
        assert _rel(snake.bias(q, dq), paper.bias(params, q, dq)) < 1e-10


@pytest.mark.parametrize("n", [4, 10, 30])
@pytest.mark.parametrize("friction", ["none", "isotropic", "anisotropic"])
def test_heterogeneous_robot_matches_generalised_closed_form(
        n: int, friction: str, rng: np.random.Generator) -> None:
    """Per-link lengths, masses, inertias, CM offsets, friction: H, h agree to 1e-10, 50 states."""
    for _ in range(50):
        params = heterogeneous_params(rng, n, friction)
        snake = Snake(params)
        q, dq = random_state(rng, n)
        assert _rel(snake.inertia_matrix(q), paper.inertia_matrix(params, q)) < 1e-10
        assert _rel(snake.bias(q, dq), paper.bias(params, q, dq)) < 1e-10
        if friction != "none":
            assert _rel(snake.friction.matrix(q), paper.friction_matrix(params, q)) < 1e-10


def test_uniform_robot_keeps_the_printed_k() -> None:
    """For equal links with the CM in the middle, K is l on the diagonal and 2l below (eq. 4)."""
    params = SnakeParams.table1(n=5)
    half = params.half_length
    printed = half * (np.eye(5) + 2.0 * np.tril(np.ones((5, 5)), -1))
    assert np.array_equal(paper.k_matrix(params), printed)


@pytest.mark.parametrize("n", [4, 10])
def test_friction_is_minus_c_dq(n: int, rng: np.random.Generator) -> None:
    """The fast friction route is -C(q) dq with C of eqs. (11)-(13), and C is symmetric PSD."""
    for params in (SnakeParams.table1(n=n, **FRICTIONS["anisotropic"]),
                   heterogeneous_params(rng, n)):
        snake = Snake(params)
        for _ in range(20):
            q, dq = random_state(rng, n)
            c = paper.friction_matrix(params, q)
            assert np.allclose(c, c.T, atol=1e-14)
            assert np.linalg.eigvalsh(c).min() > -1e-12
            assert _rel(snake.friction_force(q, dq), -c @ dq) < 1e-12


def test_link_positions_follow_eq3(rng: np.random.Generator) -> None:
    """CM positions from Pinocchio equal x = 1 x_h + K cos(theta), y likewise (eq. 3)."""
    for params in (SnakeParams.table1(), heterogeneous_params(rng, 7)):
        snake = Snake(params)
        k = paper.k_matrix(params)
        for _ in range(10):
            q, _ = random_state(rng, params.n)
            theta = paper.link_angles(q)
            poses = snake.link_poses(q)
            assert np.allclose(poses[:, 0], q[0] + k @ np.cos(theta), atol=1e-12)
            assert np.allclose(poses[:, 1], q[1] + k @ np.sin(theta), atol=1e-12)
            assert np.allclose(np.cos(poses[:, 2] - theta), 1.0)
            points = snake.joint_points(q)
            assert np.allclose(points[0], q[:2])
            segments = np.linalg.norm(np.diff(points, axis=0), axis=1)
            assert np.allclose(segments, params.link_lengths, atol=1e-12)


def test_g2_is_the_friction_weighted_cm_sum(rng: np.random.Generator) -> None:
    """g_2 (67) equals the printed uniform formula and sum c_i p_i per link; needs c_x = c_y."""
    params = SnakeParams.table1()
    n, c, half = params.n, params.c_x, params.half_length
    q, _ = random_state(rng, n)
    theta = paper.link_angles(q)
    weights = 2 * n - 2 * np.arange(1, n + 1) + 1
    printed = [n * c * q[0] + c * half * weights @ np.cos(theta),
               n * c * q[1] + c * half * weights @ np.sin(theta)]
    assert np.allclose(paper.g2(params, q), printed, rtol=1e-13)
    het = heterogeneous_params(rng, n, "isotropic")
    poses = Snake(het).link_poses(q)
    assert np.allclose(paper.g2(het, q), het.per_link("c_x") @ poses[:, :2], rtol=1e-12)
    with pytest.raises(ParameterError, match="isotropic"):
        paper.g2(params.replace(c_y=5.0), q)


def test_closed_form_validates_sizes() -> None:
    """A q of the wrong size or with NaN is a ConfigurationError, not a numpy traceback."""
    params = SnakeParams.table1()
    with pytest.raises(ConfigurationError):
        paper.inertia_matrix(params, np.zeros(5))
    with pytest.raises(ConfigurationError):
        paper.inertia_matrix(params, np.full(12, np.nan))


@pytest.mark.parametrize("q", [[0.0, 0.0, 0.1], [[0.0] * 5], [0.0, 0.0, 0.1, float("nan")],
                               None, "abcd"])
def test_link_angles_checks_its_vector(q: object) -> None:
    """link_angles is public: fewer than 4 entries, 2-D, NaN or text are ConfigurationErrors."""
    with pytest.raises(ConfigurationError, match="q"):
        paper.link_angles(q)  # type: ignore[arg-type]
    assert paper.link_angles([1.0, 2.0, 0.5, 0.25]).tolist() == [0.5, 0.75]


@pytest.mark.parametrize("call", [lambda: paper.k_matrix(None),
                                  lambda: paper.inertia_matrix({"n": 4}, np.zeros(6)),
                                  lambda: paper.l_matrix(True),
                                  lambda: paper.jacobian_q(4.0)])
def test_robot_and_size_arguments_are_checked(call: object) -> None:
    """A robot that is not a SnakeParams, or n given as a bool or float, is a ParameterError."""
    with pytest.raises(ParameterError, match=r"params|n must"):
        call()  # type: ignore[operator]
