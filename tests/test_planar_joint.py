"""Planar-joint models of our URDFs (plain Pinocchio) against the paper-coordinate Snake."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from snake_pin import ConfigurationError, ParameterError, Snake, SnakeParams
from snake_pin.planar_joint import (
    paper_dynamics,
    paper_to_planar,
    paper_to_planar_acceleration,
    paper_to_planar_force,
    planar_layout,
    planar_to_paper,
    planar_to_paper_acceleration,
    velocity_map,
)
from snake_pin.robot_file import read_urdf
from snake_pin.urdf import urdf_string
from tests.conftest import heterogeneous_params, random_state

ROOT = Path(__file__).resolve().parents[1]
THIRD_PARTY = Path(__file__).resolve().parent / "data" / "third_party_snake.urdf"
FRICTIONLESS = {"c_x": 0.0, "c_y": 0.0, "c_theta": 0.0}


def _planar(params: SnakeParams) -> pin.Model:
    """Pinocchio's model of our URDF of ``params``, as buildModelFromUrdf gives it."""
    return pin.buildModelFromXML(urdf_string(params))


def _robots(rng: np.random.Generator) -> list[tuple[pin.Model, Snake]]:
    """(planar model, friction-free Snake) for table1's committed file and random robots."""
    table1 = pin.buildModelFromUrdf(str(ROOT / "urdf" / "snake_table1.urdf"))
    out = [(table1, Snake(SnakeParams.table1(**FRICTIONLESS)))]
    for n in (4, 10):
        params = heterogeneous_params(rng, n, friction="none")
        out.append((_planar(params), Snake(params)))
    return out


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def test_layout_of_our_urdf() -> None:
    """Our URDF gives a planar root (nq = n + 3, nv = n + 2) and n - 1 revolute +z joints."""
    model = pin.buildModelFromUrdf(str(ROOT / "urdf" / "snake_engine.urdf"))
    layout = planar_layout(model)
    assert (layout.n, layout.nq, layout.nv) == (8, 11, 10)
    assert layout.idx_q.tolist() == list(range(4, 11))
    assert not layout.unbounded.any() and np.all(layout.signs == 1.0)


@pytest.mark.parametrize("n", [4, 10])
def test_state_round_trip(n: int, rng: np.random.Generator) -> None:
    """paper -> planar -> paper returns the state; q_planar holds (cos, sin) of theta_1."""
    model = _planar(heterogeneous_params(rng, n))
    for _ in range(10):
        q, dq = random_state(rng, n)
        q_planar, v_planar = paper_to_planar(model, q, dq)
        assert q_planar.shape == (n + 3,) and v_planar.shape == (n + 2,)
        np.testing.assert_allclose(q_planar[2:4], [np.cos(q[2]), np.sin(q[2])], atol=1e-15)
        np.testing.assert_allclose(q_planar[4:], q[3:], atol=0)
        q_back, dq_back = planar_to_paper(model, q_planar, v_planar)
        np.testing.assert_allclose(q_back, q, atol=1e-14)
        np.testing.assert_allclose(dq_back, dq, atol=1e-14)


def test_velocity_is_pinocchios_body_frame_velocity(rng: np.random.Generator) -> None:
    """Integrating v_planar with pin.integrate moves the paper state by q' dt (central diff)."""
    model = _planar(heterogeneous_params(rng, 10))
    step = 1e-6
    for _ in range(10):
        q, dq = random_state(rng, 10)
        q_planar, v_planar = paper_to_planar(model, q, dq)
        ahead, _ = planar_to_paper(model, pin.integrate(model, q_planar, step * v_planar), dq)
        behind, _ = planar_to_paper(model, pin.integrate(model, q_planar, -step * v_planar), dq)
        np.testing.assert_allclose((ahead - behind) / (2 * step), dq, atol=1e-7)
        # the base velocity is the head's world velocity seen in the head's frame
        c, s = np.cos(q[2]), np.sin(q[2])
        np.testing.assert_allclose(v_planar[:2], [c * dq[0] + s * dq[1],
                                                  -s * dq[0] + c * dq[1]], atol=1e-14)


def test_inertia_matrix_agrees(rng: np.random.Generator) -> None:
    """H_paper = T^T M_planar T equals Snake's CRBA to 1e-12 relative."""
    for model, snake in _robots(rng):
        data = model.createData()
        for _ in range(10):
            q, dq = random_state(rng, snake.n)
            q_planar, _ = paper_to_planar(model, q, dq)
            mass = pin.crba(model, data, q_planar)
            mass = np.triu(mass) + np.triu(mass, 1).T
            t_map = velocity_map(model, q)
            assert _relative(t_map.T @ mass @ t_map, snake.inertia_matrix(q)) < 1e-12


def test_paper_dynamics_gives_h_and_h(rng: np.random.Generator) -> None:
    """paper_dynamics' H and h are Snake's inertia_matrix and (friction-free) coriolis."""
    for model, snake in _robots(rng):
        data = model.createData()
        for _ in range(10):
            q, dq = random_state(rng, snake.n)
            mass, bias = paper_dynamics(model, data, q, dq)
            assert _relative(mass, snake.inertia_matrix(q)) < 1e-12
            assert _relative(bias, snake.coriolis(q, dq)) < 1e-12


def test_aba_agrees_with_forward_dynamics(rng: np.random.Generator) -> None:
    """pin.aba on the planar model, converted (velocity-product term included), is q''."""
    for model, snake in _robots(rng):
        data = model.createData()
        for _ in range(20):
            q, dq = random_state(rng, snake.n)
            tau = rng.normal(size=snake.n - 1)
            q_planar, v_planar = paper_to_planar(model, q, dq)
            tau_planar = paper_to_planar_force(model, q, snake.generalized_torque(tau))
            a_planar = pin.aba(model, data, q_planar, v_planar, tau_planar)
            expected = snake.forward_dynamics(q, dq, tau)
            got = planar_to_paper_acceleration(model, q_planar, v_planar, a_planar)
            assert _relative(got, expected) < 1e-10
            np.testing.assert_allclose(
                paper_to_planar_acceleration(model, q, dq, expected), a_planar,
                atol=1e-9 * np.max(np.abs(a_planar)))
            # without the velocity-product term T' q' the head's acceleration is wrong
            naive = velocity_map(model, q).T @ a_planar
            assert _relative(naive[:2], expected[:2]) > 1e-6


def test_third_party_urdf_with_continuous_and_minus_z_joints(rng: np.random.Generator) -> None:
    """Continuous (cos, sin) joints and a -z joint convert right (q_i = -phi_i)."""
    model = pin.buildModelFromXML(THIRD_PARTY.read_text(), pin.JointModelPlanar())
    layout = planar_layout(model)
    assert layout.unbounded.tolist() == [True, False, True]
    assert layout.signs.tolist() == [1.0, -1.0, 1.0]
    assert layout.nq == 4 + 3 + 2
    snake = Snake(read_urdf(THIRD_PARTY))
    data = model.createData()
    for _ in range(20):
        q, dq = random_state(rng, 4)
        tau = rng.normal(size=3)
        tau[1] = 0.0  # joint 2 is passive in the Snake (effort 0)
        q_planar, v_planar = paper_to_planar(model, q, dq)
        assert q_planar[6] == pytest.approx(-q[4])  # yaw_2 turns about -z
        q_back, dq_back = planar_to_paper(model, q_planar, v_planar)
        np.testing.assert_allclose(q_back, q, atol=1e-14)
        np.testing.assert_allclose(dq_back, dq, atol=1e-14)
        a_planar = pin.aba(model, data, q_planar, v_planar,
                           paper_to_planar_force(model, q, snake.generalized_torque(tau)))
        got = planar_to_paper_acceleration(model, q_planar, v_planar, a_planar)
        assert _relative(got, snake.forward_dynamics(q, dq, tau)) < 1e-10


def test_refuses_other_models() -> None:
    """Models that are not a planar-root chain are refused naming the joint."""
    with pytest.raises(ParameterError, match="'base_x'"):
        planar_layout(Snake(SnakeParams.table1(n=4)).model)
    fixed_base = pin.buildModelFromXML(urdf_string(SnakeParams.table1(n=4),
                                                   floating_base=False))
    with pytest.raises(ParameterError, match=r"'joint_1'.*not the planar base"):
        planar_layout(fixed_base)


def test_refuses_bad_vectors() -> None:
    """Wrong sizes and non-finite entries are ConfigurationError naming the argument."""
    model = _planar(SnakeParams.table1(n=4))
    with pytest.raises(ConfigurationError, match="q_planar"):
        planar_to_paper(model, np.zeros(6), np.zeros(6))
    with pytest.raises(ConfigurationError, match="dq"):
        paper_to_planar(model, np.zeros(6), [0.0, np.nan, 0, 0, 0, 0])
