"""Velocity-level Lyapunov-like law: the minimiser of V under the quasi-static connection."""

from __future__ import annotations

import numpy as np
import pytest

from snake_pin import ParameterError, Snake, SnakeParams, simulate
from snake_pin.control import Controller, QuasiStaticLyapunovController
from snake_pin.gaits import arc

from .conftest import head_first_state


@pytest.mark.parametrize("passive", [(), (5,)])
def test_command_minimises_v(passive: tuple, rng: np.random.Generator) -> None:
    """V at the commanded joint velocity is below V at any perturbed joint velocity."""
    snake = Snake(SnakeParams.engine(c_x=0.04, c_y=60.0, passive=passive))
    ctrl = QuasiStaticLyapunovController(snake)
    x, t = head_first_state(rng, snake.n, spread=0.2, joints=1.0, speed=0.1), 2.0
    rate, value = ctrl.velocity_command(x, t)
    jac = ctrl.connection(x[:snake.nq])
    w_r, dw_r, _ = ctrl.reference(t)
    _, dphi_r, _ = ctrl.gait.derivatives(t)
    target_u = np.r_[dw_r + ctrl.k_w1 @ (w_r - x[:3]), dphi_r[ctrl._u[3:] - 3]]

    def v_of(a: np.ndarray) -> float:
        ru, ra = jac @ a - target_u, a - dphi_r[ctrl._a - 3]
        return float(ru @ (ctrl._w_u * ru) + ra @ (ctrl._w_a * ra))

    assert v_of(rate) == pytest.approx(value)
    for _ in range(20):
        assert v_of(rate + 1e-3 * rng.normal(size=rate.size)) > value


def test_connection_predicts_the_head_when_friction_dominates(rng: np.random.Generator) -> None:
    """With friction 100x Table 1's, the simulated w' equals J a' for imposed joint motion."""
    params = SnakeParams.table1(c_x=50.0, c_y=500.0, c_theta=1e-2)
    snake = Snake(params)
    ctrl = QuasiStaticLyapunovController(snake)
    rate = np.sin(np.arange(9))  # joint velocities imposed by a stiff servo

    class Servo(Controller):
        def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
            phi_ref = 0.3 + rate * t
            return 200.0 * (phi_ref - x[3:12]) + 20.0 * (rate - x[15:])

    x0 = np.r_[arc(10, 0.3), np.zeros(12)]
    x0[15:] = rate
    traj = simulate(snake, Servo(), x0, 0.2, dt=1e-4, control_dt=1e-4)
    k = len(traj) - 1
    predicted = ctrl.connection(traj.q[k])[:3] @ traj.dq[k, 3:]
    measured = traj.dq[k, :3]
    assert np.allclose(measured, predicted, atol=0.02 * np.abs(predicted).max())


def test_passive_joint_gets_no_torque(rng: np.random.Generator) -> None:
    """Joint 5 passive: zero torque there, the connection has the phi_5 row."""
    snake = Snake(SnakeParams.engine(c_x=0.04, c_y=60.0, passive=(5,)))
    ctrl = QuasiStaticLyapunovController(snake)
    tau = ctrl(head_first_state(rng, snake.n, spread=0.2, joints=1.0, speed=0.1), 1.0)
    assert tau[4] == 0.0 and np.abs(tau).max() > 0
    assert ctrl.connection(np.r_[0, 0, 0, np.full(7, 0.3)]).shape == (4, 6)


@pytest.mark.parametrize(("changes", "kwargs"), [({"c_x": 0.0}, {}), ({}, {"servo_bandwidth": 0}),
                                                 ({}, {"max_lead": -1.0})])
def test_bad_settings(changes: dict, kwargs: dict) -> None:
    """No friction (no connection) or non-positive servo settings are ParameterErrors."""
    with pytest.raises(ParameterError):
        QuasiStaticLyapunovController(Snake(SnakeParams.engine(**changes)), **kwargs)
