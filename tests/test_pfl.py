"""PFL head controller (eqs. 68-78, sign corrected) and the Section VI.1 run."""

from __future__ import annotations

import numpy as np
import pytest

from snake_pin import ParameterError, SingularPostureError, Snake, SnakeParams, straight
from snake_pin.control import PFLController, PFLOptions
from snake_pin.experiments.pfl import run_pfl

from .conftest import heterogeneous_params


@pytest.mark.parametrize("c_y", [0.5, 5.0])
def test_closed_loop_gives_w_ddot_equal_a(c_y: float, rng: np.random.Generator) -> None:
    """Eq. (71): with the derived law, the plant's w'' equals the command a at random states."""
    snake = Snake(SnakeParams.table1(c_y=c_y))
    controller = PFLController(snake)
    for _ in range(20):
        q = np.r_[rng.normal(size=3), rng.uniform(-1.2, 1.2, 9)]
        dq = rng.normal(scale=0.5, size=12)
        x, t = np.r_[q, dq], rng.uniform(0, 10)
        tau = controller(x, t)
        ddq = snake.forward_dynamics(q, dq, tau)
        a = controller.command(x, t)
        assert np.allclose(ddq[:3], a, atol=1e-9 * max(1.0, np.abs(a).max()))


@pytest.mark.parametrize(("friction", "climb_R"), [("none", 0.0), ("isotropic", 0.0),
                                                   ("anisotropic", 0.0), ("anisotropic", 0.5)])
def test_heterogeneous_robot_gives_w_ddot_equal_a(friction: str, climb_R: float,
                                                  rng: np.random.Generator) -> None:
    """Eq. (71) on per-link robots: w'' = a at random states (the equal-link model misses)."""
    params = heterogeneous_params(rng, 10, friction)
    snake = Snake(params)
    controller = PFLController(snake, climb_R=climb_R)
    uniform = PFLController(Snake(SnakeParams.table1(c_x=0.5, c_y=0.5)), climb_R=climb_R)
    for _ in range(20):
        q = np.r_[rng.normal(size=3), rng.uniform(-1.2, 1.2, 9)]
        dq = rng.normal(scale=0.5, size=12)
        x, t = np.r_[q, dq], rng.uniform(0, 10)
        a = controller.command(x, t)
        ddq = snake.forward_dynamics(q, dq, controller(x, t))
        assert np.allclose(ddq[:3], a, atol=1e-8 * max(1.0, np.abs(a).max()))
        wrong = snake.forward_dynamics(q, dq, uniform(x, t))
        assert np.abs(wrong[:3] - a).max() > 1e-3 * max(1.0, np.abs(a).max())


def test_printed_sign_would_fail(rng: np.random.Generator) -> None:
    """Erratum 2: with +Hs a (as printed) w'' != a, so the test above can fail."""
    snake = Snake(SnakeParams.table1())
    q = np.r_[0, 0, 0, rng.uniform(-1, 1, 9)]
    dq = np.zeros(12)
    h = snake.inertia_matrix(q)
    b = snake.bias(q, dq)
    h12, h22 = h[:3, 3:], h[3:, 3:]
    schur = h[:3, :3] - h12 @ np.linalg.solve(h22, h12.T)
    a = np.array([1.0, 0.0, 0.0])
    y_printed = schur @ a - b[:3] + h12 @ np.linalg.solve(h22, b[3:])
    tau = h22 @ np.linalg.pinv(h12) @ y_printed
    assert not np.allclose(snake.forward_dynamics(q, dq, tau)[:3], a, atol=1e-3)


def test_section_vi1_run_breaks_down_and_conserves_g() -> None:
    """VI.1: head tracks, g conserved before the breakdown, which comes with an R dip."""
    run = run_pfl(t_final=6.0)
    s = run.trajectory.summary
    assert s["breakdown_time"] is not None and 3.0 < s["breakdown_time"] < 5.0
    assert s["g_drift_max"] < 1e-8
    assert s["head_error_max"] < 0.02  # 2 cm of a 1.2 m body, before the breakdown
    assert s["R_dip"] < 0.6 * s["R_peak"]  # R falls as the torque blows up


def test_singular_posture_is_refused() -> None:
    """At the straight posture (R = 0) the law is undefined: SingularPostureError."""
    controller = PFLController(Snake())
    with pytest.raises(SingularPostureError):
        controller(np.r_[straight(10), np.zeros(12)], 0.0)


@pytest.mark.parametrize("kwargs", [{"k_v": -1.0}, {"k_p": [1.0, 2.0]}, {"r_v": -0.1},
                                    {"k_p": [[1, 2, 0], [0, 1, 0], [0, 0, 1]]},
                                    {"climb_R": -1.0}])
def test_bad_gains(kwargs: dict) -> None:
    """Non-definite, wrong-size or asymmetric gains are ParameterErrors."""
    with pytest.raises(ParameterError):
        PFLController(Snake(), **kwargs)


def test_passive_joint_refused() -> None:
    """PFL needs every input: a snake with a passive joint is refused."""
    with pytest.raises(ParameterError):
        PFLController(Snake(SnakeParams.table1(passive=(5,))))


def test_climb_damping_without_climb_is_refused() -> None:
    """climb_damping has no effect with climb_R = 0: refused, not ignored; with climb_R > 0
    it is kept, and left out it is 2 /s."""
    snake = Snake(SnakeParams.table1(n=5))
    with pytest.raises(ParameterError, match="climb_damping has no effect") as info:
        PFLController(snake, climb_damping=3.0)
    assert "\n" not in str(info.value)
    assert PFLController(snake, climb_R=0.5, climb_damping=3.0).climb_damping == 3.0
    assert PFLController(snake).climb_damping == 2.0


def test_a_reference_must_be_callable() -> None:
    """A reference that is not callable is refused at construction, not at the first call."""
    snake = Snake(SnakeParams.table1(n=5))
    with pytest.raises(ParameterError, match="reference"):
        PFLController(snake, reference=(0.1, 0.0, 0.0))  # type: ignore[arg-type]


@pytest.mark.parametrize(("field", "value"), [("k_v", 0.0), ("k_p", [1.0, 2.0]),
                                              ("r_v", -0.1), ("r_min", -1.0),
                                              ("climb_R", float("nan")),
                                              ("climb_damping", 0.0)])
def test_options_refuse_a_field_out_of_bounds(field: str, value: object) -> None:
    """PFLOptions refuses a field outside its domain in one line naming it."""
    extra = {"climb_R": 1.0} if field == "climb_damping" else {}
    with pytest.raises(ParameterError) as info:
        PFLOptions(**{field: value}, **extra)
    message = str(info.value)
    assert "\n" not in message and field.lower() in message.lower()


def test_keywords_and_options_give_the_same_law() -> None:
    """Keywords of the constructor and an options object give the same torque at a state."""
    snake = Snake(SnakeParams.table1(n=5))
    x = np.r_[straight(5), np.full(7, 0.05)]
    x[3:7] = [0.3, -0.2, 0.25, -0.1]
    given = {"k_v": 4.0, "r_p": 0.1, "climb_R": 0.5, "climb_damping": 3.0}
    np.testing.assert_array_equal(PFLController(snake, **given)(x, 0.3),
                                  PFLController(snake, options=PFLOptions(**given))(x, 0.3))
