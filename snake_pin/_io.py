"""Files in and out: whole-or-absent writes, and bounded reads that never block.

Every file snake_pin writes goes through this module, and every file it reads is opened
by :func:`open_regular_file` (or :func:`read_regular_file`). What it promises:

- **Whole or absent.** A file is written to a temporary sibling in the same folder, flushed
  and ``fsync``-ed, then renamed onto its name (``os.replace``, atomic on POSIX), and the
  folder is ``fsync``-ed so the rename itself is durable. A reader sees the old file or
  the new one, never a part.
- **Permissions from the umask.** ``tempfile.mkstemp`` creates 0600 files and a rename
  keeps the mode, so the temporary file is set to ``0o666 & ~umask`` before the rename
  (0644 under umask 022, 0600 under 077), as ``open(path, "w")`` would create it. The umask
  is read at each write from ``/proc/self/status`` (Linux >= 4.7), which changes nothing;
  elsewhere it is read by setting it to 077 and back under a lock, so another thread
  creating a file in between gets a private file, never a world-writable one.
- **No temporary survives a kill.** Temporary names are
  ``.NAME.snake_pin-PID-XXXXXXXX.tmp``: a hidden file carrying the writer's pid. They are
  removed on any exception (KeyboardInterrupt included); after a ``kill -9`` they stay
  until the next write in the same folder, which calls :func:`clean_stale_temporaries`
  and removes those whose writer is no longer alive.
- **Sets of files.** :func:`atomic_group` stages several files and renames them into place
  only when its block succeeds: data files first, then figures, each kind in the order
  written. See :func:`atomic_group` for exactly what a reader can see meanwhile.
- **Reads are bounded and never hang.** :func:`open_regular_file` refuses anything but a
  regular file (a FIFO, socket, device or folder) before reading a byte: the name is
  stat-ed first, then opened with ``O_NONBLOCK`` and the descriptor fstat-ed again (the
  name may have changed in between), so a FIFO never blocks the reader. A file larger
  than the caller's bound is refused from its size, before it is read. A caller that must
  not follow a symbolic link (``follow_symlinks=False``) gets the link refused by the
  open itself (``O_NOFOLLOW``), not by a check that a rename could race.
- **TOML is bounded before it is parsed.** :func:`parse_toml` scans the text for nesting
  (arrays, inline tables and dotted keys inside each other, at most
  :data:`MAX_TOML_DEPTH` levels) before :mod:`tomllib` sees it: tomllib recurses once per
  nested array or inline table, and its time and memory grow with the square of a dotted
  key's length.

Errors of writes are ``OSError`` naming the file the caller asked for, never a temporary
name. Errors of reads are built by the caller's ``error`` function from one line that
does not name the file (the caller prefixes it), so each loader raises its own
:class:`~snake_pin.exceptions.SnakePinError` subclass.
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
import re
import stat
import tempfile
import threading
import tomllib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, NoReturn

from .exceptions import ParameterError

__all__ = [
    "MAX_TOML_DEPTH",
    "TEMP_MARKER",
    "AtomicGroup",
    "atomic_group",
    "atomic_save",
    "atomic_write_bytes",
    "atomic_writer",
    "clean_stale_temporaries",
    "current_umask",
    "decode_utf8",
    "open_regular_file",
    "parse_toml",
    "read_regular_file",
    "toml_nesting_problem",
]

#: The marker every temporary name carries: ``.NAME.snake_pin-PID-XXXXXXXX.tmp``.
TEMP_MARKER = ".snake_pin-"
_TEMP_NAME = re.compile(r"\..*\.snake_pin-(\d+)-\w+\.tmp", re.DOTALL)
#: Characters of the target's name kept in a temporary name (NAME_MAX is 255 bytes).
_NAME_KEPT = 64
_UMASK_LOCK = threading.Lock()
#: Deepest nesting a TOML file snake_pin reads may have: arrays and inline tables inside
#: each other, each adding one level plus the dots of the key it is the value of; a key's
#: own dots count too (``a.b.c = 1`` nests two tables: 2 levels). snake_pin's files need 3.
MAX_TOML_DEPTH = 32


def current_umask() -> int:
    """Return the process's umask, read without a window in which files get a wider mode.

    Linux reports it in ``/proc/self/status``; elsewhere it is swapped with 077 and back
    under a lock (a file another thread creates in that instant is private, not wider).

    Returns
    -------
    int
        The umask (e.g. ``0o022``).
    """
    try:
        with open("/proc/self/status", "rb") as status:
            for line in status:
                if line.startswith(b"Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    with _UMASK_LOCK:
        mask = os.umask(0o077)
        os.umask(mask)
    return mask


def _pid_alive(pid: int) -> bool:
    """Whether ``pid`` is a live (not zombie) process of this machine."""
    if pid <= 0:
        return True  # never ours to judge: 0 and negative pids address process groups
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # exists, owned by someone else
    except (OverflowError, OSError):
        return False  # beyond any pid the kernel hands out
    try:
        with open(f"/proc/{pid}/stat", "rb") as proc:
            state = proc.read().rsplit(b")", 1)[1].split()[0]
        return state not in (b"Z", b"X")
    except (OSError, IndexError):
        return True


def clean_stale_temporaries(folder: str | os.PathLike[str]) -> list[Path]:
    """Remove this module's temporary files in ``folder`` whose writer is no longer alive.

    Only names of the form ``.NAME.snake_pin-PID-XXXXXXXX.tmp`` that are regular files are
    considered, and only when process PID is gone (or a zombie). A pid the kernel has
    since reused keeps its file until that process ends. Errors (a folder that cannot be
    listed, a file already removed) are ignored: cleaning is best effort and cheap.

    Parameters
    ----------
    folder : str or os.PathLike
        The folder to clean (not recursively).

    Returns
    -------
    list of Path
        The files removed.
    """
    removed: list[Path] = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        match = _TEMP_NAME.fullmatch(entry.name)
        if match is None:
            continue
        try:
            if not entry.is_file(follow_symlinks=False) or _pid_alive(int(match.group(1))):
                continue
            os.unlink(entry.path)
            removed.append(Path(entry.path))
        except OSError:
            continue
    return removed


def _fsync_directory(folder: Path) -> None:
    """Make a rename in ``folder`` durable (filesystems that cannot sync folders are skipped)."""
    fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    try:
        os.fsync(fd)
    except OSError as exc:
        if exc.errno not in (errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EBADF):
            raise
    finally:
        os.close(fd)


def _reraise(exc: OSError, target: Path) -> NoReturn:
    """Raise ``exc`` again naming ``target`` (what the caller asked for), not a temporary."""
    if exc.errno is None:
        raise OSError(f"{target}: {exc}") from exc
    raise OSError(exc.errno, exc.strerror, str(target)) from exc


@dataclass
class _Staged:
    target: Path
    temp: Path
    figure: bool


class AtomicGroup:
    """Files staged by :func:`atomic_group`; use its methods inside the ``with`` block.

    Parameters
    ----------
    folder : str or os.PathLike
        Where the files go; names given to the methods are relative to it.
    """

    def __init__(self, folder: str | os.PathLike[str]) -> None:
        self.folder = Path(folder)
        self._staged: list[_Staged] = []
        self._cleaned: set[Path] = set()
        self._umask = current_umask()

    # ----------------------------------------------------------------- staging
    @property
    def targets(self) -> list[Path]:
        """The files staged so far, in the order they will be renamed into place."""
        return [s.target for s in self._order()]

    @contextlib.contextmanager
    def open(self, name: str | os.PathLike[str], *, figure: bool = False) -> Iterator[IO[bytes]]:
        """Stage ``name``: a binary handle on its temporary file.

        If the body raises, that temporary is removed at once (the group can go on).

        Parameters
        ----------
        name : str or os.PathLike
            File name relative to the group's folder (its folder must exist).
        figure : bool, optional
            Put the file among the figures, renamed after every data file.

        Yields
        ------
        IO[bytes]
            The temporary file, open for writing; flushed, given the umask's mode and
            fsync-ed when the body ends.

        Raises
        ------
        ParameterError
            If ``name`` is already staged in this group.
        OSError
            If the temporary file cannot be created or written (naming ``name``).
        """
        target = self.folder / name
        if any(s.target == target for s in self._staged):
            raise ParameterError(f"{target} is written twice in one group")
        parent = target.parent
        if parent not in self._cleaned:
            clean_stale_temporaries(parent)
            self._cleaned.add(parent)
        try:
            fd, temp = tempfile.mkstemp(
                dir=parent, prefix=f".{target.name[:_NAME_KEPT]}{TEMP_MARKER}{os.getpid()}-",
                suffix=".tmp")
        except OSError as exc:
            _reraise(exc, target)
        staged = _Staged(target, Path(temp), bool(figure))
        self._staged.append(staged)
        try:
            with os.fdopen(fd, "wb") as handle:
                yield handle
                try:
                    handle.flush()
                    os.fchmod(handle.fileno(), 0o666 & ~self._umask)
                    os.fsync(handle.fileno())
                except OSError as exc:
                    _reraise(exc, target)
        except BaseException as exc:
            self._staged.remove(staged)
            _unlink_quietly(staged.temp)
            if isinstance(exc, OSError) and exc.filename in (temp, staged.temp):
                _reraise(exc, target)
            raise

    def write_bytes(self, name: str | os.PathLike[str], data: bytes, *,
                    figure: bool = False) -> Path:
        """Stage ``data`` as ``name``.

        Parameters
        ----------
        name : str or os.PathLike
            File name relative to the group's folder (its folder must exist).
        data : bytes
            The file's content.
        figure : bool, optional
            Put the file among the figures, renamed after every data file.

        Returns
        -------
        pathlib.Path
            The final path (the file appears there when the group commits).

        Raises
        ------
        ParameterError
            If ``name`` is already staged in this group.
        OSError
            If the temporary file cannot be created or written (naming ``name``).
        """
        with self.open(name, figure=figure) as handle:
            handle.write(data)
        return self.folder / name

    def save(self, name: str | os.PathLike[str], save: Callable[[IO[bytes]], object], *,
             figure: bool = False) -> Path:
        """Stage ``name`` written by ``save(handle)``.

        Parameters
        ----------
        name : str or os.PathLike
            File name relative to the group's folder (its folder must exist).
        save : callable
            Called with the binary handle, e.g. ``lambda f: np.savez(f, t=t)``.
        figure : bool, optional
            Put the file among the figures, renamed after every data file.

        Returns
        -------
        pathlib.Path
            The final path (the file appears there when the group commits).

        Raises
        ------
        ParameterError
            If ``name`` is already staged in this group.
        OSError
            If the temporary file cannot be created or written (naming ``name``).
        """
        with self.open(name, figure=figure) as handle:
            save(handle)
        return self.folder / name

    # ------------------------------------------------------------ commit/abort
    def _order(self) -> list[_Staged]:
        return ([s for s in self._staged if not s.figure]
                + [s for s in self._staged if s.figure])

    def _commit(self) -> None:
        """Rename every staged file into place (data, then figures), then sync the folders."""
        folders: list[Path] = []
        for staged in self._order():
            try:
                os.replace(staged.temp, staged.target)
            except OSError as exc:
                _reraise(exc, staged.target)
            self._staged.remove(staged)
            if staged.target.parent not in folders:
                folders.append(staged.target.parent)
        for folder in folders:
            try:
                _fsync_directory(folder)
            except OSError as exc:
                _reraise(exc, folder)

    def _discard(self) -> None:
        """Remove every temporary still staged."""
        while self._staged:
            _unlink_quietly(self._staged.pop().temp)


def _unlink_quietly(path: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)


@contextlib.contextmanager
def atomic_group(folder: str | os.PathLike[str]) -> Iterator[AtomicGroup]:
    """Write a set of files that appear together, data before figures.

    Inside the block, stage files with :meth:`AtomicGroup.open`, :meth:`~AtomicGroup.save`
    or :meth:`~AtomicGroup.write_bytes` (``figure=True`` for figures). Each is written to
    a temporary sibling and fsync-ed; nothing is renamed while the block runs. When the
    block succeeds, the data files are renamed into place in the order they were staged,
    then the figures in theirs, then each folder is fsync-ed. If the block raises
    anything (KeyboardInterrupt included), every temporary is removed and no file of the
    set changes.

    What a reader can see: POSIX renames are atomic one by one, not as a set. While the
    block runs, and if it fails, the old files only. During the renames (microseconds,
    or forever if the process is killed in the middle), the new files form a prefix of
    that order: every file listed before a new one is new, so a new figure implies new
    data, while later files may still be old. After the block, all are new, and durable
    (on a power loss before that, which renames reached the disk is up to the
    filesystem). A rename that fails (OSError naming the file) stops there: the files
    before it are in place, the remaining temporaries are removed.

    Parameters
    ----------
    folder : str or os.PathLike
        Where the files go (an existing folder).

    Yields
    ------
    AtomicGroup
        Stage files on it inside the block.

    Raises
    ------
    OSError
        If a file cannot be staged or renamed into place (naming that file).

    Examples
    --------
    >>> with atomic_group(folder) as group:                    # doctest: +SKIP
    ...     group.save("run.npz", lambda f: np.savez(f, t=t))
    ...     group.write_bytes("run.png", png, figure=True)
    """
    group = AtomicGroup(folder)
    try:
        yield group
        group._commit()
    finally:
        group._discard()


@contextlib.contextmanager
def atomic_writer(path: str | os.PathLike[str]) -> Iterator[IO[bytes]]:
    """Open a temporary file beside ``path``; on success rename it onto ``path``.

    If the body raises, the temporary file is removed and ``path`` is untouched.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write (its folder must exist).

    Yields
    ------
    IO[bytes]
        The temporary file, open for writing.

    Raises
    ------
    OSError
        If the file cannot be written or renamed (naming ``path``).
    """
    path = Path(path)
    with atomic_group(path.parent) as group, group.open(path.name) as handle:
        yield handle


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` whole or not at all.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write (its folder must exist).
    data : bytes
        Its content.

    Raises
    ------
    OSError
        If the file cannot be written (naming ``path``).
    """
    with atomic_writer(path) as handle:
        handle.write(data)


def atomic_save(path: str | os.PathLike[str], save: Callable[[IO[bytes]], object]) -> None:
    """Call ``save(handle)`` on a temporary file and move it onto ``path`` when it succeeds.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write (its folder must exist).
    save : callable
        Called with a binary handle, e.g. ``lambda f: np.savez(f, t=t)``.

    Raises
    ------
    OSError
        If the file cannot be written (naming ``path``).
    """
    with atomic_writer(path) as handle:
        save(handle)


# --------------------------------------------------------------------------- reading
_FILE_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO"),
               (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
               (stat.S_ISBLK, "a block device"))


def _not_regular(mode: int) -> str:
    """What a non-regular file is, in words."""
    return next((name for test, name in _FILE_KINDS if test(mode)), "not a regular file")


def _refusal(exc: OSError | ValueError, kind: str) -> str:
    """One line for an error of the operating system while opening or reading."""
    if isinstance(exc, FileNotFoundError):
        return f"no such {kind}"
    if isinstance(exc, IsADirectoryError):
        return f"is a folder, not a {kind}"
    reason = (exc.strerror if isinstance(exc, OSError) else None) or str(exc)
    return f"cannot read it ({reason})"


def open_regular_file(path: str | os.PathLike[str], *, limit: int, kind: str,
                      error: Callable[[str], Exception],
                      follow_symlinks: bool = True) -> io.BufferedReader:
    """Open ``path`` for binary reading if it is a regular file of at most ``limit`` bytes.

    Never blocks and never reads a byte of anything else: the name is stat-ed and refused
    unless it is a regular file; it is then opened with ``O_NONBLOCK`` (so a FIFO put in
    its place meanwhile does not block either) and the open descriptor is fstat-ed and
    checked again, size included.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    limit : int
        Largest size accepted [bytes].
    kind : str
        What the file should be, for messages (``"robot file"``, ``"URDF"``, ...).
    error : callable
        Builds the exception to raise from one line that does not name the file, e.g.
        ``"is a FIFO, not a regular file: not a URDF"``; the caller prefixes the name.
    follow_symlinks : bool, optional
        True (default): a symbolic link is followed to its target. False: a name that is
        a symbolic link is refused, and the file is opened with ``O_NOFOLLOW``, so a link
        put in its place after the check is refused by the open itself (no window between
        check and open). Only the name's last component is concerned: the folders on the
        way are followed either way.

    Returns
    -------
    io.BufferedReader
        The open file (blocking mode), positioned at its start; close it (``with``).

    Raises
    ------
    Exception
        ``error(message)``: no such file, a folder, a FIFO/socket/device, a symbolic link
        (with ``follow_symlinks=False``), larger than ``limit``, unreadable (permissions,
        ...), or ``path`` is not a path.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise error(f"not a file path: {type(path).__name__}")
    link = f"is a symbolic link (not followed), not a regular file: not a {kind}"
    try:
        mode = os.stat(path, follow_symlinks=follow_symlinks).st_mode
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the name
        raise error(_refusal(exc, kind)) from None
    if stat.S_ISLNK(mode):
        raise error(link)
    if stat.S_ISDIR(mode):
        raise error(f"is a folder, not a {kind}")
    if not stat.S_ISREG(mode):
        raise error(f"is {_not_regular(mode)}, not a regular file: not a {kind}")
    flags = (os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0)
             | getattr(os, "O_CLOEXEC", 0))
    if not follow_symlinks:
        flags |= os.O_NOFOLLOW
    try:
        fd = os.open(path, flags)
    except (OSError, ValueError) as exc:
        if not follow_symlinks and isinstance(exc, OSError) and \
                exc.errno in (errno.ELOOP, errno.EMLINK):  # EMLINK: the BSDs' word for it
            raise error(link) from None
        raise error(_refusal(exc, kind)) from None
    try:
        info = os.fstat(fd)
    except OSError as exc:
        os.close(fd)
        raise error(_refusal(exc, kind)) from None
    problem = ""
    if not stat.S_ISREG(info.st_mode):
        problem = f"is {_not_regular(info.st_mode)}, not a regular file: not a {kind}"
    elif info.st_size > limit:
        problem = f"is larger than {limit} bytes ({info.st_size} bytes): not a {kind}"
    if problem:
        os.close(fd)
        raise error(problem)
    try:
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException as exc:
        os.close(fd)
        if isinstance(exc, OSError):
            raise error(_refusal(exc, kind)) from None
        raise


def read_regular_file(path: str | os.PathLike[str], *, limit: int, kind: str,
                      error: Callable[[str], Exception],
                      follow_symlinks: bool = True) -> bytes:
    """The bytes of ``path``, opened by :func:`open_regular_file` (at most ``limit``).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    limit : int
        Largest size accepted [bytes] (checked on its size, and again on what is read,
        in case it grew meanwhile).
    kind : str
        What the file should be, for messages.
    error : callable
        Builds the exception to raise from one line (see :func:`open_regular_file`).
    follow_symlinks : bool, optional
        False refuses a symbolic link, atomically (see :func:`open_regular_file`).

    Returns
    -------
    bytes
        The content.

    Raises
    ------
    Exception
        ``error(message)``, as :func:`open_regular_file`, or when reading fails.
    """
    with open_regular_file(path, limit=limit, kind=kind, error=error,
                           follow_symlinks=follow_symlinks) as handle:
        try:
            data = handle.read(limit + 1)
        except OSError as exc:
            raise error(_refusal(exc, kind)) from None
    if len(data) > limit:
        raise error(f"is larger than {limit} bytes: not a {kind}")
    return data


def decode_utf8(data: bytes, *, error: Callable[[str], Exception]) -> str:
    """``data`` decoded as UTF-8, or ``error("not UTF-8 text (... at byte N)")``.

    Parameters
    ----------
    data : bytes
        A file's content.
    error : callable
        Builds the exception to raise from one line.

    Returns
    -------
    str
        The text.

    Raises
    ------
    Exception
        ``error(message)`` when ``data`` is not UTF-8.
    """
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None


# Strings (multi-line ones may end in up to two more quotes), comments, and a quote that
# starts no complete string (tomllib stops with an error at that string: so does the scan).
_TOML_SKIPPED = re.compile(
    r'"""(?:[^"\\]|\\.|"(?!""))*"""(?:"{1,2})?'
    r"|'''(?:[^']|'(?!''))*'''(?:'{1,2})?"
    r'|"(?:[^"\\\n]|\\[^\n])*"'
    r"|'[^'\n]*'"
    r"|#[^\n]*"
    r"|(?P<stop>[\"'])",
    re.DOTALL)
# Everything but what counts: brackets, dots and separators.
_TOML_IGNORED = re.compile(r"[^\[\]{}.,\n]+")


def toml_nesting_problem(text: str, max_depth: int = MAX_TOML_DEPTH) -> str | None:
    """Why ``text`` nests deeper than ``max_depth`` levels, or None; one linear scan.

    Levels are those :data:`MAX_TOML_DEPTH` describes: an array or inline table adds one
    plus the dots of its key; a dotted key adds its dots. Strings and comments are
    skipped; nothing is parsed. The count may exceed the document's depth by one (the dot
    of a float value) and may fall short of it by the dots of a table header, which are
    bounded on their own.

    Parameters
    ----------
    text : str
        TOML text.
    max_depth : int, optional
        The deepest nesting accepted.

    Returns
    -------
    str or None
        ``"nested deeper than N levels (...) at line L"``, or None within the bound.
    """
    pieces: list[str] = []
    end = 0
    for match in _TOML_SKIPPED.finditer(text):
        pieces.append(text[end:match.start()])
        end = len(text)
        if match.lastgroup == "stop":
            break
        pieces.append("\n" * match.group().count("\n"))  # keeps the line numbers
        end = match.end()
    pieces.append(text[end:])
    marks = _TOML_IGNORED.sub("", "".join(pieces))
    stack: list[int] = []
    level = dots = 0
    line = 1
    for mark in marks:
        if mark == ".":
            dots += 1
        elif mark == "[" or mark == "{":
            stack.append(dots + 1)
            level += dots + 1
            dots = 0
        else:  # a closing bracket or a separator
            if stack and (mark == "]" or mark == "}"):
                level -= stack.pop()
            line += mark == "\n"
            dots = 0
            continue
        if level + dots > max_depth:
            return (f"nested deeper than {max_depth} levels (arrays, inline tables and "
                    f"dotted keys inside each other) at line {line}")
    return None


def parse_toml(text: str, *, error: Callable[[str], Exception],
               max_depth: int = MAX_TOML_DEPTH) -> dict[str, Any]:
    """Parse TOML text after bounding its nesting (:func:`toml_nesting_problem`).

    Parameters
    ----------
    text : str
        The text (its size bounded by the caller: the scan and the parse are linear in it).
    error : callable
        Builds the exception to raise from one line that does not name the file.
    max_depth : int, optional
        The deepest nesting accepted (:data:`MAX_TOML_DEPTH`).

    Returns
    -------
    dict
        The document.

    Raises
    ------
    Exception
        ``error("not valid TOML: ...")`` or ``error("nested deeper than ...")``.
    """
    problem = toml_nesting_problem(text, max_depth)
    if problem is not None:
        raise error(problem)
    try:
        return tomllib.loads(text)
    except (ValueError, RecursionError) as exc:  # TOMLDecodeError, an over-long integer
        reason = " ".join(str(exc).split())
        if len(reason) > 200:
            reason = reason[:197] + "..."
        raise error(f"not valid TOML: {reason}") from None
