"""``snake-pin reproduce``: run the report stages in order and put the report in place,
whole or not at all, and the robot options each stage honours (:data:`HONOURED`); what
the output folder holds whatever happens, and what each stage does with a robot of one's
own, are in :doc:`/reproduce`.
"""

from __future__ import annotations

import contextlib
import datetime
import json
import os
import re
import shutil
import signal
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from .._io import current_umask, fsync_directory, pid_alive
from ..exceptions import ParameterError, RunInterrupted
from ..params import ROBOTS, SnakeParams
from ..report import Report
from ..runs.parallel import SharedCluster
from .context import Context

# Context is defined in experiments.context (the stages import it from there).
__all__ = ["HONOURED", "MIN_LINKS", "reproduce", "stages"]

#: Stage -> the robot fields (``SnakeParams`` names, plus "robot" for --robot) it takes
#: from the robot it is given. Friction does not enter D and R, so the manipulability
#: stage honours it trivially; the engine stage runs the engine robot of VI.3 for a
#: preset and a robot of one's own itself (see ``unhonoured``).
HONOURED: dict[str, frozenset[str]] = {
    "robot": frozenset({"robot", "n", "passive", "c_x", "c_y", "c_theta"}),
    "manipulability": frozenset({"robot", "n", "c_x", "c_y", "c_theta"}),
    "integrability": frozenset({"robot", "n", "c_x", "c_theta"}),
    "pfl": frozenset({"robot", "n", "c_x", "c_y", "c_theta"}),
    "tracking": frozenset({"robot", "n", "c_theta"}),
    "engine": frozenset(),
    "failure_map": frozenset({"robot", "n", "c_x", "c_theta"}),
    "bench_control": frozenset(),
}

#: Stage -> the fewest links it can run with (joint 5 free or passive needs n >= 6, PFL
#: needs three actuated joints, the engine stage two beside its passive joint; a preset's
#: engine stage runs the 8-link engine robot whatever n).
MIN_LINKS: dict[str, int] = {"robot": 2, "manipulability": 6, "integrability": 2, "pfl": 4,
                             "tracking": 6, "engine": 4, "failure_map": 6, "bench_control": 2}

_STAGING = re.compile(r"\.reproduce-(\d+)-\w+")
_PARTIAL = "interrupted"


def stages() -> list[tuple[str, Callable[[Context], None]]]:
    """The report stages in order (imported lazily: each pulls in its own tools).

    Returns
    -------
    list of tuple
        (name, stage function) pairs, in the order they run.
    """
    from .bench_control import bench_control_stage
    from .engine import engine_stage
    from .failure_map import failure_map_stage
    from .integrability import integrability_stage
    from .manipulability import manipulability_stage
    from .pfl import pfl_stage
    from .robot import robot_stage
    from .tracking import tracking_stage

    return [("robot", robot_stage), ("manipulability", manipulability_stage),
            ("integrability", integrability_stage), ("pfl", pfl_stage),
            ("tracking", tracking_stage), ("engine", engine_stage),
            ("failure_map", failure_map_stage), ("bench_control", bench_control_stage)]


def unhonoured(stage: str, given: set[str] | frozenset[str], params: SnakeParams) -> list[str]:
    """The fields of ``given`` (names of :data:`HONOURED`) that ``stage`` would not honour for
    ``params``, sorted; the engine and benchmark stages also honour "robot" for a robot of
    one's own, the engine stage for its preset."""
    honoured = set(HONOURED[stage])
    if stage == "engine" and (params.name == "engine" or params.name not in ROBOTS):
        honoured.add("robot")
    if stage == "bench_control" and params.name not in ROBOTS:
        honoured.add("robot")  # a robot of one's own runs the benchmark itself
    return sorted(set(given) - honoured)


def reproduce(folder: str | Path, params: SnakeParams | None = None, *, quick: bool = False,
              only: list[str] | None = None, log: Callable[[str], None] = print,
              log_done: bool = True) -> Path:
    """Run the stages (all, or those named in ``only``) and put the report in ``folder``.

    Parameters
    ----------
    folder
        The output folder (created if needed; what it holds whatever happens: :doc:`/reproduce`).
    params
        The robot (default Table 1).
    quick
        Shorter runs, fewer engine draws (smoke tests).
    only
        Stage names to run (default all).
    log
        Called with one line as each stage starts (``[2/8] manipulability ...``).
    log_done
        Also log each stage's end (``[2/8] manipulability done in 12.3 s``).

    Returns
    -------
    Path
        ``folder/index.html``.

    Raises
    ------
    ParameterError
        An unknown stage in ``only``, a robot with fewer links than a chosen stage needs
        (:data:`MIN_LINKS`), or wheels that do not fit it; nothing is written.
    RunInterrupted
        On KeyboardInterrupt; ``partial`` is the index of the partial report.
    """
    params = params or SnakeParams.table1()
    known = stages()
    names = [name for name, _ in known]
    for name in only or []:
        if name not in names:
            raise ParameterError(f"unknown stage {name!r}; stages: {', '.join(names)}")
    chosen = [(name, fn) for name, fn in known if only is None or name in only]
    for name, _ in chosen:
        if name == "engine":
            _check_engine_robot(params)
        elif params.n < MIN_LINKS[name]:
            raise ParameterError(f"stage {name!r} needs n >= {MIN_LINKS[name]} links, "
                                 f"got n = {params.n}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    _remove_stale_staging(folder)
    staging = Path(tempfile.mkdtemp(dir=folder, prefix=f".reproduce-{os.getpid()}-"))
    try:
        os.chmod(staging, 0o777 & ~current_umask())
        report = Report(f"snake_pin report: {params.name} robot "
                        "(Ariizumi & Tanaka, manipulability without a lateral constraint)")
        timings: dict[str, float] = {}
        current, sections, files = "", 0, set()
        try:
            # one local Dask cluster for every stage's jobs, started by the first stage
            # that fans out and closed (its workers killed) when the stages end
            with SharedCluster() as cluster:
                ctx = Context(folder=staging, params=params, report=report, quick=quick,
                              cluster=cluster)
                for index, (name, fn) in enumerate(chosen, start=1):
                    current, sections, files = name, len(report.sections), _names(staging)
                    log(f"[{index}/{len(chosen)}] {name} ...")
                    start = time.perf_counter()
                    fn(ctx)
                    timings[name] = time.perf_counter() - start
                    if log_done:
                        log(f"[{index}/{len(chosen)}] {name} done in {timings[name]:.1f} s")
            current = ""
            _timing(report, timings)
            report.write(staging)
        except KeyboardInterrupt as exc:
            with _signals_deferred():
                partial = _keep_partial(folder, staging, report, timings, current, sections,
                                        files, exc)
            done = ", ".join(timings) or "none"
            where = (f"the previous report in {folder} is untouched; the stages done so far "
                     f"are in {partial}" if partial.parent != folder
                     else f"the stages done so far are in {partial}, marked interrupted")
            raise RunInterrupted(f"reproduce interrupted during stage '{current or 'report'}'"
                                 f" (done: {done}); {where}", partial=partial) from None
        with _signals_deferred():
            _move_into(staging, folder)
        return folder / "index.html"
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _check_engine_robot(params: SnakeParams) -> None:
    """The engine stage's robot has enough links and takes the default wheels (checked
    before anything is written: a robot file's links may be too short for them)."""
    from ..engine.model import WheelSpec, build_engine_model
    from ..runs.engine import engine_robot

    robot = engine_robot(params)
    if robot.n < MIN_LINKS["engine"]:
        raise ParameterError(f"stage 'engine' needs n >= {MIN_LINKS['engine']} links, "
                             f"got n = {robot.n}")
    try:
        build_engine_model(robot, WheelSpec())
    except ParameterError as exc:
        raise ParameterError(f"stage 'engine' cannot put robot '{robot.name}' on its wheels: "
                             f"{exc}") from None


def _timing(report: Report, timings: dict[str, float]) -> None:
    report.section("timing", "Timing").table(
        ["stage", "wall time [s]"], [[k, v] for k, v in timings.items()]).numbers.update(timings)


def _names(folder: Path) -> set[str]:
    return {entry.name for entry in os.scandir(folder)}


def _keep_partial(folder: Path, staging: Path, report: Report, timings: dict[str, float],
                  current: str, sections: int, files: set[str],
                  exc: BaseException) -> Path:
    """Write the interrupted report of the stages done and put it in place; its index."""
    if current:  # drop what the unfinished stage wrote
        del report.sections[sections:]
        for name in _names(staging) - files:
            with contextlib.suppress(OSError):
                path = staging / name
                if path.is_dir() and not path.is_symlink():
                    shutil.rmtree(path)
                else:
                    path.unlink()
    when = datetime.datetime.now().astimezone().isoformat(timespec="seconds")
    report.status = "interrupted"
    report.note = (f"interrupted ({_cause(exc)}) at {when} during stage "
                   f"'{current or 'report'}'; stages done: {', '.join(timings) or 'none'}")
    _timing(report, timings)
    report.write(staging)
    if _complete_report(folder):
        target = _free_partial_folder(folder)
        os.replace(staging, target)  # one rename: the whole partial report appears at once
        return target / "index.html"
    _move_into(staging, folder)
    return folder / "index.html"


def _cause(exc: BaseException | None) -> str:
    """The signal behind an interrupt ("SIGTERM", ...) if the command line named it."""
    seen = 0
    while exc is not None and seen < 10:
        text = str(exc.args[0]) if isinstance(exc, KeyboardInterrupt) and exc.args else ""
        if text.startswith("SIG"):
            return text
        exc, seen = exc.__context__, seen + 1
    return "KeyboardInterrupt"


def _complete_report(folder: Path) -> bool:
    """Whether ``folder`` holds a report that was not marked interrupted."""
    if not (folder / "index.html").is_file():
        return False
    try:
        run = json.loads((folder / "summary.json").read_text()).get("run", {})
        return run.get("status", "complete") != "interrupted"
    except (OSError, ValueError, AttributeError):
        return True  # a report we cannot read is kept, not replaced


def _free_partial_folder(folder: Path) -> Path:
    """``folder/interrupted``, emptied if it holds an earlier partial report of ours."""
    target = folder / _PARTIAL
    if target.exists() and not target.is_symlink() and target.is_dir() \
            and not _complete_report(target) and (target / "index.html").is_file():
        shutil.rmtree(target)
    suffix = 2
    while target.exists() or target.is_symlink():
        target = folder / f"{_PARTIAL}-{suffix}"
        suffix += 1
    return target


def _move_into(staging: Path, folder: Path) -> None:
    """Rename every staged file into ``folder``: data, figures and pages, summary, index."""
    last = {"index.html": 3, "summary.json": 2}

    def rank(name: str) -> tuple[int, str]:
        return last.get(name, int(name.endswith((".png", ".html", ".svg")))), name

    for name in sorted(_names(staging), key=rank):
        source, target = staging / name, folder / name
        if source.is_dir() and target.is_dir():
            # a stage's folder (e.g. the failure map's study): a folder cannot be renamed
            # onto a non-empty one, so the old one steps aside and is removed after
            old = folder / f".{name}.old-{os.getpid()}"
            os.replace(target, old)
            os.replace(source, target)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(source, target)
    fsync_directory(folder)


def _remove_stale_staging(folder: Path) -> None:
    """Remove staging folders of runs whose process is gone (killed with -9)."""
    for entry in os.scandir(folder):
        match = _STAGING.fullmatch(entry.name)
        if match is not None and entry.is_dir(follow_symlinks=False) \
                and not pid_alive(int(match.group(1))):
            shutil.rmtree(entry.path, ignore_errors=True)


@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP while files are moved and deliver the first one after
    (in the main thread: only it can change handlers)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []

    def note(signum: int, _frame: object) -> None:
        received.append(signum)

    found = (getattr(signal, name, None) for name in ("SIGINT", "SIGTERM", "SIGHUP"))
    # a signal ignored, or handled outside Python, is left as it is
    previous = {sig: signal.signal(sig, note) for sig in found
                if sig is not None and signal.getsignal(sig) not in (None, signal.SIG_IGN)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if received:
            signal.raise_signal(received[0])
