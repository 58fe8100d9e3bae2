"""Robot files (TOML), URDF import, the --robot lookup and the shipped robots."""

from __future__ import annotations

import os
import shutil
import tomllib
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import yourdfpy
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from lxml import etree

from snake_pin import ParameterError, Snake, SnakeParams
from snake_pin.exceptions import RobotFileError
from snake_pin.params import LINK_FIELDS, ROBOTS
from snake_pin.robot_file import (
    FRICTION_KEYS,
    load_robot,
    read_robot_file,
    read_urdf,
    robot_file_string,
    robot_paths,
    write_robot_file,
)
from snake_pin.urdf import urdf_string, write_urdf
from tests.conftest import heterogeneous_params, raised_without_blocking, random_state

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data"
THIRD_PARTY = DATA / "third_party_snake.urdf"
EXAMPLE = ROOT / "examples" / "robots" / "camera_head_snake.toml"


def _one_line_naming(exc: pytest.ExceptionInfo[BaseException], path: Path,
                     *names: str) -> None:
    """The error is one line naming the file and each of ``names``."""
    message = str(exc.value)
    assert "\n" not in message, message
    assert str(path) in message, message
    for name in names:
        assert name in message, (name, message)


# --------------------------------------------------------------------- TOML round trip
def _examples(rng: np.random.Generator) -> list[SnakeParams]:
    return [SnakeParams.table1(), SnakeParams.engine(), SnakeParams.table1(passive=(2, 5)),
            heterogeneous_params(rng, 4, friction="none"),
            heterogeneous_params(rng, 10, passive=(3,)),
            heterogeneous_params(rng, 30, friction="isotropic"),
            SnakeParams(n=3, mass=(0.1, 0.2, 0.3), name="mixed")]


def test_robot_file_round_trip(tmp_path: Path, rng: np.random.Generator) -> None:
    """params -> TOML -> params is the identity (uniform, per-link, passive, CM offsets)."""
    for params in _examples(rng):
        path = write_robot_file(params, tmp_path / f"{params.name}.toml")
        assert read_robot_file(path) == params


def test_written_file_is_plain_toml(rng: np.random.Generator) -> None:
    """tomllib reads the writer's text: scalars stay scalars, per-link fields are arrays."""
    params = heterogeneous_params(rng, 10, passive=(4,))
    doc = tomllib.loads(robot_file_string(params))
    assert set(doc) == {"name", "n", "passive", "links", "friction"}
    assert doc["links"]["mass"] == list(params.mass)
    assert doc["friction"]["c_theta"] == list(params.c_theta)
    assert doc["passive"] == [4]
    uniform = tomllib.loads(robot_file_string(SnakeParams.table1()))
    assert uniform["links"] == {"link_length": 0.12, "mass": 0.182, "inertia": 2.2e-4}
    assert "passive" not in uniform
    assert set(uniform["links"]) | set(uniform["friction"]) | {"com_offset"} == set(LINK_FIELDS)


def test_toml_urdf_snake_round_trip(tmp_path: Path, rng: np.random.Generator) -> None:
    """params -> TOML -> URDF -> params -> Snake: same H and h (friction in) to 1e-12."""
    for n in (4, 10):
        params = heterogeneous_params(rng, n, passive=(2,))
        from_toml = read_robot_file(write_robot_file(params, tmp_path / "robot.toml"))
        back = read_urdf(write_urdf(from_toml, tmp_path / "robot.urdf"))
        assert back == params
        original, rebuilt = Snake(params), Snake(back)
        for _ in range(20):
            q, dq = random_state(rng, n)
            scale_h = np.max(np.abs(original.inertia_matrix(q)))
            scale_b = np.max(np.abs(original.bias(q, dq)))
            assert np.max(np.abs(rebuilt.inertia_matrix(q) - original.inertia_matrix(q))) \
                <= 1e-12 * scale_h
            assert np.max(np.abs(rebuilt.bias(q, dq) - original.bias(q, dq))) <= 1e-12 * scale_b


# ------------------------------------------------------------------------ URDF import
@pytest.mark.parametrize("robot", ROBOTS)
def test_read_committed_urdf_gives_the_preset(robot: str) -> None:
    """urdf/snake_<preset>.urdf reads back as the preset, friction and name included."""
    assert read_urdf(ROOT / "urdf" / f"snake_{robot}.urdf") == SnakeParams.preset(robot)


def test_read_generated_urdf_gives_back_params(tmp_path: Path, rng: np.random.Generator) -> None:
    """Generated URDFs of per-link robots read back equal (friction, passive, CM, name)."""
    for params in _examples(rng):
        assert read_urdf(write_urdf(params, tmp_path / "robot.urdf")) == params


def test_third_party_urdf() -> None:
    """A URDF not written by us: camera merged, names, continuous/-z joints, zero friction."""
    params = read_urdf(THIRD_PARTY)
    assert params.n == 4 and params.name == "Acme_Crawler_3" and params.passive == (2,)
    np.testing.assert_allclose(params.link_lengths, [0.2, 0.15, 0.15, 0.16], rtol=1e-12)
    np.testing.assert_allclose(params.masses, [0.7, 0.4, 0.4, 0.5], rtol=1e-12)
    np.testing.assert_allclose(params.inertias, [3.44e-3, 1.2e-3, 1e-3, 9e-4], rtol=1e-12)
    np.testing.assert_allclose(params.com_offsets, [0.08, 0.07, 0.075, 0.06], rtol=1e-12)
    for key in FRICTION_KEYS:
        assert np.all(params.per_link(key) == 0.0)


def test_friction_argument(tmp_path: Path) -> None:
    """Each coefficient passed wins; the others come from <snake_pin>, else zero."""
    params = read_urdf(THIRD_PARTY, friction={"c_x": 0.5, "c_y": [1.0, 2.0, 3.0, 4.0]})
    assert params.c_x == 0.5 and params.c_y == (1.0, 2.0, 3.0, 4.0) and params.c_theta == 0.0
    ours = write_urdf(SnakeParams.engine(), tmp_path / "engine.urdf")
    mixed = read_urdf(ours, friction={"c_y": 9.0})
    assert (mixed.c_x, mixed.c_y, mixed.c_theta) == (0.5, 9.0, 1.0e-4)
    with pytest.raises(ParameterError, match=r"friction.*'cx'"):
        read_urdf(THIRD_PARTY, friction={"cx": 1.0})
    with pytest.raises(ParameterError, match="friction: link 2: c_y must be non-negative"):
        read_urdf(THIRD_PARTY, friction={"c_y": [1.0, -1.0, 1.0, 1.0]})


def _edit(source: str, edit: Callable[[etree._Element], None]) -> bytes:
    root = etree.fromstring(source.encode())
    edit(root)
    return etree.tostring(root)


@pytest.mark.parametrize("joint_type", ["floating", "planar", "fixed"])
def test_leading_base_link_is_stripped(tmp_path: Path, joint_type: str) -> None:
    """A massless root (world) joined to the head by a floating/planar/fixed joint is dropped."""
    def add_world(root: etree._Element) -> None:
        root.insert(0, etree.fromstring('<link name="world"/>'))
        root.append(etree.fromstring(
            f'<joint name="world_joint" type="{joint_type}"><parent link="world"/>'
            f'<child link="base_link"/></joint>'))

    path = tmp_path / "with_world.urdf"
    path.write_bytes(_edit(THIRD_PARTY.read_text(), add_world))
    assert read_urdf(path) == read_urdf(THIRD_PARTY)


def _element(root: etree._Element, tag: str, name: str) -> etree._Element:
    return root.find(f"{tag}[@name='{name}']")


def _set(tag: str, name: str, child: str | None, **attributes: str
         ) -> Callable[[etree._Element], None]:
    def edit(root: etree._Element) -> None:
        element = _element(root, tag, name)
        if child is not None:
            found = element.find(child)
            if found is None:
                found = etree.SubElement(element, child.rsplit("/", 1)[-1])
            element = found
        for key, value in attributes.items():
            element.set(key, value)
    return edit


def _remove(tag: str, name: str, path: str) -> Callable[[etree._Element], None]:
    def edit(root: etree._Element) -> None:
        element = _element(root, tag, name)
        found = element.find(path)
        found.getparent().remove(found)
    return edit


def _append(*xml: str) -> Callable[[etree._Element], None]:
    def edit(root: etree._Element) -> None:
        for text in xml:
            root.append(etree.fromstring(text))
    return edit


def _friction(which: str, **attributes: str) -> Callable[[etree._Element], None]:
    def edit(root: etree._Element) -> None:
        item = root.find(f"snake_pin/link_friction[@link='{which}']")
        for key, value in attributes.items():
            item.set(key, value)
    return edit


_INERTIAL = ('<inertial><mass value="0.1"/><inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" '
             'iyz="0" izz="1e-5"/></inertial>')
_FIN = (f'<link name="fin">{_INERTIAL}</link>',
        '<joint name="fin_joint" type="revolute"><parent link="link_2"/><child link="fin"/>'
        '<origin xyz="0.06 0 0"/><axis xyz="0 0 1"/>'
        '<limit effort="1" lower="-1" upper="1" velocity="1"/></joint>')

BAD_URDFS: dict[str, tuple[Callable[[etree._Element], None], tuple[str, ...]]] = {
    "branched tree": (_append(*_FIN), ("'link_2'", "branched", "'fin_joint'")),
    "joint about x": (_set("joint", "joint_3", "axis", xyz="1 0 0"), ("'joint_3'", "not z")),
    "joint without axis": (_remove("joint", "joint_3", "axis"), ("'joint_3'", "not z")),
    "prismatic joint": (_set("joint", "joint_3", None, type="prismatic"),
                        ("'joint_3'", "prismatic")),
    "floating joint in the chain": (_set("joint", "joint_3", None, type="floating"),
                                    ("'joint_3'", "floating")),
    "unknown joint type": (_set("joint", "joint_2", None, type="ball"), ("'joint_2'", "ball")),
    "mimic joint": (_set("joint", "joint_2", "mimic", joint="joint_1"), ("'joint_2'", "mimic")),
    "missing inertial": (_remove("link", "link_4", "inertial"), ("'link_4'", "<inertial>")),
    "inertial without mass": (_remove("link", "link_4", "inertial/mass"),
                              ("'link_4'", "<mass")),
    "inertial without inertia": (_remove("link", "link_4", "inertial/inertia"),
                                 ("'link_4'", "<inertia>")),
    "non-finite mass": (_set("link", "link_2", "inertial/mass", value="nan"),
                        ("'link_2'", "non-finite")),
    "zero mass": (_set("link", "link_3", "inertial/mass", value="0"), ("'link_3'", "mass")),
    "CM off the x axis": (_set("link", "link_2", "inertial/origin", xyz="0.06 0.01 0"),
                          ("'link_2'", "off the link's x axis")),
    "CM beyond the link": (_set("link", "link_2", "inertial/origin", xyz="0.5 0 0"),
                           ("'link_2'", "outside the link")),
    "rotated joint origin": (_set("joint", "joint_2", "origin", rpy="0 0 0.3"),
                             ("'joint_2'", "rpy")),
    "joint origin off the x axis": (_set("joint", "joint_2", "origin", xyz="0.1 0.05 0"),
                                    ("'joint_2'", "+x axis")),
    "joint origin backwards": (_set("joint", "joint_2", "origin", xyz="-0.12 0 0"),
                               ("'joint_2'", "+x axis")),
    "link with two parents": (_append('<joint name="extra" type="fixed"><parent link="link_1"/>'
                                      '<child link="link_3"/></joint>'),
                              ("'link_3'", "two joints", "'extra'")),
    "disconnected link": (_append('<link name="stray"/>'), ("'stray'", "roots")),
    "joint to an unknown link": (_set("joint", "joint_2", "child", link="nowhere"),
                                 ("'joint_2'", "'nowhere'")),
    "duplicate link": (_append(f'<link name="link_2">{_INERTIAL}</link>'),
                       ("'link_2'", "twice")),
    "massive world before a planar joint": (
        _append(), ()),  # replaced below (needs an inertial on world)
    "snake_pin version 2": (lambda root: root.find("snake_pin").set("version", "2"),
                            ("<snake_pin>", "version '2'")),
    "friction for an unknown link": (_friction("link_2", link="tail"),
                                     ("link_friction", "'tail'")),
    "friction not a number": (_friction("link_3", c_x="abc"),
                              ("'link_3'", "c_x", "'abc'")),
    "friction missing for a link": (
        lambda root: root.find("snake_pin").remove(
            root.find("snake_pin/link_friction[@link='link_3']")), ("'link_3'",)),
    "negative friction": (_friction("link_2", c_y="-1"), ("link 2 ('link_2')", "c_y")),
}


def _massive_world(root: etree._Element) -> None:
    _element(root, "link", "world").append(etree.fromstring(_INERTIAL))


BAD_URDFS["massive world before a planar joint"] = (_massive_world, ("'base'", "planar"))


@pytest.mark.parametrize("case", sorted(BAD_URDFS))
def test_bad_urdf_is_one_line_naming_the_element(case: str, tmp_path: Path) -> None:
    """Each malformed or unsupported URDF is one RobotFileError line naming file and element."""
    edit, names = BAD_URDFS[case]
    path = tmp_path / "bad.urdf"
    path.write_bytes(_edit(urdf_string(SnakeParams.table1(n=5)), edit))
    with pytest.raises(RobotFileError) as exc:
        read_urdf(path)
    _one_line_naming(exc, path, *names)


BAD_URDF_TEXTS = {
    "not XML": (b"hello, I am not a robot", ("not XML",)),
    "not a robot": (b"<sdf version='1.6'/>", ("<sdf>",)),
    "no robot name": (b"<robot><link name='a'/></robot>", ("name",)),
    "DTD with entities": (b'<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY x "y">]>'
                          b'<robot name="r"><link name="a"/></robot>', ("DTD",)),
    "a loop of joints": (b'<robot name="r"><link name="a"/><link name="b"/>'
                         b'<joint name="j1" type="fixed"><parent link="a"/><child link="b"/>'
                         b'</joint><joint name="j2" type="fixed"><parent link="b"/>'
                         b'<child link="a"/></joint></robot>', ("loop",)),
    "one link": (f'<robot name="r"><link name="a">{_INERTIAL}</link></robot>'.encode(),
                 ("'a'", "at least 2 links")),
}


@pytest.mark.parametrize("case", sorted(BAD_URDF_TEXTS))
def test_bad_urdf_text(case: str, tmp_path: Path) -> None:
    """Non-URDF documents are one RobotFileError line naming the file and what is wrong."""
    text, names = BAD_URDF_TEXTS[case]
    path = tmp_path / "bad.urdf"
    path.write_bytes(text)
    with pytest.raises(RobotFileError) as exc:
        read_urdf(path)
    _one_line_naming(exc, path, *names)


@pytest.mark.parametrize("reader", [read_urdf, read_robot_file])
def test_missing_file_and_folder(reader: Callable[[Path], SnakeParams], tmp_path: Path) -> None:
    """A missing file or a folder is one line naming it."""
    with pytest.raises(RobotFileError, match="no such") as exc:
        reader(tmp_path / "missing.file")
    _one_line_naming(exc, tmp_path / "missing.file")
    with pytest.raises(RobotFileError, match="folder") as exc:
        reader(tmp_path)
    _one_line_naming(exc, tmp_path)


# ------------------------------------------------------------------- TOML robot files
VALID = """\
name = "three"
n = 3
passive = [1]

[links]
link_length = [0.2, 0.1, 0.1]
mass = [0.5, 0.2, 0.3]
inertia = 1e-3
com_offset = [0.08, 0.05, 0.05]

[friction]
c_x = 0.5
c_y = [5.0, 5.0, 6.0]
c_theta = 1e-4
"""


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "robot.toml"
    path.write_text(text)
    return path


def test_valid_robot_file(tmp_path: Path) -> None:
    """The file's values become the parameters (per-link arrays, scalars, passive, name)."""
    params = read_robot_file(_write(tmp_path, VALID))
    assert params == SnakeParams(n=3, link_length=(0.2, 0.1, 0.1), mass=(0.5, 0.2, 0.3),
                                 inertia=1e-3, com_offset=(0.08, 0.05, 0.05), c_x=0.5,
                                 c_y=(5.0, 5.0, 6.0), c_theta=1e-4, passive=(1,), name="three")


def test_link_tables_equal_link_arrays(tmp_path: Path) -> None:
    """[[link]] tables give the same robot as [links] arrays; a missing com_offset is the middle."""
    text = """\
name = "three"
passive = [1]

[[link]]
link_length = 0.2
mass = 0.5
inertia = 1e-3
com_offset = 0.08

[[link]]
link_length = 0.1
mass = 0.2
inertia = 1e-3

[[link]]
link_length = 0.1
mass = 0.3
inertia = 1e-3
com_offset = 0.05

[friction]
c_x = 0.5
c_y = [5.0, 5.0, 6.0]
c_theta = 1e-4
"""
    assert read_robot_file(_write(tmp_path, text)) == read_robot_file(_write(tmp_path, VALID))


def _replace(old: str, new: str) -> str:
    assert old in VALID
    return VALID.replace(old, new)


BAD_FILES = {
    "unknown top-level key": (VALID + 'colour = "red"\n', ("'colour'",)),
    "unknown [links] key": (_replace("mass =", "masss ="), ("[links]", "'masss'")),
    "unknown [friction] key": (_replace("c_theta", "c_z"), ("[friction]", "'c_z'")),
    "missing name": (_replace('name = "three"\n', ""), ("name is missing",)),
    "name not a string": (_replace('"three"', "3"), ("name must be a string",)),
    "name with a space": (_replace('"three"', '"my robot"'), ("name", "'my robot'")),
    "missing mass": (_replace("mass = [0.5, 0.2, 0.3]\n", ""), ("[links] mass is missing",)),
    "no links": (VALID.split("[links]")[0], ("links are missing",)),
    "string mass": (_replace("mass = [0.5, 0.2, 0.3]", 'mass = "heavy"'),
                    ("mass", "'heavy'")),
    "string in an array": (_replace("[0.5, 0.2, 0.3]", '[0.5, "x", 0.3]'),
                           ("link 2: mass", "'x'")),
    "boolean inertia": (_replace("inertia = 1e-3", "inertia = true"), ("inertia", "True")),
    "negative inertia": (_replace("inertia = 1e-3", "inertia = -1"),
                         ("inertia must be positive", "-1")),
    "negative per-link mass": (_replace("[0.5, 0.2, 0.3]", "[0.5, -0.2, 0.3]"),
                               ("link 2: mass must be positive",)),
    "negative friction": (_replace("c_x = 0.5", "c_x = -0.5"), ("c_x must be non-negative",)),
    "non-finite value": (_replace("inertia = 1e-3", "inertia = nan"), ("inertia", "finite")),
    "huge integer": (_replace("inertia = 1e-3", "inertia = " + "9" * 400),
                     ("[links] inertia", "finite")),
    "arrays of different lengths": (_replace("n = 3\n", "").replace(
        "[0.5, 0.2, 0.3]", "[0.5, 0.2]"), ("different lengths", "[links] mass has 2")),
    "n against the arrays": (_replace("n = 3", "n = 4"), ("n = 4", "has 3")),
    "n not an integer": (_replace("n = 3", "n = 3.0"), ("n must be an integer",)),
    "n missing, scalars only": (
        'name = "s"\n[links]\nlink_length = 0.1\nmass = 0.1\ninertia = 1e-4\n',
        ("n is missing",)),
    "too few links": ('name = "s"\nn = 1\n[links]\nlink_length = 0.1\nmass = 0.1\n'
                      'inertia = 1e-4\n', ("n must lie in",)),
    "CM beyond the link": (_replace("[0.08, 0.05, 0.05]", "[0.08, 0.5, 0.05]"),
                           ("link 2: com_offset",)),
    "passive out of range": (_replace("passive = [1]", "passive = [9]"), ("passive joint 9",)),
    "passive not a list": (_replace("passive = [1]", 'passive = "1"'), ("passive",)),
    "links not a table": ('name = "s"\nlinks = 3\n', ("links must be a table",)),
    "friction not a table": (VALID.split("[friction]")[0].replace(
        "n = 3\n", "n = 3\nfriction = 1\n"), ("friction must be a table",)),
    "both [links] and [[link]]": (
        VALID + "\n[[link]]\nlink_length = 0.1\nmass = 0.1\ninertia = 1e-4\n",
        ("either",)),
    "link not tables": ('name = "s"\nlink = 3\n', ("[[link]]",)),
    "not TOML": ('name = "three"\nmass = \n', ("not valid TOML", "line 2")),
    "urdf and [links]": (_replace('name = "three"', 'name = "three"\nurdf = "x.urdf"'),
                         ("urdf", "[links]")),
    "urdf not a string": ('name = "s"\nurdf = 3\n', ("urdf must be a file name",)),
    "urdf missing": ('name = "s"\nurdf = "nowhere.urdf"\n', ("nowhere.urdf", "no such URDF")),
}

BAD_LINK_TABLES = {
    "missing key": ({"mass": None}, ("[[link]] 2: mass is missing",)),
    "unknown key": ({"colour": '"red"'}, ("[[link]] 2: unknown key 'colour'",)),
    "string value": ({"inertia": '"big"'}, ("[[link]] 2: inertia must be a number", "'big'")),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_robot_file_is_one_line_naming_the_field(case: str, tmp_path: Path) -> None:
    """Each bad robot file is one RobotFileError line naming the file and the field (link)."""
    text, names = BAD_FILES[case]
    path = _write(tmp_path, text)
    with pytest.raises(RobotFileError) as exc:
        read_robot_file(path)
    _one_line_naming(exc, path, *names)


@pytest.mark.parametrize("case", sorted(BAD_LINK_TABLES))
def test_bad_link_table(case: str, tmp_path: Path) -> None:
    """A bad [[link]] entry names the entry and the key."""
    change, names = BAD_LINK_TABLES[case]
    entries = []
    for i in range(3):
        entry = {"link_length": "0.1", "mass": "0.2", "inertia": "1e-3"}
        if i == 1:
            for key, value in change.items():
                if value is None:
                    entry.pop(key)
                else:
                    entry[key] = value
        entries.append("[[link]]\n" + "".join(f"{k} = {v}\n" for k, v in entry.items()))
    path = _write(tmp_path, 'name = "t"\n\n' + "\n".join(entries))
    with pytest.raises(RobotFileError) as exc:
        read_robot_file(path)
    _one_line_naming(exc, path, *names)


def test_not_utf8_and_too_large(tmp_path: Path) -> None:
    """Binary and oversized files are refused in one line before parsing."""
    path = tmp_path / "robot.toml"
    path.write_bytes(b"name = \"\xff\xfe\"\n")
    with pytest.raises(RobotFileError, match="not UTF-8") as exc:
        read_robot_file(path)
    _one_line_naming(exc, path)
    path.write_bytes(b"#" * ((1 << 20) + 1))
    with pytest.raises(RobotFileError, match="larger than") as exc:
        read_robot_file(path)
    _one_line_naming(exc, path)


_TOKENS = ['"x"', "-1", "0", "1e999", "nan", "true", "[]", "[1, 2]", "[[1]]", "{a = 1}",
           "9" * 30, "1979-05-27", "[0.1, 0.1, 0.1, 0.1]", "2.5"]
_KEYS = ["name", "n", "passive", "mass", "c_y", "com_offset", "link_length", "urdf", "zz",
         "[links]", "[friction]", "[[link]]"]


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(st.integers(0, 30), st.sampled_from(["delete", "value", "insert",
                                                              "char"]),
                          st.sampled_from(_TOKENS), st.sampled_from(_KEYS),
                          st.characters(codec="utf-8")), min_size=1, max_size=3))
def test_mutated_robot_files(tmp_path: Path, mutations: list[tuple]) -> None:
    """Random mutations of a valid file give valid parameters or a one-line RobotFileError."""
    lines = VALID.splitlines()
    for index, operation, token, key, char in mutations:
        i = index % len(lines)
        if operation == "delete":
            del lines[i]
        elif operation == "value" and "=" in lines[i]:
            lines[i] = lines[i].split("=")[0] + "= " + token
        elif operation == "insert":
            lines.insert(i, key if key.startswith("[") else f"{key} = {token}")
        elif operation == "char" and lines[i]:
            j = index % len(lines[i])
            lines[i] = lines[i][:j] + char + lines[i][j + 1:]
        if not lines:
            lines = [""]
    path = _write(tmp_path, "\n".join(lines) + "\n")
    try:
        params = read_robot_file(path)
    except RobotFileError as exc:
        assert "\n" not in str(exc) and str(path) in str(exc)
    else:
        assert isinstance(params, SnakeParams)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(st.integers(0, 10_000), st.sampled_from(
    ["0", "-1", "nan", "abc", "1 0 0", "0 0 1", "", "1e308", "link_1", "fixed", "0.05 0 0"])),
    min_size=1, max_size=3))
def test_mutated_urdfs(tmp_path: Path, mutations: list[tuple[int, str]]) -> None:
    """Random attribute values in our URDF give valid parameters or a one-line RobotFileError."""
    root = etree.fromstring(urdf_string(SnakeParams.table1(n=4)).encode())
    attributes = [(element, key) for element in root.iter() for key in element.attrib]
    for index, value in mutations:
        element, key = attributes[index % len(attributes)]
        element.set(key, value)
    path = tmp_path / "mutated.urdf"
    path.write_bytes(etree.tostring(root))
    try:
        params = read_urdf(path)
    except RobotFileError as exc:
        assert "\n" not in str(exc) and str(path) in str(exc)
    else:
        assert isinstance(params, SnakeParams)


# ------------------------------------------------------------- robot files naming a URDF
def test_robot_file_naming_a_urdf(tmp_path: Path) -> None:
    """urdf = ... takes geometry from the URDF, friction from [friction] then <snake_pin>."""
    shutil.copy(THIRD_PARTY, tmp_path / "crawler.urdf")
    write_urdf(SnakeParams.engine(), tmp_path / "engine.urdf")
    plain = _write(tmp_path, 'name = "crawler"\nurdf = "crawler.urdf"\n')
    params = read_robot_file(plain)
    assert params == read_urdf(THIRD_PARTY).replace(name="crawler")
    assert params.c_y == 0.0  # no [friction], no <snake_pin>: zero
    with_friction = _write(tmp_path, 'name = "crawler"\nurdf = "crawler.urdf"\npassive = []\n'
                                     '[friction]\nc_y = [1.0, 2.0, 3.0, 4.0]\n')
    params = read_robot_file(with_friction)
    assert params.c_y == (1.0, 2.0, 3.0, 4.0) and params.c_x == 0.0 and params.passive == ()
    ours = read_robot_file(_write(tmp_path, 'name = "mine"\nurdf = "engine.urdf"\n'
                                            '[friction]\nc_y = 7.0\n'))
    assert (ours.c_x, ours.c_y, ours.c_theta) == (0.5, 7.0, 1.0e-4)  # the rest from <snake_pin>
    mismatch = _write(tmp_path, 'name = "crawler"\nn = 5\nurdf = "crawler.urdf"\n')
    with pytest.raises(RobotFileError) as exc:
        read_robot_file(mismatch)
    _one_line_naming(exc, mismatch, "n = 5", "4 links")
    (tmp_path / "broken.urdf").write_bytes(_edit(
        THIRD_PARTY.read_text(), _set("joint", "yaw_2", "axis", xyz="0 1 0")))
    broken = _write(tmp_path, 'name = "crawler"\nurdf = "broken.urdf"\n')
    with pytest.raises(RobotFileError) as exc:
        read_robot_file(broken)
    _one_line_naming(exc, broken, "broken.urdf", "'yaw_2'")


# ------------------------------------------------------------------ shipped robots, lookup
def test_example_robot_has_a_heavier_longer_head() -> None:
    """The shipped example: 8..16 links, the head longer and heavier than any body link."""
    params = read_robot_file(EXAMPLE)
    assert 8 <= params.n <= 16 and not params.uniform
    assert params.link_lengths[0] > params.link_lengths[1:].max()
    assert params.masses[0] > params.masses[1:].max()
    assert params.com_offsets[0] < 0.5 * params.link_lengths[0]  # camera at the front
    assert not params.isotropic  # wheels: c_y > c_x on every link
    assert np.all(params.per_link("c_y") > params.per_link("c_x"))


def test_urdf_of_a_robot_file_loads_everywhere(tmp_path: Path) -> None:
    """The URDF written from a robot file loads in Pinocchio, yourdfpy and MuJoCo."""
    params = read_robot_file(EXAMPLE)
    path = write_urdf(params, tmp_path / "camera_head_snake.urdf")
    model = pin.buildModelFromUrdf(str(path))
    assert (model.nq, model.nv) == (params.n + 3, params.n + 2)
    assert [model.inertias[j].mass for j in range(1, model.njoints)] == list(params.masses)
    urdf = yourdfpy.URDF.load(str(path), load_meshes=False)
    assert urdf.validate()
    mj = mujoco.MjModel.from_xml_string(path.read_text())
    assert mj.nv == params.n + 2
    assert mj.body_mass[1:].sum() == pytest.approx(params.total_mass)
    assert read_urdf(path) == params


def test_robot_paths() -> None:
    """The shipped URDFs and example robot files are found, and load."""
    paths = robot_paths()
    assert {"snake_table1.urdf", "snake_engine.urdf", EXAMPLE.name} <= set(paths)
    for name, path in paths.items():
        assert path.name == name and path.is_file()
        if path.suffix == ".urdf":
            assert read_urdf(path).name in ROBOTS
        else:
            assert isinstance(read_robot_file(path), SnakeParams)


def test_robot_paths_prefers_package_data(tmp_path: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """Installed as a wheel: snake_pin/robots/urdf and snake_pin/robots/examples are used."""
    import importlib.resources

    package = tmp_path / "snake_pin"
    (package / "robots" / "urdf").mkdir(parents=True)
    (package / "robots" / "examples").mkdir()
    (package / "robots" / "urdf" / "snake_table1.urdf").write_text("<robot/>")
    (package / "robots" / "examples" / "wheel.toml").write_text('name = "w"')
    (package / "robots" / "examples" / "notes.txt").write_text("not a robot")
    monkeypatch.setattr(importlib.resources, "files", lambda name: package)
    assert robot_paths() == {"snake_table1.urdf": package / "robots" / "urdf" / "snake_table1.urdf",
                             "wheel.toml": package / "robots" / "examples" / "wheel.toml"}


def test_load_robot(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Presets, .toml and .urdf paths, shipped file names; anything else one clear line."""
    assert load_robot("engine") == SnakeParams.engine()
    assert load_robot("table1", passive=(5,)) == SnakeParams.table1(passive=(5,))
    assert load_robot(str(EXAMPLE)) == read_robot_file(EXAMPLE)
    assert load_robot(EXAMPLE, passive=(5,)).passive == (5,)
    assert load_robot(THIRD_PARTY) == read_urdf(THIRD_PARTY)
    monkeypatch.chdir(tmp_path)
    assert load_robot(EXAMPLE.name) == read_robot_file(EXAMPLE)  # shipped, found by name
    with pytest.raises(RobotFileError, match=r"unknown robot 'table2'.*preset") as exc:
        load_robot("table2")
    assert "\n" not in str(exc.value)
    with pytest.raises(RobotFileError, match="no such robot file"):
        load_robot("missing.toml")
    with pytest.raises(RobotFileError, match="unknown robot"):
        load_robot(str(tmp_path / "robot.json"))
    with pytest.raises(ParameterError, match=r"camera_head_snake\.toml.*passive joint 12"):
        load_robot(str(EXAMPLE), passive=(12,))


def test_write_refuses_bad_paths(tmp_path: Path) -> None:
    """Wrong suffix, missing folder and non-params are refused without writing anything."""
    with pytest.raises(ParameterError, match=r"\.toml"):
        write_robot_file(SnakeParams.table1(), tmp_path / "robot.txt")
    with pytest.raises(ParameterError, match="does not exist"):
        write_robot_file(SnakeParams.table1(), tmp_path / "missing" / "robot.toml")
    with pytest.raises(ParameterError, match="SnakeParams"):
        write_robot_file({"n": 3}, tmp_path / "robot.toml")  # type: ignore[arg-type]
    for path in (None, True, [1.0], {}):
        with pytest.raises(ParameterError, match=r"^path must be a file path, got "):
            write_robot_file(SnakeParams.table1(), path)  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------- bounded, physical input
def _refused_at_once(call: Callable[[], object]) -> RobotFileError:
    """The RobotFileError ``call`` raises, from a thread: a reader that blocks fails."""
    error = raised_without_blocking(call, "the reader")
    assert isinstance(error, RobotFileError), error
    return error


@pytest.mark.parametrize("name", ["robot.toml", "robot.urdf"])
def test_a_fifo_is_refused_without_blocking(name: str, tmp_path: Path) -> None:
    """A FIFO named as a robot file or a URDF (directly, by load_robot, or through a
    robot file's urdf =) is refused at once in one line naming it."""
    fifo = tmp_path / name
    os.mkfifo(fifo)
    for call in (lambda: load_robot(fifo), lambda: load_robot(str(fifo))):
        error = _refused_at_once(call)
        assert str(error) == f"{fifo}: is a FIFO, not a regular file: not a " \
            f"{'URDF' if name.endswith('.urdf') else 'robot file'}"
    if name.endswith(".urdf"):
        outer = _write(tmp_path, f'name = "s"\nurdf = "{name}"\n')
        error = _refused_at_once(lambda: read_robot_file(outer))
        assert str(error).startswith(f"{outer}: urdf = 'robot.urdf': ") and "FIFO" in str(error)


@pytest.mark.parametrize("nesting", [
    "x = " + "[" * 100_000 + "]" * 100_000,
    "x = " + "{a = " * 100_000 + "1" + "}" * 100_000,
    "[links]\n" + "a." * 100_000 + "mass = 1\n",
])
def test_deep_toml_is_refused_before_parsing(nesting: str, tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """10^5 nested arrays, inline tables or dotted keys are one line, not a RecursionError
    (tomllib is never called on them)."""
    import snake_pin._io

    monkeypatch.setattr(snake_pin._io.tomllib, "loads", lambda text: pytest.fail("parsed"))
    path = _write(tmp_path, 'name = "deep"\n' + nesting)
    with pytest.raises(RobotFileError, match="nested deeper than 32 levels") as exc:
        read_robot_file(path)
    _one_line_naming(exc, path)


@pytest.mark.parametrize(("field", "value"), [
    ("link_length", "1e-300"), ("link_length", "1e300"), ("link_length", "[0.1, 0.1, 200.0]"),
    ("mass", "1e-300"), ("mass", "[0.1, 1e300, 0.1]"), ("inertia", "1e-300"),
    ("inertia", "1e300"),
])
def test_physically_meaningless_links_are_refused(field: str, value: str,
                                                  tmp_path: Path) -> None:
    """Lengths, masses and inertias beyond their physical ranges are one line naming the
    file and the field (and the link of a per-link value)."""
    links = {"link_length": "0.1", "mass": "0.1", "inertia": "1e-4", field: value}
    path = _write(tmp_path, 'name = "t"\nn = 3\n[links]\n'
                  + "".join(f"{k} = {v}\n" for k, v in links.items()))
    with pytest.raises(RobotFileError, match="physically meaningful") as exc:
        read_robot_file(path)
    _one_line_naming(exc, path, field, *(["link "] if value.startswith("[") else []))


@pytest.mark.parametrize("friction", ["c_x = 1e-300", "c_y = 1e300", "c_theta = [0, 0, 1e-200]"])
def test_physically_meaningless_friction_is_refused(friction: str, tmp_path: Path) -> None:
    """Friction is 0 or within FRICTION_RANGE; the error names the file and the field."""
    path = _write(tmp_path, 'name = "t"\nn = 3\n[links]\nlink_length = 0.1\nmass = 0.1\n'
                  f"inertia = 1e-4\n[friction]\n{friction}\n")
    with pytest.raises(RobotFileError, match="physically meaningful") as exc:
        read_robot_file(path)
    _one_line_naming(exc, path, friction.split()[0])


def test_a_urdf_with_a_meaningless_inertia_names_the_link(tmp_path: Path) -> None:
    """A URDF link of inertia 1e-300 is refused naming the file and the URDF link."""
    text = urdf_string(SnakeParams.table1(n=3)).replace('izz="0.00022"', 'izz="1e-300"', 1)
    assert 'izz="1e-300"' in text
    path = tmp_path / "tiny.urdf"
    path.write_text(text)
    with pytest.raises(RobotFileError, match="physically meaningful") as exc:
        read_urdf(path)
    _one_line_naming(exc, path, "link 1 ('link_1'): inertia")


def _chain_urdf(links: int, joint: str = "revolute") -> bytes:
    """A URDF of ``links`` bare links joined in a chain (about 105 bytes a link)."""
    parts = ['<?xml version="1.0"?>\n<robot name="long">\n']
    for i in range(links):
        parts.append(f'<link name="l{i}"/>\n')
        if i + 1 < links:
            parts.append(f'<joint name="j{i}" type="{joint}"><parent link="l{i}"/>'
                         f'<child link="l{i + 1}"/></joint>\n')
    return ("".join(parts) + "</robot>\n").encode()


@pytest.mark.parametrize(("links", "joint", "expected"), [
    (100_000, "revolute", "has more than 801 <link> elements"),
    (300, "continuous", "has more than 199 revolute or continuous joints"),
])
def test_a_urdf_beyond_the_link_limit_is_refused_unparsed(
        links: int, joint: str, expected: str, tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A URDF of 10^5 links (10 MB), or of 300 movable joints, is refused from a count of
    its bytes: no XML parser runs."""
    import snake_pin.robot_file as robot_file

    monkeypatch.setattr(robot_file, "_parse_urdf", lambda *a: pytest.fail("XML parsed"))
    path = tmp_path / "long.urdf"
    path.write_bytes(_chain_urdf(links, joint))
    with pytest.raises(RobotFileError, match=expected) as exc:
        read_urdf(path)
    _one_line_naming(exc, path, "refused before parsing")


def test_the_link_count_ignores_other_tags_and_fixed_joints(tmp_path: Path) -> None:
    """<link_friction> elements, parent/child links and fixed joints are not counted: our
    200-link URDF (the limit) and one with 200 fixed sensor links still load."""
    params = SnakeParams.table1(n=200)
    path = tmp_path / "max.urdf"
    write_urdf(params, path)
    assert read_urdf(path) == params
    text = path.read_text()
    sensors = "".join(f'<link name="s{i}"/><joint name="f{i}" type="fixed">'
                      f'<parent link="link_{i + 1}"/><child link="s{i}"/></joint>\n'
                      for i in range(200))
    path.write_text(text.replace("</robot>", sensors + "</robot>"))
    assert read_urdf(path) == params
