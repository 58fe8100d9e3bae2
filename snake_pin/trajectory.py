"""A run's result, :class:`Trajectory`, saved as ``PATH.npz`` + ``PATH.json`` (whole or not
at all) and loaded with every .npy header's bounds checked before any data is decompressed,
nothing unpickled, anything malformed one TrajectoryFileError line.
"""

from __future__ import annotations

import io
import json
import math
import os
import re
import reprlib
import zipfile
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field, is_dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ._io import atomic_group, open_regular_file
from ._json import json_text
from ._validation import mebibytes, one_line, printable_path
from .exceptions import ConfigurationError, ParameterError, TrajectoryFileError
from .params import SnakeParams

__all__ = ["MAX_ARRAY_BYTES", "MAX_TOTAL_BYTES", "STATUSES", "Trajectory"]

#: Largest array a trajectory may hold, decompressed [bytes] (files and runs alike).
MAX_ARRAY_BYTES = 512 * 2**20
#: Largest total of the arrays one load reads (or one run records) [bytes].
MAX_TOTAL_BYTES = 1024 * 2**20
#: The run statuses, explained in :doc:`/architecture`.
STATUSES = ("completed", "diverged", "failed", "interrupted")

_FAULTS = ("diverged", "failed")
_CORE = ("t", "q", "dq", "tau")
_SIGNAL_PREFIX = "signal__"
_SIGNAL_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.+-]{0,63}")
_MAX_HEADER_CHARS = 1 << 20
_MAX_MEMBERS = 1024
_CHUNK = 1 << 20
_HEADER_KEYS = {"params": dict, "reason": str, "meta": dict, "summary": dict, "signals": list}


@dataclass
class Trajectory:
    """A recorded run: samples at every control step (plus the initial state).

    Parameters
    ----------
    t, q, dq : numpy.ndarray
        Sample times [s], shape (N,); configurations and velocities, shape (N, n + 2).
    tau : numpy.ndarray
        Joint torques [N m], shape (N, n - 1); ``tau[k]`` held over ``[t[k], t[k + 1])``.
    params : SnakeParams
        The robot.
    signals : dict of str to numpy.ndarray, optional
        Extra per-sample series, N rows each; NaN where missing.
    diverged, reason : optional
        Whether the run stopped on a fault ("diverged" or "failed"); why (empty if completed).
    meta, summary : dict, optional
        Run settings; scalar results written to the JSON summary.
    status : str, optional
        One of :data:`STATUSES` (sets ``diverged``); empty: from ``diverged``.

    Raises
    ------
    ParameterError
        An unknown ``status``, or ``diverged=True`` with a status that is not a fault.
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    params: SnakeParams
    signals: dict[str, np.ndarray] = field(default_factory=dict)
    diverged: bool = False
    reason: str = ""
    meta: dict[str, Any] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    status: str = ""

    def __post_init__(self) -> None:
        if self.status == "":
            self.status = "diverged" if self.diverged else "completed"
        elif self.status not in STATUSES:
            raise ParameterError(f"status must be one of {', '.join(STATUSES)}, "
                                 f"got {reprlib.repr(self.status)}")
        elif self.diverged and self.status not in _FAULTS:
            raise ParameterError(f"a run with status {self.status!r} cannot be diverged=True")
        self.diverged = self.status in _FAULTS

    @property
    def t_end(self) -> float:
        """Time of the last sample."""
        return float(self.t[-1]) if len(self.t) else 0.0

    def __len__(self) -> int:
        return len(self.t)

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike[str]) -> tuple[Path, Path]:
        """Write ``PATH.npz`` (arrays) and ``PATH.json`` (RFC 8259 summary) as one set.

        Parameters
        ----------
        path : str or os.PathLike
            The files' common name; only a trailing ``.npz``/``.json`` is dropped.

        Returns
        -------
        tuple of pathlib.Path
            The ``.npz`` and ``.json`` files written.

        Raises
        ------
        ParameterError
            No such folder, or meta/summary are not JSON.
        ConfigurationError
            The arrays are not a trajectory that :meth:`load` would accept.
        """
        try:
            given = Path(path)
        except TypeError as exc:
            raise ParameterError(f"not a file path: {reprlib.repr(path)}") from exc
        stem = re.sub(r"\.(npz|json)\Z", "", given.name)
        if stem in ("", ".", ".."):
            raise ParameterError(f"trajectory file name is empty: {printable_path(path)}")
        npz, js = given.with_name(stem + ".npz"), given.with_name(stem + ".json")
        if not npz.parent.is_dir():
            raise ParameterError(f"output directory does not exist: {npz.parent}")
        core = {name: np.asarray(getattr(self, name)) for name in _CORE}
        signals = {name: np.asarray(value) for name, value in self.signals.items()}
        problem = _array_problem(core, signals, self.params.n)
        if problem:
            raise ConfigurationError(f"cannot save this trajectory: {problem}")
        arrays = {name: arr.astype(float, copy=False) for name, arr in core.items()}
        arrays.update({_SIGNAL_PREFIX + k: v for k, v in signals.items()})
        header = {"params": self.params.to_dict(), "status": self.status,
                  "diverged": self.diverged, "reason": self.reason, "meta": self.meta,
                  "summary": self.summary, "signals": sorted(self.signals)}
        try:  # the header keeps NaN (read back as is), the summary file writes null
            arrays["header"] = np.array(json.dumps(header, default=_json_default))
            summary_text = json_text(self.summary_dict(), indent=2)
        except (TypeError, ValueError, RecursionError) as exc:
            raise ParameterError(f"the trajectory's meta/summary is not JSON: "
                                 f"{one_line(str(exc), 120)}") from None
        with atomic_group(npz.parent) as group:
            group.save(npz.name, lambda handle: np.savez_compressed(
                handle, allow_pickle=True, **arrays))
            group.write_bytes(js.name, (summary_text + "\n").encode())
        return npz, js

    def summary_dict(self) -> dict[str, Any]:
        """The JSON summary: run status plus :attr:`summary`.

        Returns
        -------
        dict
            ``robot``, ``n``, ``t_end``, ``status``, ``diverged``, ``reason``, then :attr:`summary`.
        """
        return {"robot": self.params.name, "n": self.params.n, "t_end": self.t_end,
                "status": self.status, "diverged": self.diverged, "reason": self.reason,
                **self.summary}

    @classmethod
    def load(cls, path: str | os.PathLike[str], *,
             signals: bool | Iterable[str] = True) -> Trajectory:
        """Read a trajectory written by :meth:`save`, refusing anything else.

        Parameters
        ----------
        path
            The .npz file; if none has this name and it lacks ``.npz``, ``PATH.npz``.
        signals
            Signals to read: True (all), False (none) or names; others are never decompressed.

        Raises
        ------
        TrajectoryFileError
            One line naming the file: missing, not a regular file, not a trajectory,
            corrupt, inconsistent, or beyond :data:`MAX_ARRAY_BYTES` or :data:`MAX_TOTAL_BYTES`.
        """
        wanted = _wanted_signals(signals)
        file = _resolve(path)
        shown = printable_path(file)
        raw = open_regular_file(
            file, limit=2 * MAX_TOTAL_BYTES, kind="snake_pin trajectory",
            error=lambda message: TrajectoryFileError(f"{shown}: {one_line(message)}"))
        try:
            with raw:
                if os.fstat(raw.fileno()).st_size == 0:
                    raise _Refused("the file is empty")
                return _read(cls, raw, wanted)
        except _Refused as exc:
            raise TrajectoryFileError(f"{shown} is not a usable snake_pin trajectory: "
                                      f"{one_line(str(exc))}") from None
        except zipfile.BadZipFile as exc:
            raise TrajectoryFileError(f"{shown} is not a readable snake_pin trajectory: "
                                      f"broken zip archive ({one_line(str(exc))})") from None
        except Exception as exc:  # hostile input: whatever breaks while parsing is a refusal
            raise TrajectoryFileError(f"{shown} is not a readable snake_pin trajectory "
                                      f"({type(exc).__name__}: {one_line(str(exc))})") from None


def _resolve(path: str | os.PathLike[str]) -> Path:
    """The file :meth:`Trajectory.load` opens for ``path`` (see there); opening it refuses
    a missing or irregular one."""
    try:
        given = Path(path)
    except TypeError as exc:
        raise TrajectoryFileError(f"not a file path: {reprlib.repr(path)}") from exc
    try:
        if given.name and not given.name.endswith(".npz") and not given.exists():
            alternative = given.with_name(given.name + ".npz")
            if alternative.is_file():
                return alternative
    except OSError:  # an unreadable folder: opening the file says why
        pass
    return given


def _wanted_signals(signals: object) -> frozenset[str] | None:
    """None for every signal, else the names asked for."""
    if isinstance(signals, (bool, np.bool_)):
        return None if signals else frozenset()
    if isinstance(signals, (str, bytes)) or not isinstance(signals, Iterable):
        raise ParameterError(f"signals must be True, False or a list of names, "
                             f"got {reprlib.repr(signals)}")
    names = list(signals)
    if not all(isinstance(name, str) for name in names):
        raise ParameterError(f"signal names must be strings, got {reprlib.repr(names)}")
    return frozenset(names)


class _Refused(Exception):
    """A specific reason to refuse a file (turned into TrajectoryFileError by load)."""


@dataclass
class _Member:
    info: zipfile.ZipInfo
    shape: tuple[int, ...] = ()
    dtype: np.dtype | None = None
    fortran: bool = False

    @property
    def nbytes(self) -> int:
        return math.prod(self.shape) * (self.dtype.itemsize if self.dtype is not None else 0)


def _read(cls: type[Trajectory], raw: io.BufferedReader,
          wanted: frozenset[str] | None) -> Trajectory:
    with zipfile.ZipFile(raw) as archive:
        infos = archive.infolist()
        if len(infos) > _MAX_MEMBERS:
            raise _Refused(f"{len(infos)} members (at most {_MAX_MEMBERS})")
        members = {info.filename: info for info in infos}
        if len(members) != len(infos):
            raise _Refused("two members share a name")
        if "header.npy" not in members:
            raise _Refused("no header")
        header_member = _inspect(archive, members["header.npy"], "header", kinds="U")
        if header_member.shape != () or header_member.nbytes > 4 * _MAX_HEADER_CHARS:
            raise _Refused(f"the header is not one string of at most {_MAX_HEADER_CHARS} "
                           "characters")
        header = _parse_header(str(_data(archive, header_member, "header")[()]))
        params = header["params"]
        listed = header["signals"]
        expected = {f"{name}.npy" for name in _CORE} | {"header.npy"}
        expected |= {f"{_SIGNAL_PREFIX}{name}.npy" for name in listed}
        missing, extra = sorted(expected - set(members)), sorted(set(members) - expected)
        if missing:
            raise _Refused(f"array {missing[0].removesuffix('.npy')!r} is missing")
        if extra:
            raise _Refused(f"member {extra[0]!r} is not listed in its header")
        unknown = sorted(set() if wanted is None else wanted - set(listed))
        if unknown:
            raise _Refused(f"it has no signal {unknown[0]!r} "
                           f"(it has: {', '.join(listed) or 'none'})")
        chosen = [name for name in listed if wanted is None or name in wanted]

        # 1. every needed array's .npy header and size, checked before any data is decompressed
        plan = {name: _inspect(archive, members[f"{name}.npy"], name, kinds="f8")
                for name in _CORE}
        for name in chosen:
            plan[_SIGNAL_PREFIX + name] = _inspect(
                archive, members[f"{_SIGNAL_PREFIX}{name}.npy"], f"signal {name!r}", kinds="biuf")
        total = sum(member.nbytes for member in plan.values())
        if total > MAX_TOTAL_BYTES:
            raise _Refused(f"its arrays declare {mebibytes(total)} together, beyond the "
                           f"{mebibytes(MAX_TOTAL_BYTES)} bound")

        # 2. the data, each array read to exactly its declared size
        data = {key: _data(archive, member, key) for key, member in plan.items()}
    core = {name: data[name].astype(float) for name in _CORE}
    signals = {name: data[_SIGNAL_PREFIX + name] for name in chosen}
    problem = _array_problem(core, signals, params.n)
    if problem:
        raise _Refused(problem)
    return cls(t=core["t"], q=core["q"], dq=core["dq"], tau=core["tau"], params=params,
               signals=signals, reason=header["reason"], meta=header["meta"],
               summary=header["summary"], status=header["status"])


def _inspect(archive: zipfile.ZipFile, info: zipfile.ZipInfo, label: str,
             kinds: str) -> _Member:
    """Read one member's .npy header only, refusing what is not of ``kinds`` ("f8", "U", "biuf")."""
    with archive.open(info) as stream:
        shape, fortran, dtype = _npy_header(stream, label)
    dtype = np.dtype(dtype)
    if dtype.hasobject:
        raise _Refused(f"array {label} holds Python objects (pickles are refused)")
    right = (dtype.kind == "f" and dtype.itemsize == 8) if kinds == "f8" else dtype.kind in kinds
    if dtype.names is not None or dtype.subdtype is not None or not right:
        raise _Refused(f"array {label} has dtype {dtype}, expected "
                       + {"f8": "float64", "U": "a string", "biuf": "numbers"}[kinds])
    if not all(isinstance(d, int) and d >= 0 for d in shape):
        raise _Refused(f"array {label} declares the shape {shape}")
    member = _Member(info, tuple(shape), dtype, bool(fortran))
    if member.nbytes > MAX_ARRAY_BYTES:
        raise _Refused(f"array {label} declares {member.shape} ({mebibytes(member.nbytes)}), "
                       f"beyond the {mebibytes(MAX_ARRAY_BYTES)} bound")
    return member


def _npy_header(stream: Any, label: str) -> tuple[Any, bool, Any]:
    """(shape, fortran order, dtype) from a .npy header of format 1.0 or 2.0."""
    version = np.lib.format.read_magic(stream)
    if version not in ((1, 0), (2, 0)):
        raise _Refused(f"array {label} has .npy format {version} (1.0 or 2.0 expected)")
    return (np.lib.format.read_array_header_1_0 if version == (1, 0)
            else np.lib.format.read_array_header_2_0)(stream)


def _data(archive: zipfile.ZipFile, member: _Member, label: str) -> np.ndarray:
    """Read a checked member's data: exactly its declared size, and nothing after it."""
    assert member.dtype is not None
    buffer = bytearray(member.nbytes)
    view = memoryview(buffer)
    with archive.open(member.info) as stream:
        assert isinstance(stream, io.BufferedIOBase)  # a ZipExtFile: it has readinto
        _npy_header(stream, label)
        got = 0
        while got < member.nbytes:
            count = stream.readinto(view[got: got + _CHUNK])
            if not count:
                raise _Refused(f"array {label} is truncated ({got} of {member.nbytes} bytes)")
            got += count
        if stream.read(1):
            raise _Refused(f"array {label} has data beyond its declared shape")
    array = np.frombuffer(buffer, dtype=member.dtype)
    return array.reshape(member.shape, order="F" if member.fortran else "C")


def _parse_header(text: str) -> dict[str, Any]:
    """The JSON header, checked key by key; ``params`` becomes SnakeParams."""
    try:
        header = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise _Refused(f"its header is not JSON ({one_line(str(exc), 80)})") from None
    if not isinstance(header, dict):
        raise _Refused("its header is not a JSON object")
    for key, kind in _HEADER_KEYS.items():
        if key not in header:
            raise _Refused(f"its header has no {key!r}")
        if not isinstance(header[key], kind):
            raise _Refused(f"its header's {key!r} is not a{'n' if kind is dict else ''} "
                           f"{ {dict: 'object', str: 'string', list: 'list'}[kind] }")
    listed = header["signals"]
    if not all(isinstance(s, str) and _SIGNAL_NAME.fullmatch(s) for s in listed) or \
            len(set(listed)) != len(listed):
        raise _Refused("its header's 'signals' is not a list of distinct signal names")
    status, diverged = header.get("status"), header.get("diverged")
    if diverged is not None and not isinstance(diverged, bool):
        raise _Refused("its header's 'diverged' is not true or false")
    if status is None:  # files written before statuses existed
        if diverged is None:
            raise _Refused("its header has no 'status'")
        status = "diverged" if diverged else "completed"
    if not isinstance(status, str) or status not in STATUSES:
        raise _Refused(f"its header's status is not one of {', '.join(STATUSES)}")
    if diverged is not None and diverged != (status in _FAULTS):
        raise _Refused(f"its header says status {status!r} but diverged = {diverged}")
    header["status"] = status
    try:
        header["params"] = SnakeParams.from_dict(header["params"])
    except Exception as exc:  # any rejection by SnakeParams
        raise _Refused(f"its robot parameters are invalid ({one_line(str(exc), 120)})") from None
    return header


def _array_problem(core: Mapping[str, np.ndarray], signals: Mapping[str, np.ndarray],
                   n: int) -> str:
    """What is wrong with a trajectory's arrays for an n-link robot ("" if nothing)."""
    t = core["t"]
    for name in _CORE:
        arr = core[name]
        if arr.dtype.kind not in "fiu" or arr.dtype.names is not None:
            return f"array {name} has dtype {arr.dtype}, expected floats"
    if t.ndim != 1 or len(t) == 0:
        return f"array t has shape {t.shape}, expected at least one sample"
    samples = len(t)
    for name, width in (("q", n + 2), ("dq", n + 2), ("tau", n - 1)):
        if core[name].shape != (samples, width):
            return f"array {name} has shape {core[name].shape}, expected {(samples, width)}"
    for name in _CORE:
        if not np.all(np.isfinite(core[name])):
            return f"array {name} has non-finite entries"
    if samples > 1 and not np.all(np.diff(t) > 0):
        return "its times t are not strictly increasing"
    for name, arr in signals.items():
        if not isinstance(name, str) or not _SIGNAL_NAME.fullmatch(name):
            return f"signal name {reprlib.repr(name)} is not a plain name (letters, digits, _.+-)"
        if arr.dtype.kind not in "biuf" or arr.dtype.names is not None:
            return f"signal {name!r} has dtype {arr.dtype}, expected numbers"
        if arr.ndim not in (1, 2) or arr.shape[0] != samples:
            return f"signal {name!r} has shape {arr.shape}, expected {samples} rows"
    return ""


def _json_default(value: object) -> object:
    """NumPy values and dataclasses as JSON data, NaN kept (the header's encoder)."""
    if isinstance(value, (np.ndarray, np.generic)):
        return value.tolist()
    if is_dataclass(value) and not isinstance(value, type):
        return asdict(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
