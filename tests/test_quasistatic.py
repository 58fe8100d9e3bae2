"""Velocity-level Lyapunov-like law: the minimiser of V under the quasi-static connection."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snake_pin import ParameterError, Snake, SnakeParams, simulate
from snake_pin.control import QuasiStaticLyapunovController, QuasiStaticOptions
from snake_pin.control.quasistatic import servo_gains
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


def _heavy_head(**changes: object) -> SnakeParams:
    """Table 1 links behind a head twice as long and three times as heavy, friction 100x."""
    c_x = [150.0] + [50.0] * 9
    return SnakeParams(n=10, link_length=[0.24] + [0.12] * 9, mass=[0.546] + [0.182] * 9,
                       inertia=[0.546 * 0.24**2 / 12] + [2.2e-4] * 9, c_x=c_x,
                       c_y=[10 * c for c in c_x], c_theta=[3e-2] + [1e-2] * 9,
                       name="heavy_head").replace(**changes)


@pytest.mark.parametrize("params", [SnakeParams.table1(c_x=50.0, c_y=500.0, c_theta=1e-2),
                                    _heavy_head(), _heavy_head(passive=(5,))],
                         ids=["table1", "heavy_head", "heavy_head_passive"])
def test_connection_predicts_the_head_when_friction_dominates(params: SnakeParams) -> None:
    """With friction 100x Table 1's, the simulated u' (w', passive phi') equals J a'."""
    snake = Snake(params)
    ctrl = QuasiStaticLyapunovController(snake)
    act, passive = np.array(params.actuated) - 1, np.array(params.passive, dtype=int) - 1
    rate = np.sin(np.arange(9))
    k_p, k_d = servo_gains(params, 100.0)  # joint servos stable at the 0.1 ms step

    def servo(x: np.ndarray, t: float) -> np.ndarray:
        tau = k_p * (0.3 + rate * t - x[3:12]) + k_d * (rate - x[15:])
        tau[passive] = 0.0
        return tau

    traj = simulate(snake, servo, np.r_[arc(10, 0.3), np.zeros(12)], 0.2, dt=1e-4,
                    control_dt=1e-4)
    assert traj.status == "completed"
    k = len(traj) - 1
    predicted = ctrl.connection(traj.q[k]) @ traj.dq[k, 3 + act]
    measured = np.r_[traj.dq[k, :3], traj.dq[k, 3 + passive]]
    assert np.abs(measured[:3]).max() > 0.05  # the head does move
    assert np.allclose(measured, predicted, atol=0.02 * np.abs(predicted).max())
    if not params.uniform:  # the same joint motion through equal links' friction: > 10 % off
        uniform = SnakeParams.table1(c_x=50.0, c_y=500.0, c_theta=1e-2, passive=params.passive)
        wrong = QuasiStaticLyapunovController(Snake(uniform)).connection(traj.q[k])
        assert np.abs(wrong @ traj.dq[k, 3 + act] - measured).max() \
            > 0.1 * np.abs(predicted).max()


def test_servo_gains_scale_with_each_link() -> None:
    """K_p, K_d per joint scale as m (2l)^2 of the links it joins (x12 for m x3, 2l x2)."""
    base = SnakeParams.table1()
    k_p, k_d = servo_gains(base, 20.0)
    assert np.allclose(k_p, 400.0 * 0.182 * 0.12**2) and np.allclose(k_d, 40.0 * 0.182 * 0.12**2)
    big = base.replace(mass=3 * 0.182, link_length=0.24)
    assert np.allclose(servo_gains(big, 20.0)[0], 12 * k_p)
    head = servo_gains(_heavy_head(), 20.0)[0]
    assert head[0] == pytest.approx(6.5 * k_p[0])  # (12 + 1) / 2: the head joint's mean
    assert np.allclose(head[1:], k_p[1:])
    ctrl = QuasiStaticLyapunovController(Snake(_heavy_head()))
    assert np.allclose(ctrl.k_p, head)


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


def test_link_without_friction_is_named() -> None:
    """One frictionless link breaks the quasi-static balance: the error names that link."""
    params = SnakeParams.engine(c_y=[5.0] * 6 + [0.0, 5.0])
    with pytest.raises(ParameterError, match=r"link 7: .*c_y = 0"):
        QuasiStaticLyapunovController(Snake(params))


def _straightforward_torques(ctrl: QuasiStaticLyapunovController, states: list[np.ndarray],
                             times: list[float]) -> tuple[list[np.ndarray], list[float]]:
    """The law evaluated directly: C(q) from FrictionModel.matrix, numpy solves, np.clip;
    the torques and V at each command."""
    snake = ctrl.snake
    nq, u, a = snake.nq, ctrl._u, ctrl._a
    w_u, w_a = ctrl._w_u, ctrl._w_a
    reference_a, out, values = None, [], []
    for x, t in zip(states, times, strict=True):
        c = snake.friction.matrix(x[:nq])
        jac = -np.linalg.solve(c[np.ix_(u, u)], c[np.ix_(u, a)])
        w_r, dw_r, _ = ctrl.reference(t)
        _, dphi_r, _ = ctrl.gait.derivatives(t)
        target_u = np.r_[dw_r + ctrl.k_w1 @ (w_r - x[:3]), dphi_r[u[3:] - 3]]
        target_a = dphi_r[a - 3]
        normal = jac.T @ np.diag(w_u) @ jac + np.diag(w_a)
        rate = np.linalg.solve(normal, jac.T @ (w_u * target_u) + w_a * target_a)
        residual_u, residual_a = jac @ rate - target_u, rate - target_a
        values.append(float(residual_u @ (w_u * residual_u) + residual_a @ (w_a * residual_a)))
        joints = x[a]
        if reference_a is None:
            reference_a = joints.copy()
        lead = np.clip(reference_a + rate * ctrl.dt - joints, -ctrl.max_lead, ctrl.max_lead)
        reference_a = joints + lead
        tau = np.zeros(snake.n - 1)
        tau[a - 3] = ctrl.k_p[a - 3] * lead + ctrl.k_d[a - 3] * (rate - x[nq + a])
        out.append(tau)
    return out, values


@pytest.mark.parametrize("params", [SnakeParams.engine(c_x=0.04, c_y=60.0, c_theta=1.6e-4),
                                    SnakeParams.engine(c_x=0.04, c_y=60.0, passive=(5,)),
                                    SnakeParams.engine(c_x=0.5, c_y=0.5),
                                    _heavy_head(passive=(5,))],
                         ids=["engine", "passive", "isotropic", "heavy_head_passive"])
@pytest.mark.parametrize("prepared", [False, True], ids=["alone", "prepared"])
def test_torque_equals_a_straightforward_evaluation(params: SnakeParams, prepared: bool,
                                                    rng: np.random.Generator) -> None:
    """Torques of 6 successive calls (random states, lead clipped or not) equal the law
    evaluated directly to 1e-10, with the time terms prepared in blocks or not; V too."""
    snake = Snake(params)
    ctrl = QuasiStaticLyapunovController(snake)
    times = [0.0, 0.001, 0.002, 7.5, 7.501, 30.0]
    if prepared:
        ctrl.prepare(np.array(times))
    states = [head_first_state(rng, snake.n, spread=0.2, joints=1.0, speed=0.3)
              for _ in times]
    expected, values = _straightforward_torques(ctrl, states, times)
    for x, t, tau, value in zip(states, times, expected, values, strict=True):
        got = ctrl(x, t)
        assert got.shape == (snake.n - 1,)
        assert np.abs(got - tau).max() <= 1e-10 * max(1.0, np.abs(tau).max())
        assert ctrl.signals()["V"] == pytest.approx(value, rel=1e-9, abs=1e-12)
    assert np.abs(np.array(expected)).max() > 0.01  # the torques are not trivially zero
    ctrl.reset()
    assert math.isnan(ctrl.signals()["V"])  # reset forgets the last call


@pytest.mark.parametrize("bandwidth", [0.0, -1.0, None, True, float("inf")])
def test_servo_bandwidth_is_a_positive_number(bandwidth: object) -> None:
    """servo_gains refuses a bandwidth that is not a positive finite number."""
    with pytest.raises(ParameterError, match="bandwidth"):
        servo_gains(SnakeParams.table1(n=4), bandwidth)  # type: ignore[arg-type]


def test_gait_and_reference_are_checked_at_construction() -> None:
    """A gait that is not a Serpenoid or a reference that is not callable is refused."""
    snake = Snake(SnakeParams.table1(n=4))
    with pytest.raises(ParameterError, match="gait must be a Serpenoid"):
        QuasiStaticLyapunovController(snake, gait=(0.5, 1.5))  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="reference"):
        QuasiStaticLyapunovController(snake, reference="line")  # type: ignore[arg-type]


@pytest.mark.parametrize(("field", "value"), [("servo_bandwidth", 0.0), ("max_lead", -0.3),
                                              ("control_dt", None), ("k_w2", 0.0)])
def test_options_refuse_a_field_out_of_bounds(field: str, value: object) -> None:
    """QuasiStaticOptions refuses a field outside its domain in one line naming it."""
    with pytest.raises(ParameterError) as info:
        QuasiStaticOptions(**{field: value})
    message = str(info.value)
    assert "\n" not in message and field.lower() in message.lower()


def test_keywords_and_options_give_the_same_law() -> None:
    """Keywords of the constructor and an options object give the same torque at a state."""
    snake = Snake(SnakeParams.table1(n=5))
    x = head_first_state(np.random.default_rng(3), 5)
    given = {"servo_bandwidth": 10.0, "k_phi": 15.0}
    np.testing.assert_array_equal(
        QuasiStaticLyapunovController(snake, **given)(x, 0.0),
        QuasiStaticLyapunovController(snake, options=QuasiStaticOptions(**given))(x, 0.0))


def test_shares_the_gains_of_the_torque_level_law() -> None:
    """K_w1, K_w2 and K_phi have one default and one domain for both Lyapunov-like laws."""
    from dataclasses import fields

    from snake_pin.control import LyapunovOptions

    torque = {f.name: f for f in fields(LyapunovOptions)}
    for f in fields(QuasiStaticOptions):
        if f.name in torque:
            assert (f.default, dict(f.metadata)) == (torque[f.name].default,
                                                     dict(torque[f.name].metadata))
