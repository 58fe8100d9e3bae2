"""Robot descriptions on disk: TOML robot files, URDF import, and the ``--robot`` lookup.

A file (or a preset name) becomes a validated :class:`~snake_pin.params.SnakeParams`, and
a robot file is written back; formats and the URDF mapping: :doc:`/robot_files`. Files are
bounded regular files (a URDF's elements counted on its bytes before parsing), and every
problem is one :class:`~snake_pin.exceptions.RobotFileError` line naming the file, then
the field or element (and the link).
"""

from __future__ import annotations

import functools
import importlib.resources
import io
import math
import os
import re
import textwrap
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ._io import atomic_write_bytes, decode_utf8, parse_toml, read_regular_file
from ._validation import is_number, one_line, output_file
from .exceptions import ParameterError, RobotFileError
from .params import MAX_LINKS, ROBOTS, SnakeParams

__all__ = ["FRICTION_KEYS", "GEOMETRY_TOLERANCE", "MAX_ROBOT_FILE_BYTES", "MAX_URDF_BYTES",
           "MAX_URDF_LINKS", "load_robot", "read_robot_file", "read_urdf", "robot_paths",
           "write_robot_file"]

#: Largest robot file read [bytes] (a 200-link robot with every field per link is ~30 kB).
MAX_ROBOT_FILE_BYTES = 1 << 20
#: Largest URDF read [bytes].
MAX_URDF_BYTES = 16 << 20
#: Most ``<link>`` elements a URDF may have, counted on its bytes before it is parsed: a
#: chain of MAX_LINKS bodies, each with up to three links fixed onto it, and a base.
MAX_URDF_LINKS = 4 * MAX_LINKS + 1
#: Relative tolerance (times the link length) on URDF geometry that must be exactly planar.
GEOMETRY_TOLERANCE = 1e-6
#: The friction coefficients, in the order they are written.
FRICTION_KEYS = ("c_x", "c_y", "c_theta")

_GEOMETRY_KEYS = ("link_length", "mass", "inertia", "com_offset")
_REQUIRED_GEOMETRY = ("link_length", "mass", "inertia")
_TOP_KEYS = ("name", "n", "passive", "links", "link", "friction", "urdf")
_MOVABLE = ("revolute", "continuous")
_BASE_JOINTS = ("planar", "floating", "fixed")
_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
_REPR_CHARS = 60
#: A ``<link>`` element's start tag; a movable joint's start tag (attributes in any order,
#: at most 2000 characters before ``type``, so a file of unclosed tags stays linear).
_LINK_TAG = re.compile(rb"<link[\s/>]")
_MOVABLE_TAG = re.compile(
    rb"<joint[\s][^<>]{0,2000}?\btype\s*=\s*[\"'](?:revolute|continuous)[\"']")


# --------------------------------------------------------------------------- helpers
def _short(value: object) -> str:
    """``repr(value)`` on one line, cut to a readable length."""
    return one_line(repr(value), _REPR_CHARS)


def _error(path: object, message: str) -> RobotFileError:
    """A RobotFileError ``"FILE: message"`` on one line."""
    name = os.fspath(path) if isinstance(path, (str, os.PathLike)) else _short(path)
    return RobotFileError(" ".join(f"{os.fsdecode(name)}: {message}".split()))


def _numbers(value: object, path: str | os.PathLike[str], where: str) -> object:
    """``value`` (a number or a list), refusing a TOML integer too large for a float."""
    for i, item in enumerate(value if isinstance(value, list) else [value], start=1):
        if isinstance(item, int) and not isinstance(item, bool):
            try:
                float(item)
            except OverflowError:
                at = f"{where}, link {i}" if isinstance(value, list) else where
                raise _error(path, f"{at} must be a finite number, "
                                   f"got an integer of {len(str(item))} digits") from None
    return value


def _sanitise_name(name: str, fallback: str) -> str:
    """Letters, digits and underscores only (runs of anything else become one ``_``)."""
    for candidate in (name, fallback):
        clean = re.sub(r"[^A-Za-z0-9_]+", "_", candidate or "").strip("_")
        if clean:
            return clean
    return "robot"


# ----------------------------------------------------------------------- TOML reading
def _check_keys(path: str | os.PathLike[str], table: Mapping[str, Any], allowed: tuple[str, ...],
                where: str, required: tuple[str, ...] = ()) -> None:
    for key in table:
        if key not in allowed:
            raise _error(path, f"{where}unknown key {_short(key)} "
                               f"(expected one of {', '.join(allowed)})")
    for key in required:
        if key not in table:
            raise _error(path, f"{where}{key} is missing")


def _table(path: str | os.PathLike[str], doc: Mapping[str, Any], key: str,
           header: str) -> dict[str, Any] | None:
    value = doc.get(key)
    if value is None:
        return None
    if not isinstance(value, dict):
        raise _error(path, f"{key} must be a table ({header}), got {_short(value)}")
    return value


def _link_tables(path: str | os.PathLike[str], entries: object) -> dict[str, Any]:
    """The ``[[link]]`` array of tables as per-link lists (com_offset filled with the middle)."""
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise _error(path, f"link must be an array of tables ([[link]], one per link), "
                           f"got {_short(entries)}")
    columns: dict[str, list[Any]] = {key: [] for key in _GEOMETRY_KEYS}
    any_offset = any("com_offset" in entry for entry in entries)
    for i, entry in enumerate(entries, start=1):
        where = f"[[link]] {i}: "
        _check_keys(path, entry, _GEOMETRY_KEYS, where, _REQUIRED_GEOMETRY)
        for key, value in entry.items():
            if not is_number(value):
                raise _error(path, f"{where}{key} must be a number, got {_short(value)}")
            _numbers(value, path, f"{where}{key}")
        if any_offset:
            offset = entry.get("com_offset", 0.5 * float(entry["link_length"]))
            columns["com_offset"].append(offset)
        for key in _REQUIRED_GEOMETRY:
            columns[key].append(entry[key])
    if not any_offset:
        del columns["com_offset"]
    return columns


def _fields_from_doc(path: str | os.PathLike[str], doc: dict[str, Any]
                     ) -> tuple[dict[str, Any], dict[str, str]]:
    """Per-link fields of the document and where each came from (for messages)."""
    fields: dict[str, Any] = {}
    where: dict[str, str] = {}
    links = _table(path, doc, "links", "[links]")
    if links is not None and "link" in doc:
        raise _error(path, "give the links either as [links] or as [[link]] tables, not both")
    if "urdf" in doc and (links is not None or "link" in doc):
        raise _error(path, "urdf takes the links from the URDF: remove [links]/[[link]]")
    if "link" in doc and links is None:
        for key, value in _link_tables(path, doc["link"]).items():
            fields[key], where[key] = value, f"[[link]] {key}"
    elif links is None and "urdf" not in doc:
        raise _error(path, "the links are missing: give a [links] table, [[link]] tables "
                           "or urdf = \"FILE.urdf\"")
    for header, table, keys, required in (
            ("[links]", links, _GEOMETRY_KEYS, _REQUIRED_GEOMETRY),
            ("[friction]", _table(path, doc, "friction", "[friction]"), FRICTION_KEYS, ())):
        if table is not None:
            _check_keys(path, table, keys, f"{header} ", required)
            for key, value in table.items():
                fields[key] = _numbers(value, path, f"{header} {key}")
                where[key] = f"{header} {key}"
    return fields, where


def _link_count(path: str | os.PathLike[str], doc: dict[str, Any], fields: dict[str, Any],
                where: dict[str, str]) -> int | None:
    """n from the ``n`` key and the per-link arrays, which must agree."""
    lengths = {key: len(value) for key, value in fields.items() if isinstance(value, list)}
    if "n" in doc:
        n = doc["n"]
        if not isinstance(n, int) or isinstance(n, bool):
            raise _error(path, f"n must be an integer, got {_short(n)}")
        for key, size in lengths.items():
            if size != n:
                raise _error(path, f"n = {n} but {where[key]} has {size} value(s)")
        return n
    sizes = sorted(set(lengths.values()))
    if len(sizes) > 1:
        detail = ", ".join(f"{where[key]} has {size}" for key, size in lengths.items())
        raise _error(path, f"per-link arrays have different lengths: {detail}")
    return sizes[0] if sizes else None


def read_robot_file(path: str | os.PathLike[str]) -> SnakeParams:
    """Read a TOML robot file (format in :doc:`/robot_files`) into validated parameters.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.toml`` file (at most :data:`MAX_ROBOT_FILE_BYTES`, UTF-8).

    Returns
    -------
    SnakeParams
        The robot, named by the file's ``name``.

    Raises
    ------
    RobotFileError
        Anything wrong with the file (or, with ``urdf =``, its URDF), in one line naming
        the file and the field (and link).
    """
    error = functools.partial(_error, path)
    data = read_regular_file(path, limit=MAX_ROBOT_FILE_BYTES, kind="robot file", error=error)
    doc = parse_toml(decode_utf8(data, error=error), error=error)
    _check_keys(path, doc, _TOP_KEYS, "", ("name",))
    if not isinstance(doc["name"], str):
        raise _error(path, f"name must be a string, got {_short(doc['name'])}")
    fields, where = _fields_from_doc(path, doc)
    n = _link_count(path, doc, fields, where)
    changes = {key: doc[key] for key in ("name", "passive") if key in doc}
    try:
        if "urdf" in doc:  # the robot of the URDF beside the file, which must have n links
            ref = doc["urdf"]
            if not isinstance(ref, str) or not ref:
                raise _error(path, f"urdf must be a file name (a string), got {_short(ref)}")
            try:
                params = read_urdf(Path(path).parent / ref)
            except RobotFileError as exc:
                raise _error(path, f"urdf = {ref!r}: {exc}") from None
            if n is not None and n != params.n:
                raise _error(path, f"n = {n} but the URDF {ref!r} has {params.n} links")
            return params.replace(**changes, **fields)
        if n is None:
            raise _error(path, "n is missing and no per-link array gives it")
        return SnakeParams(n=n, **changes, **fields)
    except ParameterError as exc:
        raise _error(path, str(exc)) from None


# ----------------------------------------------------------------------- TOML writing
def _toml_per_link(key: str, value: float | tuple[float, ...]) -> str:
    """``key = value`` in TOML (a float's repr is valid TOML), arrays wrapped at 86 columns."""
    if not isinstance(value, tuple):
        return f"{key} = {float(value)!r}"
    body = textwrap.fill(" ".join(f"{float(v)!r}," for v in value), 86,
                         initial_indent="    ", subsequent_indent="    ")
    return f"{key} = [\n{body}\n]"


def robot_file_string(params: SnakeParams) -> str:
    """Return the TOML robot file of ``params`` (:func:`read_robot_file` reads it back equal)."""
    lines = ["# snake_pin robot file (snake_pin.robot_file.read_robot_file reads it)",
             f'name = "{params.name}"', f"n = {params.n}"]
    if params.passive:
        lines.append(f"passive = [{', '.join(str(k) for k in params.passive)}]")
    lines += ["", "[links]"]
    for key in _GEOMETRY_KEYS:
        value = getattr(params, key)
        if value is not None:
            lines.append(_toml_per_link(key, value))
    lines += ["", "[friction]"]
    lines += [_toml_per_link(key, getattr(params, key)) for key in FRICTION_KEYS]
    return "\n".join(lines) + "\n"


def write_robot_file(params: SnakeParams, path: str | os.PathLike[str]) -> Path:
    """Write ``params`` as a TOML robot file, whole or not at all.

    Parameters
    ----------
    params : SnakeParams
        The robot.
    path : str or os.PathLike
        Output file ending in ``.toml`` in an existing folder.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ParameterError
        ``params`` is not a SnakeParams, or ``path`` not a ``.toml`` file in a folder.
    OSError
        The file cannot be written.
    """
    path = output_file(params, path, ".toml", "robot file")
    atomic_write_bytes(path, robot_file_string(params).encode())
    return path


# ------------------------------------------------------------------------ URDF reading
def _count_elements(path: str | os.PathLike[str], data: bytes) -> None:
    """Refuse a URDF with too many links or movable joints from a scan of its bytes."""
    for pattern, most, what in (
            (_LINK_TAG, MAX_URDF_LINKS, "<link> elements"),
            (_MOVABLE_TAG, MAX_LINKS - 1, f"revolute or continuous joints (a snake has at "
                                          f"most {MAX_LINKS} links)")):
        for count, _ in enumerate(pattern.finditer(data), start=1):
            if count > most:
                raise _error(path, f"has more than {most} {what}; refused before parsing")


def _parse_urdf(path: str | os.PathLike[str], data: bytes) -> tuple[Any, Any]:
    """The ``<robot>`` element of ``data`` (no DTD, no entities, no network), and yourdfpy's
    robot of it."""
    import yourdfpy
    from lxml import etree

    parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False,
                             huge_tree=False, remove_comments=True)
    try:
        tree = etree.parse(io.BytesIO(data), parser)
    except etree.XMLSyntaxError as exc:
        raise _error(path, f"not a URDF (not XML: {exc})") from None
    if tree.docinfo.doctype or tree.docinfo.internalDTD is not None:
        raise _error(path, "has a document type declaration (DTD); URDF needs none")
    root = tree.getroot()
    if root.tag != "robot":
        raise _error(path, f"not a URDF: the root element is <{root.tag}>, not <robot>")
    if not root.get("name"):
        raise _error(path, "<robot> has no name attribute")
    try:
        urdf = yourdfpy.URDF.load(io.BytesIO(etree.tostring(root)), build_scene_graph=False,
                                  load_meshes=False)
    except Exception as exc:  # yourdfpy raises whatever float()/int()/lookups raise
        raise _error(path, f"yourdfpy cannot parse it ({type(exc).__name__}: {exc})") from None
    return root, urdf.robot


def _finite(array: object) -> bool:
    return array is None or bool(np.all(np.isfinite(np.asarray(array, dtype=float))))


def _by_name(path: str | os.PathLike[str], items: list[Any], tag: str) -> dict[str, Any]:
    """``<link>`` or ``<joint>`` elements by name: each named, no name twice."""
    found: dict[str, Any] = {}
    for item in items:
        if not item.name:
            raise _error(path, f"a <{tag}> has no name")
        if item.name in found:
            raise _error(path, f"{tag} {item.name!r} is defined twice")
        found[item.name] = item
    return found


def _links_and_joints(path: str | os.PathLike[str], robot: Any
                      ) -> tuple[dict[str, Any], dict[str, Any]]:
    """The ``<link>`` and ``<joint>`` elements by name, each checked (joints forming a tree)."""
    links = _by_name(path, robot.links, "link")
    for link in links.values():
        inertial = link.inertial
        if inertial is None:
            continue
        if inertial.mass is None:
            raise _error(path, f"link {link.name!r}: <inertial> has no <mass value=...>")
        if inertial.inertia is None:
            raise _error(path, f"link {link.name!r}: <inertial> has no <inertia>")
        if not (_finite(inertial.mass) and _finite(inertial.inertia)
                and _finite(inertial.origin)):
            raise _error(path, f"link {link.name!r}: <inertial> has a non-finite value")
        if inertial.mass < 0.0:
            raise _error(path, f"link {link.name!r}: mass must be non-negative, "
                               f"got {inertial.mass:g}")
    joints = _by_name(path, robot.joints, "joint")
    parent_of: dict[str, str] = {}
    for joint in joints.values():
        if joint.type not in _JOINT_TYPES:
            raise _error(path, f"joint {joint.name!r} has unknown type {_short(joint.type)}")
        for role in ("parent", "child"):
            link = getattr(joint, role)
            if link not in links:
                raise _error(path, f"joint {joint.name!r}: {role} link {_short(link)} "
                                   f"is not a <link> of this robot")
        if joint.child in parent_of:
            raise _error(path, f"link {joint.child!r} is the child of two joints "
                               f"({parent_of[joint.child]!r}, {joint.name!r}): not a tree")
        parent_of[joint.child] = joint.name
        if not _finite(joint.origin):
            raise _error(path, f"joint {joint.name!r}: <origin> has a non-finite value")
    return links, joints


@dataclass
class _Body:
    """One rigid body of the chain: its main link, the (link, pose) fixed onto it, and the
    movable joint to the next body (None for the tail) with its pose, in the link's frame."""

    link: str
    members: list[tuple[Any, np.ndarray]] = field(default_factory=list)
    joint: Any = None
    joint_pose: np.ndarray | None = None


def _pose(origin: object) -> np.ndarray:
    return np.eye(4) if origin is None else np.asarray(origin, dtype=float)


def _chain(path: str | os.PathLike[str], robot: Any) -> list[_Body]:
    """The chain's bodies, head first (a massless base link's planar, floating or fixed joint
    stripped)."""
    links, joints = _links_and_joints(path, robot)
    children: dict[str, list[Any]] = {name: [] for name in links}
    for joint in joints.values():
        children[joint.parent].append(joint)
    child_links = {joint.child for joint in joints.values()}
    roots = [name for name in links if name not in child_links]
    if not roots:
        raise _error(path, "its joints form a loop: no root link")
    if len(roots) > 1:
        raise _error(path, f"links {', '.join(repr(r) for r in roots[:4])} are all roots: "
                           f"a snake is one connected chain")
    head = roots[0]
    root = links[head]
    if ((root.inertial is None or root.inertial.mass == 0.0) and len(children[head]) == 1
            and children[head][0].type in _BASE_JOINTS):
        head = children[head][0].child
    bodies: list[_Body] = []
    main = head
    while True:
        # the rigid body of ``main``: every link reached through fixed joints
        body = _Body(main)
        stack: list[tuple[str, np.ndarray]] = [(main, np.eye(4))]
        next_joints = []
        while stack:
            name, pose = stack.pop()
            body.members.append((links[name], pose))
            for joint in children[name]:
                if joint.type == "fixed":
                    stack.append((joint.child, pose @ _pose(joint.origin)))
                else:
                    next_joints.append((name, joint, pose @ _pose(joint.origin)))
        bodies.append(body)
        if not next_joints:
            break
        if len(next_joints) > 1:
            owner = next_joints[1][0]
            names = ", ".join(repr(j.name) for _, j, _ in next_joints)
            raise _error(path, f"link {owner!r} has two child joints ({names}): a branched "
                               f"tree, not a serial chain")
        _, body.joint, body.joint_pose = next_joints[0]
        _check_movable(path, body.joint)
        main = body.joint.child
        if len(bodies) >= MAX_LINKS:
            raise _error(path, f"has more than {MAX_LINKS} links in its chain")
    visited = {roots[0], *(link.name for body in bodies for link, _ in body.members)}
    stray = [name for name in links if name not in visited]
    if stray:
        raise _error(path, f"link {stray[0]!r} is not reachable from the head {head!r} "
                           f"(a loop of joints?)")
    for body in bodies:
        if links[body.link].inertial is None:
            raise _error(path, f"link {body.link!r} has no <inertial>: every link of the "
                               f"chain needs its mass and inertia")
    if len(bodies) < 2:
        raise _error(path, f"has no revolute joint after link {head!r}: a snake needs "
                           f"at least 2 links")
    return bodies


def _planar_inertia(body: _Body) -> tuple[float, np.ndarray, float]:
    """Mass, CM (in the main link's frame) and yaw inertia about the CM of a rigid body:
    fixed links merged by the planar parallel-axis theorem, one link's numbers unchanged."""
    parts = []
    for link, pose in body.members:
        inertial = link.inertial
        if inertial is None or inertial.mass == 0.0:
            continue
        frame = pose @ _pose(inertial.origin)
        rotation = frame[:3, :3]
        tensor = rotation @ np.asarray(inertial.inertia, dtype=float) @ rotation.T
        parts.append((float(inertial.mass), frame[:3, 3], float(tensor[2, 2])))
    if len(parts) == 1:
        return parts[0]
    mass = sum(m for m, _, _ in parts)
    if mass <= 0.0:
        return 0.0, np.zeros(3), 0.0
    centre = sum(m * c for m, c, _ in parts) / mass
    yaw = sum(j + m * float(np.sum((c[:2] - centre[:2]) ** 2)) for m, c, j in parts)
    return mass, centre, yaw


def _check_movable(path: str | os.PathLike[str], joint: Any) -> None:
    """A chain joint must be revolute/continuous about +-z and not mimic another."""
    if joint.type not in _MOVABLE:
        raise _error(path, f"joint {joint.name!r} is {joint.type}: a snake's joints are "
                           f"revolute or continuous about z")
    if joint.mimic is not None:
        raise _error(path, f"joint {joint.name!r} mimics another joint: not supported")
    axis = np.asarray(joint.axis if joint.axis is not None else [1.0, 0.0, 0.0], dtype=float)
    norm = float(np.linalg.norm(axis)) if axis.shape == (3,) else 0.0
    if not (math.isfinite(norm) and norm > 0.0):
        raise _error(path, f"joint {joint.name!r}: axis {_short(axis.tolist())} is not "
                           f"a 3-vector")
    unit = axis / norm
    if abs(unit[0]) > GEOMETRY_TOLERANCE or abs(unit[1]) > GEOMETRY_TOLERANCE:
        raise _error(path, f"joint {joint.name!r} turns about axis "
                           f"({' '.join(f'{a:g}' for a in axis)}), not z: not a planar snake")


def _last_length(link: Any, com: float) -> float:
    """The largest x the link's collision (else visual) geometry reaches; else 2 x CM offset."""
    for shapes in (link.collisions, link.visuals):
        ends = [end for shape in shapes if (end := _geometry_end(shape)) is not None]
        if ends:
            end = max(ends)
            return end if end >= com and end > 0.0 else 2.0 * com
    return 2.0 * com


def _geometry_end(shape: Any) -> float | None:
    """Largest x of a box, cylinder or sphere in its link's frame (None for meshes)."""
    pose = _pose(shape.origin)
    geometry = shape.geometry
    if geometry is None or not np.all(np.isfinite(pose)):
        return None
    rotation, centre = pose[:3, :3], pose[0, 3]
    if geometry.box is not None and geometry.box.size is not None:
        reach = 0.5 * float(np.abs(rotation[0]) @ np.asarray(geometry.box.size, dtype=float))
    elif geometry.cylinder is not None:
        axis_x = abs(float(rotation[0, 2]))
        reach = (0.5 * geometry.cylinder.length * axis_x
                 + geometry.cylinder.radius * math.sqrt(max(0.0, 1.0 - axis_x * axis_x)))
    elif geometry.sphere is not None:
        reach = float(geometry.sphere.radius)
    else:
        return None
    end = centre + reach
    return end if math.isfinite(end) else None


def _our_extension(path: str | os.PathLike[str], root: Any, chain: list[str]
                   ) -> tuple[str | None, dict[str, list[float]]]:
    """Name and per-link friction from our ``<snake_pin>`` element ({} when absent)."""
    from .urdf import EXTENSION_TAG, EXTENSION_VERSION

    elements = root.findall(EXTENSION_TAG)
    if not elements:
        return None, {}
    if len(elements) > 1:
        raise _error(path, f"has {len(elements)} <{EXTENSION_TAG}> elements; one at most")
    ext = elements[0]
    version = ext.get("version")
    if version != str(EXTENSION_VERSION):
        raise _error(path, f"<{EXTENSION_TAG}> version {_short(version)} is not supported "
                           f"(this snake_pin reads version {EXTENSION_VERSION})")
    index = {name: i for i, name in enumerate(chain)}
    friction = {key: [0.0] * len(chain) for key in FRICTION_KEYS}
    for item in ext:
        if item.tag != "link_friction":
            raise _error(path, f"<{EXTENSION_TAG}> has an unknown element <{item.tag}>")
        link = item.get("link")
        if link not in index:  # each link's index is taken once
            problem = "appears twice" if link in chain else "names no link of the chain"
            raise _error(path, f"<link_friction link={_short(link)}> {problem}")
        i = index.pop(link)
        for attribute in item.attrib:
            if attribute not in ("link", *FRICTION_KEYS):
                raise _error(path, f"<link_friction link={link!r}> has an unknown attribute "
                                   f"{attribute!r}")
        for key in FRICTION_KEYS:
            text = item.get(key)
            try:
                friction[key][i] = float(text)
            except (TypeError, ValueError):
                raise _error(path, f"<link_friction link={link!r}> {key} must be a number, "
                                   f"got {_short(text)}") from None
    for name in index:  # the first link without one
        raise _error(path, f"<{EXTENSION_TAG}> has no <link_friction> for link {name!r}")
    return ext.get("name"), friction


def _friction_argument(friction: Mapping[str, Any] | None, n: int) -> dict[str, Any]:
    """The caller's friction, checked on its own (ParameterError names the argument)."""
    if friction is None:
        return {}
    if not isinstance(friction, Mapping):
        raise ParameterError(f"friction must be a dict of {', '.join(FRICTION_KEYS)}, "
                             f"got {type(friction).__name__}")
    unknown = [key for key in friction if key not in FRICTION_KEYS]
    if unknown:
        raise ParameterError(f"friction: unknown key(s) {', '.join(map(repr, unknown))} "
                             f"(expected {', '.join(FRICTION_KEYS)})")
    try:
        SnakeParams(n=n, **friction)
    except ParameterError as exc:
        raise ParameterError(f"friction: {exc}") from None
    return dict(friction)


def read_urdf(path: str | os.PathLike[str],
              friction: Mapping[str, Any] | None = None) -> SnakeParams:
    """Read the planar snake a URDF describes (ours or anyone's; :doc:`/robot_files`).

    Parameters
    ----------
    path : str or os.PathLike
        The ``.urdf`` file (at most :data:`MAX_URDF_BYTES`).
    friction : Mapping of str to float or sequence of float, optional
        Any of ``c_x``, ``c_y``, ``c_theta`` (one number or n), winning over the file's
        ``<snake_pin>`` element; a coefficient in neither is **zero**.

    Returns
    -------
    SnakeParams
        One link per body of the chain, head first; passive joints from zero effort limits.

    Raises
    ------
    RobotFileError
        One line naming the file and the element (link or joint) at fault.
    ParameterError
        ``friction`` itself is malformed (an unknown key, a negative value).
    """
    data = read_regular_file(path, limit=MAX_URDF_BYTES, kind="URDF",
                             error=functools.partial(_error, path))
    _count_elements(path, data)
    root, robot = _parse_urdf(path, data)
    bodies = _chain(path, robot)
    chain = [body.link for body in bodies]
    n = len(bodies)
    caller = _friction_argument(friction, n)
    rows = []  # (2l, m, J, CM offset) of each body
    for body in bodies:
        name = body.link
        mass, centre, yaw = _planar_inertia(body)
        if body.joint is not None:
            assert body.joint_pose is not None  # _chain sets both or neither
            length = _joint_offset(path, body.joint.name, name, body.joint_pose)
        else:
            length = _last_length(body.members[0][0], float(centre[0]))
        scale = GEOMETRY_TOLERANCE * max(length, 1e-12)
        if mass <= 0.0:
            raise _error(path, f"link {name!r}: mass must be positive, got {mass:g}")
        if not yaw > 0.0:
            raise _error(path, f"link {name!r}: yaw inertia izz about the centre of mass "
                               f"must be positive, got {yaw:g}")
        if abs(centre[1]) > scale:
            raise _error(path, f"link {name!r}: the centre of mass lies {centre[1]:g} m off "
                               f"the link's x axis (y must be 0)")
        if not -scale <= centre[0] <= length + scale:
            raise _error(path, f"link {name!r}: the centre of mass x = {centre[0]:g} m lies "
                               f"outside the link (0..{length:g} m)")
        rows.append((length, mass, yaw, min(max(float(centre[0]), 0.0), length)))
    label, ext_friction = _our_extension(path, root, chain)
    if label is None:
        label = _sanitise_name(root.get("name"), Path(path).stem)
        label = f"{label}_urdf" if label in ROBOTS else label
    passive = tuple(k for k, body in enumerate(bodies[:-1], start=1)
                    if body.joint.limit is not None and body.joint.limit.effort == 0.0)
    lengths, masses, inertias, offsets = zip(*rows, strict=True)
    try:
        return SnakeParams(n=n, link_length=lengths, mass=masses, inertia=inertias,
                           com_offset=offsets, passive=passive, name=label,
                           **{**dict.fromkeys(FRICTION_KEYS, 0.0), **ext_friction, **caller})
    except ParameterError as exc:
        raise _error(path, _link_names(str(exc), chain)) from None


def _joint_offset(path: str | os.PathLike[str], joint: str, link: str,
                  pose: np.ndarray) -> float:
    """2l of ``link``: the x of its next joint, which must lie on +x without rotation."""
    rotation = pose[:3, :3]
    x, y = float(pose[0, 3]), float(pose[1, 3])
    if np.max(np.abs(rotation - np.eye(3))) > GEOMETRY_TOLERANCE:
        rpy = (math.atan2(rotation[2, 1], rotation[2, 2]),
               -math.asin(max(-1.0, min(1.0, rotation[2, 0]))),
               math.atan2(rotation[1, 0], rotation[0, 0]))
        raise _error(path, f"joint {joint!r}: its origin turns the next link by rpy "
                           f"({' '.join(f'{a + 0.0:.6g}' for a in rpy)}) from {link!r}; links must "
                           f"be in line at zero joint angle (rpy 0 0 0)")
    if x <= 0.0 or abs(y) > GEOMETRY_TOLERANCE * abs(x):
        raise _error(path, f"joint {joint!r}: origin ({x:g}, {y:g}) seen from link {link!r} "
                           f"is not on the link's +x axis")
    return x


def _link_names(message: str, chain: list[str]) -> str:
    """SnakeParams' ``link i:`` prefix with the URDF link's name added."""
    match = re.match(r"link (\d+):", message)
    if match and 1 <= int(match.group(1)) <= len(chain):
        i = int(match.group(1))
        return f"link {i} ({chain[i - 1]!r}):{message[match.end():]}"
    return message


# ----------------------------------------------------------------------- shipped robots
def robot_paths() -> dict[str, Path]:
    """Return the shipped URDFs and example robot files, by file name.

    Package data ``snake_pin/robots/{urdf,examples}`` when installed, else the checkout's
    ``urdf/`` and ``examples/robots/``.

    Returns
    -------
    dict of str to pathlib.Path
        File name (``snake_table1.urdf``, ``camera_head_snake.toml``, ...) -> its path.
    """
    packaged = importlib.resources.files("snake_pin") / "robots"
    checkout = Path(__file__).resolve().parent.parent
    found: dict[str, Path] = {}
    for sub, source in (("urdf", checkout / "urdf"),
                        ("examples", checkout / "examples" / "robots")):
        folder = packaged / sub
        path = Path(str(folder)) if isinstance(folder, Path) and folder.is_dir() else source
        if not path.is_dir():
            continue
        for file in sorted(path.iterdir()):
            if file.suffix in (".urdf", ".toml") and file.is_file():
                found.setdefault(file.name, file)
    return found


def load_robot(spec: str | os.PathLike[str], **overrides: Any) -> SnakeParams:
    """Return the robot a ``--robot`` value names, with ``overrides`` applied.

    Parameters
    ----------
    spec : str or os.PathLike
        A preset name, a ``.toml`` or ``.urdf`` file, or a shipped robot's file name
        (:func:`robot_paths`) when no such file is in the working directory.
    **overrides
        Field changes (e.g. ``passive=(3,)``).

    Returns
    -------
    SnakeParams
        The validated robot.

    Raises
    ------
    RobotFileError
        The file is missing, malformed, or ``spec`` is none of the above.
    ParameterError
        An override is out of its domain (the message starts with ``spec``).
    """
    text = os.fspath(spec) if isinstance(spec, (str, os.PathLike)) else None
    if not isinstance(text, str):
        raise RobotFileError(f"robot must be a name or a path, got {_short(spec)}")
    if text in ROBOTS:
        return SnakeParams.preset(text, **overrides)
    suffix = Path(text).suffix.lower()
    if suffix not in (".toml", ".urdf"):
        raise RobotFileError(
            " ".join(f"unknown robot {_short(text)}: give a preset "
                     f"({', '.join(ROBOTS)}), a .toml robot file or a .urdf file".split()))
    path = Path(text)
    if not path.exists() and path.name == text:
        path = robot_paths().get(text, path)
    params = read_robot_file(path) if suffix == ".toml" else read_urdf(path)
    if not overrides:
        return params
    try:
        return params.replace(**overrides)
    except ParameterError as exc:
        raise ParameterError(f"{text}: {exc}") from None

