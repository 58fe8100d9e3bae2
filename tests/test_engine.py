"""MuJoCo engine model (Section VI.3): mass matrix, actuators, identification, filter."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from snake_pin import ParameterError, Serpenoid, Snake, SnakeParams
from snake_pin.engine import WheelSpec, build_engine_model
from snake_pin.engine.run import DirtyDerivative, identify_friction


@pytest.fixture(scope="module")
def engine():
    return build_engine_model()


def test_chain_mass_matrix_equals_pinocchio(engine, rng: np.random.Generator) -> None:
    """MuJoCo's mass matrix on (x, y, yaw, phi), wheels included, equals Pinocchio's H."""
    snake = Snake(SnakeParams.engine())
    for _ in range(5):
        q = np.r_[rng.normal(size=2), rng.uniform(-3, 3), rng.uniform(-1.0, 1.0, 7)]
        engine.set_paper_configuration(q)
        assert np.allclose(engine.paper_configuration(), q, atol=1e-12)
        h = snake.inertia_matrix(q)
        assert np.abs(engine.chain_mass_matrix() - h).max() < 1e-10 * np.abs(h).max()


def test_link_plus_wheels_keep_the_preset(engine) -> None:
    """Body and wheel masses add up to m per link, and the whole robot to n m."""
    assert engine.body_mass + 2 * engine.wheels.mass == pytest.approx(0.417)
    assert engine.model.body_mass.sum() == pytest.approx(8 * 0.417)


def test_passive_joint_has_no_actuator() -> None:
    """A model with joint 5 passive has one actuator fewer, none on joint 5."""
    full = build_engine_model()
    passive = build_engine_model(SnakeParams.engine(passive=(5,)))
    assert passive.model.nu == full.model.nu - 1 == 6
    names = [passive.model.actuator(i).name for i in range(passive.model.nu)]
    assert "motor_5" not in names


def test_resting_snake_stays_put(engine) -> None:
    """Without torque the snake settles on its wheels and does not creep (< 1 um in 1 s)."""
    engine.set_paper_configuration(np.zeros(10))
    for _ in range(2000):
        mujoco.mj_step(engine.model, engine.data)
    assert np.abs(engine.paper_configuration()[:3]).max() < 1e-6
    assert engine.data.ncon == 16  # every wheel on the floor


def test_identified_friction_matches_contact_models() -> None:
    """c_x from coasting equals the axle damping 2b/r^2; c_y the Coulomb equivalent (5 %)."""
    friction = identify_friction()
    assert friction["c_x"] == pytest.approx(friction["c_x_rolling_model"], rel=0.1)
    assert friction["c_y"] == pytest.approx(friction["c_y_coulomb_model"], rel=0.05)
    assert friction["c_y"] > 100 * friction["c_x"]  # wheels: strongly anisotropic


def test_pyramidal_cones_identify_a_looser_coulomb_equivalent() -> None:
    """The faster pyramidal cone still gives c_y within 15 % of the Coulomb equivalent."""
    wheels = WheelSpec(cone="pyramidal")
    assert build_engine_model(wheels=wheels).model.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    friction = identify_friction(wheels=wheels)
    assert friction["c_y"] == pytest.approx(friction["c_y_coulomb_model"], rel=0.15)
    assert friction["c_x"] == pytest.approx(friction["c_x_rolling_model"], rel=0.1)


def test_elliptic_cone_is_isotropic_the_pyramidal_cone_is_not() -> None:
    """The straight snake coasting at 45 degrees to the world axes: with elliptic cones c_y
    is the one identified along the axes (1e-6); the pyramidal cone's friction limit is a
    square in the world's axes (|f_x| + |f_y| <= mu N), so sideways it is 15-35 % weaker
    there (1 / sqrt 2 for hard contacts) while it matches the Coulomb model along them."""
    along = {cone: identify_friction(wheels=WheelSpec(cone=cone))["c_y"]
             for cone in ("elliptic", "pyramidal")}
    diagonal = {cone: identify_friction(wheels=WheelSpec(cone=cone), heading=math.pi / 4)["c_y"]
                for cone in ("elliptic", "pyramidal")}
    assert diagonal["elliptic"] == pytest.approx(along["elliptic"], rel=1e-6)
    assert 0.65 < diagonal["pyramidal"] / along["pyramidal"] < 0.85
    assert identify_friction(heading=math.pi / 2)["c_y"] == pytest.approx(along["elliptic"],
                                                                          rel=1e-6)
    with pytest.raises(ParameterError, match="heading"):
        identify_friction(heading=math.nan)


def test_gait_servo_propels_the_engine_robot() -> None:
    """A serpenoid joint servo moves the wheeled robot head-first (> 0.5 m in 5 s)."""
    engine = build_engine_model()
    gait = Serpenoid(8, math.pi / 6, 1.5, 2.0)
    engine.set_paper_configuration(np.r_[0.0, 0.0, math.pi, gait.angles(0.0)])
    for _ in range(5000):
        q = engine.paper_configuration()
        dq = engine.data.qvel[engine.chain_dofs]
        phi, dphi, _ = gait.derivatives(engine.data.time)
        engine.apply_torque(5.0 * (phi - q[3:]) + 0.5 * (dphi - dq[3:]))
        for _ in range(engine.wheels.substeps):
            mujoco.mj_step(engine.model, engine.data)
    assert np.hypot(*engine.paper_configuration()[:2]) > 0.5


def test_dirty_derivative_of_a_ramp() -> None:
    """2 pi f_c s / (s + 2 pi f_c) of a ramp of slope 3 tends to 3 after a few time constants."""
    filt = DirtyDerivative(1, 10.0, 1e-3)
    out = [filt(np.array([3.0 * k * 1e-3]))[0] for k in range(500)]
    assert out[0] == 0.0 and out[-1] == pytest.approx(3.0, rel=1e-6)
    tau = 1 / (2 * math.pi * 10.0)  # first-order lag: y = 3 (1 - exp(-t / tau))
    k = int(tau / 1e-3)
    assert out[k] == pytest.approx(3.0 * (1 - math.exp(-k * 1e-3 / tau)), rel=0.05)
    into, buffer = DirtyDerivative(1, 10.0, 1e-3), np.empty(1)
    assert [into(np.array([3.0 * k * 1e-3]), buffer)[0] for k in range(500)] == out


@pytest.mark.parametrize("kwargs", [{"radius": 0.09}, {"radius": math.nan}, {"friction": -1.0},
                                    {"mass": math.inf}, {"substeps": 0}, {"mass": 0.25},
                                    {"cone": "round"}])
def test_bad_wheels_refused(kwargs: dict) -> None:
    """Overlapping or non-finite wheel/contact parameters are clear ParameterErrors."""
    with pytest.raises(ParameterError):
        build_engine_model(wheels=WheelSpec(**kwargs))


def test_short_closed_loop_run_moves_head_forward() -> None:
    """5 s of the Lyapunov-like law (velocity level) on the engine: head forward, tracking."""
    from snake_pin.engine.run import run_engine

    run = run_engine(t_final=5.0)
    traj = run.trajectory
    assert not traj.diverged and traj.q[-1, 0] > 0.3
    assert abs(traj.q[-1, 0] - 0.1 * traj.t_end) < 0.3


def _camera_head() -> SnakeParams:
    from snake_pin.robot_file import load_robot

    return load_robot("camera_head_snake.toml")


def test_per_link_identification_shares_the_whole_robots_fit() -> None:
    """Per-link robot: c_x equal per link and summing to the fit, c_y in proportion to the
    link masses and summing to the fit (within 5 % of 1.5 mu M g / v0), c_theta from each
    link's own wheel offset."""
    params = _camera_head()
    wheels = WheelSpec()
    friction = identify_friction(params, wheels)
    c_x, c_y = np.array(friction["c_x"]), np.array(friction["c_y"])
    assert c_x.shape == c_y.shape == (params.n,)
    assert np.allclose(c_x, friction["c_x_total"] / params.n, rtol=1e-15)
    assert np.allclose(c_y / params.masses, friction["c_y_total"] / params.total_mass,
                       rtol=1e-12)
    assert c_y.sum() == pytest.approx(friction["c_y_total"], rel=1e-12)
    assert friction["c_y_total"] == pytest.approx(friction["c_y_coulomb_model"], rel=0.05)
    assert friction["c_y_coulomb_model"] == pytest.approx(
        1.5 * wheels.friction * params.total_mass * 9.81 / friction["speed"])
    assert c_x.mean() == pytest.approx(friction["c_x_rolling_model"], rel=0.1)
    offsets = build_engine_model(params, wheels).wheel_offsets
    expected = 2 * offsets**2 * wheels.rolling_damping / wheels.radius**2
    assert np.allclose(friction["c_theta"], expected, rtol=1e-15)
    assert friction["c_theta"][0] > friction["c_theta"][1]  # the longer head's wider wheels


def test_per_link_identification_of_nearly_equal_links_matches_the_uniform_one() -> None:
    """A robot whose links differ by 1e-6 in mass is identified (per link) like the equal-link
    robot it nearly is (per-link values within 1e-4): the shares add up to the same fit."""
    base = SnakeParams.engine()
    nearly = base.replace(mass=tuple(base.mass * (1 + 1e-6 * np.arange(base.n))),
                          name="nearly_engine")
    assert base.uniform and not nearly.uniform
    uniform, per_link = identify_friction(base), identify_friction(nearly)
    assert isinstance(uniform["c_y"], float) and len(per_link["c_y"]) == base.n
    for key in ("c_x", "c_y", "c_theta"):
        assert np.allclose(per_link[key], uniform[key], rtol=1e-4), key


def test_initial_offset_moves_only_the_initial_joint_angles() -> None:
    """run_engine(initial_offset=d) starts at the arc of (82) with phi + d, records d, and
    refuses an offset of the wrong size or a non-finite one."""
    from snake_pin.engine.run import run_engine
    from snake_pin.gaits import initial_state

    offset = np.linspace(-1e-3, 1e-3, 7)
    traj = run_engine(t_final=0.01, initial_offset=offset).trajectory
    q0 = initial_state(8, theta_1=math.pi)[:10]
    assert np.allclose(traj.q[0, 3:], q0[3:] + offset, atol=1e-12)
    assert np.allclose(traj.q[0, :3], q0[:3], atol=1e-12)
    assert traj.meta["initial_offset"] == offset.tolist()
    for bad in (np.zeros(6), [math.nan] * 7):
        with pytest.raises(ParameterError, match="initial_offset"):
            run_engine(t_final=0.01, initial_offset=bad)


def test_perturbations_are_seeded_uniform_offsets() -> None:
    """perturbations(): (count, joints) draws within [-size, size], the same for the same
    seed, different rows and seeds, zeros for size 0; bad counts and sizes refused."""
    from snake_pin.runs.engine import perturbations

    a = perturbations(11, 7, 1e-6, seed=0)
    assert a.shape == (11, 7) and np.abs(a).max() <= 1e-6 and np.abs(a).max() > 5e-7
    assert np.array_equal(a, perturbations(11, 7, 1e-6, seed=0))
    assert not np.array_equal(a, perturbations(11, 7, 1e-6, seed=1))
    assert len({tuple(row) for row in a}) == 11
    assert not perturbations(3, 7, 0.0).any()
    for bad in ({"count": 0}, {"count": 2.5}, {"size": -1.0}, {"size": math.inf}):
        with pytest.raises(ParameterError):
            perturbations(**{"count": 3, "joints": 7, "size": 1e-6, **bad})


def test_distribution_and_median_draw() -> None:
    """distribution(): median and linearly interpolated 10/90 % percentiles of the numbers
    (None left out); Draws.median_draw() names the run whose RMS is the median."""
    from snake_pin.runs.engine import Draws, distribution

    d = distribution([float(v) for v in range(11, 0, -1)] + [None])
    assert (d["median"], d["p10"], d["p90"], d["min"], d["max"], d["count"]) == \
        (6.0, 2.0, 10.0, 1.0, 11.0, 11)
    assert distribution([None])["median"] is None
    draws = Draws("x", 1e-6, 0, np.zeros((4, 7)))
    assert draws.median_draw() is None and draws.distributions()["rms_percent"]["count"] == 0
    for i, rms in enumerate([9.0, 11.5, 8.9]):
        draws.record(i, {"rms_percent": rms, "status": "completed"})
    assert draws.done == [0, 1, 2] and draws.median_draw() == 0
    draws.record(3, {"rms_percent": 10.2, "status": "diverged"})
    assert draws.median_draw() == 0  # even count: the lower middle one
    assert draws.faults() == [3]
    assert draws.to_dict()["distribution"]["rms_percent"]["median"] == pytest.approx(9.6)


def test_run_engine_follows_the_reference_it_is_given() -> None:
    """run_engine(reference=...) drives both laws by that reference: the default line given
    explicitly reproduces the default run bit for bit, and a counter-clockwise circle of
    radius 1 body length from the same start pose takes the head at least 2 cm towards +y within 2 s
    (the line keeps it near y = 0)."""
    from snake_pin.control import head_first_reference
    from snake_pin.engine.run import run_engine
    from snake_pin.runs.benchmark import make_scenario

    for law in ("velocity", "acceleration"):
        default = run_engine(t_final=0.2, law=law).trajectory
        explicit = run_engine(t_final=0.2, law=law,
                              reference=head_first_reference()).trajectory
        assert np.array_equal(default.q, explicit.q) and np.array_equal(default.tau,
                                                                      explicit.tau)
        assert "reference" not in default.meta and "LinearReference" in explicit.meta[
            "reference"]
    circle = make_scenario("circle_1L", float(SnakeParams.engine().per_link(
        "link_length").sum()))
    line, turned = (run_engine(t_final=2.0, reference=ref).trajectory
                    for ref in (None, circle))
    assert turned.q[-1, 1] > 0.02 > abs(line.q[-1, 1])


def test_run_engine_prepares_the_controllers_sampling_instants(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The instants run_engine announces are MuJoCo's clock exactly: the velocity law reads
    every call's time terms from the prepared blocks (none computed alone), and the
    recorded times are the running sums of the engine timestep."""
    from snake_pin.control import QuasiStaticLyapunovController
    from snake_pin.engine.run import run_engine

    alone = []
    original = QuasiStaticLyapunovController._time_terms

    def counting(self: QuasiStaticLyapunovController, times: np.ndarray) -> np.ndarray:
        if len(times) == 1:
            alone.append(float(times[0]))
        return original(self, times)

    monkeypatch.setattr(QuasiStaticLyapunovController, "_time_terms", counting)
    wheels = WheelSpec(cone="pyramidal")
    traj = run_engine(t_final=0.3, wheels=wheels).trajectory
    assert traj.status == "completed" and len(traj) == 301 and alone == []
    clock = np.r_[0.0, np.cumsum(np.full(600, wheels.timestep))[1::2]]
    assert np.array_equal(traj.t, clock)


@pytest.fixture(scope="module")
def engine_friction() -> dict:
    return identify_friction()


@pytest.fixture(scope="module")
def mpc_failed_joint(engine_friction: dict):
    """1 s of the MPC on the engine, joint 5 failed, torques bounded by 1.5 N m (below what
    the first second asks for unbounded: about 2.3 N m), from a perturbed start."""
    from snake_pin.control import MPCOptions
    from snake_pin.engine.run import run_engine

    offset = np.linspace(-1e-6, 1e-6, 7)
    return run_engine(SnakeParams.engine(passive=(5,)), t_final=1.0, friction=engine_friction,
                      law="mpc", initial_offset=offset,
                      mpc_options=MPCOptions(torque_bound=1.5)).trajectory


def test_engine_mpc_torques_stay_within_the_bound(mpc_failed_joint) -> None:
    """Every torque the MPC sends to the motors is within its bound, and the bound is met
    (the run needs more: the box constrains the plan, it is not idle)."""
    traj = mpc_failed_joint
    assert traj.status == "completed" and traj.meta["law"] == "mpc"
    assert traj.meta["mpc"]["torque_bound"] == 1.5 and traj.meta["mpc"]["solves"] == 25
    peak = np.abs(traj.tau).max()
    assert peak <= 1.5 and peak > 1.5 * (1 - 1e-6)
    assert traj.q[-1, 0] > 0.03  # the head moved forward along the line


def test_engine_mpc_gives_a_failed_joint_no_torque(mpc_failed_joint) -> None:
    """Joint 5 (failed, no motor on the engine) gets exactly zero torque while the others
    work, and it still bends (moved by its neighbours)."""
    traj = mpc_failed_joint
    assert np.all(traj.tau[:, 4] == 0.0)
    assert np.all(np.abs(traj.tau[:, [0, 1, 2, 3, 5, 6]]).max(axis=0) > 0.05)
    assert np.ptp(traj.q[:, 3 + 4]) > 1e-3


def test_engine_mpc_is_deterministic(engine_friction: dict, mpc_failed_joint) -> None:
    """The same robot, start, friction and options give the same run bit for bit."""
    from snake_pin.control import MPCOptions
    from snake_pin.engine.run import run_engine

    again = run_engine(SnakeParams.engine(passive=(5,)), t_final=1.0, friction=engine_friction,
                       law="mpc", initial_offset=np.linspace(-1e-6, 1e-6, 7),
                       mpc_options=MPCOptions(torque_bound=1.5)).trajectory
    assert np.array_equal(again.q, mpc_failed_joint.q)
    assert np.array_equal(again.dq, mpc_failed_joint.dq)
    assert np.array_equal(again.tau, mpc_failed_joint.tau)


def test_engine_mpc_bound_is_the_motors_saturation() -> None:
    """The MPC's default bound on the engine is the motors' control range, which MuJoCo
    enforces: the MPC plans within exactly what the motors deliver."""
    from snake_pin.engine.run import ENGINE_TORQUE_BOUND

    model = build_engine_model().model
    assert np.all(model.actuator_ctrllimited == 1)
    assert np.all(model.actuator_ctrlrange == [-ENGINE_TORQUE_BOUND, ENGINE_TORQUE_BOUND])


@pytest.mark.parametrize(("kwargs", "words"), [
    ({"law": "pid"}, "law must be one of velocity, acceleration, mpc, got 'pid'"),
    ({"law": "velocity", "mpc_options": "x"}, "mpc_options are for law 'mpc'"),
    ({"law": "mpc", "mpc_options": {"torque_bound": 1.0}}, "mpc_options must be MPCOptions"),
    ({"law": "mpc", "mpc_options": "big"}, "exceeds the engine motors' 10 N m"),
])
def test_bad_engine_law_or_mpc_options_refused_in_one_line(kwargs: dict, words: str) -> None:
    """An unknown law, MPC options for another law or not MPCOptions, and a torque bound
    above the motors' are refused before any run, in one line."""
    from snake_pin.control import MPCOptions
    from snake_pin.engine.run import run_engine

    if kwargs.get("mpc_options") == "big":
        kwargs = {**kwargs, "mpc_options": MPCOptions(torque_bound=12.0)}
    with pytest.raises(ParameterError) as info:
        run_engine(t_final=1.0, **kwargs)
    assert words in str(info.value) and "\n" not in str(info.value)
