"""Tests of snake_pin.runs.benchmark: metrics, the benchmark, user controllers."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from snake_pin.control import Controller, LyapunovController, head_first_reference
from snake_pin.exceptions import ParameterError
from snake_pin.model import Snake
from snake_pin.paths import Circle, Line, PathReference, Timing
from snake_pin.runs import benchmark as bc
from snake_pin.runs.tracking import initial_state, tracking_params
from snake_pin.sim import simulate


@pytest.fixture(scope="module")
def snake() -> Snake:
    """The benchmark's viscous robot."""
    return Snake(tracking_params())


def _posture(snake: Snake, head: np.ndarray) -> np.ndarray:
    q = np.tile(initial_state(snake.params)[:snake.nq], (len(head), 1))
    q[:, :2] = head
    return q


def test_circle_offset_gives_cross_track_d(snake: Snake) -> None:
    """A head on a circle of radius r + d about the path's centre has cross-track d."""
    ref = PathReference(Circle(radius=1.2), Timing(0.1))
    t = np.linspace(0.0, 60.0, 601)
    w = ref.at(t)[0]
    centre = np.asarray(ref.path.centre)
    d = 0.05
    head = centre + (w[:, :2] - centre) * (1.2 + d) / 1.2
    m = bc.path_metrics(t, _posture(snake, head), np.zeros((len(t), 9)), snake, ref,
                        criteria_dt=None)
    assert m["head_ct_rms"] == pytest.approx(d, abs=1e-9)
    assert m["head_ct_max"] == pytest.approx(d, abs=1e-9)
    assert m["head_ct_rms_pct"] == pytest.approx(100 * d / 1.2, rel=1e-6)
    assert m["head_lag_rms"] == pytest.approx(0.0, abs=1e-9)  # radial offset, no lag
    assert m["head_error_rms"] == pytest.approx(d, abs=1e-9)


def test_lagging_head_gives_the_lag(snake: Snake) -> None:
    """A head a fixed arc length behind the reference has that lag and no cross-track."""
    for path in (Line(), Circle(radius=0.6)):
        ref = PathReference(path, Timing(0.1))
        t = np.linspace(0.0, 60.0, 601)
        lag = 0.3
        head = path.geometry(0.1 * t - lag).p
        m = bc.path_metrics(t, _posture(snake, head), np.ones((len(t), 9)), snake, ref,
                            criteria_dt=None)
        assert m["head_lag_rms"] == pytest.approx(lag, abs=1e-7)
        assert m["head_ct_rms"] == pytest.approx(0.0, abs=1e-7)
        assert m["torque_rms"] == pytest.approx(1.0)
        # the time-indexed error is the chord of the lag
        chord = lag if isinstance(path, Line) else 2 * 0.6 * math.sin(lag / (2 * 0.6))
        assert m["head_error_rms"] == pytest.approx(chord, abs=1e-7)


def test_window_and_head_tracking_flag(snake: Snake) -> None:
    """Only t >= 10 s counts; a non-head-tracking run has no time-indexed error."""
    ref = PathReference(Line(), Timing(0.1))
    t = np.linspace(0.0, 20.0, 201)
    head = ref.at(t)[0][:, :2] + np.where(t < 10.0, 1.0, 0.02)[:, None] * [0.0, 1.0]
    m = bc.path_metrics(t, _posture(snake, head), np.zeros((len(t), 9)), snake, ref,
                        head_tracking=False, criteria_dt=None)
    assert m["head_ct_max"] == pytest.approx(0.02)
    assert math.isnan(m["head_error_rms"])


def test_criteria_sampled_and_arc_singular_for_wheels(snake: Snake) -> None:
    """Criteria every 0.1 s: at the initial arc R > 0 while the lateral criterion vanishes."""
    ref = PathReference(Line(), Timing(0.1))
    t = np.linspace(0.0, 1.0, 101)
    q = np.tile(initial_state(snake.params)[:snake.nq], (len(t), 1))
    m = bc.path_metrics(t, q, np.zeros((len(t), 9)), snake, ref, start=0.0)
    assert len(m["series"]["t"]) == 11
    assert m["R_min"] > 1e-4
    assert m["lateral_min"] < 1e-8 * m["R_min"]
    assert m["R_tilde_min"] <= m["R_min"]


class Damped(Controller):
    """A user's controller: joint damping only (not a head-tracking law)."""

    name = "damped"

    def __init__(self, snake: Snake) -> None:
        self.nq = snake.nq

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        return -0.1 * x[self.nq + 3:]


def test_quick_benchmark_with_a_user_controller(tmp_path) -> None:
    """2 scenarios x 2 controllers + a user factory: rows, finite metrics, table, files."""
    result = bc.run_benchmark(
        scenarios=["line", "circle_1L"],
        controllers={"lyapunov": None, "pfl": None,
                     "mine": lambda snake, reference, path: Damped(snake)},
        failed=(None, 5), t_final=11.0, workers=1, error_window=10.0)
    assert len(result.rows) == 2 * 3 * 2 and result.settings["window_start"] == 10.0
    for row in result.rows:
        assert set(bc.METRIC_FIELDS) <= set(row)
    lyap = result.cell("circle_1L", "lyapunov")
    for key in ("head_ct_rms", "head_ct_max", "head_lag_rms", "head_error_rms", "cm_ct_rms",
                "R_min", "R_tilde_min", "lateral_min", "torque_rms"):
        assert np.isfinite(lyap[key]), key
    assert lyap["status"] == "completed"
    assert result.cell("line", "pfl", failed=5)["status"] == "not applicable"
    mine = result.cell("line", "mine")
    assert mine["status"] == "completed" and math.isnan(mine["head_error_rms"])
    # a damped snake stays near its start while the reference is 1.0-1.1 m ahead
    assert mine["head_lag_rms"] > 0.9 > 10 * result.cell("line", "lyapunov")["head_lag_rms"]
    files = bc.write_benchmark(result, tmp_path)
    with open(files["csv"]) as handle:
        rows = list(csv.DictReader(handle))
    assert {r["controller"] for r in rows} == {"lyapunov", "pfl", "mine"}
    doc = json.loads(files["json"].read_text())
    assert len(doc["rows"]) == 12 and "circle_1L/lyapunov/viscous/0" in doc["criteria"]
    assert {"table_viscous_0", "table_viscous_5", "claim_circle_1L"} <= set(files)


def test_bad_names_refused() -> None:
    """An unknown scenario, controller or model is one ParameterError."""
    with pytest.raises(ParameterError, match="scenario"):
        bc.run_benchmark(scenarios=["spiral"], t_final=1.0)
    with pytest.raises(ParameterError, match="controller"):
        bc.run_benchmark(controllers=["magic"], t_final=1.0)
    with pytest.raises(ParameterError, match="model"):
        bc.run_benchmark(models=["real"], t_final=1.0)


def test_lyapunov_follows_the_circle(snake: Snake) -> None:
    """Radius 1 body length, 20 s: head cross-track RMS < 4 % of L; a line would fail."""
    row = bc.run_cell("circle_1L", "lyapunov", t_final=20.0, criteria_dt=None)
    # measured 1.8 % (0.022 m); 4 % (0.048 m) is generous and under the 5 %
    assert row["status"] == "completed"
    assert row["head_ct_rms_pct"] < 4.0
    # the same law on the straight reference, judged against the circle, is far off
    straight = simulate(snake, LyapunovController(snake, head_first_reference()),
                        initial_state(snake.params), 20.0)
    m = bc.path_metrics(straight.t[::10], straight.q[::10], straight.tau[::10], snake,
                        bc.make_scenario("circle_1L", 1.2), criteria_dt=None)
    assert m["head_ct_rms_pct"] > 4.0


def _engine_direct(controller: str, failed: int | None, offset: np.ndarray | None,
                   t_final: float, start: float) -> dict:
    """run_engine on the scenario's path, by hand, and its path metrics."""
    from snake_pin.engine.run import run_engine
    from snake_pin.params import SnakeParams

    params = SnakeParams.engine()
    if failed:
        params = params.replace(passive=(failed,))
    reference = bc.make_scenario("circle_1L", params.body_length)
    law = {"lyapunov": "acceleration", "velocity": "velocity"}[controller]
    traj = run_engine(params, t_final=t_final, law=law, initial_offset=offset,
                      reference=reference).trajectory
    every = slice(None, None, 10)
    return bc.path_metrics(traj.t[every], traj.q[every], traj.tau[every], Snake(traj.params),
                           reference, start=start, criteria_dt=None)


@pytest.mark.parametrize("controller, failed, draws", [("lyapunov", 5, 1),
                                                       ("velocity", None, 3)])
def test_engine_cell_is_the_median_of_its_draws(controller: str, failed: int | None,
                                                draws: int, monkeypatch) -> None:
    """An engine cell equals run_engine on the scenario's path by hand (law, failed joint,
    perturbed starts), each metric the median over the draws."""
    from snake_pin.runs.engine import PERTURBATION, perturbations

    start, t_final = 0.2, 0.6  # a short window, so that short runs have metrics
    original = bc.path_metrics
    monkeypatch.setattr(bc, "path_metrics",
                        lambda *a, **k: original(*a, **{**k, "start": start}))
    row = bc.run_cell("circle_1L", controller, "engine", failed, t_final=t_final,
                      draws=draws, criteria_dt=None)
    assert row["status"] == "completed" and row["draws"] == draws
    offsets = perturbations(draws, 7, PERTURBATION, seed=0) if draws > 1 else [None]
    direct = [_engine_direct(controller, failed, o, t_final, start) for o in offsets]
    for key in ("head_ct_rms", "head_ct_max", "head_error_rms", "cm_ct_rms", "torque_rms"):
        assert row[key] == pytest.approx(np.median([m[key] for m in direct]), rel=1e-12)
    spread = [m["head_ct_rms_pct"] for m in direct]
    if draws > 1:
        assert [row["head_ct_rms_pct_p10"], row["head_ct_rms_pct_p90"]] == pytest.approx(
            np.percentile(spread, [10, 90]), rel=1e-12)
    assert row["body_length"] == pytest.approx(1.408)


def test_engine_cell_reports_the_draw_that_stopped(monkeypatch) -> None:
    """One of three engine draws stopping at 0.1 s: the cell is "diverged" at 0.1 s (that
    draw's time, not the median draw's), its reason counts it, t_end is the median."""
    import snake_pin.engine.run as engine_run

    original, calls = engine_run.run_engine, []

    def third_stops(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            run = original(*args, **{**kwargs, "t_final": 0.1})
            run.trajectory.status = "diverged"
            run.trajectory.reason = "diverged at t = 0.1000 s: test"
            return run
        return original(*args, **kwargs)

    monkeypatch.setattr(engine_run, "run_engine", third_stops)
    row = bc.run_cell("line", "velocity", "engine", t_final=0.3, draws=3, criteria_dt=None)
    assert len(calls) == 3 and row["draws"] == 3
    assert row["status"] == "diverged" and row["reason"].startswith("1 of 3 draws: diverged")
    assert row["diverged_at"] == pytest.approx(0.1) and row["t_end"] == pytest.approx(0.3)


def test_cells_refuse_bad_draws() -> None:
    """run_cell refuses draws that are not a positive integer, as run_benchmark does."""
    for bad in (0, -3, 1.5, True):
        with pytest.raises(ParameterError, match="draws"):
            bc.run_cell("line", "velocity", "engine", t_final=0.1, draws=bad)


def test_engine_cells_of_other_laws_are_not_applicable() -> None:
    """PFL, LOS and user factories on the engine: a "not applicable" row, no run."""
    for controller, factory in (("pfl", None), ("los", None),
                                ("mine", lambda snake, ref, path: LyapunovController(snake,
                                                                                     ref))):
        row = bc.run_cell("line", controller, "engine", factory=factory)
        assert row["status"] == "not applicable" and "engine" in row["reason"]
        assert math.isnan(row["head_ct_rms"]) and row["snapshots"] == []


def test_short_runs_have_a_metrics_window() -> None:
    """A 1 s benchmark is judged over its second half by default (not NaN for want of a
    10 s window); error_window moves the window, and one outside [0, t_final) is refused."""
    def bench(**options: float) -> bc.BenchmarkResult:
        return bc.run_benchmark(scenarios=["line"], controllers=["lyapunov"], failed=(None,),
                                t_final=1.0, workers=1, **options)

    default, later = bench(), bench(error_window=0.8)
    assert default.settings["window_start"] == 0.5 and later.settings["window_start"] == 0.8
    rows = [result.cell("line", "lyapunov") for result in (default, later)]
    assert all(math.isfinite(row["head_ct_rms"]) for row in rows)
    assert rows[0]["head_ct_rms"] != rows[1]["head_ct_rms"]
    for bad in (1.0, -0.1, math.nan):
        with pytest.raises(ParameterError, match="error_window"):
            bench(error_window=bad)


def test_default_controllers_include_mpc() -> None:
    """Every built-in controller, mpc included, is a default one and reaches the grid of a
    benchmark that names none (an empty failure list: no cell runs)."""
    assert "mpc" in bc.DEFAULT_CONTROLLERS
    assert set(bc.DEFAULT_CONTROLLERS) == set(bc.CONTROLLERS)
    empty = bc.run_benchmark(failed=(), t_final=1.0, workers=1)
    assert empty.rows == [] and empty.settings["controllers"] == list(bc.DEFAULT_CONTROLLERS)


def test_mpc_keeps_its_torque_bound() -> None:
    """A short viscous mpc cell with joint 5 failed has torque_max within MPCOptions' bound,
    and its head error in % of L is its time-indexed error over the body length."""
    from snake_pin.control import MPCOptions

    result = bc.run_benchmark(scenarios=["line"], controllers=["mpc"], failed=(5,),
                              t_final=0.3, workers=1)
    row = result.cell("line", "mpc", failed=5)
    assert row["status"] == "completed" and "torque_max" in bc.METRIC_FIELDS
    assert 0.0 < row["torque_max"] <= MPCOptions().torque_bound + 1e-9
    assert row["head_error_rms_pct"] == pytest.approx(
        100.0 * row["head_error_rms"] / row["body_length"], rel=1e-12)
    assert np.isfinite(row["head_error_rms"])


def _target_row(scenario: str, controller: str, failed: int, error: float,
                status: str = "completed") -> dict:
    return {"scenario": scenario, "controller": controller, "model": "viscous",
            "failed_joint": failed, "status": status, "head_error_rms_pct": error,
            "torque_max": 0.9}


def test_mpc_targets_pair_each_mpc_row_with_its_lyapunov_cell() -> None:
    """The targets pair an mpc row with the lyapunov row of the same scenario and failed
    joint; met needs <= 2.5 % and below the Lyapunov-like error; a missing or diverged
    partner, or an MPC above the limit, is not met."""
    from snake_pin.experiments.bench_control import mpc_targets

    rows = [_target_row("line", "lyapunov", 0, 3.0), _target_row("line", "mpc", 0, 0.4),
            _target_row("line", "lyapunov", 5, 0.3), _target_row("line", "mpc", 5, 0.4),
            _target_row("circle_1L", "mpc", 0, 0.5),
            _target_row("lane_change", "lyapunov", 0, 9.0, "diverged"),
            _target_row("lane_change", "mpc", 0, 0.5),
            _target_row("circle_2L", "lyapunov", 0, 9.0), _target_row("circle_2L", "mpc", 0, 3.0)]
    got = {(t["scenario"], t["failed_joint"]): t for t in mpc_targets(rows)}
    assert list(got) == [("line", 0), ("line", 5), ("circle_1L", 0), ("lane_change", 0),
                         ("circle_2L", 0)]
    assert (got["line", 0]["mpc"], got["line", 0]["lyapunov"]) == (0.4, 3.0)
    assert [got[k]["met"] for k in got] == [True, False, False, False, False]
    assert math.isnan(got["circle_1L", 0]["lyapunov"])
    assert math.isnan(got["lane_change", 0]["lyapunov"])


def test_report_stage_mpc_rows_and_targets(tmp_path, monkeypatch) -> None:
    """The report's stage (quick, every run cut to 0.4 s) has an mpc row within the torque
    bound; its targets table equals the rows' head errors in % of L; the page's tables
    show the head error and torque_max of every controller."""
    import matplotlib.pyplot as plt

    from snake_pin import SnakeParams
    from snake_pin.control import MPCOptions
    from snake_pin.experiments import bench_control as stage
    from snake_pin.experiments.context import Context
    from snake_pin.report import Report
    from snake_pin.viz import plots

    original = stage.run_benchmark
    monkeypatch.setattr(stage, "run_benchmark",
                        lambda *a, **k: original(*a, **{**k, "t_final": 0.4, "workers": 1}))
    # the figures are drawn but not rendered to PNG (other tests render them)
    monkeypatch.setattr(plots, "png_bytes", lambda fig, dpi=110: plt.close(fig) or b"")
    report = Report("test")
    stage.bench_control_stage(Context(folder=tmp_path, params=SnakeParams.table1(),
                                      report=report, quick=True))
    (sec,) = report.sections
    rows = {r["controller"]: r for r in sec.numbers["mpc_rows"]}
    assert set(rows) == {"lyapunov", "mpc"} and rows["mpc"]["status"] == "completed"
    assert 0.0 < rows["mpc"]["torque_max"] <= MPCOptions().torque_bound + 1e-9
    (target,) = sec.numbers["mpc_targets"]
    for name in ("mpc", "lyapunov"):
        assert target[name] == pytest.approx(
            100.0 * rows[name]["head_error_rms"] / rows[name]["body_length"], rel=1e-12)
    assert target["torque_max"] == rows["mpc"]["torque_max"]
    assert target["met"] == (target["mpc"] <= stage.MPC_TARGET_PCT
                             and target["mpc"] < target["lyapunov"])
    header, table = next(t for t in sec.tables if "MPC head error [% L]" in t[0])
    assert table == [["line", "-", float(f"{target['mpc']:.3g}"),
                      float(f"{target['lyapunov']:.3g}"), float(f"{target['torque_max']:.3g}"),
                      "yes" if target["met"] else "no"]]
    # the grid's, the MPC's and the engine's tables: head error and torque max for every
    # controller
    grids = [t for t in sec.tables if "torque max [N m]" in t[0]]
    assert len(grids) == 3
    for header, table in grids:
        col = header.index("torque max [N m]")
        assert all(isinstance(r[col], float) and r[col] > 0.0 for r in table)
    col = grids[1][0].index("head error RMS [% L]")
    assert {r[1]: r[col] for r in grids[1][1]} == {
        c: float(f"{rows[c]['head_error_rms_pct']:.3g}") for c in rows}
    assert (tmp_path / "mpc" / "error_viscous_0.png").is_file()
    assert any("error_viscous_0" in str(path) for path, _ in sec.figures)


def test_torque_max_is_the_peak_of_the_applied_torques(snake: Snake) -> None:
    """Every controller's row has torque_max: the peak |tau_i| over the whole run."""
    row = bc.run_cell("line", "lyapunov", t_final=0.2, criteria_dt=None)
    assert np.isfinite(row["torque_max"]) and row["torque_max"] > 0.0
    assert row["torque_max"] >= row["torque_rms"]
