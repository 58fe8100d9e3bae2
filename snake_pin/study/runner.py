"""Running a study on Dask: batches of runs as tasks, rows written as they arrive, resumable.

:func:`run_study` validates everything first (the study file, the output folder, the
scheduler address), then runs the missing runs only:

- **Cluster.** By default a :class:`distributed.LocalCluster` of ``workers`` processes
  (default: one per core) with one thread each, everything bound to 127.0.0.1: the
  scheduler, the workers, their nannies, and the scheduler's HTTP endpoint on a random
  loopback port (no dashboard). Workers start with ``OMP_WAIT_POLICY=PASSIVE`` and Dask's
  one-thread BLAS/OpenMP environment, and each task limits thread pools again with
  threadpoolctl (OpenMP's spinning wait and multi-threaded BLAS on tiny matrices are many
  times slower when another core is busy).
  ``scheduler="tcp://HOST:PORT"`` uses an existing cluster instead; it is first reached
  with a plain TCP connection of at most :data:`CONNECT_TIMEOUT` seconds, so an
  unreachable address fails before anything runs.
  Its workers need the same snake_pin installed, and should be started with
  ``OMP_WAIT_POLICY=PASSIVE`` in their environment (OpenMP reads it when Pinocchio is
  loaded, before any task runs; threadpoolctl still limits the thread counts per task).
- **Tasks.** Viscous-model runs go in lockstep batches of one robot layout and time step,
  evenly sized, at most ``batch_size`` (default 256) and what fits in memory, and at
  least one per worker (:func:`plan_batches`, which states the trade-off); engine runs
  go one per task. The task is :func:`snake_pin.study.work.run_batch`. At
  most one task per worker thread is submitted at a time (the next when one finishes), so
  the runs in flight - what an interrupt or a dying worker can lose - are the running ones.
- **Results.** Futures are gathered with :func:`distributed.as_completed`; each finished
  batch is written at once as one Parquet file (temp + rename). A batch whose task raised
  is recorded as ``failed`` rows carrying the error; a batch lost with a worker that died
  (after Dask's own retries) is not recorded, and the next invocation runs it again.
- **Interrupts.** On KeyboardInterrupt (Ctrl-C; ``snake-pin`` turns SIGTERM and SIGHUP
  into one) the pending futures are cancelled, the client and the local cluster are
  closed (the local workers are killed without waiting for their running batch), the
  batches already written are kept, the index is written marked ``interrupted``, and
  :class:`~snake_pin.exceptions.RunInterrupted` is raised with the
  :class:`~snake_pin.study.summary.StudySummary` as ``partial``.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import socket
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any
from urllib.parse import urlsplit

from ..batch import LAYOUT_FIELDS, layout_key
from ..exceptions import RunInterrupted
from .errors import StudyError
from .results import StudyFolder
from .spec import Scenario, StudySpec, load_study
from .summary import StudySummary

__all__ = ["CONNECT_TIMEOUT", "LAYOUT_FIELDS", "MAX_WORKERS", "check_scheduler", "plan_batches",
           "run_study"]

#: Longest wait for a scheduler address to accept a TCP connection [s].
CONNECT_TIMEOUT = 3.0
#: Most local worker processes.
MAX_WORKERS = 256
#: Environment of the local cluster's workers, on top of Dask's one-thread BLAS defaults.
WORKER_ENV = {"OMP_WAIT_POLICY": "PASSIVE", "OMP_NUM_THREADS": "1",
              "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
_CLOSE_TIMEOUT = 20
#: On an interrupt, a local worker still running a batch is killed after 0.8 this [s].
_KILL_TIMEOUT = 1.0

BatchFunction = Callable[[Sequence[Scenario]], list[dict[str, Any]]]


def run_study(spec_path: str | os.PathLike[str], out_dir: str | os.PathLike[str], *,
              scheduler: str | None = None, workers: int | None = None,
              progress: bool | None = None, log: Callable[[str], None] | None = None,
              batch_function: BatchFunction | None = None) -> StudySummary:
    """Run the study of ``spec_path`` into ``out_dir`` (only the runs not yet recorded).

    Parameters
    ----------
    spec_path
        The study file (:mod:`snake_pin.study.spec`).
    out_dir
        Its folder (:mod:`snake_pin.study.results`); created if missing.
    scheduler
        Address of an existing Dask scheduler (``tcp://host:port``); None starts a local
        cluster on 127.0.0.1.
    workers
        Local worker processes (default: one per core); refused with ``scheduler``.
    progress
        A tqdm bar (runs done, failures, ETA) on stderr, drawn only on a terminal;
        False: none.
    log
        Receives a few one-line messages (what runs where); None: silent.
    batch_function
        The task (default :func:`snake_pin.study.work.run_batch`); it must be importable
        by the workers. For tests and for plugging in other simulators.

    Returns
    -------
    StudySummary
        Also written to ``out_dir/summary.json``, with ``out_dir/index.html``.

    Raises
    ------
    StudyError
        Before anything runs: a bad study file, a folder holding another study, an
        unreachable scheduler, a bad ``workers``.
    RunInterrupted
        On KeyboardInterrupt; ``partial`` is the summary (status ``interrupted``).
    """
    started = time.monotonic()
    spec = load_study(spec_path)
    folder = StudyFolder(out_dir)
    folder.check(spec)
    workers = _check_workers(workers, scheduler)
    address = check_scheduler(scheduler) if scheduler is not None else None
    say = log or (lambda _message: None)
    if batch_function is None:
        from .work import run_batch

        batch_function = run_batch
    summary = StudySummary(name=spec.name, study_hash=spec.study_hash,
                           folder=str(folder.path), runs=len(spec.scenarios),
                           scheduler=address or f"local ({workers} workers)")
    interrupted = False
    with folder.locked(spec):
        done = folder.done_keys()
        pending = [s for s in spec.scenarios if s.key not in done]
        summary.skipped = len(spec.scenarios) - len(pending)
        try:
            if pending:
                with _client(address, workers) as client:
                    slots = _slots(client) if address else workers
                    batches = plan_batches(pending, spec.batch_size, slots)
                    say(f"study {spec.name}: {len(spec.scenarios)} runs, {summary.skipped} "
                        f"already recorded, {len(pending)} to run in {len(batches)} tasks on "
                        f"{summary.scheduler}")
                    _execute(client, batches, slots, batch_function, folder, summary,
                             progress, spec.name)
        except KeyboardInterrupt:
            interrupted = True
        _finish(spec, folder, summary, started, interrupted)
    if interrupted:
        raise RunInterrupted(summary.note, partial=summary)
    say(summary.note or f"study {spec.name}: {summary.status}")
    return summary


def _finish(spec: StudySpec, folder: StudyFolder, summary: StudySummary, started: float,
            interrupted: bool) -> None:
    """Count what is recorded, set the status and note, write summary.json and index.html."""
    from .report import write_index

    keys = {s.key for s in spec.scenarios}
    table = folder.read_table(["key", "status"])
    statuses = dict.fromkeys(("ok", "diverged", "failed"), 0)
    seen: set[str] = set()
    for key, status in zip(table.column("key").to_pylist(), table.column("status").to_pylist(),
                           strict=True):
        if key in keys and key not in seen:
            seen.add(key)
            statuses[status] = statuses.get(status, 0) + 1
    summary.recorded = len(seen)
    summary.statuses = statuses
    missing = summary.runs - summary.recorded
    if interrupted:
        summary.status = "interrupted"
        summary.note = (f"study {spec.name} interrupted: {summary.recorded}/{summary.runs} runs "
                        f"recorded, {missing} to go (run the same command again to finish)")
    elif missing:
        summary.status = "incomplete"
        summary.note = (f"study {spec.name}: {missing} runs lost with a worker; run the same "
                        "command again to retry them")
    else:
        summary.status = "complete"
        failed = statuses.get("failed", 0) + statuses.get("diverged", 0)
        summary.note = (f"study {spec.name}: {failed} of {summary.runs} runs failed or "
                        "diverged (see index.html)") if failed else ""
    summary.wall_time = time.monotonic() - started
    summary.files = {"index": str(folder.path / "index.html"),
                     "summary": str(folder.path / "summary.json"),
                     "runs": str(folder.runs), "study": str(folder.path / "study.json")}
    write_index(folder, spec, summary)


def _execute(client: Any, batches: list[list[Scenario]], slots: int,
             batch_function: BatchFunction, folder: StudyFolder, summary: StudySummary,
             progress: bool | None, name: str) -> None:
    """Keep ``slots`` batches running, write each as it completes; cancel on interrupt."""
    from distributed import as_completed
    from tqdm import tqdm

    from .results import batch_name
    from .work import failed_row

    futures: dict[Any, list[Scenario]] = {}
    queue = list(reversed(batches))
    bar = None

    def submit() -> Any:
        batch = queue.pop()
        keys = [s.key for s in batch]
        future = client.submit(batch_function, batch, pure=False,
                               key=f"snake-pin-study-{batch_name(keys)[6:26]}")
        futures[future] = batch
        return future

    try:
        bar = tqdm(total=sum(len(b) for b in batches), unit="run", desc=f"study {name}",
                   disable=None if progress is not False else True, leave=False)
        running = as_completed([submit() for _ in range(min(slots, len(queue)))],
                               loop=client.loop)
        failures = 0
        for future in running:
            batch = futures.pop(future)
            if queue:
                running.add(submit())
            error = None if future.cancelled() else future.exception()
            if future.cancelled() or _is_killed_worker(error):
                summary.lost += len(batch)
                bar.update(len(batch))
                future.release()
                continue
            if error is None:
                rows = future.result()
            else:
                text = f"task failed: {type(error).__name__}: {' '.join(str(error).split())}"
                rows = [failed_row(s, text[:500]) for s in batch]
            folder.write_batch([s.key for s in batch], rows)
            summary.ran += len(rows)
            failures += sum(r["status"] != "ok" for r in rows)
            bar.update(len(rows))
            bar.set_postfix(failed=failures, refresh=False)
            future.release()
    except BaseException:
        with contextlib.suppress(Exception):
            summary.lost += sum(len(b) for b in futures.values())
            client.cancel(list(futures), force=True)
        raise
    finally:
        if bar is not None:
            bar.close()


def _is_killed_worker(error: BaseException | None) -> bool:
    from distributed.scheduler import KilledWorker

    return isinstance(error, KilledWorker)


def plan_batches(scenarios: Sequence[Scenario], batch_size: int,
                 slots: int) -> list[list[Scenario]]:
    """Group runs into tasks: engine runs alone; viscous runs that share the robot's layout
    (:data:`snake_pin.batch.LAYOUT_FIELDS`) and the time steps ``dt``, ``control_dt`` (a
    lockstep batch shares them), in study order, in evenly sized batches.

    Each group of G runs is cut into k batches of ``ceil(G / k)`` runs, k the fewest that
    keep batches within ``batch_size`` and within what one lockstep batch holds in memory
    (:func:`snake_pin.study.work.runs_per_batch`), rounded up to a multiple of ``slots``
    (worker threads) so that every worker gets the same share.

    The trade-off: a lockstep batch of B runs costs less per run as B grows (measured on
    this 2-core machine, 10-link robot, per process: B = 1 about 3 simulated seconds per
    wall second against 13-19 for one run through :func:`snake_pin.sim.simulate`, parity
    near B = 6-8, then 41 at B = 20, 76 at B = 64, 100 at B = 256), so big batches and
    one batch per worker are fastest for small studies; but a task is written only when
    its whole batch is done, so an interrupt or a dying worker loses up to ``slots``
    batches, and uneven batches leave a worker idle at the end. Batches of fewer than
    :data:`snake_pin.study.work.MIN_LOCKSTEP` runs are simulated one by one inside the task.

    Parameters
    ----------
    scenarios
        The runs to execute, in study order.
    batch_size
        Most runs per viscous task (the study's ``batch_size``).
    slots
        Worker threads of the cluster.

    Returns
    -------
    list of list of Scenario
        The tasks: engine runs alone, then each group's batches in study order.
    """
    from .work import runs_per_batch

    batches: list[list[Scenario]] = [[s] for s in scenarios if s.model == "engine"]
    groups: dict[tuple[Any, ...], list[Scenario]] = {}
    for s in scenarios:
        if s.model != "engine":
            groups.setdefault((*layout_key(s.params), s["dt"], s["control_dt"]),
                              []).append(s)
    slots = max(1, slots)
    for group in groups.values():
        cap = max(1, min(batch_size, runs_per_batch(group)))
        count = math.ceil(len(group) / cap)
        count = min(len(group), slots * math.ceil(count / slots))
        size = math.ceil(len(group) / count)
        batches += [group[i:i + size] for i in range(0, len(group), size)]
    return batches


def check_scheduler(address: str) -> str:
    """``address`` as ``tcp://host:port`` once a TCP connection to it succeeds.

    Parameters
    ----------
    address
        ``tcp://HOST:PORT`` or ``HOST:PORT``.

    Returns
    -------
    str
        The address as ``tcp://host:port`` (IPv6 hosts in brackets).

    Raises
    ------
    StudyError
        Not a ``[tcp://]host:port`` address, or nothing accepts a connection there within
        :data:`CONNECT_TIMEOUT` seconds.
    """
    if not isinstance(address, str) or not address.strip():
        raise StudyError(f"scheduler address must be tcp://HOST:PORT, got {address!r}")
    text = address.strip()
    parts = urlsplit(text if "://" in text else f"tcp://{text}")
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        host, port = None, None
    if parts.scheme != "tcp" or not host or port is None or parts.path not in ("", "/"):
        raise StudyError(f"scheduler address must be tcp://HOST:PORT, got {text!r}")
    try:
        with socket.create_connection((host, port), timeout=CONNECT_TIMEOUT):
            pass
    except OSError as exc:
        reason = "no answer" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise StudyError(f"scheduler {text} is unreachable ({reason} within "
                         f"{CONNECT_TIMEOUT:g} s)") from None
    shown = f"[{host}]" if ":" in host else host
    return f"tcp://{shown}:{port}"


def _check_workers(workers: int | None, scheduler: str | None) -> int:
    if workers is None:
        return max(1, os.cpu_count() or 1)
    if scheduler is not None:
        raise StudyError("workers applies to the local cluster; the scheduler's cluster has "
                         "its own")
    if isinstance(workers, bool) or not isinstance(workers, int) or \
            not 1 <= workers <= MAX_WORKERS:
        raise StudyError(f"workers must be an integer in 1..{MAX_WORKERS}, got {workers!r}")
    return workers


def _slots(client: Any) -> int:
    with contextlib.suppress(Exception):
        return max(1, sum(client.nthreads().values()))
    return 1


@contextlib.contextmanager
def _client(address: str | None, workers: int) -> Iterator[Any]:
    """A Dask client: of the scheduler at ``address``, or of a new local cluster (closed,
    with its worker processes, when the block ends however it ends)."""
    from distributed import Client, LocalCluster

    if address is not None:
        try:
            client = Client(address, timeout=f"{3 * CONNECT_TIMEOUT:g}s",
                            set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise StudyError(f"scheduler {address}: no Dask scheduler answered "
                             f"({' '.join(str(exc).split())})") from None
        try:
            yield client
        finally:
            with contextlib.suppress(Exception):
                client.close(timeout=_CLOSE_TIMEOUT)
        return
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           host="127.0.0.1", dashboard_address=None,
                           scheduler_kwargs={"dashboard": False,
                                             "dashboard_address": "127.0.0.1:0"},
                           silence_logs=logging.ERROR, env=dict(WORKER_ENV))
    try:
        client = Client(cluster, set_as_default=False)
        try:
            yield client
        finally:
            with contextlib.suppress(Exception):
                client.close(timeout=_CLOSE_TIMEOUT)
    except BaseException:
        # interrupted: stop the workers without waiting for their running batch (a nanny
        # otherwise waits 4 s for it before killing the process)
        with contextlib.suppress(Exception):
            cluster.sync(_close_nannies, list(cluster.workers.values()), _KILL_TIMEOUT)
        raise
    finally:
        with contextlib.suppress(Exception):
            cluster.close(timeout=_CLOSE_TIMEOUT)


async def _close_nannies(nannies: Sequence[Any], timeout: float) -> None:
    """Close the local workers' nannies at once, each killing its process after 0.8 timeout."""
    import asyncio

    await asyncio.gather(*(n.close(timeout=timeout, reason="snake-pin-study-interrupted")
                           for n in nannies), return_exceptions=True)
