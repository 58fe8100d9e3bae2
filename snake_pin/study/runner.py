"""Running a study on Dask (one run per task, rows written as they arrive, resumable) on an
authenticated local cluster or a checked existing one: :ref:`studies` (How a study runs).
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import socket
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from typing import Any
from urllib.parse import urlsplit

from .._io import decode_utf8, read_regular_file
from .._validation import brief, one_line, printable_path
from ..exceptions import RunInterrupted
from .errors import StudyError
from .results import StudyFolder
from .spec import Scenario, StudySpec, load_study
from .summary import StudySummary

__all__ = ["CONNECT_TIMEOUT", "LOCAL_HOSTS", "MAX_CONNECT_TIMEOUT", "MAX_WORKERS",
           "load_security", "run_study"]

#: Default longest wait for a scheduler to complete Dask's handshake [s].
CONNECT_TIMEOUT = 10.0
#: Largest ``connect_timeout`` accepted [s].
MAX_CONNECT_TIMEOUT = 600.0
#: Most local worker processes.
MAX_WORKERS = 256
#: Host headers the local cluster's HTTP servers answer (any other: 403).
LOCAL_HOSTS = ("127.0.0.1", "localhost")
#: Environment of the local cluster's workers, on top of Dask's one-thread BLAS defaults.
WORKER_ENV = {"OMP_WAIT_POLICY": "PASSIVE", "OMP_NUM_THREADS": "1",
              "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
_CLOSE_TIMEOUT = 20
#: On an interrupt, a local worker still running a task is killed after 0.8 this [s].
_KILL_TIMEOUT = 1.0
#: Largest security file read [bytes].
_MAX_SECURITY_BYTES = 1 << 20
#: Dask config keys a security file may set, under ``distributed.comm``.
_TLS_KEYS = ("require-encryption", "tls.ca-file", "tls.ciphers", "tls.min-version",
             "tls.max-version", "tls.client.cert", "tls.client.key", "tls.scheduler.cert",
             "tls.scheduler.key", "tls.worker.cert", "tls.worker.key")

BatchFunction = Callable[[Sequence[Scenario]], list[dict[str, Any]]]


def run_study(spec_path: str | os.PathLike[str], out_dir: str | os.PathLike[str], *,
              scheduler: str | None = None, workers: int | None = None,
              security: Any = None, connect_timeout: float = CONNECT_TIMEOUT,
              dashboard: bool = False, progress: bool | None = None,
              log: Callable[[str], None] | None = None,
              batch_function: BatchFunction | None = None,
              client: Any = None) -> StudySummary:
    """Run the study of ``spec_path`` into ``out_dir`` (only the runs not yet recorded).

    Parameters
    ----------
    spec_path, out_dir
        The study file; its folder (created if missing).
    scheduler
        An existing Dask scheduler (``tcp://`` or ``tls://host:port``); None: a local cluster.
    workers
        Local worker processes (default: one per core).
    security
        A ``distributed.security.Security``, a YAML file (:func:`load_security`) or None.
    connect_timeout
        Longest wait [s] for the scheduler's handshake (at most :data:`MAX_CONNECT_TIMEOUT`).
    dashboard
        Serve the local cluster's Dask dashboard on 127.0.0.1 (its link goes to ``log``).
    progress
        A tqdm bar on stderr, drawn only on a terminal; False: none.
    log
        Receives a few one-line messages; None: silent.
    batch_function
        The task (default :func:`snake_pin.study.work.run_batch`), importable by the workers.
    client
        A running ``distributed.Client`` to run on (left open; excludes the four above).

    Returns
    -------
    StudySummary
        Also written to ``out_dir/summary.json``, with ``out_dir/index.html``.

    Raises
    ------
    StudyError
        Before anything runs: a bad study file, folder, scheduler or argument.
    RunInterrupted
        On KeyboardInterrupt; ``partial`` is the summary (status ``interrupted``).
    """
    started = time.monotonic()
    spec = load_study(spec_path)
    address = None
    if client is not None:
        if scheduler is not None or workers is not None or security is not None or dashboard:
            raise StudyError("a client brings its own cluster: scheduler, workers, security "
                             "and dashboard do not apply")
        address = _client_address(client)
    folder = StudyFolder(out_dir)
    folder.check(spec)
    workers = _slots(client) if client is not None else _check_workers(workers, scheduler)
    timeout = _check_timeout(connect_timeout)
    credentials = None
    if scheduler is not None:
        if dashboard:
            raise StudyError("dashboard applies to the local cluster; the scheduler's "
                             "cluster has its own")
        credentials = _security(security)
        address = check_scheduler(scheduler, security=credentials, timeout=timeout)
    elif security is not None:
        raise StudyError("security applies to a given scheduler; the local cluster makes "
                         "its own TLS credentials")
    say = log or (lambda _message: None)
    if batch_function is None:
        from .work import run_batch

        batch_function = run_batch
    summary = StudySummary(name=spec.name, study_hash=spec.study_hash,
                           folder=str(folder.path), runs=len(spec.scenarios),
                           scheduler=address or f"local ({workers} worker"
                           f"{'s' if workers != 1 else ''})")
    interrupted = False
    with folder.locked(spec):
        done = folder.done_keys()
        pending = [s for s in spec.scenarios if s.key not in done]
        summary.skipped = len(spec.scenarios) - len(pending)
        try:
            if pending:
                with contextlib.nullcontext(client) if client is not None else \
                        dask_client(address, workers, security=credentials, timeout=timeout,
                                    dashboard=bool(dashboard), log=say) as client:
                    slots = _slots(client) if address else workers
                    batches = plan_batches(pending)
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
    rows = zip(table.column("key").to_pylist(), table.column("status").to_pylist(), strict=True)
    first = dict(reversed([(k, s) for k, s in rows if k in keys]))  # each run's first row
    statuses = {**dict.fromkeys(("ok", "diverged", "failed"), 0), **Counter(first.values())}
    summary.recorded = len(first)
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
    from distributed.scheduler import KilledWorker
    from tqdm import tqdm

    from .results import batch_name
    from .work import failed_row

    futures: dict[Any, list[Scenario]] = {}
    queue = list(reversed(batches))

    def submit() -> Any:
        batch = queue.pop()
        file = batch_name([s.key for s in batch])
        future = client.submit(batch_function, batch, pure=False,
                               key=f"snake-pin-study-{file[6:26]}")
        futures[future] = batch
        return future

    bar = tqdm(total=sum(len(b) for b in batches), unit="run", desc=f"study {name}",
               disable=None if progress is not False else True, leave=False)
    try:
        running = as_completed([submit() for _ in range(min(slots, len(queue)))],
                               loop=client.loop)
        failures = 0
        for future in running:
            batch = futures.pop(future)
            if queue:
                running.add(submit())
            error = None if future.cancelled() else future.exception()
            if future.cancelled() or isinstance(error, KilledWorker):
                summary.lost += len(batch)
            else:
                text = f"task failed: {type(error).__name__}: {' '.join(str(error).split())}"
                rows = future.result() if error is None else \
                    [failed_row(s, text[:500]) for s in batch]
                folder.write_batch([s.key for s in batch], rows)
                summary.ran += len(rows)
                failures += sum(r["status"] != "ok" for r in rows)
                bar.set_postfix(failed=failures, refresh=False)
            bar.update(len(batch))
            future.release()
    except BaseException:
        with contextlib.suppress(Exception):
            summary.lost += sum(len(b) for b in futures.values())
            client.cancel(list(futures), force=True)
        raise
    finally:
        bar.close()


def plan_batches(scenarios: Sequence[Scenario]) -> list[list[Scenario]]:
    """The study's tasks: one run each, in study order."""
    return [[s] for s in scenarios]


def check_scheduler(address: str, *, security: Any = None,
                    timeout: float = CONNECT_TIMEOUT) -> str:
    """``address`` normalised, once the scheduler there has completed Dask's handshake (TCP,
    then Dask's handshake and identity, on a deadline of ``timeout`` of its own)."""
    text, scheme, host, port = _parse_address(address)
    timeout = _check_timeout(timeout)
    credentials = _security(security)
    shown = f"[{host}]" if ":" in host else host
    normal = f"{scheme}://{shown}:{port}"
    if scheme == "tls":
        _check_credentials(text, credentials)
    elif credentials.require_encryption:
        raise StudyError(f"scheduler {text}: the security settings require encryption; give "
                         f"the scheduler's tls:// address")
    deadline = time.monotonic() + timeout
    try:
        with socket.create_connection((host, port), timeout=timeout) as probe:
            if scheme == "tls":
                _finish_tls(probe, credentials, deadline)
    except ConnectionResetError:
        raise StudyError(f"scheduler {text} did not complete Dask's handshake (it reset the "
                         "connection)") from None
    except OSError as exc:
        reason = "no answer" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise StudyError(f"scheduler {text} is unreachable ({reason} within "
                         f"{timeout:g} s)") from None
    try:
        identity = _handshake(normal, credentials, max(0.05, deadline - time.monotonic()))
    except Exception as exc:  # whatever a foreign server's bytes make the reader raise
        raise StudyError(_handshake_failure(text, scheme, host, port, exc, timeout,
                                            deadline)) from None
    kind = identity.get("type") if isinstance(identity, dict) else None
    if kind != "Scheduler":
        raise StudyError(f"scheduler {text} answered Dask's handshake but is "
                         f"{'a ' + one_line(str(kind), 40) if kind else 'no Dask server'}, "
                         "not a scheduler")
    return normal


def load_security(path: str | os.PathLike[str]) -> Any:
    """A Dask cluster's credentials from a YAML file of Dask config (format: :ref:`studies`).

    Parameters
    ----------
    path
        The file (a regular file of at most 1 MiB).

    Returns
    -------
    distributed.security.Security
        The credentials, for :func:`run_study`.

    Raises
    ------
    StudyError
        Not YAML, or a ``distributed.comm.tls`` setting missing, unknown or mistyped.
    """
    import dask
    import yaml  # PyYAML, a dependency of Dask
    from distributed.security import Security

    shown = printable_path(path)

    def refuse(problem: str) -> StudyError:
        return StudyError(f"security file {shown}: {one_line(problem)}")

    # read once, checked, and parsed as Dask parses its config files (yaml.safe_load)
    text = decode_utf8(read_regular_file(path, limit=_MAX_SECURITY_BYTES, kind="security file",
                                         error=refuse), error=refuse)
    try:
        data = yaml.safe_load(text)
    except Exception as exc:  # yaml's errors (multi-line), or a nesting too deep to parse
        raise StudyError(f"security file {shown} is not YAML Dask config: "
                         f"{one_line(str(exc)) or type(exc).__name__}") from None
    if data is None:
        raise StudyError(f"security file {shown} is empty")
    if not isinstance(data, dict):
        raise StudyError(f"security file {shown} is not YAML Dask config: its top level is "
                         f"a {type(data).__name__}, not a mapping")
    settings = _tls_settings(data, shown)
    try:
        with dask.config.set({f"distributed.comm.{k}": v for k, v in settings.items()}):
            return Security()
    except (ValueError, TypeError) as exc:
        raise StudyError(f"security file {shown}: {one_line(str(exc))}") from None


def _tls_settings(data: Any, shown: str) -> dict[str, Any]:
    """The ``distributed.comm`` TLS leaves of a Dask config document, dotted, checked."""
    distributed = data.get("distributed")
    comm = distributed.get("comm") if isinstance(distributed, dict) else None
    found: dict[str, Any] = {}

    def walk(node: Any, prefix: str) -> None:
        for key, value in node.items():
            name = f"{prefix}{str(key).replace('_', '-')}"
            if isinstance(value, dict):
                walk(value, name + ".")
            elif name in _TLS_KEYS:
                kind = bool if name == "require-encryption" else \
                    (float, int) if name.endswith("-version") else str
                if value is not None and (not isinstance(value, kind) or (
                        kind is not bool and isinstance(value, bool))):
                    raise StudyError(f"security file {shown}: distributed.comm.{name} has "
                                     f"the wrong type ({type(value).__name__})")
                found[name] = value
            elif name.startswith("tls.") or name == "require-encryption":
                raise StudyError(f"security file {shown}: unknown setting "
                                 f"distributed.comm.{one_line(name, 80)}")

    if isinstance(comm, dict):
        walk(comm, "")
    if not any(k.startswith("tls.") and v for k, v in found.items()):
        raise StudyError(f"security file {shown} sets no distributed.comm.tls setting "
                         "(ca-file, client.cert, client.key)")
    return found


def _security(security: Any) -> Any:
    """``security`` as a :class:`distributed.security.Security` (None: Dask's config)."""
    from distributed.security import Security

    if isinstance(security, Security):
        return security
    if isinstance(security, (str, os.PathLike)):
        return load_security(security)
    if security is not None:
        raise StudyError("security must be a distributed.security.Security or the path of "
                         f"a YAML file of Dask config, got {type(security).__name__}")
    try:
        return Security()
    except (ValueError, TypeError) as exc:
        raise StudyError(f"Dask's distributed.comm.tls config: {one_line(str(exc))}") from None


def _check_credentials(text: str, security: Any) -> None:
    """Refuse a tls:// address without client credentials, or with unloadable ones."""
    if not (security.tls_ca_file and security.tls_client_cert):
        raise StudyError(f"scheduler {text} needs its cluster's TLS credentials: give a "
                         "security file (--security FILE: Dask config with "
                         "distributed.comm.tls.ca-file, client.cert and client.key) or set "
                         "them in Dask's config")
    try:
        security.get_connection_args("client")
    except (OSError, ValueError) as exc:  # ssl.SSLError is an OSError
        raise StudyError(f"scheduler {text}: the TLS credentials cannot be loaded "
                         f"({one_line(str(exc))})") from None


def _parse_address(address: Any) -> tuple[str, str, str, int]:
    """(text, scheme, host, port) of ``[tcp|tls://]host:port``, or a StudyError."""
    expected = "scheduler address must be tcp://HOST:PORT or tls://HOST:PORT"
    if not isinstance(address, str) or not address.strip():
        raise StudyError(f"{expected}, got {address!r}")
    text = address.strip()
    parts = urlsplit(text if "://" in text else f"tcp://{text}")
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        host, port = None, None
    if parts.scheme not in ("tcp", "tls") or not host or port is None or \
            parts.path not in ("", "/") or parts.query or parts.fragment:
        raise StudyError(f"{expected}, got {text!r}")
    return text, parts.scheme, host, port


def _check_timeout(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value) or not 0 < value <= MAX_CONNECT_TIMEOUT:
        raise StudyError(f"connect_timeout must be a number of seconds in (0, "
                         f"{MAX_CONNECT_TIMEOUT:g}], got {value!r}")
    return float(value)


def _handshake(address: str, security: Any, timeout: float) -> Any:
    """Dask's handshake with ``address`` and its identity, in a thread waited on for
    ``timeout`` plus a second at most."""
    import asyncio

    from distributed.comm import connect

    args = security.get_connection_args("client")

    async def exchange() -> Any:
        comm = await connect(address, timeout=timeout, **args)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    outcome, done = _in_thread(lambda: asyncio.run(asyncio.wait_for(exchange(), timeout)),
                               "snake-pin-scheduler-check")
    done.wait(timeout + 1.0)
    if "value" in outcome:
        return outcome["value"]
    error = outcome.get("error")
    if error is None or isinstance(error, asyncio.CancelledError):
        raise TimeoutError
    raise error


def _finish_tls(probe: socket.socket, security: Any, deadline: float) -> None:
    """Complete a TLS handshake on the probe (a TLS listener warns of a connection closed
    before one), failures left to Dask's handshake; at most 1 s or half the time left."""
    left = min(1.0, (deadline - time.monotonic()) / 2)
    context = security.get_connection_args("client").get("ssl_context")
    if left <= 0.01 or context is None:
        return
    probe.settimeout(left)
    with contextlib.suppress(OSError, ValueError), \
            context.wrap_socket(probe, server_hostname=None):
        pass


def _handshake_failure(text: str, scheme: str, host: str, port: int, exc: BaseException,
                       timeout: float, deadline: float) -> str:
    """One line saying why Dask's handshake with ``text`` failed (and what to give)."""
    silent = isinstance(exc, TimeoutError) or "Timed out" in str(exc)
    if scheme == "tcp" and not silent and _speaks_tls(host, port, deadline):
        return (f"scheduler {text} speaks TLS: give tls://{host}:{port} and its cluster's "
                "credentials (--security FILE, or Dask's distributed.comm.tls config)")
    if scheme == "tls" and "certificate" in str(exc).lower():
        return (f"scheduler {text} refused these TLS credentials (give its cluster's: "
                f"--security FILE): {one_line(str(exc), 120)}")
    reason = f"no answer within {timeout:g} s" if silent else \
        f"{type(exc).__name__}: {one_line(str(exc), 120) or 'no detail'}"
    hint = ("; is it a tcp:// scheduler?" if scheme == "tls" and silent else "")
    return f"scheduler {text} did not complete Dask's handshake ({reason}){hint}"


def _speaks_tls(host: str, port: int, deadline: float) -> bool:
    """Whether the server at host:port answers a TLS handshake (before ``deadline``)."""
    import ssl

    left = min(2.0, deadline - time.monotonic())
    if left <= 0.05:
        return False
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    context.check_hostname = False
    context.verify_mode = ssl.CERT_NONE
    try:
        with socket.create_connection((host, port), timeout=left) as raw, \
                context.wrap_socket(raw, server_hostname=None):
            return True
    except ssl.SSLError as exc:  # an alert is TLS speaking; "wrong version number" is not
        return "ALERT" in str(exc).upper()
    except OSError:
        return False


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


def _client_address(client: object) -> str:
    """The scheduler address of a running ``distributed.Client``; StudyError otherwise."""
    from distributed import Client

    if not isinstance(client, Client) or client.status != "running":
        raise StudyError(f"client must be a running distributed.Client, got {brief(client)}")
    return str(client.scheduler_info()["address"])


def _slots(client: Any) -> int:
    with contextlib.suppress(Exception):
        return max(1, sum(client.nthreads().values()))
    return 1


@contextlib.contextmanager
def dask_client(address: str | None, workers: int, *, security: Any = None,
            timeout: float = CONNECT_TIMEOUT, dashboard: bool = False,
            log: Callable[[str], None] | None = None) -> Iterator[Any]:
    """A Dask client of the scheduler at ``address``, or of a new local cluster (TLS on
    127.0.0.1, closed with its workers when the block ends): the package's one executor."""
    from distributed import Client

    if address is not None:
        # on a deadline of its own: a Client to a silent server waits past its timeout
        made, done = _in_thread(lambda: Client(address, security=security, set_as_default=False,
                                               timeout=f"{timeout:g}s"), "snake-pin-client")
        done.wait(timeout + 2.0)
        if "value" not in made:
            reason = one_line(str(made["error"])) if "error" in made else \
                f"no answer within {timeout:g} s"
            raise StudyError(f"scheduler {address}: no Dask scheduler answered ({reason})")
        with _closing(made["value"]) as client:
            yield client
        return
    with _local_cluster(workers, dashboard=dashboard, log=log) as cluster, \
            _closing(Client(cluster, security=cluster.security, set_as_default=False)) as client:
        yield client


@contextlib.contextmanager
def _closing(client: Any) -> Iterator[Any]:
    """``client``, closed (errors ignored) when the block ends however it ends."""
    try:
        yield client
    finally:
        with contextlib.suppress(Exception):
            client.close(timeout=_CLOSE_TIMEOUT)


@contextlib.contextmanager
def _local_cluster(workers: int, *, dashboard: bool = False,
                   log: Callable[[str], None] | None = None) -> Iterator[Any]:
    """``workers`` processes on 127.0.0.1, TLS with credentials made here, HTTP servers with no
    route but the optional dashboard, answering local Host headers only."""
    import dask
    from distributed import LocalCluster
    from distributed.security import Security

    security = Security.temporary()
    routes = list(dask.config.get("distributed.scheduler.http.routes")) if dashboard else []
    # silence_logs CRITICAL: Dask's own lines (a worker stopped while it runs a task logs
    # its lost heartbeats) stay off stderr; a task's error comes back through its future
    with dask.config.set({"distributed.scheduler.http.routes": routes,
                          "distributed.worker.http.routes": []}):
        cluster = _started(lambda: LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
            protocol="tls://", security=security, dashboard_address=None,
            scheduler_kwargs={"dashboard": bool(dashboard), "dashboard_address": "127.0.0.1:0"},
            silence_logs=logging.CRITICAL, env=dict(WORKER_ENV)))
    try:
        _guard_hosts(cluster.scheduler)
        if dashboard and log is not None:
            log(f"dashboard: {_dashboard_link(cluster.scheduler)}")
        yield cluster
    except BaseException:
        _kill_workers(cluster)
        raise
    finally:
        with contextlib.suppress(Exception):
            cluster.close(timeout=_CLOSE_TIMEOUT)


def _dashboard_link(scheduler: Any) -> str:
    import importlib.util

    port = scheduler.services["dashboard"].port
    if importlib.util.find_spec("bokeh") is None:
        return (f"http://127.0.0.1:{port}/info/main/workers.html (Dask's info pages; "
                "install bokeh for the full dashboard)")
    return f"http://127.0.0.1:{port}/status"


def _guard_hosts(server: Any) -> None:
    """Make ``server``'s HTTP server answer 403 to a Host header outside :data:`LOCAL_HOSTS`."""
    from tornado import web

    app = getattr(server, "http_application", None)
    if app is None:
        return
    find = app.find_handler

    def find_handler(request: Any, **kwargs: Any) -> Any:
        if getattr(request, "host_name", None) not in LOCAL_HOSTS:
            return app.get_handler_delegate(request, web.ErrorHandler, {"status_code": 403})
        return find(request, **kwargs)

    app.find_handler = find_handler


def _started(make: Callable[[], Any]) -> Any:
    """The cluster ``make()`` starts in a thread: a KeyboardInterrupt meanwhile waits for the
    start to finish (a half-started cluster cannot be closed), then stops it and goes on."""
    made, done = _in_thread(make, "snake-pin-cluster-start")
    interrupt: BaseException | None = None
    while not done.is_set():
        try:
            done.wait()
        except KeyboardInterrupt as exc:
            interrupt = exc
    if "error" in made:
        raise interrupt if interrupt is not None else made["error"]
    cluster = made["value"]
    if interrupt is not None:
        _kill_workers(cluster)
        with contextlib.suppress(Exception):
            cluster.close(timeout=_CLOSE_TIMEOUT)
        raise interrupt
    return cluster


def _in_thread(make: Callable[[], Any], name: str) -> tuple[dict[str, Any], threading.Event]:
    """``make()`` in a daemon thread: its ``value`` or ``error`` once the event is set."""
    made: dict[str, Any] = {}
    done = threading.Event()  # not Thread.join: an interrupted join can mark it stopped

    def target() -> None:
        try:
            made["value"] = make()
        except BaseException as exc:  # handed to the caller's thread
            made["error"] = exc
        finally:
            done.set()

    threading.Thread(target=target, name=name, daemon=True).start()
    return made, done


def _kill_workers(cluster: Any) -> None:
    """Interrupted: close the local workers' nannies at once, each killing its process after
    0.8 :data:`_KILL_TIMEOUT` (a nanny otherwise waits 4 s for the running task)."""
    with contextlib.suppress(Exception):
        cluster.sync(_close_nannies, list(cluster.workers.values()), _KILL_TIMEOUT)


async def _close_nannies(nannies: Sequence[Any], timeout: float) -> None:
    import asyncio

    await asyncio.gather(*(n.close(timeout=timeout, reason="snake-pin-study-interrupted")
                           for n in nannies), return_exceptions=True)
