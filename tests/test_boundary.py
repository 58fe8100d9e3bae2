"""The library boundary: public callables refuse None and wrong types with the package's errors.

Every public callable (``snake_pin.__all__`` and the ``__all__`` of the modules listed in
:data:`MODULES`) has a row in :data:`ROWS`: valid arguments, from which the walk
substitutes each bad value of :data:`BAD` for one argument at a time. The call must raise
a :class:`~snake_pin.exceptions.SnakePinError` (never a bare TypeError, ValueError, ...);
for the rows of this walk's own modules, of the expected subclass and in one line that
names the argument. Result records (dataclasses the package fills from checked inputs)
have a row without arguments and say so.
"""

from __future__ import annotations

import importlib
import inspect
import math
import shutil
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

import snake_pin
from snake_pin import exceptions
from snake_pin.exceptions import ConfigurationError, ParameterError, SnakePinError

#: Modules whose ``__all__`` the walk covers, beside ``snake_pin`` itself.
MODULES = ("snake_pin.manipulability", "snake_pin.model", "snake_pin.gaits",
           "snake_pin.integrability", "snake_pin.singular", "snake_pin.sweeps",
           "snake_pin.friction", "snake_pin.planar_joint", "snake_pin.paper",
           "snake_pin.control", "snake_pin.control.base",
           "snake_pin.control.gains", "snake_pin.control.los",
           "snake_pin.control.lyapunov", "snake_pin.control.mpc", "snake_pin.control.pfl",
           "snake_pin.control.quasistatic", "snake_pin.control.reference")

#: The wrong values substituted for each argument: none, text, a list of the wrong
#: length (or type), a bool where a number or an array is expected, and a mapping.
BAD: dict[str, Any] = {"None": None, "str": "abc", "short": [1.0], "bool": True, "dict": {}}

#: A folder for the rows that write files, removed after the module's tests.
_FOLDER = tempfile.mkdtemp(prefix="snake_pin_boundary_")


@pytest.fixture(scope="module", autouse=True)
def _remove_folder() -> Iterator[None]:
    """Remove the rows' folder after the module's tests."""
    yield
    shutil.rmtree(_FOLDER, ignore_errors=True)


@dataclass(frozen=True)
class World:
    """Valid arguments shared by the rows (one small robot and what is made from it)."""

    params: Any
    snake: Any
    q: np.ndarray
    dq: np.ndarray
    planar: Any
    traj: Any
    lyapunov: Any
    pfl: Any
    quasistatic: Any
    folder: Path


@cache
def world() -> World:
    """The shared valid arguments, made once."""
    from snake_pin.gaits import arc, initial_state
    from snake_pin.urdf import urdf_string

    params = snake_pin.SnakeParams.table1(n=5)
    snake = snake_pin.Snake(params)
    folder = Path(_FOLDER)
    traj = snake_pin.simulate(snake, snake_pin.OpenLoop(lambda t: np.zeros(4)),
                              initial_state(5), 0.002)
    return World(params=params, snake=snake, q=arc(5, 0.3), dq=np.linspace(0.1, 0.4, 7),
                 planar=pin.buildModelFromXML(urdf_string(params)), traj=traj,
                 lyapunov=snake_pin.LyapunovController(snake),
                 pfl=snake_pin.PFLController(snake),
                 quasistatic=snake_pin.control.QuasiStaticLyapunovController(snake),
                 folder=folder)


@dataclass(frozen=True)
class Row:
    """One public callable: how to call it with valid arguments.

    ``call(w)`` returns the callable and its valid keyword arguments; ``skip`` names, per
    argument, the kinds of :data:`BAD` that are valid values there; ``errors`` the
    expected error class per argument (ParameterError by default); ``names`` the word a
    message uses for an argument when it is not the argument's own name; ``owner`` the
    module of another helper (those rows check the class only); ``record`` says why a
    callable is not walked.
    """

    call: Callable[[World], tuple[Callable[..., Any], dict[str, Any]]] | None = None
    skip: dict[str, str] = field(default_factory=dict)
    errors: dict[str, Any] = field(default_factory=dict)
    names: dict[str, str] = field(default_factory=dict)
    owner: str | None = None
    record: str | None = None


RECORD = "a result record the package fills from checked inputs"
ABSTRACT = "an abstract base class (no arguments)"
CONFIG = ConfigurationError
EITHER = (ConfigurationError, ParameterError)


def _m(name: str) -> ModuleType:
    return importlib.import_module(name)


def _serpenoid(w: World) -> Any:
    return snake_pin.Serpenoid(5, 0.5, 1.0, 1.0)


ROWS: dict[str, Row] = {
    # ------------------------------------------------------------------ snake_pin
    "snake_pin.trajectory.Trajectory": Row(record=RECORD),
    "snake_pin.control.base.Controller": Row(record=ABSTRACT),
    "snake_pin.control.base.ReferenceLaw": Row(record=ABSTRACT),
    "snake_pin.model.DynamicsDerivatives": Row(record=RECORD),
    "snake_pin.manipulability.Manipulability": Row(record=RECORD),
    "snake_pin.control.los.LOSController": Row(
        lambda w: (snake_pin.LOSController,
                   {"snake": w.snake, "path": _m("snake_pin.paths").Line(), "params": None,
                    "look_ahead": 0.5}),
        skip={"path": "None", "params": "None"}),
    "snake_pin.control.los.LOSParams": Row(
        lambda w: (_m("snake_pin.control.los").LOSParams,
                   {"alpha": 0.5, "omega": 0.8, "steering": "cascaded", "k_theta": 10.0,
                    "speed_period": 0.0})),
    "snake_pin.control.reference.LinearReference": Row(
        lambda w: (snake_pin.LinearReference, {"velocity": (0.1, 0.0, 0.0),
                                               "start": (0.0, 0.0, 0.0)}),
        errors={"velocity": CONFIG, "start": CONFIG}),
    "snake_pin.control.lyapunov.LyapunovController": Row(
        lambda w: (snake_pin.LyapunovController,
                   {"snake": w.snake, "reference": snake_pin.LinearReference(),
                    "gait": _serpenoid(w), "options": None, "k_w1": 2.0, "k_w2": 400.0,
                    "k_phi": 20.0, "lam": 10.0, "lam_shape": 5.0, "k_shape": 0.1}),
        skip={"reference": "None", "gait": "None", "options": "None", "k_phi": "None",
              "lam_shape": "None", "k_shape": "None"}),
    "snake_pin.control.lyapunov.LyapunovOptions": Row(
        lambda w: (_m("snake_pin.control.lyapunov").LyapunovOptions,
                   {"k_w1": 2.0, "k_w2": (400.0, 400.0, 45.0), "k_phi": 20.0, "lam": 10.0,
                    "lam_shape": 5.0, "k_shape": 0.1}),
        # the joints' gain alone has no size to check ([1.0]: one joint)
        skip={"k_phi": "None short", "lam_shape": "None", "k_shape": "None"}),
    "snake_pin.control.mpc.MPCController": Row(
        lambda w: (snake_pin.MPCController,
                   {"snake": w.snake, "reference": snake_pin.LinearReference(),
                    "gait": _serpenoid(w), "options": _m("snake_pin.control.mpc").MPCOptions(
                        horizon=0.02, resolve_period=0.01, first_iterations=1)}),
        skip={"reference": "None", "gait": "None", "options": "None"}),
    "snake_pin.control.mpc.MPCOptions": Row(
        lambda w: (_m("snake_pin.control.mpc").MPCOptions,
                   {"horizon": 0.5, "node_dt": 0.01, "resolve_period": 0.04,
                    "torque_bound": 1.0, "joint_limit": 1.5, "iterations": 2,
                    "first_iterations": 50, "step_halvings": 3, "feedback": True,
                    "weights": _m("snake_pin.ocp").CostWeights()}),
        skip={"feedback": "bool"}),
    "snake_pin.control.mpc.SolveStats": Row(record=RECORD),
    "snake_pin.control.base.OpenLoop": Row(
        lambda w: (snake_pin.OpenLoop, {"schedule": lambda t: np.zeros(4)})),
    "snake_pin.control.pfl.PFLController": Row(
        lambda w: (snake_pin.PFLController,
                   {"snake": w.snake, "reference": snake_pin.LinearReference(),
                    "gait": _serpenoid(w), "options": None, "k_v": 6.0, "k_p": 6.2,
                    "r_v": 0.041, "r_p": 0.079, "r_min": 1e-9, "climb_R": 0.5,
                    "climb_damping": 2.0}),
        skip={"reference": "None", "gait": "None", "options": "None",
              "climb_damping": "None"}),
    "snake_pin.control.pfl.PFLOptions": Row(
        lambda w: (_m("snake_pin.control.pfl").PFLOptions,
                   {"k_v": 6.0, "k_p": (6.2, 6.2, 6.2), "r_v": 0.041, "r_p": 0.079,
                    "r_min": 1e-9, "climb_R": 0.5, "climb_damping": 2.0}),
        # the joints' gains alone have no size to check ([1.0]: one joint)
        skip={"r_v": "short", "r_p": "short", "climb_damping": "None"}),
    "snake_pin.paths.PathReference": Row(
        lambda w: (snake_pin.PathReference, {"path": _m("snake_pin.paths").Line(),
                                             "timing": None}),
        skip={"timing": "None"}, owner="paths"),
    "snake_pin.gaits.Serpenoid": Row(
        lambda w: (snake_pin.Serpenoid, {"n": 5, "alpha": 0.5, "ts": 1.0, "v": 0.0})),
    "snake_pin.model.Snake": Row(
        lambda w: (snake_pin.Snake, {"params": w.params}),
        skip={"params": "None"}, errors={"params": CONFIG}),
    "snake_pin.params.SnakeParams": Row(
        lambda w: (snake_pin.SnakeParams,
                   {"n": 5, "link_length": 0.12, "mass": 0.182, "inertia": 2.2e-4,
                    "c_x": 0.5, "c_y": 0.5, "c_theta": 7.2e-5, "passive": (), "name": "x",
                    "com_offset": None}),
        skip={"com_offset": "None", "name": "str"}),
    "snake_pin.paths.along_track": Row(
        lambda w: (snake_pin.along_track, {"path": _m("snake_pin.paths").Line(),
                                           "points": np.zeros((2, 2)), "span": None}),
        skip={"span": "None"}, owner="paths"),
    "snake_pin.paths.cross_track_error": Row(
        lambda w: (snake_pin.cross_track_error, {"path": _m("snake_pin.paths").Line(),
                                                 "points": np.zeros((2, 2)), "span": None}),
        skip={"span": "None"}, owner="paths"),
    "snake_pin.gaits.arc": Row(
        lambda w: (snake_pin.arc, {"n": 5, "phi0": 0.3, "x_h": 0.0, "theta_1": 0.1})),
    "snake_pin.urdf.build_urdf": Row(
        lambda w: (snake_pin.build_urdf, {"params": w.params, "floating_base": True}),
        skip={"floating_base": "bool"}, owner="urdf"),
    "snake_pin.manipulability.dynamic_manipulability": Row(
        lambda w: (snake_pin.dynamic_manipulability,
                   {"model": w.snake.model, "data": w.snake.model.createData(), "q": w.q,
                    "unactuated": [0, 1, 2], "task": np.eye(7)[:2], "rows": [0, 1]}),
        skip={"task": "None", "rows": "None"},
        errors={"q": CONFIG, "task": EITHER}),
    "snake_pin.control.reference.head_first_reference": Row(
        lambda w: (snake_pin.head_first_reference, {"speed": 0.1})),
    "snake_pin.paths.load_path": Row(
        lambda w: (snake_pin.load_path, {"spec": "line"}), owner="paths"),
    "snake_pin.robot_file.load_robot": Row(
        lambda w: (snake_pin.load_robot, {"spec": "table1", "n": 5}), owner="robot_file"),
    "snake_pin.manipulability.manipulability": Row(
        lambda w: (_m("snake_pin.manipulability").manipulability,
                   {"snake": w.snake, "q": w.q, "free_joint": 2, "heading": True,
                    "blocks": False}),
        skip={"free_joint": "None", "heading": "bool", "blocks": "bool"},
        errors={"q": CONFIG}),
    "snake_pin.robot_file.read_robot_file": Row(
        lambda w: (snake_pin.read_robot_file,
                   {"path": snake_pin.write_robot_file(w.params, w.folder / "r.toml")}),
        owner="robot_file"),
    "snake_pin.robot_file.read_urdf": Row(
        lambda w: (snake_pin.read_urdf,
                   {"path": snake_pin.write_urdf(w.params, w.folder / "r.urdf"),
                    "friction": None}),
        skip={"friction": "None dict"}, owner="robot_file"),
    "snake_pin.robot_file.robot_paths": Row(lambda w: (snake_pin.robot_paths, {}),
                                            owner="robot_file"),
    "snake_pin.sim.simulate": Row(
        lambda w: (snake_pin.simulate,
                   {"snake": w.snake, "controller": snake_pin.OpenLoop(lambda t: np.zeros(4)),
                    "x0": np.r_[w.q, np.zeros(7)], "t_final": 0.002, "dt": 1e-3,
                    "control_dt": 1e-3, "method": "rk4", "max_speed": 1e3,
                    "max_distance": 1e3, "progress": False, "meta": None}),
        skip={"progress": "bool", "meta": "None dict"}, errors={"x0": CONFIG}),
    "snake_pin.gaits.straight": Row(
        lambda w: (snake_pin.straight, {"n": 5, "y_h": 0.0})),
    "snake_pin.robot_file.write_robot_file": Row(
        lambda w: (snake_pin.write_robot_file, {"params": w.params,
                                                "path": w.folder / "w.toml"}),
        owner="robot_file"),
    "snake_pin.urdf.write_urdf": Row(
        lambda w: (snake_pin.write_urdf, {"params": w.params, "path": w.folder / "w.urdf"}),
        owner="urdf"),
    # ------------------------------------------------------------ manipulability
    "snake_pin.manipulability.lateral_constraint_manipulability": Row(
        lambda w: (_m("snake_pin.manipulability").lateral_constraint_manipulability,
                   {"snake": w.snake, "q": w.q, "constrained": [2, 3]}),
        skip={"constrained": "None"}, errors={"q": CONFIG}),
    # --------------------------------------------------------------------- model
    "snake_pin.model.SnakeData": Row(
        lambda w: (_m("snake_pin.model").SnakeData, {"snake": w.snake}),
        skip={"pin_data": "None"}),
    "snake_pin.model.paper_model": Row(
        lambda w: (_m("snake_pin.model").paper_model, {"params": w.params})),
    # --------------------------------------------------------------------- gaits
    "snake_pin.gaits.configuration": Row(
        lambda w: (_m("snake_pin.gaits").configuration,
                   {"phi": np.zeros(4), "x_h": 0.0, "y_h": 0.0, "theta_1": 0.0}),
        skip={"phi": "short"}, errors={"phi": CONFIG}),
    "snake_pin.gaits.initial_state": Row(
        lambda w: (_m("snake_pin.gaits").initial_state, {"n": 5, "theta_1": 0.0})),
    # ------------------------------------------------------------- integrability
    "snake_pin.integrability.Involutivity": Row(record=RECORD),
    "snake_pin.integrability.PartialIntegrability": Row(record=RECORD),
    "snake_pin.integrability.conserved_quantity": Row(
        lambda w: (_m("snake_pin.integrability").conserved_quantity,
                   {"snake": w.snake, "q": w.q, "dq": w.dq}),
        errors={"q": CONFIG, "dq": CONFIG}),
    "snake_pin.integrability.implied_g2": Row(
        lambda w: (_m("snake_pin.integrability").implied_g2,
                   {"snake": w.snake, "q": w.q, "q0": np.zeros(7), "nodes": 4}),
        skip={"q0": "None"}, errors={"q": CONFIG, "q0": CONFIG}),
    "snake_pin.integrability.involutivity": Row(
        lambda w: (_m("snake_pin.integrability").involutivity,
                   {"snake": w.snake, "samples": 1, "seed": 0})),
    "snake_pin.integrability.partial_integrability": Row(
        lambda w: (_m("snake_pin.integrability").partial_integrability,
                   {"snake": w.snake, "k": 2, "samples": 1, "seed": 0, "tolerance": 1e-6})),
    # ------------------------------------------------------------------ singular
    "snake_pin.singular.SingularFamily": Row(record=RECORD),
    "snake_pin.singular.SingularSearch": Row(record=RECORD),
    "snake_pin.singular.find_singular_postures": Row(
        lambda w: (_m("snake_pin.singular").find_singular_postures,
                   {"params": w.params, "starts": 1, "bound": 1.0, "free_joint": None,
                    "seed": 0, "relative": 1e-6, "progress": False}),
        skip={"free_joint": "None", "progress": "bool"}),
    # -------------------------------------------------------------------- sweeps
    "snake_pin.sweeps.RMap": Row(record=RECORD),
    "snake_pin.sweeps.Sweep": Row(record=RECORD),
    "snake_pin.sweeps.r_map": Row(
        lambda w: (_m("snake_pin.sweeps").r_map,
                   {"snake": w.snake, "free_joint": None, "alpha_points": 3, "ts_points": 3,
                    "alpha_max": 1.0, "ts_max": 1.0}),
        skip={"free_joint": "None"}),
    "snake_pin.sweeps.sweep": Row(
        lambda w: (_m("snake_pin.sweeps").sweep,
                   {"snake": w.snake, "family": "arc", "free_joint": None, "points": 2,
                    "bounds": (0.1, 0.2), "progress": False}),
        skip={"free_joint": "None", "bounds": "None", "progress": "bool"}),
    # ------------------------------------------------------------------ friction
    "snake_pin.friction.FrictionData": Row(
        lambda w: (_m("snake_pin.friction").FrictionData, {"friction": w.snake.friction})),
    "snake_pin.friction.FrictionModel": Row(
        lambda w: (_m("snake_pin.friction").FrictionModel,
                   {"params": w.params, "model": w.snake.model})),
    "snake_pin.friction.damping_twin": Row(
        lambda w: (_m("snake_pin.friction").damping_twin,
                   {"model": w.snake.model, "params": w.params})),
    "snake_pin.friction.friction_forces": Row(
        lambda w: (_m("snake_pin.friction").friction_forces,
                   {"model": w.snake.model, "data": w.snake.model.createData(),
                    "params": w.params, "q": w.q, "dq": w.dq}),
        errors={"q": CONFIG, "dq": CONFIG}),
    # -------------------------------------------------------------- planar_joint
    "snake_pin.planar_joint.PlanarLayout": Row(
        lambda w: (_m("snake_pin.planar_joint").PlanarLayout,
                   {"n": 5, "nq": 8, "nv": 7, "idx_q": np.arange(4, 8),
                    "unbounded": np.zeros(4, dtype=bool), "signs": np.ones(4)})),
    "snake_pin.planar_joint.paper_dynamics": Row(
        lambda w: (_m("snake_pin.planar_joint").paper_dynamics,
                   {"model": w.planar, "data": w.planar.createData(), "q": w.q, "dq": w.dq}),
        errors={"q": CONFIG, "dq": CONFIG}),
    "snake_pin.planar_joint.paper_to_planar": Row(
        lambda w: (_m("snake_pin.planar_joint").paper_to_planar,
                   {"model": w.planar, "q": w.q, "dq": w.dq}),
        errors={"q": CONFIG, "dq": CONFIG}),
    "snake_pin.planar_joint.paper_to_planar_acceleration": Row(
        lambda w: (_m("snake_pin.planar_joint").paper_to_planar_acceleration,
                   {"model": w.planar, "q": w.q, "dq": w.dq, "ddq": w.dq}),
        errors={"q": CONFIG, "dq": CONFIG, "ddq": CONFIG}),
    "snake_pin.planar_joint.paper_to_planar_force": Row(
        lambda w: (_m("snake_pin.planar_joint").paper_to_planar_force,
                   {"model": w.planar, "q": w.q, "force": w.dq}),
        errors={"q": CONFIG, "force": CONFIG}),
    "snake_pin.planar_joint.planar_layout": Row(
        lambda w: (_m("snake_pin.planar_joint").planar_layout, {"model": w.planar})),
    "snake_pin.planar_joint.planar_to_paper": Row(
        lambda w: (_m("snake_pin.planar_joint").planar_to_paper,
                   {"model": w.planar, "q_planar": np.r_[0.0, 0.0, 1.0, 0.0, np.zeros(4)],
                    "v_planar": w.dq}),
        errors={"q_planar": CONFIG, "v_planar": CONFIG}),
    "snake_pin.planar_joint.planar_to_paper_acceleration": Row(
        lambda w: (_m("snake_pin.planar_joint").planar_to_paper_acceleration,
                   {"model": w.planar, "q_planar": np.r_[0.0, 0.0, 1.0, 0.0, np.zeros(4)],
                    "v_planar": w.dq, "a_planar": w.dq}),
        errors={"q_planar": CONFIG, "v_planar": CONFIG, "a_planar": CONFIG}),
    "snake_pin.planar_joint.velocity_map": Row(
        lambda w: (_m("snake_pin.planar_joint").velocity_map, {"model": w.planar, "q": w.q}),
        errors={"q": CONFIG}),
    # --------------------------------------------------------------------- paper
    **{f"snake_pin.paper.{name}": Row(
        lambda w, name=name: (getattr(snake_pin.paper, name), {"n": 5}))
       for name in ("actuation_matrix", "jacobian_q", "l_matrix")},
    **{f"snake_pin.paper.{name}": Row(
        lambda w, name=name: (getattr(snake_pin.paper, name),
                              {"params": w.params, "q": w.q, "dq": w.dq}),
        errors={"q": CONFIG, "dq": CONFIG})
       for name in ("bias", "coriolis")},
    **{f"snake_pin.paper.{name}": Row(
        lambda w, name=name: (getattr(snake_pin.paper, name), {"params": w.params, "q": w.q}),
        errors={"q": CONFIG})
       for name in ("friction_matrix", "g2", "inertia_matrix")},
    **{f"snake_pin.paper.{name}": Row(
        lambda w, name=name: (getattr(snake_pin.paper, name),
                              {"params": w.params, "theta": np.zeros(5)}),
        errors={"theta": CONFIG})
       for name in ("friction_matrix_bar", "inertia_matrix_bar", "jacobian_xy",
                    "w_matrix_bar")},
    "snake_pin.paper.k_matrix": Row(lambda w: (snake_pin.paper.k_matrix, {"params": w.params})),
    "snake_pin.paper.link_angles": Row(
        lambda w: (snake_pin.paper.link_angles, {"q": w.q}), errors={"q": CONFIG}),
    # ------------------------------------------------------- control.quasistatic
    "snake_pin.control.quasistatic.QuasiStaticLyapunovController": Row(
        lambda w: (snake_pin.control.QuasiStaticLyapunovController,
                   {"snake": w.snake, "reference": snake_pin.LinearReference(),
                    "gait": _serpenoid(w), "options": None, "k_w1": 2.0, "k_w2": 400.0,
                    "k_phi": 20.0, "servo_bandwidth": 20.0, "max_lead": 0.3,
                    "control_dt": 1e-3}),
        skip={"reference": "None", "gait": "None", "options": "None", "k_phi": "None"}),
    "snake_pin.control.quasistatic.QuasiStaticOptions": Row(
        lambda w: (_m("snake_pin.control.quasistatic").QuasiStaticOptions,
                   {"k_w1": 2.0, "k_w2": 400.0, "k_phi": 20.0, "servo_bandwidth": 20.0,
                    "max_lead": 0.3, "control_dt": 1e-3}),
        # the joints' gain alone has no size to check ([1.0]: one joint)
        skip={"k_phi": "None short"}),
    "snake_pin.control.quasistatic.servo_gains": Row(
        lambda w: (_m("snake_pin.control.quasistatic").servo_gains,
                   {"params": w.params, "bandwidth": 20.0})),
}

#: Public methods of Snake that check their arguments (walked beside the table).
SNAKE_METHODS: dict[str, tuple[str, ...]] = {
    "inertia_matrix": ("q",), "inverse_inertia_matrix": ("q",), "coriolis": ("q", "dq"),
    "friction_force": ("q", "dq"), "bias": ("q", "dq"), "generalized_torque": ("tau",),
    "forward_dynamics": ("q", "dq", "tau"), "dynamics_derivatives": ("q", "dq", "tau"),
    "kinetic_energy": ("q", "dq"), "head_pose": ("q",), "link_poses": ("q",),
    "joint_points": ("q",), "check_q": ("q",), "check_dq": ("dq",), "check_tau": ("tau",),
    "check_state": ("x",),
}

for _method, _arguments in SNAKE_METHODS.items():
    ROWS[f"snake_pin.model.Snake.{_method}"] = Row(
        lambda w, method=_method, arguments=_arguments: (
            getattr(w.snake, method),
            {a: {"q": w.q, "dq": w.dq, "tau": np.zeros(4), "x": np.r_[w.q, w.dq]}[a]
             for a in arguments}),
        errors=dict.fromkeys(_arguments, CONFIG))


#: Callables that left their module's ``__all__`` (a module's own pieces) but are still walked.
UNLISTED = frozenset({"snake_pin.model.paper_model", "snake_pin.planar_joint.PlanarLayout",
                      "snake_pin.planar_joint.paper_dynamics",
                      "snake_pin.planar_joint.velocity_map"})


def _public() -> dict[str, Any]:
    """Qualified name -> object of every public callable the walk must cover."""
    found: dict[str, Any] = {}
    for module in (snake_pin, *(_m(name) for name in MODULES)):
        for name in module.__all__:
            obj = getattr(module, name)
            if isinstance(obj, ModuleType) or not callable(obj):
                continue
            if inspect.isclass(obj) and issubclass(obj, (SnakePinError, KeyboardInterrupt)):
                continue  # the error classes take a message
            found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return found


def _cases() -> list[Any]:
    cases = []
    for key, row in ROWS.items():
        if row.call is None:
            continue
        for argument in row.call(world())[1]:
            for kind in BAD:
                if kind in row.skip.get(argument, "").split():
                    continue
                case_id = f"{key.removeprefix('snake_pin.')}:{argument}:{kind}"
                cases.append(pytest.param(key, argument, kind, id=case_id))
    return cases


def _normalised(text: str) -> str:
    return text.lower().replace("_", " ")


@pytest.mark.parametrize(("key", "argument", "kind"), _cases())
def test_wrong_argument_is_a_snake_pin_error(key: str, argument: str, kind: str) -> None:
    """A bad value for one argument raises the package's own error, in one line naming it."""
    row = ROWS[key]
    assert row.call is not None
    function, valid = row.call(world())
    valid[argument] = BAD[kind]
    try:
        function(**valid)
    except SnakePinError as exc:
        if row.owner is not None:
            return
        expected = row.errors.get(argument, ParameterError)
        assert isinstance(exc, expected), f"{type(exc).__name__}: {exc}"
        message = str(exc)
        assert "\n" not in message, message
        named = _normalised(row.names.get(argument, argument))
        assert named in _normalised(message), f"{argument!r} not named in: {message}"
    except Exception as exc:  # the point: nothing else may escape
        pytest.fail(f"{type(exc).__name__} (not a SnakePinError): {exc}")
    else:
        pytest.fail(f"{argument} = {BAD[kind]!r} was accepted")


@pytest.mark.parametrize("key", [k for k, row in ROWS.items() if row.call is not None])
def test_valid_arguments_are_accepted(key: str) -> None:
    """The table's valid call succeeds (so each bad value is what the walk refuses)."""
    row = ROWS[key]
    assert row.call is not None
    function, valid = row.call(world())
    function(**valid)


def test_table_covers_every_public_callable() -> None:
    """Every public callable of the walked modules has a row; every row is public or UNLISTED."""
    public = set(_public())
    walked = {key for key in ROWS if not key.startswith("snake_pin.model.Snake.")}
    assert public - walked == set(), sorted(public - walked)
    assert walked - public == UNLISTED, sorted((walked - public) ^ UNLISTED)


def test_rows_of_records_say_why() -> None:
    """A row without a call says why (a result record or an abstract class)."""
    for key, row in ROWS.items():
        assert (row.call is None) == (row.record is not None), key


def test_rows_without_task_are_refused() -> None:
    """rows= without task= has no effect, so it is refused in one line naming both."""
    w = world()
    with pytest.raises(ParameterError, match=r"rows.*task") as info:
        snake_pin.dynamic_manipulability(w.snake.model, w.snake.model.createData(), w.q,
                                         [0, 1, 2], rows="planar")
    assert "\n" not in str(info.value)


def test_rows_with_a_task_are_used() -> None:
    """rows= keeps the named rows of the task Jacobian: D is that of the kept rows."""
    w = world()
    model = w.snake.model
    task = np.eye(7)[:3]
    kept = snake_pin.dynamic_manipulability(model, model.createData(), w.q, [0, 1, 2],
                                            task=task, rows=[0, 1])
    alone = snake_pin.dynamic_manipulability(model, model.createData(), w.q, [0, 1, 2],
                                             task=task[:2])
    assert kept.D == pytest.approx(alone.D, rel=1e-12) and math.isfinite(kept.D)


def test_exceptions_module_lists_the_hierarchy() -> None:
    """Every class the walk skips as an error class is one of the package's own."""
    for name in snake_pin.__all__:
        obj = getattr(snake_pin, name)
        if inspect.isclass(obj) and issubclass(obj, BaseException):
            assert name in exceptions.__all__, name
