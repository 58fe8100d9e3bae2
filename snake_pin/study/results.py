"""A study's output folder and its Parquet dataset of results (one row per run).

Layout of ``DIR``::

    DIR/study.json               the normalised study and its hash (the folder's identity)
    DIR/runs/batch-<id>.parquet  one file per finished batch, written whole (temp + rename)
    DIR/summary.json             StudySummary.to_dict() of the last invocation
    DIR/index.html               the page (figures embedded)
    DIR/.lock                    held while a study writes here

``pandas.read_parquet(DIR / "runs")`` (or ``pyarrow.parquet.read_table``, or polars) opens
the results directly: every batch file has the schema :data:`SCHEMA` (columns: every
setting of :data:`snake_pin.study.spec.SETTINGS`, null where it does not apply, then the
identity, status and metric columns of :mod:`snake_pin.study.work`). Temporary files
are hidden (``.name...tmp``), and Parquet readers skip hidden files.

A folder belongs to one study: :meth:`StudyFolder.check` refuses a folder whose
``study.json`` holds another study hash, or a non-empty folder that is not a study folder.
Finished runs are found by their keys (:meth:`StudyFolder.done_keys`), so re-running a
study runs only the missing ones, whatever batches the earlier runs were grouped in.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from .._io import atomic_save, atomic_write_bytes
from .errors import StudyError
from .spec import KEY_FORMAT, SETTINGS, StudySpec

__all__ = ["RUNS", "SCHEMA", "STATUSES", "StudyFolder", "batch_name", "rows_table"]

#: Folder of the Parquet dataset inside a study folder.
RUNS = "runs"
#: Row statuses.
STATUSES = ("ok", "diverged", "failed")
_KINDS = {"float": pa.float64(), "int": pa.int64(), "str": pa.string(), "joints": pa.string()}
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
_IDENTITY = "study.json"
_FORMAT = 1


def batch_name(keys: Sequence[str]) -> str:
    """The file name of a batch.

    Parameters
    ----------
    keys
        The run keys of the batch, in order.

    Returns
    -------
    str
        ``batch-<first 20 hex of sha256 of its keys>.parquet``.
    """
    digest = hashlib.sha256("\n".join(keys).encode("ascii")).hexdigest()
    return f"batch-{digest[:20]}.parquet"


def rows_table(rows: Sequence[dict[str, Any]]) -> pa.Table:
    """Rows as a table of :data:`SCHEMA` (missing columns null, extra keys refused).

    Parameters
    ----------
    rows
        Result rows (dicts keyed by column).

    Returns
    -------
    pyarrow.Table
        One row per dict, in order.

    Raises
    ------
    StudyError
        A row has a key that is not a column of :data:`SCHEMA`.
    """
    names = set(SCHEMA.names)
    for row in rows:
        extra = set(row) - names
        if extra:
            raise StudyError(f"result row has unknown columns: {', '.join(sorted(extra))}")
    return pa.Table.from_pylist(list(rows), schema=SCHEMA)


class StudyFolder:
    """The output folder of one study (see the module docstring).

    Parameters
    ----------
    path
        ``DIR``; nothing is created until :meth:`prepare`.
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.runs = self.path / RUNS
        self._lock: int | None = None

    # ------------------------------------------------------------ checking
    def check(self, spec: StudySpec) -> None:
        """Refuse a folder that cannot hold ``spec`` (creates nothing).

        Parameters
        ----------
        spec
            The study to be run here.

        Raises
        ------
        StudyError
            ``DIR`` is a file; holds another study (its study.json hash differs); is not
            empty and not a study folder; or its study.json is unreadable.
        """
        shown = _shown(self.path)
        if not self.path.exists():
            if self.path.is_symlink():
                raise StudyError(f"{shown}: a broken symbolic link, not a folder")
            return
        if not self.path.is_dir():
            raise StudyError(f"{shown} exists and is not a folder")
        identity = self.path / _IDENTITY
        if not identity.exists():
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

    def identity(self) -> dict[str, Any]:
        """The stored ``study.json``.

        Returns
        -------
        dict
            Its content.

        Raises
        ------
        StudyError
            The file is unreadable or not a JSON object.
        """
        file = self.path / _IDENTITY
        try:
            with open(file, "rb") as handle:
                data = json.loads(handle.read(1 << 24))
        except (OSError, ValueError) as exc:
            raise StudyError(f"{_shown(file)} is not a readable study identity: "
                             f"{_one_line(str(exc))}") from None
        if not isinstance(data, dict):
            raise StudyError(f"{_shown(file)} is not a readable study identity")
        return data

    def done_keys(self) -> set[str]:
        """Keys of the runs already recorded (every batch file's ``key`` column).

        Returns
        -------
        set of str
            The keys.

        Raises
        ------
        StudyError
            A batch file that Parquet cannot read (name it; remove it to re-run its runs).
        """
        keys: set[str] = set()
        for file in self.batch_files():
            try:
                column = pq.read_table(file, columns=["key"]).column("key")
            except (OSError, pa.ArrowException, KeyError) as exc:
                raise StudyError(f"{_shown(file)} is not a readable batch file "
                                 f"({_one_line(str(exc))}); remove it to run its runs "
                                 "again") from None
            keys.update(column.to_pylist())
        return keys

    def batch_files(self) -> list[Path]:
        """The batch files, sorted by name (hidden temporaries excluded).

        Returns
        -------
        list of Path
            The files of ``runs/``.
        """
        if not self.runs.is_dir():
            return []
        return sorted(p for p in self.runs.iterdir()
                      if p.suffix == ".parquet" and not p.name.startswith(".") and p.is_file())

    # ------------------------------------------------------------- writing
    def prepare(self, spec: StudySpec) -> None:
        """Create the folder, take its lock, check it again and write ``study.json`` (if new).

        Parameters
        ----------
        spec
            The study to be run here.

        Raises
        ------
        StudyError
            Another process holds the folder's lock (a study is running there), or
            :meth:`check` fails under the lock.
        """
        self.path.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path / ".lock", os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise StudyError(f"{_shown(self.path)}: another study run is writing to this "
                             "folder") from None
        self._lock = fd
        try:
            self.check(spec)  # again, under the lock: another run may have started here
            if not (self.path / _IDENTITY).exists():
                payload = {"format": _FORMAT, **spec.to_dict()}
                atomic_write_bytes(self.path / _IDENTITY, (json.dumps(
                    payload, indent=2, allow_nan=False) + "\n").encode())
            self.runs.mkdir(exist_ok=True)
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
        """:meth:`prepare` on entry, :meth:`release` on exit.

        Parameters
        ----------
        spec
            The study to be run here.

        Yields
        ------
        StudyFolder
            This folder, locked.
        """
        self.prepare(spec)
        try:
            yield self
        finally:
            self.release()

    def write_batch(self, keys: Sequence[str], rows: Sequence[dict[str, Any]]) -> Path:
        """Write one batch's rows as ``runs/batch-<id>.parquet``, whole or not at all.

        Parameters
        ----------
        keys
            The batch's run keys (they name the file).
        rows
            Its result rows.

        Returns
        -------
        Path
            The file written.
        """
        table = rows_table(rows)
        path = self.runs / batch_name(keys)
        atomic_save(path, lambda handle: pq.write_table(table, handle))
        return path

    def read_table(self, columns: Sequence[str] | None = None) -> pa.Table:
        """Every recorded row (an empty table of :data:`SCHEMA` if none).

        Parameters
        ----------
        columns
            Only these columns (None: all).

        Returns
        -------
        pyarrow.Table
            The rows of every batch file.
        """
        files = self.batch_files()
        if not files:
            return SCHEMA.empty_table() if columns is None else \
                SCHEMA.empty_table().select(list(columns))
        tables = [pq.read_table(f, columns=list(columns) if columns else None,
                                schema=SCHEMA) for f in files]
        return pa.concat_tables(tables)


def _shown(path: object) -> str:
    text = os.fspath(path) if isinstance(path, os.PathLike) else str(path)
    return text if text.isprintable() else repr(text)


def _one_line(text: str, limit: int = 200) -> str:
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."
