"""Lockstep batches (snake_pin.batch, snake_pin.control.batched): every run equals simulate."""

from __future__ import annotations

import numpy as np
import pytest

from snake_pin import ConfigurationError, OpenLoop, ParameterError, Snake, SnakeParams, simulate
from snake_pin.batch import BatchResult, simulate_batch
from snake_pin.control import (
    LinearReference,
    LyapunovController,
    PFLController,
    QuasiStaticLyapunovController,
)
from snake_pin.control.batched import BatchTerms, FrictionCoefficients
from snake_pin.exceptions import RunInterrupted
from snake_pin.experiments.tracking import initial_state, tracking_params
from snake_pin.gaits import Serpenoid
from snake_pin.gaits import initial_state as arc_state
from snake_pin.sim import Trajectory

from .conftest import heterogeneous_params, random_state

#: The issue's bar: every run of a batch equals simulate's to 1e-9 over 3 s (relative to
#: the array's scale where that exceeds 1: a diverging run's speeds reach 1e3).
TOLERANCE = 1e-9
T_FINAL = 3.0


def _assert_same_run(got: Trajectory, ref: Trajectory) -> None:
    assert (got.status, got.reason) == (ref.status, ref.reason)
    assert got.params == ref.params
    np.testing.assert_array_equal(got.t, ref.t)
    for name in ("q", "dq", "tau"):
        want = getattr(ref, name)
        scale = max(1.0, float(np.abs(want).max()))
        np.testing.assert_allclose(getattr(got, name), want, rtol=0, atol=TOLERANCE * scale,
                                   err_msg=name)
    assert got.signals.keys() == ref.signals.keys()
    for name, want in ref.signals.items():
        scale = max(1.0, float(np.nanmax(np.abs(want)))) if np.isfinite(want).any() else 1.0
        np.testing.assert_allclose(got.signals[name], want, rtol=0, atol=TOLERANCE * scale)
    assert got.meta == ref.meta


def _check_batch(robots: list[SnakeParams], make: list, x0s: list[np.ndarray],
                 t_final: float | list[float] = T_FINAL, **options: object) -> BatchResult:
    """Run the batch, then each run through simulate, and compare run by run."""
    snakes = {p: Snake(p) for p in robots}
    result = simulate_batch(robots, [m(snakes[p]) for m, p in zip(make, robots, strict=True)],
                            x0s, t_final, **options)
    finals = t_final if isinstance(t_final, list) else [t_final] * len(robots)
    for b, (m, p) in enumerate(zip(make, robots, strict=True)):
        ref = simulate(snakes[p], m(snakes[p]), x0s[b], finals[b])
        _assert_same_run(result.trajectory(b), ref)
    return result


def test_lyapunov_batch_equals_simulate_with_passive_friction_gains_and_divergence() -> None:
    """Lyapunov runs (passive, per-run friction, gains, gaits; one diverging) equal simulate."""
    base = tracking_params()
    per_link = base.replace(c_x=(0.5,) * 9 + (1.5,), c_y=(25.0,) * 5 + (10.0,) * 5)
    robots = [base, base.replace(passive=(5,)), base.replace(c_y=5.0), base, per_link,
              per_link.replace(passive=(2, 7)), base]
    model = Snake(base.replace(c_y=10.0))  # a controller whose friction model is off
    make = [
        lambda s: LyapunovController(s),
        lambda s: LyapunovController(s),
        lambda s: LyapunovController(s, lam=5.0, gait=Serpenoid(10, np.pi / 5, 1.2, 1.5)),
        # mu dt > 2: the joint-velocity error grows by ~1.02 per step until it blows up
        lambda s: LyapunovController(s, lam_shape=2040.0),
        lambda s: LyapunovController(s, k_w1=[[2.0, 0.5, 0.0], [0.5, 2.0, 0.0], [0, 0, 3.0]],
                                     reference=LinearReference((0.05, 0.02, 0.0), (0, 0, np.pi))),
        lambda s: LyapunovController(s, k_shape=1.0, k_w2=(100.0, 100.0, 10.0)),
        lambda s: LyapunovController(model),
    ]
    x0s = [initial_state(p) for p in robots]
    x0s[2] = x0s[2] + np.r_[np.zeros(3), np.linspace(-0.1, 0.1, 9), np.zeros(12)]
    result = _check_batch(robots, make, x0s)
    assert result.status == ["completed"] * 3 + ["diverged"] + ["completed"] * 3
    assert 0.2 < result.last_t[3] < 0.5 * T_FINAL  # it left mid-run; the others went on
    assert np.all(result.last_t[[0, 1, 2, 4, 5, 6]] == pytest.approx(T_FINAL))


def test_velocity_and_pfl_laws_in_one_batch_equal_simulate() -> None:
    """Velocity-level and PFL runs grouped in one batch equal simulate, with a passive joint."""
    wheels = SnakeParams.table1(c_x=0.5, c_y=10.0)
    iso = SnakeParams.table1()
    robots = [wheels, wheels.replace(passive=(3,)), wheels.replace(c_y=5.0), iso, iso, iso, iso]
    make = [
        lambda s: QuasiStaticLyapunovController(s),
        lambda s: QuasiStaticLyapunovController(s),
        lambda s: QuasiStaticLyapunovController(s, servo_bandwidth=10.0, max_lead=0.1,
                                                k_w2=(100.0, 100.0, 10.0)),
        lambda s: PFLController(s),
        lambda s: PFLController(s, k_v=4.0, r_p=0.2),
        lambda s: PFLController(s, climb_R=0.5),
        lambda s: PFLController(s, r_min=1e3),  # R is never that large: fails at once
    ]
    x0s = [initial_state(p) for p in robots[:3]] + [arc_state(10)] * 4
    result = _check_batch(robots, make, x0s, t_final=2.0)
    assert result.status == ["completed"] * 6 + ["failed"]
    assert "SingularPostureError: R = " in result.reason[6]
    assert set(result.signals) == {"V", "R"}


def test_any_controller_runs_per_run_with_its_failures() -> None:
    """Functions and other controllers run per run; their failures stop only their own run."""
    params = SnakeParams.table1(n=6)
    n_tau = params.n - 1

    def wave(x: np.ndarray, t: float) -> np.ndarray:
        return 0.01 * np.sin(3 * t + np.arange(n_tau))

    def breaks(x: np.ndarray, t: float) -> np.ndarray:
        if t >= 0.25:
            raise RuntimeError("sensor lost")
        return np.zeros(n_tau)

    def short(x: np.ndarray, t: float) -> np.ndarray:
        return np.zeros(n_tau - (t > 0.1))

    make = [lambda s: wave, lambda s: breaks, lambda s: OpenLoop(lambda t: np.full(n_tau, 1e-3)),
            lambda s: short, lambda s: LyapunovController(s)]
    robots = [params] * len(make)
    result = _check_batch(robots, make, [arc_state(6, np.pi)] * len(make), t_final=0.5)
    assert result.status == ["completed", "failed", "completed", "failed", "completed"]
    assert "RuntimeError: sensor lost" in result.reason[1]
    assert result.reason[3] == "controller returned 4 torques, expected 5 at t = 0.1010 s"


def test_stride_per_run_final_times_and_the_aba_route() -> None:
    """A stride keeps every k-th sample and the last; t_final per run; ABA gives the same run."""
    params = tracking_params()
    snake = Snake(params)
    finals = [0.5, 0.3337, 0.41]
    refs = [simulate(snake, LyapunovController(snake), initial_state(params), t) for t in finals]
    for dynamics in ("closed_form", "aba"):
        result = simulate_batch(params, [LyapunovController(snake) for _ in finals],
                                [initial_state(params)] * 3, finals, stride=7,
                                dynamics=dynamics)
        for b, ref in enumerate(refs):
            got = result.trajectory(b)
            last = len(ref) - 1
            keep = [*range(0, last, 7), last]
            assert got.meta.pop("stride") == 7
            _assert_same_run(got, Trajectory(
                t=ref.t[keep], q=ref.q[keep], dq=ref.dq[keep], tau=ref.tau[keep],
                params=ref.params, signals={k: v[keep] for k, v in ref.signals.items()},
                status=ref.status, reason=ref.reason, meta=ref.meta))
    assert result.t[1] == pytest.approx(0.007) and len(result.t) == 500 // 7 + 1


def test_interrupt_keeps_every_run_so_far() -> None:
    """Ctrl-C in a batch: RunInterrupted carries the runs, those still going marked so."""
    params = SnakeParams.table1(n=5)

    def interrupts(x: np.ndarray, t: float) -> np.ndarray:
        if t >= 0.05:
            raise KeyboardInterrupt
        return np.zeros(4)

    def fails(x: np.ndarray, t: float) -> np.ndarray:
        raise ValueError("no")

    with pytest.raises(RunInterrupted) as caught:
        simulate_batch(params, [lambda x, t: np.zeros(4), interrupts, fails],
                       [arc_state(5)] * 3, 1.0)
    partial = caught.value.partial
    assert isinstance(partial, BatchResult)
    assert partial.status == ["interrupted", "interrupted", "failed"]
    assert partial.reason[0] == "interrupted at t = 0.0500 s"
    run = partial.trajectory(1)
    assert len(run) == 51 and run.t_end == pytest.approx(0.05) and not run.tau[-1].any()


def test_batch_terms_equal_pinocchio_on_heterogeneous_robots(rng: np.random.Generator) -> None:
    """Closed-form H, h, C, friction and q'' over a batch equal Snake's (Pinocchio) per run."""
    for friction in ("none", "isotropic", "anisotropic"):
        layout = heterogeneous_params(rng, 7, friction)
        robots = [layout, layout.replace(c_y=3.0, c_x=0.2, passive=(4,)), layout]
        terms, coeffs = BatchTerms(layout), FrictionCoefficients(robots)
        states = [np.concatenate(random_state(rng, 7)) for _ in robots]
        x = np.array(states)
        tau = rng.normal(size=(3, 6))
        batched = {"H": terms.inertia(x), "C": terms.friction_matrix(x, coeffs),
                   "h": terms.bias(x, coeffs), "ddq": terms.forward_dynamics(x, coeffs, tau)}
        for b, robot in enumerate(robots):
            snake, (q, dq) = Snake(robot), (states[b][:9], states[b][9:])
            expected = {"H": snake.inertia_matrix(q), "C": snake.friction.matrix(q),
                        "h": snake.bias(q, dq),
                        "ddq": np.linalg.solve(snake.inertia_matrix(q),
                                               np.r_[0, 0, 0, tau[b]] - snake.bias(q, dq))}
            for name, want in expected.items():
                np.testing.assert_allclose(batched[name][b], want, rtol=0,
                                           atol=1e-10 * max(1.0, np.abs(want).max()),
                                           err_msg=f"{friction} {name} run {b}")


def test_batch_refuses_bad_arguments() -> None:
    """Mixed layouts, shared controllers, wrong shapes and options: one error each, nothing run."""
    params = SnakeParams.table1(n=4)
    snake = Snake(params)
    x0s = [arc_state(4)] * 2

    def ctrls() -> list[LyapunovController]:
        return [LyapunovController(snake) for _ in range(2)]

    with pytest.raises(ParameterError, match="link_length, mass differ"):
        simulate_batch([params, params.replace(link_length=0.2, mass=1.0)], ctrls(), x0s, 1.0)
    shared = LyapunovController(snake)
    with pytest.raises(ParameterError, match="its own controller"):
        simulate_batch(params, [shared, shared], x0s, 1.0)
    with pytest.raises(ParameterError, match="list of 2 controllers"):
        simulate_batch([params, params], ctrls()[:1], x0s, 1.0)
    with pytest.raises(ConfigurationError, match=r"shape \(2, 12\)"):
        simulate_batch(params, ctrls(), [arc_state(4)], 1.0)
    with pytest.raises(ConfigurationError, match=r"x0s\[1\] has non-finite"):
        simulate_batch(params, ctrls(), [arc_state(4), np.full(12, np.nan)], 1.0)
    with pytest.raises(ParameterError, match="t_final"):
        simulate_batch(params, ctrls(), x0s, [1.0, -1.0])
    with pytest.raises(ParameterError, match="dynamics"):
        simulate_batch(params, ctrls(), x0s, 1.0, dynamics="rnea")
    with pytest.raises(ParameterError, match="stride"):
        simulate_batch(params, ctrls(), x0s, 1.0, stride=0)
    with pytest.raises(ParameterError, match="raise the stride"):
        simulate_batch(params, [lambda x, t: np.zeros(3) for _ in range(4096)],
                       [arc_state(4)] * 4096, 1000.0)
    with pytest.raises(ParameterError, match="7-link robot"):
        simulate_batch(params, [LyapunovController(Snake(SnakeParams.table1(n=7)))],
                       [arc_state(4)], 1.0)
