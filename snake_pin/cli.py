"""The ``snake-pin`` console script: one parser, one subcommand per job.

Heavy imports happen inside the subcommand that needs them. Every error a user can cause
ends as one line on stderr and exit status 2; ``--json`` prints exactly one JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

from .exceptions import SnakePinError
from .params import ROBOTS, SnakeParams

__all__ = ["build_parser", "main", "parse_angle"]

_ANGLE = re.compile(r"^\s*([+-]?)\s*(\d+(?:\.\d*)?(?:e[+-]?\d+)?)?\s*(\*?\s*pi)?\s*"
                    r"(?:/\s*(\d+(?:\.\d*)?))?\s*$", re.IGNORECASE)


class UsageError(SnakePinError):
    """A command-line argument is wrong."""


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line and exit status 2."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{self.prog}: {message}")


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
    return -value if sign == "-" else value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from exc
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return value


def _non_negative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from exc
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"must be a non-negative number, got {text!r}")
    return value


def _int_at_least(low: int) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from exc
        if value < low:
            raise argparse.ArgumentTypeError(f"must be at least {low}, got {value}")
        return value
    return parse


def _robot_options(parser: argparse.ArgumentParser, *, friction: bool = False) -> None:
    parser.add_argument("--robot", choices=ROBOTS, default="table1", help="preset robot")
    parser.add_argument("--n", type=_int_at_least(2), help="number of links (overrides preset)")
    parser.add_argument("--passive", type=_int_at_least(1), action="append", default=[],
                        metavar="K", help="make joint K passive (repeatable)")
    if friction:
        parser.add_argument("--cx", type=_non_negative_float, help="c_x [N s/m]")
        parser.add_argument("--cy", type=_non_negative_float, help="c_y [N s/m]")
        parser.add_argument("--ctheta", type=_non_negative_float, help="c_theta [N m s]")


def _params(args: argparse.Namespace) -> SnakeParams:
    changes: dict[str, Any] = {}
    if getattr(args, "n", None) is not None:
        changes["n"] = args.n
    if getattr(args, "passive", None):
        changes["passive"] = tuple(args.passive)
    for flag, key in (("cx", "c_x"), ("cy", "c_y"), ("ctheta", "c_theta")):
        if getattr(args, flag, None) is not None:
            changes[key] = getattr(args, flag)
    return SnakeParams.preset(args.robot, **changes)


def _emit(args: argparse.Namespace, payload: dict[str, Any], text: str) -> None:
    if getattr(args, "json", False):
        print(json.dumps(payload, default=_json_default))
    else:
        print(text)


def _json_default(value: object) -> object:
    if hasattr(value, "tolist"):
        return value.tolist()
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


# ----------------------------------------------------------------- subcommands
def _cmd_generate(args: argparse.Namespace) -> None:
    from .urdf import write_urdf

    params = _params(args)
    out = Path(args.output)
    if out.suffix != ".urdf":
        raise UsageError(f"generate: output must end in .urdf, got {out}")
    out.parent.mkdir(parents=True, exist_ok=True)
    write_urdf(params, out)
    _emit(args, {"urdf": str(out), "n": params.n, "passive": list(params.passive)},
          f"wrote {out} ({params.n} links, passive joints: {list(params.passive) or 'none'})")


def _cmd_info(args: argparse.Namespace) -> None:
    from .experiments.robot import info

    data = info(_params(args))
    _emit(args, data, "\n".join(f"{k:>13}: {v}" for k, v in data.items()))


def _cmd_reproduce(args: argparse.Namespace) -> None:
    from .experiments import reproduce, stages

    known = [name for name, _ in stages()]
    for name in args.only or []:
        if name not in known:
            raise UsageError(f"reproduce: unknown stage {name!r}; stages: {', '.join(known)}")
    index = reproduce(args.output, _params(args), quick=args.quick, only=args.only,
                      log=lambda line: print(line, file=sys.stderr, flush=True))
    print(f"report: {index}")


def _parse_q(text: str) -> list[float]:
    try:
        return [parse_angle(part) for part in text.replace(" ", "").split(",") if part]
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"--q: {exc}") from exc


def _posture(args: argparse.Namespace, n: int) -> list[float]:
    from . import gaits

    if args.shape == "straight":
        return gaits.straight(n).tolist()
    if args.shape == "arc":
        if args.phi0 is None:
            raise UsageError("manip: --shape arc needs --phi0")
        return gaits.arc(n, args.phi0).tolist()
    if args.shape == "serpenoid":
        return gaits.Serpenoid(n, args.alpha, args.ts).configuration().tolist()
    if args.q is None:
        raise UsageError("manip: --shape q needs --q x,y,theta1,phi1,...")
    if len(args.q) != n + 2:
        raise UsageError(f"manip: --q needs {n + 2} values for n = {n}, got {len(args.q)}")
    return args.q


def _cmd_manip(args: argparse.Namespace) -> None:
    from .manipulability import manipulability
    from .model import Snake

    params = _params(args)
    snake = Snake(params)
    res = manipulability(snake, _posture(args, params.n), free_joint=args.free_joint,
                         heading=not args.no_heading)
    tilde = "~" if (args.free_joint or params.passive) else ""
    _emit(args, res.to_dict(),
          f"D{tilde} = {res.D:.6g}\nR{tilde} = {res.R:.6g}\nsigma = {res.sigma}\n"
          f"lambda = {res.lambda_}")


def _cmd_sweep(args: argparse.Namespace) -> None:
    from .model import Snake
    from .sweeps import sweep

    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    result = sweep(Snake(_params(args)), args.family, free_joint=args.free_joint,
                   points=args.points, progress=not args.json)
    paths = result.write(out)
    payload = {"family": args.family, "free_joint": args.free_joint,
               "zeros": result.zeros().tolist(), "R_min": float(result.R.min()),
               "D_min": float(result.D.min()), "files": {k: str(v) for k, v in paths.items()}}
    _emit(args, payload, f"wrote {', '.join(str(p) for p in paths.values())}; "
                         f"R = 0 at {result.label} = {result.zeros().tolist()}")


def _cmd_singular(args: argparse.Namespace) -> None:
    from .singular import find_singular_postures

    params = _params(args)
    search = find_singular_postures(params, starts=args.starts, bound=args.bound,
                                    free_joint=args.free_joint, seed=args.seed,
                                    progress=not args.json)
    if args.output:
        from .experiments.manipulability import draw_singular

        out = Path(args.output)
        out.mkdir(parents=True, exist_ok=True)
        draw_singular(search, out / "singular_postures.png")
    lines = [f"{len(search.families)} famil{'y' if len(search.families) == 1 else 'ies'} "
             f"with R <= {search.threshold:.3g} (typical R {search.R_typical:.3g}), "
             f"from {search.starts} starts:"]
    lines += [f"  {'straight' if f.straight else 'non-straight'} x{f.members}: "
              f"R = {f.R:.3g}, phi = {[round(x, 3) for x in f.phi]}" for f in search.families]
    _emit(args, search.to_dict(), "\n".join(lines))


def _cmd_simulate(args: argparse.Namespace) -> None:
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    params = _params(args)
    if args.controller == "pfl":
        from .experiments.pfl import plot_pfl, run_pfl

        if params.passive:
            raise UsageError("simulate: PFL needs every joint actuated (drop --passive)")
        run = run_pfl(params, t_final=args.t_final or 10.0, climb_R=args.climb_r,
                      progress=not args.json)
        stem = "pfl"
        traj = run.trajectory
        figures = plot_pfl(run, out, stem)
    else:
        from .experiments.tracking import TRACKING_FRICTION, plot_tracking, run_tracking

        if args.cx is None and args.cy is None:  # anisotropic default (erratum 3)
            params = params.replace(**TRACKING_FRICTION)
        traj = run_tracking(params, t_final=args.t_final or 60.0, progress=not args.json)
        stem = "lyapunov"
        figures = plot_tracking(traj, out, stem)
    npz, summary_path = traj.save(out / stem)
    payload = traj.summary_dict()
    payload["files"] = [str(npz), str(summary_path), *(str(p) for p in figures.values())]
    _emit(args, payload, json.dumps(payload, indent=2, default=_json_default))


def _cmd_view(args: argparse.Namespace) -> None:
    from .sim import Trajectory
    from .viz.meshcat_view import view, write_html

    traj = Trajectory.load(args.trajectory)
    if args.robot is not None and (traj.params.name != args.robot):
        raise UsageError(f"view: {args.trajectory} is a run of the '{traj.params.name}' robot, "
                         f"not '{args.robot}'")
    if args.html:
        out = write_html(traj, args.html, fps=args.fps)
        _emit(args, {"html": str(out), "t_end": traj.t_end}, f"wrote {out}")
        return
    view(traj, port=args.port, fps=args.fps)


def _cmd_engine(args: argparse.Namespace) -> None:
    from .engine.model import WheelSpec
    from .engine.run import identify_friction, run_engine
    from .experiments.engine import plot_engine, summarize

    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    params = SnakeParams.engine(passive=tuple(args.passive))
    wheels = WheelSpec(radius=args.wheel_radius, friction=args.mu, cone=args.cone)
    friction = identify_friction(params.replace(passive=()), wheels)
    run = run_engine(params, wheels=wheels, t_final=args.t_final, friction=friction,
                     law=args.law, progress=not args.json)
    summarize(run.trajectory)
    npz, summary_path = run.trajectory.save(out / "engine")
    figures = plot_engine(run, None, out, "engine")
    payload = {**run.trajectory.summary_dict(), "friction": friction,
               "files": [str(npz), str(summary_path), *(str(p) for p in figures.values())]}
    _emit(args, payload, json.dumps(payload, indent=2, default=_json_default))


def build_parser() -> argparse.ArgumentParser:
    """The whole command line, built in one place."""
    parser = _Parser(prog="snake-pin", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser("generate", help="write the URDF of a snake robot")
    _robot_options(p)
    p.add_argument("-o", "--output", required=True, help="output file (.urdf)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_generate)

    p = sub.add_parser("info", help="parameters and model sizes of a robot")
    _robot_options(p, friction=True)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_info)

    p = sub.add_parser("manip", help="manipulability D, R of one posture (eqs. 30, 31, 42)")
    _robot_options(p)
    p.add_argument("--shape", choices=("straight", "arc", "serpenoid", "q"), default="straight")
    p.add_argument("--phi0", type=parse_angle, help="arc: common joint angle (e.g. pi/10)")
    p.add_argument("--alpha", type=parse_angle, default=math.pi / 4, help="serpenoid alpha")
    p.add_argument("--ts", type=float, default=1.5, help="serpenoid T_s")
    p.add_argument("--q", type=_parse_q, help="full configuration x,y,theta1,phi1,...")
    p.add_argument("--free-joint", type=_int_at_least(0), metavar="K", help="joint K is free")
    p.add_argument("--no-heading", action="store_true", help="leave theta_1 out of the task")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_manip)

    p = sub.add_parser("sweep", help="D and R along a posture family (Figs. 2-9)")
    p.add_argument("family", choices=("arc", "alpha", "ts"))
    _robot_options(p)
    p.add_argument("--free-joint", type=_int_at_least(0), metavar="K", help="joint K is free")
    p.add_argument("--points", type=_int_at_least(2), default=201)
    p.add_argument("-o", "--output", required=True, help="output folder")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_sweep)

    p = sub.add_parser("singular", help="search the joint box for singular postures (R = 0)")
    _robot_options(p)
    p.add_argument("--starts", type=_int_at_least(1), default=200)
    p.add_argument("--bound", type=parse_angle, default=math.pi / 2, help="|phi_i| <= bound")
    p.add_argument("--free-joint", type=_int_at_least(0), metavar="K")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("-o", "--output", help="folder for a drawing of the families")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_singular)

    p = sub.add_parser("simulate", help="closed-loop head tracking run (VI.1 / VI.2)")
    p.add_argument("--controller", choices=("pfl", "lyapunov"), required=True)
    _robot_options(p, friction=True)
    p.add_argument("--t-final", type=_positive_float, help="duration [s] (pfl 10, lyapunov 60)")
    p.add_argument("--climb-r", type=_non_negative_float, default=0.0,
                   help="PFL: gain of the singularity-aware redundancy term")
    p.add_argument("-o", "--output", required=True, help="output folder")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser("engine", help="the VI.3 run on MuJoCo (wheels, Coulomb contacts)")
    p.add_argument("--passive", type=_int_at_least(1), action="append", default=[],
                   metavar="K", help="make joint K passive (repeatable)")
    p.add_argument("--t-final", type=_positive_float, default=60.0, help="duration [s]")
    p.add_argument("--wheel-radius", type=_positive_float, default=0.03, help="[m]")
    p.add_argument("--mu", type=_positive_float, default=1.0, help="wheel-floor friction")
    p.add_argument("--law", choices=("velocity", "acceleration"), default="velocity",
                   help="form of the Lyapunov-like law (velocity level with servos by default)")
    p.add_argument("--cone", choices=("elliptic", "pyramidal"), default="elliptic",
                   help="MuJoCo friction cone (pyramidal: about 2x faster, less faithful)")
    p.add_argument("-o", "--output", required=True, help="output folder")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_engine)

    p = sub.add_parser("view", help="meshcat viewer of a saved trajectory (127.0.0.1 only)")
    p.add_argument("trajectory", help="a .npz written by simulate/reproduce")
    p.add_argument("--html", metavar="FILE", help="write a self-contained animation page instead")
    p.add_argument("--port", type=_int_at_least(1), help="web port of the live viewer")
    p.add_argument("--fps", type=_positive_float, default=20.0, help="animation frame rate")
    p.add_argument("--robot", choices=ROBOTS, help="refuse a run of another robot")
    p.add_argument("--json", action="store_true", help="print one JSON object (with --html)")
    p.set_defaults(func=_cmd_view)

    p = sub.add_parser("reproduce", help="run every experiment and write the HTML report")
    _robot_options(p, friction=True)
    p.add_argument("-o", "--output", default="results", help="output folder")
    p.add_argument("--quick", action="store_true", help="shorter runs (for smoke tests)")
    p.add_argument("--only", action="append", metavar="STAGE", help="run only this stage")
    p.set_defaults(func=_cmd_reproduce)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``snake-pin``; returns the exit status."""
    try:
        args = build_parser().parse_args(argv)
        args.func(args)
    except SnakePinError as exc:
        message = str(exc)
        print(message if message.startswith("snake-pin") else f"snake-pin: {message}",
              file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"snake-pin: {exc.strerror or exc}: {exc.filename or ''}".rstrip(": "),
              file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
