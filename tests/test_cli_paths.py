"""CLI: runs along paths (--path, los, a user's Controller), bench-control and study wiring."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from snake_pin.cli import main
from snake_pin.paths import load_path
from snake_pin.sim import Trajectory


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_simulate_follows_a_circle_path(tmp_path: Path, capsys) -> None:
    """--path circle --path-param radius=R: the saved run's reference is that circle."""
    code, out, _ = _run(["simulate", "--controller", "lyapunov", "--path", "circle",
                         "--path-param", "radius=1.2", "--t-final", "2", "-o",
                         str(tmp_path), "--json"], capsys)
    assert code == 0
    payload = json.loads(out)
    assert payload["status"] == "completed"
    traj = Trajectory.load(tmp_path / "lyapunov.npz")
    assert "Circle" in traj.meta["path"] and "1.2" in traj.meta["path"]
    reference = load_path("circle", radius=1.2)
    w_r, _, _ = reference(traj.t_end)
    assert np.hypot(*(traj.q[-1, :2] - w_r[:2])) < 0.15  # the head is near the circle's point


def test_user_controller_class_runs_from_the_command_line(tmp_path: Path, capsys,
                                                          monkeypatch) -> None:
    """--controller module:Class builds Class(snake, reference); its torques are applied."""
    module = tmp_path / "my_law.py"
    module.write_text(
        "import numpy as np\n"
        "from snake_pin.control import Controller\n"
        "class Still(Controller):\n"
        "    name = 'still'\n"
        "    def __init__(self, snake, reference):\n"
        "        self.n = snake.n\n"
        "    def __call__(self, x, t):\n"
        "        return np.zeros(self.n - 1)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    sys.modules.pop("my_law", None)
    code, _, err = _run(["simulate", "--controller", "my_law:Still", "--t-final", "0.5",
                         "-o", str(tmp_path / "out")], capsys)
    assert code == 0, err
    traj = Trajectory.load(tmp_path / "out" / "run.npz")
    assert np.all(traj.tau == 0.0) and traj.meta["controller"] == "still"


def test_readme_controller_joins_the_benchmark(tmp_path: Path, capsys, monkeypatch) -> None:
    """The README's my_law.py, named my_law:FastHead, runs in bench-control beside the
    built-in law with its own gains (lambda = 20/s, not 10/s: the rows differ)."""
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    code = readme.split("```python\n# my_law.py\n", 1)[1].split("```", 1)[0]
    (tmp_path / "my_law.py").write_text(code)
    monkeypatch.syspath_prepend(str(tmp_path))
    sys.modules.pop("my_law", None)
    status, out, err = _run(["bench-control", "--controller", "lyapunov", "--controller",
                             "my_law:FastHead", "--scenario", "circle_1L", "--no-failure",
                             "--t-final", "12", "-o", str(tmp_path / "bench"), "--json"],
                            capsys)
    assert status == 0, err
    rows = {row["controller"]: row for row in json.loads(out)["rows"]}
    assert set(rows) == {"lyapunov", "my_law:FastHead"}
    assert all(row["status"] == "completed" for row in rows.values())
    assert rows["lyapunov"]["torque_rms"] != rows["my_law:FastHead"]["torque_rms"]


@pytest.mark.parametrize("argv, fragment", [
    (["--controller", "nope:Missing"], "cannot import"),
    (["--controller", "snake_pin.params:SnakeParams"], "not a snake_pin Controller"),
    (["--controller", "kalman"], "choose pfl, lyapunov, los"),
    (["--controller", "lyapunov", "--path", "circle", "--path-param", "radius=-1"],
     "radius must be positive"),
    (["--controller", "lyapunov", "--path", "circle", "--path-param", "radius"],
     "KEY=VALUE"),
    (["--controller", "lyapunov", "--speed", "0.2"], "apply with --path"),
    (["--controller", "lyapunov", "--path", "missing.csv"], "missing.csv"),
])
def test_bad_path_and_controller_options_are_one_line(argv: list[str], fragment: str,
                                                      tmp_path: Path, capsys) -> None:
    """Each wrong path/controller option: exit 2, one line naming it, no folder created."""
    out_dir = tmp_path / "never"
    code, out, err = _run(["simulate", *argv, "-o", str(out_dir)], capsys)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and fragment in err
    assert not out_dir.exists()


def test_engine_follows_the_path_it_is_given(tmp_path: Path, capsys) -> None:
    """engine --path circle --path-param --speed runs exactly run_engine(reference=that path)."""
    from snake_pin.engine.run import run_engine
    from snake_pin.params import SnakeParams

    code, out, err = _run(["engine", "--path", "circle", "--path-param", "radius=1.4",
                           "--speed", "0.15", "--t-final", "0.5", "-o", str(tmp_path),
                           "--json"], capsys)
    assert code == 0, err
    payload = json.loads(out)
    assert payload["status"] == "completed" and "head_ct_rms" in payload
    traj = Trajectory.load(tmp_path / "engine.npz")
    reference = load_path("circle", radius=1.4, speed=0.15)
    assert traj.meta["reference"] == repr(reference)
    direct = run_engine(SnakeParams.engine(), t_final=0.5, reference=reference).trajectory
    np.testing.assert_array_equal(traj.q, direct.q)
    np.testing.assert_array_equal(traj.tau, direct.tau)
    error = np.linalg.norm(traj.q[:, :2] - reference.at(traj.t)[0][:, :2], axis=1)
    late = error[traj.t >= payload["error_window"]]
    assert payload["error_window"] == 0.25
    assert payload["rms_head_error"] == pytest.approx(np.sqrt(np.mean(late**2)), rel=1e-12)
    assert payload["reference"] == "path circle (radius=1.4) at 0.15 m/s"
    assert (tmp_path / "engine_path.png").is_file()


@pytest.mark.parametrize("command", ["simulate", "engine"])
def test_path_runs_print_the_summary_of_straight_runs(tmp_path: Path, capsys,
                                                      command: str) -> None:
    """simulate and engine print the same text summary (keys, in order) with and without
    --path, and a path run draws its head against the path (x-y PNG) in the folder."""
    from snake_pin.cli import SUMMARY_KEYS

    extra = ["--controller", "lyapunov"] if command == "simulate" else ["--cone", "pyramidal"]
    keys = []
    for path in ([], ["--path", "sinusoid"]):
        out_dir = tmp_path / ("path" if path else "line")
        code, out, err = _run([command, *extra, *path, "--t-final", "0.3", "-o", str(out_dir)],
                              capsys)
        assert code == 0 and err == "", err
        keys.append([line.split(":")[0].strip() for line in out.splitlines()
                     if not line.startswith(" " * 20)])
        assert "np." not in out and "series" not in out and len(out.splitlines()) < 30
    assert keys[0] == keys[1] == [*SUMMARY_KEYS, "files"]
    stem = "lyapunov" if command == "simulate" else "engine"
    figure = tmp_path / "path" / f"{stem}_path.png"
    assert figure.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("command", ["simulate", "engine"])
@pytest.mark.parametrize("argv, fragment", [
    (["--path", "circle", "--path-param", "radius=-1"], "radius must be positive"),
    (["--path", "circle", "--path-param", "radius"], "KEY=VALUE"),
    (["--path", "circle", "--path-param", "radius=big"], "must be a number"),
    (["--path", "circle", "--speed", "0"], "--speed"),
    (["--speed", "0.2"], "apply with --path"),
    (["--path-param", "radius=1"], "apply with --path"),
    (["--path", "missing.csv"], "missing.csv"),
    (["--path", "spiral"], "unknown path"),
])
def test_simulate_and_engine_refuse_the_same_bad_paths(command: str, argv: list[str],
                                                       fragment: str, tmp_path: Path,
                                                       capsys) -> None:
    """Both subcommands parse --path through one function: same one line, exit 2, no folder."""
    out_dir = tmp_path / "never"
    extra = ["--controller", "lyapunov"] if command == "simulate" else []
    code, out, err = _run([command, *extra, *argv, "-o", str(out_dir)], capsys)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and fragment in err
    assert not out_dir.exists()


@pytest.mark.parametrize("path", ["circle", "lane_change"])
def test_engine_path_with_seeds_runs_each_draw_on_that_path(path: str, tmp_path: Path,
                                                            capsys) -> None:
    """engine --path P --seeds 2 (the draws run in worker processes): each draw is
    run_engine(reference=P, initial_offset=its offset) bit for bit, and the distribution
    names the path."""
    from snake_pin.engine.run import run_engine
    from snake_pin.params import SnakeParams
    from snake_pin.runs.engine import PERTURBATION, perturbations

    code, out, err = _run(["engine", "--path", path, "--seeds", "2", "--t-final", "0.3",
                           "-o", str(tmp_path), "--json"], capsys)
    assert code == 0, err
    reference = load_path(path)
    assert json.loads(out)["path"] == repr(reference)
    offsets = perturbations(2, 7, PERTURBATION, seed=0)
    for k, offset in enumerate(offsets, start=1):
        traj = Trajectory.load(tmp_path / f"engine_seed{k}.npz")
        assert traj.meta["reference"] == repr(reference)
        direct = run_engine(SnakeParams.engine(), t_final=0.3, reference=reference,
                            initial_offset=offset).trajectory
        np.testing.assert_array_equal(traj.q, direct.q)


def test_bench_control_quick_writes_its_table(tmp_path: Path, capsys) -> None:
    """bench-control --quick on one scenario and one law writes CSV/JSON with finite rows."""
    code, out, err = _run(["bench-control", "--scenario", "line", "--controller", "lyapunov",
                           "--no-failure", "--t-final", "11", "-o", str(tmp_path), "--json"],
                          capsys)
    assert code == 0, err
    rows = json.loads(out)["rows"]
    assert len(rows) == 1 and rows[0]["scenario"] == "line"
    assert np.isfinite(rows[0]["head_ct_rms"])
    assert (tmp_path / "benchmark.csv").is_file()


def test_bench_control_engine_draws_reach_the_cell(tmp_path: Path, capsys) -> None:
    """bench-control --draws N runs N perturbed engine starts per cell (the row says so)."""
    code, out, err = _run(["bench-control", "--model", "engine", "--scenario", "line",
                           "--controller", "velocity", "--no-failure", "--t-final", "0.2",
                           "--draws", "2", "-o", str(tmp_path), "--json"], capsys)
    assert code == 0, err
    (row,) = json.loads(out)["rows"]
    assert (row["model"], row["draws"], row["status"]) == ("engine", 2, "completed")


def test_study_subcommand_is_wired(tmp_path: Path, capsys) -> None:
    """`snake-pin study` refuses a bad study file in one line (exit 2) before running."""
    bad = tmp_path / "bad.toml"
    bad.write_text("[base]\nnot_a_setting = 1\n")
    code, out, err = _run(["study", str(bad), "-o", str(tmp_path / "s")], capsys)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and "not_a_setting" in err
