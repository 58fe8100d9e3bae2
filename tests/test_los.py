"""LOS path following (Liljebäck et al.): guidance, kinematics, joint law, closed loop."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snake_pin import ParameterError, Snake, SnakeParams, simulate
from snake_pin.control.los import (
    LOSController,
    LOSParams,
    ReferenceFilter,
    body_kinematics,
    los_heading,
)
from snake_pin.paths import Circle, Line, PathReference, Timing

from .conftest import head_first_state

#: Short runs: 10 ms steps give the cross-track errors of 1 ms steps to a millimetre.
STEP = 1e-2


@pytest.fixture(scope="module")
def snake() -> Snake:
    return Snake(SnakeParams.table1(c_y=25.0))


def _start(snake: Snake, ctrl: LOSController, cm_y: float) -> np.ndarray:
    """At rest in the gait's t = 0 posture, head first along +x, the CM at height cm_y."""
    x = np.r_[0.0, 0.0, np.pi, ctrl.gait(0.0)[0], np.zeros(snake.nv)]
    x[1] += cm_y - body_kinematics(snake, x)[0][1]
    return x


class _WrongSign(LOSController):
    """The heading feedback with the book's sign copied verbatim (conventions not converted)."""

    def steering_offset(self, t: float, g: dict[str, float], ref: np.ndarray) -> float:
        mean_gait = float(np.mean(self.gait(t)[0]))
        return -super().steering_offset(t, g, ref) - 2.0 * mean_gait


def test_los_heading_formula() -> None:
    """theta_los = gamma - atan(e / Delta) on hand-made cases."""
    assert los_heading(0.0, 0.0, 0.6) == 0.0
    assert los_heading(0.0, 0.3, 0.3) == pytest.approx(-math.pi / 4)
    assert los_heading(1.0, -0.6, 0.6) == pytest.approx(1.0 + math.pi / 4)
    assert los_heading(0.0, 1e9, 0.6) == pytest.approx(-math.pi / 2)


def test_body_kinematics(snake: Snake, rng: np.random.Generator) -> None:
    """CM = mass-weighted link CMs, its velocity and psi' match central differences."""
    nq = snake.nq
    masses = snake.params.masses
    for _ in range(5):
        x = head_first_state(rng, snake.n)
        p_cm, v_cm, psi, dpsi = body_kinematics(snake, x)
        poses = snake.link_poses(x[:nq])
        np.testing.assert_allclose(p_cm, masses @ poses[:, :2] / masses.sum(), atol=1e-14)
        # psi averages the continuous theta_i (link_poses wraps them to (-pi, pi])
        theta = x[2] + np.r_[0.0, np.cumsum(x[3:nq])]
        np.testing.assert_allclose(np.angle(np.exp(1j * (theta - poses[:, 2]))), 0.0,
                                   atol=1e-12)
        assert psi == pytest.approx(theta.mean() + math.pi)
        h = 1e-6
        shift = np.r_[h * x[nq:], np.zeros(nq)]
        plus, minus = body_kinematics(snake, x + shift), body_kinematics(snake, x - shift)
        np.testing.assert_allclose((plus[0] - minus[0]) / (2 * h), v_cm, atol=1e-8)
        assert (plus[2] - minus[2]) / (2 * h) == pytest.approx(dpsi, abs=1e-8)


def test_guidance_on_a_circle(snake: Snake) -> None:
    """A CM 0.2 m outside a left-turning circle is e = -0.2 and aims atan(0.2/Delta) inwards."""
    circle = Circle(radius=1.2)
    ctrl = LOSController(snake, circle, look_ahead=0.5)
    x = np.r_[0.0, 0.0, np.pi, np.zeros(snake.n - 1), np.zeros(snake.nv)]
    polar = 0.4  # place the CM at polar angle 0.4 about the centre, radius 1.4
    p_cm = body_kinematics(snake, x)[0]
    target = np.array(circle.centre) + 1.4 * np.array([math.cos(polar), math.sin(polar)])
    x[:2] += target - p_cm
    g = ctrl.guidance(x)
    assert g["e_ct"] == pytest.approx(-0.2, abs=1e-12)
    assert g["s_cm"] == pytest.approx(1.2 * (polar + math.pi / 2), abs=1e-12)
    assert g["theta_los"] == pytest.approx(polar + math.pi / 2 + math.atan(0.2 / 0.5))
    assert g["theta_avg"] == pytest.approx(2 * math.pi)  # straight, head first along +x


def test_joint_law_linearises_the_actuated_joints(snake: Snake,
                                                  rng: np.random.Generator) -> None:
    """Under tau, q_a'' = phi_r'' + k_d e' + k_p e exactly; plant_acceleration is q''."""
    for params in (snake.params, snake.params.replace(passive=(5,))):
        plant = Snake(params)
        ctrl = LOSController(plant)
        nq = plant.nq
        act = np.array(params.actuated) - 1
        for _ in range(5):
            x = head_first_state(rng, plant.n)
            phi_r, dphi_r, ddphi_r = (rng.normal(size=plant.n - 1) for _ in range(3))
            tau = ctrl.joint_torques(x, phi_r, dphi_r, ddphi_r)
            ddq = plant.forward_dynamics(x[:nq], x[nq:], tau)
            v = ddphi_r + 20.0 * (dphi_r - x[nq + 3:]) + 100.0 * (phi_r - x[3:nq])
            np.testing.assert_allclose(ddq[3:][act], v[act], rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(ctrl.plant_acceleration(plant), ddq, rtol=1e-9,
                                       atol=1e-9)
            assert np.all(tau[np.setdiff1d(np.arange(plant.n - 1), act)] == 0.0)
        assert ctrl.plant_acceleration(Snake(params)) is None  # another plant: not reused


def test_reference_filter() -> None:
    """Unit DC gain; y' follows the slope of a ramp; the derivatives are y's derivatives."""
    filt = ReferenceFilter(period=1.0)
    filt.update(0.0, 0.0)
    for _ in range(2000):
        state = filt.update(2.0, 0.005)
    np.testing.assert_allclose(state, [2.0, 0.0, 0.0], atol=1e-9)
    filt.reset()
    times = np.arange(0.0, 10.0, 0.001)
    states = np.array([filt.update(0.3 * t, 0.001 if t else 0.0) for t in times])
    assert states[-1, 1] == pytest.approx(0.3, rel=1e-6)
    np.testing.assert_allclose(np.gradient(states[:, 0], times)[100:-1], states[100:-1, 1],
                               atol=2e-3)
    np.testing.assert_allclose(np.gradient(states[:, 1], times)[100:-1], states[100:-1, 2],
                               atol=2e-3)


def test_a_positive_offset_turns_right_at_the_identified_rate(snake: Snake) -> None:
    """Constant phi_0 = 0.1: psi' = -(lambda_2 / lambda_1) v_t phi_0 (the law's model)."""
    ctrl = LOSController(snake)
    ctrl.steering_offset = lambda t, g, ref: 0.1  # type: ignore[method-assign]
    traj = simulate(snake, ctrl, _start(snake, ctrl, 0.0), 25.0, dt=STEP, control_dt=STEP)
    assert traj.status == "completed"
    late = (traj.t > 10.0) & np.isfinite(traj.signals["theta_avg"])
    rate = np.polyfit(traj.t[late], traj.signals["theta_avg"][late], 1)[0]
    speed = float(np.mean(traj.signals["v_t"][late]))
    predicted = -ctrl.params.lambda2 / ctrl.params.lambda1 * speed * 0.1
    assert rate < 0.0
    assert rate == pytest.approx(predicted, rel=0.15)


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_converges_to_a_straight_path(snake: Snake, side: float) -> None:
    """From 0.3 m off the x axis the CM error falls below 0.1 of it within 30 s."""
    ctrl = LOSController(snake, Line())
    traj = simulate(snake, ctrl, _start(snake, ctrl, 0.3 * side), 30.0, dt=STEP,
                    control_dt=STEP)
    assert traj.status == "completed"
    error = traj.signals["e_ct"]
    assert error[0] == pytest.approx(0.3 * side)
    assert np.nanmax(np.abs(error[traj.t > 27.0])) < 0.1 * 0.3
    assert traj.signals["s_cm"][-2] - traj.signals["s_cm"][0] > 2.0  # it moves along
    phi_r = np.array([ctrl.gait(t)[0] for t in traj.t]) + traj.signals["phi_0"][:, None]
    settled = traj.t > 5.0
    assert np.nanmax(np.abs(traj.q[settled, 3:] - phi_r[settled])) < 0.05
    assert np.all(np.isfinite(traj.tau)) and np.abs(traj.tau).max() < 10.0


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_the_wrong_sign_does_not_converge(snake: Snake, side: float) -> None:
    """The book's sign copied without converting: no progress, no convergence, saturated."""
    ctrl = _WrongSign(snake, Line())
    traj = simulate(snake, ctrl, _start(snake, ctrl, 0.3 * side), 25.0, dt=STEP,
                    control_dt=STEP)
    late = traj.t > 15.0
    assert np.nanmean(np.abs(traj.signals["e_ct"][late])) > 0.3 * 0.3
    assert traj.signals["s_cm"][-2] - traj.signals["s_cm"][0] < 0.5
    assert np.nanmax(np.abs(traj.signals["phi_0"][late])) == pytest.approx(
        ctrl.params.phi0_max, rel=1e-3)


def test_follows_a_circle_of_one_body_length(snake: Snake) -> None:
    """Radius 1.2 m: CM cross-track RMS over 20-40 s under 5 cm, moving around it."""
    ctrl = LOSController(snake, PathReference(Circle(radius=1.2), Timing(0.1)))
    traj = simulate(snake, ctrl, _start(snake, ctrl, 0.0), 40.0, dt=STEP, control_dt=STEP)
    assert traj.status == "completed"
    late = traj.t > 20.0
    error = traj.signals["e_ct"][late]
    assert np.sqrt(np.nanmean(error**2)) < 0.05
    assert traj.signals["theta_ref"][-2] - traj.signals["theta_ref"][0] > 2.0  # turning


def test_reset_repeats_the_run(snake: Snake) -> None:
    """Filters and the path-point tracker restart: two runs of one controller are equal."""
    ctrl = LOSController(snake, Circle(radius=0.8))
    x0 = _start(snake, ctrl, 0.1)
    first = simulate(snake, ctrl, x0, 2.0, dt=STEP, control_dt=STEP)
    second = simulate(snake, ctrl, x0, 2.0, dt=STEP, control_dt=STEP)
    np.testing.assert_array_equal(first.q, second.q)
    np.testing.assert_array_equal(first.signals["phi_0"], second.signals["phi_0"])


def test_pd_steering_converges(snake: Snake) -> None:
    """The experiments' PD steering also brings the CM to a straight path."""
    ctrl = LOSController(snake, Line(), steering="pd")
    traj = simulate(snake, ctrl, _start(snake, ctrl, 0.3), 25.0, dt=STEP, control_dt=STEP)
    assert np.nanmax(np.abs(traj.signals["e_ct"][traj.t > 23.0])) < 0.1 * 0.3


@pytest.mark.parametrize("kwargs, expected", [
    ({"look_ahead": 0.0}, "look_ahead must be positive"),
    ({"omega": float("nan")}, "omega must be finite"),
    ({"steering": "bang_bang"}, "steering must be one of cascaded, pd"),
    ({"alpha": -0.1}, "alpha must be non-negative"),
    ({"k_theta": True}, "k_theta must be a number"),
    ({"lambda2": "20"}, "lambda2 must be a number"),
])
def test_bad_parameters_are_refused(snake: Snake, kwargs: dict[str, object],
                                    expected: str) -> None:
    """Out-of-domain parameters are one ParameterError line naming them."""
    with pytest.raises(ParameterError, match=expected) as info:
        LOSController(snake, **kwargs)
    assert "\n" not in str(info.value)
    with pytest.raises(ParameterError, match=expected):
        LOSParams(**kwargs)  # type: ignore[arg-type]


def test_unknown_options_are_refused(snake: Snake) -> None:
    """A misspelt option or a non-path is refused, not ignored."""
    with pytest.raises(ParameterError, match="unknown LOS parameter 'lookahead'"):
        LOSController(snake, lookahead=1.0)
    with pytest.raises(ParameterError, match="path must be a Path"):
        LOSController(snake, "circle")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="nothing to control"):
        LOSController(Snake(SnakeParams.table1(n=3, passive=(1, 2))))


@pytest.mark.parametrize(("kwargs", "law"), [
    ({"k_p": 2.0}, "pd"), ({"k_d": 0.5}, "pd"), ({"k_theta": 5.0, "steering": "pd"}, "cascaded"),
    ({"lambda1": 10.0, "steering": "pd"}, "cascaded"),
    ({"v_min": 0.1, "steering": "pd"}, "cascaded"),
])
def test_the_other_laws_fields_are_refused(snake: Snake, kwargs: dict[str, object],
                                            law: str) -> None:
    """A field only the other steering law reads, set away from its default, is refused."""
    with pytest.raises(ParameterError, match=f"has no effect .*the '{law}' law") as info:
        LOSParams(**kwargs)  # type: ignore[arg-type]
    assert "\n" not in str(info.value)
    with pytest.raises(ParameterError, match="has no effect"):
        LOSController(snake, **kwargs)


def test_params_must_be_los_params(snake: Snake) -> None:
    """params={} (or any other non-LOSParams) is refused, not read as the defaults."""
    with pytest.raises(ParameterError, match="params must be LOSParams"):
        LOSController(snake, params={})  # type: ignore[arg-type]
    kept = LOSController(snake, params=LOSParams(steering="pd", k_p=2.0))
    assert kept.params.k_p == 2.0 and kept.params.steering == "pd"


def test_cached_gait_cannot_be_changed_by_a_caller(snake: Snake) -> None:
    """gait(t) asked twice returns the same values even if the caller tried to modify the
    first answer (the cached arrays are read-only)."""
    ctrl = LOSController(snake, Line())
    phi, _, _ = ctrl.gait(1.3)
    with pytest.raises(ValueError):
        phi += 1.0
    again, _, _ = ctrl.gait(1.3)
    np.testing.assert_array_equal(again, ctrl.params.alpha * np.sin(
        ctrl.params.omega * 1.3 - ctrl._lags))
