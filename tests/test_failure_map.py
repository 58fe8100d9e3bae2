"""Tests of snake_pin.experiments.failure_map (the report stage)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from snake_pin import SnakeParams
from snake_pin.exceptions import RunInterrupted
from snake_pin.experiments.failure_map import (
    FULL,
    MPC_FULL,
    failure_map_stage,
    failure_map_study,
    findings,
    map_tables,
    mpc_findings,
)
from snake_pin.experiments.reproduce import Context
from snake_pin.report import Report
from snake_pin.robot_file import load_robot
from snake_pin.study import load_study

REPO = Path(__file__).resolve().parent.parent


def test_the_full_plan_on_table1_is_the_shipped_study(tmp_path: Path) -> None:
    """The stage's full study on Table 1 expands to the runs of studies/failure_map.toml."""
    path = failure_map_study(SnakeParams.table1(), FULL, tmp_path)
    shipped = load_study(REPO / "studies" / "failure_map.toml")
    assert load_study(path).study_hash == shipped.study_hash
    assert len(shipped.scenarios) == 40


def test_the_full_mpc_line_on_table1_is_the_shipped_study(tmp_path: Path) -> None:
    """The stage's full MPC study on Table 1 is studies/failure_map_mpc.toml: the MPC,
    60 s, failed joint 0..9 at c_y = 50 c_x, the Lyapunov-like map's line and reference."""
    path = failure_map_study(SnakeParams.table1(), MPC_FULL, tmp_path, controller="mpc")
    assert path.name == "failure_map_mpc.toml"
    shipped = load_study(REPO / "studies" / "failure_map_mpc.toml")
    assert load_study(path).study_hash == shipped.study_hash
    assert [s["failed_joint"] for s in shipped.scenarios] == list(range(10))
    lyapunov = load_study(REPO / "studies" / "failure_map.toml").scenarios
    for scenario in shipped.scenarios:
        assert scenario.controller == "mpc" and scenario["t_final"] == 60.0
        assert scenario.params.c_y == 50 * scenario.params.c_x == 25.0
        line = next(s for s in lyapunov if s["c_y"] == 25.0
                    and s["failed_joint"] == scenario["failed_joint"])
        assert line.params == scenario.params
        for name in ("ref_speed", "init_phi", "gait_alpha", "gait_ts", "gait_v", "dt",
                     "control_dt", "error_window"):
            assert scenario[name] == line[name], name


def test_a_robot_of_ones_own_is_written_beside_the_study(tmp_path: Path) -> None:
    """A 6-link robot with a passive joint: its file (passive cleared), failed joints 0..5."""
    robot = SnakeParams.table1(n=6, mass=0.3, name="my_robot").replace(passive=(2,))
    spec = load_study(failure_map_study(robot, FULL, tmp_path))
    assert load_robot(str(tmp_path / "failure_map_robot.toml")).passive == ()
    assert sorted({s["failed_joint"] for s in spec.scenarios}) == [0, 1, 2, 3, 4, 5]
    assert {s.params.mass for s in spec.scenarios} == {0.3}
    assert {s.params.c_y / s.params.c_x for s in spec.scenarios} == {10.0, 25.0, 50.0, 100.0}


def test_the_robots_own_c_x_sets_the_friction_of_the_ratios(tmp_path: Path) -> None:
    """Table 1 with c_x = 1: c_y = 10..100 N s/m; per-link c_x falls back to C_X = 0.5."""
    spec = load_study(failure_map_study(SnakeParams.table1(c_x=1.0), FULL, tmp_path))
    assert {s.params.c_x for s in spec.scenarios} == {1.0}
    assert sorted({s.params.c_y for s in spec.scenarios}) == [10.0, 25.0, 50.0, 100.0]
    per_link = SnakeParams.table1(n=4, c_x=[0.5, 0.6, 0.5, 0.5], name="lumpy")
    (tmp_path / "lumpy").mkdir()
    spec = load_study(failure_map_study(per_link, FULL, tmp_path / "lumpy"))
    assert {s.params.c_x for s in spec.scenarios} == {0.5}


def _tables(rms: dict[int, list[float]], rt: dict[int, list[float]],
            ratios: tuple[float, ...]) -> dict[str, Any]:
    rows = [{"failed_joint": j, "c_x": 0.5, "c_y": 0.5 * r, "status": "ok",
             "rms_head_error_pct": rms[j][i], "R_tilde_min": rt[j][i]}
            for j in rms for i, r in enumerate(ratios)]
    return map_tables(rows, sorted(rms), ratios)


def test_findings_name_the_lost_ratio_the_broken_and_the_zero_R_joints() -> None:
    """Synthetic map: ratio 10 lost, joint 2 breaks (worst), joint 1's R~ is rounding."""
    ratios = (10.0, 50.0, 100.0)
    rms = {0: [150.0, 3.0, 3.5], 1: [100.0, 3.6, 4.5], 2: [120.0, 14.0, 19.0],
           5: [170.0, 6.0, 11.0]}
    rt = {0: [1e-3, 9e-3, 1e-2], 1: [1e-18, 2e-18, 1e-18], 2: [1e-5, 7e-6, 4e-6],
          5: [3e-4, 8e-5, 1e-4]}
    text, numbers = findings(_tables(rms, rt, ratios), sorted(rms), ratios)
    assert numbers["tracking_ratios"] == [50.0, 100.0]
    assert numbers["broken_joints"] == [2, 5] and numbers["worst_joint"] == 2
    assert numbers["tracking_joints"] == [1]
    assert numbers["R_tilde_zero_joints"] == [1] and numbers["lowest_R_tilde_joint"] == 2
    assert "c_y/c_x = 10 no run tracks" in text[0]
    assert "joint 2 and 5 failed" in text[1] and "the worst is joint 2" in text[1]


def test_mpc_findings_compare_the_laws_joint_by_joint() -> None:
    """Synthetic line: the MPC tracks with joint 5, not with 1 and 2 (worst 2), joint 3's
    run diverged; it is lower than the Lyapunov-like law with none and 1, higher with 5;
    joint 2 has no Lyapunov-like value and is left out of the comparison."""
    def rows(rms: dict[int, float | None], status: dict[int, str]) -> list[dict[str, Any]]:
        return [{"failed_joint": j, "c_x": 0.5, "c_y": 25.0, "status": status.get(j, "ok"),
                 "rms_head_error_pct": v, "R_tilde_min": 1e-3} for j, v in rms.items()]

    joints = [0, 1, 2, 3, 5]
    mpc = map_tables(rows({0: 2.0, 1: 30.0, 2: 80.0, 3: 500.0, 5: 6.0}, {3: "diverged"}),
                     joints, (50.0,))
    lyapunov = map_tables(rows({0: 3.2, 1: 40.0, 3: 7.0, 5: 5.9}, {}), [0, 1, 3, 5],
                          (50.0,))
    text, numbers = mpc_findings(mpc, lyapunov, joints, 50.0)
    assert numbers["tracking_joints"] == [5] and numbers["broken_joints"] == [1, 2]
    assert numbers["worst_joint"] == 2 and numbers["not_ok"] == {"3": "diverged"}
    assert numbers["lower_than_lyapunov"] == [0, 1]
    assert numbers["higher_than_lyapunov"] == [5]
    assert (numbers["none_rms_pct"], numbers["lyapunov_none_rms_pct"]) == (2.0, 3.2)
    assert "RMS 2.0 % (the Lyapunov-like law: 3.2 %)" in text
    assert "joint 1 and 2 failed it does not (30.0, 80.0 %); the worst is joint 2" in text
    assert "joint 3: diverged" in text and "lower in 2 (no failure, joint 1)" in text


def test_map_tables_key_every_cell_and_keep_failed_runs_as_their_status() -> None:
    """Every (joint, ratio) cell exists; a diverged run has no value but its status."""
    rows = [{"failed_joint": 0, "c_x": 0.5, "c_y": 25.0, "status": "ok",
             "rms_head_error_pct": 3.0, "R_tilde_min": 1e-2},
            {"failed_joint": 3, "c_x": 0.5, "c_y": 25.0, "status": "diverged",
             "rms_head_error_pct": 80.0, "R_tilde_min": 1e-4}]
    tables = map_tables(rows, [0, 3], (50.0, 100.0))
    assert tables["rms_head_error_pct"] == {"0": {"50": 3.0, "100": None},
                                            "3": {"50": None, "100": None}}
    assert tables["status"]["3"] == {"50": "diverged", "100": "missing"}


@pytest.mark.usefixtures("tiny_report")
def test_the_stage_runs_the_study_and_reports_its_numbers(tmp_path: Path) -> None:
    """A tiny quick map: study folder, heatmaps, series, tables equal to the Parquet rows,
    joint 1's R~ found zero, the MPC's line beside the law's from its own rows, numbers
    JSON-safe."""
    report = Report("test")
    ctx = Context(folder=tmp_path, params=SnakeParams.table1(), report=report, quick=True,
                  options={"study_workers": 1})
    failure_map_stage(ctx)
    sec = report.sections[-1]
    assert sec.key == "failure_map"
    for name in ("failure_map.toml", "failure_map/index.html", "failure_map_series.png",
                 "failure_map_rms_head_error_pct.png", "failure_map_R_tilde_min.png"):
        assert (tmp_path / name).is_file(), name
    assert {p.name for p, _ in sec.figures} >= {"failure_map_rms_head_error_pct.png",
                                                 "failure_map_R_tilde_min.png",
                                                 "failure_map_series.png"}
    frame = pd.read_parquet(tmp_path / "failure_map" / "runs")
    assert len(frame) == 6 and set(frame["status"]) == {"ok"}
    for _, row in frame.iterrows():
        cell = sec.numbers["rms_head_error_pct"][str(row["failed_joint"])][
            f"{row['c_y'] / row['c_x']:g}"]
        assert cell == row["rms_head_error_pct"]
    assert sec.numbers["findings"]["R_tilde_zero_joints"] == [1]
    assert sec.numbers["series_ratio"] == 50.0
    assert set(sec.numbers["series"]) == {"no failure", "joint 5 failed (worst here)",
                                          "joint 1 failed"} or \
        set(sec.numbers["series"]) == {"no failure", "joint 1 failed (worst here)"}
    assert sec.numbers["study"]["status"] == "complete"
    mpc = sec.numbers["mpc"]
    assert mpc["study"]["status"] == "complete" and mpc["plan"]["failed_joints"] == [0, 5]
    frame = pd.read_parquet(tmp_path / "failure_map_mpc" / "runs")
    assert len(frame) == 2 and set(frame["controller"]) == {"mpc"}
    for _, row in frame.iterrows():
        assert row["status"] == "ok" and row["t_end"] == 0.4
        assert mpc["rms_head_error_pct"][str(row["failed_joint"])]["50"] == \
            row["rms_head_error_pct"]
    assert mpc["findings"]["none_rms_pct"] == mpc["rms_head_error_pct"]["0"]["50"]
    assert mpc["findings"]["lyapunov_none_rms_pct"] == \
        sec.numbers["rms_head_error_pct"]["0"]["50"]
    assert (tmp_path / "failure_map_mpc.png").is_file()
    assert (tmp_path / "failure_map_mpc.toml").is_file()
    json.dumps(report.summary(), allow_nan=False)
    assert any("failed joint" in " ".join(map(str, h)) for h, _ in sec.tables)
    text = " ".join([sec.title, *sec.paragraphs])
    assert "(1 worker)" in text and "1 workers" not in text and "issue" not in text


@pytest.mark.usefixtures("tiny_report")
def test_an_interrupted_study_propagates(tmp_path: Path,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """RunInterrupted from the study leaves the stage unchanged (nothing swallowed)."""
    import snake_pin.study

    def interrupted(*_args: Any, **_kwargs: Any) -> Any:
        raise RunInterrupted("study failure_map interrupted", partial=None)

    monkeypatch.setattr(snake_pin.study, "run_study", interrupted)
    report = Report("test")
    ctx = Context(folder=tmp_path, params=SnakeParams.table1(), report=report, quick=True)
    with pytest.raises(RunInterrupted):
        failure_map_stage(ctx)


@pytest.mark.usefixtures("tiny_report")
def test_the_study_shows_its_bar_on_a_terminal_only(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """The stage leaves the study's progress bar to the terminal test (progress=None: drawn
    on a TTY, not in a log), and passes the worker options on."""
    import snake_pin.study

    seen: dict[str, Any] = {}

    def interrupted(*_args: Any, **kwargs: Any) -> Any:
        seen.update(kwargs)
        raise RunInterrupted("study failure_map interrupted", partial=None)

    monkeypatch.setattr(snake_pin.study, "run_study", interrupted)
    ctx = Context(folder=tmp_path, params=SnakeParams.table1(), report=Report("test"),
                  quick=True, options={"study_workers": 1, "study_scheduler": None})
    with pytest.raises(RunInterrupted):
        failure_map_stage(ctx)
    assert "progress" in seen and seen["progress"] is None
    assert seen["workers"] == 1 and seen["scheduler"] is None
