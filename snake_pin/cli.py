"""The ``snake-pin`` console script: one parser, one subcommand per job, one contract.

Heavy imports happen inside the subcommand that needs them. The contract every subcommand
keeps (arguments checked first, one line and exit 2 when wrong, ``--json``, the run
summary, signals): :ref:`cli`, README "Security and robustness".
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import math
import numbers
import os
import re
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn
from urllib.parse import urlparse

from . import __version__
from ._json import json_text
from ._validation import float_arg, int_arg, number_arg
from .exceptions import RunInterrupted, SnakePinError, StudyError
from .params import MAX_LINKS, ROBOTS, SnakeParams

__all__ = ["EXIT_FAILED", "EXIT_INTERRUPTED", "EXIT_OK", "EXIT_USAGE", "SUMMARY_KEYS",
           "build_parser", "main"]

#: Exit statuses (also in ``snake-pin --help``).
EXIT_OK = 0
EXIT_USAGE = 2
EXIT_FAILED = 3
EXIT_INTERRUPTED = 130

#: Largest |entry| of ``--q`` [m, rad] (manipulability is translation invariant up to it).
MAX_COORDINATE = 1e9
#: Control period of ``simulate`` [s]; with sim.MAX_STEPS it bounds --t-final.
SIMULATE_DT = 1e-3
MAX_PORT = 65535
MIN_FPS, MAX_FPS = 1.0, 120.0
#: Engine options' ranges: a wheel bigger than the link collides with its neighbours.
MAX_WHEEL_RADIUS = 0.1
MAX_MU = 10.0
#: ``engine --seeds``: most runs (each 60 s run writes ~13 MB), largest offset [rad].
MAX_SEEDS = 100
MAX_PERTURBATION = 0.1
#: The keys of a run's summary (simulate, engine), with or without --json and --path.
SUMMARY_KEYS = ("robot", "n", "controller", "reference", "status", "reason", "t_end",
                "error_window", "rms_head_error", "max_head_error", "rms_head_error_pct",
                "max_head_error_pct", "R_min", "D_min", "torque_max")
_ERROR_WINDOW_HELP = ("judge head errors over t >= SECONDS (default: 10 s, or the second half "
                      "of a run shorter than 20 s; in the summary as error_window)")

_EPILOG = """\
exit status:
  0    done
  2    a wrong argument, input file or option combination (one line on stderr,
       nothing computed, no folder created)
  3    the run diverged or failed (results written, status in the summary)
  130  interrupted by SIGINT (Ctrl-C), SIGTERM or SIGHUP (what was computed is
       written, marked interrupted; one line on stderr). The live viewer, which
       serves until interrupted, exits 0 then.

limits: --n <= {links}, --t-final <= {t_max:g} s ({steps} control steps),
--points <= {points}, --starts <= {starts}, 0 <= --seed <= 2**32 - 1, --port <= 65535,
--fps in [1, 120], |--q entries| <= 1e9, --seeds <= {seeds}, --perturbation <= {eps:g} rad.

robots: --robot takes a preset (table1, engine), a TOML robot file (.toml) or a URDF
(.urdf); the robots shipped with snake_pin also by bare file name (e.g.
camera_head_snake.toml). A problem with the file is one line naming it.
"""

_ANGLE = re.compile(r"^\s*([+-]?)\s*(\d+(?:\.\d*)?(?:e[+-]?\d+)?|\.\d+(?:e[+-]?\d+)?)?"
                    r"\s*(\*?\s*pi)?\s*(?:/\s*(\d+(?:\.\d*)?))?\s*$", re.IGNORECASE)
#: Values that start with '-' but are not options: numbers, angles and lists of them
#: ("-0.8,0,...", "-pi/10", "-.5", "-inf"). argparse reads everything else that starts with
#: '-' as an option; its own matcher only knows plain negative numbers.
_NEGATIVE_VALUE = re.compile(r"^-(?:\.?\d|\s*pi\b|inf|nan)", re.IGNORECASE)


class UsageError(SnakePinError):
    """A command-line argument is wrong."""


class _Parser(argparse.ArgumentParser):
    """ArgumentParser with one-line errors (exit 2) that takes ``--q -0.8,0`` and ``-pi/5``."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # argparse's _parse_optional reads a '-' argument matching this as a value
        self._negative_number_matcher = _NEGATIVE_VALUE

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{self.prog}: {message}")


@dataclass
class _Outcome:
    """What a subcommand produced: the JSON payload, its text form, status and a note."""

    payload: dict[str, Any] = field(default_factory=dict)
    text: str = ""
    status: int = EXIT_OK
    note: str = ""  # one line for stderr
    after: Callable[[], None] | None = None  # run once the output is printed


# ------------------------------------------------------------------- argument types
def parse_angle(text: str) -> float:
    """An angle in radians from ``0.3``, ``pi/5``, ``-pi/3``, ``2*pi/3`` or ``pi``."""
    match = _ANGLE.match(text)
    if not match or not (match.group(2) or match.group(3)):
        raise argparse.ArgumentTypeError(f"not an angle: {text!r} (use e.g. 0.3 or pi/5)")
    sign, number, has_pi, divisor = match.groups()
    value = float(number) if number else 1.0
    if has_pi:
        value *= math.pi
    if divisor:
        if float(divisor) == 0.0:
            raise argparse.ArgumentTypeError(f"division by zero in {text!r}")
        value /= float(divisor)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"not a finite angle: {text!r}")
    return -value if sign == "-" else value


def _parse_q(text: str) -> list[float]:
    values = [parse_angle(part) for part in text.replace(" ", "").split(",") if part]
    if not values:
        raise argparse.ArgumentTypeError(f"no numbers in {text!r}")
    if any(abs(v) > MAX_COORDINATE for v in values):
        raise argparse.ArgumentTypeError(f"entries must lie within +-{MAX_COORDINATE:g}")
    return values


# ---------------------------------------------------------------- shared options
_FRICTION_FLAGS = {"cx": "c_x", "cy": "c_y", "ctheta": "c_theta"}


_ROBOT_HELP = ("a preset (" + ", ".join(ROBOTS) + "), a .toml robot file or a .urdf "
               "(shipped robots also by file name, e.g. camera_head_snake.toml)")


def _robot_options(parser: argparse.ArgumentParser, *, friction: bool = True,
                   default: str = "table1", free_joint: bool = False) -> None:
    """--robot, --n, --passive, (unless ``engine``'s wheels set it) the friction options and
    (manip, sweep, singular) --free-joint."""
    parser.add_argument("--robot", metavar="ROBOT", help=f"{_ROBOT_HELP}; default {default}")
    parser.add_argument("--n", type=int_arg(2, MAX_LINKS),
                        help=f"number of links, 2..{MAX_LINKS} (overrides the preset)")
    parser.add_argument("--passive", type=int_arg(1, MAX_LINKS), action="append", default=[],
                        metavar="K", help="make joint K passive (repeatable)")
    for flag, key in _FRICTION_FLAGS.items() if friction else ():
        unit = "N m s" if flag == "ctheta" else "N s/m"
        parser.add_argument(f"--{flag}", type=float_arg(0.0), help=f"{key} [{unit}]")
    if free_joint:
        parser.add_argument("--free-joint", type=int_arg(1, MAX_LINKS), metavar="K",
                            help="joint K is free (beside any --passive joints)")


def _joint(option: str, k: int, n: int) -> int:
    """Joint ``k`` of ``--option`` if the n-link robot has it, else a UsageError naming both."""
    if not 1 <= k <= n - 1:
        raise UsageError(f"argument {option}: joint {k} is outside 1..{n - 1} "
                         f"for the {n}-link robot")
    return k


def _params(args: argparse.Namespace, default: str = "table1") -> SnakeParams:
    """The robot of --robot with --n, --passive and friction applied (a bad file: one line)."""
    from .robot_file import load_robot

    spec = args.robot or default
    base = load_robot(spec)
    changes: dict[str, Any] = {key: getattr(args, flag) for flag, key in
                               {"n": "n", **_FRICTION_FLAGS}.items()
                               if getattr(args, flag, None) is not None}
    if args.passive:
        changes["passive"] = tuple(_joint("--passive", k, changes.get("n", base.n))
                                   for k in args.passive)
    return load_robot(spec, **changes) if changes else base


def _analysis(args: argparse.Namespace) -> tuple[SnakeParams, int | tuple[int, ...] | None]:
    """The robot of manip, sweep, singular with every joint actuated, and its free joints
    (--passive ones and --free-joint), refused when the task needs more links."""
    from .manipulability import task_split

    params = _params(args)
    free = set(params.passive)
    if args.free_joint is not None:
        free.add(_joint("--free-joint", args.free_joint, params.n))
    joints = (min(free) if len(free) == 1 else tuple(sorted(free))) if free else None
    task_split(params.n, joints, not getattr(args, "no_heading", False))
    return params.replace(passive=()), joints


def _output_folder(text: str) -> Path:
    """The output folder (not created): an existing file there is refused."""
    out = Path(text)
    if out.exists() and not out.is_dir():
        raise UsageError(f"argument -o/--output: {text} exists and is not a folder")
    return out


def _progress(args: argparse.Namespace) -> bool:
    """Progress bars: never with --json, and only on a terminal (tqdm checks that too)."""
    return not getattr(args, "json", False) and sys.stderr.isatty()


def _save_trajectory(traj: Any, out: Path, stem: str) -> list[Path]:
    """Save a run (npz + JSON) with its peak ``|tau_i|`` in the summary."""
    from .metrics import torque_max

    traj.summary["torque_max"] = torque_max(traj)
    return list(traj.save(out / stem))


def _interrupted_run(exc: RunInterrupted, out: Path, stem: str) -> _Outcome:
    """Save the partial trajectory of an interrupted run; the outcome that says so."""
    traj = exc.partial
    if traj is None or not len(traj):
        return _Outcome(status=EXIT_INTERRUPTED, note=f"{exc}; nothing to save")
    files = _save_trajectory(traj, out, stem)
    payload = {**traj.summary_dict(), "files": [str(f) for f in files]}
    return _Outcome(payload, _summary_text(payload), EXIT_INTERRUPTED,
                    f"{exc}; partial run saved to {files[0]} (status interrupted)")


def _plain(value: Any) -> str:
    """A value as plain text (6 significant digits, "none", [a, b], "-" for "")."""
    if value is None:
        return "none"
    if isinstance(value, str):
        return value or "-"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        return f"{float(value):.6g}"
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{k}: {_plain(v)}" for k, v in value.items()) + "}"
    if isinstance(value, Iterable):
        return "[" + ", ".join(_plain(v) for v in value) + "]"
    return str(value)


def _wrote(paths: Mapping[str, Path]) -> tuple[dict[str, str], str]:
    """Files written, by role: as the payload's ``files`` and as the text's first line."""
    return {k: str(v) for k, v in paths.items()}, f"wrote {', '.join(map(str, paths.values()))}"


def _summary_text(payload: Mapping[str, Any]) -> str:
    """A run's summary as text: one line per key of :data:`SUMMARY_KEYS`, then the files."""
    width = max(len(key) for key in SUMMARY_KEYS)
    lines = [f"{key:>{width}}: {_plain(payload.get(key))}" for key in SUMMARY_KEYS]
    files = payload.get("files") or []
    lines.append(f"{'files':>{width}}: " + (f"\n{'':>{width}}  ".join(map(str, files))
                                            or "none"))
    return "\n".join(lines)


def _error_window(args: argparse.Namespace, t_final: float, dt: float) -> float:
    """``--error-window`` (below the run's duration ``t_final``), else the default window's
    start; ``--t-final`` is refused first beyond sim.MAX_STEPS control steps of ``dt``."""
    from .metrics import default_error_window
    from .sim import MAX_STEPS

    if args.t_final is not None and args.t_final > MAX_STEPS * dt * (1 + 1e-12):
        raise UsageError(f"argument --t-final: at most {MAX_STEPS * dt:g} s "
                         f"({MAX_STEPS} control steps of {dt:g} s), got {args.t_final:g}")
    if args.error_window is None:
        return default_error_window(t_final)
    if args.error_window >= t_final:
        raise UsageError(f"argument --error-window: must be below the run's duration "
                         f"({t_final:g} s), got {args.error_window:g}")
    return float(args.error_window)


#: What the head follows without --path in the tracking runs (the summary's ``reference``).
_LINE_HEAD_FIRST = "line w_r = [0.1 t, 0, pi]"


def _path_text(args: argparse.Namespace) -> str:
    """``--path`` and its settings in words (the summary's ``reference``)."""
    settings = _path_parameters(args)
    speed = settings.pop("speed", 0.1)
    shown = ", ".join(f"{key}={value:g}" for key, value in settings.items())
    return (f"path {args.path if args.path is not None else 'line'}"
            + (f" ({shown})" if shown else "") + f" at {speed:g} m/s")


def _save_run(traj: Any, out: Path, stem: str, figures: Callable[[], Iterable[Path]],
              extra: Mapping[str, Any] | None = None) -> _Outcome:
    """Save a finished run (npz, JSON, criteria CSV) then its ``figures()``; its outcome."""
    from ._io import atomic_write_bytes
    from .metrics import window_note

    files = _save_trajectory(traj, out, stem)  # data first, then the figures
    series = traj.meta.get("criteria")
    if isinstance(series, Mapping) and series.get("t"):  # t and each criterion, whole or not
        names = [k for k, v in series.items() if len(v) == len(series["t"])]
        rows = [",".join(names)] + [",".join(repr(float(series[k][i])) for k in names)
                                    for i in range(len(series["t"]))]
        atomic_write_bytes(out / f"{stem}_criteria.csv", ("\n".join(rows) + "\n").encode())
        files.append(out / f"{stem}_criteria.csv")
    files += figures()
    payload = {**traj.summary_dict(), **(extra or {}), "files": [str(f) for f in files]}
    failed = traj.status in ("diverged", "failed") or traj.diverged
    fault = f"run {traj.status}: {traj.reason} (results in {out})" if failed else ""
    note = "; ".join(part for part in (fault, window_note(payload)) if part)
    return _Outcome(payload, _summary_text(payload), EXIT_FAILED if failed else EXIT_OK, note)


# ----------------------------------------------------------------- subcommands
def _cmd_generate(args: argparse.Namespace) -> _Outcome:
    params = _params(args)
    out = Path(args.output)
    if out.suffix != ".urdf":
        raise UsageError(f"argument -o/--output: must end in .urdf, got {out}")
    if out.is_dir():
        raise UsageError(f"argument -o/--output: {out} is a folder")
    from .urdf import write_urdf

    out.parent.mkdir(parents=True, exist_ok=True)
    write_urdf(params, out)
    passive = ", ".join(map(str, params.passive)) or "none"
    return _Outcome({"urdf": str(out), "robot": params.name, "n": params.n,
                     "passive": list(params.passive)},
                    f"wrote {out} (robot {params.name}, {params.n} links, passive joints: "
                    f"{passive})")


def _cmd_info(args: argparse.Namespace) -> _Outcome:
    from .runs.outputs import info

    params = _params(args)
    data = info(params)
    shown = {**data, "passive": ", ".join(map(str, params.passive)) or "none"}
    return _Outcome(data, "\n".join(f"{k:>13}: {_plain(v)}" for k, v in shown.items()))


_SHAPE_OPTIONS = {"phi0": "arc", "alpha": "serpenoid", "ts": "serpenoid", "q": "q"}


def _shape(args: argparse.Namespace) -> str:
    """--shape, or the shape the shape-specific options imply; conflicts are refused."""
    given = {flag: shape for flag, shape in _SHAPE_OPTIONS.items()
             if getattr(args, flag) is not None}
    implied = set(given.values())
    if args.shape is None:
        if len(implied) > 1:
            flags = ", ".join(f"--{flag}" for flag in given)
            raise UsageError(f"manip: {flags} describe different shapes; give one shape")
        return implied.pop() if implied else "straight"
    for flag, shape in given.items():
        if shape != args.shape:
            raise UsageError(f"manip: --{flag} applies to --shape {shape}, not --shape "
                             f"{args.shape}")
    return args.shape


def _posture(args: argparse.Namespace, shape: str, n: int) -> list[float]:
    from . import gaits

    if shape == "straight":
        return gaits.straight(n).tolist()
    if shape == "arc":
        if args.phi0 is None:
            raise UsageError("manip: --shape arc needs --phi0")
        return gaits.arc(n, args.phi0).tolist()
    if shape == "serpenoid":
        alpha = math.pi / 4 if args.alpha is None else args.alpha
        ts = 1.5 if args.ts is None else args.ts
        return gaits.Serpenoid(n, alpha, ts).configuration().tolist()
    if args.q is None:
        raise UsageError("manip: --shape q needs --q x,y,theta1,phi1,...")
    if len(args.q) != n + 2:
        raise UsageError(f"argument --q: needs {n + 2} values for n = {n}, got {len(args.q)}")
    return args.q


def _cmd_manip(args: argparse.Namespace) -> _Outcome:
    params, free = _analysis(args)
    shape = _shape(args)
    from .manipulability import manipulability
    from .model import Snake

    res = manipulability(Snake(params), _posture(args, shape, params.n), free_joint=free,
                         heading=not args.no_heading)
    tilde = "~" if free else ""
    return _Outcome(res.to_dict(),
                    f"D{tilde} = {res.D:.6g}\nR{tilde} = {res.R:.6g}\n"
                    f"sigma = {_plain(res.sigma)}\nlambda = {_plain(res.lambda_)}")


def _cmd_sweep(args: argparse.Namespace) -> _Outcome:
    params, free = _analysis(args)
    bounds = None if args.range is None else (float(args.range[0]), float(args.range[1]))
    if bounds is not None and not bounds[0] < bounds[1]:
        raise UsageError(f"argument --range: LOW must be below HIGH, got {bounds[0]:g} "
                         f"{bounds[1]:g}")
    if bounds is not None and max(map(abs, bounds)) > MAX_COORDINATE:
        raise UsageError(f"argument --range: values must lie within +-{MAX_COORDINATE:g}")
    out = _output_folder(args.output)
    from .model import Snake
    from .runs.outputs import write_sweep
    from .sweeps import sweep

    out.mkdir(parents=True, exist_ok=True)
    try:
        result = sweep(Snake(params), args.family, free_joint=free, points=args.points,
                       bounds=bounds, progress=_progress(args))
    except RunInterrupted as exc:
        partial = exc.partial
        if partial is None or not len(partial.values):
            return _Outcome(status=EXIT_INTERRUPTED, note=f"{exc}; nothing to save")
        files, wrote = _wrote(write_sweep(partial, out))
        return _Outcome({**partial.to_dict(), "files": files},
                        f"{wrote}\n{len(partial.values)} of {args.points} postures (interrupted)",
                        EXIT_INTERRUPTED, f"{exc}; partial sweep saved to {files['json']} "
                                          "(status interrupted)")
    files, wrote = _wrote(write_sweep(result, out))
    zeros = result.zeros().tolist()
    low, high = float(result.values[0]), float(result.values[-1])
    payload = {"family": args.family, "free_joint": result.to_dict()["free_joint"],
               "status": result.status, "range": [low, high], "points": len(result.values),
               "zeros": zeros, "R_min": float(result.R.min()), "D_min": float(result.D.min()),
               "files": files}
    name = result.label.split(" [")[0]
    found = f"R = 0 at {name} = {_plain(zeros)}" if zeros else \
        f"R > 0 everywhere (smallest {float(result.R.min()):.6g})"
    return _Outcome(payload, f"{wrote}\n{len(result.values)} postures, {name} from {low:.6g} "
                             f"to {high:.6g}: {found}")


def _cmd_singular(args: argparse.Namespace) -> _Outcome:
    params, free = _analysis(args)
    if not 0 < args.bound <= math.pi:
        raise UsageError(f"argument --bound: must lie in (0, pi], got {args.bound:g}")
    out = _output_folder(args.output) if args.output else None
    from .runs.outputs import write_singular
    from .singular import find_singular_postures

    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    status, note = EXIT_OK, ""
    try:
        search = find_singular_postures(params, starts=args.starts, bound=args.bound,
                                        free_joint=free, seed=args.seed, progress=_progress(args))
    except RunInterrupted as exc:
        search, status, note = exc.partial, EXIT_INTERRUPTED, str(exc)
    payload = search.to_dict()
    if out is not None:
        files = write_singular(search, out)
        payload["files"] = [str(p) for p in files]
        if status == EXIT_INTERRUPTED:
            note += f"; partial search saved to {files[0]} (status interrupted)"
    lines = [f"{len(search.families)} famil{'y' if len(search.families) == 1 else 'ies'} "
             f"with R <= {search.threshold:.3g} (typical R {search.R_typical:.3g}), "
             f"from {search.starts} start{'' if search.starts == 1 else 's'}:"]
    lines += [f"  {'straight' if f.straight else 'non-straight'} x{f.members}: "
              f"R = {f.R:.3g}, phi = [{', '.join(f'{float(x):.3f}' for x in f.phi)}]"
              for f in search.families]
    return _Outcome(payload, "\n".join(lines), status, note)


def _user_controller_class(spec: str) -> type:
    """The ``module:Class`` a user names with ``--controller`` (a Controller subclass)."""
    import importlib

    from .control import Controller

    module_name, _, class_name = spec.partition(":")
    try:
        cls = getattr(importlib.import_module(module_name), class_name)
    except (ImportError, AttributeError, ValueError) as exc:
        raise UsageError(f"argument --controller: cannot import {spec!r} "
                         f"({type(exc).__name__}: {exc})") from None
    if not (isinstance(cls, type) and issubclass(cls, Controller)):
        raise UsageError(f"argument --controller: {spec!r} is not a snake_pin Controller subclass")
    return cls


def _path_parameters(args: argparse.Namespace) -> dict[str, Any]:
    """``--speed`` and every ``--path-param KEY=VALUE`` as keyword arguments of load_path."""
    params: dict[str, Any] = {}
    if args.speed is not None:
        params["speed"] = args.speed
    for item in args.path_param or []:
        key, sep, value = item.partition("=")
        if not sep or not key.isidentifier():
            raise UsageError(f"argument --path-param: expected KEY=VALUE, got {item!r}")
        try:
            params[key] = float(value)
        except ValueError:
            raise UsageError(f"argument --path-param: {key} must be a number, "
                             f"got {value!r}") from None
    return params


def _path_reference(args: argparse.Namespace, default: str | None = None) -> Any:
    """The head reference of ``--path`` (else ``default``); None without either."""
    if args.path is None and default is None:
        if args.speed is not None or args.path_param:
            raise UsageError("arguments --speed/--path-param: apply with --path")
        return None
    from .paths import load_path

    spec: str = args.path if args.path is not None else str(default)
    return load_path(spec, **_path_parameters(args))


def _path_options(parser: argparse.ArgumentParser) -> None:
    """``--path``, ``--path-param``, ``--speed``: the options :func:`_path_reference` reads."""
    parser.add_argument("--path", metavar="NAME|FILE",
                        help="follow a path instead of the paper's straight line: line, "
                        "circle, arc, lane_change, sinusoid, or a .toml/.csv path file")
    parser.add_argument("--path-param", action="append", metavar="KEY=VALUE",
                        help="a parameter of the path shape (e.g. radius=1.2), repeatable")
    parser.add_argument("--speed", type=float_arg(0.0, open_low=True),
                        help="reference speed along the path [m/s] (default 0.1)")


def _path_summary(traj: Any, reference: Any, start: float, *,
                  head_tracking: bool = True) -> None:
    """Fill a path run's summary: head error and ``path_metrics``."""
    import numpy as np

    from .metrics import head_error_summary
    from .model import Snake
    from .runs.benchmark import path_metrics

    error = np.linalg.norm(traj.q[:, :2] - reference.at(traj.t)[0][:, :2], axis=1)
    metrics = path_metrics(traj.t, traj.q, traj.tau, Snake(traj.params), reference,
                           head_tracking=head_tracking, start=start)
    traj.signals["head_error"] = error
    traj.meta["criteria"] = metrics.pop("series")
    traj.summary.update({**metrics, **head_error_summary(traj, error, start=start),
                         "body_length": traj.params.body_length,
                         "passive": list(traj.params.passive)})


def _path_figures(traj: Any, reference: Any, out: Path, stem: str) -> list[Path]:
    """A path run's figures: the time series and the head against the path in the plane."""
    from .viz.plots import plot_head_path, plot_trajectory

    figure, xy = out / f"{stem}.png", out / f"{stem}_path.png"
    plot_trajectory(traj, figure)
    plot_head_path(traj, reference.at(traj.t)[0][:, :2], xy,
                   title=f"Head against its reference: {traj.summary.get('reference', 'the path')}")
    return [figure, xy]


def _cmd_simulate(args: argparse.Namespace) -> _Outcome:
    params = _params(args)
    kind = args.controller
    on_path = args.path is not None or kind not in ("pfl", "lyapunov", "mpc")
    if kind not in ("pfl", "lyapunov", "los", "mpc") and ":" not in kind:
        raise UsageError(f"argument --controller: choose pfl, lyapunov, los, mpc or "
                         f"module:Class (a Controller subclass), got {kind!r}")
    if kind != "pfl" and args.climb_r is not None:
        raise UsageError("argument --climb-r: applies to --controller pfl only")
    mpc_options = _mpc_options(args)
    if kind == "pfl" and params.passive:
        raise UsageError("simulate: PFL needs every joint actuated (drop --passive)")
    t_final = args.t_final or (10.0 if kind == "pfl" and not on_path else 60.0)
    start = _error_window(args, t_final, SIMULATE_DT)
    user = _user_controller_class(kind) if ":" in kind else None  # refused before any folder
    # a bad path, or --speed/--path-param without one: refused here
    reference = _path_reference(args, "line" if on_path else None)
    out = _output_folder(args.output)
    out.mkdir(parents=True, exist_ok=True)
    stem = "run" if user is not None else kind
    if args.cx is None and args.cy is None and (on_path or kind in ("lyapunov", "mpc")):
        # the tracking runs' anisotropic default friction (erratum 3)
        from .runs.tracking import tracking_friction

        params, _ = tracking_friction(params)
    try:
        if reference is not None:
            traj = _simulate_law(args, params, reference, user, t_final, mpc_options,
                                 {"path": repr(reference)})
            _path_summary(traj, reference, start, head_tracking=kind != "los")
            traj.summary.update(controller=kind, reference=_path_text(args))
        elif kind == "mpc":  # the MPC on the tracking line, summarised as run_tracking
            from .control import head_first_reference
            from .model import Snake
            from .runs.tracking import REFERENCE, summarize_tracking

            line = head_first_reference()
            traj = summarize_tracking(
                _simulate_law(args, params, line, None, t_final, mpc_options,
                              {"reference": REFERENCE}),
                Snake(params), line, start, controller="mpc", reference=_LINE_HEAD_FIRST)
        elif kind == "pfl":
            from .runs.pfl import run_pfl

            run = run_pfl(params, t_final=t_final, climb_R=args.climb_r,
                          control_dt=SIMULATE_DT, error_window=start,
                          progress=_progress(args))
            traj = run.trajectory
            traj.summary["reference"] = "line w_r = [0.1 t, 0, 0]"
        else:
            from .runs.tracking import run_tracking

            traj = run_tracking(params, t_final=t_final, error_window=start,
                                progress=_progress(args))
            traj.summary["reference"] = _LINE_HEAD_FIRST
    except RunInterrupted as exc:
        return _interrupted_run(exc, out, stem)
    from .runs.pfl import plot_pfl
    from .runs.tracking import plot_tracking

    return _save_run(traj, out, stem, lambda: (
        _path_figures(traj, reference, out, stem) if reference is not None
        else plot_pfl(run, out, stem).values() if kind == "pfl"
        else plot_tracking(traj, out, stem).values()))


def _mpc_options(args: argparse.Namespace, *, engine: bool = False) -> Any:
    """``--horizon``/``--torque-bound`` as MPCOptions for the MPC (else refused; None)."""
    given = {key: getattr(args, key) for key in ("horizon", "torque_bound")
             if getattr(args, key) is not None}
    choice = "--law" if engine else "--controller"
    if (args.law if engine else args.controller) != "mpc":
        if given:
            option = "--" + next(iter(given)).replace("_", "-")
            raise UsageError(f"argument {option}: applies to {choice} mpc only")
        return None
    from .control.mpc import MPCOptions

    if engine:
        from .engine.run import ENGINE_TORQUE_BOUND

        if given.setdefault("torque_bound", ENGINE_TORQUE_BOUND) > ENGINE_TORQUE_BOUND:
            raise UsageError(f"argument --torque-bound: at most the engine motors' "
                             f"{ENGINE_TORQUE_BOUND:g} N m")
    return MPCOptions(**given)


def _simulate_law(args: argparse.Namespace, params: SnakeParams, reference: Any,
                  user: type | None, t_final: float, mpc_options: Any, meta: dict[str, Any]
                  ) -> Any:
    """A run of ``--controller`` (a user's ``module:Class`` too) on the viscous model."""
    from .control import LOSController, LyapunovController, MPCController, PFLController, PFLOptions
    from .model import Snake
    from .runs.tracking import initial_state
    from .sim import simulate

    snake = Snake(params)
    pfl = PFLOptions() if args.climb_r is None else PFLOptions(climb_R=args.climb_r)
    laws: dict[str, tuple[Any, dict[str, Any]]] = {
        "lyapunov": (LyapunovController, {}), "los": (LOSController, {}),
        "mpc": (MPCController, {"options": mpc_options}),
        "pfl": (PFLController, {"options": pfl})}
    law, options = laws.get(args.controller, (user, {}))
    controller = law(snake, reference, **options)
    return simulate(snake, controller, initial_state(params), t_final,
                    progress=_progress(args), meta=meta)


def _cmd_engine(args: argparse.Namespace) -> _Outcome:
    from .engine.model import WheelSpec, build_engine_model

    params = _params(args, default="engine")
    if args.perturbation is not None and args.seeds is None:
        raise UsageError("argument --perturbation: applies with --seeds N (a distribution of "
                         "N perturbed runs)")
    wheels = WheelSpec(radius=args.wheel_radius, friction=args.mu, cone=args.cone)
    start = _error_window(args, args.t_final, wheels.control_dt)
    reference = _path_reference(args)  # a bad path: refused here, before any folder
    mpc_options = _mpc_options(args, engine=True)
    out = _output_folder(args.output)
    build_engine_model(params, wheels)  # wheels that do not fit the robot: refused here
    from .engine.run import identify_friction, run_engine
    from .runs.engine import plot_engine, summarize

    out.mkdir(parents=True, exist_ok=True)
    friction = identify_friction(params.replace(passive=()), wheels)
    if args.seeds is not None:
        return _engine_seeds(args, params, wheels, friction, out, reference, start,
                             mpc_options)
    try:
        run = run_engine(params, wheels=wheels, t_final=args.t_final, friction=friction,
                         law=args.law, reference=reference, progress=_progress(args),
                         mpc_options=mpc_options)
    except RunInterrupted as exc:
        return _interrupted_run(exc, out, "engine")
    traj = run.trajectory
    traj.summary["controller"] = "mpc" if args.law == "mpc" else f"lyapunov ({args.law} law)"
    summarize(traj, reference=reference, start=start)
    if reference is None:
        traj.summary["reference"] = _LINE_HEAD_FIRST
    else:
        _path_summary(traj, reference, start)
        traj.summary.update(path=repr(reference), reference=_path_text(args))
    return _save_run(traj, out, "engine", lambda: (
        plot_engine(run, None, out, "engine").values() if reference is None
        else _path_figures(traj, reference, out, "engine")), {"friction": friction})


def _engine_seeds(args: argparse.Namespace, params: SnakeParams, wheels: Any,
                  friction: dict[str, Any], out: Path, reference: Any, start: float,
                  mpc_options: Any) -> _Outcome:
    """``engine --seeds N``: the runs, their distribution (engine_seeds.json), median figures."""
    from tqdm import tqdm

    from ._io import atomic_write_bytes
    from .runs.engine import PERTURBATION, Draws, engine_draw, perturbations, plot_engine
    from .runs.parallel import iter_jobs
    from .trajectory import Trajectory

    size = PERTURBATION if args.perturbation is None else args.perturbation
    passive = ", ".join(map(str, params.passive))
    draws = Draws(f"engine, {args.law} law" + (f", joint{'s' if len(params.passive) > 1 else ''}"
                                               f" {passive} passive" if passive else ""),
                  size, 0, perturbations(args.seeds, params.n - 1, size, seed=0))
    width = len(str(args.seeds))
    stems = [f"engine_seed{k + 1:0{width}d}" for k in range(args.seeds)]
    jobs = [(engine_draw, (params, offset), {"wheels": wheels, "t_final": args.t_final,
                                             "friction": friction, "law": args.law,
                                             "mpc_options": mpc_options,
                                             "reference": reference, "error_window": start})
            for offset in draws.offsets]
    interrupted = False
    with tqdm(total=args.seeds, desc="engine runs", unit="run", leave=False,
              disable=not _progress(args)) as bar:
        try:
            for k, run in iter_jobs(jobs):
                npz, summary = run.trajectory.save(out / stems[k])
                draws.record(k, run.trajectory.summary_dict(), [npz, summary])
                bar.update(1)
        except KeyboardInterrupt:  # RunInterrupted included: a run in progress is dropped
            interrupted = True
    files: list[str] = [f for k in draws.done for f in draws.files[k]]
    median = draws.median_draw()
    if median is not None:
        traj = Trajectory.load(out / f"{stems[median]}.npz")
        files += [str(p) for p in plot_engine(traj, None, out, "engine",
                                              reference).values()]
    data = {"status": "interrupted" if interrupted else "completed", "robot": params.name,
            "law": args.law, "t_final": args.t_final, "error_window": start,
            "friction": friction, **draws.to_dict()}
    if reference is not None:
        data["path"] = repr(reference)
    if median is not None:
        data["median_run"] = stems[median]
    table = out / "engine_seeds.json"
    atomic_write_bytes(table, (json_text(data, indent=2) + "\n").encode())
    files.insert(0, str(table))
    payload = {**data, "files": files}
    text = (draws.text() + f"\n  head errors and torques over t >= {start:g} s"
            + (f"\nmedian run: {stems[median]}" if median is not None else ""))
    if interrupted:
        return _Outcome(payload, text, EXIT_INTERRUPTED,
                        f"engine runs interrupted; {len(draws.done)} of {args.seeds} runs "
                        f"finished, saved with their distribution in {table} (status interrupted)")
    faults = len(draws.faults())
    return _Outcome(payload, text, EXIT_FAILED if faults else EXIT_OK, f"{faults} of {args.seeds} "
                    f"runs diverged or failed (results in {out})" if faults else "")


def _cmd_view(args: argparse.Namespace) -> _Outcome:
    if args.html is not None:
        if args.port is not None:
            raise UsageError("argument --port: the live viewer's port; --html starts no server")
        html = Path(args.html)
        if html.suffix.lower() not in (".html", ".htm"):
            raise UsageError(f"argument --html: must end in .html, got {args.html}")
        if not html.parent.is_dir():
            raise UsageError(f"argument --html: no folder {html.parent}")
    from .robot_file import load_robot
    from .trajectory import Trajectory
    from .viz.meshcat_view import view, write_html

    expected = load_robot(args.robot).name if args.robot is not None else None
    traj = Trajectory.load(args.trajectory, signals=False)
    if expected is not None and traj.params.name != expected:
        raise UsageError(f"view: {args.trajectory} is a run of the '{traj.params.name}' robot, "
                         f"not '{expected}' ({args.robot})")
    if args.html is not None:
        out = write_html(traj, args.html, fps=args.fps)
        return _Outcome({"html": str(out), "t_end": traj.t_end}, f"wrote {out}")
    if not args.json:
        view(traj, port=args.port, fps=args.fps)  # prints its URL, serves until Ctrl-C
        return _Outcome(text="")
    url = view(traj, port=args.port, fps=args.fps, block=False)
    return _Outcome({"url": url, "t_end": traj.t_end},
                    after=lambda: _serve_until_interrupted(url))


def _serve_until_interrupted(url: str) -> None:
    """Wait while the viewer's server answers on its port (Ctrl-C/SIGTERM ends the wait)."""
    port = urlparse(url).port
    try:
        while True:
            time.sleep(1.0)
            try:
                with socket.create_connection(("127.0.0.1", port or 80), timeout=2.0):
                    pass
            except OSError as exc:
                raise SnakePinError(f"meshcat server at {url} stopped on its own") from exc
    except KeyboardInterrupt:
        return


def _cmd_reproduce(args: argparse.Namespace) -> _Outcome:
    from .experiments import reproduce, stages
    from .experiments.reproduce import unhonoured

    known = [name for name, _ in stages()]
    for name in args.only or []:
        if name not in known:
            raise UsageError(f"argument --only: unknown stage {name!r}; stages: {', '.join(known)}")
    params = _params(args)
    flags = {"robot": "--robot", "n": "--n", "passive": "--passive",
             **{key: f"--{flag}" for flag, key in _FRICTION_FLAGS.items()}}
    given = {key for key, flag in flags.items()
             if getattr(args, flag.lstrip("-"), None) not in (None, [])}
    for name in args.only or known:
        refused = unhonoured(name, given, params)
        if refused:
            raise UsageError(f"reproduce: stage '{name}' sets {', '.join(refused)} itself and "
                             f"cannot honour {', '.join(flags[k] for k in refused)}; leave "
                             "them out or choose stages with --only")
    out = _output_folder(args.output)
    index = reproduce(out, params, quick=args.quick, only=args.only,
                      log=lambda line: _say(f"reproduce {line}"),
                      log_done=args.verbose or sys.stderr.isatty())
    return _Outcome({"index": str(index)}, f"report: {index}")


_STUDY_DESCRIPTION = """\
Run every run a study file describes on Dask, one Parquet row per run in DIR/runs, the page
in DIR/index.html, the summary in DIR/summary.json; runs already recorded are not run again
(after an interrupt, run the same command to finish). By default a local TLS cluster on
127.0.0.1; --scheduler uses an existing one (documentation: Concepts, Studies)."""


def _cmd_study(args: argparse.Namespace) -> _Outcome:
    """Run the study; a bad file, folder, scheduler or security file is one StudyError line."""
    from .study import run_study

    local = "applies to the local cluster, not with --scheduler"
    for flag, wrong, why in (
            ("workers", args.scheduler is not None and args.workers is not None, local),
            ("dashboard", args.scheduler is not None and args.dashboard, local),
            ("security", args.scheduler is None and args.security is not None,
             "applies with --scheduler (the local cluster makes its own credentials)")):
        if wrong:
            raise StudyError(f"argument --{flag}: {why}")
    verbose = bool(args.verbose) or bool(args.dashboard) or sys.stderr.isatty()
    try:
        summary = run_study(args.study, args.output, scheduler=args.scheduler,
                            workers=args.workers, security=args.security,
                            connect_timeout=args.connect_timeout, dashboard=args.dashboard,
                            progress=None, log=_say if verbose else None)
    except RunInterrupted as exc:
        return _Outcome(exc.partial.to_dict(), exc.partial.text(), EXIT_INTERRUPTED, str(exc))
    return _Outcome(summary.to_dict(), summary.text(),
                    EXIT_FAILED if summary.status == "incomplete" else EXIT_OK,
                    summary.note if summary.status != "complete" else "")


# --------------------------------------------------------------------- parser
def _cmd_bench_control(args: argparse.Namespace) -> _Outcome:
    from .runs import benchmark as bench

    start = _error_window(args, min(args.t_final, bench.QUICK_T_FINAL) if args.quick
                          else args.t_final, SIMULATE_DT)
    for name in args.scenario or []:
        if name not in bench.SCENARIOS:
            raise UsageError(f"argument --scenario: unknown {name!r}; choose from "
                             f"{', '.join(bench.SCENARIOS)}")
    controllers: dict[str, Any] = {}
    for spec in args.controller or list(bench.DEFAULT_CONTROLLERS):
        if ":" in spec:
            cls = _user_controller_class(spec)
            controllers[spec] = lambda snake, reference, path, cls=cls: cls(snake, reference)
        elif spec in bench.CONTROLLERS:
            controllers[spec] = None
        else:
            raise UsageError(f"argument --controller: unknown {spec!r}; choose from "
                             f"{', '.join(bench.CONTROLLERS)} or module:Class")
    out = _output_folder(args.output)
    out.mkdir(parents=True, exist_ok=True)
    result = bench.run_benchmark(scenarios=args.scenario, controllers=controllers,
                                 models=tuple(args.model or ("viscous",)),
                                 failed=(None,) if args.no_failure else (None, 5),
                                 t_final=args.t_final, quick=args.quick, error_window=start,
                                 draws=args.draws or bench.ENGINE_DRAWS)
    files, wrote = _wrote(bench.write_benchmark(result, out))
    return _Outcome({"error_window": start, "rows": result.table(), "files": files},
                    f"{wrote}\n{len(result.rows)} runs, path metrics over t >= {start:g} s")


def _run_options(parser: argparse.ArgumentParser, t_final: float | None, help_t: str,
                 help_window: str = _ERROR_WINDOW_HELP) -> None:
    """``--t-final`` and ``--error-window`` of the commands that run."""
    parser.add_argument("--t-final", type=float_arg(0.0, open_low=True), default=t_final,
                        help=help_t)
    parser.add_argument("--error-window", type=float_arg(0.0), metavar="SECONDS",
                        help=help_window)


def _mpc_flags(parser: argparse.ArgumentParser, horizon: str, bound: str) -> None:
    """``--horizon`` and ``--torque-bound`` (read by :func:`_mpc_options`)."""
    parser.add_argument("--horizon", type=number_arg, metavar="SECONDS",
                        help=f"MPC only: the prediction horizon [s] (default 0.5{horizon})")
    parser.add_argument("--torque-bound", type=number_arg, metavar="NM",
                        help=f"MPC only: |tau_i| <= NM [N m] (default {bound})")


def _command(parser: argparse.ArgumentParser, func: Callable[[argparse.Namespace], _Outcome],
             output: str | None = "output folder", *, required: bool = True,
             json: str = "print one JSON object", **output_kwargs: Any) -> None:
    """A subcommand's ``-o/--output`` (unless None), ``--json`` and handler."""
    if output is not None:
        parser.add_argument("-o", "--output", required=required, help=output, **output_kwargs)
    parser.add_argument("--json", action="store_true", help=json)
    parser.set_defaults(func=func)


def build_parser() -> argparse.ArgumentParser:
    """The whole command line, built in one place.

    Returns
    -------
    argparse.ArgumentParser
        ``snake-pin`` with its subcommands; its errors raise :class:`UsageError` (one
        line) instead of exiting.
    """
    from .sim import MAX_STEPS as steps
    from .singular import MAX_SEED, MAX_STARTS
    from .sweeps import MAX_POINTS

    parser = _Parser(prog="snake-pin", description=__doc__.splitlines()[0],
                     formatter_class=argparse.RawDescriptionHelpFormatter,
                     epilog=_EPILOG.format(links=MAX_LINKS, t_max=steps * SIMULATE_DT,
                                           steps=steps, points=MAX_POINTS, starts=MAX_STARTS,
                                           seeds=MAX_SEEDS, eps=MAX_PERTURBATION))
    parser.add_argument("--version", action="version", version=f"snake-pin {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser("generate", help="write the URDF of a snake robot")
    _robot_options(p)
    _command(p, _cmd_generate, output="output file (.urdf)")

    p = sub.add_parser("info", help="parameters and model sizes of a robot")
    _robot_options(p)
    _command(p, _cmd_info, output=None)

    p = sub.add_parser("manip", help="manipulability D, R of one posture (eqs. 30, 31, 42)",
                       description="D and R of one posture. The shape is --shape, or the one "
                       "its options imply (--phi0: arc, --alpha/--ts: serpenoid, --q: q); "
                       "options of another shape are refused. --passive joints and --free-joint "
                       "are free joints (D~, R~ of eq. 42).")
    _robot_options(p, free_joint=True)
    p.add_argument("--shape", choices=("straight", "arc", "serpenoid", "q"),
                   help="posture family (default straight, or implied by the options below)")
    p.add_argument("--phi0", type=parse_angle, help="arc: common joint angle (e.g. pi/10)")
    p.add_argument("--alpha", type=parse_angle, help="serpenoid alpha (default pi/4)")
    p.add_argument("--ts", type=number_arg, help="serpenoid T_s (default 1.5)")
    p.add_argument("--q", type=_parse_q, help="full configuration x,y,theta1,phi1,... "
                   "(angles may be written pi/5; |entries| <= 1e9)")
    p.add_argument("--no-heading", action="store_true", help="leave theta_1 out of the task")
    _command(p, _cmd_manip, output=None)

    p = sub.add_parser("sweep", help="D and R along a posture family (Figs. 2-9)")
    p.add_argument("family", choices=("arc", "alpha", "ts"))
    _robot_options(p, free_joint=True)
    p.add_argument("--points", type=int_arg(2, MAX_POINTS), default=201,
                   help=f"postures along the family, 2..{MAX_POINTS} (0, the straight "
                   "posture, is added when the range holds it and the grid misses it)")
    p.add_argument("--range", type=parse_angle, nargs=2, metavar=("LOW", "HIGH"),
                   help="the swept parameter's range, LOW < HIGH (angles may be written "
                   "pi/5; default: arc -pi/5..pi/5, alpha 0..pi/2, ts 0..2)")
    _command(p, _cmd_sweep)

    p = sub.add_parser("singular", help="search the joint box for singular postures (R = 0)")
    _robot_options(p, free_joint=True)
    p.add_argument("--starts", type=int_arg(1, MAX_STARTS), default=200,
                   help=f"random starts, 1..{MAX_STARTS}")
    p.add_argument("--bound", type=parse_angle, default=math.pi / 2,
                   help="|phi_i| <= bound, in (0, pi]")
    p.add_argument("--seed", type=int_arg(0, MAX_SEED), default=0, help="0..2**32-1")
    _command(p, _cmd_singular, output="folder for the families (drawing and JSON)",
             required=False)

    p = sub.add_parser("simulate", help="closed-loop head tracking run (VI.1 / VI.2)")
    p.add_argument("--controller", required=True,
                   metavar="pfl|lyapunov|los|mpc|module:Class",
                   help="the law: pfl, lyapunov, los (line-of-sight path following, "
                   "needs a path: default line), mpc (model-predictive head tracking, "
                   "|tau_i| <= --torque-bound; about 2.5 s of wall per simulated second) or "
                   "a Controller subclass of your own, built as Class(snake, reference)")
    _path_options(p)
    _robot_options(p)
    _run_options(p, None, f"duration [s], at most {steps * SIMULATE_DT:g} (pfl 10, lyapunov 60)")
    p.add_argument("--climb-r", type=float_arg(0.0),
                   help="PFL only: gain of the singularity-aware redundancy term (default 0)")
    _mpc_flags(p, "; at least the re-solve period, 0.04", "1")
    _command(p, _cmd_simulate)

    p = sub.add_parser("engine", help="the VI.3 run on MuJoCo (wheels, Coulomb contacts)",
                       description="The Lyapunov-like law (or the MPC: --law mpc) on MuJoCo, a "
                       "wheel pair per link (Section VI.3). The runs are chaotic: --seeds N "
                       "runs N perturbed starts and reports the distribution (documentation: "
                       "Concepts, The engine model); --path follows a path as simulate does.")
    _robot_options(p, friction=False, default="engine")  # friction: identified from wheels
    _path_options(p)
    _run_options(p, 60.0, f"duration [s], at most {steps * SIMULATE_DT:g}")
    p.add_argument("--wheel-radius", type=float_arg(0.0, MAX_WHEEL_RADIUS, open_low=True),
                   default=0.03, help=f"[m], at most {MAX_WHEEL_RADIUS:g}")
    p.add_argument("--mu", type=float_arg(0.0, MAX_MU, open_low=True), default=1.0,
                   help=f"wheel-floor friction, at most {MAX_MU:g}")
    p.add_argument("--law", choices=("velocity", "acceleration", "mpc"), default="velocity",
                   help="form of the Lyapunov-like law (velocity level with servos by default), "
                   "or mpc: model-predictive head tracking, |tau_i| <= --torque-bound")
    _mpc_flags(p, "", "and at most the motors' 10")
    p.add_argument("--cone", choices=("elliptic", "pyramidal"), default="elliptic",
                   help="MuJoCo friction cone (default elliptic; pyramidal: faster, but its "
                   "sideways friction depends on the heading, 26 %% weaker at 45 degrees)")
    p.add_argument("--seeds", type=int_arg(1, MAX_SEEDS), metavar="N",
                   help=f"run N times from perturbed initial postures, 1..{MAX_SEEDS}, and "
                   "report the distribution")
    p.add_argument("--perturbation", type=float_arg(0.0, MAX_PERTURBATION, open_low=True),
                   metavar="EPS", help="with --seeds: offsets of the initial joint angles, "
                   f"uniform in [-EPS, EPS] rad (default 1e-6, at most {MAX_PERTURBATION:g})")
    _command(p, _cmd_engine)

    p = sub.add_parser("view", help="meshcat viewer of a saved trajectory (127.0.0.1 only)")
    p.add_argument("trajectory", help="a .npz written by simulate/reproduce")
    p.add_argument("--html", metavar="FILE", help="write a self-contained animation page instead")
    p.add_argument("--port", type=int_arg(1, MAX_PORT), help="web port of the live viewer")
    p.add_argument("--fps", type=float_arg(MIN_FPS, MAX_FPS), default=20.0,
                   help="animation frame rate, 1..120")
    p.add_argument("--robot", metavar="ROBOT",
                   help=f"refuse a run of another robot ({_ROBOT_HELP}; compared by name)")
    _command(p, _cmd_view, None, json="print one JSON object (with --html: the page; live: "
             "the URL, then serve until Ctrl-C)")

    p = sub.add_parser("reproduce", help="run every experiment and write the HTML report",
                       description="Run the report stages and move the report into place when "
                       "all are done (interrupted: the stages done so far, marked so). Robot "
                       "options apply to the stages that use them; a stage that sets one itself "
                       "refuses it (documentation: The paper's experiments, Robots of one's own).")
    _robot_options(p)
    p.add_argument("-o", "--output", default="results", help="output folder")
    p.add_argument("--quick", action="store_true", help="shorter runs (for smoke tests)")
    p.add_argument("--only", action="append", metavar="STAGE", help="run only this stage")
    p.add_argument("--verbose", action="store_true",
                   help="log each stage's end (with its wall time) beside its start on "
                   "stderr even when it is not a terminal (one line per stage otherwise)")
    p.set_defaults(func=_cmd_reproduce)

    from .study.runner import CONNECT_TIMEOUT, MAX_CONNECT_TIMEOUT, MAX_WORKERS

    p = sub.add_parser("study", help="run a study (grids and random samples of runs) on Dask, "
                       "resumable", description=_STUDY_DESCRIPTION)
    p.add_argument("study", metavar="STUDY.toml", help="the study file")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="tcp://HOST:PORT or tls://HOST:PORT of an existing Dask scheduler "
                   "(default: a local cluster on 127.0.0.1, authenticated by TLS)")
    p.add_argument("--security", metavar="FILE",
                   help="with --scheduler: the cluster's TLS credentials, a YAML file of "
                   "Dask config (distributed.comm.tls.ca-file, client.cert, client.key; "
                   "default: Dask's own config)")
    p.add_argument("--connect-timeout", type=float_arg(0.0, MAX_CONNECT_TIMEOUT, open_low=True),
                   default=CONNECT_TIMEOUT, metavar="SECONDS",
                   help="longest wait for the scheduler to complete Dask's handshake "
                   f"(default {CONNECT_TIMEOUT:g})")
    p.add_argument("--workers", type=int_arg(1, MAX_WORKERS), metavar="N",
                   help=f"local worker processes, 1..{MAX_WORKERS} (default: one per core)")
    p.add_argument("--dashboard", action="store_true",
                   help="serve the local cluster's Dask dashboard on 127.0.0.1 (a random "
                   "port, printed on stderr); off by default")
    p.add_argument("--verbose", action="store_true",
                   help="log on stderr even when it is not a terminal")
    _command(p, _cmd_study, "output folder (re-run the same command to finish an interrupted "
             "study)", json="print the summary as one JSON object", metavar="DIR")

    p = sub.add_parser("bench-control", help="controller benchmark on paths (scenarios x "
                       "controllers x models, with and without joint 5 failed)")
    p.add_argument("--scenario", action="append", metavar="NAME",
                   help="a scenario (repeatable; default all): line, circle_0.5L, circle_1L, "
                   "circle_2L, lane_change, sinusoid, waypoints")
    p.add_argument("--controller", action="append", metavar="NAME|module:Class",
                   help="a controller (repeatable; default every built-in one): lyapunov, "
                   "velocity, pfl, pfl_climb, los, mpc (model-predictive, |tau_i| <= 1 N m; "
                   "about 2.5 s of wall per simulated second), or a Controller subclass of "
                   "your own")
    p.add_argument("--model", action="append", choices=("viscous", "engine"),
                   help="plant (repeatable; default viscous)")
    p.add_argument("--no-failure", action="store_true", help="skip the runs with joint 5 failed")
    _run_options(p, 60.0, "duration of each run [s] (--quick: at most 12)",
                 "judge the path metrics over t >= SECONDS (default: 10 s, or the second "
                 "half of runs shorter than 20 s; in the settings as window_start)")
    p.add_argument("--draws", type=int_arg(1, 100), metavar="N",
                   help="engine runs per cell from perturbed starts, 1..100 (the engine is "
                   "chaotic: a cell reports their median and 10-90 %% range; default: "
                   "bench_control.ENGINE_DRAWS)")
    p.add_argument("--quick", action="store_true", help="short runs of a few cells")
    _command(p, _cmd_bench_control)
    return parser


# ------------------------------------------------------------------ running
_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")


@contextlib.contextmanager
def _signals_as_interrupts() -> Iterator[list[str]]:
    """SIGINT, SIGTERM, SIGHUP raise KeyboardInterrupt once in the block (main thread only)."""
    received: list[str] = []
    if threading.current_thread() is not threading.main_thread():
        yield received
        return
    previous = {sig: signal.getsignal(sig) for sig in (getattr(signal, name, None)
                                                       for name in _SIGNALS)
                if sig is not None and signal.getsignal(sig) != signal.SIG_IGN}  # nohup: deaf

    def interrupt(signum: int, _frame: object) -> None:
        for sig in previous:
            signal.signal(sig, signal.SIG_IGN)
        received.append(signal.Signals(signum).name)
        raise KeyboardInterrupt(received[-1])

    for sig in previous:
        signal.signal(sig, interrupt)
    try:
        yield received
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)


@contextlib.contextmanager
def _stdout_to_stderr(active: bool) -> Iterator[None]:
    """With ``active``, stdout (Python's and C's) goes to stderr while the block runs."""
    if not active:
        yield
        return
    _flush_c_stdio()
    with contextlib.suppress(OSError, ValueError):
        sys.stdout.flush()
    try:
        saved = os.dup(1)
        os.dup2(2, 1)
    except OSError:
        saved = -1
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        _flush_c_stdio()
        if saved >= 0:
            os.dup2(saved, 1)
            os.close(saved)


def _flush_c_stdio() -> None:
    with contextlib.suppress(OSError, AttributeError, TypeError):
        ctypes.CDLL(None).fflush(None)


def _say(message: str) -> None:
    print(message if message.startswith("snake-pin") else f"snake-pin: {message}",
          file=sys.stderr, flush=True)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``snake-pin``.

    Parameters
    ----------
    argv
        The arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit status: 0 done, 2 wrong input, 3 a run diverged or failed, 130
        interrupted (see ``snake-pin --help``).
    """
    with _signals_as_interrupts() as received:
        try:
            try:
                args = build_parser().parse_args(argv)
            except SystemExit as exc:  # --help
                return int(exc.code or 0)
            json_mode = bool(getattr(args, "json", False))
            with _stdout_to_stderr(json_mode):
                outcome = args.func(args)
            if json_mode and outcome.payload:
                print(json_text(outcome.payload), flush=True)
            elif not json_mode and outcome.text:
                print(outcome.text, flush=True)
            if outcome.note:
                cause = f"{received[0]}: " if received and outcome.status == \
                    EXIT_INTERRUPTED else ""
                _say(cause + outcome.note)
            if outcome.after is not None:
                outcome.after()
            return outcome.status
        except SnakePinError as exc:
            _say(" ".join(str(exc).split()) or type(exc).__name__)
            return EXIT_USAGE
        except OSError as exc:
            where = f": {exc.filename}" if exc.filename else ""
            _say(f"{exc.strerror or exc}{where}")
            return EXIT_USAGE
        except KeyboardInterrupt as exc:
            text = " ".join(str(exc).split())
            cause = received[0] if received else "KeyboardInterrupt"
            _say(f"{cause}: {text}" if text and text != cause else f"interrupted by {cause}")
            return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
