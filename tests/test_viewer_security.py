"""Viewer security: loopback-only listeners, no listener for HTML, servers die with parents."""

from __future__ import annotations

import base64
import os
import selectors
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from snake_pin import OpenLoop, Snake, SnakeParams, SnakePinError, simulate
from snake_pin.viz import meshcat_view
from snake_pin.viz.meshcat_view import start_server, stop_server, write_html

SERVER = "snake_pin.viz.meshcat_server"


@pytest.fixture(scope="module")
def run_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 0.1 s open-loop run of the Table 1 robot, saved as run.npz."""
    snake = Snake(SnakeParams.table1())
    x0 = np.r_[0.0, 0.0, 0.0, np.full(9, np.pi / 6), np.zeros(12)]
    traj = simulate(snake, OpenLoop(lambda t: np.zeros(9)), x0, t_final=0.1)
    npz, _ = traj.save(tmp_path_factory.mktemp("run") / "run")
    return npz


# --- reading the process table and the socket tables from /proc ----------------------------

def _children(pid: int) -> list[int]:
    out = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            out += [int(c) for c in (task / "children").read_text().split()]
        except OSError:
            pass
    return out


def _tree(pid: int) -> list[int]:
    """``pid`` and all its descendants."""
    found, todo = [], [pid]
    while todo:
        p = todo.pop()
        found.append(p)
        todo += _children(p)
    return found


def _socket_inodes(pid: int) -> set[str]:
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").glob("*"):
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    return inodes


def _address(hex_address: str) -> str:
    """/proc/net/tcp{,6} address (host byte order words) -> dotted or colon form."""
    ip_hex, port_hex = hex_address.split(":")
    raw = b"".join(int(ip_hex[i:i + 8], 16).to_bytes(4, sys.byteorder)
                   for i in range(0, len(ip_hex), 8))
    family = socket.AF_INET if len(raw) == 4 else socket.AF_INET6
    return f"{socket.inet_ntop(family, raw)}:{int(port_hex, 16)}"


def _listening(pid: int) -> list[str]:
    """Every listening TCP address (IPv4 and IPv6) of ``pid`` and its descendants."""
    out = []
    for p in _tree(pid):
        inodes = _socket_inodes(p)
        for table in ("tcp", "tcp6"):
            for row in Path(f"/proc/{p}/net/{table}").read_text().splitlines()[1:]:
                fields = row.split()
                if fields[3] == "0A" and fields[9] in inodes:  # 0A: TCP_LISTEN
                    out.append(_address(fields[1]))
    return sorted(set(out))


def _alive(pid: int) -> bool:
    """Whether any thread of ``pid`` still runs (zombies awaiting their reaper do not).

    The thread-group leader turns zombie before the other threads (meshcat's ZMQ threads)
    have exited and released the process's files, so every thread is checked.
    """
    for stat in Path(f"/proc/{pid}/task").glob("*/stat"):
        try:
            if stat.read_text().rsplit(")", 1)[1].split()[0] not in "ZX":
                return True
        except OSError:
            pass
    return False


def _listeners_on(port: int) -> list[str]:
    """Listening TCP sockets on ``port`` (any address, IPv4 or IPv6) in this network namespace."""
    out = []
    for table in ("tcp", "tcp6"):
        for row in Path(f"/proc/self/net/{table}").read_text().splitlines()[1:]:
            fields = row.split()
            if fields[3] == "0A" and int(fields[1].split(":")[1], 16) == port:
                out.append(_address(fields[1]))
    return out


def _wait_gone(pid: int, port: int | None = None, timeout: float = 5.0) -> bool:
    """Wait until ``pid`` has no running thread and nothing listens on ``port``."""
    deadline = time.monotonic() + timeout
    while _alive(pid) or (port is not None and _listeners_on(port)):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def _readline(stream: object, timeout: float) -> str:
    """One line of a child's stdout, or fail (never hang) after ``timeout`` seconds."""
    fd = stream.fileno()  # type: ignore[attr-defined]
    data = b""
    with selectors.DefaultSelector() as selector:
        selector.register(fd, selectors.EVENT_READ)
        deadline = time.monotonic() + timeout
        while not data.endswith(b"\n"):
            left = deadline - time.monotonic()
            assert left > 0 and selector.select(left), f"no line within {timeout} s: {data!r}"
            chunk = os.read(fd, 1)
            assert chunk, f"stream closed after {data!r}"
            data += chunk
    return data.decode()


def _start_view(run_file: Path, cli: bool = False, stderr: object = subprocess.DEVNULL
                ) -> tuple[subprocess.Popen[bytes], int, int]:
    """A process running a blocking live ``view``; return it, its server's pid and web port."""
    if cli:
        cmd = [sys.executable, "-m", "snake_pin.cli", "view", str(run_file)]
    else:
        # Python leaves SIGINT ignored if it starts ignored (as in a background job):
        # install its KeyboardInterrupt handler, as an interactive session has it.
        code = ("import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
                "from snake_pin.sim import Trajectory; "
                "from snake_pin.viz.meshcat_view import view; "
                "view(Trajectory.load(sys.argv[1]), port=int(sys.argv[2]), fps=10)")
        cmd = [sys.executable, "-c", code, str(run_file), str(_free_port())]
    parent = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                              stderr=stderr)
    try:
        line = _readline(parent.stdout, 60.0)
        assert line.startswith("meshcat viewer: http://127.0.0.1:"), line
        port = int(line.split("http://127.0.0.1:")[1].split("/")[0])
        servers = [p for p in _tree(parent.pid)[1:]
                   if SERVER in Path(f"/proc/{p}/cmdline").read_bytes().decode()]
        assert len(servers) == 1, servers
    except BaseException:
        parent.kill()
        parent.wait()
        raise
    return parent, servers[0], port


def _free_port() -> int:
    """A port that is free on 127.0.0.1 now, outside the range meshcat searches (7000 up)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _kill_tree(parent: subprocess.Popen[bytes], server: int) -> None:
    parent.kill()
    parent.wait()
    if _alive(server):
        os.kill(server, signal.SIGKILL)


# --- 1. listeners ------------------------------------------------------------------------

def test_live_view_listens_on_ipv4_loopback_only(run_file: Path) -> None:
    """`snake-pin view`: every listening socket of its process tree is 127.0.0.1, web and ZMQ."""
    parent, server, port = _start_view(run_file, cli=True)
    try:
        listening = _listening(parent.pid)
        assert f"127.0.0.1:{port}" in listening  # the web port
        assert len(listening) == 2, listening  # and the ZMQ port, nothing else
        assert all(a.startswith("127.0.0.1:") for a in listening), listening
    finally:
        _kill_tree(parent, server)


def test_write_html_opens_no_socket_and_starts_no_process(
        run_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`write_html` binds, listens, connects nothing and spawns nothing; the page is complete."""
    import zmq

    from snake_pin.sim import Trajectory

    traj = Trajectory.load(run_file)

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("write_html touched the network or started a process")

    for owner, name in ((socket.socket, "bind"), (socket.socket, "listen"),
                        (socket.socket, "connect"), (zmq.Socket, "bind"),
                        (zmq.Socket, "connect"), (subprocess.Popen, "__init__"),
                        (os, "fork"), (os, "posix_spawn")):
        monkeypatch.setattr(owner, name, refuse)
    before = _socket_inodes(os.getpid())
    page = write_html(traj, tmp_path / "run.html", fps=10)
    assert _socket_inodes(os.getpid()) <= before
    text = page.read_text()
    assert "new MeshCat.Viewer" in text and "handle_command_bytearray" in text
    # the commands: objects for 10 links x 3 parts, head path, reference, animation
    assert text.count("fetch(\"data:application/octet-binary;base64,") > 30


# --- 2. the server dies with its parent ---------------------------------------------------

@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT, signal.SIGKILL],
                         ids=lambda s: signal.Signals(s).name)
def test_server_dies_with_its_parent(run_file: Path, sig: int) -> None:
    """A signal to the process running `view` ends its server and its listener within seconds."""
    parent, server, port = _start_view(run_file)
    try:
        parent.send_signal(sig)
        parent.wait(timeout=10)
        assert _wait_gone(server, port), f"server {server} or its port outlived its parent"
        if sig == signal.SIGINT:  # Ctrl-C is how a blocking view ends: normally
            assert parent.returncode == 0
    finally:
        _kill_tree(parent, server)


def test_view_reports_a_server_that_dies_on_its_own(run_file: Path, tmp_path: Path) -> None:
    """If the server dies while `view` waits, `view` raises SnakePinError saying so."""
    errors = tmp_path / "stderr.txt"
    with errors.open("wb") as sink:
        parent, server, _ = _start_view(run_file, stderr=sink)
    try:
        os.kill(server, signal.SIGKILL)
        assert parent.wait(timeout=10) == 1
        last = errors.read_text().strip().splitlines()[-1]
        assert last.startswith("snake_pin.exceptions.SnakePinError: meshcat server stopped"), last
    finally:
        _kill_tree(parent, server)


def test_failed_start_is_reported_and_reaped(monkeypatch: pytest.MonkeyPatch) -> None:
    """A server that cannot bind (port taken after the check) is a SnakePinError naming
    the cause, and leaves no process behind."""
    monkeypatch.setattr(meshcat_view, "_port_problem", lambda port: None)
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        with pytest.raises(SnakePinError, match=r"did not start: .*Address already in use"):
            start_server(busy.getsockname()[1])
    leftovers = [p for p in _tree(os.getpid())[1:]
                 if SERVER in Path(f"/proc/{p}/cmdline").read_bytes().decode()]
    assert not leftovers


def test_server_stops_at_end_of_stdin() -> None:
    """Closing the server's stdin pipe (what any death of the parent does) stops it."""
    proc = subprocess.Popen([sys.executable, "-m", SERVER, "--stdin-eof", "--quiet"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL)
    try:
        assert _readline(proc.stdout, 30.0).startswith("zmq_url=tcp://127.0.0.1:")
        assert _readline(proc.stdout, 5.0).startswith("web_url=http://127.0.0.1:")
        assert proc.poll() is None
        proc.stdin.close()  # type: ignore[union-attr]
        assert proc.wait(timeout=5) == 0
    finally:
        proc.kill()
        proc.wait()


def test_server_gets_sigterm_when_parent_is_killed() -> None:
    """With --parent, PR_SET_PDEATHSIG ends the server after SIGKILL of a parent even
    when its stdin is not the parent's pipe."""
    code = ("import os, subprocess, sys, time; "
            f"p = subprocess.Popen([sys.executable, '-m', '{SERVER}', '--quiet', "
            "'--parent', str(os.getpid())], stdin=subprocess.DEVNULL, "
            "stdout=subprocess.PIPE, stderr=subprocess.DEVNULL); "
            "p.stdout.readline(); p.stdout.readline(); print(p.pid, flush=True); time.sleep(60)")
    parent = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                              stderr=subprocess.DEVNULL)
    server = 0
    try:
        server = int(_readline(parent.stdout, 30.0))
        assert _alive(server)
        parent.kill()
        parent.wait()
        assert _wait_gone(server), "server survived SIGKILL of its parent"
    finally:
        _kill_tree(parent, server)


# --- 3. the server keeps serving ----------------------------------------------------------

def _http_get(port: int, path: str, host: str = "127.0.0.1") -> tuple[int, bytes]:
    with socket.create_connection(("127.0.0.1", port), timeout=5.0) as conn:
        conn.sendall(f"GET {path} HTTP/1.0\r\nHost: {host}:{port}\r\n\r\n".encode())
        data = b""
        while chunk := conn.recv(65536):
            data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    return int(head.split()[1]), body


def _upgrade(port: int, host: str = "127.0.0.1") -> bytes:
    """The first bytes of the answer to a WebSocket handshake on ``/``."""
    key = base64.b64encode(os.urandom(16)).decode()
    with socket.create_connection(("127.0.0.1", port), timeout=5.0) as conn:
        conn.sendall((f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
                      f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                      "Sec-WebSocket-Version: 13\r\n\r\n").encode())
        return conn.recv(12)


@pytest.fixture(scope="module")
def server() -> Iterator[tuple[subprocess.Popen[bytes], int]]:
    """A live server with a one-node scene (so every WebSocket is sent data); its web port."""
    proc, zmq_url, web_url = start_server()
    try:
        vis = meshcat_view._connect(zmq_url)
        vis["box"].set_transform(np.eye(4))
        meshcat_view._disconnect(vis)
        yield proc, int(web_url.split(":")[2].split("/")[0])
    finally:
        stop_server(proc)


def test_server_survives_connection_churn(server: tuple[subprocess.Popen[bytes], int]) -> None:
    """2,000 TCP connect/close cycles and 500 WebSocket handshakes, then the page is served."""
    proc, port = server
    for _ in range(2000):
        with socket.create_connection(("127.0.0.1", port), timeout=5.0):
            pass
    for _ in range(500):
        assert _upgrade(port) == b"HTTP/1.1 101"
    status, body = _http_get(port, "/static/")
    assert status == 200
    assert b"new MeshCat.Viewer" in body
    assert proc.poll() is None


def test_server_answers_local_host_names_only(server: tuple[subprocess.Popen[bytes], int]
                                              ) -> None:
    """Host 127.0.0.1 or localhost is served; any other Host (DNS rebinding) gets 404."""
    _, port = server
    assert _http_get(port, "/static/")[0] == 200
    assert _http_get(port, "/static/", host="localhost")[0] == 200
    assert _http_get(port, "/static/", host="attacker.example")[0] == 404
    assert _http_get(port, "/static/", host="127.0.0.1.attacker.example")[0] == 404
    assert _upgrade(port) == b"HTTP/1.1 101"
    assert _upgrade(port, host="attacker.example") == b"HTTP/1.1 404"
