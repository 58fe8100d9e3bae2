"""Tests of snake_pin.study.work: a task's rows are the single-run path's, failures stay alone."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from snake_pin.study import work
from snake_pin.study.spec import Scenario, parse_study
from snake_pin.study.work import result_row, run_batch, simulate_scenario

#: Short runs of one layout: friction, failed joints (k_shape 0.3), a noisy start.
STUDY = """
[base]
t_final = 0.4
error_window = 0.2
c_x = 0.5
init_noise = 0.02
[axes.c_y]
values = [10.0, 50.0]
[axes.failed_joint]
values = [0, 3]
"""


@pytest.fixture(scope="module")
def scenarios() -> list[Scenario]:
    return list(parse_study(STUDY).scenarios)


def test_task_rows_are_the_rows_of_simulate_scenario(scenarios: list[Scenario]) -> None:
    """run_batch's rows equal result_row of simulate_scenario run by run, exactly (all but
    the wall time): a study run is the single run."""
    rows = run_batch(scenarios)
    assert [r["key"] for r in rows] == [s.key for s in scenarios]
    for scenario, row in zip(scenarios, rows, strict=True):
        alone = result_row(scenario, simulate_scenario(scenario))
        assert row["status"] == alone["status"] == "ok"
        assert row["wall_time"] > 0
        assert {k: v for k, v in row.items() if k != "wall_time"} == \
            {k: v for k, v in alone.items() if k != "wall_time"}


def test_a_run_whose_controller_cannot_be_built_fails_alone(
        scenarios: list[Scenario], monkeypatch: pytest.MonkeyPatch) -> None:
    """One scenario's controller raises: its row is failed with the error, the others ok."""
    original = work.build_controller

    def flaky(scenario: Scenario, snake: Any) -> Any:
        if scenario.index == 2:
            raise ZeroDivisionError("no torque today")
        return original(scenario, snake)

    monkeypatch.setattr(work, "build_controller", flaky)
    rows = run_batch(scenarios)
    assert [r["status"] for r in rows] == ["ok", "ok", "failed", "ok"]
    assert rows[2]["reason"] == "ZeroDivisionError: no torque today"
    assert rows[2]["rms_head_error"] is None and rows[3]["R_min"] > 0


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
