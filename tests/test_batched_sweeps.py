"""Tests of snake_pin.experiments.batched_sweeps (routes of the report's tracking runs)."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

from snake_pin import ParameterError, SnakeParams
from snake_pin.experiments import tracking
from snake_pin.experiments.batched_sweeps import iter_tracking_runs, run_tracking_batch
from snake_pin.experiments.tracking import (
    C_Y_FACTORS,
    DECAY_RATES,
    plot_sweep,
    report_runs,
    sweep_findings,
    sweep_ratio,
    sweep_text,
    tracking_friction,
    tracking_params,
)
from snake_pin.metrics import head_error_summary, percent


@pytest.fixture
def short_window(monkeypatch: pytest.MonkeyPatch) -> None:
    """Judge head errors from 1 s, so that 2 s runs have an error window."""
    monkeypatch.setattr(tracking, "head_error_summary",
                        functools.partial(head_error_summary, start=1.0))


@pytest.fixture
def batches(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The size of every simulate_batch call the test makes, in order (a spy)."""
    import snake_pin.batch

    sizes: list[int] = []
    original = snake_pin.batch.simulate_batch

    def spy(robots: list[SnakeParams], *args: object, **kwargs: object) -> object:
        sizes.append(len(robots))
        return original(robots, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(snake_pin.batch, "simulate_batch", spy)
    return sizes


@pytest.mark.usefixtures("short_window")
def test_the_stage_runs_batched_give_the_per_run_rows(batches: list[int]) -> None:
    """The tracking stage's 18 runs (2 s) as one lockstep batch give the rows of the runs
    one by one to 1e-9: RMS, % of body, max error, R min, D min (g drift to 1e-6)."""
    robot, _ = tracking_friction(SnakeParams.table1())
    runs = report_runs(robot, 2.0, own=False)
    jobs = [(r.params, r.t_final, r.options) for r in runs]
    batched = dict(iter_tracking_runs(jobs, workers=1, lockstep_from=1))
    assert batches == [len(jobs)]
    alone = dict(iter_tracking_runs(jobs, workers=1, lockstep_from=len(jobs) + 1))
    assert batches == [len(jobs)]  # one by one: no batch
    assert sorted(batched) == sorted(alone) == list(range(len(runs)))
    for index, run in enumerate(runs):
        got, want = batched[index], alone[index]
        assert got.t_end == want.t_end == run.t_final and got.status == want.status
        assert got.summary["rms_head_error"] is not None
        assert percent(got.summary["rms_relative"]) == pytest.approx(
            percent(want.summary["rms_relative"]), rel=1e-9)
        for key in ("rms_head_error", "max_head_error", "R_min", "D_min"):
            assert got.summary[key] == pytest.approx(want.summary[key], rel=1e-9), key
        assert got.summary["g_drift"] == pytest.approx(want.summary["g_drift"], rel=1e-6,
                                                       abs=1e-12)
        for key in ("c_x", "c_y", "passive"):
            assert got.summary[key] == want.summary[key]
        for key in ("lam", "lam_shape", "k_shape", "reference"):
            assert got.meta[key] == want.meta[key], key


def test_two_workers_give_each_job_its_own_run() -> None:
    """On 2 worker processes, by either route, the trajectory handed back for job i is
    job i's: its c_y, its duration and its decay rate."""
    jobs = [(tracking_params(c_y=c_y), t_final, {"lam": lam})
            for c_y, t_final, lam in ((10.0, 0.3, 3.0), (20.0, 0.5, 5.0), (30.0, 0.2, 7.0),
                                      (40.0, 0.4, 9.0))]
    for lockstep_from in (1, 100):
        seen = dict(iter_tracking_runs(jobs, workers=2, lockstep_from=lockstep_from))
        assert sorted(seen) == [0, 1, 2, 3]
        for index, (params, t_final, options) in enumerate(jobs):
            traj = seen[index]
            assert traj.params.c_y == params.c_y and traj.summary["c_y"] == params.c_y
            assert traj.t_end == pytest.approx(t_final, abs=1e-12)
            assert traj.meta["lam"] == options["lam"]


def test_run_tracking_batch_equals_iter_in_one_batch() -> None:
    """run_tracking_batch returns the runs in job order: same head error, bit for bit, as
    the same batch through iter_tracking_runs."""
    jobs = [(tracking_params(c_y=c_y), 0.3, {}) for c_y in (50.0, 10.0)]
    direct = run_tracking_batch(jobs)
    through = dict(iter_tracking_runs(jobs, workers=1, lockstep_from=1))
    for index, traj in enumerate(direct):
        assert traj.params.c_y == jobs[index][0].c_y
        assert np.array_equal(traj.signals["head_error"], through[index].signals["head_error"])


@pytest.mark.parametrize("job", [(SnakeParams.table1(), 1.0, {"gamma": 2.0}),
                                 ("table1", 1.0, {}), (SnakeParams.table1(), 1.0)])
def test_bad_jobs_are_refused_before_anything_runs(job: object) -> None:
    """An unknown controller option or a malformed job is a ParameterError naming it, raised
    by the call itself (before any next())."""
    with pytest.raises(ParameterError, match="job 0"):
        iter_tracking_runs([job])  # type: ignore[list-item]
    with pytest.raises(ParameterError, match="job 0"):
        run_tracking_batch([job])  # type: ignore[list-item]


@pytest.mark.parametrize("name", ["workers", "lockstep_from"])
@pytest.mark.parametrize("value", [0, -1, 1.5, True])
def test_workers_and_lockstep_from_must_be_positive_integers(name: str, value: object) -> None:
    """workers and lockstep_from outside 1, 2, ... are refused with their name, by the
    call itself."""
    with pytest.raises(ParameterError, match=name):
        iter_tracking_runs([(tracking_params(), 0.1, {})], **{name: value})


def test_report_runs_vary_one_setting_each() -> None:
    """The stage's runs: four with files, then two sweeps that change only the decay rates
    (mu = lambda / 2) or only every link's c_y, skipping the default point (the first run)."""
    robot = tracking_params()
    runs = report_runs(robot, 60.0, own=False)
    assert [r.stem for r in runs[:4]] == ["tracking", "tracking_passive5",
                                          "tracking_isotropic", "tracking_one_rate"]
    assert [r.animate for r in runs] == [True, True] + [False] * (len(runs) - 2)
    assert runs[1].params == robot.replace(passive=(5,)) and runs[2].t_final == 30.0
    assert runs[2].params.c_y == runs[2].params.c_x
    assert all(r.sweep is None for r in runs[:4])
    sweep = runs[4:]
    assert all(r.stem is None and r.t_final == 60.0 for r in sweep)
    rates = [r for r in sweep if r.sweep is not None and r.sweep[0] == "lam"]
    frictions = [r for r in sweep if r.sweep is not None and r.sweep[0] == "c_y"]
    assert len(rates) + len(frictions) == len(sweep)
    assert [(r.params, dict(r.options)) for r in rates] == [
        (robot, {"lam": lam, "lam_shape": lam / 2}) for lam in DECAY_RATES if lam != 10.0]
    assert [(r.params, dict(r.options)) for r in frictions] == [
        (robot.replace(c_y=25.0 * f), {}) for f in C_Y_FACTORS if f != 1.0]
    assert frictions[0].label == "c_y = 2.5 N s/m (c_y / c_x = 5)"
    mine = SnakeParams.table1(c_x=0.5, c_y=[20.0] * 10, name="mine")
    own = [r for r in report_runs(mine, 11.0, own=True) if r.sweep and r.sweep[0] == "c_y"]
    assert [r.params.per_link("c_y")[0] for r in own] == [20.0 * f for f in C_Y_FACTORS
                                                           if f != 1.0]
    assert own[0].params.per_link("c_x").tolist() == [0.5] * 10
    assert own[0].label == "c_y x 0.1 on every link"


def test_the_sweeps_default_is_the_laws_default() -> None:
    """The first run (no options) is both sweeps' default point: the law's own lambda is in
    DECAY_RATES with mu = lambda / 2, and 1 is in C_Y_FACTORS."""
    from snake_pin import Snake
    from snake_pin.control import LyapunovController

    law = LyapunovController(Snake(tracking_params()))
    assert law.lam in DECAY_RATES and law.lam_shape == law.lam / 2
    assert 1.0 in C_Y_FACTORS
    assert list(DECAY_RATES) == sorted(DECAY_RATES)
    assert list(C_Y_FACTORS) == sorted(C_Y_FACTORS)


def test_sweep_findings_name_the_best_point_and_those_off_target() -> None:
    """sweep_findings: the smallest error, both ends (skipping a point without an error
    window), the points above the target and those without an error; the text quotes
    them and does not repeat an end that is the best point."""
    curves = {"lam": [(1.0, 12.0, 0.1), (3.0, 4.0, 0.2), (10.0, 6.0, 0.3), (30.0, None, 0.0)],
              "c_y": [(5.0, None, 0.0)]}
    found = sweep_findings(curves)
    lam = found["lam"]
    assert lam is not None and found["c_y"] is None
    assert lam["best"] == [3.0, 4.0, 0.2]
    assert lam["first"] == [1.0, 12.0, 0.1] and lam["last"] == [10.0, 6.0, 0.3]
    assert lam["above"] == [1.0, 10.0] and lam["no_window"] == [30.0]
    text = sweep_text(found, c_y_name="c_y / c_x")
    assert "smallest at 3/s (4 % of the body, R min 0.2)" in text
    assert "against 12 % at 1/s (R min 0.1) and 6 % at 10/s (R min 0.3)" in text
    assert "above the 5 % target at 1, 10/s." in text
    assert "No error window (the run ended first) at 30/s." in text
    assert "No run of the c_y / c_x sweep has an error window." in text
    ends = sweep_text(sweep_findings({"lam": [(1.0, 2.0, 0.1), (3.0, 4.0, 0.2)]}), "x")
    assert ends.count("2 %") == 1 and "every point is within the 5 % target" in ends


def test_plot_sweep_draws_a_sweep_without_any_error(tmp_path: Path) -> None:
    """A sweep whose runs all ended before their error window is drawn as a note, not a
    crash (log scales refuse empty data)."""
    path = plot_sweep({"lam": [(1.0, None, 0.0), (10.0, None, 0.0)],
                       "c_y": [(5.0, 3.0, 0.1), (50.0, 4.0, 0.1)]}, tmp_path / "s.png",
                      c_y_axis="c_y / c_x", default={"lam": 10.0, "c_y": 50.0})
    assert path.stat().st_size > 1000


def test_the_friction_sweep_keeps_c_y_above_c_x_and_names_the_ratio() -> None:
    """A factor that would bring c_y down to c_x or below on any link is skipped (Section V);
    the ratio labels follow the friction, not the links' geometry."""
    low = tracking_params(c_x=0.5, c_y=1.0)  # c_y / c_x = 2: factors below 0.5 are skipped
    factors = [r.sweep[1] for r in report_runs(low, 1.0, own=True) if r.sweep and
               r.sweep[0] == "c_y"]
    assert factors == [f for f in C_Y_FACTORS if f > 0.5 and f != 1.0]
    long_tail = SnakeParams.table1(link_length=[0.14] * 9 + [0.2], c_x=0.5, c_y=25.0)
    assert sweep_ratio(long_tail) == 50.0
    labels = [r.label for r in report_runs(long_tail, 1.0, own=False) if r.sweep and
              r.sweep[0] == "c_y"]
    assert labels[0] == "c_y = 2.5 N s/m (c_y / c_x = 5)"
    assert sweep_ratio(SnakeParams.table1(c_x=0.5, c_y=[20.0] * 9 + [30.0])) is None


def test_the_default_route_follows_the_studys_lockstep_rule(batches: list[int]) -> None:
    """By default a worker's share goes lockstep from MIN_LOCKSTEP runs of one layout on
    (the study's rule), below it one by one; another layout counts apart."""
    from snake_pin.study.work import MIN_LOCKSTEP

    job = (tracking_params(), 0.05, {})
    other = (tracking_params(n=6), 0.05, {})
    dict(iter_tracking_runs([job] * (MIN_LOCKSTEP - 1) + [other], workers=1))
    assert batches == []
    seen = dict(iter_tracking_runs([job] * MIN_LOCKSTEP + [other], workers=1))
    assert batches == [MIN_LOCKSTEP] and seen[MIN_LOCKSTEP].params.n == 6
