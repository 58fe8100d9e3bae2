"""The command line's contract, case by case (the issue's audit) and fuzzed (hypothesis):
exit 0 or 2, one line on stderr for 2, no traceback, exactly one strict JSON object with
--json, nothing created for a wrong argument, no temporary left behind."""

from __future__ import annotations

import contextlib
import ctypes
import json
import math
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from snake_pin import Snake, SnakeParams, Trajectory, arc
from snake_pin._json import json_text
from snake_pin.cli import EXIT_FAILED, EXIT_USAGE, main
from snake_pin.gaits import Serpenoid
from snake_pin.manipulability import manipulability


def _run(capfd: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    capfd.readouterr()
    code = main(list(argv))
    out, err = capfd.readouterr()
    return code, out, err


def _strict_json(text: str) -> dict:
    """The one JSON object of ``text`` (RFC 8259: NaN/Infinity refused)."""
    def refuse(constant: str) -> None:
        raise AssertionError(f"{constant} is not JSON")

    assert text.endswith("\n") and text.count("\n") == 1, text
    data = json.loads(text, parse_constant=refuse)
    assert isinstance(data, dict)
    return data


def _usage_error(code: int, out: str, err: str) -> str:
    assert code == EXIT_USAGE, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("snake-pin"), err
    assert out == "" and "Traceback" not in err
    return lines[0]


def _leftovers(folder: Path) -> list[Path]:
    """Temporary files or staging folders anywhere under ``folder``."""
    return [p for p in folder.rglob("*") if ".snake_pin-" in p.name
            or p.name.startswith(".reproduce-") or p.name.endswith(".tmp")]


def _R(q: list[float], **kwargs: object) -> float:
    return manipulability(Snake(), np.asarray(q), **kwargs).R


Q = [0.1, -0.2, 0.3, 0.2, -0.1, 0.4, 0.0, 0.3, -0.5, 0.2, 0.1, 0.6]


# -------------------------------------------------------- silent wrong answers
def test_manip_q_without_shape_uses_the_configuration(capfd: pytest.CaptureFixture[str]) -> None:
    """--q alone implies --shape q: D and R of that configuration, not of the straight one."""
    code, out, _ = _run(capfd, "manip", "--q", ",".join(map(str, Q)), "--json")
    assert code == 0 and _strict_json(out)["R"] == pytest.approx(_R(Q), rel=1e-12)
    assert _R(Q) > 1e-6  # (the straight posture has R = 0)


@pytest.mark.parametrize(("argv", "flag"), [
    (["--shape", "arc", "--q", "0,0,0,0,0,0,0,0,0,0,0,0"], "--q"),
    (["--shape", "straight", "--phi0", "pi/10"], "--phi0"),
    (["--shape", "q", "--alpha", "pi/4", "--q", "0,0,0,0,0,0,0,0,0,0,0,0"], "--alpha"),
    (["--phi0", "0.1", "--ts", "1.5"], "--phi0"),
])
def test_manip_refuses_options_of_another_shape(capfd: pytest.CaptureFixture[str],
                                                argv: list[str], flag: str) -> None:
    """A shape option that the chosen shape would ignore is refused, naming it."""
    assert flag in _usage_error(*_run(capfd, "manip", *argv))


def test_manip_passive_and_free_joint_are_both_free(capfd: pytest.CaptureFixture[str]) -> None:
    """--passive 5 --free-joint 3: R~ with joints 3 and 5 free (neither dropped)."""
    code, out, _ = _run(capfd, "manip", "--passive", "5", "--free-joint", "3", "--q",
                        ",".join(map(str, Q)), "--json")
    r = _strict_json(out)["R"]
    assert code == 0 and r == pytest.approx(_R(Q, free_joint=(3, 5)), rel=1e-12)
    assert r != pytest.approx(_R(Q, free_joint=3), rel=1e-6)
    assert r != pytest.approx(_R(Q, free_joint=5), rel=1e-6)


@pytest.mark.parametrize(("argv", "flag"), [
    (["--passive", "3"], "--passive"),
    (["--cx", "1"], "--cx"),
    (["--cy", "2", "--only", "tracking"], "--cy"),
    (["--cy", "2", "--only", "integrability"], "--cy"),
    (["--ctheta", "1e-4", "--only", "engine"], "--ctheta"),
    (["--n", "12", "--only", "engine"], "--n"),
    (["--robot", "table1", "--only", "engine"], "--robot"),
    (["--passive", "5", "--only", "pfl"], "--passive"),
    (["--robot", "camera_head_snake.toml", "--passive", "5", "--only", "engine"], "--passive"),
    (["--robot", "camera_head_snake.toml", "--cy", "9", "--only", "tracking"], "--cy"),
])
def test_reproduce_refuses_options_a_stage_sets_itself(capfd: pytest.CaptureFixture[str],
                                                       tmp_path: Path, argv: list[str],
                                                       flag: str) -> None:
    """reproduce refuses a robot option that a chosen stage would override, naming both,
    and creates nothing."""
    out = tmp_path / "report"
    line = _usage_error(*_run(capfd, "reproduce", *argv, "-o", str(out)))
    assert flag in line and "stage" in line and not out.exists()


def test_reproduce_honours_robot_options_in_the_robot_stage(capfd: pytest.CaptureFixture[str],
                                                            tmp_path: Path) -> None:
    """--n, --passive and friction reach the robot stage's numbers."""
    code, _, _ = _run(capfd, "reproduce", "--only", "robot", "--n", "7", "--passive", "3",
                      "--cx", "0.7", "-o", str(tmp_path))
    robot = json.loads((tmp_path / "summary.json").read_text())["robot"]
    assert code == 0 and (robot["n"], robot["passive"], robot["c_x"]) == (7, [3], 0.7)


def test_reproduce_refuses_too_few_links_for_a_stage(capfd: pytest.CaptureFixture[str],
                                                     tmp_path: Path) -> None:
    """A stage that needs more links (joint 5 free) refuses --n 5 before writing anything."""
    out = tmp_path / "report"
    line = _usage_error(*_run(capfd, "reproduce", "--only", "tracking", "--n", "5",
                              "-o", str(out)))
    assert "tracking" in line and not out.exists()


@pytest.mark.parametrize("x", ["1e6", "1e9", "-1e9"])
def test_manip_far_from_the_origin_is_translation_invariant(capfd: pytest.CaptureFixture[str],
                                                            x: str) -> None:
    """D and R of a posture at |x_h| up to 1e9 m equal those at the origin."""
    far = [x, x, *map(str, Q[2:])]
    code, out, _ = _run(capfd, "manip", "--q", ",".join(far), "--json")
    data = _strict_json(out)
    reference = manipulability(Snake(), np.asarray(Q))
    assert code == 0 and data["D"] == pytest.approx(reference.D, rel=1e-9)
    assert data["R"] == pytest.approx(reference.R, rel=1e-9)


def test_view_opens_only_the_file_given(capfd: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """`view bk/pfl.backup` does not open bk/pfl.npz: one line naming the path given."""
    (tmp_path / "bk").mkdir()
    _tiny().save(tmp_path / "bk" / "pfl")
    given = str(tmp_path / "bk" / "pfl.backup")
    line = _usage_error(*_run(capfd, "view", given, "--html", str(tmp_path / "x.html")))
    assert given in line and not (tmp_path / "x.html").exists()


def test_view_port_with_html_is_refused(capfd: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """--port only applies to the live viewer: with --html it is refused, not ignored."""
    _tiny().save(tmp_path / "run")
    assert "--port" in _usage_error(*_run(capfd, "view", str(tmp_path / "run.npz"), "--html",
                                          str(tmp_path / "x.html"), "--port", "7123"))


# -------------------------------------------------------------- negative values
@pytest.mark.parametrize(("argv", "expected"), [
    (["--q", "-0.8," + ",".join(map(str, Q[1:]))], lambda: _R([-0.8, *Q[1:]])),
    (["--q=-0.8," + ",".join(map(str, Q[1:]))], lambda: _R([-0.8, *Q[1:]])),
    (["--q", "-pi/5,0,-0.3" + ",0.2" * 9], lambda: _R([-math.pi / 5, 0, -0.3, *[0.2] * 9])),
    (["--phi0", "-pi/10"], lambda: manipulability(Snake(), arc(10, -math.pi / 10)).R),
    (["--shape", "arc", "--phi0", "-0.25"], lambda: manipulability(Snake(), arc(10, -0.25)).R),
    (["--alpha", "-pi/4"],
     lambda: manipulability(Snake(), Serpenoid(10, -math.pi / 4, 1.5).configuration()).R),
    (["--ts", "-1.5"],
     lambda: manipulability(Snake(), Serpenoid(10, math.pi / 4, -1.5).configuration()).R),
])
def test_negative_values_are_accepted(capfd: pytest.CaptureFixture[str], argv: list[str],
                                      expected) -> None:
    """Values that start with '-' (numbers, angles, lists) are values, not options."""
    code, out, err = _run(capfd, "manip", *argv, "--json")
    assert code == 0, err
    assert _strict_json(out)["R"] == pytest.approx(expected(), rel=1e-12, abs=1e-300)


def test_negative_number_for_a_count_is_refused_as_a_value(
        capfd: pytest.CaptureFixture[str]) -> None:
    """`--seed -1` is read as the value -1 and refused by its range, not as an option."""
    assert "must lie in 0..4294967295" in _usage_error(*_run(capfd, "singular", "--seed", "-1"))


# ---------------------------------------------------------------------- limits
@pytest.mark.parametrize(("argv", "flag"), [
    (["simulate", "--controller", "pfl", "--t-final", "1e12", "-o", "{out}"], "--t-final"),
    (["simulate", "--controller", "lyapunov", "--t-final", "1000.5", "-o", "{out}"],
     "--t-final"),
    (["engine", "--t-final", "1e12", "-o", "{out}"], "--t-final"),
    (["sweep", "arc", "--points", "1e12", "-o", "{out}"], "--points"),
    (["sweep", "arc", "--points", "1000000000000", "-o", "{out}"], "--points"),
    (["sweep", "arc", "--points", "100001", "-o", "{out}"], "--points"),
    (["singular", "--starts", "1e12", "-o", "{out}"], "--starts"),
    (["singular", "--starts", "10001", "-o", "{out}"], "--starts"),
    (["singular", "--seed", "-1", "-o", "{out}"], "--seed"),
    (["singular", "--seed", "4294967296", "-o", "{out}"], "--seed"),
    (["info", "--n", "500"], "--n"),
    (["manip", "--n", "201"], "--n"),
    (["generate", "--n", "500", "-o", "{out}/x.urdf"], "--n"),
    (["reproduce", "--n", "500", "-o", "{out}"], "--n"),
    (["manip", "--q", "1e300" + ",0" * 11], "--q"),
    (["view", "x.npz", "--port", "70000"], "--port"),
    (["view", "x.npz", "--fps", "1e9", "--html", "{out}/x.html"], "--fps"),
    (["engine", "--seeds", "0", "-o", "{out}"], "--seeds"),
    (["engine", "--seeds", "101", "-o", "{out}"], "--seeds"),
    (["engine", "--seeds", "3", "--perturbation", "1", "-o", "{out}"], "--perturbation"),
    (["engine", "--seeds", "3", "--perturbation", "0", "-o", "{out}"], "--perturbation"),
    (["engine", "--perturbation", "1e-3", "-o", "{out}"], "--perturbation"),
    (["engine", "--wheel-radius", "0.09", "-o", "{out}"], "wheels"),
    (["engine", "--robot", "camera_head_snake.toml", "--passive", "10", "-o", "{out}"],
     "--passive"),
])
def test_limits_are_refused_before_anything_is_created(capfd: pytest.CaptureFixture[str],
                                                       tmp_path: Path, argv: list[str],
                                                       flag: str) -> None:
    """Each documented limit: one line naming the option, status 2, no output folder."""
    out = tmp_path / "out"
    line = _usage_error(*_run(capfd, *[a.replace("{out}", str(out)) for a in argv]))
    assert flag in line and not out.exists()


def test_help_documents_exit_statuses_and_limits(capfd: pytest.CaptureFixture[str]) -> None:
    """`snake-pin --help` lists the exit statuses 0, 2, 3, 130 and every limit."""
    code, out, _ = _run(capfd, "--help")
    assert code == 0
    for text in ("0    done", "2    a wrong argument", "3    the run diverged",
                 "130  interrupted", "--n <= 200", "--t-final <= 1000 s", "--points <= 100000",
                 "--starts <= 10000", "0 <= --seed <= 2**32 - 1", "--seeds <= 100",
                 "--perturbation <= 0.1 rad", "--robot takes a preset"):
        assert text in out


# --------------------------------------------------------------------- smaller
BROKEN_ROBOT = 'name = "broken"\nn = 4\n[links]\nlink_length = 0.1\nmass = -1.0\ninertia = 1e-4\n'


@pytest.mark.parametrize("argv", [
    ["generate", "-o", "{out}/x.urdf"], ["info"], ["manip"], ["sweep", "arc", "-o", "{out}"],
    ["singular", "-o", "{out}"], ["simulate", "--controller", "pfl", "-o", "{out}"],
    ["engine", "-o", "{out}"], ["reproduce", "-o", "{out}"],
    ["view", "{tmp}/run.npz", "--html", "{tmp}/x.html"],
])
@pytest.mark.parametrize("robot", ["missing.toml", "broken.toml", "broken.urdf", "cobra"])
def test_every_command_refuses_a_bad_robot_in_one_line(capfd: pytest.CaptureFixture[str],
                                                       tmp_path: Path, argv: list[str],
                                                       robot: str) -> None:
    """--robot with a missing file, a negative mass, a URDF that is not XML or an unknown
    name: every command says so in one line naming the robot given, status 2, no folder."""
    (tmp_path / "broken.toml").write_text(BROKEN_ROBOT)
    (tmp_path / "broken.urdf").write_text("<robot name='x'><link name='a'>")
    _tiny().save(tmp_path / "run")
    out = tmp_path / "out"
    given = str(tmp_path / robot) if "." in robot else robot
    args = [a.replace("{out}", str(out)).replace("{tmp}", str(tmp_path)) for a in argv]
    line = _usage_error(*_run(capfd, *args, "--robot", given))
    assert given in line and not out.exists() and not (tmp_path / "x.html").exists()
    if robot == "broken.toml":
        assert "mass" in line


def test_reproduce_refuses_a_robot_its_engine_stage_cannot_put_on_wheels(
        capfd: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """A robot file whose links are shorter than the engine's wheels: reproduce refuses it
    in one line naming the stage and the robot, before any stage runs or folder exists."""
    short = tmp_path / "short.toml"
    short.write_text('name = "short"\nn = 6\n[links]\nlink_length = 0.05\nmass = 0.2\n'
                     'inertia = 1e-4\n[friction]\nc_x = 0.5\nc_y = 5.0\n')
    out = tmp_path / "report"
    line = _usage_error(*_run(capfd, "reproduce", "--robot", str(short), "-o", str(out)))
    assert "stage 'engine'" in line and "short" in line and "wheels" in line
    assert not out.exists()


def test_report_re_exports_the_json_functions() -> None:
    """snake_pin.report offers json_safe/json_text: the same functions as snake_pin._json."""
    import snake_pin._json
    import snake_pin.report

    assert snake_pin.report.json_text is snake_pin._json.json_text
    assert snake_pin.report.json_safe is snake_pin._json.json_safe


def test_json_text_is_rfc_8259() -> None:
    """NaN and infinities (Python or NumPy) become null; NumPy values become plain JSON."""
    text = json_text({"a": math.nan, "b": [math.inf, 1.5], "c": np.float64("-inf"),
                      "d": np.arange(2), "e": np.bool_(True), "f": Path("x")})
    assert text == '{"a": null, "b": [null, 1.5], "c": null, "d": [0, 1], "e": true, "f": "x"}'


def test_c_level_output_never_reaches_json_stdout(capfd: pytest.CaptureFixture[str],
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """What C code prints during a --json command (LAPACK's xerbla does) goes to stderr;
    stdout holds the one JSON object."""
    import snake_pin.runs.outputs as robot

    info = robot.info

    def noisy(*args: object) -> dict:
        ctypes.CDLL(None).printf(b" ** On entry to DLASCL parameter number  4\n")
        os.write(1, b"raw fd 1\n")
        print("python print")
        return info(*args)

    monkeypatch.setattr(robot, "info", noisy)
    code, out, err = _run(capfd, "info", "--json")
    assert code == 0 and _strict_json(out)["nq"] == 12
    assert "DLASCL" in err and "raw fd 1" in err and "python print" in err


def test_view_html_json_prints_one_object(capfd: pytest.CaptureFixture[str],
                                          tmp_path: Path) -> None:
    """view --html --json prints one JSON object naming the page it wrote."""
    _tiny().save(tmp_path / "run")
    code, out, _ = _run(capfd, "view", str(tmp_path / "run.npz"), "--html",
                        str(tmp_path / "run.html"), "--json")
    assert code == 0 and _strict_json(out)["html"] == str(tmp_path / "run.html")


def test_no_progress_bar_into_a_non_terminal(capfd: pytest.CaptureFixture[str],
                                            tmp_path: Path) -> None:
    """With stderr not a terminal, a sweep draws no progress bar: stderr stays empty."""
    code, _, err = _run(capfd, "sweep", "ts", "--points", "300", "-o", str(tmp_path))
    assert code == 0 and err == ""


def test_diverged_run_exits_3_with_its_results(capfd: pytest.CaptureFixture[str],
                                               tmp_path: Path) -> None:
    """The VI.1 PFL run breaks down: status 3 (not 0, not 130), one line saying so, the
    JSON summary with status "diverged" and the run's files written."""
    code, out, err = _run(capfd, "simulate", "--controller", "pfl", "--t-final", "5",
                          "-o", str(tmp_path), "--json")
    assert code == EXIT_FAILED
    assert err.count("\n") == 1 and "run diverged" in err and "Traceback" not in err
    data = _strict_json(out)
    assert data["status"] == "diverged" and data["t_end"] < 5
    assert Trajectory.load(tmp_path / "pfl.npz").status == "diverged"


def test_output_file_in_place_of_a_folder_is_refused(capfd: pytest.CaptureFixture[str],
                                                    tmp_path: Path) -> None:
    """-o naming an existing file is one line, status 2, the file untouched."""
    target = tmp_path / "taken"
    target.write_text("mine")
    assert "-o/--output" in _usage_error(*_run(capfd, "sweep", "arc", "-o", str(target)))
    assert target.read_text() == "mine"


# ------------------------------------------------------------------------ fuzz
def _tiny() -> Trajectory:
    return Trajectory(t=np.array([0.0, 0.1]), q=np.zeros((2, 12)), dq=np.zeros((2, 12)),
                      tau=np.zeros((2, 9)), params=SnakeParams.table1())


@pytest.fixture(scope="module")
def trajectory_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A valid trajectory and malformed ones: empty, garbage, truncated, NaN inside."""
    import meshcat  # noqa: F401  (its IPython import raises the recursion limit: not mid-fuzz)

    folder = tmp_path_factory.mktemp("runs")
    valid, _ = _tiny().save(folder / "valid")
    data = valid.read_bytes()
    (folder / "empty.npz").write_bytes(b"")
    (folder / "garbage.npz").write_bytes(b"PK\x03\x04" + bytes(range(256)) * 4)
    (folder / "truncated.npz").write_bytes(data[: len(data) // 2])
    with np.load(valid) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["q"] = np.full_like(arrays["q"], np.nan)
    np.savez(folder / "nan.npz", **arrays)
    return {name: folder / f"{name}.npz" for name in
            ("valid", "empty", "garbage", "truncated", "nan", "missing")}


BAD = ["", "nan", "inf", "-inf", "1e400", "abc", "1e12", "1000000000000", "-1", "0", "--json",
       "-pi/x", "1,,2", "é", " ", "0x10", "--", "-o"]
TEXT = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"),
               max_size=6)


def _values(*good: str) -> st.SearchStrategy[str]:
    """Half the time a value from ``good`` (which holds some wrong ones too), else junk."""
    return st.one_of(st.sampled_from(good), st.sampled_from(good), st.sampled_from(BAD), TEXT)


Q12 = ",".join(map(str, Q))
OPTIONS: dict[str, st.SearchStrategy[str]] = {
    "--robot": _values("table1", "engine", "cobra", "camera_head_snake.toml"),
    "--n": _values("2", "4", "6", "8", "12", "201", "500"),
    "--passive": _values("1", "3", "5", "7", "9", "10", "201"),
    "--free-joint": _values("1", "3", "5", "9", "10"),
    "--cx": _values("0", "0.5", "25", "1e300", "-0.5"),
    "--cy": _values("0", "0.5", "25", "-2"),
    "--ctheta": _values("0", "7e-5", "-1"),
    "--shape": _values("straight", "arc", "serpenoid", "q", "spiral"),
    "--phi0": _values("pi/5", "-pi/10", "0.3", "2*pi/3", "pi/0", "7"),
    "--alpha": _values("pi/4", "-pi/4", "0", "1e308"),
    "--ts": _values("1.5", "-1.5", "0", "2"),
    "--q": _values(Q12, "-0.8" + Q12[3:], "1,2", "1e10" + Q12[3:], "pi" + ",pi" * 11),
    "--points": _values("2", "5", "11", "1", "100001"),
    "--starts": _values("1", "2", "10001"),
    "--seed": _values("0", "7", "4294967295", "4294967296"),
    "--bound": _values("pi/2", "0.5", "7", "-1", "pi"),
    "--fps": _values("1", "20", "120", "0.5", "121"),
    "--bogus": st.just(""),
    "--no-heading": st.just(""),
    "--json": st.just(""),
}
CHEAP = {
    "info": ["--robot", "--n", "--passive", "--cx", "--cy", "--ctheta", "--json", "--bogus"],
    "manip": ["--robot", "--passive", "--shape", "--phi0", "--alpha", "--ts", "--q",
              "--free-joint", "--no-heading", "--json", "--bogus", "--n"],
    "generate": ["--robot", "--n", "--passive", "--json", "--bogus"],
    "sweep": ["--robot", "--passive", "--free-joint", "--points", "--json", "--bogus"],
    "singular": ["--robot", "--passive", "--free-joint", "--starts", "--seed", "--bound",
                 "--json", "--bogus"],
    "view": ["--fps", "--robot", "--json", "--bogus"],
}
#: Commands that would run for long: each example carries one argument sure to be wrong.
EXPENSIVE = {
    "simulate": (["--controller", "pfl"], [["--t-final", "1e12"], ["--t-final", "nan"],
                                           ["--controller", "pid"], ["--passive", "0"],
                                           ["--climb-r", "-1"], ["--cx", "inf"], ["--bogus"],
                                           ["--n", "500"]]),
    "engine": ([], [["--t-final", "1e12"], ["--mu", "0"], ["--wheel-radius", "1"],
                    ["--cone", "square"], ["--passive", "10"], ["--law", "x"], ["--n", "8"],
                    ["--seeds", "0"], ["--perturbation", "1e-3"]]),
    "reproduce": (["--quick"], [["--only", "nothing"], ["--passive", "3"], ["--cx", "1"],
                               ["--n", "500"], ["--n", "3"], ["--robot", "cobra"]]),
}


@st.composite
def command_lines(draw: st.DrawFn) -> tuple[list[str], str | None]:
    """An argument list with placeholders ({out}: a folder that does not exist yet, {tmp}:
    one that does, @run:NAME: a trajectory file), and the -o target if any."""
    command = draw(st.sampled_from(sorted(CHEAP) + sorted(EXPENSIVE)))
    argv: list[str] = [command]
    if command in EXPENSIVE:
        fixed, bad = EXPENSIVE[command]
        wrong = draw(st.sampled_from(bad))
        names = [o for o in ("--robot", "--n", "--passive", "--cx", "--cy", "--json")
                 if o not in wrong]
        for option in draw(st.lists(st.sampled_from(names), max_size=3, unique=True)):
            argv += [option] + ([draw(OPTIONS[option])] if draw(OPTIONS[option]) else [])
        return [*argv, *fixed, "-o", "{out}", *wrong], "{out}"
    if command == "sweep":
        argv.append(draw(st.sampled_from(["arc", "alpha", "ts", "spiral"])))
        argv += ["--points", draw(st.sampled_from(["2", "7", "0", "abc"]))]
    if command == "singular":
        argv += ["--starts", draw(st.sampled_from(["1", "2", "0", "x"])),
                 "--n", draw(st.sampled_from(["4", "6", "10", "3"]))]
    if command == "view":
        argv.append("@run:" + draw(st.sampled_from(
            ["valid", "empty", "garbage", "truncated", "nan", "missing"])))
        argv += ["--html", draw(st.sampled_from(["{tmp}/page.html", "{tmp}/page.txt",
                                                 "{out}/page.html"]))]
    if draw(st.booleans()):
        argv.append("--json")
    for option in draw(st.lists(st.sampled_from(CHEAP[command]), max_size=3)):
        value = draw(OPTIONS[option])
        if option in ("--starts", "--n") and command == "singular":
            continue  # keep searches small: their counts are drawn above
        argv += [option, value] if value or option not in ("--json", "--no-heading",
                                                           "--bogus") else [option]
    target = None
    if command == "generate":
        target = draw(st.sampled_from(["{out}/robot.urdf", "{out}/robot.txt"]))
        argv += ["-o", target]
    elif command == "sweep" or (command == "singular" and draw(st.booleans())):
        target = "{out}"
        argv += ["-o", target]
    return argv, target


@contextlib.contextmanager
def _scratch() -> Iterator[Path]:
    folder = Path(tempfile.mkdtemp(prefix="snake-pin-fuzz-"))
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@settings(max_examples=100, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture,
                                 HealthCheck.too_slow, HealthCheck.data_too_large])
@given(case=command_lines())
def test_any_command_line_keeps_the_contract(capfd: pytest.CaptureFixture[str],
                                             trajectory_files: dict[str, Path],
                                             case: tuple[list[str], str | None]) -> None:
    """Exit 0 or 2; on 2 one line and nothing created; never a traceback; with --json and 0
    exactly one strict JSON object; no temporary file left."""
    template, target = case
    with _scratch() as scratch:
        out = scratch / "out"

        def fill(arg: str) -> str:
            for name, path in trajectory_files.items():
                arg = arg.replace(f"@run:{name}", str(path))
            return arg.replace("{out}", str(out)).replace("{tmp}", str(scratch))

        argv = [fill(a) for a in template]
        code, stdout, stderr = _run(capfd, *argv)
        event(f"{argv[0]} -> {code}")
        assert "Traceback" not in stdout + stderr, (argv, stderr)
        assert code in (0, EXIT_USAGE), (argv, code, stderr)
        if code == EXIT_USAGE:
            _usage_error(code, stdout, stderr)
            if target is not None:
                assert not out.exists(), (argv, stderr)
        elif "--json" in argv[1:] and "--bogus" not in argv:
            _strict_json(stdout)
        assert _leftovers(scratch) == []
