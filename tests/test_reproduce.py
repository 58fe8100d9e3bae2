"""The main job end to end: `snake-pin reproduce --quick` writes every section."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

from snake_pin.cli import main

SECTIONS = ("robot", "manipulability", "singular", "integrability", "pfl", "tracking", "engine")


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("report")
    assert main(["reproduce", "--quick", "-o", str(folder)]) == 0
    return folder


def test_every_section_is_in_the_page_and_summary(report: Path) -> None:
    """index.html has a section per stage with embedded figures; summary.json has their numbers."""
    html = (report / "index.html").read_text()
    summary = json.loads((report / "summary.json").read_text())
    for key in SECTIONS:
        assert f"id='{key}'" in html and key in summary
    assert html.count("data:image/png;base64,") >= 25


def _page_text(report: Path) -> str:
    """The report page without its embedded images."""
    return re.sub(r"data:image/png;base64,[^']*", "", (report / "index.html").read_text())


def test_the_page_speaks_to_readers(report: Path) -> None:
    """The report is a product page: no project history ("issue 14"), captions that give
    each figure's number once, plain numbers, articles and plurals right, the robot's
    passive joints as "none" rather than an empty list."""
    text = _page_text(report)
    assert not re.search(r"issues? \d", text, re.IGNORECASE)
    assert "<td>passive</td><td>none</td>" in text
    for caption in re.findall(r"<figcaption>([^<]*)</figcaption>", text):
        assert len(re.findall(r"\bFigs?\. ", caption)) <= 1, caption
    assert re.search(r"<figcaption>Fig\. 2: all joints at phi0 \(", text)
    for wrong in ("np.float64", "a 8-link", "a 11-link", "a 18-link", "(1 workers)",
                  "(1 starts)", "<td>[]</td>"):
        assert wrong not in text, wrong


def test_linked_pages_exist(report: Path) -> None:
    """Every link of the page (the meshcat animations) points to a file that was written."""
    html = (report / "index.html").read_text()
    links = re.findall(r"<a href='([^'#]+)'>", html)
    assert links and all((report / link).is_file() for link in links)


def test_key_results_are_reported(report: Path) -> None:
    """The summary carries the headline numbers of each experiment."""
    summary = json.loads((report / "summary.json").read_text())
    assert summary["singular"]["singular"]["non_straight_singular_exists"] is True
    assert summary["pfl"]["isotropic"]["g_drift_max"] < 1e-8
    assert summary["tracking"]["tracking"]["R_min"] > 0
    assert summary["integrability"]["involutivity"][0][3] == "involutive"
    assert summary["engine"]["friction"]["c_y"] > summary["engine"]["friction"]["c_x"]


def test_the_tracking_sweeps_are_reported_from_their_runs(report: Path) -> None:
    """The tracking stage's sweeps: every point has its row, the figure is embedded, and the
    findings' best point is the smallest error of that sweep's runs (the default run's
    included)."""
    from snake_pin.experiments.tracking import C_Y_FACTORS, DECAY_RATES

    tracking = json.loads((report / "summary.json").read_text())["tracking"]
    sweep = tracking["sweep"]
    assert len(sweep) == len(DECAY_RATES) + len(C_Y_FACTORS) - 2  # the default is run once
    default = 100 * tracking["tracking"]["rms_relative"]
    rates = [100 * row["rms_relative"] for label, row in sweep.items() if "lambda" in label]
    frictions = [100 * row["rms_relative"] for label, row in sweep.items() if "c_y" in label]
    found = tracking["sweep_findings"]
    assert found["lam"]["best"][1] == pytest.approx(min([*rates, default]), rel=1e-12)
    assert found["c_y"]["best"][1] == pytest.approx(min([*frictions, default]), rel=1e-12)
    assert found["c_y"]["first"][0] == pytest.approx(50.0 * C_Y_FACTORS[0])  # c_y / c_x
    html = (report / "index.html").read_text()
    assert "RMS head error against the head&#x27;s decay rate" in html


def test_engine_results_are_distributions(report: Path) -> None:
    """The engine stage reports each configuration over 3 perturbed runs (--quick): the
    median and range are those of the runs, the files are the median run's, the target is
    judged on the median, and the viscous model is found insensitive."""
    import numpy as np

    from snake_pin.trajectory import Trajectory

    engine = json.loads((report / "summary.json").read_text())["engine"]
    for stem in ("engine", "engine_passive5"):
        draws = engine[stem]["draws"]
        rms = [run["summary"]["rms_percent"] for run in draws["runs"]]
        assert draws["draws"] == draws["finished"] == 3 and draws["perturbation"] == 1e-6
        assert draws["distribution"]["rms_percent"]["median"] == pytest.approx(np.median(rms))
        median = draws["median_draw"]
        assert rms[median] == pytest.approx(np.median(rms))
        saved = Trajectory.load(report / f"{stem}.npz", signals=False)
        assert saved.summary["rms_percent"] == pytest.approx(rms[median], rel=1e-12)
        assert np.abs(np.array([run["offset"] for run in draws["runs"]])).max() <= 1e-6
    label = "velocity law, no passive joint"
    assert engine["target_met"][label] == \
        (engine["engine"]["draws"]["distribution"]["rms_percent"]["median"] <= 10.0)
    check = engine["viscous_sensitivity"]
    assert check["sensitive"] is False and len(check["rms_percent_perturbed"]) == 3
    assert check["relative_change"] < 1e-3
    for name, mpc in engine["mpc"].items():  # the MPC on MuJoCo: line and circle_1L
        assert mpc["statuses"] == ["completed"] * 3, name
        peaks = [run["summary"]["torque_max"] for run in mpc["draws"]["runs"]]
        assert max(peaks) <= mpc["torque_bound"] + 1e-9
        assert mpc["distribution"]["torque_max"]["median"] == pytest.approx(np.median(peaks))
    assert set(engine["mpc"]) == {"line", "circle_1L"}


def test_which_stages_honour_which_robot() -> None:
    """The engine stage honours --robot for the engine preset and for a robot of one's own,
    not for Table 1 (it would run the engine preset); it never honours --passive or --n."""
    from snake_pin import SnakeParams
    from snake_pin.experiments.reproduce import unhonoured
    from snake_pin.robot_file import load_robot
    from snake_pin.runs.engine import engine_robot

    own = load_robot("camera_head_snake.toml")
    assert unhonoured("engine", {"robot"}, own) == []
    assert unhonoured("engine", {"robot"}, SnakeParams.engine()) == []
    assert unhonoured("engine", {"robot"}, SnakeParams.table1()) == ["robot"]
    assert unhonoured("engine", {"robot", "passive", "n"}, own) == ["n", "passive"]
    assert engine_robot(SnakeParams.table1()) == SnakeParams.engine()
    assert engine_robot(own.replace(passive=(5,))) == own


def test_tracking_keeps_an_anisotropic_robots_own_friction() -> None:
    """The tracking stage's friction: a robot file's own when c_y > c_x on every link, else
    (presets, an isotropic robot file) the tracking friction of erratum 3, said so."""
    from snake_pin import SnakeParams
    from snake_pin.robot_file import load_robot
    from snake_pin.runs.tracking import TRACKING_FRICTION, tracking_friction

    own = load_robot("camera_head_snake.toml")
    robot, sentence = tracking_friction(own)
    assert robot is own and "own friction" in sentence
    iso = own.replace(c_y=own.per_link("c_x"))
    robot, sentence = tracking_friction(iso)
    assert (robot.c_x, robot.c_y) == (TRACKING_FRICTION["c_x"], TRACKING_FRICTION["c_y"])
    assert "replaces the robot's own" in sentence
    assert robot.masses.tolist() == own.masses.tolist()
    robot, sentence = tracking_friction(SnakeParams.table1())
    assert robot == SnakeParams.table1(**TRACKING_FRICTION) and "replaces" not in sentence


def test_first_links_and_the_pfl_threshold_follow_the_robot() -> None:
    """first_links cuts per-link values to the first n links (equal links: replace(n=n));
    PFL's breakdown threshold is 1 N m for Table 1 and scales with m (2l)^2 per link."""
    import numpy as np

    from snake_pin import SnakeParams
    from snake_pin.experiments.integrability import first_links
    from snake_pin.robot_file import load_robot
    from snake_pin.runs.pfl import TAU_BREAKDOWN, breakdown_threshold

    own = load_robot("camera_head_snake.toml")
    four = first_links(own, 4)
    assert four.n == 4 and four.masses.tolist() == own.masses[:4].tolist()
    assert four.com_offsets.tolist() == own.com_offsets[:4].tolist()
    assert four.per_link("c_y").tolist() == own.per_link("c_y")[:4].tolist()
    assert first_links(SnakeParams.table1(), 4) == SnakeParams.table1(n=4)
    assert breakdown_threshold(SnakeParams.table1()) == TAU_BREAKDOWN
    expected = np.mean(own.masses * own.link_lengths**2) / (0.182 * 0.12**2)
    assert breakdown_threshold(own) == pytest.approx(TAU_BREAKDOWN * expected, rel=1e-12)


def test_report_is_complete_strict_json_and_in_place(report: Path) -> None:
    """The run is marked complete, summary.json is RFC 8259 (no NaN/Infinity), every file
    has the umask's mode and no staging folder is left in the output folder."""
    def refuse(constant: str) -> None:
        raise AssertionError(f"{constant} in summary.json")

    summary = json.loads((report / "summary.json").read_text(), parse_constant=refuse)
    assert summary["run"]["status"] == "complete"
    assert summary["run"]["sections"][:len(SECTIONS)] == list(SECTIONS)
    assert not [p for p in report.iterdir() if p.name.startswith(".")]
    umask = os.umask(0)
    os.umask(umask)
    assert {p.stat().st_mode & 0o777 for p in report.iterdir() if p.is_file()} \
        == {0o666 & ~umask}
    assert {p.stat().st_mode & 0o777 for p in report.iterdir() if p.is_dir()} \
        <= {0o777 & ~umask}


@pytest.mark.usefixtures("tiny_report")
def test_reproduce_runs_every_stage_on_a_robot_file(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """reproduce --quick --robot camera_head_snake.toml (a shipped robot by bare file name):
    every stage runs on that robot (the failure map and the path benchmark too) and the
    report is complete; the robot stage lists its per-link values, and the engine stage
    puts that robot itself on wheels (10 links, friction identified per link) and reports
    its distributions. The failure maps and MPC runs are the tiny ones (how stages honour
    a robot, not their numbers)."""
    from snake_pin.experiments import failure_map, stages
    from snake_pin.robot_file import load_robot
    from snake_pin.trajectory import Trajectory

    params = load_robot("camera_head_snake.toml")
    # the tiny map with the tail joint too
    monkeypatch.setattr(failure_map, "QUICK", failure_map.MapPlan(
        1.0, (0, 1, params.n - 1), (25.0, 50.0), error_window=0.5))
    assert main(["reproduce", "--quick", "--robot", "camera_head_snake.toml",
                 "-o", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["run"]["status"] == "complete"
    assert set(summary["run"]["sections"]) >= {name for name, _ in stages()}
    rows = json.loads((tmp_path / "benchmark.json").read_text())
    assert rows["settings"]["robot"]["name"] == "camera_head_snake"
    assert summary["robot"]["mass"] == params.masses.tolist()
    engine = summary["engine"]
    assert len(engine["friction"]["c_y"]) == 10
    assert engine["friction"]["c_y"][0] > engine["friction"]["c_y"][1]  # the heavier head
    run = Trajectory.load(tmp_path / "engine.npz", signals=False)
    assert run.params.name == "camera_head_snake" and run.params.n == 10
    assert run.params.link_lengths.tolist() == params.link_lengths.tolist()
    assert engine["engine"]["draws"]["finished"] == 3
    assert engine["engine"]["body_length"] == pytest.approx(params.body_length)
    html = (tmp_path / "index.html").read_text()
    assert "camera_head_snake" in html and "median" in html
    assert str(params.n - 1) in summary["failure_map"]["rms_head_error_pct"]


@pytest.mark.usefixtures("tiny_report")
def test_reproduce_twice_into_the_same_folder(tmp_path: Path) -> None:
    """A second reproduce replaces the first, stage folders (the failure map's studies,
    tiny) too."""
    argv = ["reproduce", "--quick", "--only", "failure_map", "-o", str(tmp_path)]
    assert main(argv) == 0
    first = (tmp_path / "failure_map").stat().st_ino
    assert main(argv) == 0
    assert (tmp_path / "failure_map" / "runs").is_dir()
    assert (tmp_path / "failure_map").stat().st_ino != first
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
