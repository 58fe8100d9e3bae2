"""Pinocchio model against the paper's closed form (eqs. 3-20)."""

from __future__ import annotations

import numpy as np
import pytest

from snake_pin import ConfigurationError, Snake, SnakeParams, paper

from .conftest import random_state

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


@pytest.mark.parametrize("n", [4, 10])
def test_friction_is_minus_c_dq(n: int, rng: np.random.Generator) -> None:
    """The fast friction route is -C(q) dq with C of eqs. (11)-(13), and C is symmetric PSD."""
    params = SnakeParams.table1(n=n, **FRICTIONS["anisotropic"])
    snake = Snake(params)
    for _ in range(20):
        q, dq = random_state(rng, n)
        c = paper.friction_matrix(params, q)
        assert np.allclose(c, c.T, atol=1e-14)
        assert np.linalg.eigvalsh(c).min() > -1e-12
        assert _rel(snake.friction_force(q, dq), -c @ dq) < 1e-12


def test_link_positions_follow_eq3(table1: Snake, rng: np.random.Generator) -> None:
    """CM positions from Pinocchio equal x = 1 x_h + K cos(theta), y likewise (eq. 3)."""
    params = table1.params
    k = paper.k_matrix(params.n, params.half_length)
    for _ in range(10):
        q, _ = random_state(rng, params.n)
        theta = paper.link_angles(q)
        poses = table1.link_poses(q)
        assert np.allclose(poses[:, 0], q[0] + k @ np.cos(theta), atol=1e-12)
        assert np.allclose(poses[:, 1], q[1] + k @ np.sin(theta), atol=1e-12)
        assert np.allclose(np.cos(poses[:, 2] - theta), 1.0)
        assert np.allclose(table1.joint_points(q)[0], q[:2])


def test_closed_form_validates_sizes() -> None:
    """A q of the wrong size or with NaN is a ConfigurationError, not a numpy traceback."""
    params = SnakeParams.table1()
    with pytest.raises(ConfigurationError):
        paper.inertia_matrix(params, np.zeros(5))
    with pytest.raises(ConfigurationError):
        paper.inertia_matrix(params, np.full(12, np.nan))
