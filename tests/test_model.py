"""Snake model: dynamics consistency and the physics invariants (H SPD, power, momentum, g)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from snake_pin import ConfigurationError, Snake, SnakeParams, paper

from .conftest import random_state

angles = st.floats(-np.pi, np.pi, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(2, 16), data=st.data())
def test_inertia_matrix_is_symmetric_positive_definite(n: int, data: st.DataObject) -> None:
    """H(q) is symmetric and positive definite for any posture (Section III.1)."""
    snake = Snake(SnakeParams.table1(n=n))
    q = np.array(data.draw(st.lists(angles, min_size=n + 2, max_size=n + 2)))
    h = snake.inertia_matrix(q)
    assert np.array_equal(h, h.T)
    assert np.linalg.eigvalsh(h).min() > 0.0
    assert h[0, 0] == pytest.approx(n * snake.params.mass)


def test_forward_dynamics_solves_eq20(table1: Snake, rng: np.random.Generator) -> None:
    """ABA's q'' satisfies H q'' + h = E tau (eq. 20)."""
    e = paper.actuation_matrix(table1.n)
    for _ in range(20):
        q, dq = random_state(rng, table1.n)
        tau = rng.normal(size=table1.n - 1)
        ddq = table1.forward_dynamics(q, dq, tau)
        residual = table1.inertia_matrix(q) @ ddq + table1.bias(q, dq) - e @ tau
        assert np.max(np.abs(residual)) < 1e-10


def test_passive_joint_torque_is_ignored(rng: np.random.Generator) -> None:
    """With joint 5 passive, any torque on it leaves q'' unchanged."""
    snake = Snake(SnakeParams.table1(passive=(5,)))
    q, dq = random_state(rng, snake.n)
    tau = rng.normal(size=snake.n - 1)
    other = tau.copy()
    other[4] += 3.0
    assert np.array_equal(snake.forward_dynamics(q, dq, tau), snake.forward_dynamics(q, dq, other))
    assert snake.actuation_matrix[:, 4].sum() == 0.0


def _rk4_with_power(snake: Snake, x: np.ndarray, torques: np.ndarray, dt: float,
                    params: SnakeParams, *, power: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Integrate [q, dq, work] with RK4; work' = tau . phi' - dq^T C dq (power balance)."""
    nq = snake.nq

    def f(y: np.ndarray, tau: np.ndarray) -> np.ndarray:
        q, dq = y[:nq], y[nq:2 * nq]
        rate = tau @ dq[3:] - dq @ paper.friction_matrix(params, q) @ dq if power else 0.0
        return np.r_[dq, snake.forward_dynamics(q, dq, tau), rate]

    y = np.r_[x, 0.0]
    history = [y]
    for tau in torques:
        k1 = f(y, tau)
        k2 = f(y + 0.5 * dt * k1, tau)
        k3 = f(y + 0.5 * dt * k2, tau)
        k4 = f(y + dt * k3, tau)
        y = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        history.append(y)
    return np.array(history), y


def test_power_balance(rng: np.random.Generator) -> None:
    """T(t) - T(0) equals the integral of tau . phi' - dq^T C dq (rel. error < 1e-6)."""
    params = SnakeParams.table1(c_y=4.0)
    snake = Snake(params)
    q, dq = random_state(rng, params.n)
    torques = np.repeat(rng.normal(scale=0.05, size=(40, params.n - 1)), 25, axis=0)
    history, _ = _rk4_with_power(snake, np.r_[q, dq], torques, 1e-3, params)
    nq = snake.nq
    energy = np.array([snake.kinetic_energy(y[:nq], y[nq:2 * nq]) for y in history])
    work = history[:, -1]
    change = energy - energy[0]
    assert np.max(np.abs(change - work)) < 1e-6 * np.max(np.abs(change))
    assert abs(change[-1]) > 1e-4  # the test is not vacuous: energy did change


def test_linear_momentum_conserved_without_friction(rng: np.random.Generator) -> None:
    """With zero friction the first two rows of H dq (total linear momentum) stay put."""
    params = SnakeParams.table1(c_x=0.0, c_y=0.0, c_theta=0.0)
    snake = Snake(params)
    q, dq = random_state(rng, params.n)
    torques = np.repeat(rng.normal(scale=0.02, size=(30, params.n - 1)), 100, axis=0)
    history, _ = _rk4_with_power(snake, np.r_[q, dq], torques, 5e-4, params, power=False)
    nq = snake.nq
    momentum = np.array([snake.inertia_matrix(y[:nq])[:2] @ y[nq:2 * nq] for y in history])
    # RK4 truncation only: relative drift below 1e-8 (a model error gives O(1))
    assert np.max(np.abs(momentum - momentum[0])) < 1e-8 * np.linalg.norm(momentum[0])
    assert np.ptp(history[:, 3:nq]) > 0.1  # the body did move


def test_g_conserved_with_isotropic_friction(rng: np.random.Generator) -> None:
    """Section V: with c_x = c_y, g = H1 dq + g2 (eq. 67) is constant for any torques."""
    params = SnakeParams.table1()  # c_x = c_y = 0.5
    snake = Snake(params)
    q, dq = random_state(rng, params.n)
    # 3 s of piecewise-constant torques of controller size (0.02 N m), RK4 at 0.5 ms
    torques = np.repeat(rng.normal(scale=0.02, size=(60, params.n - 1)), 100, axis=0)
    history, _ = _rk4_with_power(snake, np.r_[q, dq], torques, 5e-4, params, power=False)
    nq = snake.nq
    g = np.array([snake.inertia_matrix(y[:nq])[:2] @ y[nq:2 * nq] + paper.g2(params, y[:nq])
                  for y in history])
    assert np.max(np.abs(g - g[0])) < 1e-8
    assert np.ptp(history[:, 0]) > 1e-3  # the head did move


def test_head_pose_and_bad_sizes(table1: Snake) -> None:
    """head_pose is w = q[:3]; wrong-sized vectors are ConfigurationErrors."""
    q = np.arange(12.0)
    assert np.array_equal(table1.head_pose(q), q[:3])
    with pytest.raises(ConfigurationError):
        table1.check_q(np.zeros(11))
    with pytest.raises(ConfigurationError):
        table1.check_tau([0.0] * 8)


def test_state_methods_follow_in_place_changes(rng: np.random.Generator) -> None:
    """friction_force, bias and state_derivative read the arrays they are given, also ones
    changed in place since the last call (no cache serves an old state)."""
    snake = Snake(SnakeParams.table1(c_y=5.0))
    q, dq = random_state(rng, snake.n)
    x = np.r_[q, dq]
    tau = rng.normal(size=snake.n - 1)
    q, dq = x[:snake.nq], x[snake.nq:]  # views of x
    first, first_bias = snake.friction_force(q, dq), snake.bias(q, dq)
    x[snake.nq + 4] += 0.5  # same array object, new state
    assert np.allclose(snake.friction_force(q, dq), snake.friction(q.copy(), dq.copy()))
    assert not np.allclose(snake.friction_force(q, dq), first)
    assert not np.allclose(snake.bias(q, dq), first_bias)
    assert np.array_equal(snake.bias(q, dq), snake.bias(q.copy(), dq.copy()))
    assert np.array_equal(snake.state_derivative(x, tau), snake.forward_dynamics(q, dq, tau))


def _central(fn, x: np.ndarray, step: float) -> np.ndarray:
    """Central-difference Jacobian of ``fn`` at ``x`` (columns: coordinates of x)."""
    cols = [(fn(x + step * e) - fn(x - step * e)) / (2 * step) for e in np.eye(x.size)]
    return np.array(cols).T


def _rel_to_largest(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


def test_root_is_a_chain_of_three_single_dof_joints(table1: Snake) -> None:
    """base_x, base_y, base_yaw carry x_h, y_h, theta_1; link i hangs on joint i + 2."""
    model = table1.model
    assert [model.names[j] for j in (1, 2, 3)] == ["base_x", "base_y", "base_yaw"]
    assert [model.joints[j].shortname() for j in (1, 2, 3)] == [
        "JointModelPX", "JointModelPY", "JointModelRZ"]
    assert model.inertias[1].mass == 0.0 and model.inertias[2].mass == 0.0
    assert [model.inertias[int(j)].mass for j in table1.link_joints] == [0.182] * 10
    assert model.existFrame("link_1") and model.existFrame("link_10")
    assert (model.nq, model.nv) == (12, 12)


@pytest.mark.parametrize("n", [4, 10, 30])
def test_pinocchio_derivatives_match_central_differences(n: int,
                                                         rng: np.random.Generator) -> None:
    """computeABADerivatives / computeRNEADerivatives on the root chain: 1e-6, 20 states."""
    import pinocchio as pin

    snake = Snake(SnakeParams.table1(n=n))
    model, data = snake.model, snake.data
    for _ in range(20):
        q, v = random_state(rng, n)
        tau, a = rng.normal(size=n + 2), rng.normal(size=n + 2)
        ddq_dq, ddq_dv, _ = pin.computeABADerivatives(model, data, q, v, tau)
        ddq_dq, ddq_dv = ddq_dq.copy(), ddq_dv.copy()
        assert _rel_to_largest(ddq_dq, _central(
            lambda x, v=v, tau=tau: pin.aba(model, data, x, v, tau).copy(), q, 1e-5)) < 1e-6
        assert _rel_to_largest(ddq_dv, _central(
            lambda x, q=q, tau=tau: pin.aba(model, data, q, x, tau).copy(), v, 1e-5)) < 1e-6
        dtau_dq, dtau_dv, _ = pin.computeRNEADerivatives(model, data, q, v, a)
        dtau_dq, dtau_dv = dtau_dq.copy(), dtau_dv.copy()
        assert _rel_to_largest(dtau_dq, _central(
            lambda x, v=v, a=a: pin.rnea(model, data, x, v, a).copy(), q, 1e-5)) < 1e-6
        assert _rel_to_largest(dtau_dv, _central(
            lambda x, q=q, a=a: pin.rnea(model, data, q, x, a).copy(), v, 1e-5)) < 1e-6


@pytest.mark.parametrize("n", [4, 10, 30])
@pytest.mark.parametrize("friction", ["isotropic", "anisotropic", "heterogeneous"])
def test_dynamics_derivatives_with_friction(n: int, friction: str,
                                            rng: np.random.Generator) -> None:
    """d q''/d(q, dq, tau) with friction equal central differences of forward_dynamics."""
    from .conftest import heterogeneous_params

    params = {"isotropic": lambda: SnakeParams.table1(n=n),
              "anisotropic": lambda: SnakeParams.table1(n=n, c_y=25.0, passive=(n // 2,)),
              "heterogeneous": lambda: heterogeneous_params(rng, n)}[friction]()
    snake = Snake(params)
    for _ in range(5):
        q, dq = random_state(rng, n)
        tau = rng.normal(size=n - 1)
        d = snake.dynamics_derivatives(q, dq, tau)
        assert _rel_to_largest(d.ddq, snake.forward_dynamics(q, dq, tau)) < 1e-10
        assert _rel_to_largest(d.ddq_dq, _central(
            lambda x, dq=dq, tau=tau: snake.forward_dynamics(x, dq, tau), q, 1e-5)) < 1e-6
        assert _rel_to_largest(d.ddq_dv, _central(
            lambda x, q=q, tau=tau: snake.forward_dynamics(q, x, tau), dq, 1e-5)) < 1e-6
        assert _rel_to_largest(d.ddq_dtau, _central(
            lambda x, q=q, dq=dq: snake.forward_dynamics(q, dq, x), tau, 1e-5)) < 1e-6
        assert np.all(d.ddq_dtau[:, [k - 1 for k in params.passive]] == 0.0)


def test_snake_from_urdf_and_robot_file_round_trip(tmp_path, rng: np.random.Generator) -> None:
    """params -> TOML -> URDF -> Snake gives the same H and h to 1e-12 (friction kept)."""
    from snake_pin.robot_file import load_robot, write_robot_file
    from snake_pin.urdf import write_urdf

    from .conftest import heterogeneous_params

    params = heterogeneous_params(rng, 7, passive=(3,))
    toml_path = write_robot_file(params, tmp_path / "robot.toml")
    from_toml = Snake(load_robot(toml_path))
    urdf_path = write_urdf(from_toml.params, tmp_path / "robot.urdf")
    from_urdf = Snake.from_urdf(urdf_path)
    original = Snake(params)
    assert from_urdf.params.passive == (3,)
    for _ in range(10):
        q, dq = random_state(rng, 7)
        for other in (from_toml, from_urdf):
            assert _rel_to_largest(other.inertia_matrix(q), original.inertia_matrix(q)) < 1e-12
            assert _rel_to_largest(other.bias(q, dq), original.bias(q, dq)) < 1e-12


def test_snake_refuses_what_is_not_a_robot() -> None:
    """Snake('my.urdf') says to use from_urdf; a missing file is a one-line RobotFileError."""
    from snake_pin.exceptions import RobotFileError

    with pytest.raises(ConfigurationError, match="from_urdf"):
        Snake("my.urdf")  # type: ignore[arg-type]
    with pytest.raises(RobotFileError, match=r"missing\.urdf"):
        Snake.from_urdf("missing.urdf")


def test_snake_data_and_paper_model_check_their_arguments() -> None:
    """SnakeData needs a Snake; paper_model a SnakeParams; create_data gives fresh buffers."""
    from snake_pin import ParameterError
    from snake_pin.model import SnakeData, paper_model

    snake = Snake(SnakeParams.table1(n=4))
    with pytest.raises(ParameterError, match="snake must be a Snake"):
        SnakeData(snake.model)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="params must be a SnakeParams"):
        paper_model({"n": 4})  # type: ignore[arg-type]
    first, second = snake.create_data(), snake.create_data()
    assert first.torque.shape == (snake.nq,) and first.pin is not second.pin
    assert not np.shares_memory(first.mass, second.mass)


def test_calc_methods_equal_the_closed_form(rng: np.random.Generator) -> None:
    """The one implementation over a SnakeData: q'' (calc_acceleration), (b, H^-1)
    (calc_affine) and (H, h) (calc_mass_and_bias) equal snake_pin.paper's closed form,
    per-link anisotropic robot with a passive joint, on two data objects in turn."""
    params = SnakeParams.table1(c_y=(0.5, 9.0, 0.5, 4.0, 12.0, 0.5, 7.0, 0.5, 2.0, 5.0),
                                passive=(4,))
    snake = Snake(params)
    data = [snake.create_data(), snake.create_data()]
    e = paper.actuation_matrix(params.n)
    e[:, 3] = 0.0  # joint 4 passive
    for k in range(6):
        q, dq = random_state(rng, params.n)
        tau = rng.normal(size=params.n - 1)
        h_closed, bias_closed = paper.inertia_matrix(params, q), paper.bias(params, q, dq)
        ddq_closed = np.linalg.solve(h_closed, e @ tau - bias_closed)
        own = data[k % 2]
        torque = snake.calc_torque(own, tau)
        assert np.array_equal(torque, e @ tau)
        ddq = snake.calc_acceleration(own, q, dq, torque)
        assert np.allclose(ddq, ddq_closed, rtol=1e-8, atol=1e-8 * np.abs(ddq_closed).max())
        b, h_inv = snake.calc_affine(own, q, dq)
        assert np.allclose(h_inv @ h_closed, np.eye(snake.nq), atol=1e-8)
        assert np.array_equal(h_inv, h_inv.T)
        assert np.allclose(b + h_inv @ torque, ddq, rtol=1e-9, atol=1e-9 * np.abs(ddq).max())
        mass, bias = snake.calc_mass_and_bias(own, q, dq)
        assert np.allclose(mass, h_closed, rtol=1e-12, atol=1e-14)
        assert np.allclose(bias, bias_closed, rtol=1e-10, atol=1e-12)
