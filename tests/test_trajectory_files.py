"""Trajectory files: whole stems, statuses, and a bounded, total loader (fuzzed with hypothesis)."""

from __future__ import annotations

import io
import json
import math
import os
import stat
import struct
import tracemalloc
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from snake_pin import (
    ConfigurationError,
    OpenLoop,
    ParameterError,
    Snake,
    Trajectory,
    TrajectoryFileError,
    simulate,
    trajectory,
)
from snake_pin._io import TEMP_MARKER
from snake_pin.trajectory import MAX_ARRAY_BYTES, MAX_TOTAL_BYTES

from .conftest import raised_without_blocking

_FUZZ = settings(max_examples=80, deadline=None,
                 suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def original(table1: Snake) -> Trajectory:
    """A short run with a signal, a summary and meta: the file every mutation starts from."""
    x0 = np.r_[np.zeros(3), np.full(9, np.pi / 6), np.zeros(12)]
    traj = simulate(table1, OpenLoop(lambda t: 0.01 * np.sin(t + np.arange(9))), x0, 0.01)
    traj.signals["R"] = np.linspace(0.0, 1.0, len(traj))
    traj.signals["V"] = np.full(len(traj), np.nan)
    traj.summary.update({"rms": 0.25, "note": "ok"})
    return traj


@pytest.fixture(scope="module")
def saved(original: Trajectory, tmp_path_factory: pytest.TempPathFactory) -> bytes:
    folder = tmp_path_factory.mktemp("original")
    npz, _ = original.save(folder / "run")
    return npz.read_bytes()


@pytest.fixture(scope="module")
def members(saved: bytes) -> dict[str, bytes]:
    with zipfile.ZipFile(io.BytesIO(saved)) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def _same(a: Trajectory, b: Trajectory, *, signals: bool = True) -> bool:
    arrays = all(np.array_equal(getattr(a, k), getattr(b, k)) for k in ("t", "q", "dq", "tau"))
    sig = (sorted(a.signals) == sorted(b.signals) and all(
        np.array_equal(a.signals[k], b.signals[k], equal_nan=True) for k in a.signals)) \
        if signals else b.signals == {}
    return (arrays and sig and a.params == b.params and a.status == b.status
            and a.reason == b.reason and a.meta == b.meta and a.summary == b.summary)


def _refused(path: Path, **kwargs: Any) -> str:
    """Load ``path`` expecting a refusal; return its one-line message."""
    with pytest.raises(TrajectoryFileError) as info:
        Trajectory.load(path, **kwargs)
    message = str(info.value)
    assert "\n" not in message and str(path) in message and TEMP_MARKER not in message
    return message


def _equal_or_refused(path: Path, original: Trajectory) -> None:
    for signals in (True, False):
        try:
            back = Trajectory.load(path, signals=signals)
        except TrajectoryFileError as exc:
            message = str(exc)
            assert "\n" not in message and str(path) in message
        else:
            assert _same(original, back, signals=signals)


def _npy(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, array, allow_pickle=True)
    return buf.getvalue()


def _zip(contents: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in contents.items():
            archive.writestr(name, data)
    return buf.getvalue()


def _array(members: dict[str, bytes], name: str) -> np.ndarray:
    return np.lib.format.read_array(io.BytesIO(members[f"{name}.npy"]))


def _header(members: dict[str, bytes]) -> dict[str, Any]:
    return json.loads(str(_array(members, "header")[()]))


def _with_header(members: dict[str, bytes], header: object) -> bytes:
    text = header if isinstance(header, str) else json.dumps(header)
    return _zip({**members, "header.npy": _npy(np.array(text))})


# ---------------------------------------------------------------- names and statuses
def test_save_keeps_the_whole_stem(original: Trajectory, tmp_path: Path) -> None:
    """run.v2 -> run.v2.npz + run.v2.json; only a trailing .npz/.json is dropped."""
    for given_name, stem in (("run.v2", "run.v2"), ("run.v2.npz", "run.v2"),
                             ("b.json", "b"), ("c.tar", "c.tar")):
        npz, js = original.save(tmp_path / given_name)
        assert (npz.name, js.name) == (f"{stem}.npz", f"{stem}.json")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["run.v2.npz", "run.v2.json", "b.npz", "b.json", "c.tar.npz", "c.tar.json"])
    assert _same(original, Trajectory.load(tmp_path / "run.v2"))  # the file save("run.v2") wrote
    for bad in ("", ".npz", "dir/.json"):
        with pytest.raises(ParameterError):
            original.save(tmp_path / bad if bad else bad)
    with pytest.raises(ParameterError, match="does not exist"):
        original.save(tmp_path / "missing" / "run")


def test_load_opens_the_file_given(original: Trajectory, tmp_path: Path) -> None:
    """bk/pfl.backup is refused when missing (never bk/pfl.npz), and opened when it exists."""
    (tmp_path / "bk").mkdir()
    npz, _ = original.save(tmp_path / "bk" / "pfl")
    message = _refused(tmp_path / "bk" / "pfl.backup")
    assert "no such snake_pin trajectory" in message and "pfl.npz" not in message
    (tmp_path / "bk" / "pfl.backup").write_bytes(npz.read_bytes())
    assert _same(original, Trajectory.load(tmp_path / "bk" / "pfl.backup"))
    assert "is a folder" in _refused(tmp_path / "bk")


def test_saved_files_are_readable_by_others(original: Trajectory, tmp_path: Path) -> None:
    """Both files get the umask's mode (0644 under the usual 022), not mkstemp's 0600."""
    from snake_pin._io import current_umask

    for path in original.save(tmp_path / "run"):
        assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~current_umask()


@pytest.mark.parametrize("status", ["completed", "diverged", "failed", "interrupted"])
def test_status_round_trips(original: Trajectory, tmp_path: Path, status: str) -> None:
    """The status is in the header and the JSON summary; diverged only for the two faults."""
    traj = Trajectory(t=original.t, q=original.q, dq=original.dq, tau=original.tau,
                      params=original.params, status=status, reason=f"{status} at t = 0.01 s")
    _, js = traj.save(tmp_path / "run")
    summary = json.loads(js.read_text())
    assert summary["status"] == status and summary["diverged"] == (status in ("diverged",
                                                                              "failed"))
    back = Trajectory.load(tmp_path / "run.npz")
    assert back.status == status and back.diverged == traj.diverged and back.reason == traj.reason


def test_status_and_diverged_must_agree(original: Trajectory) -> None:
    """diverged=True with a non-fault status, or an unknown status, is a ParameterError."""
    arrays = {k: getattr(original, k) for k in ("t", "q", "dq", "tau")}
    with pytest.raises(ParameterError):
        Trajectory(**arrays, params=original.params, diverged=True, status="interrupted")
    with pytest.raises(ParameterError):
        Trajectory(**arrays, params=original.params, status="finished")
    assert Trajectory(**arrays, params=original.params, diverged=True).status == "diverged"


def test_files_without_status_still_load(members: dict[str, bytes], tmp_path: Path,
                                         original: Trajectory) -> None:
    """Headers written before statuses existed (diverged only) load, status derived."""
    header = _header(members)
    del header["status"]
    path = tmp_path / "old.npz"
    path.write_bytes(_with_header(members, header))
    assert _same(original, Trajectory.load(path))


def test_summary_json_is_strict(original: Trajectory, tmp_path: Path) -> None:
    """Non-finite summary numbers are null in the .json (RFC 8259); the header keeps them."""
    traj = Trajectory(t=original.t, q=original.q, dq=original.dq, tau=original.tau,
                      params=original.params, summary={"rms": math.nan, "top": [1.0, math.inf]})
    _, js = traj.save(tmp_path / "run")

    def refuse(token: str) -> None:
        raise AssertionError(f"non-RFC token {token}")

    summary = json.loads(js.read_text(), parse_constant=refuse)
    assert summary["rms"] is None and summary["top"] == [1.0, None]
    assert math.isnan(Trajectory.load(tmp_path / "run.npz").summary["rms"])


def test_save_refuses_what_load_would_refuse(original: Trajectory, tmp_path: Path) -> None:
    """NaN states, ragged arrays, bad signal names or non-JSON meta: nothing is written."""
    base = {k: getattr(original, k) for k in ("t", "q", "dq", "tau")}
    bad_q = original.q.copy()
    bad_q[3, 2] = np.nan
    cases = [
        (ConfigurationError, {**base, "q": bad_q}),
        (ConfigurationError, {**base, "tau": original.tau[:-1]}),
        (ConfigurationError, {**base, "t": original.t[::-1].copy()}),
        (ConfigurationError, {**base, "signals": {"a/b": original.t}}),
        (ConfigurationError, {**base, "signals": {"R": original.t[:-1]}}),
        (ParameterError, {**base, "meta": {"f": object()}}),
    ]
    for error, kwargs in cases:
        with pytest.raises(error):
            Trajectory(params=original.params, **kwargs).save(tmp_path / "run")
    assert list(tmp_path.iterdir()) == []


# -------------------------------------------------------------------- choosing signals
def test_load_reads_only_the_signals_asked_for(original: Trajectory, tmp_path: Path) -> None:
    """signals=False reads none, a list reads those; unknown names and bad values are refused."""
    original.save(tmp_path / "run")
    path = tmp_path / "run.npz"
    assert Trajectory.load(path, signals=False).signals == {}
    assert sorted(Trajectory.load(path, signals=["R"]).signals) == ["R"]
    assert sorted(Trajectory.load(path).signals) == ["R", "V"]
    assert "no signal 'X'" in _refused(path, signals=["X"])
    for bad in ("R", 3, [1]):
        with pytest.raises(ParameterError):
            Trajectory.load(path, signals=bad)


# ------------------------------------------------------------------- hostile files
def test_simple_broken_files(saved: bytes, tmp_path: Path) -> None:
    """Zero bytes, not a zip, a foreign npz, an empty zip: one line each."""
    cases = {
        "empty.npz": b"",
        "text.npz": b"hello, world\n",
        "foreign.npz": _zip({"a.npy": _npy(np.zeros(3))}),
        "nothing.npz": _zip({}),
        "half.npz": saved[: len(saved) // 2],
    }
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
        _refused(tmp_path / name)
    assert "empty" in _refused(tmp_path / "empty.npz")


@_FUZZ
@given(cut=st.data())
def test_truncated_files(saved: bytes, original: Trajectory, tmp_path: Path,
                         cut: st.DataObject) -> None:
    """A file cut anywhere is refused (or, if the cut spares everything, equal)."""
    offset = cut.draw(st.integers(0, len(saved) - 1))
    path = tmp_path / "cut.npz"
    path.write_bytes(saved[:offset])
    _equal_or_refused(path, original)


@_FUZZ
@given(flips=st.data())
def test_flipped_bytes(saved: bytes, original: Trajectory, tmp_path: Path,
                       flips: st.DataObject) -> None:
    """Flipped bytes anywhere: refused, or (in fields nothing depends on) equal."""
    data = bytearray(saved)
    for _ in range(flips.draw(st.integers(1, 4))):
        offset = flips.draw(st.integers(0, len(data) - 1))
        data[offset] ^= flips.draw(st.integers(1, 255))
    path = tmp_path / "flipped.npz"
    path.write_bytes(bytes(data))
    _equal_or_refused(path, original)


_CORE = ["t", "q", "dq", "tau"]


def _mutated_array(array: np.ndarray, how: str, where: int, name: str) -> np.ndarray:
    """``array`` made wrong in one way (every result is an invalid trajectory array)."""
    flat = array.astype(float).copy().reshape(-1)
    if how in ("nan", "inf", "-inf"):
        flat[where % flat.size] = float(how)
        return flat.reshape(array.shape)
    return {
        "object": lambda: np.array([object()] * array.shape[0], dtype=object),
        "complex": lambda: array.astype(complex),
        "int": lambda: array.astype(np.int64),
        "float32": lambda: array.astype(np.float32),
        "bool": lambda: array != 0,
        "string": lambda: array.astype("U8"),
        "structured": lambda: np.zeros(array.shape[0], dtype=[("a", "<f8")]),
        "datetime": lambda: np.zeros(array.shape, dtype="datetime64[s]"),
        "drop_row": lambda: array[:-1],
        "add_row": lambda: np.concatenate([array, array[-1:] + 1.0]),
        "transpose": lambda: np.ascontiguousarray(array.T) if array.ndim == 2
        else array[:, None],
        "extra_axis": lambda: array[..., None, None],
        "empty": lambda: array[:0],
        "scalar": lambda: np.array(1.0),
        "reversed": lambda: array[::-1].copy() if name == "t" else array[:, :-1],
        "repeat": lambda: np.r_[array[:1], array[:-1]] if name == "t" else array[:, :0],
    }[how]()


_HOW = st.sampled_from(["nan", "inf", "-inf", "object", "complex", "int", "float32", "bool",
                        "string", "structured", "datetime", "drop_row", "add_row",
                        "transpose", "extra_axis", "empty", "scalar", "reversed", "repeat"])


@_FUZZ
@given(name=st.sampled_from(_CORE), how=_HOW, where=st.integers(0, 10**6))
def test_bad_arrays_are_refused(members: dict[str, bytes], tmp_path: Path, name: str,
                                how: str, where: int) -> None:
    """NaN/inf, wrong dtypes (object, complex, ...), shapes, lengths or times: refused."""
    bad = _mutated_array(_array(members, name), how, where, name)
    path = tmp_path / "bad.npz"
    path.write_bytes(_zip({**members, f"{name}.npy": _npy(bad)}))
    message = _refused(path)
    if how == "object":
        assert "pickle" in message


@_FUZZ
@given(change=st.sampled_from(["drop", "add", "rename", "signal_dtype", "signal_length"]),
       which=st.sampled_from([*_CORE, "header", "signal__R"]),
       extra=st.sampled_from(["extra.npy", "signal__Z.npy", "t.txt", "../evil.npy",
                              "dir/t.npy"]))
def test_bad_members_are_refused(members: dict[str, bytes], tmp_path: Path, change: str,
                                 which: str, extra: str) -> None:
    """A missing, unknown, renamed or malformed member is refused."""
    contents = dict(members)
    if change == "drop":
        del contents[f"{which}.npy"]
    elif change == "add":
        contents[extra] = _npy(np.zeros(3))
    elif change == "rename":
        contents[extra] = contents.pop(f"{which}.npy")
    elif change == "signal_dtype":
        contents["signal__R.npy"] = _npy(np.array(["a"] * 2, dtype=object))
    else:
        contents["signal__R.npy"] = _npy(np.zeros(3))
    path = tmp_path / "members.npz"
    path.write_bytes(_zip(contents))
    _refused(path)


_NOT = {"params": st.one_of(st.none(), st.integers(), st.text(max_size=5), st.lists(st.none())),
        "reason": st.one_of(st.none(), st.integers(), st.lists(st.text(max_size=3))),
        "meta": st.one_of(st.none(), st.integers(), st.text(max_size=5), st.lists(st.none())),
        "summary": st.one_of(st.none(), st.floats(), st.text(max_size=5)),
        "signals": st.one_of(st.none(), st.text(max_size=5), st.just(["R", "R", "V"]),
                             st.just(["R"]), st.just(["R", "V", "X"]), st.just([1, 2]),
                             st.just({"R": 1})),
        "status": st.one_of(st.integers(), st.sampled_from(["finished", "", "COMPLETED"])),
        "diverged": st.one_of(st.just(True), st.integers(2, 9), st.text(max_size=3))}
_BAD_PARAMS = st.sampled_from([{"n": 0}, {"n": 5}, {"n": 10.5}, {"n": "10"}, {"mass": -1.0},
                               {"mass": "x"}, {"link_length": float("nan")}, {"colour": 1},
                               {"passive": [42]}, {"passive": 5}, {"inertia": None}])


@_FUZZ
@given(data=st.data())
def test_bad_headers_are_refused(members: dict[str, bytes], tmp_path: Path,
                                 data: st.DataObject) -> None:
    """Not JSON, not an object, missing keys, wrong types, rejected params: refused."""
    good = _header(members)
    kind = data.draw(st.sampled_from(["truncated", "not_object", "missing", "wrong_type",
                                      "params", "not_string"]))
    path = tmp_path / "header.npz"
    if kind == "truncated":
        text = json.dumps(good)
        path.write_bytes(_with_header(members, text[: data.draw(st.integers(0, len(text) - 1))]))
    elif kind == "not_object":
        value = data.draw(st.one_of(st.none(), st.integers(), st.lists(st.integers()),
                                    st.text(max_size=5)))
        path.write_bytes(_with_header(members, json.dumps(value)))
    elif kind == "missing":
        keys = data.draw(st.sampled_from([["params"], ["reason"], ["meta"], ["summary"],
                                          ["signals"], ["status", "diverged"]]))
        path.write_bytes(_with_header(members, {k: v for k, v in good.items() if k not in keys}))
    elif kind == "wrong_type":
        key = data.draw(st.sampled_from(sorted(_NOT)))
        path.write_bytes(_with_header(members, {**good, key: data.draw(_NOT[key])}))
    elif kind == "params":
        params = {**good["params"], **data.draw(_BAD_PARAMS)}
        path.write_bytes(_with_header(members, {**good, "params": params}))
    else:
        value = data.draw(st.sampled_from([np.zeros(3), np.array([json.dumps(good)] * 2),
                                           np.array(json.dumps(good).encode())]))
        path.write_bytes(_zip({**members, "header.npy": _npy(value)}))
    _refused(path)


# ------------------------------------------------------------------ bounded memory
def _deflated_zeros(prefix: bytes, chunks: int) -> tuple[bytes, int, int]:
    """A raw deflate stream of ``prefix`` + ``chunks`` MiB of zeros, built in milliseconds.

    After a full flush deflate restarts, so every MiB of zeros compresses to the same
    bytes: compress one and repeat it. Returns (stream, decompressed size, CRC-32).
    """
    zeros = bytes(1 << 20)
    packer = zlib.compressobj(9, zlib.DEFLATED, -15)
    first = packer.compress(prefix + zeros) + packer.flush(zlib.Z_FULL_FLUSH)
    block = packer.compress(zeros) + packer.flush(zlib.Z_FULL_FLUSH)
    stream = first + block * (chunks - 1) + packer.flush()
    crc = zlib.crc32(prefix)
    big = bytes(16 << 20)
    for _ in range(chunks // 16):
        crc = zlib.crc32(big, crc)
    for _ in range(chunks % 16):
        crc = zlib.crc32(zeros, crc)
    return stream, len(prefix) + (chunks << 20), crc


def _with_raw_member(valid: bytes, name: str, stream: bytes, size: int, crc: int) -> bytes:
    """``valid`` (a zip) plus one deflated member given as its raw stream."""
    out = io.BytesIO()
    central = []
    with zipfile.ZipFile(io.BytesIO(valid)) as archive:
        entries = [(i.filename, 8 if i.compress_type == zipfile.ZIP_DEFLATED else 0,
                    i.CRC, _raw(valid, i), i.file_size) for i in archive.infolist()]
    for entry_name, method, entry_crc, data, entry_size in [*entries,
                                                            (name, 8, crc, stream, size)]:
        encoded = entry_name.encode()
        offset = out.tell()
        out.write(struct.pack("<4s5H3L2H", b"PK\x03\x04", 20, 0, method, 0, 0x21, entry_crc,
                              len(data), entry_size, len(encoded), 0) + encoded + data)
        central.append(struct.pack("<4s6H3L5H2L", b"PK\x01\x02", 20, 20, 0, method, 0, 0x21,
                                   entry_crc, len(data), entry_size, len(encoded), 0, 0, 0, 0,
                                   0, offset) + encoded)
    start = out.tell()
    out.write(b"".join(central))
    out.write(struct.pack("<4s4H2LH", b"PK\x05\x06", 0, 0, len(central), len(central),
                          out.tell() - start, start, 0))
    return out.getvalue()


def _raw(data: bytes, info: zipfile.ZipInfo) -> bytes:
    name_len, extra_len = struct.unpack("<2H", data[info.header_offset + 26:
                                                    info.header_offset + 30])
    start = info.header_offset + 30 + name_len + extra_len
    return data[start: start + info.compress_size]


def _peak_bytes(call) -> tuple[Any, int]:
    tracemalloc.start()
    try:
        result = call()
    except TrajectoryFileError as exc:
        result = exc
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return result, peak


def test_a_3_gib_signal_in_a_4_mb_file(original: Trajectory, tmp_path: Path) -> None:
    """The unused 3 GiB signal is never decompressed; asking for it is refused up front."""
    small = Trajectory(t=original.t, q=original.q, dq=original.dq, tau=original.tau,
                       params=original.params, signals={"R": original.signals["R"]})
    small.save(tmp_path / "base")
    valid = (tmp_path / "base.npz").read_bytes()
    with zipfile.ZipFile(io.BytesIO(valid)) as archive:
        body = dict((n, archive.read(n)) for n in archive.namelist())
    header = _header(body)
    header["signals"] = ["R", "big"]
    valid = _with_header(body, header)
    count = 3 * 2**30 // 8
    npy_header = io.BytesIO()
    np.lib.format.write_array_header_1_0(npy_header, {"descr": "<f8", "fortran_order": False,
                                                      "shape": (count,)})
    stream, size, crc = _deflated_zeros(npy_header.getvalue(), 3 * 1024)
    path = tmp_path / "bomb.npz"
    path.write_bytes(_with_raw_member(valid, "signal__big.npy", stream, size, crc))
    assert path.stat().st_size < 4_000_000
    with zipfile.ZipFile(path) as archive:  # a well-formed zip: 3 GiB once inflated
        assert archive.getinfo("signal__big.npy").file_size > 3 * 2**30 > MAX_ARRAY_BYTES

    loaded, peak = _peak_bytes(lambda: Trajectory.load(path, signals=False))
    assert isinstance(loaded, Trajectory) and _same(small, loaded, signals=False)
    assert peak < 16 * 2**20
    loaded, peak = _peak_bytes(lambda: Trajectory.load(path, signals=["R"]))
    assert isinstance(loaded, Trajectory) and sorted(loaded.signals) == ["R"]
    assert peak < 16 * 2**20
    refused, peak = _peak_bytes(lambda: Trajectory.load(path))
    assert isinstance(refused, TrajectoryFileError) and "bound" in str(refused)
    assert "\n" not in str(refused) and peak < 16 * 2**20


def test_an_array_longer_than_its_header_says(original: Trajectory, tmp_path: Path) -> None:
    """A member whose stream runs on past its declared shape is refused after one extra byte."""
    small = Trajectory(t=original.t, q=original.q, dq=original.dq, tau=original.tau,
                       params=original.params)
    small.save(tmp_path / "base")
    with zipfile.ZipFile(tmp_path / "base.npz") as archive:
        body = {n: archive.read(n) for n in archive.namelist() if n != "t.npy"}
        valid = _zip(body)
    npy = _npy(original.t)
    stream, size, crc = _deflated_zeros(npy, 512)  # t, then 512 MiB of zeros
    path = tmp_path / "long.npz"
    path.write_bytes(_with_raw_member(valid, "t.npy", stream, size, crc))
    refused, peak = _peak_bytes(lambda: Trajectory.load(path))
    assert isinstance(refused, TrajectoryFileError) and "beyond its declared shape" in str(refused)
    assert peak < 16 * 2**20


# ---------------------------------------------------------------- what is opened at all
def _refused_at_once(path: Path) -> str:
    """``_refused(path)`` from a thread: a load that blocks (a FIFO opened) fails."""
    text: list[str] = []
    error = raised_without_blocking(lambda: text.append(_refused(path)), "Trajectory.load")
    assert error is None and len(text) == 1, error
    return text[0]


def test_a_fifo_is_refused_without_blocking(tmp_path: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    """A FIFO named as a trajectory (or put in place after the name was checked) is
    refused at once, never opened for a blocking read."""
    fifo = tmp_path / "run.npz"
    os.mkfifo(fifo)
    assert "not a regular file" in _refused_at_once(fifo)
    assert "no such snake_pin trajectory" in _refused_at_once(tmp_path / "run")
    monkeypatch.setattr(trajectory, "_resolve", lambda path: Path(path))
    assert _refused_at_once(fifo) == \
        f"{fifo}: is a FIFO, not a regular file: not a snake_pin trajectory"


def test_a_file_beyond_the_size_bound_is_refused_unread(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """A file larger than twice MAX_TOTAL_BYTES is refused from its size: no zip is read."""
    huge = tmp_path / "huge.npz"
    with open(huge, "wb") as handle:
        handle.truncate(2 * MAX_TOTAL_BYTES + 1)  # sparse: nothing written
    monkeypatch.setattr(zipfile, "ZipFile", lambda *a, **k: pytest.fail("read as a zip"))
    assert f"is larger than {2 * MAX_TOTAL_BYTES} bytes" in _refused(huge)
