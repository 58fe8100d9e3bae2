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
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from snake_pin import _io
from snake_pin._io import (
    TEMP_MARKER,
    atomic_group,
    atomic_save,
    atomic_write_bytes,
    clean_stale_temporaries,
    current_umask,
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
    from snake_pin._io import atomic_writer
    with atomic_writer(sys.argv[1]) as handle:
        handle.write(b"partial")
        handle.flush()
        print("ready", flush=True)
        time.sleep(60)
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
