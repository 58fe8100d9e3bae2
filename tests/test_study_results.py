"""Tests of snake_pin.study.results, .summary and .report: the folder, Parquet, the page."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
import pytest

from snake_pin.study import StudyError, StudySummary
from snake_pin.study.report import figure_plan, write_index
from snake_pin.study.results import SCHEMA, StudyFolder, batch_name, rows_table
from snake_pin.study.spec import SETTINGS, parse_study
from snake_pin.study.work import failed_row

STUDY = """
[study]
name = "unit"
[base]
t_final = 0.5
error_window = 0.1
c_x = 0.5
[axes.c_y]
values = [10.0, 25.0]
[axes.failed_joint]
values = [0, 5]
[axes.init_noise]
uniform = [0.0, 0.05]
samples = 2
seed = 3
"""


def _rows(spec, scenarios) -> list[dict]:
    """Cheap stand-in rows: failed_row plus made-up metrics (no simulation)."""
    rows = []
    for s in scenarios:
        row = failed_row(s, "")
        row.update(status="ok", rms_head_error_pct=1.0 + s.index, R_tilde_min=0.01 / (1 + s.index),
                   t_end=0.5, wall_time=0.1)
        rows.append(row)
    return rows


def _reject_constant(name: str) -> None:
    raise ValueError(f"non-RFC JSON constant {name}")


def test_schema_has_every_setting_and_the_metrics() -> None:
    """Each setting is a column of its kind; key, status and the metrics follow."""
    for name, setting in SETTINGS.items():
        kind = str(SCHEMA.field(name).type)
        assert kind == {"float": "double", "int": "int64", "str": "string",
                        "joints": "string", "bool": "bool"}[setting.kind], name
    for name in ("key", "status", "reason", "rms_head_error_pct", "R_min", "R_tilde_min",
                 "D_min", "t_end", "torque_rms", "wall_time", "robot_params"):
        assert name in SCHEMA.names


def test_rows_table_fills_missing_columns_with_null_and_refuses_unknown_ones() -> None:
    """A row without engine settings has nulls there; an extra column is refused."""
    spec = parse_study(STUDY)
    table = rows_table(_rows(spec, spec.scenarios[:2]))
    assert table.schema == SCHEMA
    assert table.column("mu").to_pylist() == [None, None]
    assert table.column("c_y").to_pylist() == [10.0, 10.0]
    with pytest.raises(StudyError, match="unknown columns: bogus"):
        rows_table([{**_rows(spec, spec.scenarios[:1])[0], "bogus": 1}])


def test_batches_are_written_whole_and_pandas_reads_the_folder(tmp_path: Path) -> None:
    """pandas.read_parquet(DIR/runs) sees every written row and skips hidden temporaries."""
    spec = parse_study(STUDY)
    folder = StudyFolder(tmp_path / "out")
    folder.check(spec)
    with folder.locked(spec):
        first, second = spec.scenarios[:3], spec.scenarios[3:]
        path = folder.write_batch([s.key for s in first], _rows(spec, first))
        folder.write_batch([s.key for s in second], _rows(spec, second))
        assert path.name == batch_name([s.key for s in first])
        (folder.runs / ".batch-x.parquet.snake_pin-1-abc.tmp").write_bytes(b"half a file")
        frame = pd.read_parquet(tmp_path / "out" / "runs")
        assert sorted(frame["index"]) == list(range(len(spec.scenarios)))
        assert set(frame["key"]) == folder.done_keys() == {s.key for s in spec.scenarios}
        assert frame["c_y"].dtype == "float64" and frame["failed_joint"].dtype == "int64"
        assert json.loads((tmp_path / "out" / "study.json").read_text())["study_hash"] == \
            spec.study_hash


def test_an_unreadable_batch_file_is_named(tmp_path: Path) -> None:
    """A batch file that is not Parquet stops the resume with its name, in one line."""
    spec = parse_study(STUDY)
    folder = StudyFolder(tmp_path)
    folder.prepare(spec)
    folder.release()
    bad = folder.runs / "batch-0000.parquet"
    bad.write_bytes(b"PAR1 not really")
    with pytest.raises(StudyError) as info:
        folder.done_keys()
    assert str(bad) in str(info.value) and "\n" not in str(info.value)


def test_a_folder_holds_one_study(tmp_path: Path) -> None:
    """Another study's folder, a non-empty foreign folder and a file are refused."""
    spec = parse_study(STUDY)
    other = parse_study(STUDY.replace("25.0", "30.0"))
    folder = StudyFolder(tmp_path / "out")
    with folder.locked(spec):
        pass
    folder.check(spec)  # the same study: fine
    with pytest.raises(StudyError, match="holds a different study"):
        folder.check(other)
    (tmp_path / "foreign").mkdir()
    (tmp_path / "foreign" / "notes.txt").write_text("mine")
    with pytest.raises(StudyError, match="not empty and holds no study"):
        StudyFolder(tmp_path / "foreign").check(spec)
    (tmp_path / "file").write_text("x")
    with pytest.raises(StudyError, match="is not a folder"):
        StudyFolder(tmp_path / "file").check(spec)


def test_the_folder_lock_refuses_a_second_writer(tmp_path: Path) -> None:
    """While one StudyFolder holds the lock, another prepare() is refused."""
    spec = parse_study(STUDY)
    with StudyFolder(tmp_path).locked(spec):
        with pytest.raises(StudyError, match="another study run is writing"):
            StudyFolder(tmp_path).prepare(spec)
    with StudyFolder(tmp_path).locked(spec):
        pass  # released: free again


def test_figure_plan_follows_the_axes() -> None:
    """Two grid axes: heatmap; one: lines with bands over seeds/random axes; none: histogram."""
    assert figure_plan(parse_study(STUDY)) == ("heatmap", ["c_y", "failed_joint"],
                                               ["init_noise"])
    one = parse_study("[axes.lam]\nvalues = [5.0, 10.0]\n[axes.init_seed]\nvalues = [1, 2]\n")
    assert figure_plan(one) == ("lines", ["lam"], ["init_seed"])
    assert figure_plan(parse_study("[base]\nt_final = 1.0\n"))[0] == "histogram"


@pytest.mark.parametrize("axes", [STUDY, "[base]\nt_final = 0.5\n[axes.lam]\n"
                                  "values = [5.0, 10.0]\n[axes.init_seed]\nvalues = [1, 2]\n"])
def test_index_is_self_contained_with_a_sortable_table_and_strict_json(tmp_path: Path,
                                                                       axes: str) -> None:
    """index.html embeds its PNGs, lists every run; summary.json has no NaN."""
    spec = parse_study(axes)
    folder = StudyFolder(tmp_path)
    with folder.locked(spec):
        done = spec.scenarios[:-1]  # one run missing, as after an interrupt
        folder.write_batch([s.key for s in done], _rows(spec, done))
        summary = StudySummary(name=spec.name, study_hash=spec.study_hash, folder=str(tmp_path),
                               status="interrupted", runs=len(spec.scenarios),
                               recorded=len(done), wall_time=float("nan"),
                               note="study unit interrupted")
        page = write_index(folder, spec, summary).read_text()
    assert len(re.findall(r"<img [^>]*src='data:image/png;base64,", page)) == 2
    assert not re.search(r"(src|href)=['\"]https?:", page)
    assert page.count("<tr>") == 1 + len(done)
    assert "class='sortable'" in page and "addEventListener('click'" in page
    assert "Interrupted:" in page and "study unit interrupted" in page
    data = json.loads((tmp_path / "summary.json").read_text(), parse_constant=_reject_constant)
    assert data["status"] == "interrupted" and data["wall_time"] is None
    assert data == summary.to_dict()


def test_summary_dict_is_plain_and_text_names_the_counts() -> None:
    """to_dict() holds only JSON types (NaN -> None); text() says status and counts."""
    summary = StudySummary(name="s", study_hash="ab", folder="/x", runs=4, recorded=3, ran=3,
                           statuses={"ok": 2, "diverged": 1, "failed": 0},
                           wall_time=math.inf, scheduler="local (2 workers)")
    data = summary.to_dict()
    assert json.loads(json.dumps(data, allow_nan=False)) == data
    assert data["wall_time"] is None
    assert "3/4 runs recorded (2 ok, 1 diverged)" in summary.text()


def test_written_batches_keep_the_parameters_of_each_run(tmp_path: Path) -> None:
    """Each row carries its run's settings and resolved robot (robot_params JSON)."""
    spec = parse_study(STUDY)
    folder = StudyFolder(tmp_path)
    with folder.locked(spec):
        folder.write_batch([s.key for s in spec.scenarios], _rows(spec, spec.scenarios))
    table = pq.read_table(folder.runs)
    by_key = {s.key: s for s in spec.scenarios}
    for row in table.to_pylist():
        scenario = by_key[row["key"]]
        for name, value in scenario.settings.items():
            if name == "passive":
                value = ",".join(map(str, value))
            elif value is None:  # friction: the robot's own
                value = getattr(scenario.params, name)
            assert row[name] == value, name
        assert json.loads(row["robot_params"]) == scenario.params.to_dict()


def test_figures_label_the_axes_in_words_and_show_c_y_as_the_friction_ratio(
        tmp_path: Path) -> None:
    """save_figures writes one PNG per metric whose axes read "c_y/c_x" (ticks 20, 50) and
    "failed joint"; log colours for R~ grey out cells 1e6 below the largest."""
    from matplotlib import image

    from snake_pin.study.report import axis_label, save_figures

    spec = parse_study(STUDY)
    label, shown = axis_label(spec, "c_y")
    assert label.startswith("c_y/c_x") and [shown(v) for v in (10.0, 25.0)] == [20.0, 50.0]
    assert axis_label(spec, "failed_joint")[0] == "failed joint (0: none)"
    mixed = parse_study("[axes.c_x]\nvalues = [0.5, 1.0]\n[axes.c_y]\nvalues = [5.0, 25.0]\n")
    assert axis_label(mixed, "c_y")[0] == "c_y [N s/m]"  # no single c_x: no ratio
    rows = _rows(spec, spec.scenarios)
    for row in rows:
        if row["failed_joint"] == 5 and row["c_y"] == 10.0:
            row["R_tilde_min"] = 1e-18  # structurally zero: below the log floor
    figures = save_figures(spec, rows, tmp_path, "map")
    assert [p.name for p, _ in figures] == ["map_rms_head_error_pct.png",
                                            "map_R_tilde_min.png"]
    assert all(image.imread(p).shape[0] > 100 for p, _ in figures)
    assert "c_y/c_x" in figures[0][1] and "failed joint" in figures[0][1]
    assert "grey" in figures[1][1] and "grey" not in figures[0][1]


# ------------------------------------------------------------ folder safety
def _prepared(tmp_path: Path) -> tuple[StudyFolder, object]:
    spec = parse_study(STUDY)
    folder = StudyFolder(tmp_path / "out")
    with folder.locked(spec):
        pass
    return folder, spec


def test_a_symbolic_link_as_the_folder_or_its_runs_is_refused(tmp_path: Path) -> None:
    """DIR or DIR/runs as a link to another folder: one line, nothing written there."""
    folder, spec = _prepared(tmp_path)
    outside = tmp_path / "outside"
    outside.mkdir()
    (tmp_path / "link").symlink_to(outside)
    with pytest.raises(StudyError, match="is a symbolic link") as info:
        StudyFolder(tmp_path / "link").prepare(spec)
    assert "\n" not in str(info.value)
    (folder.runs).rmdir()
    folder.runs.symlink_to(outside)
    for action in (lambda: folder.check(spec), lambda: folder.prepare(spec),
                   folder.done_keys,
                   lambda: folder.write_batch([spec.scenarios[0].key],
                                              _rows(spec, spec.scenarios[:1]))):
        with pytest.raises(StudyError, match="runs is a symbolic link"):
            action()
    assert list(outside.iterdir()) == []


def test_a_linked_lock_or_identity_is_not_followed(tmp_path: Path) -> None:
    """DIR/.lock linked to a missing file is refused without creating it; a linked
    study.json is not read."""
    folder, spec = _prepared(tmp_path)
    target = tmp_path / "victim"
    (folder.path / ".lock").unlink()
    (folder.path / ".lock").symlink_to(target)
    with pytest.raises(StudyError, match="lock"):
        folder.prepare(spec)
    assert not target.exists() and folder._lock is None
    (folder.path / ".lock").unlink()
    real = tmp_path / "identity.json"
    (folder.path / "study.json").rename(real)
    (folder.path / "study.json").symlink_to(real)
    with pytest.raises(StudyError, match="not a readable study identity"):
        folder.check(spec)


def test_an_identity_that_is_not_a_small_regular_file_is_refused(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """study.json as a FIFO (never opened: it would block) or beyond the size bound is
    refused in one line naming it."""
    import os

    from snake_pin.study import results

    folder, spec = _prepared(tmp_path)
    identity = folder.path / "study.json"
    size = identity.stat().st_size
    monkeypatch.setattr(results, "_MAX_IDENTITY_BYTES", size - 1)
    with pytest.raises(StudyError, match=f"larger than {size - 1} bytes") as info:
        folder.check(spec)
    assert str(identity) in str(info.value) and "\n" not in str(info.value)
    monkeypatch.undo()
    identity.unlink()
    os.mkfifo(identity)
    with pytest.raises(StudyError, match="FIFO, not a regular file") as info:
        folder.check(spec)
    assert str(identity) in str(info.value)


def test_a_batch_file_beyond_the_size_bound_is_refused(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A batch file larger than the bound is refused with its name, never counted as done."""
    from snake_pin.study import results

    folder, spec = _prepared(tmp_path)
    path = folder.runs / batch_name([spec.scenarios[0].key])
    pq.write_table(rows_table(_rows(spec, spec.scenarios[:1])), path)
    assert folder.done_keys() == {spec.scenarios[0].key}
    monkeypatch.setattr(results, "_MAX_BATCH_FILE_BYTES", path.stat().st_size - 1)
    with pytest.raises(StudyError, match=r"larger than \d+ bytes") as info:
        folder.done_keys()
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_a_folder_that_cannot_be_written_fails_before_any_run(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Writing probed for real: a folder under a file, or one whose writes fail (as on a
    read-only filesystem), is refused by prepare() in one line, before any cluster starts."""
    import errno
    import tempfile

    from snake_pin.study import runner

    spec = parse_study(STUDY)
    (tmp_path / "file").write_text("x")
    with pytest.raises(StudyError, match="cannot create the folder"):
        StudyFolder(tmp_path / "file" / "out").prepare(spec)
    study = tmp_path / "study.toml"
    study.write_text(STUDY)

    def read_only(*_args: object, **_kwargs: object) -> None:
        raise OSError(errno.EROFS, "Read-only file system")

    def no_cluster(*_args: object, **_kwargs: object) -> None:
        raise AssertionError("a cluster was started")

    monkeypatch.setattr(tempfile, "mkstemp", read_only)
    monkeypatch.setattr(runner, "dask_client", no_cluster)
    with pytest.raises(StudyError, match=r"cannot write here \(Read-only file system") as info:
        runner.run_study(study, tmp_path / "ro")
    assert "\n" not in str(info.value)
    assert not (tmp_path / "ro" / "study.json").exists()


def _write_part(folder: StudyFolder, name: str, table: object) -> Path:
    path = folder.runs / name
    pq.write_table(table, path)
    return path


def test_a_part_file_missing_columns_or_with_bad_rows_is_refused_not_counted(
        tmp_path: Path) -> None:
    """Parts with only `key`, a wrong column type, a null key or an unknown status are
    refused by done_keys, read_table and the page, each naming the file; a good part is
    read."""
    import pyarrow as pa

    folder, spec = _prepared(tmp_path)
    first = spec.scenarios[:2]
    good = rows_table(_rows(spec, first))
    folder.write_batch([s.key for s in first], _rows(spec, first))
    assert folder.done_keys() == {s.key for s in first}
    key = spec.scenarios[2].key
    status_at = SCHEMA.get_field_index("status")
    bad = {
        "batch-key-only.parquet": (pa.table({"key": [key]}), "columns missing"),
        "batch-int-status.parquet": (good.set_column(status_at, "status", pa.array([1, 2])),
                                     "column status is int64"),
        "batch-null-key.parquet": (good.set_column(SCHEMA.get_field_index("key"), "key",
                                                   pa.array([None, key], pa.string())),
                                   "no key"),
        "batch-bad-status.parquet": (good.set_column(status_at, "status",
                                                     pa.array(["ok", "done"])), "status"),
    }
    summary = StudySummary(name="unit", study_hash=spec.study_hash, folder=str(folder.path))
    for name, (table, problem) in bad.items():
        path = _write_part(folder, name, table)
        for read in (folder.done_keys, folder.read_table,
                     lambda: write_index(folder, spec, summary)):
            with pytest.raises(StudyError, match=re.escape(problem)) as info:
                read()
            assert str(path) in str(info.value) and "\n" not in str(info.value)
        path.unlink()
    assert folder.done_keys() == {s.key for s in first}
    assert folder.read_table(["key", "c_y"]).num_rows == 2


def test_a_batch_without_the_mpc_columns_reads_them_as_null(tmp_path: Path) -> None:
    """A batch file written before the MPC's settings were columns is read, every MPC column
    null and the others as written; lacking any other column it is refused."""
    from snake_pin.study.results import _OPTIONAL

    folder, spec = _prepared(tmp_path)
    first = spec.scenarios[:2]
    full = rows_table(_rows(spec, first))
    assert {"horizon", "feedback", "weight_torque"} <= _OPTIONAL
    older = full.drop_columns(sorted(_OPTIONAL))
    _write_part(folder, "batch-older.parquet", older)
    assert folder.done_keys() == {s.key for s in first}
    table = folder.read_table()
    assert table.schema == SCHEMA
    assert table.select(older.column_names).equals(older)
    assert all(table.column(name).null_count == 2 for name in _OPTIONAL)
    _write_part(folder, "batch-older-still.parquet", older.drop_columns(["c_y"]))
    with pytest.raises(StudyError, match="1 columns missing: c_y"):
        folder.read_table()


def test_part_files_that_are_not_regular_files_are_refused(tmp_path: Path) -> None:
    """A FIFO (never opened: it would block), a folder or a link named *.parquet in runs/
    is refused with its name."""
    import os

    folder, spec = _prepared(tmp_path)
    real = tmp_path / "elsewhere.parquet"
    pq.write_table(rows_table(_rows(spec, spec.scenarios[:1])), real)
    makers = {"batch-fifo.parquet": os.mkfifo, "batch-dir.parquet": os.mkdir,
              "batch-link.parquet": lambda p: os.symlink(real, p)}
    for name, make in makers.items():
        path = folder.runs / name
        make(path)
        with pytest.raises(StudyError, match="not a regular file") as info:
            folder.done_keys()
        assert str(path) in str(info.value)
        os.rmdir(path) if path.is_dir() and not path.is_symlink() else path.unlink()
    assert folder.done_keys() == set()


# ------------------------------------------------------------------ categories
def _tick_labels(axis: object) -> list[str]:
    return [t.get_text() for t in axis.get_ticklabels()]


def test_categorical_axes_are_drawn_as_categories() -> None:
    """The failed joint and the controller get one tick per value labelled with it (also in
    a heatmap); a real-valued axis stays to scale (its points at c_y/c_x)."""
    from snake_pin.study.report import _figure_objects, is_categorical

    assert is_categorical("failed_joint", [0, 5, 9]) and is_categorical("controller", ["a"])
    assert not is_categorical("c_y", [10.0, 25.0])
    joints = parse_study("[base]\nt_final = 0.5\n[axes.failed_joint]\nvalues = [0, 5, 9]\n"
                         "[axes.init_seed]\nvalues = [1, 2]\n")
    controllers = parse_study("[base]\nt_final = 0.5\n[axes.controller]\n"
                              "values = [\"lyapunov\", \"velocity\"]\n")
    for spec, name, labels in ((joints, "failed_joint", ["0", "5", "9"]),
                               (controllers, "controller", ["lyapunov", "velocity"])):
        figures = _figure_objects("lines", [name], spec, _rows(spec, spec.scenarios))
        assert len(figures) == 2
        for _, _, fig in figures:
            ax = fig.axes[0]
            assert _tick_labels(ax.xaxis) == labels
            assert list(ax.get_xticks()) == list(range(len(labels)))
    spec = parse_study(STUDY)
    for _, _, fig in _figure_objects("heatmap", ["c_y", "failed_joint"], spec,
                                     _rows(spec, spec.scenarios)):
        assert _tick_labels(fig.axes[0].yaxis) == ["0", "5"]
    ratio = parse_study("[base]\nt_final = 0.5\nc_x = 0.5\n[axes.c_y]\n"
                        "values = [10.0, 25.0, 40.0]\n")
    _, _, fig = _figure_objects("lines", ["c_y"], ratio, _rows(ratio, ratio.scenarios))[0]
    assert list(fig.axes[0].lines[0].get_xdata()) == [20.0, 50.0, 80.0]
