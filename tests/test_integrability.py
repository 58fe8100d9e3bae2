"""Section V: Theorem 2 per split, eq. (67), conservation of g, Theorem 3."""

from __future__ import annotations

import numpy as np
import pytest

from snake_pin import OpenLoop, ParameterError, Serpenoid, Snake, SnakeParams, paper, simulate
from snake_pin.integrability import (
    conserved_quantity,
    conserved_quantity_along,
    implied_g2,
    involutivity,
    lie_bracket_defect,
    partial_integrability,
)

ISO = SnakeParams.table1()
ANISO = SnakeParams.table1(c_y=5.0)


def test_k2_isotropic_is_partially_integrable() -> None:
    """k = 2, c_x = c_y: x_h, y_h cyclic and C1 a gradient (Theorem 2 holds)."""
    res = partial_integrability(Snake(ISO), 2, samples=4)
    assert res.cyclic and res.gradient and res.integrable


def test_k2_anisotropic_fails_gradient_condition() -> None:
    """k = 2, c_x != c_y: C1 is not a gradient (condition 2 fails by O(1))."""
    res = partial_integrability(Snake(ANISO), 2, samples=3)
    assert res.cyclic and not res.gradient and res.gradient_defect > 1e-2


def test_k3_fails_cyclic_condition() -> None:
    """k = 3: theta_1 is not cyclic (condition 1 fails)."""
    res = partial_integrability(Snake(ISO), 3, samples=3)
    assert not res.cyclic and res.cyclic_defect > 1e-2


def test_implied_g2_equals_eq67(rng: np.random.Generator) -> None:
    """The line integral of C1 equals g2 of eq. (67) up to its value at the start."""
    snake = Snake(ISO)
    for _ in range(3):
        q = np.r_[rng.normal(size=3), rng.uniform(-1.5, 1.5, 9)]
        q0 = np.r_[rng.normal(size=3), rng.uniform(-1.5, 1.5, 9)]
        expected = paper.g2(ISO, q) - paper.g2(ISO, q0)
        assert np.allclose(implied_g2(snake, q, q0), expected, atol=1e-12)


def test_g_is_centre_of_mass_form(rng: np.random.Generator) -> None:
    """g = m sum x_i' + c sum x_i, and the vectorised form equals H1 dq + g2."""
    snake = Snake(ISO)
    q = np.r_[rng.normal(size=3), rng.uniform(-1.5, 1.5, 9)]
    dq = rng.normal(size=12)
    g = conserved_quantity(snake, q, dq)
    assert np.allclose(conserved_quantity_along(snake, q[None], dq[None])[0], g, atol=1e-12)
    eps = 1e-7
    poses = snake.link_poses(q)[:, :2]
    velocity = (snake.link_poses(q + eps * dq)[:, :2] - snake.link_poses(q - eps * dq)[:, :2])
    velocity /= 2 * eps
    direct = ISO.mass * velocity.sum(axis=0) + ISO.c_x * poses.sum(axis=0)
    assert np.allclose(g, direct, atol=1e-6)


def _open_loop_run(params: SnakeParams):
    gait = Serpenoid(params.n, np.pi / 4, 1.0, 2.0)
    snake = Snake(params)
    x0 = np.r_[gait.configuration(), np.zeros(snake.nv)]
    run = simulate(snake, OpenLoop(lambda t: 0.02 * np.sin(2 * t + np.arange(params.n - 1))),
                   x0, 3.0, dt=5e-4, control_dt=1e-3)
    return run, conserved_quantity_along(snake, run.q, run.dq)


def test_g_conserved_along_simulated_run_isotropic() -> None:
    """Section V: with c_x = c_y, |g - g(0)| < 1e-8 over a 3 s simulated run."""
    run, g = _open_loop_run(ISO)
    assert np.abs(g - g[0]).max() < 1e-8
    assert np.ptp(run.q[:, 0]) > 1e-3


def test_g_drifts_with_anisotropic_friction() -> None:
    """With c_y = 10 c_x the same run changes g visibly (> 1e-2)."""
    _, g = _open_loop_run(ANISO)
    assert np.abs(g - g[0]).max() > 1e-2


@pytest.mark.parametrize("n", [4, 5])
def test_theorem3_involutive(n: int) -> None:
    """ker [H1 g2] on (q, t) is involutive for n = 4, 5 (bracket defect at noise level)."""
    res = involutivity(Snake(SnakeParams.table1(n=n)), samples=4)
    assert res.involutive and res.defect < 1e-7


def test_bracket_test_detects_non_involutive() -> None:
    """The same bracket test flags the Heisenberg distribution ker(dz - y dx) with O(1)."""
    def forms(z: np.ndarray) -> np.ndarray:
        return np.array([[-z[1], 0.0, 1.0]])
    assert lie_bracket_defect(forms, np.array([0.3, 0.7, 0.1])) > 0.1


def test_bad_split_and_friction() -> None:
    """k outside 1..3 and Theorem 3 with anisotropic friction are ParameterErrors."""
    with pytest.raises(ParameterError):
        partial_integrability(Snake(ISO), 4)
    with pytest.raises(ParameterError):
        involutivity(Snake(ANISO))


@pytest.mark.parametrize("k", [True, 1.0, 0, 4])
def test_split_k_is_an_integer_from_one_to_three(k: object) -> None:
    """k = True would pass a membership test in (1, 2, 3): refused, like 1.0 and 0."""
    snake = Snake(SnakeParams.table1(n=4))
    with pytest.raises(ParameterError, match="k must"):
        partial_integrability(snake, k, samples=1)  # type: ignore[arg-type]


def test_forms_must_give_one_column_per_coordinate() -> None:
    """lie_bracket_defect refuses forms whose A(z) has the wrong width before differencing."""
    with pytest.raises(ParameterError, match=r"forms\(z\) must return an \(r, 3\) array"):
        lie_bracket_defect(lambda z: np.ones((1, 2)), np.zeros(3))
    with pytest.raises(ParameterError, match="forms must be a callable"):
        lie_bracket_defect(np.ones((1, 3)), np.zeros(3))  # type: ignore[arg-type]
