"""The fast closed-loop step gives the results of the step it replaced (issue 13)."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from snake_pin import OpenLoop, Snake, SnakeParams, simulate
from snake_pin.control import Controller, LyapunovController, PFLController
from snake_pin.experiments.tracking import initial_state, tracking_params
from snake_pin.friction import WHEELED_TWIN_MAX_LINKS

from .conftest import head_first_state, heterogeneous_params

FIXTURE = Path(__file__).parent / "data" / "speed_baseline.npz"
SCRIPT = Path(__file__).parents[1] / "scripts" / "record_speed_fixture.py"


def _recorder():
    """scripts/record_speed_fixture.py as a module (its ``run`` defines the runs)."""
    spec = importlib.util.spec_from_file_location("record_speed_fixture", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("name", ["lyapunov", "lyapunov_passive5", "pfl_vi1"])
def test_reference_runs_end_where_they_did(name: str) -> None:
    """The 60 s tracking runs and the VI.1 PFL run end within 1e-9 of the recorded states.

    tests/data/speed_baseline.npz holds the final q, dq and t_end of each run, recorded once
    by ``python scripts/record_speed_fixture.py`` at commit e8edb99 (the step before the
    speed work; dc0b889 ends within 2e-12 of it, 1.2e-10 relative on the PFL blow-up). The
    PFL run ends at its breakdown with |dq| ~ 700, so errors are relative to
    max(1, |value|).
    """
    recorded = np.load(FIXTURE)
    traj = _recorder().run(name)
    assert traj.t_end == pytest.approx(float(recorded[f"{name}_t_end"]), abs=1e-12)
    for key, now in (("q", traj.q[-1]), ("dq", traj.dq[-1])):
        then = recorded[f"{name}_{key}"]
        scale = max(1.0, float(np.abs(then).max()))
        assert np.abs(now - then).max() <= 1e-9 * scale, key


# ----------------------------------------------------------------- fast step vs plain step
class _PlainSnake(Snake):
    """The same robot with its own state_derivative, so simulate takes the plain RK4 step."""

    def state_derivative(self, x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        return super().state_derivative(x, tau)


def _robots() -> dict[str, SnakeParams]:
    rng = np.random.default_rng(13)
    return {"isotropic": tracking_params(c_y=0.5), "wheels": tracking_params(),
            "passive": tracking_params(passive=(3, 5)),
            "rnea passes": tracking_params(SnakeParams.table1(n=WHEELED_TWIN_MAX_LINKS + 2)),
            "per link": heterogeneous_params(rng, 10, "anisotropic", passive=(4,))}


@pytest.mark.parametrize(("robot", "law"), [
    (robot, law) for robot, params in _robots().items()
    for law in ("lyapunov", "pfl", "open loop, two substeps")
    if not (law == "pfl" and params.passive)])  # PFL needs every joint actuated
def test_fast_step_equals_the_plain_step(robot: str, law: str) -> None:
    """The fast RK4 (its first stage from the controller) follows the plain RK4 to 1e-9.

    The plain step is a plant that replaces state_derivative (the checked API, per stage);
    a wrong stage or hold would be off by O(dt) = 1e-3.
    """
    params = _robots()[robot]
    runs = []
    for cls in (Snake, _PlainSnake):
        snake = cls(params)
        settings = {}
        if law == "lyapunov":
            controller = LyapunovController(snake)
        elif law == "pfl":
            controller = PFLController(snake)
        else:
            controller = OpenLoop(lambda t, n=snake.n: 0.02 * np.sin(3 * t + np.arange(n - 1)))
            settings = {"dt": 5e-4}
        runs.append(simulate(snake, controller, initial_state(params), 0.3, **settings))
    fast, plain = runs
    assert fast.status == plain.status == "completed" and len(fast) == len(plain) == 301
    assert np.abs(fast.q - plain.q).max() < 1e-9
    assert np.abs(fast.dq - plain.dq).max() < 1e-9 * max(1.0, np.abs(plain.dq).max())
    assert np.abs(fast.tau - plain.tau).max() < 1e-7 * max(1.0, np.abs(plain.tau).max())


def test_fast_step_diverges_where_the_plain_step_does() -> None:
    """A run leaving its bounds stops at the same sample with the same reason on both paths."""
    params = tracking_params()
    runs = [simulate(cls(params), OpenLoop(lambda t: np.full(9, 0.0 if t < 0.05 else 40.0)),
                     initial_state(params), 1.0, max_speed=20.0) for cls in (Snake, _PlainSnake)]
    assert runs[0].status == runs[1].status == "diverged"
    assert runs[0].reason == runs[1].reason and len(runs[0]) == len(runs[1]) > 50


class _TurnsBad(Controller):
    """Finite torques with a signal "a", then from t = 0.02 s ``bad`` at ``entry`` and a
    new signal "b"."""

    name = "turns_bad"

    def __init__(self, bad: float, entry: int) -> None:
        self.bad, self.entry, self._t = bad, entry, 0.0

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        self._t = t
        tau = 0.01 * np.sin(2 * t + np.arange(9))
        if t >= 0.02 - 1e-12:
            tau[self.entry] = self.bad
        return tau

    def signals(self) -> dict[str, float]:
        return {"a": self._t, **({"b": 1.0} if self._t >= 0.02 - 1e-12 else {})}


@pytest.mark.parametrize(("bad", "entry", "passive", "max_speed"), [
    (np.nan, 0, (), 1e3), (np.inf, 3, (), math.inf), (-np.inf, 8, (), 1e3),
    (np.nan, 4, (5,), 1e3), (np.inf, 4, (5,), math.inf), (-np.inf, 4, (5,), 1e3)])
def test_fast_step_refuses_a_torque_where_the_plain_step_does(
        bad: float, entry: int, passive: tuple, max_speed: float) -> None:
    """A non-finite torque (a passive joint's included) fails the run at its sample on both
    paths alike: the same reason, samples, torques and signals (none from that call)."""
    params = tracking_params(passive=passive)
    runs = [simulate(cls(params), _TurnsBad(bad, entry), initial_state(params), 0.05,
                     max_speed=max_speed) for cls in (Snake, _PlainSnake)]
    fast, plain = runs
    assert fast.status == plain.status == "failed" and len(fast) == len(plain) == 21
    assert fast.reason == plain.reason == \
        "controller returned a non-finite torque at t = 0.0200 s"
    assert np.array_equal(fast.tau, plain.tau) and not fast.tau[-1].any()
    assert set(fast.signals) == set(plain.signals) == {"a"}
    assert np.array_equal(fast.signals["a"], plain.signals["a"], equal_nan=True)
    assert np.isnan(fast.signals["a"][-1])
    assert np.abs(fast.q - plain.q).max() < 1e-12


@pytest.mark.parametrize("robot", ["isotropic", "wheels"])
def test_a_run_after_a_blown_up_run_of_the_same_robot_is_untouched(robot: str) -> None:
    """What a non-finite torque left in a run's buffers does not reach the next run of the
    same robot (equal to the run on a fresh robot)."""
    params = _robots()[robot]
    used = Snake(params)
    blown = simulate(used, _TurnsBad(np.inf, 3), initial_state(params), 0.05)
    assert blown.status == "failed"
    runs = [simulate(snake, LyapunovController(snake), initial_state(params), 0.05)
            for snake in (used, Snake(params))]
    assert runs[0].status == runs[1].status == "completed"
    assert np.array_equal(runs[0].q, runs[1].q) and np.array_equal(runs[0].dq, runs[1].dq)


class _Predicting(LyapunovController):
    """The law, coasting its own robot for 3 ms before every 10th sample (a run nested in
    the run), and for 10 ms in ``prepare`` from a shifted start."""

    def prepare(self, times: np.ndarray) -> None:
        super().prepare(times)
        shifted = initial_state(self.snake.params) + 0.05
        simulate(self.snake, OpenLoop(lambda t: np.zeros(self.snake.n - 1)), shifted, 0.01)
        super().prepare(times)

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        if round(t * 1000) % 10 == 0:
            simulate(self.snake, OpenLoop(lambda s: np.zeros(self.snake.n - 1)), x, 0.003)
        return super().__call__(x, t)


@pytest.mark.parametrize("robot", ["isotropic", "wheels"])
def test_runs_of_one_robot_nest(robot: str) -> None:
    """A controller that simulates its own robot (in prepare and in its calls) does not
    disturb the run it is in: the same run as on another robot object."""
    params = _robots()[robot]
    plant = Snake(params)
    nested = simulate(plant, _Predicting(plant), initial_state(params), 0.1)
    apart = simulate(plant, _Predicting(Snake(params)), initial_state(params), 0.1)
    assert nested.status == apart.status == "completed"
    assert np.abs(nested.q - apart.q).max() < 1e-12
    assert np.abs(nested.tau - apart.tau).max() <= 1e-9 * np.abs(apart.tau).max()


class _StrictTurnsBad(_TurnsBad):
    """:class:`_TurnsBad` that has numpy raise on every floating-point error from its first
    call on, and whose signals and q'' refuse a non-finite torque of its own."""

    name = "strict_turns_bad"

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        np.seterr(all="raise")
        self._tau = super().__call__(x, t)
        return self._tau

    def signals(self) -> dict[str, float]:
        if not np.isfinite(self._tau).all():
            raise ValueError("no signals for a non-finite torque")
        return super().signals()

    def plant_acceleration(self, snake: object) -> np.ndarray | None:
        if not np.isfinite(self._tau).all():
            raise ValueError("no q'' for a non-finite torque")
        return None


@pytest.mark.parametrize(("bad", "passive"), [(np.inf, (5,)), (np.nan, (5,)), (-np.inf, ())])
def test_bad_torque_refused_first_whatever_the_controller_does(bad: float,
                                                               passive: tuple) -> None:
    """A controller that sets numpy's errors to raise mid-run and whose signals fail on its
    own non-finite torque: the fast path still names the torque, as the plain one does."""
    params = tracking_params(passive=passive)
    runs = []
    for cls in (Snake, _PlainSnake):
        previous = np.geterr()
        try:
            runs.append(simulate(cls(params), _StrictTurnsBad(bad, 4), initial_state(params),
                                 0.05))
        finally:
            np.seterr(**previous)
    fast, plain = runs
    assert fast.status == plain.status == "failed" and len(fast) == len(plain) == 21
    assert fast.reason == plain.reason == \
        "controller returned a non-finite torque at t = 0.0200 s"
    assert np.array_equal(fast.tau, plain.tau) and set(fast.signals) == set(plain.signals)


@pytest.mark.parametrize("robot", ["isotropic", "wheels", "passive", "rnea passes"])
def test_controllers_know_the_plants_acceleration(robot: str) -> None:
    """plant_acceleration is the plant's q'' under the returned torque, for its own robot only."""
    params = _robots()[robot]
    snake, other = Snake(params), Snake(params)
    rng = np.random.default_rng(5)
    laws = [LyapunovController(snake)] + ([] if params.passive else [PFLController(snake)])
    for law in laws:
        for _ in range(5):
            x = head_first_state(rng, snake.n)
            tau = law(x, rng.uniform(0, 10))
            ddq = snake.forward_dynamics(x[:snake.nq], x[snake.nq:], tau)
            assert np.abs(law.plant_acceleration(snake) - ddq).max() < \
                1e-9 * max(1.0, np.abs(ddq).max())
            assert law.plant_acceleration(other) is None


@pytest.mark.parametrize("mirrors", [True, False])
@pytest.mark.parametrize("robot", ["isotropic", "wheels", "rnea passes", "per link"])
def test_calc_methods_match_the_checked_api(robot: str, mirrors: bool,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """calc_affine gives b = q''(tau = 0) and the whole H^-1; calc_mass_and_bias the whole
    H and h. Also with bindings that fill the upper triangle only (simulated: SnakeData
    then mirrors it itself)."""
    import pinocchio as pin

    import snake_pin.model

    if not mirrors:
        crba, minverse = pin.crba, pin.computeMinverse

        def upper_only(matrix: np.ndarray) -> np.ndarray:
            matrix[np.tril_indices(len(matrix), -1)] = 0.0
            return np.triu(matrix)

        monkeypatch.setattr(pin, "crba", lambda m, d, *a: (crba(m, d, *a), upper_only(d.M))[1])
        monkeypatch.setattr(pin, "computeMinverse",
                            lambda m, d, *a: (minverse(m, d, *a), upper_only(d.Minv))[1])
        assert not snake_pin.model._binding_mirrors(Snake(_robots()[robot]).model)
    snake = Snake(_robots()[robot])
    data = snake.create_data()
    rng = np.random.default_rng(8)
    nq = snake.nq
    for _ in range(5):
        x = head_first_state(rng, snake.n)
        q, dq = x[:nq], x[nq:]
        b, minv = snake.calc_affine(data, q, dq)
        assert np.allclose(b, snake.forward_dynamics(q, dq, np.zeros(snake.n - 1)),
                           rtol=1e-10, atol=1e-10)
        assert np.allclose(minv, snake.inverse_inertia_matrix(q), rtol=1e-10, atol=1e-10)
        mass, bias = snake.calc_mass_and_bias(data, q, dq)
        assert np.allclose(mass, snake.inertia_matrix(q), atol=1e-14)
        assert np.allclose(bias, snake.bias(q, dq), rtol=1e-12, atol=1e-13)


def _classical_rk4(snake: Snake, schedule, x0: np.ndarray, t_final: float, dt: float,
                   control_dt: float) -> np.ndarray:
    """The classical RK4 with a zero-order hold, on the checked forward_dynamics: the
    states at each control sample (written here, independent of the package's step)."""
    nq, substeps = snake.nq, round(control_dt / dt)

    def slope(x: np.ndarray, tau: np.ndarray) -> np.ndarray:
        return np.concatenate((x[nq:], snake.forward_dynamics(x[:nq], x[nq:], tau)))

    states, x = [x0], x0.copy()
    for k in range(round(t_final / control_dt)):
        tau = schedule(k * control_dt)
        for _ in range(substeps):
            d1 = slope(x, tau)
            d2 = slope(x + 0.5 * dt * d1, tau)
            d3 = slope(x + 0.5 * dt * d2, tau)
            d4 = slope(x + dt * d3, tau)
            x = x + dt / 6.0 * (d1 + 2.0 * d2 + 2.0 * d3 + d4)
        states.append(x)
    return np.array(states)


@pytest.mark.parametrize("robot", ["isotropic", "wheels", "passive", "rnea passes"])
def test_rk4_equals_the_classical_formula(robot: str) -> None:
    """simulate's RK4 (stage states from rows of Y = [Z; d1..d4], first stage on the plant) is
    the classical RK4 with the torque held, to 1e-11 (a wrong stage or weight: O(dt))."""
    params = _robots()[robot]
    snake = Snake(params)

    def schedule(t: float, n: int = params.n) -> np.ndarray:
        return 0.02 * np.sin(3 * t + np.arange(n - 1))

    x0 = initial_state(params)
    run = simulate(snake, OpenLoop(schedule), x0, 0.05, dt=5e-4)
    expected = _classical_rk4(snake, schedule, x0, 0.05, 5e-4, 1e-3)
    assert run.status == "completed"
    assert np.abs(np.hstack((run.q, run.dq)) - expected).max() < 1e-11


@pytest.mark.parametrize("law", [LyapunovController, PFLController])
def test_time_terms_do_not_depend_on_prepare(law: type) -> None:
    """Announced times (blocks of references) give the torques of calls one at a time."""
    snake = Snake(tracking_params())
    first, second = law(snake), law(snake)
    times = np.arange(2100) * 1e-3
    second.prepare(times)
    rng = np.random.default_rng(2)
    for k in (0, 1, 2, 3, 1500, 1501, 2099):
        x = head_first_state(rng, snake.n)
        for t in (times[k], 0.123456):  # an announced time, then one that is not
            expected = first(x, float(t))
            assert np.abs(second(x, float(t)) - expected).max() <= \
                1e-12 * max(1.0, np.abs(expected).max())
        for skipped in range(k + 1, min(k + 1 + 1499 * (k == 0), len(times))):
            second(x, float(times[skipped]))  # walk past a block boundary


def test_one_blas_thread_inside_simulate() -> None:
    """The run's loop holds BLAS to one thread; the limits are restored after it."""
    from threadpoolctl import threadpool_info

    before = {pool["filepath"]: pool["num_threads"] for pool in threadpool_info()}
    seen: list[set[int]] = []

    def controller(x: np.ndarray, t: float) -> np.ndarray:
        seen.append({pool["num_threads"] for pool in threadpool_info()
                     if pool["user_api"] == "blas"})
        return np.zeros(9)

    simulate(Snake(), controller, initial_state(SnakeParams.table1()), 0.003)
    assert seen and all(threads == {1} for threads in seen)
    assert {pool["filepath"]: pool["num_threads"] for pool in threadpool_info()} == before


def test_saved_figures_keep_their_labels_without_the_tight_box(tmp_path: Path) -> None:
    """save_figure lays a figure out (constrained) and writes it whole: every label inside."""
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from PIL import Image

    from snake_pin.viz.plots import save_figure

    fig, axes = plt.subplots(2, 1, figsize=(6, 4))
    for ax in axes:
        ax.plot([0, 1], [0, 1])
        ax.set_yticks([0, 1], ["a long tick label", "another long tick label"])
        ax.set_ylabel("a long label [m s^-1]")
        ax.set_xlabel("t [s]")
    fig.suptitle("a title")
    save_figure(fig, tmp_path / "figure.png")
    assert fig.get_layout_engine() is not None
    with Image.open(tmp_path / "figure.png") as image:
        assert image.size == (660, 440)  # 6 x 4 in at 110 dpi: nothing cropped
    renderer = FigureCanvasAgg(fig).get_renderer()  # the closed figure, laid out as saved
    whole = fig.bbox
    for text in [fig.get_suptitle() and fig._suptitle, *(ax.yaxis.label for ax in axes),
                 axes[1].xaxis.label]:
        box = text.get_window_extent(renderer)
        assert box.x0 >= whole.x0 and box.y0 >= whole.y0
        assert box.x1 <= whole.x1 and box.y1 <= whole.y1


def test_robots_and_controllers_still_pickle_after_a_run() -> None:
    """A used robot and its laws round-trip (their data objects made again) and rerun."""
    import pickle

    params = tracking_params()
    snake = Snake(params)
    laws = [LyapunovController(snake), PFLController(snake)]
    for law in laws:
        before = simulate(snake, law, initial_state(params), 0.02)
        copy = pickle.loads(pickle.dumps(law))
        assert copy.snake is not snake
        after = simulate(copy.snake, copy, initial_state(params), 0.02)
        assert np.array_equal(before.q, after.q) and np.array_equal(before.tau, after.tau)
    again = pickle.loads(pickle.dumps(snake))
    data = pickle.loads(pickle.dumps(snake.create_data()))
    x = initial_state(params)
    assert np.array_equal(again.calc_affine(again.create_data(), x[:snake.nq], x[snake.nq:])[0],
                          snake.calc_affine(data, x[:snake.nq], x[snake.nq:])[0])


def test_a_shallow_copy_keeps_its_own_last_call(rng: np.random.Generator) -> None:
    """copy.copy of a law: calling the copy leaves the original's signals alone (and the
    Lyapunov-like law's q''; PFL's q'' is a buffer that shallow copies share, as before)."""
    import copy

    snake = Snake(tracking_params())
    for law in (LyapunovController(snake), PFLController(snake)):
        law(head_first_state(rng, snake.n), 1.0)
        signals, ddq = dict(law.signals()), law.plant_acceleration(snake).copy()
        twin = copy.copy(law)
        twin(head_first_state(rng, snake.n), 2.0)
        assert law.signals() == signals and twin.signals() != signals
        if isinstance(law, LyapunovController):
            assert np.array_equal(law.plant_acceleration(snake), ddq)


def test_a_subclass_call_is_what_a_run_calls() -> None:
    """A law's subclass that scales or clips its torque gets its own __call__ in a run."""

    class Scaled(LyapunovController):
        def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
            return 2.0 * super().__call__(x, t)

    class Clipped(LyapunovController):
        def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
            return np.clip(super().__call__(x, t), -0.005, 0.005)

    params = tracking_params()
    snake = Snake(params)
    law = LyapunovController(snake)
    run = simulate(snake, Scaled(snake), initial_state(params), 0.02)
    assert np.allclose(run.tau[0], 2.0 * law(initial_state(params), 0.0), rtol=1e-12)
    run = simulate(snake, Clipped(snake), initial_state(params), 0.02)
    assert np.abs(run.tau).max() <= 0.005
    assert np.abs(law(initial_state(params), 0.0)).max() > 0.005


@pytest.mark.parametrize("law", [LyapunovController, PFLController])
def test_a_law_on_another_robot_object_reads_its_own_state(law: type) -> None:
    """A law whose model is another Snake object (same robot) is not handed the plant's
    RK4 state: its run is the run of a law on the plant itself (to rounding: the plant
    then evaluates RK4's first stage itself)."""
    params = tracking_params() if law is LyapunovController else SnakeParams.table1(c_y=5.0)
    plant = Snake(params)
    x0 = initial_state(params) if law is LyapunovController else \
        np.r_[0.0, 0.0, 0.0, np.full(params.n - 1, np.pi / 6), np.zeros(params.n + 2)]
    runs = [simulate(plant, law(model), x0, 0.2) for model in (plant, Snake(params))]
    assert runs[0].status == runs[1].status == "completed"
    assert np.allclose(runs[0].q, runs[1].q, rtol=0.0, atol=1e-12)
    assert np.abs(runs[0].tau - runs[1].tau).max() <= 1e-9 * np.abs(runs[1].tau).max()
