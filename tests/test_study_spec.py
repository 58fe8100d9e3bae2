"""Tests of snake_pin.study.spec: the study file, its validation, expansion and run keys."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from snake_pin import SnakeParams
from snake_pin.exceptions import SnakePinError
from snake_pin.robot_file import write_robot_file
from snake_pin.sim import MAX_STEPS
from snake_pin.study import SETTINGS, StudyError, load_study, run_key
from snake_pin.study.spec import MAX_RUNS, canonical_json, parse_study

from .conftest import raised_without_blocking

REPO = Path(__file__).resolve().parent.parent
QUICK = """
[base]
t_final = 0.5
error_window = 0.1
c_y = 25.0
"""


def _write(tmp_path: Path, text: str, name: str = "study.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _refused(tmp_path: Path, text: str) -> str:
    path = _write(tmp_path, text)
    with pytest.raises(StudyError) as info:
        load_study(path)
    message = str(info.value)
    assert isinstance(info.value, SnakePinError)
    assert "\n" not in message and message.startswith(str(path) + ": ")
    return message


BAD = {
    "not TOML": ("[base\nt_final = 1", "not valid TOML"),
    "unknown table": ("[bsae]\nt_final = 1.0", "unknown table 'bsae' (did you mean 'base'?)"),
    "unknown study key": ("[study]\nbatchsize = 4", "[study] unknown key 'batchsize'"),
    "unknown setting": ("[base]\nlamda = 3.0", "[base] unknown setting 'lamda' (did you mean "
                        "'lam'?)"),
    "string for a number": ("[base]\nt_final = \"60\"", "[base] t_final must be a number"),
    "boolean for a number": ("[base]\nc_y = true", "[base] c_y must be a number"),
    "float for an integer": ("[base]\nfailed_joint = 2.0", "[base] failed_joint must be an "
                             "integer"),
    "unknown choice": ("[base]\ncontroller = \"lqr\"", "[base] controller must be one of "
                       "lyapunov, velocity, pfl, mpc"),
    "negative friction": ("[base]\nc_y = -1.0", "[base] c_y must be >= 0"),
    "batch size": ("[study]\nbatch_size = 4", "[study] batch_size is no longer a setting: "
                   "every run is one task"),
    "empty axis": ("[axes.c_y]\nvalues = []", "[axes.c_y] values is empty"),
    "empty linspace": ("[axes.c_y]\nlinspace = [1.0, 2.0, 0]", "[axes.c_y] linspace = [a, b, n] "
                       "needs an integer n >= 1"),
    "axis over nothing": ("[axes.friction]\nvalues = [1.0]", "[axes.friction] there is no "
                          "setting 'friction' to vary"),
    "axis key": ("[axes.c_y]\nvaluez = [1.0]", "[axes.c_y] unknown key 'valuez'"),
    "two forms": ("[axes.c_y]\nvalues = [1.0]\nlinspace = [1.0, 2.0, 3]", "needs exactly one of"),
    "axis over a list": ("[axes.passive]\nvalues = [1]", "[axes.passive] passive is a list"),
    "random integer axis": ("[axes.failed_joint]\nuniform = [0, 9]\nsamples = 3\nseed = 1",
                            "[axes.failed_joint] failed_joint takes int values"),
    "random without seed": ("[axes.c_y]\nuniform = [1.0, 2.0]\nsamples = 3", "needs seed = S"),
    "repeated value": ("[axes.c_y]\nvalues = [1.0, 2.0, 1]", "values[2] repeats values[0]"),
    "random out of domain": ("[axes.c_y]\nnormal = [0.0, 1.0]\nsamples = 20\nseed = 3",
                             "[axes.c_y] value"),
    "unequal samples": ("[axes.c_y]\nuniform = [1.0, 2.0]\nsamples = 3\nseed = 1\n"
                        "[axes.c_x]\nuniform = [1.0, 2.0]\nsamples = 4\nseed = 2",
                        "random axes are sampled jointly and need the same samples"),
    "base and axis": ("[base]\nc_y = 1.0\n[axes.c_y]\nvalues = [2.0]", "[axes.c_y] c_y is also "
                      "set in [base]"),
    "failed joint out of range": ("[axes.failed_joint]\nvalues = [0, 10]", "[axes.failed_joint] "
                                  "failed_joint 10 is outside 0..9"),
    "passive out of range": ("[base]\npassive = [12]", "[base] passive joint 12 is outside 1..9"),
    "failed joint already passive": ("[base]\npassive = [5]\nfailed_joint = 5",
                                     "failed_joint 5 is already passive"),
    "t_final beyond MAX_STEPS": ("[base]\nt_final = 2000.0", f"MAX_STEPS = {MAX_STEPS}"),
    "control_dt not a multiple": ("[base]\ndt = 0.0003", "must be 1..1000 times [base] dt"),
    "too many runs": ("[axes.c_y]\nlinspace = [1.0, 50.0, 400]\n[axes.c_x]\n"
                      "linspace = [0.1, 2.0, 400]", f"160000 runs, at most {MAX_RUNS}"),
    "setting of another controller": ("[base]\ncontroller = \"pfl\"\nlam = 3.0",
                                      "[base] lam applies to controller lyapunov only"),
    "setting of another model": ("[base]\nmu = 0.5", "[base] mu applies to the engine model "
                                 "only"),
    "setting not for every run": ("[base]\nlam = 3.0\n[axes.controller]\n"
                                  "values = [\"lyapunov\", \"velocity\"]",
                                  "lam applies to controller lyapunov only, and this study has "
                                  "runs with controller velocity"),
    "pfl on the engine": ("[base]\nmodel = \"engine\"\ncontroller = \"pfl\"\nrobot = \"engine\"",
                          "controller pfl runs on the viscous model only"),
    "pfl with a failed joint": ("[base]\ncontroller = \"pfl\"\n[axes.failed_joint]\n"
                                "values = [0, 3]", "controller pfl needs every joint actuated"),
    "MPC horizon shorter than a node": ("[base]\ncontroller = \"mpc\"\nnode_dt = 0.02\n"
                                        "[axes.horizon]\nvalues = [0.5, 0.01]",
                                        "[axes.horizon] MPC horizon 0.01 s is shorter than one "
                                        "node (0.02 s)"),
    "MPC re-solve not whole nodes": ("[base]\ncontroller = \"mpc\"\nresolve_period = 0.035",
                                     "[base] MPC resolve_period 0.035 s is not a whole number "
                                     "of nodes of 0.01 s"),
    "MPC negative weight": ("[base]\ncontroller = \"mpc\"\nweight_torque = -0.5",
                            "[base] weight_torque must be >= 0, got -0.5"),
    "MPC zero torque bound": ("[base]\ncontroller = \"mpc\"\n[axes.torque_bound]\n"
                              "values = [1.0, 0.0]", "[axes.torque_bound] values[1] must be > 0, "
                              "got 0.0"),
    "MPC zero iterations": ("[base]\ncontroller = \"mpc\"\niterations = 0",
                            "[base] iterations must be >= 1, got 0"),
    "MPC feedback not a switch": ("[base]\ncontroller = \"mpc\"\nfeedback = 1",
                                  "[base] feedback must be true or false, got an integer 1"),
    "MPC failed joint out of range": ("[base]\ncontroller = \"mpc\"\n[axes.failed_joint]\n"
                                      "values = [0, 10]", "[axes.failed_joint] failed_joint 10 "
                                      "is outside 0..9"),
    "MPC on the engine": ("[base]\nmodel = \"engine\"\ncontroller = \"mpc\"\n"
                          "robot = \"engine\"", "controller mpc runs on the viscous model only"),
    "MPC setting for another law": ("[base]\nhorizon = 0.3", "[base] horizon applies to "
                                    "controller mpc only"),
    "missing robot file": ("[base]\nrobot = \"nowhere.toml\"", "[base] robot 'nowhere.toml'"),
    "deep arrays": ("[axes.c_y]\nvalues = " + "[" * 100_000 + "]" * 100_000,
                    "nested deeper than 32 levels (arrays, inline tables and dotted keys "
                    "inside each other) at line 2"),
    "deep inline tables": ("[axes]\nc_y = " + "{v=" * 100_000 + "1" + "}" * 100_000,
                           "nested deeper than 32 levels"),
    "long dotted key": ("[axes]\n" + "c_y." * 100_000 + "values = [1.0]\n",
                        "nested deeper than 32 levels"),
    "over-long integer": ("[base]\nfailed_joint = " + "9" * 5000, "not valid TOML"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_study_files_are_refused_in_one_line_naming_the_key(tmp_path: Path,
                                                                case: str) -> None:
    """Each bad file gives one StudyError line with the file, the table and the key."""
    text, expected = BAD[case]
    assert expected in _refused(tmp_path, text)


def test_missing_and_oversized_files_are_refused(tmp_path: Path) -> None:
    """A missing file and one beyond MAX_STUDY_BYTES are refused in one line."""
    with pytest.raises(StudyError, match="no such study file"):
        load_study(tmp_path / "absent.toml")
    big = _write(tmp_path, "# " + "x" * (1 << 20))
    with pytest.raises(StudyError, match="larger than"):
        load_study(big)


def test_shipped_studies_validate() -> None:
    """Every studies/*.toml loads; the failure map is 10 failed joints x 4 c_y on Table 1."""
    files = sorted((REPO / "studies").glob("*.toml"))
    assert {"example.toml", "failure_map.toml"} <= {f.name for f in files}
    for file in files:
        assert load_study(file).scenarios
    spec = load_study(REPO / "studies" / "failure_map.toml")
    assert len(spec.scenarios) == 40
    assert {s["failed_joint"] for s in spec.scenarios} == set(range(10))
    assert {s.params.c_y / s.params.c_x for s in spec.scenarios} == {10.0, 25.0, 50.0, 100.0}
    assert all(s["t_final"] == 60.0 and s.controller == "lyapunov" for s in spec.scenarios)


def test_grid_is_a_product_and_random_axes_are_sampled_jointly(tmp_path: Path) -> None:
    """Grid axes cross in file order (c_y, lam, init_seed), the random point innermost."""
    spec = load_study(_write(tmp_path, QUICK.replace("c_y = 25.0\n", "") + """
[axes.c_y]
values = [10.0, 25.0]
[axes.init_noise]
uniform = [0.0, 0.1]
samples = 4
seed = 11
[axes.lam]
linspace = [4.0, 12.0, 3]
[axes.init_seed]
values = [1, 2, 3, 4]
"""))
    noise = np.random.default_rng(11).uniform(0.0, 0.1, 4)
    grid = [(s["c_y"], s["lam"], s["init_seed"]) for s in spec.scenarios[::4]]
    assert grid == [(c, lam, k) for c in (10.0, 25.0) for lam in (4.0, 8.0, 12.0)
                    for k in (1, 2, 3, 4)]
    assert [s["init_noise"] for s in spec.scenarios[:4]] == noise.tolist()
    assert len(spec.scenarios) == 2 * 3 * 4 * 4
    assert [a.setting for a in spec.random_axes] == ["init_noise"]


def test_random_axes_share_their_sample_index(tmp_path: Path) -> None:
    """Two random axes give S points (k-th draw of each), not S^2."""
    spec = load_study(_write(tmp_path, QUICK.replace("c_y = 25.0\n", "") + """
[axes.c_y]
normal = [25.0, 2.0]
samples = 5
seed = 1
[axes.lam]
uniform = [5.0, 10.0]
samples = 5
seed = 2
"""))
    assert len(spec.scenarios) == 5
    assert [s["c_y"] for s in spec.scenarios] == np.random.default_rng(1).normal(25, 2, 5).tolist()
    assert [s["lam"] for s in spec.scenarios] == \
        np.random.default_rng(2).uniform(5, 10, 5).tolist()


def test_defaults_are_resolved_into_the_settings(tmp_path: Path) -> None:
    """lam_shape = lam / 2, k_shape 0.3 with a failed joint, PFL's gait of VI.1."""
    spec = load_study(_write(tmp_path, QUICK + "lam = 6.0\n[axes.failed_joint]\n"
                             "values = [0, 4]\n"))
    plain, failed = spec.scenarios
    assert plain["lam_shape"] == 3.0 and plain["k_shape"] == 0.0
    assert failed["k_shape"] == 0.3 and failed.params.passive == (4,)
    assert plain["gait_alpha"] == math.pi / 6 and "k_v" not in plain.settings
    pfl = load_study(_write(tmp_path, QUICK + "controller = \"pfl\"\n", "pfl.toml")).scenarios[0]
    assert (pfl["gait_alpha"], pfl["gait_ts"], pfl["gait_v"]) == (math.pi / 3, 1.0, 0.18)
    assert "lam" not in pfl.settings and pfl["k_v"] == 6.0


def test_engine_runs_keep_only_engine_settings(tmp_path: Path) -> None:
    """An engine run has mu, wheel_radius, cone and no viscous-model settings."""
    spec = load_study(_write(tmp_path, "[base]\nrobot = \"engine\"\nmodel = \"engine\"\n"
                             "controller = \"velocity\"\nt_final = 1.0\n[axes.mu]\n"
                             "values = [0.5, 1.0]\n"))
    run = spec.scenarios[0]
    assert run["mu"] == 0.5 and run["wheel_radius"] == 0.03 and run["cone"] == "elliptic"
    assert "c_y" not in run.settings and "dt" not in run.settings
    assert run.params.n == 8


def test_canonical_json_is_sorted_compact_and_finite() -> None:
    """Sorted keys, no spaces, repr'd floats, -0.0 as 0.0, NaN refused."""
    assert canonical_json({"b": 0.1, "a": [-0.0, 1, "x"], "c": (2.5e-300,)}) == \
        '{"a":[0.0,1,"x"],"b":0.1,"c":[2.5e-300]}'
    with pytest.raises(ValueError):
        canonical_json({"x": float("nan")})


def test_run_key_is_stable_across_processes() -> None:
    """The same run has the same key in another interpreter with another hash seed."""
    spec = parse_study(QUICK)
    scenario = spec.scenarios[0]
    code = ("from snake_pin.study.spec import parse_study\n"
            f"print(parse_study({QUICK!r}).scenarios[0].key)")
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           env=env, check=True, timeout=120).stdout.strip()
    assert other == scenario.key
    assert scenario.key == run_key(dict(scenario.settings), scenario.params)
    assert len(scenario.key) == 64 and int(scenario.key, 16) >= 0


def _changed(value: object, setting: str) -> object:
    if isinstance(value, bool) or value is None:
        return 0.7
    if isinstance(value, float):
        return value * 1.5 + 0.01
    if isinstance(value, int):
        return value + 1
    if isinstance(value, list):
        return [*value, 3]
    choices = SETTINGS[setting].choices
    return next(c for c in choices if c != value) if choices else value + "x"


@pytest.mark.parametrize("controller", ["lyapunov", "velocity", "pfl", "mpc"])
def test_run_key_changes_with_every_setting_and_the_robot(controller: str) -> None:
    """Changing any one setting, or any robot parameter, gives another key; the robot's
    spelling alone (its content unchanged) does not."""
    scenario = parse_study(QUICK + f"controller = \"{controller}\"\n").scenarios[0]
    settings = dict(scenario.settings)
    keys = {scenario.key}
    for name, value in settings.items():
        if name == "robot":
            continue
        keys.add(run_key({**settings, name: _changed(value, name)}, scenario.params))
        assert len(keys) == 2, name
        keys.discard(next(k for k in keys if k != scenario.key))
    assert run_key({**settings, "robot": "./table1.toml"}, scenario.params) == scenario.key
    for field, value in (("mass", 0.2), ("inertia", 3e-4), ("c_theta", 1e-4),
                         ("link_length", 0.13), ("passive", (2,))):
        assert run_key(settings, scenario.params.replace(**{field: value})) != scenario.key


def test_study_hash_follows_the_runs_not_the_layout(tmp_path: Path) -> None:
    """Name and key order leave the hash; a changed value changes it."""
    one = parse_study("[study]\nname = \"a\"\n" + QUICK +
                      "[axes.lam]\nvalues = [5.0, 10.0]\n")
    two = parse_study("[axes.lam]\nvalues = [5.0, 10.0]\n[study]\nname = \"b\"\n"
                      "[base]\nc_y = 25.0\nerror_window = 0.1\nt_final = 0.5\n")
    three = parse_study(QUICK + "[axes.lam]\nvalues = [5.0, 11.0]\n")
    assert one.study_hash == two.study_hash != three.study_hash
    assert one.scenarios[0].key == three.scenarios[0].key != three.scenarios[1].key


def test_robot_files_are_read_beside_the_study_and_their_content_keys_the_run(
        tmp_path: Path) -> None:
    """A relative robot file resolves next to the study; editing it changes the keys."""
    robots = tmp_path / "robots"
    robots.mkdir()
    write_robot_file(SnakeParams(n=6, name="six"), robots / "six.toml")
    study = _write(tmp_path, "[base]\nrobot = \"robots/six.toml\"\nt_final = 0.5\n"
                   "[axes.failed_joint]\nvalues = [0, 5]\n")
    before = load_study(study)
    assert [s.params.n for s in before.scenarios] == [6, 6]
    write_robot_file(SnakeParams(n=6, name="six", mass=0.3), robots / "six.toml")
    after = load_study(study)
    assert before.scenarios[0].key != after.scenarios[0].key
    assert before.study_hash != after.study_hash
    with pytest.raises(StudyError, match=r"failed_joint 6 is outside 0\.\.5"):
        load_study(_write(tmp_path, "[base]\nrobot = \"robots/six.toml\"\n"
                          "[axes.failed_joint]\nvalues = [6]\n", "bad.toml"))


def test_a_fifo_is_refused_without_blocking(tmp_path: Path) -> None:
    """A FIFO given as the study file is refused at once, in one line naming it."""
    fifo = tmp_path / "study.toml"
    os.mkfifo(fifo)
    error = raised_without_blocking(lambda: load_study(fifo), "load_study on a FIFO")
    assert isinstance(error, StudyError)
    assert str(error) == f"{fifo}: is a FIFO, not a regular file: not a study file"


def test_one_robot_file_named_many_ways_is_one_robot(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """Relative, dotted, absolute, symlinked and copied spellings of one robot file give
    the same runs, keys and study hash; two of them on one axis are refused as one run."""
    robots = tmp_path / "robots"
    robots.mkdir()
    write_robot_file(SnakeParams(n=6, name="six"), robots / "a.toml")
    (tmp_path / "link.toml").symlink_to(robots / "a.toml")
    (tmp_path / "copy.toml").write_bytes((robots / "a.toml").read_bytes())
    monkeypatch.chdir(tmp_path)
    tail = "t_final = 0.5\n[axes.failed_joint]\nvalues = [0, 2]\n"
    spellings = ["robots/a.toml", "./robots/../robots/a.toml", str(robots / "a.toml"),
                 "link.toml", "copy.toml"]
    specs = [load_study(_write(tmp_path, f"[base]\nrobot = {name!r}\n" + tail, f"s{i}.toml"))
             for i, name in enumerate(spellings)]
    keys = {tuple(s.key for s in spec.scenarios) for spec in specs}
    assert len(keys) == 1 and len(next(iter(keys))) == 2
    assert len({spec.study_hash for spec in specs}) == 1
    message = _refused(tmp_path, f"[base]\n{tail.split(chr(10))[0]}\n[axes.robot]\n"
                       f"values = ['robots/a.toml', './robots/../robots/a.toml']\n")
    assert ("[axes.robot] robot './robots/../robots/a.toml' is the same robot as "
            "'robots/a.toml'") in message
    write_robot_file(SnakeParams(n=6, name="six", mass=0.3), tmp_path / "copy.toml")
    other = load_study(_write(tmp_path, "[base]\nrobot = 'copy.toml'\n" + tail, "o.toml"))
    assert other.study_hash != specs[0].study_hash


def test_a_physically_meaningless_robot_file_names_the_study_robot_and_field(
        tmp_path: Path) -> None:
    """A robot file with a 1e-300 kg link fails the study in one line naming the study
    file, the robot and the field."""
    (tmp_path / "tiny.toml").write_text('name = "tiny"\nn = 3\n[links]\nlink_length = 0.1\n'
                                        "mass = [0.1, 1e-300, 0.1]\ninertia = 1e-4\n")
    message = _refused(tmp_path, "[base]\nrobot = \"tiny.toml\"\n")
    assert "[base] robot 'tiny.toml'" in message and "link 2: mass must be in" in message


def test_law_settings_are_the_options_fields() -> None:
    """Each law's settings take their defaults, kinds, bounds and controllers from its options
    class (the MPC's cost weights as weight_<name>)."""
    from dataclasses import fields, is_dataclass

    from snake_pin.control.gains import default_k_phi
    from snake_pin.study.spec import LAW_OPTIONS

    seen = set()
    for controller, cls in LAW_OPTIONS.items():
        for f in fields(cls):
            if f.name in ("control_dt", "r_min", "climb_damping"):
                assert f.name not in SETTINGS or f.name == "control_dt"
                continue
            meta = f.metadata
            if is_dataclass(f.default):
                rows = [(f"weight_{g.name}", g.default, g.metadata) for g in fields(f.default)]
            elif meta["entries"]:
                rows = [(f"{f.name}_{e}", v, meta) for e, v in zip(meta["entries"], f.default,
                                                                   strict=True)]
            elif f.name == "k_phi":
                rows = [(name, v, meta) for name, v in zip(["k_phi_1", "k_phi"],
                                                           default_k_phi(2), strict=True)]
            else:
                rows = [(f.name, f.default, meta)]
            for name, default, m in rows:
                setting = SETTINGS[name]
                assert (setting.default, setting.low, setting.high, setting.open_low) == \
                    (default, m["low"], m["high"], m["open_low"]), name
                assert setting.kind == {bool: "bool", int: "int"}.get(type(default), "float"), name
                assert controller in setting.controllers, name
                seen.add(name)
    owned = {name for name, s in SETTINGS.items() if set(s.controllers) != set(LAW_OPTIONS)
             and s.models == ("viscous",)}
    assert owned == seen


def test_mpc_settings_are_its_options_and_cost_weights() -> None:
    """Every MPC setting's lower bound is where its class itself starts refusing (the bound
    accepted unless open, below it refused), and a run's settings build those options."""
    from dataclasses import fields, replace

    from snake_pin.control import MPCOptions
    from snake_pin.ocp import CostWeights

    expected = {f.name: (MPCOptions, f.name) for f in fields(MPCOptions) if f.name != "weights"}
    expected |= {f"weight_{f.name}": (CostWeights, f.name) for f in fields(CostWeights)}
    mpc_only = {name for name, s in SETTINGS.items() if s.controllers == ("mpc",)}
    assert mpc_only == set(expected)
    for name, (cls, field) in expected.items():
        setting = SETTINGS[name]
        assert setting.help, name
        if setting.kind == "bool":
            continue
        assert setting.low is not None and setting.high is None, name
        low = int(setting.low) if setting.kind == "int" else setting.low
        below = low - 1 if setting.kind == "int" else low - 1e-9
        if setting.open_low:
            with pytest.raises(SnakePinError):
                replace(cls(), **{field: low})
        else:
            replace(cls(), **{field: low})
        with pytest.raises(SnakePinError):
            replace(cls(), **{field: below})
    spec = parse_study(QUICK + 'controller = "mpc"\nhorizon = 0.3\nfeedback = false\n'
                       "weight_torque = 0.25\niterations = 3\n")
    options = law_options_of(spec)
    assert options == MPCOptions(horizon=0.3, feedback=False, iterations=3,
                                 weights=CostWeights(torque=0.25))


def law_options_of(spec: Any) -> Any:
    from snake_pin.study.spec import law_options

    scenario = spec.scenarios[0]
    return law_options(scenario.settings, scenario.params.n - 1)


@pytest.mark.parametrize(("controller", "passive"), [("lyapunov", "[3]"), ("velocity", "[]"),
                                                     ("pfl", "[]"), ("mpc", "[3]")])
def test_a_run_builds_the_default_options(controller: str, passive: str) -> None:
    """A study run without gains builds its controller from the options' own defaults."""
    from snake_pin.control import LyapunovOptions, MPCOptions, PFLOptions, QuasiStaticOptions
    from snake_pin.study.spec import law_options

    spec = parse_study(QUICK + f'controller = "{controller}"\npassive = {passive}\n')
    scenario = spec.scenarios[0]
    joints = scenario.params.n - 1
    expected = {"lyapunov": LyapunovOptions().resolved(joints, passive=True),
                "velocity": QuasiStaticOptions(k_phi=tuple(
                    LyapunovOptions().resolved(joints).k_phi)),
                "pfl": PFLOptions(), "mpc": MPCOptions()}[controller]
    assert law_options(scenario.settings, joints) == expected
