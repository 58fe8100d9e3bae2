"""Tests of snake_pin.study.runner and .work: Dask execution, resuming, failures, interrupts."""

from __future__ import annotations

import argparse
import functools
import json
import logging
import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import dask
import pandas as pd
import pytest

import snake_pin.study
from snake_pin import cli
from snake_pin.exceptions import RunInterrupted
from snake_pin.study import StudyError, StudySummary, load_study, run_study, work
from snake_pin.study.runner import check_scheduler, plan_batches
from snake_pin.study.spec import Scenario, parse_study
from snake_pin.study.work import result_row, run_batch, simulate_scenario

REPO = Path(__file__).resolve().parent.parent
METRICS = ("rms_head_error", "max_head_error", "rms_head_error_pct", "max_head_error_pct",
           "R_min", "R_tilde_min", "D_min", "t_end", "torque_rms")
STUDY = """
[study]
name = "small"
[base]
t_final = 0.4
error_window = 0.1
c_x = 0.5
[axes.c_y]
values = [10.0, 25.0]
[axes.failed_joint]
values = [0, 5, 9]
"""
linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")


@pytest.fixture(scope="module")
def scheduler() -> Iterator[str]:
    """One 2-worker local cluster (127.0.0.1) shared by the tests; a dead worker's task
    fails at once (allowed-failures 0) so the killed-worker test needs no retries."""
    from distributed import LocalCluster

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None,
                               scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                               silence_logs=logging.CRITICAL)
    try:
        yield cluster.scheduler_address
    finally:
        cluster.close()


def _study(tmp_path: Path, text: str = STUDY) -> Path:
    path = tmp_path / "study.toml"
    path.write_text(text)
    return path


# ------------------------------------------------- batch functions run by the workers
def _explode(index: int, batch: Sequence[Scenario]) -> list[dict[str, Any]]:
    """Raise for the batch holding run ``index``, run the others normally."""
    if any(s.index == index for s in batch):
        raise RuntimeError(f"boom at run {index}")
    return run_batch(batch)


def _counting(marks: str, batch: Sequence[Scenario]) -> list[dict[str, Any]]:
    """run_batch, leaving one file per run executed in ``marks``."""
    for s in batch:
        Path(marks, s.key).write_text("")
    return run_batch(batch)


def _die(index: int, batch: Sequence[Scenario]) -> list[dict[str, Any]]:
    """Kill this worker process when the batch holds run ``index``."""
    if any(s.index == index for s in batch):
        os._exit(1)
    return run_batch(batch)


def _slow_after_first(batch: Sequence[Scenario]) -> list[dict[str, Any]]:
    """Run 0 runs at once; every other batch waits (at most 60 s) before running."""
    if batch[0].index != 0:
        time.sleep(60)
    return run_batch(batch)


# ---------------------------------------------------------------------- tests
def _same(got: Any, expected: Any, rel: float = 1e-12) -> bool:
    if expected is None:
        return got is None or (isinstance(got, float) and math.isnan(got))
    return got == pytest.approx(expected, rel=rel, abs=1e-15)


def test_cluster_results_equal_the_single_runs(tmp_path: Path, scheduler: str) -> None:
    """A 2-worker cluster runs one run per task (one batch file each), and every row's
    metrics equal those of simulate_scenario of the same scenario here, to 1e-12."""
    study = _study(tmp_path)
    summary = run_study(study, tmp_path / "out", scheduler=scheduler)
    assert (summary.status, summary.ran, summary.recorded, summary.lost) == ("complete", 6, 6, 0)
    frame = pd.read_parquet(tmp_path / "out" / "runs")
    assert len(frame) == 6
    assert len(list((tmp_path / "out" / "runs").glob("batch-*.parquet"))) == 6
    for scenario in load_study(study).scenarios:
        expected = result_row(scenario, simulate_scenario(scenario))
        got = frame[frame["key"] == scenario.key].iloc[0]
        assert got["status"] == expected["status"] == "ok"
        assert got["c_y"] == scenario["c_y"] and got["failed_joint"] == scenario["failed_joint"]
        for metric in METRICS:
            assert _same(got[metric], expected[metric]), metric
    assert summary.statuses == {"ok": 6, "diverged": 0, "failed": 0}
    assert (tmp_path / "out" / "index.html").is_file()


def test_a_study_runs_on_a_client_it_leaves_open(tmp_path: Path, scheduler: str,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """Given a client (a cluster shared with other work), the study runs on its workers (no
    cluster of its own) with the rows of the same study run through the scheduler, and
    leaves the client usable; a client with workers of its own, or that is not a running
    client, is one StudyError line before any file is written."""
    from distributed import Client

    from snake_pin.study import runner

    study = _study(tmp_path)
    with Client(scheduler) as client, monkeypatch.context() as patch:
        patch.setattr(runner, "dask_client", None)  # calling it would fail the test
        summary = run_study(study, tmp_path / "shared", client=client)
        assert client.submit(sum, [1, 2]).result() == 3
        with pytest.raises(StudyError, match="client brings its own cluster"):
            run_study(study, tmp_path / "refused", client=client, workers=1)
    for bad in (scheduler, client):  # an address, a closed client
        with pytest.raises(StudyError, match=r"client must be a running distributed\.Client"):
            run_study(study, tmp_path / "refused", client=bad)
    assert not (tmp_path / "refused").exists()
    assert (summary.status, summary.recorded, summary.scheduler) == \
        ("complete", 6, scheduler)
    run_study(study, tmp_path / "own", scheduler=scheduler)
    shared, own = (pd.read_parquet(tmp_path / name / "runs").sort_values("key")
                   .reset_index(drop=True) for name in ("shared", "own"))
    pd.testing.assert_frame_equal(shared[["key", *METRICS]], own[["key", *METRICS]])


MPC_STUDY = """
[study]
name = "mpc"
[base]
controller = "mpc"
t_final = 0.5
error_window = 0.25
c_x = 0.5
c_y = 25.0
horizon = 0.3
torque_bound = 1.5
weight_torque = 0.3
[axes.failed_joint]
values = [0, 5]
"""


def test_an_mpc_study_run_is_the_direct_simulation(tmp_path: Path, scheduler: str) -> None:
    """The two runs of a 0.5 s MPC study, on the cluster, give the metrics of simulate with an
    MPCController built here by hand (the study's reference, gait, start and options) to
    1e-9."""
    import numpy as np

    from snake_pin import Snake
    from snake_pin.control import LinearReference, MPCController, MPCOptions
    from snake_pin.gaits import Serpenoid, arc
    from snake_pin.ocp import CostWeights
    from snake_pin.sim import simulate

    study = _study(tmp_path, MPC_STUDY)
    summary = run_study(study, tmp_path / "out", scheduler=scheduler)
    assert summary.statuses == {"ok": 2, "diverged": 0, "failed": 0}
    frame = pd.read_parquet(tmp_path / "out" / "runs")
    options = MPCOptions(horizon=0.3, torque_bound=1.5, weights=CostWeights(torque=0.3))
    reference = LinearReference(velocity=(0.1, 0.0, 0.0), start=(0.0, 0.0, math.pi))
    for scenario in load_study(study).scenarios:
        params = scenario.params
        assert params.passive == ((5,) if scenario["failed_joint"] else ())
        assert (params.c_x, params.c_y) == (0.5, 25.0)
        snake = Snake(params)
        law = MPCController(snake, reference, Serpenoid(10, math.pi / 6, 1.5, 2.0), options)
        x0 = np.r_[arc(10, math.pi / 6, theta_1=math.pi), np.zeros(12)]
        traj = simulate(snake, law, x0, 0.5)
        late = traj.t >= 0.25
        target = np.array([reference(t)[0][:2] for t in traj.t[late]])
        error = np.linalg.norm(traj.q[late, :2] - target, axis=1)
        got = frame[frame["key"] == scenario.key].iloc[0]
        assert got["horizon"] == 0.3 and got["feedback"]
        assert got["t_end"] == traj.t_end == 0.5
        assert got["rms_head_error"] == pytest.approx(np.sqrt(np.mean(error**2)), rel=1e-9)
        assert got["max_head_error"] == pytest.approx(error.max(), rel=1e-9)
        assert got["torque_rms"] == pytest.approx(np.sqrt(np.mean(traj.tau[:-1]**2)),
                                                  rel=1e-9)
        if scenario["failed_joint"]:
            assert not np.any(traj.tau[:, 4])


def test_a_rerun_executes_only_the_missing_runs(tmp_path: Path, scheduler: str) -> None:
    """Delete one batch file: the re-run executes exactly its runs, touches no other file."""
    study, out = _study(tmp_path), tmp_path / "out"
    marks = tmp_path / "marks"
    marks.mkdir()
    count = functools.partial(_counting, str(marks))
    run_study(study, out, scheduler=scheduler, batch_function=count)
    assert len(list(marks.iterdir())) == 6
    files = sorted((out / "runs").iterdir())
    assert len(files) == 6
    removed = files[1]
    lost = set(pd.read_parquet(removed)["key"])
    removed.unlink()
    kept = {f: f.stat().st_mtime_ns for f in files if f != removed}
    for mark in marks.iterdir():
        mark.unlink()
    summary = run_study(study, out, scheduler=scheduler, batch_function=count)
    assert {m.name for m in marks.iterdir()} == lost
    assert (summary.ran, summary.skipped, summary.recorded) == (len(lost), 6 - len(lost), 6)
    assert all(f.stat().st_mtime_ns == t for f, t in kept.items())
    assert set(pd.read_parquet(out / "runs")["key"]) == {s.key for s in
                                                         load_study(study).scenarios}
    again = run_study(study, out, scheduler=scheduler, batch_function=count)
    assert (again.ran, again.skipped, again.status) == (0, 6, "complete")


def test_a_task_that_raises_is_recorded_as_failed_and_the_rest_completes(
        tmp_path: Path, scheduler: str) -> None:
    """The run whose task raised becomes a failed row with the error; others are ok."""
    out = tmp_path / "out"
    summary = run_study(_study(tmp_path), out, scheduler=scheduler,
                        batch_function=functools.partial(_explode, 1))
    frame = pd.read_parquet(out / "runs").sort_values("index")
    failed = frame[frame["status"] == "failed"]
    assert set(failed["index"]) == {1}  # one run per task
    assert all("RuntimeError: boom at run 1" in r for r in failed["reason"])
    assert failed["rms_head_error"].isna().all()
    assert (frame[frame["status"] != "failed"]["status"] == "ok").all()
    assert summary.statuses == {"ok": 5, "diverged": 0, "failed": 1}
    assert summary.status == "complete" and "1 of 6 runs failed" in summary.note


def test_a_run_that_raises_inside_a_batch_fails_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    """In run_batch, one run's exception gives its failed row; the batch goes on."""
    spec = parse_study(STUDY)
    original = work.simulate_scenario

    def flaky(scenario: Scenario) -> work.RunOutcome:
        if scenario.index == 1:
            raise ZeroDivisionError("no torque today")
        return original(scenario)

    monkeypatch.setattr(work, "simulate_scenario", flaky)
    rows = run_batch(spec.scenarios[:3])
    assert [r["status"] for r in rows] == ["ok", "failed", "ok"]
    assert rows[1]["reason"] == "ZeroDivisionError: no torque today"
    assert rows[1]["R_min"] is None and rows[0]["R_min"] > 0 and rows[2]["t_end"] == 0.4


def test_a_killed_worker_loses_only_its_run(tmp_path: Path, scheduler: str) -> None:
    """A worker that dies loses its run (not recorded); a re-run runs just that run."""
    study, out = _study(tmp_path), tmp_path / "out"
    summary = run_study(study, out, scheduler=scheduler,
                        batch_function=functools.partial(_die, 3))
    assert (summary.status, summary.lost, summary.recorded) == ("incomplete", 1, 5)
    assert "run the same command again" in summary.note
    assert set(pd.read_parquet(out / "runs")["index"]) == {0, 1, 2, 4, 5}
    again = run_study(study, out, scheduler=scheduler)
    assert (again.ran, again.status) == (1, "complete")


def test_unreachable_or_malformed_scheduler_addresses_are_refused(tmp_path: Path) -> None:
    """A closed port or a non-tcp address: one StudyError line, no folder created."""
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    for address in (f"tcp://127.0.0.1:{port}", f"127.0.0.1:{port}"):
        with pytest.raises(StudyError, match="unreachable") as info:
            check_scheduler(address)
        assert "\n" not in str(info.value)
    for address in ("http://127.0.0.1:80", "127.0.0.1", "", "tcp://host:port"):
        with pytest.raises(StudyError, match="tcp://HOST:PORT"):
            check_scheduler(address)
    with pytest.raises(StudyError, match="unreachable"):
        run_study(_study(tmp_path), tmp_path / "out", scheduler=f"tcp://127.0.0.1:{port}")
    assert not (tmp_path / "out").exists()


def test_bad_input_is_refused_before_anything_runs(tmp_path: Path) -> None:
    """A bad study, another study's folder, or a bad worker count: nothing is written."""
    with pytest.raises(StudyError, match=r"\[base\] unknown setting"):
        run_study(_study(tmp_path, "[base]\nspeed = 1.0\n"), tmp_path / "a")
    assert not (tmp_path / "a").exists()
    spec = parse_study(STUDY)
    from snake_pin.study.results import StudyFolder

    with StudyFolder(tmp_path / "b").locked(spec):
        pass
    before = sorted(p.name for p in (tmp_path / "b").iterdir())
    with pytest.raises(StudyError, match="holds a different study"):
        run_study(_study(tmp_path, STUDY.replace("25.0", "50.0")), tmp_path / "b")
    assert sorted(p.name for p in (tmp_path / "b").iterdir()) == before
    for workers in (0, -1, 1000, 2.0):
        with pytest.raises(StudyError, match="workers must be an integer"):
            run_study(_study(tmp_path), tmp_path / "c", workers=workers)
    with pytest.raises(StudyError, match="workers applies to the local cluster"):
        run_study(_study(tmp_path), tmp_path / "c", workers=2, scheduler="tcp://127.0.0.1:1")
    assert not (tmp_path / "c").exists()


def test_every_run_is_one_task_in_study_order() -> None:
    """plan_batches gives one single-run task per scenario, viscous and engine alike, in
    study order."""
    runs = list(load_study(REPO / "studies" / "failure_map.toml").scenarios)
    assert plan_batches(runs) == [[s] for s in runs]
    engine = parse_study("[base]\nrobot = \"engine\"\nmodel = \"engine\"\ncontroller = "
                         "\"velocity\"\nt_final = 1.0\n[axes.failed_joint]\nvalues = [0, 1, 2]\n")
    assert [[s.index for s in b] for b in plan_batches(engine.scenarios)] == [[0], [1], [2]]


def test_a_study_file_with_batch_size_is_refused_in_one_line(tmp_path: Path) -> None:
    """batch_size (older study files) is refused, not ignored: one line saying runs are one
    per task, and nothing is created."""
    study = _study(tmp_path, STUDY.replace("[base]", "batch_size = 2\n[base]"))
    with pytest.raises(StudyError, match="batch_size is no longer a setting: every run is "
                       "one task") as info:
        run_study(study, tmp_path / "out")
    assert "\n" not in str(info.value)
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------- interrupts (a process)
def _stat(pid: int) -> list[str] | None:
    try:
        with open(f"/proc/{pid}/stat") as handle:
            return handle.read().rsplit(")", 1)[1].split()
    except OSError:
        return None


def _descendants(root: int) -> dict[int, str]:
    """Live descendants of ``root``: pid -> start time (to tell a reused pid)."""
    parents: dict[int, int] = {}
    start: dict[int, str] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            fields = _stat(int(entry))
            if fields is not None:
                parents[int(entry)] = int(fields[1])
                start[int(entry)] = fields[19]
    found: dict[int, str] = {}
    frontier = [root]
    while frontier:
        parent = frontier.pop()
        for pid, ppid in parents.items():
            if ppid == parent and pid not in found:
                found[pid] = start[pid]
                frontier.append(pid)
    return found


def _alive(pid: int, started: str) -> bool:
    fields = _stat(pid)
    return fields is not None and fields[19] == started and fields[0] not in ("Z", "X")


def _listening(pids: Sequence[int]) -> list[str]:
    """Local addresses (hex, as /proc/net shows them) of TCP listeners owned by ``pids``."""
    inodes = set()
    for pid in pids:
        try:
            for fd in os.listdir(f"/proc/{pid}/fd"):
                with_link = os.readlink(f"/proc/{pid}/fd/{fd}")
                if with_link.startswith("socket:["):
                    inodes.add(with_link[8:-1])
        except OSError:
            continue
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with open(table) as handle:
            for line in handle.readlines()[1:]:
                fields = line.split()
                if fields[3] == "0A" and fields[9] in inodes:  # 0A: LISTEN
                    found.append(fields[1].split(":")[0])
    return found


SCRIPT = """
import json, signal, sys
from snake_pin import SnakeParams
from snake_pin.exceptions import RunInterrupted
from snake_pin.robot_file import write_robot_file
from snake_pin.study import run_study
from tests.test_study_runner import _slow_after_first

def interrupt(signum, frame):
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise KeyboardInterrupt("SIGTERM")

if __name__ == "__main__":
    signal.signal(signal.SIGTERM, interrupt)
    try:
        run_study(sys.argv[1], sys.argv[2], workers=2, batch_function=_slow_after_first)
    except RunInterrupted as exc:
        print(json.dumps(exc.partial.to_dict()))
        sys.exit(130)
    sys.exit(0)
"""


@linux_only
def test_sigterm_keeps_written_runs_leaves_no_process_and_a_rerun_finishes(
        tmp_path: Path, scheduler: str) -> None:
    """SIGTERM after the first batch: interrupted summary, batch kept, workers gone,
    every listener was on 127.0.0.1, and the same study then completes the rest."""
    study = _study(tmp_path)
    out = tmp_path / "out"
    script = tmp_path / "run.py"
    script.write_text(SCRIPT)
    env = {**os.environ, "PYTHONPATH": f"{REPO}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    proc = subprocess.Popen([sys.executable, str(script), str(study), str(out)], cwd=REPO,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not list((out / "runs").glob("batch-*.parquet")):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no batch file within 120 s"
            time.sleep(0.05)
        children = _descendants(proc.pid)
        listeners = _listening([proc.pid, *children])
        written = sorted((out / "runs").glob("batch-*.parquet"))
        proc.send_signal(signal.SIGTERM)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr
    partial = json.loads(stdout)
    assert partial["status"] == "interrupted" and partial["recorded"] == 1
    assert partial["lost"] == 2  # in flight: one batch per worker; the rest never started
    assert json.loads((out / "summary.json").read_text())["status"] == "interrupted"
    assert "Interrupted:" in (out / "index.html").read_text()
    assert sorted((out / "runs").glob("batch-*.parquet")) == written
    assert len(children) >= 2  # the workers (and Dask's helpers)
    deadline = time.monotonic() + 30
    while any(_alive(p, s) for p, s in children.items()) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [p for p, s in children.items() if _alive(p, s)]
    assert len(listeners) >= 3 and set(listeners) == {"0100007F"}  # 127.0.0.1 only
    summary = run_study(study, out, scheduler=scheduler)
    assert (summary.ran, summary.skipped, summary.status) == (5, 1, "complete")


# ------------------------------------------------------------------ the subcommand
def _parser() -> argparse.ArgumentParser:
    return cli.build_parser()


def test_study_subcommand_runs_the_study_and_returns_its_summary(tmp_path: Path,
                                                                 scheduler: str) -> None:
    """`study FILE -o DIR --scheduler A --json` returns status 0 and summary.json's data."""
    out = tmp_path / "out"
    args = _parser().parse_args(["study", str(_study(tmp_path)), "-o", str(out),
                                 "--scheduler", scheduler, "--json"])
    result = args.func(args)
    assert result.status == 0 and result.note == ""
    assert result.payload == json.loads((out / "summary.json").read_text())
    assert result.payload["recorded"] == 6 and "6/6 runs recorded" in result.text


def test_study_subcommand_options_and_interrupt(tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """Bad --workers is a usage error; with --scheduler a StudyError; an interrupt
    returns the interrupted status with the partial summary."""
    parser = _parser()
    for bad in ("0", "x", "10000"):
        with pytest.raises(cli.UsageError, match="--workers"):
            parser.parse_args(["study", "s.toml", "-o", "d", "--workers", bad])
    args = parser.parse_args(["study", "s.toml", "-o", "d", "--workers", "2",
                              "--scheduler", "tcp://127.0.0.1:1"])
    with pytest.raises(StudyError, match="--workers"):
        args.func(args)
    partial = StudySummary(name="s", study_hash="ab", folder="d", status="interrupted",
                           runs=4, recorded=1, note="study s interrupted: 1/4")

    def interrupted(*_args: Any, **_kwargs: Any) -> StudySummary:
        raise RunInterrupted(partial.note, partial=partial)

    monkeypatch.setattr(snake_pin.study, "run_study", interrupted)
    args = parser.parse_args(["study", "s.toml", "-o", "d"])
    result = args.func(args)
    assert (result.status, result.note) == (130, "study s interrupted: 1/4")
    assert result.payload == partial.to_dict()
