"""URDF generator: committed files, loaders (Pinocchio, yourdfpy, MuJoCo), passive marks."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import yourdfpy

from snake_pin import SnakeParams
from snake_pin.urdf import build_urdf, passive_joints, urdf_string, write_urdf

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = {"table1": ROOT / "urdf" / "snake_table1.urdf",
             "engine": ROOT / "urdf" / "snake_engine.urdf"}


@pytest.mark.parametrize("robot", sorted(COMMITTED))
def test_committed_urdf_regenerates_byte_for_byte(robot: str, tmp_path: Path) -> None:
    """urdf/snake_<robot>.urdf is exactly what the generator writes today."""
    out = write_urdf(SnakeParams.preset(robot), tmp_path / f"{robot}.urdf")
    assert out.read_bytes() == COMMITTED[robot].read_bytes()


@pytest.mark.parametrize("robot", sorted(COMMITTED))
def test_loads_in_pinocchio_with_planar_base(robot: str) -> None:
    """Pinocchio sees a planar root (nq = n + 3, nv = n + 2) and the link inertias."""
    params = SnakeParams.preset(robot)
    model = pin.buildModelFromUrdf(str(COMMITTED[robot]))
    assert model.names[1] == "base"
    assert (model.nq, model.nv) == (params.n + 3, params.n + 2)
    inertia = model.inertias[1]
    assert inertia.mass == pytest.approx(params.mass)
    assert inertia.lever == pytest.approx([params.half_length, 0, 0])
    assert inertia.inertia[2, 2] == pytest.approx(params.inertia)


@pytest.mark.parametrize("robot", sorted(COMMITTED))
def test_validates_in_yourdfpy(robot: str) -> None:
    """yourdfpy loads the file and its validate() accepts it."""
    urdf = yourdfpy.URDF.load(str(COMMITTED[robot]), load_meshes=False)
    assert urdf.validate()
    assert len(urdf.actuated_joints) == SnakeParams.preset(robot).n  # base + n - 1 joints


@pytest.mark.parametrize("robot", sorted(COMMITTED))
def test_loads_in_mujoco(robot: str) -> None:
    """MuJoCo compiles the file: 2 slides + 1 hinge for the base, n - 1 hinges."""
    params = SnakeParams.preset(robot)
    model = mujoco.MjModel.from_xml_path(str(COMMITTED[robot]))
    assert model.nv == params.n + 2
    assert model.body_mass[1:].sum() == pytest.approx(params.total_mass)


def test_passive_joint_is_marked_by_zero_effort() -> None:
    """A passive joint has effort 0; loaders (Pinocchio, passive_joints) can tell."""
    params = SnakeParams.table1(passive=(5,))
    text = urdf_string(params)
    assert passive_joints(text) == (5,)
    model = pin.buildModelFromXML(text)
    efforts = model.effortLimit[3:]  # after x, y, theta (planar uses 4 q but 3 v)
    assert np.count_nonzero(efforts == 0.0) == 1 and efforts[4] == 0.0


def test_write_refuses_bad_paths(tmp_path: Path) -> None:
    """Wrong suffix and missing folders are refused without writing anything."""
    from snake_pin import ParameterError

    with pytest.raises(ParameterError):
        write_urdf(SnakeParams.table1(), tmp_path / "robot.xml")
    with pytest.raises(ParameterError):
        write_urdf(SnakeParams.table1(), tmp_path / "missing" / "robot.urdf")
    for path in (None, True, [1.0], {}):
        with pytest.raises(ParameterError, match=r"^path must be a file path, got "):
            write_urdf(SnakeParams.table1(), path)  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("build", [build_urdf, urdf_string])
def test_bad_arguments_are_one_line_naming_them(build: Callable[..., object],
                                                tmp_path: Path) -> None:
    """Anything but SnakeParams, or a floating_base that is not a bool, is refused in
    one ParameterError line naming the argument."""
    from snake_pin import ParameterError

    for params in (None, "table1", {"n": 3}, SnakeParams.table1().to_dict()):
        with pytest.raises(ParameterError, match=r"^params must be a SnakeParams, got "):
            build(params)
        with pytest.raises(ParameterError, match=r"^params must be a SnakeParams, got "):
            write_urdf(params, tmp_path / "robot.urdf")  # type: ignore[arg-type]
    for flag in (None, "yes", 1, [True]):
        with pytest.raises(ParameterError, match=r"^floating_base must be True or False"):
            build(SnakeParams.table1(), floating_base=flag)
    assert list(tmp_path.iterdir()) == []
