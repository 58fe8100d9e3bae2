"""URDF generation: a planar n-link snake with a floating planar base (Fig. 1), via yourdfpy.

The one description of the robot's geometry and inertia (:class:`snake_pin.model.Snake`
builds its model from it), in the frames of :ref:`coordinates`; a ``world`` link and a
``planar`` joint ``base`` carry the head. Passive joints have ``<limit effort="0">``.
"""

from __future__ import annotations

import io
import os
import re
from pathlib import Path

import numpy as np
import yourdfpy
from lxml import etree

from ._io import atomic_write_bytes
from ._validation import check_params, flag, output_file
from .exceptions import SnakePinError
from .params import SnakeParams

__all__ = ["EFFORT_LIMIT", "EXTENSION_TAG", "EXTENSION_VERSION", "JOINT_LIMIT", "build_urdf",
           "passive_joints", "urdf_string", "write_urdf"]

#: Tag and version of the element that carries snake_pin's own data (friction) in a URDF.
EXTENSION_TAG = "snake_pin"
EXTENSION_VERSION = 1
#: Rated joint torque written into the URDF [N m] (not enforced by the dynamics).
EFFORT_LIMIT = 10.0
#: Joint range written into the URDF [rad] (``|phi_i| <= pi/2``, the singular search's box).
JOINT_LIMIT = 0.5 * np.pi
#: Joint velocity limit written into the URDF [rad/s].
VELOCITY_LIMIT = 10.0
#: Link radius as a fraction of the link length (drawing and collision only).
RADIUS_RATIO = 0.15

_BODY_RGBA = np.array([0.13, 0.55, 0.13, 1.0])
_HEAD_RGBA = np.array([0.85, 0.33, 0.10, 1.0])


def _translation(x: float) -> np.ndarray:
    pose = np.eye(4)
    pose[0, 3] = x
    return pose


def _link(index: int, length: float, mass: float, yaw_inertia: float, com: float
          ) -> yourdfpy.Link:
    radius = RADIUS_RATIO * length
    # A cylinder's axis is z in URDF: turn it onto the link's x axis, centred at x = l_i.
    pose = np.array([[0.0, 0.0, 1.0, 0.5 * length], [0.0, 1.0, 0.0, 0.0],
                     [-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    geometry = yourdfpy.Geometry(cylinder=yourdfpy.Cylinder(radius=radius, length=length))
    material = yourdfpy.Material(name="head" if index == 1 else "body")
    # Thin rod in the plane: I_yy = I_zz = J about the CM; I_xx of the cylinder's section.
    inertia = np.diag([0.5 * mass * radius**2, yaw_inertia, yaw_inertia])
    return yourdfpy.Link(
        name=f"link_{index}",
        inertial=yourdfpy.Inertial(origin=_translation(com), mass=mass, inertia=inertia),
        visuals=[yourdfpy.Visual(name=f"link_{index}_visual", origin=pose,
                                 geometry=geometry, material=material)],
        collisions=[yourdfpy.Collision(name=f"link_{index}_collision", origin=pose,
                                       geometry=geometry)],
    )


def build_urdf(params: SnakeParams, *, floating_base: bool = True) -> yourdfpy.URDF:
    """Build the robot description of ``params`` as a yourdfpy object.

    Parameters
    ----------
    params : SnakeParams
        Robot parameters; ``params.passive`` joints get a zero effort limit.
    floating_base : bool, optional
        Include the ``world`` link and the ``planar`` joint ``base`` (else the head is root).

    Returns
    -------
    yourdfpy.URDF
        Links ``link_i`` (head first) joined by revolute z joints ``joint_i`` (no friction).

    Raises
    ------
    ParameterError
        If ``params`` is not a SnakeParams or ``floating_base`` not a bool.
    """
    check_params(params)
    flag(floating_base, "floating_base")
    links = [_link(i, *map(float, row)) for i, row in enumerate(zip(
        params.link_lengths, params.masses, params.inertias, params.com_offsets, strict=True),
        start=1)]
    joints = []
    for i in range(1, params.n):
        effort = 0.0 if i in params.passive else EFFORT_LIMIT
        joints.append(yourdfpy.Joint(
            name=f"joint_{i}", type="revolute", parent=f"link_{i}", child=f"link_{i + 1}",
            origin=_translation(float(params.link_lengths[i - 1])), axis=np.array([0.0, 0.0, 1.0]),
            limit=yourdfpy.Limit(effort=effort, velocity=VELOCITY_LIMIT,
                                 lower=-JOINT_LIMIT, upper=JOINT_LIMIT),
            dynamics=yourdfpy.Dynamics(damping=0.0, friction=0.0),
        ))
    if floating_base:
        links.insert(0, yourdfpy.Link(name="world"))
        joints.insert(0, yourdfpy.Joint(name="base", type="planar", parent="world",
                                        child="link_1", origin=np.eye(4),
                                        axis=np.array([0.0, 0.0, 1.0])))
    materials = [yourdfpy.Material(name="head", color=yourdfpy.Color(rgba=_HEAD_RGBA)),
                 yourdfpy.Material(name="body", color=yourdfpy.Color(rgba=_BODY_RGBA))]
    robot = yourdfpy.Robot(name=f"snake_{params.name}", links=links, joints=joints,
                           materials=materials)
    return yourdfpy.URDF(robot=robot, build_scene_graph=floating_base, load_meshes=False)


def urdf_string(params: SnakeParams, *, floating_base: bool = True) -> str:
    """Return the URDF text of ``params``, pretty-printed (same parameters, same bytes).

    Parameters
    ----------
    params : SnakeParams
        Robot parameters.
    floating_base : bool, optional
        As in :func:`build_urdf`.

    Returns
    -------
    str
        The XML document, with a ``<snake_pin>`` element carrying the friction and name.

    Raises
    ------
    ParameterError
        As :func:`build_urdf`.
    """
    # yourdfpy's own write_xml_string drops its keyword arguments (``*kwargs``), so
    # serialise its element tree the way its write_xml_file does.
    tree = build_urdf(params, floating_base=floating_base).write_xml()
    _add_extension(tree.getroot(), params)
    return etree.tostring(tree, xml_declaration=True, pretty_print=True,
                          encoding="UTF-8").decode()


def _add_extension(robot: etree._Element, params: SnakeParams) -> None:
    """Append ``<snake_pin version name><link_friction link c_x c_y c_theta/>...</snake_pin>``:
    the friction and name a URDF cannot say (other tools ignore the element)."""
    ext = etree.SubElement(robot, EXTENSION_TAG, version=str(EXTENSION_VERSION),
                           name=params.name)
    friction = {key: params.per_link(key) for key in ("c_x", "c_y", "c_theta")}
    for i in range(params.n):
        etree.SubElement(ext, "link_friction", link=f"link_{i + 1}",
                         **{key: repr(float(values[i])) for key, values in friction.items()})


def write_urdf(params: SnakeParams, path: str | os.PathLike[str]) -> Path:
    """Write the URDF of ``params`` to ``path`` whole or not at all, validated by yourdfpy.

    Parameters
    ----------
    params : SnakeParams
        Robot parameters.
    path : str or os.PathLike
        Output file ending in ``.urdf``, in an existing folder.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ParameterError
        ``params`` is not a SnakeParams, or ``path`` not a ``.urdf`` file in a folder.
    SnakePinError
        yourdfpy rejects the generated description (a bug, not a user error).
    OSError
        The file cannot be written.
    """
    path = output_file(params, path, ".urdf", "output file")
    if not build_urdf(params).validate():
        raise SnakePinError(f"yourdfpy rejected the generated description of {params.name}")
    atomic_write_bytes(path, urdf_string(params).encode())
    return path


def passive_joints(urdf_text: str) -> tuple[int, ...]:
    """Return the joints marked passive (zero effort limit) in a URDF text.

    Parameters
    ----------
    urdf_text : str
        A URDF document whose joints are named ``joint_<i>`` (as generated here).

    Returns
    -------
    tuple of int
        Sorted 1-based indices i of the ``joint_<i>`` elements whose effort limit is 0.
    """
    urdf = yourdfpy.URDF.load(io.BytesIO(urdf_text.encode()), build_scene_graph=False,
                              load_meshes=False)
    out = []
    for name, joint in urdf.joint_map.items():
        match = re.fullmatch(r"joint_(\d+)", name)
        if match and joint.limit is not None and joint.limit.effort == 0.0:
            out.append(int(match.group(1)))
    return tuple(sorted(out))
