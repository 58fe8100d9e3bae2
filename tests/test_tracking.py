"""Tests of snake_pin.experiments.tracking (the stage's runs on Dask, its sweeps and findings)
and of snake_pin.runs.tracking (one tracking run)."""

from __future__ import annotations

from pathlib import Path

import pytest

from snake_pin import SnakeParams
from snake_pin.experiments.tracking import (
    C_Y_FACTORS,
    DECAY_RATES,
    plot_sweep,
    report_runs,
    sweep_findings,
    sweep_ratio,
    sweep_text,
)
from snake_pin.runs.parallel import run_jobs
from snake_pin.runs.tracking import run_tracking, tracking_params


def test_two_workers_give_each_job_its_own_run() -> None:
    """On a 2-worker Dask cluster the run handed back for job i is job i's (its c_y,
    duration and decay rate), and equals the same run made in this process."""
    jobs = [(tracking_params(c_y=c_y), t_final, {"lam": lam})
            for c_y, t_final, lam in ((10.0, 0.3, 3.0), (20.0, 0.5, 5.0), (30.0, 0.2, 7.0))]
    runs = run_jobs([(run_tracking, (params,), {"t_final": t_final, **options})
                     for params, t_final, options in jobs], workers=2)
    for (params, t_final, options), traj in zip(jobs, runs, strict=True):
        assert traj.params.c_y == params.c_y and traj.summary["c_y"] == params.c_y
        assert traj.t_end == pytest.approx(t_final, abs=1e-12)
        assert traj.meta["lam"] == options["lam"]
    here = run_tracking(jobs[0][0], t_final=jobs[0][1], **jobs[0][2])
    assert here.summary_dict() == runs[0].summary_dict()
    assert (here.q == runs[0].q).all()


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
