"""Tests of the study's cluster security (snake_pin.study.runner, .command): the local
cluster's TLS credentials, bounded scheduler handshakes, security files, the dashboard."""

from __future__ import annotations

import contextlib
import http.client
import os
import re
import socket
import ssl
import struct
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from snake_pin import cli
from snake_pin.study import StudyError, run_study
from snake_pin.study.runner import _local_cluster, check_scheduler, load_security

STUDY = """
[study]
name = "tiny"
[base]
t_final = 0.05
error_window = 0.0
[axes.failed_joint]
values = [0, 5]
"""


def _bounded(call: Callable[[], Any], seconds: float = 30.0) -> Any:
    """``call()`` in a thread: its result or its exception, or a failure if it is still
    running after ``seconds`` (a hang fails the test instead of blocking the suite)."""
    outcome: dict[str, Any] = {}

    def target() -> None:
        try:
            outcome["value"] = call()
        except BaseException as exc:
            outcome["error"] = exc

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), f"still running after {seconds} s"
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


def _refused(call: Callable[[], Any], seconds: float = 30.0) -> BaseException:
    """The exception ``call()`` raises within ``seconds`` (failing if it succeeds).

    Dask's client asserts that its IO-loop thread started within 10 s; on a loaded machine
    it may not, which says nothing about the credentials: that attempt is made again."""
    for _ in range(3):
        try:
            _bounded(call, seconds)
        except AssertionError as exc:
            frames = traceback.extract_tb(exc.__traceback__)
            if frames and "distributed" in Path(frames[-1].filename).parts:
                continue  # the client's own loop did not start: not an answer
            raise
        except Exception as exc:
            return exc
        raise AssertionError("it succeeded")
    raise AssertionError("the client's IO loop did not start in three attempts")


# --------------------------------------------------------- the study's cluster
def _security_file(folder: Path, security: Any) -> Path:
    """A Dask config YAML file pointing at ``security``'s CA, client cert and key."""
    paths = {}
    for name, field in (("ca", "tls_ca_file"), ("client", "tls_client_cert"),
                        ("client-key", "tls_client_key")):
        paths[name] = folder / f"{name}.pem"
        paths[name].write_text(getattr(security, field))
    config = folder / "dask-security.yaml"
    config.write_text(f"distributed:\n  comm:\n    require-encryption: true\n    tls:\n"
                      f"      ca-file: {paths['ca']}\n      client:\n"
                      f"        cert: {paths['client']}\n        key: {paths['client-key']}\n")
    return config


@pytest.fixture(scope="module")
def cluster() -> Iterator[Any]:
    """The local cluster of a study, one worker, started the way run_study starts it."""
    with _local_cluster(1) as local:
        yield local


def test_the_local_cluster_runs_tasks_only_for_holders_of_its_credentials(cluster: Any) -> None:
    """Scheduler and workers listen on tls://127.0.0.1; with the run's credentials a client
    runs a task; without them, with other ones, or over tcp:// it cannot connect."""
    from distributed import Client
    from distributed.security import Security

    address = cluster.scheduler_address
    assert address.startswith("tls://127.0.0.1:")
    with Client(address, security=cluster.security, timeout="20s",
                set_as_default=False) as client:
        assert _bounded(lambda: client.submit(sum, [1, 2], pure=False).result()) == 3
        workers = client.scheduler_info()["workers"]
    assert workers and all(a.startswith("tls://127.0.0.1:") for a in workers)
    assert all(w["nanny"].startswith("tls://127.0.0.1:") for w in workers.values())
    tcp = address.replace("tls://", "tcp://")
    for target, security in ((address, None), (address, Security.temporary()), (tcp, None)):
        options = {} if security is None else {"security": security}
        _refused(lambda t=target, o=options: Client(t, timeout="3s", set_as_default=False, **o))


def test_check_scheduler_names_what_a_tls_scheduler_needs(cluster: Any, tmp_path: Path) -> None:
    """A tls:// scheduler without credentials, with foreign ones, or reached over tcp://:
    one line saying what to give; its credentials in a Dask config file: accepted; a
    worker's address: not a scheduler."""
    from distributed.security import Security

    address = cluster.scheduler_address
    port = address.rsplit(":", 1)[1]
    cases = ((address, None, "needs its cluster's TLS credentials"),
             (address, Security.temporary(), "refused these TLS credentials"),
             (f"tcp://127.0.0.1:{port}", None, f"speaks TLS: give tls://127.0.0.1:{port}"))
    for target, security, message in cases:
        error = _refused(lambda t=target, s=security: check_scheduler(t, security=s,
                                                                      timeout=5.0))
        assert isinstance(error, StudyError) and message in str(error)
        assert "\n" not in str(error)
    config = _security_file(tmp_path, cluster.security)
    assert _bounded(lambda: check_scheduler(address, security=config)) == address
    worker = next(iter(cluster.scheduler.workers))
    error = _refused(lambda: check_scheduler(worker, security=config))
    assert isinstance(error, StudyError) and "not a scheduler" in str(error)


def test_checking_a_tls_scheduler_leaves_no_warning_in_its_log(cluster: Any) -> None:
    """The reachability probe of a tls:// scheduler completes a TLS handshake, so the
    scheduler logs no 'TLS handshake failed' (as it does for a bare TCP connection)."""
    import logging

    records: list[logging.LogRecord] = []
    handler = logging.Handler(logging.WARNING)
    handler.emit = records.append  # type: ignore[method-assign]
    logger = logging.getLogger("distributed.comm.tcp")
    level = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.WARNING)
    try:
        address = cluster.scheduler_address
        assert _bounded(lambda: check_scheduler(address, security=cluster.security)) == address
        # then a bare TCP connection, whose warning shows that the log is being read
        with socket.create_connection(("127.0.0.1", int(address.rsplit(":", 1)[1]))) as bare:
            mark = f":{bare.getsockname()[1]}'"
        deadline = time.monotonic() + 10.0
        while not any(mark in r.getMessage() for r in records) and time.monotonic() < deadline:
            time.sleep(0.02)
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)
    messages = [record.getMessage() for record in records]
    assert messages and all(mark in m and "TLS handshake failed" in m for m in messages), \
        messages


def test_a_study_runs_on_a_tls_scheduler_given_a_security_file(cluster: Any, tmp_path: Path,
                                                               capsys: Any) -> None:
    """`snake-pin study --scheduler tls://... --security FILE`: exit 0, every run recorded."""
    import json

    config = _security_file(tmp_path, cluster.security)
    assert load_security(config).tls_client_key == str(tmp_path / "client-key.pem")
    study = tmp_path / "study.toml"
    study.write_text(STUDY)
    status = _bounded(lambda: cli.main(["study", str(study), "-o", str(tmp_path / "out"),
                                        "--scheduler", cluster.scheduler_address,
                                        "--security", str(config), "--json"]), 120)
    captured = capsys.readouterr()
    assert status == 0, captured.err
    summary = json.loads(captured.out)
    assert (summary["status"], summary["recorded"]) == ("complete", 2)
    assert summary["scheduler"] == cluster.scheduler_address


def test_the_dashboard_is_off_unless_asked_and_answers_local_hosts_only() -> None:
    """Without dashboard the scheduler's HTTP server serves nothing; with it, the link is on
    127.0.0.1 and a Host header other than 127.0.0.1/localhost gets 403 (no workers: cheap)."""
    def get(port: int, path: str, host: str) -> int:
        connection = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
        try:
            connection.request("GET", path, headers={"Host": host})
            return connection.getresponse().status
        finally:
            connection.close()

    with _local_cluster(0) as plain:
        port = plain.scheduler.services["dashboard"].port
        assert get(port, "/health", f"127.0.0.1:{port}") == 404
    messages: list[str] = []
    with _local_cluster(0, dashboard=True, log=messages.append) as local:
        port = local.scheduler.services["dashboard"].port
        assert local.scheduler.services["dashboard"].address == "127.0.0.1"
        assert [m for m in messages if m.startswith(f"dashboard: http://127.0.0.1:{port}/")]
        for host, status in ((f"127.0.0.1:{port}", 200), (f"localhost:{port}", 200),
                             ("evil.example", 403), (f"evil.example:{port}", 403)):
            assert get(port, "/health", host) == status, host


# --------------------------------------------------------- bounded handshakes
@contextlib.contextmanager
def _server(mode: str) -> Iterator[str]:
    """A TCP server on 127.0.0.1 that accepts and then says nothing (``silent``), sends
    bytes that are not Dask (``http``, ``frames``), or resets the connection (``reset``)."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen()
    listener.settimeout(0.2)
    stop = threading.Event()
    held: list[socket.socket] = []

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = listener.accept()
            except OSError:
                continue
            if mode == "reset":
                conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                conn.close()
                continue
            with contextlib.suppress(OSError):
                if mode == "http":
                    conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")
                elif mode == "frames":  # a frame header announcing 16 bytes of junk
                    conn.sendall(struct.pack("<Q", 16) + b"\xc1" * 16)
            held.append(conn)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{listener.getsockname()[1]}"
    finally:
        stop.set()
        thread.join(5)
        for conn in held:
            conn.close()
        listener.close()


@pytest.mark.parametrize(("mode", "message"), [
    ("silent", "did not complete Dask's handshake (no answer within 0.5 s)"),
    ("http", "did not complete Dask's handshake ("),
    ("frames", "did not complete Dask's handshake ("),
    ("reset", "did not complete Dask's handshake ("),
])
def test_a_server_that_does_not_speak_dask_fails_in_one_line_before_any_folder(
        tmp_path: Path, mode: str, message: str) -> None:
    """Silent, garbage or resetting servers: check_scheduler and run_study give one
    StudyError line within the connect timeout, and the output folder is never created."""
    study = tmp_path / "study.toml"
    study.write_text(STUDY)
    out = tmp_path / "out"
    with _server(mode) as address:
        for call in (lambda: check_scheduler(address, timeout=0.5),
                     lambda: run_study(study, out, scheduler=address, connect_timeout=0.5)):
            error = _refused(call, 10)
            assert isinstance(error, StudyError), repr(error)
            assert message in str(error) and "\n" not in str(error)
            assert not out.exists()


def test_the_cli_bounds_the_handshake_and_creates_nothing(tmp_path: Path, capsys: Any) -> None:
    """`--connect-timeout 0.5` to a silent server: exit 2, one stderr line, no folder."""
    study = tmp_path / "study.toml"
    study.write_text(STUDY)
    out = tmp_path / "out"
    with _server("silent") as address:
        status = _bounded(lambda: cli.main(["study", str(study), "-o", str(out), "--scheduler",
                                            address, "--connect-timeout", "0.5"]), 10)
    err = capsys.readouterr().err
    assert status == 2 and len(err.strip().splitlines()) == 1
    assert "no answer within 0.5 s" in err and "Traceback" not in err
    assert not out.exists()


def test_a_scheduler_that_goes_silent_after_the_check_is_given_up(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """If the server stops speaking Dask between the check and the client (here: the check
    is skipped), the client is abandoned on its own deadline with one line, not a hang."""
    from snake_pin.study import runner

    study = tmp_path / "study.toml"
    study.write_text(STUDY)
    monkeypatch.setattr(runner, "check_scheduler", lambda address, **_: address)
    with _server("silent") as address:
        error = _refused(lambda: run_study(study, tmp_path / "out", scheduler=address,
                                           connect_timeout=0.5), 10)
    assert isinstance(error, StudyError) and "no Dask scheduler answered" in str(error)
    assert "\n" not in str(error)


# ------------------------------------------------------------------ options
def test_security_options_are_checked_before_anything_is_created(tmp_path: Path) -> None:
    """A tls:// address without credentials, tcp:// with settings requiring encryption,
    security or dashboard where they do not apply, a bad timeout: one line, no folder."""
    from distributed.security import Security

    study = tmp_path / "study.toml"
    study.write_text(STUDY)
    out = tmp_path / "out"
    cases = [({"scheduler": "tls://127.0.0.1:1"}, "needs its cluster's TLS credentials"),
             ({"scheduler": "tcp://127.0.0.1:1", "security": Security(require_encryption=True)},
              "require encryption"),
             ({"security": Security()}, "security applies to a given scheduler"),
             ({"scheduler": "tcp://127.0.0.1:1", "dashboard": True},
              "dashboard applies to the local cluster"),
             ({"connect_timeout": 0}, "connect_timeout must be"),
             ({"connect_timeout": float("nan")}, "connect_timeout must be"),
             ({"scheduler": "udp://127.0.0.1:1"}, "tcp://HOST:PORT or tls://HOST:PORT")]
    for options, message in cases:
        with pytest.raises(StudyError, match=re.escape(message)):
            run_study(study, out, **options)
        assert not out.exists()
    parser = cli.build_parser()
    for bad in ("0", "-1", "nan", "x", "1e9"):
        with pytest.raises(cli.UsageError, match="--connect-timeout"):
            parser.parse_args(["study", "s.toml", "-o", "d", "--connect-timeout", bad])
    for argv, message in ((["--security", "f.yaml"], "--security: applies with --scheduler"),
                          (["--scheduler", "tcp://127.0.0.1:1", "--dashboard"],
                           "--dashboard: applies to the local cluster")):
        args = parser.parse_args(["study", str(study), "-o", str(out), *argv])
        with pytest.raises(StudyError, match=re.escape(message)):
            args.func(args)
    assert not out.exists()


def test_security_files_are_dask_config_and_bad_ones_are_named(tmp_path: Path) -> None:
    """load_security reads distributed.comm.tls (underscores as Dask spells them too); a
    missing file, a folder, a FIFO, a file too large, not UTF-8, bad YAML, no mapping, no
    TLS setting, an unknown one or a wrong type: one line naming the file."""
    good = tmp_path / "good.yaml"
    good.write_text("distributed:\n  comm:\n    require_encryption: true\n    tls:\n"
                    "      ca_file: /ca.pem\n      min-version: 1.3\n      client:\n"
                    "        cert: /client.pem\n  scheduler:\n    work-stealing: false\n")
    security = load_security(good)
    assert (security.tls_ca_file, security.tls_client_cert) == ("/ca.pem", "/client.pem")
    assert security.require_encryption is True and security.tls_client_key is None
    assert security.tls_min_version == ssl.TLSVersion.TLSv1_3
    (tmp_path / "folder.yaml").mkdir()
    bad = {"missing.yaml": None, "folder.yaml": None,
           "broken.yaml": "distributed: [unclosed\n",
           "empty.yaml": "distributed:\n  comm:\n    timeouts:\n      connect: 5s\n",
           "typo.yaml": "distributed:\n  comm:\n    tls:\n      cafile: /ca.pem\n",
           "type.yaml": "distributed:\n  comm:\n    tls:\n      ca-file: 3\n",
           "version.yaml": "distributed:\n  comm:\n    tls:\n      ca-file: /ca.pem\n"
                           "      min-version: 1.1\n"}
    bad.update({"blank.yaml": "", "list.yaml": "- distributed\n",
                "large.yaml": "#" * (1 << 20) + "\n", "latin1.yaml": None})
    (tmp_path / "latin1.yaml").write_bytes(b"distributed: caf\xe9\n")
    os.mkfifo(tmp_path / "fifo.yaml")  # never opened: reading it would block
    bad["fifo.yaml"] = None
    messages = {"missing.yaml": "no such security file", "folder.yaml": "is a folder",
                "blank.yaml": "is empty", "list.yaml": "top level is a list",
                "large.yaml": "larger than 1048576 bytes", "latin1.yaml": "not UTF-8",
                "fifo.yaml": "FIFO, not a regular file",
                "broken.yaml": "not YAML Dask config", "empty.yaml": "no distributed.comm.tls",
                "typo.yaml": "unknown setting distributed.comm.tls.cafile",
                "type.yaml": "wrong type", "version.yaml": "min-version"}
    for name, text in bad.items():
        path = tmp_path / name
        if text is not None:
            path.write_text(text)
        with pytest.raises(StudyError) as info:
            load_security(path)
        assert str(path) in str(info.value) and messages[name] in str(info.value), name
        assert "\n" not in str(info.value)
