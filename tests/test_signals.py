"""Interrupted runs: SIGINT/SIGTERM/SIGHUP end a command with one line, status 130, the
partial result written and marked interrupted, and no worker process left behind."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from snake_pin.cli import EXIT_INTERRUPTED, main
from snake_pin.runs.parallel import run_jobs
from snake_pin.sim import Trajectory


def _run(capfd: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capfd.readouterr()
    return code, out, err


def _signal_on_call(sig: signal.Signals, at: int, fn: Callable) -> Callable:
    """``fn`` that sends ``sig`` to this process on its ``at``-th call."""
    calls = [0]

    def wrapped(*args: object, **kwargs: object) -> object:
        calls[0] += 1
        if calls[0] == at:
            signal.raise_signal(sig)
        return fn(*args, **kwargs)
    return wrapped


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def _state(pid: int) -> str | None:
    """A process's state letter, None once it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0]
    except OSError:
        return None


def _children(pid: int) -> list[int]:
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as stat:
                    if int(stat.read().rsplit(")", 1)[1].split()[1]) == pid:
                        found.append(int(entry))
            except (OSError, IndexError, ValueError):
                continue
    return found


def _all_gone(pids: list[int], within: float = 10.0) -> bool:
    """Whether every pid is gone or a zombie (dead, awaiting its reaper) within the bound."""
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        if all(_state(pid) in (None, "Z", "X") for pid in pids):
            return True
        time.sleep(0.1)
    return False


linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")


@pytest.fixture(autouse=True)
def default_signal_handlers() -> Iterator[None]:
    """Python's default handlers for SIGINT, SIGTERM and SIGHUP during each test, restored
    after: the tests send these signals to this process and to child processes, which
    inherit an ignored signal (pytest started as `nohup pytest` or `pytest &` in a script
    ignores SIGINT, and the command line rightly stays deaf to an inherited ignore)."""
    wanted = {signal.SIGINT: signal.default_int_handler, signal.SIGTERM: signal.SIG_DFL}
    if hasattr(signal, "SIGHUP"):
        wanted[signal.SIGHUP] = signal.SIG_DFL
    previous = {sig: signal.signal(sig, handler) for sig, handler in wanted.items()}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)


def _last_line(err: str) -> str:
    """The last stderr line (after reproduce's stage lines), with no traceback anywhere."""
    assert "Traceback" not in err and err.strip(), err
    return err.strip().splitlines()[-1]


# --------------------------------------------------------------------- in process
def test_sigterm_during_simulate_saves_the_partial_run(capfd: pytest.CaptureFixture[str],
                                                       tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """SIGTERM in simulate: status 130, one line naming the signal and the time, the
    partial run saved with status "interrupted", the JSON says so, handlers restored."""
    from snake_pin.control import PFLController

    # the 300th control step (t = 0.299 s): samples 0 .. 0.299 s are whole
    monkeypatch.setattr(PFLController, "__call__",
                        _signal_on_call(signal.SIGTERM, 300, PFLController.__call__))
    before = signal.getsignal(signal.SIGTERM)
    code, out, err = _run(capfd, "simulate", "--controller", "pfl", "--t-final", "5",
                          "-o", str(tmp_path), "--json")
    assert code == EXIT_INTERRUPTED
    line = _one_line(err)
    assert "SIGTERM" in line and "interrupted at t = 0.29" in line and "pfl.npz" in line
    summary = json.loads(out)
    assert summary["status"] == "interrupted" and summary["t_end"] == pytest.approx(0.299)
    traj = Trajectory.load(tmp_path / "pfl.npz")
    assert traj.status == "interrupted" and len(traj) == 300 and not traj.diverged
    assert signal.getsignal(signal.SIGTERM) == before


def test_sighup_during_engine_saves_the_partial_run(capfd: pytest.CaptureFixture[str],
                                                    tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """SIGHUP in the MuJoCo loop: status 130 and the engine's partial run, marked
    interrupted (run_engine does what simulate does)."""
    from snake_pin.engine.run import DirtyDerivative

    monkeypatch.setattr(DirtyDerivative, "__call__",
                        _signal_on_call(signal.SIGHUP, 100, DirtyDerivative.__call__))
    code, out, err = _run(capfd, "engine", "--t-final", "1", "--cone", "pyramidal",
                          "-o", str(tmp_path))
    assert code == EXIT_INTERRUPTED
    assert "SIGHUP" in _one_line(err) and "status: interrupted\n" in out
    traj = Trajectory.load(tmp_path / "engine.npz")
    assert traj.status == "interrupted" and 90 <= len(traj) <= 100
    assert "interrupted at t = 0.09" in traj.reason


def test_sigint_during_sweep_writes_the_postures_done(capfd: pytest.CaptureFixture[str],
                                                     tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """SIGINT in a sweep: status 130, CSV/JSON/PNG of the postures computed so far, the JSON
    marked interrupted with the number asked for."""
    import snake_pin.sweeps as sweeps

    monkeypatch.setattr(sweeps, "manipulability",
                        _signal_on_call(signal.SIGINT, 8, sweeps.manipulability))
    code, _, err = _run(capfd, "sweep", "arc", "--points", "50", "-o", str(tmp_path))
    assert code == EXIT_INTERRUPTED and "SIGINT" in _one_line(err)
    data = json.loads((tmp_path / "sweep_arc.json").read_text())
    assert data["status"] == "interrupted" and data["points_requested"] == 50
    assert 7 <= len(data["values"]) == len(data["R"]) <= 8
    assert (tmp_path / "sweep_arc.png").is_file()
    assert (tmp_path / "sweep_arc.csv").read_text().count("\n") == len(data["values"]) + 1


def test_sigterm_during_singular_writes_the_starts_done(capfd: pytest.CaptureFixture[str],
                                                       tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """SIGTERM in the singular search: status 130, the search over the finished starts
    written (JSON marked interrupted, drawing) and printed as the one JSON object."""
    import snake_pin.singular as singular

    monkeypatch.setattr(singular, "minimize",
                        _signal_on_call(signal.SIGTERM, 5, singular.minimize))
    code, out, err = _run(capfd, "singular", "--starts", "20", "-o", str(tmp_path), "--json")
    assert code == EXIT_INTERRUPTED and "SIGTERM" in _one_line(err)
    printed = json.loads(out)
    saved = json.loads((tmp_path / "singular_postures.json").read_text())
    for data in (printed, saved):
        assert data["status"] == "interrupted" and data["starts"] == 2
        assert data["starts_requested"] == 20
    assert (tmp_path / "singular_postures.png").is_file()


def _report_stage_interrupt(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make the robot stage receive SIGTERM while it draws (after its first figure)."""
    import snake_pin.experiments.robot as robot

    monkeypatch.setattr(robot, "plot_postures",
                        _signal_on_call(signal.SIGTERM, 1, robot.plot_postures))


def test_interrupted_reproduce_keeps_a_complete_previous_report(
        capfd: pytest.CaptureFixture[str], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A complete report stays byte for byte; the partial one (marked interrupted, naming
    the stage) goes to interrupted/; no staging folder is left."""
    assert main(["reproduce", "--only", "robot", "-o", str(tmp_path)]) == 0
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    capfd.readouterr()
    _report_stage_interrupt(monkeypatch)
    code, _, err = _run(capfd, "reproduce", "--only", "robot", "-o", str(tmp_path))
    assert code == EXIT_INTERRUPTED and "untouched" in _last_line(err)
    assert err.count("\n") == 2  # the stage's line, then the interruption's
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()} == before
    run = json.loads((tmp_path / "interrupted" / "summary.json").read_text())["run"]
    assert run["status"] == "interrupted" and "during stage 'robot'" in run["note"]
    assert "Interrupted run" in (tmp_path / "interrupted" / "index.html").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*before, "interrupted"])


def test_interrupted_reproduce_in_a_new_folder_marks_its_index(
        capfd: pytest.CaptureFixture[str], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Without a previous report, the output folder gets the index of the stages done,
    marked interrupted, and none of the unfinished stage's files."""
    _report_stage_interrupt(monkeypatch)
    code, _, err = _run(capfd, "reproduce", "--only", "robot", "-o", str(tmp_path))
    assert code == EXIT_INTERRUPTED and "marked interrupted" in _last_line(err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["index.html", "summary.json"]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["run"]["status"] == "interrupted" and "robot" not in summary


def test_stale_staging_folder_of_a_killed_run_is_removed(tmp_path: Path) -> None:
    """A staging folder whose process is gone (kill -9) is removed by the next run; one of
    a live process is kept."""
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    stale = tmp_path / f".reproduce-{dead}-abc123"
    live = tmp_path / f".reproduce-{os.getpid()}-def456"
    for folder in (stale, live):
        folder.mkdir()
        (folder / "robot_postures.png").write_bytes(b"half")
    assert main(["reproduce", "--only", "robot", "-o", str(tmp_path)]) == 0
    assert not stale.exists() and live.exists()


def _interrupt_parent_then_sleep(seconds: float) -> int:
    os.kill(os.getppid(), signal.SIGINT)
    time.sleep(seconds)
    return 0


@linux_only
def test_interrupt_while_waiting_terminates_the_pool() -> None:
    """KeyboardInterrupt in the parent while jobs run: the workers are killed before it
    goes on, and the workers themselves ignored the SIGINT."""
    import multiprocessing

    with pytest.raises(KeyboardInterrupt):
        run_jobs([(_interrupt_parent_then_sleep, (30.0,), {}), (time.sleep, (30.0,), {})],
                 workers=2)
    assert multiprocessing.active_children() == []


def _pool_state() -> tuple[int, list[int], str | None]:
    """What a job sees: its pid, its BLAS/OpenMP pools' thread counts, OMP_WAIT_POLICY."""
    from threadpoolctl import threadpool_info

    return (os.getpid(), [pool["num_threads"] for pool in threadpool_info()],
            os.environ.get("OMP_WAIT_POLICY"))


def test_pool_jobs_run_with_one_blas_thread_and_passive_openmp() -> None:
    """Jobs in pool workers see every BLAS/OpenMP pool limited to one thread and
    OMP_WAIT_POLICY=PASSIVE; a job run in this process (one job) is limited too, and the
    limits are restored after it."""
    from threadpoolctl import threadpool_info

    before = [pool["num_threads"] for pool in threadpool_info()]
    results = run_jobs([(_pool_state, (), {}), (_pool_state, (), {})], workers=2)
    assert all(pid != os.getpid() for pid, _, _ in results)
    assert all(set(threads) == {1} and policy == "PASSIVE" for _, threads, policy in results)
    (pid, threads, _), = run_jobs([(_pool_state, (), {})])
    assert pid == os.getpid() and set(threads) == {1}
    assert [pool["num_threads"] for pool in threadpool_info()] == before


def test_iter_jobs_yields_each_result_with_its_index() -> None:
    """iter_jobs gives every job's result once, with the job's index (any order)."""
    from snake_pin.runs.parallel import iter_jobs

    jobs = [(pow, (k, 2), {}) for k in range(6)]
    pairs = list(iter_jobs(jobs, workers=2))
    assert sorted(pairs) == [(k, k * k) for k in range(6)]


def test_sigterm_during_engine_seeds_keeps_the_runs_done(capfd: pytest.CaptureFixture[str],
                                                         tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """engine --seeds 3, SIGTERM during the second run (runs in this process): status 130,
    one line, the first run saved, engine_seeds.json marked interrupted with the
    distribution of the one finished run, and the JSON output says so."""
    import snake_pin.runs.parallel as parallel
    from snake_pin.engine.run import DirtyDerivative

    monkeypatch.setattr(parallel.os, "cpu_count", lambda: 1)
    monkeypatch.setattr(DirtyDerivative, "__call__",
                        _signal_on_call(signal.SIGTERM, 150, DirtyDerivative.__call__))
    code, out, err = _run(capfd, "engine", "--seeds", "3", "--t-final", "0.1", "--cone",
                          "pyramidal", "-o", str(tmp_path), "--json")
    assert code == EXIT_INTERRUPTED
    line = _one_line(err)
    assert "SIGTERM" in line and "1 of 3 runs finished" in line
    data = json.loads(out)
    table = json.loads((tmp_path / "engine_seeds.json").read_text())
    for record in (data, table):
        assert record["status"] == "interrupted" and record["finished"] == 1
        assert record["distribution"]["R_min"]["count"] == 1
    assert (tmp_path / "engine_seed1.npz").is_file()
    assert not (tmp_path / "engine_seed2.npz").exists()
    assert Trajectory.load(tmp_path / "engine_seed1.npz").status == "completed"


# -------------------------------------------------------------- real processes
def _popen(*args: str, cwd: Path, code: str | None = None) -> subprocess.Popen[str]:
    command = [sys.executable, "-c", code] if code else [sys.executable, "-m", "snake_pin.cli"]
    return subprocess.Popen([*command, *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _wait_for(condition: Callable[[], bool], within: float = 60.0) -> None:
    deadline = time.monotonic() + within
    while not condition():
        assert time.monotonic() < deadline, "the process did not get there in time"
        time.sleep(0.05)


@linux_only
def test_ctrl_c_on_a_simulate_process(tmp_path: Path) -> None:
    """A real SIGINT to `snake-pin simulate` once its loop runs: exit 130, one line, no
    traceback, the partial run on disk marked interrupted."""
    marker = tmp_path / "started"
    code = textwrap.dedent(f"""
        import pathlib, sys
        from snake_pin.control import LyapunovController
        from snake_pin.cli import main
        step, calls = LyapunovController.__call__, [0]
        def counted(*args):
            calls[0] += 1
            if calls[0] == 50:  # 49 control steps are whole by now: t_end >= 0.049 s
                pathlib.Path({str(marker)!r}).touch()
                LyapunovController.__call__ = step
            return step(*args)
        LyapunovController.__call__ = counted
        sys.exit(main(sys.argv[1:]))
    """)
    proc = _popen("simulate", "--controller", "lyapunov", "--t-final", "100", "-o", "out",
                  cwd=tmp_path, code=code)
    try:
        _wait_for(marker.exists)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == EXIT_INTERRUPTED and "status: interrupted\n" in out
    assert "SIGINT" in _one_line(err)
    traj = Trajectory.load(tmp_path / "out" / "lyapunov.npz")
    assert traj.status == "interrupted" and 0 < traj.t_end < 100


@linux_only
def test_sigterm_on_reproduce_leaves_no_worker(tmp_path: Path) -> None:
    """SIGTERM to `snake-pin reproduce` once its pool runs: exit 130, one line, every worker
    gone, and the folder holds the index of the stages done, marked interrupted."""
    proc = _popen("reproduce", "--quick", "--only", "tracking", "-o", "out", cwd=tmp_path)
    try:
        _wait_for(lambda: len(_children(proc.pid)) >= 2)
        workers = _children(proc.pid)
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == EXIT_INTERRUPTED and out == ""
    assert err.startswith("snake-pin: reproduce [1/1] tracking ...\n")
    assert "SIGTERM" in _last_line(err) and "during stage 'tracking'" in _last_line(err)
    assert _all_gone(workers)
    folder = tmp_path / "out"
    assert sorted(p.name for p in folder.iterdir()) == ["index.html", "summary.json"]
    assert json.loads((folder / "summary.json").read_text())["run"]["status"] == "interrupted"


@linux_only
def test_sigterm_on_engine_seeds_leaves_no_worker(tmp_path: Path) -> None:
    """SIGTERM to `snake-pin engine --seeds 4` while its pool runs: exit 130, one line,
    every worker gone, engine_seeds.json marked interrupted."""
    proc = _popen("engine", "--seeds", "4", "--t-final", "30", "--cone", "pyramidal",
                  "-o", "out", cwd=tmp_path)
    try:
        _wait_for(lambda: len(_children(proc.pid)) >= 2)
        workers = _children(proc.pid)
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == EXIT_INTERRUPTED and out.startswith("engine")
    assert "SIGTERM" in _one_line(err) and "runs finished" in err
    assert _all_gone(workers)
    table = json.loads((tmp_path / "out" / "engine_seeds.json").read_text())
    assert table["status"] == "interrupted" and table["finished"] < 4
    assert not [p for p in (tmp_path / "out").iterdir() if ".snake_pin-" in p.name]


@linux_only
def test_pool_workers_die_with_a_killed_parent(tmp_path: Path) -> None:
    """kill -9 of the process that runs a pool: its workers die too (PR_SET_PDEATHSIG)."""
    code = textwrap.dedent("""
        import time
        from snake_pin.runs.parallel import run_jobs
        run_jobs([(time.sleep, (60.0,), {}), (time.sleep, (60.0,), {})], workers=2)
    """)
    proc = _popen(cwd=tmp_path, code=code)
    try:
        _wait_for(lambda: len(_children(proc.pid)) >= 2)
        workers = _children(proc.pid)
        proc.kill()
        proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert _all_gone(workers)


@linux_only
def test_live_view_json_prints_the_url_then_stops_on_sigterm(tmp_path: Path) -> None:
    """`view RUN --json` (live) prints one JSON object with a 127.0.0.1 URL, serves until
    SIGTERM, then exits 0 with its server gone."""
    import numpy as np

    from snake_pin import SnakeParams

    traj = Trajectory(t=np.array([0.0, 0.1]), q=np.zeros((2, 12)), dq=np.zeros((2, 12)),
                      tau=np.zeros((2, 9)), params=SnakeParams.table1())
    traj.save(tmp_path / "run")
    proc = _popen("view", "run.npz", "--json", cwd=tmp_path)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        data = json.loads(line)
        assert data["url"].startswith("http://127.0.0.1:")
        server = _children(proc.pid)
        proc.send_signal(signal.SIGTERM)
        rest, _ = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 0 and rest == ""
    assert _all_gone(server)
