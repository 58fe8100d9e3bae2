"""Tests of snake_pin.study.work: lockstep batches inside a task, their fallbacks and memory."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from snake_pin.exceptions import ConfigurationError
from snake_pin.study import work
from snake_pin.study.spec import Scenario, parse_study
from snake_pin.study.work import (
    BATCH_RECORD_BYTES,
    MIN_LOCKSTEP,
    run_batch,
    runs_per_batch,
    simulate_scenario,
    simulate_viscous_batch,
)

#: 12 short runs of one layout: friction, failed joints (k_shape 0.3), rates, a noisy start.
STUDY = """
[base]
t_final = 0.6
error_window = 0.2
c_x = 0.5
init_noise = 0.02
[axes.c_y]
values = [10.0, 50.0]
[axes.failed_joint]
values = [0, 3, 9]
[axes.lam]
values = [5.0, 10.0]
"""
METRICS = ("rms_head_error", "max_head_error", "R_min", "R_tilde_min", "D_min", "t_end",
           "torque_rms")


@pytest.fixture(scope="module")
def scenarios() -> list[Scenario]:
    return list(parse_study(STUDY).scenarios)


@pytest.fixture(scope="module")
def one_by_one(scenarios: list[Scenario]) -> list[Any]:
    return [simulate_scenario(s).trajectory for s in scenarios]


def _assert_same_runs(outcomes: Any, expected: list[Any], tol: float) -> None:
    assert len(outcomes) == len(expected)
    for outcome, ref in zip(outcomes, expected, strict=True):
        traj = outcome.trajectory
        assert (traj.status, traj.reason) == (ref.status, ref.reason)
        np.testing.assert_array_equal(traj.t, ref.t)
        for name in ("q", "dq", "tau"):
            np.testing.assert_allclose(getattr(traj, name), getattr(ref, name), rtol=0,
                                       atol=tol, err_msg=name)


def test_a_lockstep_batch_equals_the_runs_one_by_one(scenarios: list[Scenario],
                                                     one_by_one: list[Any]) -> None:
    """12 runs in one lockstep batch equal simulate_scenario run by run to 1e-9 (q, dq, tau),
    and share one wall time (the batch's, divided by its runs)."""
    assert len(scenarios) >= MIN_LOCKSTEP
    outcomes = simulate_viscous_batch(scenarios)
    _assert_same_runs(outcomes, one_by_one, 1e-9)
    walls = {o.wall_time for o in outcomes}
    assert len(walls) == 1 and next(iter(walls)) > 0


def test_batched_rows_equal_rows_of_runs_one_by_one(scenarios: list[Scenario]) -> None:
    """run_batch's rows through the lockstep path equal its rows run alone, to 1e-9."""
    rows = run_batch(scenarios)
    for scenario, row in zip(scenarios, rows, strict=True):
        alone = run_batch([scenario])[0]  # one run: simulated one by one
        assert row["key"] == alone["key"] and row["status"] == alone["status"] == "ok"
        for metric in METRICS:
            assert row[metric] == pytest.approx(alone[metric], rel=1e-9, abs=1e-15), metric


def test_a_run_whose_controller_cannot_be_built_fails_alone(
        scenarios: list[Scenario], one_by_one: list[Any],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """One scenario's controller raises: its outcome is the error, the batch goes on."""
    original = work.build_controller

    def flaky(scenario: Scenario, snake: Any) -> Any:
        if scenario.index == 4:
            raise ZeroDivisionError("no torque today")
        return original(scenario, snake)

    monkeypatch.setattr(work, "build_controller", flaky)
    outcomes = simulate_viscous_batch(scenarios)
    assert outcomes[4].trajectory is None
    assert outcomes[4].error == "ZeroDivisionError: no torque today"
    keep = [i for i in range(len(scenarios)) if i != 4]
    _assert_same_runs([outcomes[i] for i in keep], [one_by_one[i] for i in keep], 1e-9)
    rows = run_batch(scenarios)
    assert [r["status"] for r in rows].count("failed") == 1 and rows[4]["status"] == "failed"


def test_a_batch_refused_as_a_whole_runs_one_by_one(
        scenarios: list[Scenario], one_by_one: list[Any],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """simulate_batch refuses the batch: every run goes through simulate (bit for bit)."""
    import snake_pin.batch

    def refuse(*_args: Any, **_kwargs: Any) -> Any:
        raise ConfigurationError("not today")

    monkeypatch.setattr(snake_pin.batch, "simulate_batch", refuse)
    _assert_same_runs(simulate_viscous_batch(scenarios), one_by_one, 0.0)


def test_a_task_beyond_the_memory_budget_runs_as_even_lockstep_chunks(
        scenarios: list[Scenario], one_by_one: list[Any],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """With room for 5 runs per batch, 12 runs go as 3 chunks of 4 (3 wall times), equal."""
    per_run = 601 * (2 * 12 + 9 + 2) * 8  # 0.6 s at 1 kHz, n = 10
    monkeypatch.setattr(work, "BATCH_RECORD_BYTES", 5 * per_run + 100)
    assert runs_per_batch(scenarios) == 5
    outcomes = simulate_viscous_batch(scenarios)
    _assert_same_runs(outcomes, one_by_one, 1e-9)
    walls = [o.wall_time for o in outcomes]
    assert [len(set(walls[i:i + 4])) for i in (0, 4, 8)] == [1, 1, 1]
    assert len(set(walls)) == 3


def test_few_runs_are_simulated_one_by_one(scenarios: list[Scenario],
                                           one_by_one: list[Any]) -> None:
    """Fewer than MIN_LOCKSTEP runs take simulate's path: identical bits, own wall times."""
    few = scenarios[:MIN_LOCKSTEP - 1]
    outcomes = simulate_viscous_batch(few)
    _assert_same_runs(outcomes, one_by_one[:len(few)], 0.0)


def test_outcomes_cut_their_trajectory_when_read(scenarios: list[Scenario]) -> None:
    """The outcome sequence holds no Trajectory: each read cuts a fresh (equal) one."""
    outcomes = simulate_viscous_batch(scenarios)
    first, again = outcomes[0], outcomes[0]
    assert first is not again and first.trajectory is not again.trajectory
    np.testing.assert_array_equal(first.trajectory.q, again.trajectory.q)
    assert [o.trajectory.t_end for o in outcomes[2:4]] == [0.6, 0.6]
    assert len(outcomes[::5]) == 3


def test_runs_per_batch_keeps_a_batch_within_the_record_budget() -> None:
    """60 s of the 10-link robot: 63 runs fit 1 GiB of samples, 64 do not; short runs: more."""
    spec = parse_study("[base]\nt_final = 60.0\n[axes.c_y]\nvalues = [5.0, 25.0]\n")
    runs = list(spec.scenarios)
    per_run = 60001 * (2 * 12 + 9 + 2) * 8
    count = runs_per_batch(runs)
    assert count * per_run <= BATCH_RECORD_BYTES < (count + 1) * per_run
    assert count == 63
    short = parse_study("[base]\nt_final = 6.0\n")
    assert runs_per_batch(list(short.scenarios)) == math.floor(
        BATCH_RECORD_BYTES / (6001 * 35 * 8))


@pytest.mark.parametrize("noise", [0.0, 1e-6])
def test_an_engine_run_starts_from_its_seeded_noise(monkeypatch: pytest.MonkeyPatch,
                                                    noise: float) -> None:
    """An engine run gets init_noise as offsets of its initial joint angles: the Gaussian
    draw of numpy's default_rng(init_seed), each seed its own (zeros without noise)."""
    import snake_pin.engine.run

    seen: list[np.ndarray] = []

    class Stop(Exception):
        pass

    def spy(*args: object, initial_offset: np.ndarray, **kwargs: object) -> None:
        seen.append(np.array(initial_offset))
        raise Stop

    monkeypatch.setattr(work, "_engine_friction", lambda *a: {"c_x": 1.0})
    monkeypatch.setattr(snake_pin.engine.run, "run_engine", spy)
    spec = parse_study("[base]\nrobot = \"engine\"\nmodel = \"engine\"\ncontroller = "
                       f"\"velocity\"\nt_final = 1.0\ninit_noise = {noise!r}\n"
                       "[axes.init_seed]\nvalues = [3, 4]\n")
    for scenario in spec.scenarios:
        with pytest.raises(Stop):
            work._simulate_engine(scenario)
    assert len({s.key for s in spec.scenarios}) == 2
    for scenario, offset in zip(spec.scenarios, seen, strict=True):
        want = (np.random.default_rng(scenario["init_seed"]).normal(0.0, noise, 7) if noise
                else np.zeros(7))
        np.testing.assert_array_equal(offset, want)
    assert (not np.array_equal(seen[0], seen[1])) == (noise > 0)
