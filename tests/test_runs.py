"""Tests of snake_pin.runs: its place below the command line and the report, and the Dask
cluster a block of run_jobs calls shares (snake_pin.runs.parallel.SharedCluster)."""

from __future__ import annotations

import ast
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from snake_pin.runs.parallel import SharedCluster, run_jobs

PACKAGE = Path(__file__).resolve().parents[1] / "snake_pin"


def _imported(path: Path) -> set[str]:
    """Every snake_pin module a file imports (relative imports resolved), lazy ones too."""
    here = ["snake_pin", *path.relative_to(PACKAGE).with_suffix("").parts[:-1]]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(here[:len(here) - node.level + 1] + ([base] if base else []))
            found.update(f"{base}.{alias.name}" for alias in node.names)
            found.add(base)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return {name for name in found if name.startswith("snake_pin")}


def test_the_command_line_calls_no_report_stage() -> None:
    """cli.py imports the report's runner (for reproduce) and no report stage: its runs come
    from snake_pin.runs."""
    from snake_pin.experiments import stages

    imported = _imported(PACKAGE / "cli.py")
    for name, _ in stages():
        stage = f"snake_pin.experiments.{name}"
        assert not {m for m in imported if m == stage or m.startswith(stage + ".")}, name
    assert any(name.startswith("snake_pin.runs.") for name in imported)


def test_the_runs_import_neither_the_report_nor_the_command_line() -> None:
    """snake_pin.runs sits below both of its users."""
    for path in (PACKAGE / "runs").glob("*.py"):
        above = {name for name in _imported(path)
                 if name.startswith(("snake_pin.experiments", "snake_pin.cli"))}
        assert not above, f"{path.name} imports {sorted(above)}"


def _pid() -> int:
    return os.getpid()


def _pids(count: int) -> list[tuple[Callable[[], int], tuple[()], dict[str, Any]]]:
    """``count`` jobs that give the pid of the process they run in."""
    return [(_pid, (), {}) for _ in range(count)]


def test_a_shared_cluster_serves_every_call_of_its_block_and_closes_with_it() -> None:
    """Two run_jobs calls in one block run on the same worker processes (one cluster, not
    one per call); the workers are gone once the block ends."""
    with SharedCluster(workers=2) as cluster:
        first = set(run_jobs(_pids(4), cluster=cluster))
        client = cluster.client()
        second = set(run_jobs(_pids(4), cluster=cluster))
        assert cluster.client() is client
        assert os.getpid() not in first | second
        assert first | second <= set(client.run(os.getpid).values())
    deadline = time.monotonic() + 30.0
    while any(os.path.exists(f"/proc/{pid}") for pid in first | second):
        assert time.monotonic() < deadline, "the shared cluster's workers outlived its block"
        time.sleep(0.1)


def test_a_shared_cluster_starts_only_when_jobs_fan_out() -> None:
    """A block whose calls run here (one job, or one worker) starts no cluster."""
    with SharedCluster(workers=2) as cluster:
        assert run_jobs(_pids(1), cluster=cluster) == [os.getpid()]
        assert cluster._client is None
    with SharedCluster(workers=1) as cluster:
        assert run_jobs(_pids(3), cluster=cluster) == [os.getpid()] * 3
        assert cluster._client is None


def test_a_job_error_in_a_shared_cluster_reaches_the_caller() -> None:
    """A job's exception comes back from run_jobs; the block's cluster still closes."""
    with pytest.raises(ZeroDivisionError), SharedCluster(workers=2) as cluster:
        run_jobs([(divmod, (1, 0), {}), (divmod, (4, 2), {})], cluster=cluster)
