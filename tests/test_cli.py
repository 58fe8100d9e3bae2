"""Command line: one JSON object with --json, one error line and status 2 on bad input."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from snake_pin.cli import main, parse_angle


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("argv", [
    ["generate", "--passive", "12", "-o", "x.urdf"],
    ["generate", "-o", "robot.txt"],
    ["generate", "--robot", "cobra", "-o", "x.urdf"],
    ["info", "--n", "1"],
    ["info", "--cx", "-1"],
    ["info", "--cy", "nan"],
    ["reproduce", "--only", "nothing", "-o", "out"],
    ["manip", "--shape", "arc"],
    ["manip", "--shape", "arc", "--phi0", "pi/zero"],
    ["manip", "--shape", "q", "--q", "0,0,0,1"],
    ["manip", "--free-joint", "12"],
    ["manip", "--n", "3"],
    ["sweep", "spiral", "-o", "out"],
    ["sweep", "arc", "--points", "1", "-o", "out"],
    ["sweep", "arc", "--range", "0.5", "-0.3", "-o", "out"],
    ["sweep", "arc", "--range", "0.2", "0.2", "-o", "out"],
    ["sweep", "ts", "--range", "nan", "1", "-o", "out"],
    ["sweep", "ts", "--range", "0", "inf", "-o", "out"],
    ["sweep", "alpha", "--range", "0", "-o", "out"],
    ["simulate", "--controller", "lyapunov", "--t-final", "2", "--error-window", "2",
     "-o", "out"],
    ["simulate", "--controller", "pfl", "--error-window", "-1", "-o", "out"],
    ["engine", "--t-final", "1", "--error-window", "5", "-o", "out"],
    ["bench-control", "--quick", "--error-window", "12", "-o", "out"],
    ["singular", "--starts", "0"],
    ["singular", "--bound", "7"],
    ["engine", "--cone", "square", "-o", "out"],
    ["engine", "--mu", "-1", "-o", "out"],
    ["no-such-command"],
    [],
])
def test_bad_input_is_one_line_and_status_2(capsys: pytest.CaptureFixture[str],
                                            argv: list[str], tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """Each wrong argument gives exit status 2 and exactly one line on stderr."""
    monkeypatch.chdir(tmp_path)
    code, out, err = _run(capsys, *argv)
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and err.startswith("snake-pin")
    assert out == ""


def test_info_json(capsys: pytest.CaptureFixture[str]) -> None:
    """info --json prints one object with nq, nv, total mass and body length."""
    code, out, _ = _run(capsys, "info", "--robot", "engine", "--json")
    data = json.loads(out)
    assert code == 0 and data["nq"] == data["nv"] == 10
    assert data["total_mass"] == pytest.approx(8 * 0.417)
    assert data["body_length"] == pytest.approx(8 * 0.176)


def test_generate_writes_urdf(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """generate --n 6 --passive 2 writes a URDF with that joint marked passive."""
    from snake_pin.urdf import passive_joints

    out_file = tmp_path / "six.urdf"
    code, _, _ = _run(capsys, "generate", "--n", "6", "--passive", "2", "-o", str(out_file))
    assert code == 0 and passive_joints(out_file.read_text()) == (2,)


def test_reproduce_writes_report(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """reproduce --only robot --verbose logs the stage's start and end, writes index.html
    (figures embedded) and summary.json, and leaves no staging folder."""
    code, _, err = _run(capsys, "reproduce", "--only", "robot", "--verbose", "-o", str(tmp_path))
    lines = err.splitlines()
    assert code == 0 and len(lines) == 2 and "[1/1] robot ..." in lines[0]
    assert "[1/1] robot done in" in lines[1]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    html = (tmp_path / "index.html").read_text()
    assert "data:image/png;base64," in html
    assert json.loads((tmp_path / "summary.json").read_text())["robot"]["nq"] == 12


@pytest.mark.parametrize(("text", "value"), [("pi/5", math.pi / 5), ("-pi/3", -math.pi / 3),
                                             ("2*pi/3", 2 * math.pi / 3), ("0.25", 0.25),
                                             ("pi", math.pi), ("1e-2", 0.01)])
def test_parse_angle(text: str, value: float) -> None:
    """Angles accept plain radians and multiples of pi."""
    assert parse_angle(text) == pytest.approx(value)


def test_manip_json_matches_library(capsys: pytest.CaptureFixture[str]) -> None:
    """manip --json prints exactly {D, R, sigma, lambda} equal to manipulability()."""
    import numpy as np

    from snake_pin import Snake, arc
    from snake_pin.manipulability import manipulability

    code, out, _ = _run(capsys, "manip", "--shape", "arc", "--phi0", "pi/10", "--json")
    data = json.loads(out)
    assert code == 0 and set(data) == {"D", "R", "sigma", "lambda"}
    ref = manipulability(Snake(), arc(10, math.pi / 10))
    assert data["R"] == pytest.approx(ref.R) and np.allclose(data["sigma"], ref.sigma)


def test_manip_full_configuration(capsys: pytest.CaptureFixture[str]) -> None:
    """--q takes the full configuration; the straight posture gives R = 0."""
    code, out, _ = _run(capsys, "manip", "--shape", "q", "--q", "1,2,pi/3" + ",0" * 9, "--json")
    assert code == 0 and json.loads(out)["R"] == pytest.approx(0.0, abs=1e-14)


def test_sweep_and_singular_json(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """sweep writes its files and names the zero; singular prints postures and R."""
    code, out, _ = _run(capsys, "sweep", "alpha", "--points", "11", "-o", str(tmp_path), "--json")
    data = json.loads(out)
    assert code == 0 and data["zeros"] == [0.0] and Path(data["files"]["png"]).exists()
    code, out, _ = _run(capsys, "singular", "--starts", "3", "--json")
    data = json.loads(out)
    assert code == 0 and len(data["postures"]) == len(data["R"])


def test_simulate_pfl_json(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """simulate --controller pfl --json prints the VI.1 summary and writes the run."""
    code, out, _ = _run(capsys, "simulate", "--controller", "pfl", "--t-final", "1",
                        "-o", str(tmp_path), "--json")
    data = json.loads(out)
    assert code == 0
    for key in ("t_end", "diverged", "breakdown_time", "t_R_min", "R_min", "g_drift_max",
                "head_error_max"):
        assert key in data
    assert data["t_end"] == pytest.approx(1.0) and data["g_drift_max"] < 1e-8
    assert (tmp_path / "pfl.npz").exists() and (tmp_path / "pfl_torque.png").exists()


@pytest.mark.parametrize("argv", [["simulate", "--controller", "pfl", "--passive", "5", "-o"],
                                  ["simulate", "--controller", "pid", "-o"],
                                  ["simulate", "--controller", "pfl", "--t-final", "-2", "-o"]])
def test_simulate_bad_input(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                            argv: list[str]) -> None:
    """Bad simulate arguments: one line, status 2."""
    code, _, err = _run(capsys, *argv, str(tmp_path))
    assert code == 2 and len(err.strip().splitlines()) == 1


def test_simulate_lyapunov_json(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """simulate --controller lyapunov --passive 5 --json prints the VI.2 summary keys."""
    code, out, _ = _run(capsys, "simulate", "--controller", "lyapunov", "--passive", "5",
                        "--t-final", "11", "-o", str(tmp_path), "--json")
    data = json.loads(out)
    assert code == 0 and data["passive"] == [5] and data["c_y"] == 25.0
    for key in ("t_end", "diverged", "rms_head_error", "max_head_error", "R_min", "D_min",
                "body_length"):
        assert key in data
    assert data["R_min"] > 0 and data["body_length"] == pytest.approx(1.2)


@pytest.mark.parametrize("passive", ["0", "10"])
def test_simulate_passive_out_of_range(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                       passive: str) -> None:
    """A passive joint index out of range is one line, status 2."""
    code, _, err = _run(capsys, "simulate", "--controller", "lyapunov", "--passive", passive,
                        "-o", str(tmp_path))
    assert code == 2 and len(err.strip().splitlines()) == 1


def test_view_errors(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """view: a missing file, another robot's run and a busy port are one line, status 2."""
    import socket

    import numpy as np

    from snake_pin import SnakeParams, Trajectory

    code, _, err = _run(capsys, "view", str(tmp_path / "nothing.npz"))
    assert code == 2 and "no such snake_pin trajectory" in err
    assert len(err.strip().splitlines()) == 1
    traj = Trajectory(t=np.zeros(1), q=np.zeros((1, 10)), dq=np.zeros((1, 10)),
                      tau=np.zeros((1, 7)), params=SnakeParams.engine())
    npz, _ = traj.save(tmp_path / "engine_run")
    code, _, err = _run(capsys, "view", str(npz), "--robot", "table1", "--html",
                        str(tmp_path / "x.html"))
    assert code == 2 and "engine" in err and len(err.strip().splitlines()) == 1
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        code, _, err = _run(capsys, "view", str(npz), "--port", str(busy.getsockname()[1]))
    assert code == 2 and "already in use" in err


def test_view_html(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """view --html writes the self-contained page."""
    code, out, _ = _run(capsys, "simulate", "--controller", "pfl", "--t-final", "0.5",
                        "-o", str(tmp_path), "--json")
    assert code == 0
    code, out, _ = _run(capsys, "view", str(tmp_path / "pfl.npz"), "--html",
                        str(tmp_path / "pfl.html"), "--json")
    assert code == 0 and json.loads(out)["html"].endswith("pfl.html")
    assert (tmp_path / "pfl.html").stat().st_size > 100_000


def test_engine_json_with_pyramidal_cones(capsys: pytest.CaptureFixture[str],
                                          tmp_path: Path) -> None:
    """engine --cone pyramidal --json: one object, the short run and its identified friction."""
    code, out, _ = _run(capsys, "engine", "--cone", "pyramidal", "--t-final", "0.3",
                        "-o", str(tmp_path), "--json")
    data = json.loads(out)
    assert code == 0 and data["t_end"] == pytest.approx(0.3) and not data["diverged"]
    assert data["friction"]["c_y"] > 100 * data["friction"]["c_x"]
    assert (tmp_path / "engine.npz").is_file()


def test_engine_mpc_keeps_its_bound(capsys: pytest.CaptureFixture[str],
                                    tmp_path: Path) -> None:
    """engine --law mpc --torque-bound 3: the MPC on MuJoCo, its peak torque within 3 N m and
    the saved torques' own maximum; a bound above the motors' or an MPC option without
    --law mpc is one line, exit 2, no folder."""
    import numpy as np

    from snake_pin.sim import Trajectory

    code, out, _ = _run(capsys, "engine", "--law", "mpc", "--torque-bound", "3",
                        "--t-final", "0.3", "-o", str(tmp_path / "run"), "--json")
    data = json.loads(out)
    traj = Trajectory.load(tmp_path / "run" / "engine.npz")
    assert code == 0 and data["controller"] == "mpc"
    assert data["torque_max"] == pytest.approx(float(np.abs(traj.tau).max()), abs=1e-12)
    assert data["torque_max"] <= 3.0 + 1e-9
    for argv in (["--law", "mpc", "--torque-bound", "20"], ["--horizon", "1"]):
        code, _, err = _run(capsys, "engine", *argv, "-o", str(tmp_path / "bad"))
        assert code == 2 and len(err.strip().splitlines()) == 1
        assert not (tmp_path / "bad").exists()


def _window_rms(npz: Path, start: float) -> tuple[float, float]:
    """RMS and max of the saved run's head error over t >= start."""
    import numpy as np

    from snake_pin.sim import Trajectory

    traj = Trajectory.load(npz)
    error = traj.signals["head_error"][traj.t >= start]
    return float(np.sqrt(np.mean(error**2))), float(error.max())


@pytest.mark.parametrize(("controller", "extra", "window"), [
    ("lyapunov", [], 1.0),                          # default: half of a 2 s run
    ("lyapunov", ["--error-window", "0.5"], 0.5),
    ("pfl", [], 1.0),
    ("pfl", ["--error-window", "1.5"], 1.5),
])
def test_short_runs_judge_head_errors_over_the_error_window(
        capsys: pytest.CaptureFixture[str], tmp_path: Path, controller: str,
        extra: list[str], window: float) -> None:
    """A 2 s run (shorter than the 10 s window) reports head errors over t >= error_window:
    half the run by default, --error-window when given; the numbers are the saved head
    error's RMS and max over that window, also in % of the body; the window is in the
    summary and the text."""
    code, out, err = _run(capsys, "simulate", "--controller", controller, "--t-final", "2",
                          *extra, "-o", str(tmp_path), "--json")
    data = json.loads(out)
    assert code == 0 and err == "" and data["error_window"] == window
    rms, peak = _window_rms(tmp_path / f"{controller}.npz", window)
    assert data["rms_head_error"] == pytest.approx(rms, rel=1e-12)
    assert data["max_head_error"] == pytest.approx(peak, rel=1e-12)
    assert data["rms_head_error_pct"] == pytest.approx(100 * rms / 1.2, rel=1e-12)
    assert data["max_head_error_pct"] == pytest.approx(100 * peak / 1.2, rel=1e-12)
    code, out, _ = _run(capsys, "simulate", "--controller", controller, "--t-final", "2",
                        *extra, "-o", str(tmp_path))
    assert code == 0 and f"error_window: {window:g}\n" in out


@pytest.mark.parametrize("command", ["simulate", "engine", "bench-control"])
def test_help_states_the_error_window_and_its_default(capsys: pytest.CaptureFixture[str],
                                                      command: str) -> None:
    """Every command that reports head errors takes --error-window and its help states the
    default (10 s, or the second half of shorter runs)."""
    code, out, _ = _run(capsys, command, "--help")
    text = " ".join(out.split())
    assert code == 0 and "--error-window SECONDS" in text
    assert "default: 10 s, or the second half of" in text


def test_an_empty_error_window_is_said_in_the_note(capsys: pytest.CaptureFixture[str],
                                                   tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """A run that stops before its error window starts: the metrics are null and the
    stderr note says the window is empty (never silently null)."""
    import numpy as np

    from snake_pin.control import LyapunovController

    step = LyapunovController.__call__

    def fails_late(self: LyapunovController, x: np.ndarray, t: float) -> np.ndarray:
        return np.full(self.snake.n - 1, np.nan) if t >= 0.2 else step(self, x, t)

    monkeypatch.setattr(LyapunovController, "__call__", fails_late)
    code, out, err = _run(capsys, "simulate", "--controller", "lyapunov", "--t-final", "2",
                          "-o", str(tmp_path), "--json")
    data = json.loads(out)
    assert code == 3 and data["status"] == "failed" and data["t_end"] < 1.0
    assert data["error_window"] == 1.0 and data["rms_head_error"] is None
    line = err.strip()
    assert len(line.splitlines()) == 1
    assert "no samples in the head-error window t >= 1 s" in line and "null" in line


# ---------------------------------------------------------------- robot files
SMALL_ROBOT = """\
name = "small_camera_snake"
n = 6

[links]
link_length = [0.26, 0.176, 0.176, 0.176, 0.176, 0.176]
mass = [0.75, 0.417, 0.417, 0.417, 0.417, 0.667]
inertia = [4.286e-3, 1.2e-3, 1.2e-3, 1.2e-3, 1.2e-3, 1.333e-3]
com_offset = [0.106, 0.088, 0.088, 0.088, 0.088, 0.088]

[friction]
c_x = [0.9, 0.5, 0.5, 0.5, 0.5, 0.8]
c_y = [9.0, 5.0, 5.0, 5.0, 5.0, 8.0]
c_theta = 1e-4
"""
Q6 = [0.1, -0.2, 0.3, 0.4, -0.3, 0.5, 0.2, -0.6]


@pytest.fixture
def robot_file(tmp_path: Path) -> Path:
    path = tmp_path / "small.toml"
    path.write_text(SMALL_ROBOT)
    return path


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    """`snake-pin --version` prints `snake-pin <snake_pin.__version__>` and exits 0."""
    import snake_pin

    code, out, _ = _run(capsys, "--version")
    assert code == 0 and out == f"snake-pin {snake_pin.__version__}\n"


def test_info_json_of_a_robot_file_lists_per_link_values(capsys: pytest.CaptureFixture[str]
                                                         ) -> None:
    """info --robot camera_head_snake.toml --json: per-link fields as lists (head first),
    CM offsets, total mass and body length of that robot."""
    from snake_pin.robot_file import load_robot

    params = load_robot("camera_head_snake.toml")
    code, out, _ = _run(capsys, "info", "--robot", "camera_head_snake.toml", "--json")
    data = json.loads(out)
    assert code == 0 and data["name"] == "camera_head_snake" and data["n"] == 10
    for key, values in (("link_length", params.link_lengths), ("mass", params.masses),
                        ("c_y", params.per_link("c_y")), ("com_offsets", params.com_offsets)):
        assert data[key] == values.tolist(), key
    assert data["total_mass"] == pytest.approx(params.masses.sum())
    assert data["body_length"] == pytest.approx(params.link_lengths.sum())
    assert "half_length" not in data


def test_generate_writes_the_urdf_of_a_robot_file(capsys: pytest.CaptureFixture[str],
                                                  robot_file: Path, tmp_path: Path) -> None:
    """generate --robot FILE.toml writes a URDF that reads back as the same robot, and
    --robot FILE.urdf then gives the same D and R as the TOML file."""
    from snake_pin.robot_file import load_robot

    urdf = tmp_path / "small.urdf"
    code, out, _ = _run(capsys, "generate", "--robot", str(robot_file), "-o", str(urdf),
                        "--json")
    assert code == 0 and json.loads(out)["robot"] == "small_camera_snake"
    assert load_robot(urdf) == load_robot(robot_file)
    results = []
    for spec in (robot_file, urdf):
        code, out, _ = _run(capsys, "manip", "--robot", str(spec), "--q",
                            ",".join(map(str, Q6)), "--json")
        results.append(json.loads(out))
    assert code == 0 and results[0]["R"] == pytest.approx(results[1]["R"], rel=1e-12)


def test_analysis_commands_use_the_robot_file(capsys: pytest.CaptureFixture[str],
                                              robot_file: Path, tmp_path: Path) -> None:
    """manip, sweep and singular with --robot FILE give the library's numbers for that
    robot (not Table 1's)."""
    import numpy as np

    from snake_pin import Snake, SnakeParams
    from snake_pin.manipulability import manipulability
    from snake_pin.robot_file import load_robot
    from snake_pin.singular import find_singular_postures
    from snake_pin.sweeps import sweep

    params = load_robot(robot_file)
    snake = Snake(params)
    code, out, _ = _run(capsys, "manip", "--robot", str(robot_file), "--q",
                        ",".join(map(str, Q6)), "--json")
    r = json.loads(out)["R"]
    assert code == 0 and r == pytest.approx(manipulability(snake, np.array(Q6)).R, rel=1e-12)
    assert r != pytest.approx(
        manipulability(Snake(SnakeParams.table1(n=6)), np.array(Q6)).R, rel=1e-3)
    code, out, _ = _run(capsys, "sweep", "arc", "--robot", str(robot_file), "--points", "5",
                        "-o", str(tmp_path / "sweep"), "--json")
    files = json.loads(out)["files"]
    data = json.loads(Path(files["json"]).read_text())
    assert code == 0 and data["robot"] == "small_camera_snake"
    assert np.allclose(data["R"], sweep(snake, "arc", points=5).R, rtol=1e-12)
    code, out, _ = _run(capsys, "singular", "--robot", str(robot_file), "--starts", "1",
                        "--json")
    search = find_singular_postures(params, starts=1)
    assert code == 0 and json.loads(out)["R"] == pytest.approx(search.to_dict()["R"])


def test_runs_and_view_use_the_robot_file(capsys: pytest.CaptureFixture[str],
                                          robot_file: Path, tmp_path: Path) -> None:
    """simulate (both controllers), engine and reproduce run the file's robot (the
    Lyapunov run keeps its anisotropic per-link friction, the engine identifies friction
    per link); view --robot accepts its runs and refuses another robot's."""
    from snake_pin.robot_file import load_robot
    from snake_pin.sim import Trajectory

    params = load_robot(robot_file)
    code, out, _ = _run(capsys, "simulate", "--controller", "pfl", "--robot", str(robot_file),
                        "--t-final", "0.05", "-o", str(tmp_path / "pfl"), "--json")
    assert code == 0 and json.loads(out)["robot"] == "small_camera_snake"
    assert Trajectory.load(tmp_path / "pfl" / "pfl.npz").params == params
    code, out, _ = _run(capsys, "simulate", "--controller", "lyapunov", "--robot",
                        str(robot_file), "--t-final", "0.05", "-o", str(tmp_path / "lyap"),
                        "--json")
    assert code == 0 and json.loads(out)["c_y"] == params.per_link("c_y").tolist()
    code, out, _ = _run(capsys, "engine", "--robot", str(robot_file), "--t-final", "0.05",
                        "-o", str(tmp_path / "engine"), "--json")
    data = json.loads(out)
    assert code == 0 and data["robot"] == "small_camera_snake"
    assert len(data["friction"]["c_y"]) == 6
    run = str(tmp_path / "engine" / "engine.npz")
    code, out, _ = _run(capsys, "view", run, "--robot", str(robot_file), "--html",
                        str(tmp_path / "page.html"), "--json")
    assert code == 0 and (tmp_path / "page.html").is_file()
    code, _, err = _run(capsys, "view", run, "--robot", "table1", "--html",
                        str(tmp_path / "other.html"))
    assert code == 2 and "small_camera_snake" in err and "table1" in err
    code, _, _ = _run(capsys, "reproduce", "--only", "robot", "--robot", str(robot_file),
                      "-o", str(tmp_path / "report"))
    robot = json.loads((tmp_path / "report" / "summary.json").read_text())["robot"]
    assert code == 0 and robot["name"] == "small_camera_snake"
    assert robot["mass"] == params.masses.tolist()


def test_engine_seeds_reports_the_distribution(capsys: pytest.CaptureFixture[str],
                                               tmp_path: Path) -> None:
    """engine --seeds 3: three runs from the seeded offsets (within +-EPS), each saved; the
    JSON's median and 10-90 % range are those of the runs' own summaries; a run can be
    repeated from its recorded offset; the text gives the medians."""
    import numpy as np

    from snake_pin.engine.run import run_engine
    from snake_pin.runs.engine import perturbations, summarize

    code, out, _ = _run(capsys, "engine", "--seeds", "3", "--perturbation", "1e-3",
                        "--t-final", "0.3", "-o", str(tmp_path), "--json")
    data = json.loads(out)
    assert code == 0 and data["status"] == "completed" and data["finished"] == 3
    offsets = np.array([run["offset"] for run in data["runs"]])
    assert np.array_equal(offsets, perturbations(3, 7, 1e-3, seed=0))
    r_min = [run["summary"]["R_min"] for run in data["runs"]]
    assert len(set(r_min)) == 3  # the offsets do change the runs
    dist = data["distribution"]["R_min"]
    assert dist["median"] == pytest.approx(np.median(r_min), rel=1e-15)
    assert dist["p10"] == pytest.approx(np.percentile(r_min, 10), rel=1e-15)
    assert dist["p90"] == pytest.approx(np.percentile(r_min, 90), rel=1e-15)
    rms = [run["summary"]["rms_percent"] for run in data["runs"]]  # over t >= 0.15 s
    assert data["error_window"] == pytest.approx(0.15) and None not in rms
    assert data["median_run"] == f"engine_seed{rms.index(sorted(rms)[1]) + 1}"
    assert all((tmp_path / f"engine_seed{k}.npz").is_file() for k in (1, 2, 3))
    assert (tmp_path / "engine_head.png").is_file()
    again = run_engine(t_final=0.3, initial_offset=offsets[1]).trajectory
    assert summarize(again)["R_min"] == pytest.approx(r_min[1], rel=1e-9)
    code, out, _ = _run(capsys, "engine", "--seeds", "1", "--t-final", "0.3", "-o",
                        str(tmp_path / "text"))
    assert code == 0 and "R min" in out and "median" in out


# ------------------------------------------------------------------- summaries and text
def _text_keys(out: str) -> list[str]:
    """The keys of a text summary: the word before ':' on each line that has one."""
    return [line.split(":", 1)[0].strip() for line in out.splitlines()
            if ":" in line and not line.startswith(" " * 20)]


def _no_series(value: object) -> bool:
    """Whether a JSON value holds no time series (no list longer than 20 entries)."""
    if isinstance(value, list):
        return len(value) <= 20 and all(_no_series(v) for v in value)
    if isinstance(value, dict):
        return all(_no_series(v) for v in value.values())
    return True


@pytest.mark.parametrize("controller", ["lyapunov", "pfl", "mpc"])
def test_run_summaries_have_the_same_keys_with_or_without_path(
        capsys: pytest.CaptureFixture[str], tmp_path: Path, controller: str) -> None:
    """simulate prints the same summary keys (SUMMARY_KEYS) with and without --path, in
    text and in JSON; no time series reaches stdout (they are in the npz and CSV)."""
    from snake_pin.cli import SUMMARY_KEYS

    texts, payloads = [], []
    for extra in ([], ["--path", "circle"]):
        out_dir = tmp_path / ("path" if extra else "line")
        argv = ["simulate", "--controller", controller, "--t-final", "0.4", *extra,
                "-o", str(out_dir)]
        code, out, _ = _run(capsys, *argv)
        assert code == 0 and len(out) < 2000
        texts.append(out)
        code, out, _ = _run(capsys, *argv, "--json")
        data = json.loads(out)
        assert code == 0 and set(SUMMARY_KEYS) <= set(data) and _no_series(data)
        assert data["rms_head_error"] is not None and data["error_window"] == 0.2
        assert data["torque_max"] > 0.0  # the peak |tau_i| of every controller's run
        payloads.append(data)
    assert _text_keys(texts[0]) == _text_keys(texts[1]) == [*SUMMARY_KEYS, "files"]
    assert payloads[1]["reference"].startswith("path circle")
    csv = Path(next(f for f in payloads[1]["files"] if f.endswith("_criteria.csv")))
    header, *rows = csv.read_text().splitlines()
    assert header.split(",")[:2] == ["t", "R"] and len(rows) == 5  # every 0.1 s of 0.4 s


@pytest.mark.parametrize("argv", [
    ["manip", "--phi0", "pi/10"],
    ["manip", "--shape", "serpenoid", "--free-joint", "5"],
    ["singular", "--starts", "4"],
    ["info", "--robot", "camera_head_snake.toml"],
    ["info", "--passive", "3"],
    ["sweep", "arc", "--points", "6", "-o", "{out}"],
    ["generate", "--cx", "0.3", "-o", "{out}/x.urdf"],
    ["simulate", "--controller", "pfl", "--t-final", "0.2", "-o", "{out}"],
])
def test_text_outputs_have_plain_numbers(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                         argv: list[str]) -> None:
    """Without --json, stdout holds plain text: no NumPy or Python reprs of numbers."""
    code, out, _ = _run(capsys, *(a.replace("{out}", str(tmp_path)) for a in argv))
    assert code == 0 and out.strip()
    for bad in ("np.", "float64", "array(", "[]"):
        assert bad not in out, (bad, out)


def test_sweep_of_an_even_grid_names_the_singular_zero(capsys: pytest.CaptureFixture[str],
                                                      tmp_path: Path) -> None:
    """sweep arc --points 60 (an even grid over -pi/5..pi/5) sweeps phi0 = 0 too and reports
    R = 0 there; --range sets the swept range."""
    code, out, _ = _run(capsys, "sweep", "arc", "--points", "60", "-o", str(tmp_path), "--json")
    data = json.loads(out)
    assert code == 0 and data["zeros"] == [0.0] and data["points"] == 61
    code, out, _ = _run(capsys, "sweep", "arc", "--points", "60", "-o", str(tmp_path))
    assert code == 0 and "R = 0 at phi0 = [0]" in out
    code, out, _ = _run(capsys, "sweep", "arc", "--points", "4", "--range", "-0.3", "pi/10",
                        "-o", str(tmp_path / "range"), "--json")
    data = json.loads(out)
    saved = json.loads(Path(data["files"]["json"]).read_text())
    assert code == 0 and data["range"] == pytest.approx([-0.3, math.pi / 10])
    assert saved["values"][0] == -0.3 and 0.0 in saved["values"] and len(saved["values"]) == 5


def _robot_flags(parser: object) -> dict[str, set[str]]:
    """Subcommand -> its robot options (of --robot, --n, --passive, --cx, --cy, --ctheta)."""
    import argparse

    robot = {"--robot", "--n", "--passive", "--cx", "--cy", "--ctheta"}
    assert isinstance(parser, argparse.ArgumentParser)
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {name: {o for a in p._actions for o in a.option_strings} & robot
            for name, p in sub.choices.items()}


def test_every_command_that_takes_a_robot_takes_every_robot_option() -> None:
    """generate, info, manip, sweep, singular, simulate and reproduce take the same robot
    options; engine all but the friction it identifies from its wheels."""
    from snake_pin.cli import build_parser

    flags = _robot_flags(build_parser())
    full = {"--robot", "--n", "--passive", "--cx", "--cy", "--ctheta"}
    for name in ("generate", "info", "manip", "sweep", "singular", "simulate", "reproduce"):
        assert flags[name] == full, name
    assert flags["engine"] == {"--robot", "--n", "--passive"}


def test_generate_honours_the_friction_options(capsys: pytest.CaptureFixture[str],
                                               tmp_path: Path) -> None:
    """generate --cx/--cy/--ctheta/--n: the URDF reads back with that friction and n."""
    from snake_pin.robot_file import load_robot

    out_file = tmp_path / "robot.urdf"
    code, _, _ = _run(capsys, "generate", "--n", "7", "--cx", "0.3", "--cy", "2.5",
                      "--ctheta", "1e-4", "-o", str(out_file))
    robot = load_robot(out_file)
    assert code == 0 and robot.n == 7
    assert (robot.c_x, robot.c_y, robot.c_theta) == (0.3, 2.5, 1e-4)


def test_joint_errors_name_the_robot_in_plain_english(capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    """A joint out of range on the 8-link engine robot: one line, no "a 8-link"."""
    code, _, err = _run(capsys, "manip", "--robot", "engine", "--passive", "8")
    assert code == 2 and "outside 1..7 for the 8-link robot" in err and "a 8" not in err


def test_reproduce_logs_one_line_per_stage_when_stderr_is_not_a_terminal(
        capsys: pytest.CaptureFixture[str], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """reproduce with stderr not a terminal (captured): one line per stage on stderr, as the
    stage starts, in order; stdout names the report."""
    import importlib

    import snake_pin.experiments as experiments

    reproduce = importlib.import_module("snake_pin.experiments.reproduce")  # not the function

    def stage(ctx: object) -> None:
        pass

    fake = [("robot", stage), ("manipulability", stage), ("pfl", stage)]
    monkeypatch.setattr(reproduce, "stages", lambda: fake)
    monkeypatch.setattr(experiments, "stages", lambda: fake)
    code, out, err = _run(capsys, "reproduce", "-o", str(tmp_path))
    assert code == 0 and out.startswith("report: ")
    assert err.splitlines() == ["snake-pin: reproduce [1/3] robot ...",
                                "snake-pin: reproduce [2/3] manipulability ...",
                                "snake-pin: reproduce [3/3] pfl ..."]


def test_simulate_mpc_keeps_its_torque_bound(capsys: pytest.CaptureFixture[str],
                                             tmp_path: Path) -> None:
    """simulate --controller mpc runs the MPC on the tracking line: the Lyapunov run's
    summary keys, torque_max within the bound, and a passive joint gets exactly zero torque."""
    import numpy as np

    from snake_pin.cli import SUMMARY_KEYS
    from snake_pin.trajectory import Trajectory

    code, out, err = _run(capsys, "simulate", "--controller", "mpc", "--t-final", "0.3",
                          "--passive", "5", "--torque-bound", "0.8", "-o", str(tmp_path),
                          "--json")
    data = json.loads(out)
    assert code == 0, err
    assert set(SUMMARY_KEYS) <= set(data) and data["controller"] == "mpc"
    assert data["status"] == "completed" and 0.0 < data["torque_max"] <= 0.8 + 1e-9
    traj = Trajectory.load(tmp_path / "mpc.npz")
    assert np.all(traj.tau[:, 4] == 0.0) and np.abs(traj.tau).max() <= 0.8 + 1e-9
    code, out, err = _run(capsys, "simulate", "--controller", "lyapunov", "--t-final", "0.3",
                          "--passive", "5", "-o", str(tmp_path / "lyapunov"), "--json")
    assert code == 0 and set(json.loads(out)) == set(data), err  # the same summary keys


@pytest.mark.parametrize(("argv", "fragment"), [
    (["--controller", "mpc", "--horizon", "0.001"], "horizon"),
    (["--controller", "mpc", "--torque-bound", "-1"], "torque_bound"),
    (["--controller", "lyapunov", "--horizon", "0.5"], "--horizon: applies to --controller mpc"),
])
def test_simulate_refuses_bad_mpc_options(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                          argv: list[str], fragment: str) -> None:
    """A bad MPC option (checked by MPCOptions), or one given to another law, is one line
    on stderr, exit 2, and no folder."""
    out_dir = tmp_path / "out"
    code, out, err = _run(capsys, "simulate", *argv, "-o", str(out_dir))
    assert code == 2 and out == "" and fragment in err and err.count("\n") == 1, err
    assert not out_dir.exists()
