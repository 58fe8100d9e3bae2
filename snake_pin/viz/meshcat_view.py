"""The browser viewer: a snake trajectory in meshcat, live or as one self-contained page.

Links are capsules in the body colour, the head link's front sphere is orange, passive
joints are blue spheres, the head's reference path a black line. :func:`write_html`
opens no network listener or connection and starts no process; :func:`view` serves the
scene from a loopback-only child process that dies with this one however it ends. How,
and why: :doc:`/promises` (The browser viewer).
"""

from __future__ import annotations

import atexit
import errno
import os
import re
import selectors
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._io import atomic_write_bytes
from ..exceptions import ParameterError, SnakePinError

if TYPE_CHECKING:
    import meshcat

    from ..trajectory import Trajectory

__all__ = ["view", "write_html"]

BODY_COLOR = 0x228B22
HEAD_COLOR = 0xD9541A
PASSIVE_COLOR = 0x1F4FD1
HOST = "127.0.0.1"


def _port_problem(port: int) -> str | None:
    """Why 127.0.0.1:port cannot be bound now (in words), or None when it can."""
    if not 1 <= port <= 65535:
        return f"port must lie in 1..65535, got {port}"
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((HOST, port))
        except PermissionError:
            return (f"port {port} on {HOST}: permission denied (ports below 1024 need "
                    "privileges; choose one from 1024 up)" if port < 1024
                    else f"port {port} on {HOST}: permission denied")
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                return f"port {port} on {HOST} is already in use"
            return f"port {port} on {HOST} cannot be bound: {exc.strerror or exc}"
    return None


def _read_urls(proc: subprocess.Popen[bytes], timeout: float) -> dict[str, str] | None:
    """The server's ``zmq_url`` and ``web_url`` lines, or None if it ends or stays silent."""
    assert proc.stdout is not None
    fd = proc.stdout.fileno()
    urls: dict[str, str] = {}
    pending = b""
    deadline = time.monotonic() + timeout
    with selectors.DefaultSelector() as selector:
        selector.register(fd, selectors.EVENT_READ)
        while len(urls) < 2:
            left = deadline - time.monotonic()
            if left <= 0 or not selector.select(left):
                return None
            chunk = os.read(fd, 4096)
            if not chunk:
                return None
            *lines, pending = (pending + chunk).split(b"\n")
            for line in lines:
                match = re.fullmatch(r"(zmq_url|web_url)=(\S+)", line.decode(errors="replace")
                                     .strip())
                if match:
                    urls[match.group(1)] = match.group(2)
    return urls


def start_server(port: int | None = None, timeout: float = 20.0
                 ) -> tuple[subprocess.Popen[bytes], str, str]:
    """Start meshcat's bridge on 127.0.0.1 (``port``, or the first free one from 7000) in a
    child process that stops when this one ends; return it, its ZMQ URL and its web URL."""
    if port is not None and (problem := _port_problem(port)) is not None:
        raise ParameterError(problem)
    cmd = [sys.executable, "-u", "-m", "snake_pin.viz.meshcat_server", "--stdin-eof", "--quiet"]
    if threading.current_thread() is threading.main_thread():
        # PR_SET_PDEATHSIG follows the thread that started the child: only from the main one
        cmd += ["--parent", str(os.getpid())]
    if port is not None:
        cmd += ["--port", str(port)]
    # stderr goes to a file, never to a pipe: only the start-up messages land there.
    with tempfile.TemporaryFile() as errors:
        proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=errors, start_new_session=True)
        try:
            urls = _read_urls(proc, timeout)
        except BaseException:
            stop_server(proc)
            raise
        finally:
            assert proc.stdout is not None
            proc.stdout.close()  # the server sends its stdout to /dev/null after the URLs
        if urls is None:
            stop_server(proc)
            errors.seek(0)
            lines = errors.read().decode(errors="replace").strip().splitlines()
            raise SnakePinError("meshcat server did not start"
                                + (f": {lines[-1]}" if lines else f" within {timeout:g} s"))
    return proc, urls["zmq_url"], urls["web_url"]


def stop_server(proc: subprocess.Popen[bytes]) -> None:
    """Stop a server from :func:`start_server` and reap it (harmless if it already ended):
    end of file on its stdin, then SIGTERM, and SIGKILL after 5 s."""
    if proc.stdin is not None and not proc.stdin.closed:
        proc.stdin.close()  # end of file: the server leaves its loop
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            proc.kill()
    proc.wait()


def _connect(zmq_url: str) -> meshcat.Visualizer:
    """A Visualizer on our server, without meshcat's "open the visualizer" print."""
    import contextlib
    import io

    import meshcat

    with contextlib.redirect_stdout(io.StringIO()):
        return meshcat.Visualizer(zmq_url=zmq_url)


def _disconnect(vis: meshcat.Visualizer) -> None:
    """Close the Visualizer's socket (its ``close()`` fails in meshcat 0.3.2)."""
    vis.window.zmq_socket.close(linger=0)


class _Requests:
    """The window's side of the in-process channel: a request goes straight to the bridge."""

    def __init__(self, bridge: Any) -> None:
        self.bridge = bridge

    def send_multipart(self, frames: list[bytes]) -> None:
        self.bridge.handle_zmq(frames)

    def send(self, data: bytes) -> None:
        self.bridge.handle_zmq([data])

    def recv(self) -> bytes:
        reply, self.bridge.last = self.bridge.last, None
        if reply is None:
            raise SnakePinError("meshcat's bridge sent no reply")
        return reply


def offline_visualizer() -> meshcat.Visualizer:
    """Return a :class:`meshcat.Visualizer` with no server, socket or process behind it: its
    window passes every command to meshcat's own bridge code, run here on an in-memory scene
    tree, so that ``static_html()`` returns meshcat's static export as a live server would.
    """
    import meshcat
    from meshcat.servers.tree import SceneTree
    from meshcat.servers.zmqserver import ZMQWebSocketBridge
    from meshcat.visualizer import ViewerWindow

    class OfflineBridge(ZMQWebSocketBridge):
        # ZMQWebSocketBridge.__init__ binds the web and ZMQ ports; handle_zmq needs none
        # of that, only the scene tree, the (empty) WebSocket pool and a reply channel:
        # itself, keeping the last reply it sends.
        def __init__(self) -> None:
            self.host = HOST
            self.web_url = ""
            self.websocket_pool: set[object] = set()
            self.tree = SceneTree()
            self.zmq_socket = self
            self.last: bytes | None = None

        def send(self, data: bytes) -> None:
            self.last = data

    class OfflineWindow(ViewerWindow):
        # ViewerWindow.__init__ connects (or starts) a server; send/get_scene need a socket.
        def __init__(self) -> None:
            self.server_proc = None
            self.zmq_url = ""
            self.web_url = ""
            self.zmq_socket = _Requests(OfflineBridge())

    return meshcat.Visualizer(window=OfflineWindow())


def _link_geometry(vis: meshcat.Visualizer, traj: Trajectory) -> None:
    """The links' shapes: capsules, the head's orange sphere, the passive joints' blue ones."""
    import meshcat.geometry as g

    params = traj.params
    lengths = params.link_lengths
    body = g.MeshLambertMaterial(color=BODY_COLOR)
    for i in range(1, params.n + 1):
        length = float(lengths[i - 1])  # each link drawn at its own length
        radius = 0.15 * length
        node = vis["snake"][f"link_{i}"]
        # meshcat's cylinder axis is y: turn it onto the link's x axis, centred at x = l.
        turn = np.array([[0.0, -1.0, 0.0, 0.5 * length], [1.0, 0.0, 0.0, 0.0],
                         [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
        node["body"].set_object(g.Cylinder(length, radius), body)
        node["body"].set_transform(turn)
        for end, x in (("front", 0.0), ("back", length)):
            color = HEAD_COLOR if (i == 1 and end == "front") else BODY_COLOR
            node[end].set_object(g.Sphere(radius * (1.15 if color == HEAD_COLOR else 1.0)),
                                 g.MeshLambertMaterial(color=color))
            node[end].set_transform(_translation(x, 0.0, 0.0))
        if i - 1 in params.passive:  # joint i - 1 sits at this link's front end
            node["passive"].set_object(g.Sphere(radius * 1.35),
                                       g.MeshLambertMaterial(color=PASSIVE_COLOR))


def _translation(x: float, y: float, z: float) -> np.ndarray:
    """The homogeneous transform of a translation."""
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose


def _link_transforms(snake, q: np.ndarray, z: float) -> list[np.ndarray]:
    """The links' poses at q, lifted to height z."""
    import pinocchio as pin

    pin.forwardKinematics(snake.model, snake.data, q)
    out = []
    for joint in snake.link_joints:
        pose = snake.data.oMi[int(joint)].homogeneous.copy()
        pose[2, 3] = z
        out.append(pose)
    return out


def _scene(vis: meshcat.Visualizer, traj: Trajectory, fps: float, reference: bool) -> None:
    """The whole scene of ``traj``: robot, head path, reference, view and animation."""
    import meshcat.animation as ma
    import meshcat.geometry as g

    from ..model import Snake

    snake = Snake(traj.params)
    z = 0.15 * float(traj.params.link_lengths.max())
    vis.delete()
    vis["/Axes"].set_property("visible", False)
    _link_geometry(vis, traj)
    head = traj.q[:, :2]
    if reference and traj.t_end > 0:
        ref = np.array([[0.0, 0.1 * traj.t_end], [0.0, 0.0], [0.0, 0.0]])
        vis["reference"].set_object(g.Line(g.PointsGeometry(ref),
                                           g.LineBasicMaterial(color=0x000000, linewidth=2)))
    path = np.vstack([head.T, np.zeros(len(head))])[:, :: max(1, len(head) // 2000)]
    vis["head_path"].set_object(g.Line(g.PointsGeometry(path),
                                       g.LineBasicMaterial(color=HEAD_COLOR)))
    # Fit the run into a top-down view of the origin: centre it and scale it to about 3 m
    # (moving meshcat's camera target is not kept by its orbit controls in a static page).
    margin = 0.5 * traj.params.body_length
    low, high = head.min(axis=0) - margin, head.max(axis=0) + margin
    scale = min(1.0, 3.0 / max(high - low))
    centre_x, centre_y = 0.5 * (low + high)
    vis.set_transform(np.diag([scale, scale, scale, 1.0])
                      @ _translation(-float(centre_x), -float(centre_y), 0.0))
    # camera straight above the origin (meshcat's camera frame is y-up)
    vis["/Cameras/default/rotated/<object>"].set_property("position", [0.0, 3.0, 0.01])
    for i, pose in enumerate(_link_transforms(snake, traj.q[0], z), start=1):
        vis["snake"][f"link_{i}"].set_transform(pose)
    if len(traj) < 2:
        return
    animation = ma.Animation(default_framerate=fps)
    times = np.arange(0.0, traj.t_end + 1e-9, 1.0 / fps)
    indices = np.minimum(np.searchsorted(traj.t, times), len(traj) - 1)
    for frame, k in enumerate(indices):
        with animation.at_frame(vis, frame) as at:
            for i, pose in enumerate(_link_transforms(snake, traj.q[k], z), start=1):
                at["snake"][f"link_{i}"].set_transform(pose)
    vis.set_animation(animation, play=True, repetitions=1000)


def write_html(traj: Trajectory, path: str | os.PathLike[str], *, fps: float = 20.0,
               reference: bool = True) -> Path:
    """Write one self-contained HTML page animating ``traj``, with no server and no socket.

    Parameters
    ----------
    traj : Trajectory
        The trajectory to animate.
    path : str or os.PathLike
        The ``.html`` or ``.htm`` page, in an existing folder; written whole or not at all.
    fps : float, optional
        Animation frames per second of simulated time, 1..120.
    reference : bool, optional
        Draw the reference line of the head (the x axis).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ParameterError
        A bad ``path`` or ``fps``.
    """
    path = Path(path)
    if path.suffix.lower() not in (".html", ".htm"):
        raise ParameterError(f"HTML output must end in .html: {path}")
    if not path.parent.exists():
        raise ParameterError(f"output directory does not exist: {path.parent}")
    _check_fps(fps)
    vis = offline_visualizer()
    _scene(vis, traj, fps, reference)
    atomic_write_bytes(path, vis.static_html().encode())
    return path


def _check_fps(fps: float) -> None:
    """ParameterError unless 1 <= fps <= 120."""
    if not 1 <= fps <= 120:
        raise ParameterError(f"fps must lie in 1..120, got {fps}")


def view(traj: Trajectory, *, port: int | None = None, fps: float = 30.0,
         block: bool = True) -> str:
    """Serve a live meshcat scene on 127.0.0.1 playing ``traj``; return its URL.

    Parameters
    ----------
    traj : Trajectory
        The trajectory to play.
    port : int or None, optional
        The web port on 127.0.0.1 (None: the first free one from 7000).
    fps : float, optional
        Animation frames per second of simulated time, 1..120.
    block : bool, optional
        Wait until Ctrl-C, then stop the server; without it the server lives until this
        process ends.

    Returns
    -------
    str
        The viewer's URL, ``http://127.0.0.1:PORT/static/``.

    Raises
    ------
    ParameterError
        A bad ``fps``, or ``port`` out of range or in use.
    SnakePinError
        The server does not start, or stops on its own while ``block`` waits.
    """
    _check_fps(fps)
    proc, zmq_url, web_url = start_server(port)
    keep = False
    try:
        vis = _connect(zmq_url)
        try:
            _scene(vis, traj, fps, reference=True)
        finally:
            _disconnect(vis)
        announce = f"meshcat viewer: {web_url} (Ctrl-C to stop)"
        if not block:
            print(announce, flush=True)
            keep = True
            atexit.register(stop_server, proc)
            return web_url
        try:  # from the announcement on, Ctrl-C is the normal way to stop
            print(announce, flush=True)
            # wait without reaping: waitid, unlike Popen.wait, holds no lock that a
            # KeyboardInterrupt could leave taken (stop_server would then hang)
            os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOWAIT)
        except KeyboardInterrupt:
            return web_url
        proc.wait()
        raise SnakePinError(f"meshcat server stopped on its own (exit status {proc.returncode})")
    finally:
        if not keep:
            stop_server(proc)
