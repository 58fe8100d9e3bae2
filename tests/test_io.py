"""Whole-or-absent files: umask modes, fsync order, temporaries after errors and kill -9, groups."""

from __future__ import annotations

import builtins
import os
import signal
import stat
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from snake_pin import _io
from snake_pin._io import (
    MAX_TOML_DEPTH,
    TEMP_MARKER,
    atomic_group,
    atomic_save,
    atomic_write_bytes,
    clean_stale_temporaries,
    current_umask,
    decode_utf8,
    open_regular_file,
    parse_toml,
    read_regular_file,
    toml_nesting_problem,
)
from snake_pin.exceptions import ParameterError


@pytest.fixture
def umask() -> Iterator[None]:
    """Restore the process umask after a test that changes it."""
    old = os.umask(0o022)
    os.umask(old)
    try:
        yield
    finally:
        os.umask(old)


def _temporaries(folder: Path) -> list[str]:
    return [p.name for p in folder.iterdir() if TEMP_MARKER in p.name]


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


@pytest.mark.parametrize(("mask", "mode"), [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_mode_follows_the_umask(tmp_path: Path, umask: None, mask: int, mode: int) -> None:
    """Single files and group members get 0o666 & ~umask, as open(path, 'w') would give."""
    os.umask(mask)
    assert current_umask() == mask
    atomic_write_bytes(tmp_path / "one.bin", b"1")
    with atomic_group(tmp_path) as group:
        group.write_bytes("data.json", b"{}")
        group.write_bytes("fig.png", b"png", figure=True)
    for name in ("one.bin", "data.json", "fig.png"):
        assert _mode(tmp_path / name) == mode, name


def test_umask_without_proc(monkeypatch: pytest.MonkeyPatch, umask: None) -> None:
    """Without /proc the umask is read by swapping it, and left as it was."""
    os.umask(0o027)

    def no_proc(file, *args, **kwargs):
        if str(file).startswith("/proc/"):
            raise FileNotFoundError(file)
        return builtins.open(file, *args, **kwargs)

    monkeypatch.setattr(_io, "open", no_proc, raising=False)
    assert current_umask() == 0o027
    assert os.umask(0o022) == 0o027


def test_mode_in_a_fresh_process(tmp_path: Path) -> None:
    """A process started under umask 077 writes 0600, under 022 writes 0644."""
    code = ("import sys; from snake_pin._io import atomic_write_bytes; "
            "atomic_write_bytes(sys.argv[1], b'x')")
    for mask, mode in ((0o077, 0o600), (0o022, 0o644)):
        target = tmp_path / f"m{mask:o}.bin"
        subprocess.run([sys.executable, "-c", code, str(target)], check=True, timeout=60,
                       preexec_fn=lambda m=mask: os.umask(m))
        assert _mode(target) == mode


def test_fsync_file_before_rename_and_folder_after(tmp_path: Path,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Each staged file is fsync-ed before any rename, the folder after the renames."""
    events: list[str] = []
    real_fsync, real_replace = os.fsync, os.replace

    def fsync(fd: int) -> None:
        events.append("fsync dir" if stat.S_ISDIR(os.fstat(fd).st_mode) else "fsync file")
        real_fsync(fd)

    def replace(src, dst) -> None:
        events.append(f"rename {Path(dst).name}")
        real_replace(src, dst)

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(os, "replace", replace)
    atomic_write_bytes(tmp_path / "a.bin", b"a")
    assert events == ["fsync file", "rename a.bin", "fsync dir"]
    events.clear()
    with atomic_group(tmp_path) as group:
        group.write_bytes("b.bin", b"b")
        group.write_bytes("c.bin", b"c")
    assert events == ["fsync file", "fsync file", "rename b.bin", "rename c.bin", "fsync dir"]


def test_no_temporary_after_an_exception(tmp_path: Path) -> None:
    """A failing writer leaves the old file as it was and no temporary."""
    target = tmp_path / "run.npz"
    target.write_bytes(b"old")

    def half(handle) -> None:
        handle.write(b"new but half")
        raise ValueError("writer failed")

    with pytest.raises(ValueError, match="writer failed"):
        atomic_save(target, half)
    assert target.read_bytes() == b"old" and _temporaries(tmp_path) == []


@pytest.mark.parametrize("error", [KeyboardInterrupt, RuntimeError])
def test_group_is_all_or_nothing(tmp_path: Path, error: type[BaseException]) -> None:
    """A group whose block raises (Ctrl-C included) changes no file and leaves no temporary."""
    (tmp_path / "data.json").write_bytes(b"old data")
    (tmp_path / "fig.png").write_bytes(b"old fig")
    with pytest.raises(error), atomic_group(tmp_path) as group:
        group.write_bytes("data.json", b"new data")
        group.write_bytes("fig.png", b"new fig", figure=True)
        group.write_bytes("extra.csv", b"new")
        raise error()
    assert (tmp_path / "data.json").read_bytes() == b"old data"
    assert (tmp_path / "fig.png").read_bytes() == b"old fig"
    assert not (tmp_path / "extra.csv").exists() and _temporaries(tmp_path) == []


def test_group_renames_data_before_figures(tmp_path: Path,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """Nothing is renamed inside the block; then data files in order, then figures in order."""
    renamed: list[str] = []
    real_replace = os.replace

    def replace(src, dst) -> None:
        renamed.append(Path(dst).name)
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with atomic_group(tmp_path) as group:
        group.write_bytes("fig1.png", b"f1", figure=True)
        group.save("run.npz", lambda handle: handle.write(b"npz"))
        group.write_bytes("fig2.png", b"f2", figure=True)
        with group.open("run.json") as handle:
            handle.write(b"{}")
        assert renamed == [] and not (tmp_path / "run.npz").exists()
        assert [p.name for p in group.targets] == ["run.npz", "run.json", "fig1.png",
                                                   "fig2.png"]
    assert renamed == ["run.npz", "run.json", "fig1.png", "fig2.png"]
    assert (tmp_path / "run.json").read_bytes() == b"{}" and _temporaries(tmp_path) == []


def test_failed_rename_keeps_a_prefix_and_names_the_file(tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """If the second rename fails, the first file is new, the rest old; the error names it."""
    for name in ("a.json", "b.json", "c.png"):
        (tmp_path / name).write_bytes(b"old")
    real_replace = os.replace

    def replace(src, dst) -> None:
        if Path(dst).name == "b.json":
            raise PermissionError(13, "Permission denied", str(src))
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(PermissionError) as info, atomic_group(tmp_path) as group:
        group.write_bytes("c.png", b"new", figure=True)
        group.write_bytes("a.json", b"new")
        group.write_bytes("b.json", b"new")
    assert info.value.filename == str(tmp_path / "b.json") and TEMP_MARKER not in str(info.value)
    contents = [(tmp_path / n).read_bytes() for n in ("a.json", "b.json", "c.png")]
    assert contents == [b"new", b"old", b"old"] and _temporaries(tmp_path) == []


def test_errors_name_the_target_not_a_temporary(tmp_path: Path) -> None:
    """Writing into a missing folder is an OSError naming the file asked for."""
    target = tmp_path / "missing" / "run.json"
    with pytest.raises(FileNotFoundError) as info:
        atomic_write_bytes(target, b"{}")
    assert info.value.filename == str(target) and TEMP_MARKER not in str(info.value)


def test_a_file_written_twice_in_a_group_is_refused(tmp_path: Path) -> None:
    """Staging the same name twice is a ParameterError and writes nothing."""
    with pytest.raises(ParameterError), atomic_group(tmp_path) as group:
        group.write_bytes("a.bin", b"1")
        group.write_bytes("a.bin", b"2")
    assert list(tmp_path.iterdir()) == []


_WRITER = textwrap.dedent("""
    import sys, time
    from snake_pin._io import atomic_save
    def save(handle):
        handle.write(b"partial")
        handle.flush()
        print("ready", flush=True)
        time.sleep(60)
    atomic_save(sys.argv[1], save)
""")


def test_kill_9_leaves_a_temporary_that_the_next_write_removes(tmp_path: Path) -> None:
    """A killed writer's temporary survives only until the next write in that folder."""
    child = subprocess.Popen([sys.executable, "-c", _WRITER, str(tmp_path / "run.npz")],
                             stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None and child.stdout.readline().strip() == "ready"
        (temp,) = _temporaries(tmp_path)
        assert f"{TEMP_MARKER}{child.pid}-" in temp and temp.startswith(".run.npz.")
        assert clean_stale_temporaries(tmp_path) == []  # its writer is alive: kept
        child.send_signal(signal.SIGKILL)
    finally:
        child.kill()
        child.wait(timeout=30)
        if child.stdout is not None:
            child.stdout.close()
    assert _temporaries(tmp_path) == [temp]
    atomic_write_bytes(tmp_path / "other.json", b"{}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["other.json"]


def test_cleaning_spares_live_writers_and_foreign_files(tmp_path: Path) -> None:
    """Only marked regular files of dead (or zombie) pids go; others stay."""
    zombie = subprocess.Popen([sys.executable, "-c", "pass"])
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:  # let it exit without reaping it: a zombie
        state = Path(f"/proc/{zombie.pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        if state == "Z":
            break
        time.sleep(0.01)
    assert state == "Z"
    try:
        keep = [f".a{TEMP_MARKER}{os.getpid()}-x1y2.tmp", f".b{TEMP_MARKER}abc-x1y2.tmp",
                "plain.tmp", f"c{TEMP_MARKER}1-x.tmp"]
        gone = [f".d{TEMP_MARKER}{zombie.pid}-x1y2.tmp", f".e{TEMP_MARKER}99999999999-ab.tmp"]
        for name in keep + gone:
            (tmp_path / name).write_bytes(b"")
        (tmp_path / f".f{TEMP_MARKER}99999999999-ab.tmp").mkdir()
        removed = clean_stale_temporaries(tmp_path)
    finally:
        zombie.wait(timeout=30)
    assert sorted(p.name for p in removed) == sorted(gone)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [*keep, f".f{TEMP_MARKER}99999999999-ab.tmp"])


_NAME = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="/\x00"),
                min_size=1, max_size=60).filter(lambda s: s not in (".", ".."))


@settings(max_examples=40, deadline=None)
@given(name=_NAME, data=st.binary(max_size=64))
def test_any_file_name_is_written_exactly(name: str, data: bytes) -> None:
    """Whatever the name (long, dotted, unicode), exactly that file appears with the data."""
    name = name if len(name.encode()) <= 255 else name[:50]
    with tempfile.TemporaryDirectory() as folder:
        atomic_write_bytes(Path(folder) / name, data)
        assert os.listdir(folder) == [name]
        assert (Path(folder) / name).read_bytes() == data


def test_long_names_fit(tmp_path: Path) -> None:
    """A 255-byte name (NAME_MAX) is written although its temporary name adds a marker."""
    name = "n" * 251 + ".npz"
    atomic_write_bytes(tmp_path / name, b"x")
    assert [p.name for p in tmp_path.iterdir()] == [name]


# --------------------------------------------------------------------------- reading
class _Refused(ParameterError):
    """The error the reading tests ask the helpers to raise."""


def _refused(message: str) -> _Refused:
    return _Refused(f"the file: {message}")


def _read(path: object, limit: int = 1 << 10) -> bytes:
    return read_regular_file(path, limit=limit, kind="test file",  # type: ignore[arg-type]
                             error=_refused)


def _refusal(call: Callable[[], object]) -> str:
    """The one-line message ``call`` raises; a call that blocks (a FIFO opened) fails."""
    outcome: list[BaseException | object] = []
    worker = threading.Thread(target=lambda: outcome.append(_catch(call)), daemon=True)
    worker.start()
    worker.join(60)
    assert not worker.is_alive(), "the reader blocked"
    error = outcome[0]
    assert isinstance(error, _Refused), error
    assert "\n" not in str(error)
    return str(error)


def _catch(call: Callable[[], object]) -> BaseException | object:
    try:
        return call()
    except BaseException as exc:  # returned to the test thread
        return exc


def test_regular_files_are_read_whole(tmp_path: Path) -> None:
    """A regular file (directly or through a symlink) within the bound is read whole."""
    (tmp_path / "a").write_bytes(b"x" * 1024)
    (tmp_path / "link").symlink_to(tmp_path / "a")
    assert _read(tmp_path / "a") == b"x" * 1024
    assert _read(str(tmp_path / "link")) == b"x" * 1024


def test_a_fifo_is_refused_without_blocking(tmp_path: Path) -> None:
    """A FIFO, or a symlink to one, is refused at once: nothing waits for a writer."""
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "link").symlink_to(tmp_path / "fifo")
    for name in ("fifo", "link"):
        message = _refusal(lambda name=name: _read(tmp_path / name))
        assert message == "the file: is a FIFO, not a regular file: not a test file"


def test_a_fifo_swapped_in_after_the_stat_is_refused(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """The opened descriptor is checked again: a FIFO put in place after the stat neither
    blocks nor is read."""
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "plain").write_bytes(b"x")
    real_stat = os.stat
    monkeypatch.setattr(os, "stat", lambda path, *a, **k: real_stat(tmp_path / "plain"))
    assert "is a FIFO" in _refusal(lambda: _read(tmp_path / "fifo"))


def test_other_non_regular_files_and_bad_names_are_refused(tmp_path: Path) -> None:
    """Folders, devices, missing files, NUL bytes and non-paths each give one line."""
    assert _refusal(lambda: _read(tmp_path)) == "the file: is a folder, not a test file"
    assert "a character device" in _refusal(lambda: _read("/dev/zero"))
    assert _refusal(lambda: _read(tmp_path / "none")) == "the file: no such test file"
    assert "cannot read it" in _refusal(lambda: _read("a\x00b"))
    assert "not a file path" in _refusal(lambda: _read(0))  # never stat-ed as a descriptor


def test_the_size_bound_is_checked_before_reading(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """A file beyond the bound is refused from its size: not a byte of it is read."""
    big = tmp_path / "big"
    with open(big, "wb") as handle:
        handle.truncate(1 << 40)  # sparse: 1 TiB, never read
    reads: list[int] = []
    real_read = os.read
    monkeypatch.setattr(os, "read", lambda fd, n: reads.append(n) or real_read(fd, n))
    assert "is larger than 1024 bytes (1099511627776 bytes)" in _refusal(lambda: _read(big))
    assert reads == []
    (tmp_path / "edge").write_bytes(b"y" * 1024)
    assert _read(tmp_path / "edge") == b"y" * 1024


_LINK = "the file: is a symbolic link (not followed), not a regular file: not a test file"


def test_links_are_refused_when_not_followed(tmp_path: Path) -> None:
    """With follow_symlinks=False a link (to a file, a FIFO or nothing) is refused in one
    line and never opened; the plain file itself is still read whole."""
    (tmp_path / "a").write_bytes(b"abc")
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "to-file").symlink_to(tmp_path / "a")
    (tmp_path / "to-fifo").symlink_to(tmp_path / "fifo")
    (tmp_path / "dangling").symlink_to(tmp_path / "none")
    for name in ("to-file", "to-fifo", "dangling"):
        assert _refusal(lambda name=name: read_regular_file(
            tmp_path / name, limit=10, kind="test file", error=_refused,
            follow_symlinks=False)) == _LINK
    assert read_regular_file(tmp_path / "a", limit=10, kind="test file", error=_refused,
                             follow_symlinks=False) == b"abc"
    with open_regular_file(tmp_path / "a", limit=3, kind="test file", error=_refused,
                           follow_symlinks=False) as handle:
        assert handle.read() == b"abc"
    assert _read(tmp_path / "to-file") == b"abc"  # followed by default


def test_a_link_swapped_in_after_the_check_is_refused_by_the_open(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The open itself refuses a link (O_NOFOLLOW): a link put in place after the name was
    checked is not followed to its target."""
    (tmp_path / "secret").write_bytes(b"secret")
    (tmp_path / "plain").write_bytes(b"x")
    (tmp_path / "link").symlink_to(tmp_path / "secret")
    real_stat = os.stat
    monkeypatch.setattr(os, "stat", lambda path, *a, **k: real_stat(tmp_path / "plain"))
    opened: list[int] = []
    real_open = os.open
    monkeypatch.setattr(os, "open", lambda path, flags, *a: opened.append(flags) or
                        real_open(path, flags, *a))
    assert _refusal(lambda: open_regular_file(tmp_path / "link", limit=10, kind="test file",
                                              error=_refused, follow_symlinks=False)) == _LINK
    assert opened and all(flags & os.O_NOFOLLOW for flags in opened)
    assert _read(tmp_path / "link") == b"secret"  # the same swap, followed by default


def test_open_regular_file_gives_a_blocking_handle_at_the_start(tmp_path: Path) -> None:
    """The handle is an ordinary blocking binary file (what pyarrow or zipfile expect)."""
    (tmp_path / "a").write_bytes(b"abc")
    with open_regular_file(tmp_path / "a", limit=3, kind="part", error=_refused) as handle:
        assert os.get_blocking(handle.fileno()) and handle.read() == b"abc"


def test_decode_utf8_names_the_byte() -> None:
    """Bytes that are not UTF-8 give one line with the offending byte's position."""
    assert decode_utf8("é".encode(), error=_refused) == "é"
    with pytest.raises(_Refused, match=r"not UTF-8 text \(invalid start byte at byte 2\)"):
        decode_utf8(b"ab\xff", error=_refused)


@pytest.mark.parametrize("text", [
    "x = " + "[" * 100_000,
    "x = " + "[" * 100_000 + "]" * 100_000,
    "x = " + "{a = " * 100_000 + "1" + "}" * 100_000,
    "a" + ".a" * 100_000 + " = 1",
    "[" + "a." * 100_000 + "a]\n",
    "[[" + "a." * 100_000 + "a]]\n",
    "x = [{" + "a." * 20 + "b = [[" + "{c." * 20,
])
def test_deep_toml_is_refused_before_tomllib(text: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Deep arrays, inline tables and dotted keys are refused by the scan: tomllib (which
    recurses on the first two and is quadratic in the third) never sees them."""
    monkeypatch.setattr(_io.tomllib, "loads", lambda text: pytest.fail("tomllib was called"))
    with pytest.raises(_Refused, match=f"nested deeper than {MAX_TOML_DEPTH} levels"):
        parse_toml(text, error=_refused)


def test_nesting_is_counted_outside_strings_and_comments_only() -> None:
    """Brackets and dots inside strings of every kind and comments do not count; the
    bound itself is accepted and parsed."""
    deep = "[" * 40
    text = (f'a = "{deep}"\nb = \'{deep}\'\nc = """\n{deep}\n"""\nd = \'\'\'{deep}\'\'\'\n'
            f'e = """x""""\n# {deep}\nf = "\\"{deep}"\n"g.{"." * 40}" = 1\n'
            f'h = [1.5, 2.5, 3.5, 4.5, 5.5, 6.5, 7.5, 8.5, 9.5, 10.5, 11.5, 12.5, 13.5, 14.5, '
            f'15.5, 16.5, 17.5, 18.5, 19.5, 20.5, 21.5, 22.5, 23.5, 24.5, 25.5, 26.5, 27.5, '
            f'28.5, 29.5, 30.5, 31.5, 32.5, 33.5]\n')
    doc = parse_toml(text, error=_refused)
    assert doc["a"] == doc["b"] == deep and doc["e"] == 'x"' and len(doc["h"]) == 33
    at_bound = "x = " + "[" * MAX_TOML_DEPTH + "]" * MAX_TOML_DEPTH
    assert toml_nesting_problem(at_bound) is None
    assert toml_nesting_problem("x = " + "[" * (MAX_TOML_DEPTH + 1)) is not None
    assert toml_nesting_problem("a" + ".a" * MAX_TOML_DEPTH + " = 1") is None
    assert toml_nesting_problem("a" + ".a" * (MAX_TOML_DEPTH + 1) + " = 1") is not None


def test_invalid_toml_is_one_line_of_the_callers_error() -> None:
    """Syntax errors and integers beyond Python's digit limit are the caller's error."""
    for text in ("x = = 1", "x = " + "9" * 5000, 'x = "unterminated [[[[[[',
                 'x = """' + '\\"' * 100_000 + "[" * 100_000):
        with pytest.raises(_Refused, match=r"^the file: not valid TOML: ") as exc:
            parse_toml(text, error=_refused)
        assert "\n" not in str(exc.value)
