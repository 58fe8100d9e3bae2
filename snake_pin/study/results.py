"""A study's output folder and its Parquet dataset of results (one row per run,
:data:`SCHEMA`): :ref:`studies` (The study folder)."""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import stat
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from .._io import atomic_save, atomic_write_bytes, open_regular_file
from .._validation import one_line, printable_path
from .errors import StudyError
from .spec import KEY_FORMAT, SETTINGS, StudySpec

__all__ = ["RUNS", "SCHEMA", "STATUSES"]

#: Folder of the Parquet dataset inside a study folder.
RUNS = "runs"
#: Row statuses.
STATUSES = ("ok", "diverged", "failed")
_KINDS = {"float": pa.float64(), "int": pa.int64(), "str": pa.string(), "joints": pa.string(),
          "bool": pa.bool_()}
#: The columns of every batch file, in order.
SCHEMA = pa.schema(
    [pa.field(name, _KINDS[s.kind]) for name, s in SETTINGS.items()]
    + [pa.field("key", pa.string(), nullable=False), pa.field("index", pa.int64()),
       pa.field("n", pa.int64()), pa.field("body_length", pa.float64()),
       pa.field("robot_params", pa.string()),
       pa.field("status", pa.string(), nullable=False), pa.field("reason", pa.string())]
    + [pa.field(name, pa.float64()) for name in (
        "rms_head_error", "max_head_error", "rms_head_error_pct", "max_head_error_pct",
        "R_min", "R_tilde_min", "D_min", "t_end", "torque_rms", "wall_time")])
#: Columns a batch file may lack (null in its rows): the MPC's settings, which no run of
#: another controller has.
_OPTIONAL = frozenset(name for name, s in SETTINGS.items() if s.controllers == ("mpc",))
_IDENTITY = "study.json"
_FORMAT = 1
#: Largest study.json and batch file read [bytes].
_MAX_IDENTITY_BYTES = 1 << 24
_MAX_BATCH_FILE_BYTES = 1 << 26


def batch_name(keys: Sequence[str]) -> str:
    """The file name of a batch."""
    digest = hashlib.sha256("\n".join(keys).encode("ascii")).hexdigest()
    return f"batch-{digest[:20]}.parquet"


def rows_table(rows: Sequence[dict[str, Any]]) -> pa.Table:
    """Rows as a table of :data:`SCHEMA` (missing columns null, extra keys refused)."""
    names = set(SCHEMA.names)
    for row in rows:
        extra = set(row) - names
        if extra:
            raise StudyError(f"result row has unknown columns: {', '.join(sorted(extra))}")
    return pa.Table.from_pylist(list(rows), schema=SCHEMA)


class StudyFolder:
    """The output folder of one study (see the module docstring)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.runs = self.path / RUNS
        self._lock: int | None = None

    def check(self, spec: StudySpec) -> None:
        """Refuse a folder that cannot hold ``spec`` (creates nothing)."""
        shown = printable_path(self.path)
        if self.path.is_symlink():
            raise StudyError(f"{shown} is a symbolic link; give the folder itself (a study "
                             "writes only inside its own folder)")
        if not self.path.exists():
            return
        if not self.path.is_dir():
            raise StudyError(f"{shown} exists and is not a folder")
        self._check_runs()
        identity = self.path / _IDENTITY
        if not os.path.lexists(identity):
            visible = [e for e in os.listdir(self.path) if not e.startswith(".")]
            if visible:
                raise StudyError(f"{shown} is not empty and holds no study (no {_IDENTITY}); "
                                 "give a new or empty folder")
            return
        stored = self.identity()
        if stored.get("format") != _FORMAT or stored.get("key_format") != KEY_FORMAT:
            raise StudyError(f"{shown} holds a study of another format "
                             f"({_IDENTITY} format {stored.get('format')!r}); use a new folder")
        if stored.get("study_hash") != spec.study_hash:
            raise StudyError(f"{shown} holds a different study ({stored.get('name')!r}, hash "
                             f"{str(stored.get('study_hash'))[:12]}; this one "
                             f"{spec.study_hash[:12]}); use another folder")

    def _check_runs(self) -> None:
        """Refuse a ``runs`` that is a symbolic link or not a folder."""
        if self.runs.is_symlink():
            raise StudyError(f"{printable_path(self.runs)} is a symbolic link; a study writes only "
                             "inside its own folder (remove the link)")
        if self.runs.exists() and not self.runs.is_dir():
            raise StudyError(f"{printable_path(self.runs)} exists and is not a folder")

    def identity(self) -> dict[str, Any]:
        """The stored ``study.json``."""
        file = self.path / _IDENTITY
        shown = printable_path(file)

        def refuse(problem: str) -> StudyError:
            return StudyError(f"{shown} is not a readable study identity: {one_line(problem)}")

        try:  # a link is refused by the open itself
            with open_regular_file(file, limit=_MAX_IDENTITY_BYTES, kind="study identity",
                                   error=refuse, follow_symlinks=False) as handle:
                data = json.loads(handle.read(_MAX_IDENTITY_BYTES))
        except StudyError:
            raise
        except (OSError, ValueError) as exc:
            raise refuse(str(exc)) from None
        if not isinstance(data, dict):
            raise StudyError(f"{printable_path(file)} is not a readable study identity")
        return data

    def done_keys(self) -> set[str]:
        """Keys of the runs already recorded (every batch file's ``key`` column)."""
        keys: set[str] = set()
        for file in self.batch_files():
            keys.update(_read_batch(file, ["key"]).column("key").to_pylist())
        return keys

    def batch_files(self) -> list[Path]:
        """The batch files, sorted by name (hidden temporaries excluded)."""
        self._check_runs()
        if not self.runs.is_dir():
            return []
        files = []
        for entry in os.scandir(self.runs):
            if not entry.name.endswith(".parquet") or entry.name.startswith("."):
                continue
            if not entry.is_file(follow_symlinks=False):
                raise StudyError(f"{printable_path(entry.path)} is not a regular file (a link, "
                                 "folder or device); remove it to run its runs again")
            files.append(Path(entry.path))
        return sorted(files)

    def prepare(self, spec: StudySpec) -> None:
        """Create the folder, take its lock, check it again, write ``study.json`` (if new) and
        try writing (a probe file in the folder and in ``runs/``), before any run."""
        shown = printable_path(self.path)
        self.check(spec)
        _mkdir(self.path, parents=True)
        try:
            fd = os.open(self.path / ".lock", os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW
                         | os.O_NONBLOCK, 0o666)
        except OSError as exc:
            raise StudyError(f"{printable_path(self.path / '.lock')}: cannot open the study's lock "
                             f"({exc.strerror or exc}; a symbolic link is refused)") from None
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise StudyError(f"{printable_path(self.path / '.lock')} is not a regular file")
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise StudyError(f"{shown}: another study run is writing to this folder") from None
        except BaseException:
            os.close(fd)
            raise
        self._lock = fd
        try:
            self.check(spec)  # again, under the lock: another run may have started here
            _probe_writable(self.path)
            identity = self.path / _IDENTITY
            if not identity.exists():
                text = json.dumps({"format": _FORMAT, **spec.to_dict()}, indent=2,
                                  allow_nan=False)
                try:
                    atomic_write_bytes(identity, (text + "\n").encode())
                except OSError as exc:
                    raise StudyError(f"{printable_path(identity)}: cannot write "
                                     f"({exc.strerror or exc})") from None
            _mkdir(self.runs)
            self._check_runs()
            _probe_writable(self.runs)
        except BaseException:
            self.release()
            raise

    def release(self) -> None:
        """Drop the folder's lock (idempotent)."""
        if self._lock is not None:
            with contextlib.suppress(OSError):
                fcntl.flock(self._lock, fcntl.LOCK_UN)
            os.close(self._lock)
            self._lock = None

    @contextlib.contextmanager
    def locked(self, spec: StudySpec) -> Iterator[StudyFolder]:
        """:meth:`prepare` on entry, :meth:`release` on exit."""
        self.prepare(spec)
        try:
            yield self
        finally:
            self.release()

    def write_batch(self, keys: Sequence[str], rows: Sequence[dict[str, Any]]) -> Path:
        """Write one batch's rows as ``runs/batch-<id>.parquet``, whole or not at all."""
        table = rows_table(rows)
        self._check_runs()
        path = self.runs / batch_name(keys)
        atomic_save(path, lambda handle: pq.write_table(table, handle))
        return path

    def read_table(self, columns: Sequence[str] | None = None) -> pa.Table:
        """Every recorded row (an empty table of :data:`SCHEMA` if none)."""
        names = list(columns) if columns is not None else list(SCHEMA.names)
        files = self.batch_files()
        if not files:
            return SCHEMA.empty_table().select(names)
        return pa.concat_tables([_read_batch(f, names) for f in files])


def _read_batch(file: Path, columns: Sequence[str]) -> pa.Table:
    """``columns`` of one batch file, checked (see :meth:`StudyFolder.read_table`)."""
    def refuse(problem: str) -> StudyError:
        return StudyError(f"{printable_path(file)} is not a usable batch file ({problem}); remove "
                          "it to run its runs again")

    try:
        with open_regular_file(file, limit=_MAX_BATCH_FILE_BYTES, kind="Parquet batch file",
                               error=refuse, follow_symlinks=False) as handle:
            parquet = pq.ParquetFile(handle)
            schema = parquet.schema_arrow
            absent = [n for n in SCHEMA.names if n not in schema.names]
            missing = [n for n in absent if n not in _OPTIONAL]
            if missing:
                shown = ", ".join(missing[:4]) + (", ..." if len(missing) > 4 else "")
                raise refuse(f"{len(missing)} columns missing: {shown}")
            for name in (n for n in SCHEMA.names if n not in absent):
                found, expected = schema.field(name).type, SCHEMA.field(name).type
                if not _compatible(found, expected):
                    raise refuse(f"column {name} is {found}, not {expected}")
            wanted = list(dict.fromkeys([*columns, "key", "status"]))
            table = parquet.read(columns=[n for n in wanted if n not in absent])
            for name in (n for n in wanted if n in absent):
                table = table.append_column(SCHEMA.field(name),
                                            pa.nulls(table.num_rows, SCHEMA.field(name).type))
    except StudyError:
        raise
    except (OSError, ValueError, pa.ArrowException) as exc:
        raise refuse(one_line(str(exc)) or type(exc).__name__) from None
    if table.column("key").null_count:
        raise refuse("a row has no key")
    if table.column("status").null_count:
        raise refuse("a row has no status")
    try:
        table = table.select(wanted).cast(pa.schema([SCHEMA.field(n) for n in wanted]))
    except (ValueError, pa.ArrowException) as exc:
        raise refuse(one_line(str(exc))) from None
    if not pc.all(pc.is_in(table.column("status"), value_set=pa.array(STATUSES))).as_py():
        raise refuse(f"a row's status is not one of {', '.join(STATUSES)}")
    return table.select(list(columns))


def _compatible(found: pa.DataType, expected: pa.DataType) -> bool:
    """Whether a column of type ``found`` reads as ``expected`` without reinterpretation."""
    if found == expected or pa.types.is_null(found):
        return True
    if pa.types.is_string(expected):
        return pa.types.is_string(found) or pa.types.is_large_string(found)
    if pa.types.is_integer(expected):
        return pa.types.is_integer(found)
    if pa.types.is_floating(expected):
        return pa.types.is_floating(found) or pa.types.is_integer(found)
    return False


def _probe_writable(folder: Path) -> None:
    """Write, sync and remove a hidden probe file in ``folder``, or raise a StudyError."""
    try:
        fd, name = tempfile.mkstemp(dir=folder, prefix=".write-probe-", suffix=".tmp")
        try:
            os.write(fd, b"snake-pin")
            os.fsync(fd)
        finally:
            os.close(fd)
            with contextlib.suppress(OSError):
                os.unlink(name)
    except OSError as exc:
        raise StudyError(f"{printable_path(folder)}: cannot write here ({exc.strerror or exc})") \
            from None


def _mkdir(folder: Path, parents: bool = False) -> None:
    """Create ``folder`` (it may exist), or raise a StudyError."""
    try:
        folder.mkdir(parents=parents, exist_ok=True)
    except OSError as exc:
        raise StudyError(f"{printable_path(folder)}: cannot create the folder "
                         f"({exc.strerror or exc})") from None
