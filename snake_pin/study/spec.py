"""The study file: a base scenario, axes over its settings, and the runs they expand to.

Format, combination of axes, validation and run keys: :ref:`study-file`.
"""

from __future__ import annotations

import difflib
import functools
import hashlib
import itertools
import json
import math
import os
import reprlib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import Field, dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any, cast

import numpy as np

from .._io import decode_utf8, parse_toml, read_regular_file
from .._validation import is_number, one_line, printable_path
from ..control import LyapunovOptions, MPCOptions, PFLOptions, QuasiStaticOptions
from ..control.gains import K_PHI_FIRST, K_PHI_REST
from ..exceptions import ParameterError, SnakePinError
from ..metrics import ERROR_WINDOW
from ..params import SnakeParams
from ..sim import MAX_SUBSTEPS, check_size, check_steps
from .errors import StudyError

__all__ = ["CONTROLLERS", "MAX_RUNS", "MAX_STUDY_BYTES", "MODELS", "SETTINGS", "Scenario",
           "Setting", "StudySpec", "load_study", "run_key"]

#: Most runs one study may expand to.
MAX_RUNS = 100_000
#: Largest study file [bytes].
MAX_STUDY_BYTES = 1 << 20
#: Seeds (of random axes and of the initial-posture noise) lie in 0..MAX_SEED.
MAX_SEED = 2**32 - 1
#: Version of the key's canonical form; part of every key (2: the robot by content only).
KEY_FORMAT = 2
#: Engine control period [s] (``WheelSpec().control_dt``), for the t_final bound.
ENGINE_CONTROL_DT = 1e-3
MODELS = ("viscous", "engine")
CONTROLLERS = ("lyapunov", "velocity", "pfl", "mpc")
_TRACKING = ("lyapunov", "velocity")
_TABLES = ("study", "base", "axes")
_STUDY_KEYS = ("name", "description")
_GRID_FORMS = ("values", "linspace")
_RANDOM_FORMS = ("uniform", "normal")
_AXIS_KEYS = (*_GRID_FORMS, *_RANDOM_FORMS, "samples", "seed")
#: Engine limits, as ``snake-pin engine`` (a wheel bigger than a link hits its neighbours).
_MAX_WHEEL_RADIUS = 0.1
_MAX_MU = 10.0


@dataclass(frozen=True)
class Setting:
    """One scalar setting of a scenario.

    Parameters
    ----------
    name, kind, default
        Key; ``float``, ``int``, ``str``, ``bool`` or ``joints``; default (None: per run).
    help
        One line for the documentation.
    low, high, open_low, choices
        The domain: ``low <= value <= high`` (``low <`` if ``open_low``), or ``choices``.
    models, controllers
        Where it applies.
    """

    name: str
    kind: str
    default: Any
    help: str
    low: float | None = None
    high: float | None = None
    open_low: bool = False
    choices: tuple[str, ...] = ()
    models: tuple[str, ...] = MODELS
    controllers: tuple[str, ...] = CONTROLLERS

    def _applies(self, model: str, controller: str) -> bool:
        """Whether this setting applies to a run of ``model`` and ``controller``."""
        return model in self.models and controller in self.controllers

    def _domain(self) -> str:
        """The domain in words, e.g. ``"> 0"``, ``"in [0, 10]"``, ``"one of a, b"``."""
        if self.kind == "bool":
            return "true or false"
        if self.choices:
            return "one of " + ", ".join(self.choices)
        if self.low is not None and self.high is not None:
            return f"in {'(' if self.open_low else '['}{self.low:g}, {self.high:g}]"
        if self.low is not None:
            return f"{'>' if self.open_low else '>='} {self.low:g}"
        return "finite"

    def _problem(self, value: Any) -> str:
        """Why a value (of the setting's kind) is outside the domain ("" when inside)."""
        if self.kind == "bool":
            return ""
        if self.kind == "str":
            return "" if not self.choices or value in self.choices else \
                f"must be {self._domain()}, got {_short(value)}"
        if self.kind == "joints":
            return "" if all(k >= 1 for k in value) else \
                f"joints are numbered from 1, got {_short(value)}"
        below = self.low is not None and (value < self.low or
                                          (self.open_low and value == self.low))
        above = self.high is not None and value > self.high
        return f"must be {self._domain()}, got {value!r}" if below or above else ""


#: The options dataclass of each controller: their fields are the laws' settings.
LAW_OPTIONS: dict[str, type] = {"lyapunov": LyapunovOptions, "velocity": QuasiStaticOptions,
                                "pfl": PFLOptions, "mpc": MPCOptions}
#: Option fields a study does not set: the controller's period is the run's own
#: ``control_dt``; r_min and climb_damping keep their defaults.
_NOT_IN_STUDIES = frozenset({"control_dt", "r_min", "climb_damping"})
#: Words for a head gain's diagonal entries in the settings' help.
_ENTRY_WORDS = {"x": "x_h", "y": "y_h", "theta": "theta_1"}
#: The MPC's cost weights (:class:`~snake_pin.ocp.CostWeights`) are settings with this prefix.
WEIGHT_PREFIX = "weight_"


def _law_fields() -> dict[str, tuple[Field[Any], tuple[str, ...]]]:
    """Each option field a study sets (``weight_<name>`` for the MPC's cost weights), with the
    controllers that declare it."""
    found: dict[str, tuple[Field[Any], tuple[str, ...]]] = {}
    for controller, cls in LAW_OPTIONS.items():
        for f in fields(cls):
            if f.name in _NOT_IN_STUDIES:
                continue
            inner = fields(f.default) if is_dataclass(f.default) else ()
            for name, g in [(WEIGHT_PREFIX + g.name, g) for g in inner] or [(f.name, f)]:
                first, owners = found.get(name, (g, ()))
                found[name] = first, (*owners, controller)
    return found


def _law_settings() -> list[Setting]:
    """The laws' settings from their options' fields: a head gain one per diagonal entry,
    K_phi two (``k_phi_1``, ``k_phi``), another gain one scalar (times identity)."""
    out = []
    for name, (f, controllers) in _law_fields().items():
        meta, default = f.metadata, f.default
        kind = {bool: "bool", int: "int"}.get(type(default), "float")
        made = functools.partial(Setting, kind=kind, low=meta["low"], high=meta["high"],
                                 open_low=meta["open_low"], models=("viscous",),
                                 controllers=controllers)
        symbol, unit = meta.get("symbol"), f" [{meta['unit']}]" if meta["unit"] else ""
        if meta.get("entries"):
            out += [made(name=f"{name}_{entry}", default=value,
                         help=f"{symbol} entry of {_ENTRY_WORDS[entry]}")
                    for entry, value in zip(meta["entries"], cast("tuple[float, ...]", default),
                                            strict=True)]
        elif symbol and meta["size"] is None and default is None:  # K_phi
            out += [made(name=f"{name}_1", default=K_PHI_FIRST, help=f"{symbol} entry of joint 1"),
                    made(name=name, default=K_PHI_REST,
                         help=f"{symbol} entries of joints 2..n-1")]
        elif symbol:
            out.append(made(name=name, default=default, help=f"{symbol} (times identity)"))
        else:
            extra = f" ({meta['default_doc']})" if meta.get("default_doc") else ""
            out.append(made(name=name, default=default, help=meta["doc"] + unit + extra))
    return out


def law_options(settings: Mapping[str, Any], joints: int) -> Any:
    """The options of a viscous run's controller from its settings, for ``joints`` = n - 1
    (a ParameterError for MPC settings that do not combine)."""
    controller = settings["controller"]
    cls = LAW_OPTIONS[controller]
    values: dict[str, Any] = {}
    for f in fields(cls):
        meta = f.metadata
        if is_dataclass(f.default) and not isinstance(f.default, type):
            values[f.name] = replace(f.default, **{g.name: settings[WEIGHT_PREFIX + g.name]
                                                   for g in fields(f.default)})
        elif f.name == "control_dt":
            values[f.name] = settings["control_dt"]
        elif f.name in _NOT_IN_STUDIES:
            continue
        elif meta["entries"]:
            values[f.name] = tuple(settings[f"{f.name}_{e}"] for e in meta["entries"])
        elif meta["symbol"] and meta["size"] is None and f.default is None:  # K_phi
            values[f.name] = (settings[f"{f.name}_1"],
                              *([settings[f.name]] * (joints - 1)))
        else:
            values[f.name] = settings[f.name]
    return cls(**values)


_viscous = functools.partial(Setting, models=("viscous",))
_engine = functools.partial(Setting, models=("engine",), controllers=_TRACKING)
#: Every setting a study can give in ``[base]`` or vary on an axis.
SETTINGS: dict[str, Setting] = {s.name: s for s in (
    # the run
    Setting("robot", "str", "table1", "a preset (table1, engine) or a .toml/.urdf robot file"),
    Setting("model", "str", "viscous", "viscous (Pinocchio, RK4) or engine (MuJoCo, wheels)",
            choices=MODELS),
    Setting("controller", "str", "lyapunov", "lyapunov (torque level), velocity (velocity "
            "level with joint servos), pfl or mpc (receding-horizon Box-FDDP)",
            choices=CONTROLLERS),
    Setting("t_final", "float", 60.0, "duration [s]", 0.0, open_low=True),
    Setting("error_window", "float", ERROR_WINDOW, "head errors are judged over "
            "t >= error_window [s]", 0.0),
    Setting("passive", "joints", (), "joints without an actuator (a list, base only)"),
    Setting("failed_joint", "int", 0, "one more joint whose actuator gives no torque "
            "(0 = none)", 0.0),
    # integration, friction (None: the robot's own), reference, gait, initial posture
    _viscous("dt", "float", 1e-3, "RK4 step [s]", 0.0, open_low=True),
    _viscous("control_dt", "float", 1e-3, "control period [s], a multiple of dt", 0.0,
             open_low=True),
    _viscous("c_x", "float", None, "friction along each link [N s/m] (default: the robot's)",
             0.0),
    _viscous("c_y", "float", None, "friction across each link [N s/m] (default: the robot's)",
             0.0),
    _viscous("c_theta", "float", None, "rotational friction [N m s] (default: the robot's)",
             0.0),
    _viscous("ref_speed", "float", 0.1, "head reference speed along +x [m/s]"),
    _viscous("gait_alpha", "float", None, "serpenoid winding angle [rad] (lyapunov/velocity/"
             "mpc pi/6, pfl pi/3)"),
    _viscous("gait_ts", "float", None, "serpenoid periods along the body (1.5; pfl 1)", 0.0,
             open_low=True),
    _viscous("gait_v", "float", None, "serpenoid temporal frequency [rad/s] (2; pfl 0.18)"),
    _viscous("init_phi", "float", math.pi / 6, "joint angles of the initial arc [rad] "
             "(eq. 82)"),
    Setting("init_noise", "float", 0.0, "standard deviation of Gaussian noise added to each "
            "initial joint angle [rad] (engine runs are chaotic: spread them with init_seed)",
            0.0),
    Setting("init_seed", "int", 0, "seed of that noise", 0.0, MAX_SEED),
    # the control laws: generated from their options dataclasses (snake_pin.control)
    *_law_settings(),
    # engine (MuJoCo)
    _engine("mu", "float", 1.0, "wheel-floor Coulomb friction", 0.0, _MAX_MU, open_low=True),
    _engine("wheel_radius", "float", 0.03, "wheel radius [m]", 0.0, _MAX_WHEEL_RADIUS,
            open_low=True),
    _engine("cone", "str", "elliptic", "MuJoCo friction cone (pyramidal: faster, but its "
            "sideways friction depends on the heading, 26 % weaker at 45 degrees)",
            choices=("elliptic", "pyramidal")),
    _engine("cutoff", "float", 10.0, "cut-off of the velocity filter [Hz]", 0.0, open_low=True),
)}

#: Gait defaults per controller: (alpha, T_s, v) of Sections VI.2 and VI.1.
GAIT_DEFAULTS = {"lyapunov": (math.pi / 6, 1.5, 2.0), "velocity": (math.pi / 6, 1.5, 2.0),
                 "pfl": (math.pi / 3, 1.0, 0.18), "mpc": (math.pi / 6, 1.5, 2.0)}


# ------------------------------------------------------------------ the parsed study
@dataclass(frozen=True)
class Axis:
    """One axis: the setting it varies, its form (values, linspace, uniform, normal), its
    values in order (drawn for the random forms) and its normalised source for study.json."""

    setting: str
    form: str
    values: tuple[Any, ...]
    source: dict[str, Any]

    @property
    def random(self) -> bool:
        """Whether the axis is sampled (uniform/normal), not a grid."""
        return self.form in _RANDOM_FORMS


@dataclass(frozen=True, eq=False)
class Scenario:
    """One run of a study, normalised.

    Parameters
    ----------
    index, key
        Position in the study (random point innermost); :func:`run_key`.
    settings
        Every setting that applies to its model and controller, defaults filled in.
    params
        The robot it simulates (friction applied, ``passive`` plus ``failed_joint``).
    """

    index: int
    key: str
    settings: dict[str, Any]
    params: SnakeParams

    @property
    def model(self) -> str:
        """``viscous`` or ``engine``."""
        return self.settings["model"]

    @property
    def controller(self) -> str:
        """``lyapunov``, ``velocity``, ``pfl`` or ``mpc``."""
        return self.settings["controller"]

    def __getitem__(self, name: str) -> Any:
        return self.settings[name]


@dataclass(frozen=True, eq=False)
class StudySpec:
    """A validated study: its axes and the runs they expand to (see the module docstring).

    Parameters
    ----------
    path, name, description
        The study file; ``[study]`` name and description.
    base, axes
        The settings ``[base]`` gives; grid axes (in file order), then random axes.
    scenarios, study_hash
        Every run, in study order; SHA-256 (hex) of the sorted run keys.
    """

    path: Path
    name: str
    description: str
    base: dict[str, Any]
    axes: tuple[Axis, ...]
    scenarios: tuple[Scenario, ...] = field(repr=False)
    study_hash: str

    @property
    def grid_axes(self) -> tuple[Axis, ...]:
        """The crossed axes."""
        return tuple(a for a in self.axes if not a.random)

    @property
    def random_axes(self) -> tuple[Axis, ...]:
        """The jointly sampled axes."""
        return tuple(a for a in self.axes if a.random)

    def to_dict(self) -> dict[str, Any]:
        """The normalised study as plain JSON data (written to ``study.json``).

        Returns
        -------
        dict
            Name, description, base, axes, run count, study hash, key format.
        """
        return {"name": self.name, "description": self.description, "base": _plain(self.base),
                "axes": [{"setting": a.setting, **a.source} for a in self.axes],
                "runs": len(self.scenarios), "study_hash": self.study_hash,
                "key_format": KEY_FORMAT}


# ------------------------------------------------------------------------- keys
def canonical_json(value: Any) -> str:
    """Canonical JSON text of plain data: sorted keys, no spaces, ASCII, floats by ``repr``
    (-0.0 as 0.0); a ValueError for NaN or infinities."""
    return json.dumps(_plain(value), sort_keys=True, separators=(",", ":"), ensure_ascii=True,
                      allow_nan=False)


def run_key(settings: Mapping[str, Any], params: SnakeParams) -> str:
    """The key of a run: SHA-256 of its canonical settings and robot.

    Parameters
    ----------
    settings
        The run's normalised settings (``robot`` left out: the robot counts by ``params``).
    params
        The robot it simulates.

    Returns
    -------
    str
        64 hexadecimal characters.
    """
    named = {name: value for name, value in settings.items() if name != "robot"}
    text = canonical_json({"format": KEY_FORMAT, "settings": named,
                           "robot": params.to_dict()})
    return hashlib.sha256(text.encode("ascii")).hexdigest()


def _plain(value: Any) -> Any:
    """Plain JSON data with -0.0 normalised (tuples become lists)."""
    if isinstance(value, bool) or value is None or isinstance(value, (str, int)):
        return value
    if isinstance(value, float):
        return 0.0 if value == 0.0 else value
    if isinstance(value, np.generic):
        return _plain(value.item())
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    raise TypeError(f"not plain data: {type(value).__name__}")


# ----------------------------------------------------------------------- reading
def load_study(path: str | os.PathLike[str]) -> StudySpec:
    """Read and validate a study file (see the module docstring).

    Parameters
    ----------
    path
        The TOML study file.

    Returns
    -------
    StudySpec
        The validated study.

    Raises
    ------
    StudyError
        One line naming the file and the key at fault.
    """
    try:
        file = Path(path)
    except TypeError:
        raise StudyError(f"study file must be a path, got {_short(path)}") from None
    where = functools.partial(_error, printable_path(file))
    data = read_regular_file(file, limit=MAX_STUDY_BYTES, kind="study file", error=where)
    return parse_study(decode_utf8(data, error=where), file)


def parse_study(text: str, path: str | os.PathLike[str] = "<study>") -> StudySpec:
    """Validate study text (:func:`load_study`'s); ``path`` is named in errors, and relative
    robot files are read beside it."""
    file = Path(path)
    where = functools.partial(_error, printable_path(file))
    if not isinstance(text, str):
        raise where(f"study text must be a string, got {_kind_name(text)}")
    if len(text) > MAX_STUDY_BYTES:
        raise where(f"is larger than {MAX_STUDY_BYTES} characters: not a study file")
    doc = parse_toml(text, error=where)
    _check_keys(where, "", doc, _TABLES, "table")
    study = _table(where, doc, "study")
    if "batch_size" in study:
        raise where("[study] batch_size is no longer a setting: every run is one task "
                    "(remove the line)")
    _check_keys(where, "[study]", study, _STUDY_KEYS, "key")
    name = study.get("name", file.stem)
    description = study.get("description", "")
    for key, value in (("name", name), ("description", description)):
        if not isinstance(value, str) or not value.isprintable() or len(value) > 2000:
            raise where(f"[study] {key} must be one line of printable text, got {_short(value)}")
    base_doc = _table(where, doc, "base")
    base = {}
    for key, value in base_doc.items():
        setting = _known(where, key, "[base] unknown setting")
        base[key] = _typed(where, f"[base] {key}", setting, value)
    axes_doc = _table(where, doc, "axes")
    axes = [_axis(where, name_, spec, base) for name_, spec in axes_doc.items()]
    axes = [a for a in axes if not a.random] + [a for a in axes if a.random]
    random = {a.setting: len(a.values) for a in axes if a.random}  # sampled jointly
    if len(set(random.values())) > 1:
        listed = ", ".join(f"{k} {v}" for k, v in random.items())
        raise where(f"[axes] random axes are sampled jointly and need the same samples; "
                    f"got {listed}")
    total = math.prod([len(a.values) for a in axes if not a.random] + [*set(random.values())])
    if total > MAX_RUNS:
        raise where(f"[axes] the study expands to {total} runs, at most {MAX_RUNS}")
    scenarios = _scenarios(where, file, base, axes)
    keys = sorted(s.key for s in scenarios)
    study_hash = hashlib.sha256(canonical_json(keys).encode("ascii")).hexdigest()
    return StudySpec(path=file, name=name, description=description, base=base,
                     axes=tuple(axes), scenarios=tuple(scenarios), study_hash=study_hash)


def _error(shown: str, message: str) -> StudyError:
    """A one-line error of the study file ``shown``."""
    return StudyError(one_line(f"{shown}: {message}", 400))


_Where = Callable[[str], StudyError]


def _check_keys(where: _Where, table: str, doc: Mapping[str, Any], allowed: Sequence[str],
                kind: str) -> None:
    for key in doc:
        if key not in allowed:
            hint = _did_you_mean(key, allowed) or f" (known: {', '.join(allowed)})"
            raise where(f"{table + ' ' if table else ''}unknown {kind} {_short(key)}{hint}")


def _did_you_mean(key: object, known: Iterable[str]) -> str:
    close = difflib.get_close_matches(str(key), list(known), n=1)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _table(where: _Where, doc: Mapping[str, Any], key: str) -> dict[str, Any]:
    value = doc.get(key, {})
    if not isinstance(value, dict):
        raise where(f"[{key}] must be a table, got {_kind_name(value)}")
    return value


def _known(where: _Where, key: str, message: str, after: str = "") -> Setting:
    """The setting ``key``, else an error naming it and the closest known name."""
    if key not in SETTINGS:
        raise where(f"{message} {_short(key)}{after}{_did_you_mean(key, SETTINGS)}")
    return SETTINGS[key]


def _typed(where: _Where, label: str, setting: Setting, value: Any) -> Any:
    """``value`` converted to the setting's kind and checked against its domain."""
    if setting.kind in _SCALARS:
        accepts, words = _SCALARS[setting.kind]
        if not accepts(value):
            raise where(f"{label} must be {words}, got {_kind_name(value)} {_short(value)}")
    if setting.kind == "float":
        value = float(value)
        if not math.isfinite(value):
            raise where(f"{label} must be finite, got {value}")
        value = 0.0 if value == 0.0 else value
    elif setting.kind == "joints":
        if not isinstance(value, list) or not all(_is_int(k) for k in value):
            raise where(f"{label} must be a list of joint numbers, got {_short(value)}")
        if len(set(value)) != len(value):
            raise where(f"{label} lists a joint twice: {_short(value)}")
        value = tuple(sorted(value))
    problem = setting._problem(value)
    if problem:
        raise where(f"{label} {problem}")
    return value


def _axis(where: _Where, name: str, spec: Any, base: Mapping[str, Any]) -> Axis:
    label = f"[axes.{name}]"
    setting = _known(where, name, f"{label} there is no setting", " to vary")
    if not isinstance(spec, dict):
        raise where(f"{label} must be a table such as {{ values = [...] }}, got {_kind_name(spec)}")
    if setting.kind == "joints":
        raise where(f"{label} passive is a list (base only); vary failed_joint instead")
    if name in base:
        raise where(f"{label} {name} is also set in [base]; give it in one place")
    _check_keys(where, label, spec, _AXIS_KEYS, "key")
    forms = [f for f in (*_GRID_FORMS, *_RANDOM_FORMS) if f in spec]
    if len(forms) != 1:
        raise where(f"{label} needs exactly one of values, linspace, uniform, normal; "
                    f"got {', '.join(forms) or 'none'}")
    form = forms[0]
    random = form in _RANDOM_FORMS
    for key in ("samples", "seed"):
        if key in spec and not random:
            raise where(f"{label} {key} applies to uniform/normal axes, not {form}")
    if form != "values" and setting.kind != "float":
        raise where(f"{label} {name} takes {setting.kind} values: use values = [...]")
    raw = spec[form]
    if form == "values":
        if not isinstance(raw, list):
            raise where(f"{label} values must be a list, got {_kind_name(raw)}")
        if not raw:
            raise where(f"{label} values is empty")
        values = [_typed(where, f"{label} values[{i}]", setting, v) for i, v in enumerate(raw)]
        seen: dict[Any, int] = {}
        for i, v in enumerate(values):
            if v in seen:
                raise where(f"{label} values[{i}] repeats values[{seen[v]}] = {v!r}")
            seen[v] = i
        return Axis(name, form, tuple(values), {"values": list(values)})
    shape = "[a, b, n]" if form == "linspace" else "[a, b]"
    if not isinstance(raw, list) or len(raw) != shape.count(",") + 1 or \
            not all(is_number(v) for v in raw):
        raise where(f"{label} {form} must be {shape} (numbers), got {_short(raw)}")
    numbers = [float(v) for v in raw]
    if not all(math.isfinite(v) for v in numbers):
        raise where(f"{label} {form} must be finite, got {_short(raw)}")
    if form == "linspace":
        low, high, count = numbers
        if not _is_int(raw[2]) or count < 1:
            raise where(f"{label} linspace = [a, b, n] needs an integer n >= 1, "
                        f"got {_short(raw[2])}")
        if count > MAX_RUNS:
            raise where(f"{label} linspace has {int(count)} points, at most {MAX_RUNS}")
        if count > 1 and low == high:
            raise where(f"{label} linspace from {low!r} to itself repeats one value")
        drawn: list[float] = np.linspace(low, high, int(count)).tolist()
        source: dict[str, Any] = {"linspace": [low, high, int(count)]}
    else:
        samples: Any = spec.get("samples")
        seed: Any = spec.get("seed")
        if not _is_int(samples) or samples < 1:
            raise where(f"{label} needs samples = N (an integer >= 1), got {_short(samples)}")
        if samples > MAX_RUNS:
            raise where(f"{label} samples = {samples}, at most {MAX_RUNS}")
        if not _is_int(seed) or not 0 <= seed <= MAX_SEED:
            raise where(f"{label} needs seed = S (an integer in 0..2**32 - 1), got {_short(seed)}")
        rng = np.random.default_rng(seed)
        a, b = numbers
        if form == "uniform":
            if not a < b:
                raise where(f"{label} uniform = [a, b] needs a < b, got [{a!r}, {b!r}]")
            drawn = rng.uniform(a, b, size=(samples,)).tolist()
        else:
            if not b > 0:
                raise where(f"{label} normal = [mean, sigma] needs sigma > 0, got {b!r}")
            drawn = rng.normal(a, b, size=(samples,)).tolist()
        source = {form: [a, b], "samples": samples, "seed": seed}
    values = []
    for i, v in enumerate(drawn):
        v = 0.0 if v == 0.0 else float(v)
        problem = setting._problem(v)
        if problem:
            raise where(f"{label} value {i} ({v!r}) of {form}: {name} {problem}")
        values.append(v)
    return Axis(name, form, tuple(values), {**source, "values": values})


# -------------------------------------------------------------------- expansion
def _scenarios(where: _Where, file: Path, base: Mapping[str, Any],
               axes: Sequence[Axis]) -> list[Scenario]:
    grid = [a for a in axes if not a.random]
    random = [a for a in axes if a.random]
    points = list(zip(*(a.values for a in random), strict=True)) if random else [()]
    origin = {a.setting: f"[axes.{a.setting}]" for a in axes}

    def place(name: str) -> str:
        return origin.get(name, "[base]")

    _check_applicability(where, base, axes, set(base) | set(origin), place)
    robots = _robots(where, file, base, axes, place)
    scenarios: list[Scenario] = []
    cache: dict[tuple[Any, ...], SnakeParams] = {}
    seen: dict[str, int] = {}
    names = [a.setting for a in grid] + [a.setting for a in random]
    for values in itertools.product(*(a.values for a in grid)):
        for point in points:
            settings = _normalise({**base, **dict(zip(names, (*values, *point), strict=True))})
            params = _params(where, settings, robots[settings["robot"]], place, cache)
            _check_run(where, settings, params, place)
            key = run_key(settings, params)
            if key in seen:
                raise where(f"[axes] runs {seen[key]} and {len(scenarios)} are the same run "
                            "(identical settings)")
            seen[key] = len(scenarios)
            scenarios.append(Scenario(len(scenarios), key, settings, params))
    return scenarios


def _check_applicability(where: _Where, base: Mapping[str, Any], axes: Sequence[Axis],
                         explicit: set[str], place: Any) -> None:
    """Every explicit setting must apply to every (model, controller) the study has."""
    varied = {a.setting: a.values for a in axes}
    pairs = list(itertools.product(*(varied.get(name, (base.get(name, SETTINGS[name].default),))
                                     for name in ("model", "controller"))))
    for model, controller in pairs:
        if model == "engine" and controller in ("pfl", "mpc"):
            raise where(f"{place('controller')} controller {controller} runs on the "
                        f"viscous model only, but {place('model')} has model engine")
    for name in sorted(explicit, key=list(SETTINGS).index):
        setting = SETTINGS[name]
        for model, controller in pairs:
            if not setting._applies(model, controller):
                scope, other = (f"the {'/'.join(setting.models)} model", f"model {model}") \
                    if model not in setting.models else \
                    (f"controller {'/'.join(setting.controllers)}", f"controller {controller}")
                raise where(f"{place(name)} {name} applies to {scope} only, and this "
                            f"study has runs with {other}")


def _robots(where: _Where, file: Path, base: Mapping[str, Any], axes: Sequence[Axis],
            place: Any) -> dict[str, SnakeParams]:
    """Each robot the study names, loaded once (files relative to the study file)."""
    from ..robot_file import load_robot

    names: Iterable[str] = next((a.values for a in axes if a.setting == "robot"),
                                (base.get("robot", SETTINGS["robot"].default),))
    robots: dict[str, SnakeParams] = {}
    for name in names:
        local = file.parent / name
        spec = str(local) if not os.path.isabs(name) and local.exists() else name
        try:
            robot = load_robot(spec)
        except SnakePinError as exc:
            raise where(f"{place('robot')} robot {_short(name)}: "
                        f"{one_line(str(exc), 300)}") from None
        same = next((other for other, known in robots.items() if known == robot), None)
        if same is not None:
            raise where(f"{place('robot')} robot {_short(name)} is the same robot as "
                        f"{_short(same)} (the same file or content): one run, give it once")
        robots[name] = robot
    return robots


def _normalise(chosen: Mapping[str, Any]) -> dict[str, Any]:
    """Every setting that applies to the run's model and controller, defaults resolved
    (those None in :data:`SETTINGS` depend on other settings)."""
    model = chosen.get("model", SETTINGS["model"].default)
    controller = chosen.get("controller", SETTINGS["controller"].default)
    settings = {name: chosen.get(name, s.default) for name, s in SETTINGS.items()
                if s._applies(model, controller)}
    settings["passive"] = list(settings["passive"])
    if model != "viscous":
        return settings
    for name, value in zip(("gait_alpha", "gait_ts", "gait_v"), GAIT_DEFAULTS[controller],
                           strict=True):
        if settings[name] is None:
            settings[name] = value
    if controller == "lyapunov":
        options = LyapunovOptions(lam=settings["lam"], lam_shape=settings["lam_shape"],
                                  k_shape=settings["k_shape"]).resolved(
            passive=bool(settings["passive"] or settings["failed_joint"]))
        settings["lam_shape"], settings["k_shape"] = options.lam_shape, options.k_shape
    return settings


def _params(where: _Where, settings: Mapping[str, Any], robot: SnakeParams, place: Any,
            cache: dict[tuple[Any, ...], SnakeParams]) -> SnakeParams:
    """The robot of one run: friction overrides, passive joints plus the failed joint."""
    n = robot.n
    for k in settings["passive"]:
        if not 1 <= k <= n - 1:
            raise where(f"[base] passive joint {k} is outside 1..{n - 1} for robot "
                        f"{_short(settings['robot'])} (n = {n})")
    failed = settings["failed_joint"]
    if not 0 <= failed <= n - 1:
        raise where(f"{place('failed_joint')} failed_joint {failed} is outside 0..{n - 1} "
                    f"(0 = none) for robot {_short(settings['robot'])} (n = {n})")
    if failed and failed in settings["passive"]:
        raise where(f"{place('failed_joint')} failed_joint {failed} is already passive in [base]")
    passive = tuple(sorted({*settings["passive"], *([failed] if failed else [])}))
    friction = {k: settings[k] for k in ("c_x", "c_y", "c_theta")
                if settings.get(k) is not None}
    cache_key = (settings["robot"], passive, tuple(sorted(friction.items())))
    params = cache.get(cache_key)
    if params is None:
        try:
            params = robot.replace(passive=passive, **friction)
        except SnakePinError as exc:
            names = ", ".join(sorted({place(k) for k in friction}) or [place("robot")])
            raise where(f"{names} robot {_short(settings['robot'])}: "
                        f"{one_line(str(exc), 300)}") from None
        cache[cache_key] = params
    return params


def _check_run(where: _Where, settings: Mapping[str, Any], params: SnakeParams,
               place: Any) -> None:
    """Cross-setting checks of one run (things that only fail when combined)."""
    controller, model = settings["controller"], settings["model"]
    n = params.n
    if not params.actuated:
        raise where(f"{place('failed_joint')} every joint of robot "
                    f"{_short(settings['robot'])} would be passive: nothing to control")
    if controller == "pfl":
        if params.passive:
            raise where(f"{place('controller')} controller pfl needs every joint "
                        f"actuated; {place('failed_joint')} or [base] passive leaves "
                        f"joint {params.passive[0]} without torque")
        if n < 4:
            raise where(f"{place('controller')} controller pfl needs n >= 4 links, robot "
                        f"{_short(settings['robot'])} has {n}")
    if controller == "mpc":
        try:
            law_options(settings, n - 1)
        except SnakePinError as exc:
            message = one_line(str(exc), 300)
            words = set(message.split())  # a cross-field check: each field was parsed
            named = [name for name in settings
                     if SETTINGS[name].controllers == ("mpc",) and name in words]
            raise where(f"{place(named[0]) if named else place('controller')} {message}") from None
    if controller == "velocity" and model == "viscous":
        for key in ("c_x", "c_y"):
            if np.any(params.per_link(key) <= 0):
                given = place(key) if settings.get(key) is not None else place("robot")
                raise where(f"{given} controller velocity needs {key} > 0 on every "
                            f"link of robot {_short(settings['robot'])}")
    # the bounds of snake_pin.sim.simulate, checked here for every run before any runs
    dt = settings.get("dt", ENGINE_CONTROL_DT)
    control_dt = settings.get("control_dt", ENGINE_CONTROL_DT)
    try:
        _, steps = check_steps(settings["t_final"], dt, control_dt)
        check_size(steps + 1, n + 2, n - 1, settings["t_final"])
    except ParameterError as exc:
        if "t_final" in str(exc):
            raise where(f"{place('t_final')} {exc}") from None
        raise where(f"{place('control_dt')} control_dt = {control_dt:g} s must be 1.."
                    f"{MAX_SUBSTEPS} times {place('dt')} dt = {dt:g} s") from None


# ------------------------------------------------------------------------ helpers
def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


#: The scalar kinds: what a value must be, in words.
_SCALARS: dict[str, tuple[Callable[[object], bool], str]] = {
    "float": (is_number, "a number"), "int": (_is_int, "an integer"),
    "bool": (lambda v: isinstance(v, bool), "true or false"),
    "str": (lambda v: isinstance(v, str), "a string")}


def _kind_name(value: object) -> str:
    return {bool: "a boolean", int: "an integer", float: "a number", str: "a string",
            list: "a list", dict: "a table"}.get(type(value), type(value).__name__)


_REPR = reprlib.Repr()
_REPR.maxstring, _REPR.maxother, _REPR.maxlist = 60, 60, 8
_short = _REPR.repr
