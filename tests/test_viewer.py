"""Browser viewer: the static meshcat page renders the snake in headless Chromium."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest

from snake_pin import OpenLoop, ParameterError, Snake, SnakeParams, simulate
from snake_pin.control import LyapunovController
from snake_pin.experiments.tracking import initial_state, tracking_params
from snake_pin.viz import meshcat_view
from snake_pin.viz.meshcat_view import BODY_COLOR, start_server, stop_server, write_html


def _browser() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    if os.environ.get("CI"):
        pytest.fail("no Chromium on the CI machine: .ci/run must install Debian's chromium")
    pytest.skip("Chromium is not installed (CI installs it)")


@pytest.fixture(scope="module")
def page(tmp_path_factory: pytest.TempPathFactory) -> Path:
    params = tracking_params(passive=(5,))
    snake = Snake(params)
    traj = simulate(snake, LyapunovController(snake), initial_state(params), 2.0)
    return write_html(traj, tmp_path_factory.mktemp("view") / "run.html", fps=10)


def test_page_is_self_contained(page: Path) -> None:
    """The page needs no server or network: no http(s) resource is referenced."""
    text = page.read_text()
    assert "MeshCat.Viewer" in text
    for marker in ('src="http', "src='http", 'href="http', "import('http"):
        assert marker not in text


def test_snake_is_drawn_in_headless_chromium(page: Path, tmp_path: Path) -> None:
    """A screenshot of the page is not blank and shows the snake's body colour."""
    shot = tmp_path / "shot.png"
    cmd = [_browser(), "--headless", "--no-sandbox", "--disable-gpu-sandbox", "--disable-quic",
           "--no-first-run", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}", "--use-angle=swiftshader",
           "--enable-unsafe-swiftshader", "--window-size=900,600", "--virtual-time-budget=6000",
           f"--screenshot={shot}", page.resolve().as_uri()]
    subprocess.run(cmd, check=False, capture_output=True, timeout=120)
    assert shot.exists(), "Chromium wrote no screenshot"
    image = mpimg.imread(shot)[..., :3]
    assert image.std() > 0.05  # not a blank page
    body = np.array([(BODY_COLOR >> 16) & 255, (BODY_COLOR >> 8) & 255, BODY_COLOR & 255]) / 255
    close = np.linalg.norm(image - body, axis=2) < 0.15
    green = (image[..., 1] > image[..., 0] + 0.15) & (image[..., 1] > image[..., 2] + 0.15)
    assert (close | green).sum() > 30, "no pixel of the snake's colour in the screenshot"


def test_html_refuses_bad_paths(page: Path, tmp_path: Path) -> None:
    """Wrong suffix or a missing folder: ParameterError, nothing written."""
    from snake_pin import Trajectory

    traj = Trajectory(t=np.zeros(1), q=np.zeros((1, 12)), dq=np.zeros((1, 12)),
                      tau=np.zeros((1, 9)), params=SnakeParams.table1())
    with pytest.raises(ParameterError):
        write_html(traj, tmp_path / "page.txt")
    with pytest.raises(ParameterError):
        write_html(traj, tmp_path / "missing" / "page.html")


def test_port_in_use_is_refused() -> None:
    """Asking the viewer for a busy port on 127.0.0.1 is a clear ParameterError."""
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        with pytest.raises(ParameterError, match="already in use"):
            start_server(busy.getsockname()[1])


def test_privileged_port_is_refused_as_permission_denied(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch,
                                                        capsys: pytest.CaptureFixture[str]
                                                        ) -> None:
    """A port the user may not bind (below 1024 without privileges: EACCES) is refused as
    permission denied, not as "already in use": by start_server and by `view --port 80`
    (one line, status 2, no server started)."""
    import errno

    from snake_pin.cli import main
    from snake_pin.sim import Trajectory

    def denied(self: socket.socket, address: object) -> None:
        raise PermissionError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(socket.socket, "bind", denied)
    monkeypatch.setattr(meshcat_view.subprocess, "Popen", None)  # no server may start
    with pytest.raises(ParameterError, match="permission denied") as info:
        start_server(80)
    assert "below 1024" in str(info.value) and "in use" not in str(info.value)
    traj = Trajectory(t=np.zeros(1), q=np.zeros((1, 12)), dq=np.zeros((1, 12)),
                      tau=np.zeros((1, 9)), params=SnakeParams.table1())
    npz, _ = traj.save(tmp_path / "run")
    assert main(["view", str(npz), "--port", "80"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1
    assert "port 80" in err and "permission denied" in err and "in use" not in err


def test_offline_page_is_what_a_live_server_returns(monkeypatch: pytest.MonkeyPatch) -> None:
    """The same commands give, byte for byte, the page meshcat's live bridge returns
    (objects replaced, subtrees deleted, properties, transforms, the animation)."""
    import itertools
    import uuid

    import meshcat.geometry as g

    snake = Snake(SnakeParams.table1())
    x0 = np.r_[0.0, 0.0, 0.0, np.full(9, np.pi / 6), np.zeros(12)]
    traj = simulate(snake, OpenLoop(lambda t: 0.01 * np.sin(t + np.arange(9))), x0, 0.3)
    shift = np.eye(4)
    shift[:3, 3] = (0.5, -0.25, 0.1)

    def page(vis: object) -> str:
        counter = itertools.count()  # meshcat names objects by uuid1: make them repeatable
        monkeypatch.setattr(uuid, "uuid1", lambda: uuid.UUID(int=next(counter)))
        meshcat_view._scene(vis, traj, 10.0, reference=True)
        vis["extra/a"].set_object(g.Box([0.1, 0.2, 0.3]))
        vis["extra/a"].set_property("visible", False)
        vis["extra/a"].set_object(g.Sphere(0.05))  # replaces the box and drops its property
        vis["extra/b"].set_object(g.Box([0.1, 0.1, 0.1]))
        vis["extra/b/c"].set_transform(shift)
        vis["extra/b"].delete()  # the whole subtree goes
        vis["extra"].set_transform(shift)
        vis["extra"].set_transform(shift.T @ shift)  # the later transform wins
        return vis.static_html()

    meshcat_view._scene(meshcat_view.offline_visualizer(), traj, 10.0, True)  # import-time uuids
    offline = page(meshcat_view.offline_visualizer())
    proc, zmq_url, _ = start_server()
    try:
        vis = meshcat_view._connect(zmq_url)
        live = page(vis)
        meshcat_view._disconnect(vis)
    finally:
        stop_server(proc)
    assert offline.count("handle_command_bytearray") > 40
    assert offline == live


def test_links_are_placed_at_their_joints_for_a_per_link_robot() -> None:
    """Each link's frame is drawn at its front joint (per-link lengths, root-chain model)."""
    from snake_pin import Snake
    from snake_pin.viz.meshcat_view import _link_transforms

    from .conftest import heterogeneous_params

    rng = np.random.default_rng(5)
    snake = Snake(heterogeneous_params(rng, 6))
    q = np.r_[0.3, -0.2, 0.7, rng.uniform(-1, 1, 5)]
    poses = _link_transforms(snake, q, 0.02)
    points = snake.joint_points(q)
    assert np.allclose([p[:2, 3] for p in poses], points[:-1], atol=1e-12)
    assert np.allclose([np.arctan2(p[1, 0], p[0, 0]) for p in poses],
                       snake.link_poses(q)[:, 2], atol=1e-12)
