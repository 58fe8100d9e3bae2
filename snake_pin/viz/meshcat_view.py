"""The browser viewer: a snake trajectory in meshcat, live or as one self-contained page.

Links are capsules (a cylinder with two spheres) in the body colour, the head link's
front sphere is orange, passive joints are blue spheres, and the reference path of the
head is a black line. :func:`write_html` uses meshcat's static export: the page embeds
meshcat's JavaScript, the scene and the animation, and opens with no server or network.
Servers bind to 127.0.0.1 only.
"""

from __future__ import annotations

import os
import re
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._io import atomic_write_bytes
from ..exceptions import ParameterError, SnakePinError

if TYPE_CHECKING:
    import meshcat

    from ..sim import Trajectory

__all__ = ["BODY_COLOR", "start_server", "view", "write_html"]

BODY_COLOR = 0x228B22
HEAD_COLOR = 0xD9541A
PASSIVE_COLOR = 0x1F4FD1
HOST = "127.0.0.1"


def port_is_free(port: int) -> bool:
    """Whether 127.0.0.1:port can be bound now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((HOST, port))
        except OSError:
            return False
    return True


def start_server(port: int | None = None, timeout: float = 20.0
                 ) -> tuple[subprocess.Popen[bytes], str, str]:
    """Start meshcat's bridge on 127.0.0.1 in a subprocess; return (process, zmq, web URL)."""
    if port is not None:
        if not 1 <= port <= 65535:
            raise ParameterError(f"port must lie in 1..65535, got {port}")
        if not port_is_free(port):
            raise ParameterError(f"port {port} on {HOST} is already in use")
    cmd = [sys.executable, "-u", "-m", "snake_pin.viz.meshcat_server"]
    if port is not None:
        cmd += ["--port", str(port)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True)
    urls: dict[str, str] = {}
    deadline = time.monotonic() + timeout
    while len(urls) < 2:
        line = proc.stdout.readline().decode() if proc.stdout else ""
        match = re.match(r"(zmq_url|web_url)=(\S+)", line.strip())
        if match:
            urls[match.group(1)] = match.group(2)
        elif proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            err = proc.stderr.read().decode().strip().splitlines() if proc.stderr else []
            raise SnakePinError("meshcat server did not start"
                                + (f": {err[-1]}" if err else ""))
    return proc, urls["zmq_url"], urls["web_url"]


def _connect(zmq_url: str) -> meshcat.Visualizer:
    """A Visualizer on our server, without meshcat's "open the visualizer" print."""
    import contextlib
    import io

    import meshcat

    with contextlib.redirect_stdout(io.StringIO()):
        return meshcat.Visualizer(zmq_url=zmq_url)


def _disconnect(vis: meshcat.Visualizer) -> None:
    # Visualizer.close() fails in meshcat 0.3.2 (its window has no close()); close the socket.
    vis.window.zmq_socket.close(linger=0)


def _link_geometry(vis: meshcat.Visualizer, traj: Trajectory) -> None:
    import meshcat.geometry as g

    params = traj.params
    radius = 0.15 * params.link_length
    length = params.link_length
    body = g.MeshLambertMaterial(color=BODY_COLOR)
    for i in range(1, params.n + 1):
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
    pose = np.eye(4)
    pose[:3, 3] = (x, y, z)
    return pose


def _link_transforms(snake, q: np.ndarray, z: float) -> list[np.ndarray]:
    import pinocchio as pin

    pin.forwardKinematics(snake.model, snake.data, q)
    out = []
    for i in range(1, snake.n + 1):
        pose = snake.data.oMi[i].homogeneous.copy()
        pose[2, 3] = z
        out.append(pose)
    return out


def _scene(vis: meshcat.Visualizer, traj: Trajectory, fps: float, reference: bool) -> None:
    import meshcat.animation as ma
    import meshcat.geometry as g

    from ..model import Snake

    snake = Snake(traj.params)
    z = 0.15 * traj.params.link_length
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
    points = np.vstack([head, traj.q[0, :2] + [[0.0, 0.0]]])
    low, high = points.min(axis=0) - traj.params.body_length / 2, points.max(axis=0) \
        + traj.params.body_length / 2
    scale = min(1.0, 3.0 / max(high - low))
    fit = np.diag([scale, scale, scale, 1.0]) @ _translation(*(-0.5 * (low + high)), 0.0)
    vis.set_transform(fit)
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
    """Write one self-contained HTML page animating ``traj`` (meshcat's static export)."""
    path = Path(path)
    if path.suffix.lower() not in (".html", ".htm"):
        raise ParameterError(f"HTML output must end in .html: {path}")
    if not path.parent.exists():
        raise ParameterError(f"output directory does not exist: {path.parent}")
    if not 1 <= fps <= 120:
        raise ParameterError(f"fps must lie in 1..120, got {fps}")
    proc, zmq_url, _ = start_server()
    try:
        vis = _connect(zmq_url)
        _scene(vis, traj, fps, reference)
        html = vis.static_html()
        _disconnect(vis)
    finally:
        proc.kill()
        proc.wait()
    atomic_write_bytes(path, html.encode())
    return path


def view(traj: Trajectory, *, port: int | None = None, fps: float = 30.0,
         block: bool = True) -> str:
    """Serve a live meshcat scene on 127.0.0.1 playing ``traj``; return its URL.

    With ``block`` the call waits until interrupted (Ctrl-C) and then stops the server.
    """
    proc, zmq_url, web_url = start_server(port)
    try:
        vis = _connect(zmq_url)
        _scene(vis, traj, fps, reference=True)
        print(f"meshcat viewer: {web_url} (Ctrl-C to stop)", flush=True)
        if block:
            while proc.poll() is None:
                time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        if block:
            proc.kill()
            proc.wait()
    return web_url
