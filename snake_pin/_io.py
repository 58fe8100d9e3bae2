"""Files in and out: whole-or-absent writes, and bounded reads that never block.

Every file snake_pin writes or reads goes through this module; what it promises and
why, and the errors it raises: :ref:`files`.
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

from ._validation import one_line
from .exceptions import ParameterError

__all__ = ["MAX_TOML_DEPTH", "TEMP_MARKER", "AtomicGroup", "atomic_group", "atomic_save",
           "atomic_write_bytes", "clean_stale_temporaries", "current_umask", "decode_utf8",
           "open_regular_file", "parse_toml", "read_regular_file", "toml_nesting_problem"]

#: The marker every temporary name carries: ``.NAME.snake_pin-PID-XXXXXXXX.tmp``.
TEMP_MARKER = ".snake_pin-"
_TEMP_NAME = re.compile(r"\..*\.snake_pin-(\d+)-\w+\.tmp", re.DOTALL)
#: Characters of the target's name kept in a temporary name (NAME_MAX is 255 bytes).
_NAME_KEPT = 64
_UMASK_LOCK = threading.Lock()
#: Deepest nesting of a TOML file snake_pin reads: each array or inline table adds one level
#: plus its key's dots (``a.b.c = 1`` is 2 levels). snake_pin's files need 3.
MAX_TOML_DEPTH = 32


def current_umask() -> int:
    """The process's umask, read without a window in which files get a wider mode."""
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


def pid_alive(pid: int) -> bool:
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
    """Remove the temporaries in ``folder`` whose writer is gone (best effort); return them."""
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
            if not entry.is_file(follow_symlinks=False) or pid_alive(int(match.group(1))):
                continue
            os.unlink(entry.path)
            removed.append(Path(entry.path))
        except OSError:
            continue
    return removed


def fsync_directory(folder: Path) -> None:
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
    """Files staged by :func:`atomic_group` in ``folder``; use its methods inside the block."""

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
        """Stage ``name`` (relative to the folder): yield a binary handle on its temporary
        (``figure=True``: renamed after the data files; ParameterError if staged twice)."""
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
        """Stage ``data`` as ``name`` (as :meth:`open`); return the final path."""
        return self.save(name, lambda handle: handle.write(data), figure=figure)

    def save(self, name: str | os.PathLike[str], save: Callable[[IO[bytes]], object], *,
             figure: bool = False) -> Path:
        """Stage ``name`` written by ``save(handle)`` (as :meth:`open`); return the final path."""
        with self.open(name, figure=figure) as handle:
            save(handle)
        return self.folder / name

    # ------------------------------------------------------------ commit/abort
    def _order(self) -> list[_Staged]:
        return ([s for s in self._staged if not s.figure]
                + [s for s in self._staged if s.figure])

    def _commit(self) -> None:
        """Rename every staged file into place (data, then figures), then sync the folders."""
        order = self._order()
        folders = dict.fromkeys(staged.target.parent for staged in order)
        for staged in order:
            try:
                os.replace(staged.temp, staged.target)
            except OSError as exc:
                _reraise(exc, staged.target)
            self._staged.remove(staged)
        for folder in folders:
            try:
                fsync_directory(folder)
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
    """Write a set of files in ``folder`` staged on the yielded :class:`AtomicGroup`,
    renamed into place when the block succeeds, data before figures (:ref:`files`)."""
    group = AtomicGroup(folder)
    try:
        yield group
        group._commit()
    finally:
        group._discard()


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` whole or not at all."""
    atomic_save(path, lambda handle: handle.write(data))


def atomic_save(path: str | os.PathLike[str], save: Callable[[IO[bytes]], object]) -> None:
    """Write ``path`` whole or not at all by ``save(handle)`` (e.g. ``np.savez``)."""
    path = Path(path)
    with atomic_group(path.parent) as group:
        group.save(path.name, save)


# --------------------------------------------------------------------------- reading
_FILE_KINDS = ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISSOCK, "a socket"),
               (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"))


def _not_regular(mode: int, kind: str) -> str:
    """Why a file of ``mode`` is not a ``kind``, or "" for a regular file."""
    if stat.S_ISREG(mode):
        return ""
    if stat.S_ISLNK(mode):
        return f"is a symbolic link (not followed), not a regular file: not a {kind}"
    if stat.S_ISDIR(mode):
        return f"is a folder, not a {kind}"
    name = next((name for test, name in _FILE_KINDS if test(mode)), "not a regular file")
    return f"is {name}, not a regular file: not a {kind}"


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
    """Open ``path`` for binary reading if it is a regular file of at most ``limit`` bytes,
    never blocking (:ref:`files`); a refusal is ``error(line)``, naming ``kind``, not the file."""
    if not isinstance(path, (str, os.PathLike)):
        raise error(f"not a file path: {type(path).__name__}")
    try:
        problem = _not_regular(os.stat(path, follow_symlinks=follow_symlinks).st_mode, kind)
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the name
        raise error(_refusal(exc, kind)) from None
    if problem:
        raise error(problem)
    flags = (os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0)
             | getattr(os, "O_CLOEXEC", 0))
    if not follow_symlinks:
        flags |= os.O_NOFOLLOW
    try:
        fd = os.open(path, flags)
    except (OSError, ValueError) as exc:
        if not follow_symlinks and isinstance(exc, OSError) and \
                exc.errno in (errno.ELOOP, errno.EMLINK):  # EMLINK: the BSDs' word for it
            raise error(_not_regular(stat.S_IFLNK, kind)) from None
        raise error(_refusal(exc, kind)) from None
    try:
        info = os.fstat(fd)
    except OSError as exc:
        os.close(fd)
        raise error(_refusal(exc, kind)) from None
    problem = _not_regular(info.st_mode, kind) or (
        f"is larger than {limit} bytes ({info.st_size} bytes): not a {kind}"
        if info.st_size > limit else "")
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
    """The bytes of ``path`` opened by :func:`open_regular_file` (``limit`` checked again)."""
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
    """``data`` decoded as UTF-8, or ``error("not UTF-8 text (... at byte N)")``."""
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
    """Why ``text`` nests deeper than ``max_depth`` levels, or None: one linear scan, no parse
    (strings and comments skipped; a float's dot may count one level too many)."""
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
    """Parse TOML text after bounding its nesting (tomllib recurses per level), or ``error``."""
    problem = toml_nesting_problem(text, max_depth)
    if problem is not None:
        raise error(problem)
    try:
        return tomllib.loads(text)
    except (ValueError, RecursionError) as exc:  # TOMLDecodeError, an over-long integer
        raise error(f"not valid TOML: {one_line(str(exc))}") from None
