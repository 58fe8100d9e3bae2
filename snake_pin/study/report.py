"""A study's page, ``DIR/index.html`` (self-contained, figures following the axes:
:ref:`studies`, The study page), and ``DIR/summary.json``; PNG figures for other reports.
"""

from __future__ import annotations

import base64
import html
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._io import atomic_group, atomic_write_bytes
from .._json import json_text
from .results import RUNS, StudyFolder
from .spec import SETTINGS, StudySpec
from .summary import StudySummary

__all__ = ["AXIS_LABELS", "LOG_SPAN", "MAX_TABLE_ROWS", "METRICS"]

#: Most rows in the page's table (all runs are in the Parquet dataset anyway).
MAX_TABLE_ROWS = 2000
#: Metrics plotted: column, label, scale ("log", or "auto": log when the values span a
#: factor of 10 or more).
METRICS = (("rms_head_error_pct", "RMS head error [% of body length]", "auto"),
           ("R_tilde_min", "R~ min along the run", "log"))
#: Words for the axes of the figures (other settings are shown by name).
AXIS_LABELS = {"failed_joint": "failed joint (0: none)", "c_x": "c_x [N s/m]",
               "c_y": "c_y [N s/m]", "c_theta": "c_theta [N m s]", "lam": "lambda [1/s]",
               "lam_shape": "mu [1/s]", "k_shape": "k_shape [1/s^2]", "t_final": "t_final [s]",
               "ref_speed": "reference speed [m/s]", "gait_alpha": "gait alpha [rad]",
               "gait_ts": "gait T_s", "gait_v": "gait v [rad/s]",
               "init_noise": "initial noise [rad]", "mu": "wheel friction mu",
               "wheel_radius": "wheel radius [m]"}
#: A log colour scale spans at most this factor below its largest value.
LOG_SPAN = 1e6
_TABLE_METRICS = ("rms_head_error_pct", "max_head_error_pct", "R_min", "R_tilde_min", "D_min",
                  "t_end", "torque_rms", "wall_time")
_JS = """<script>
document.querySelectorAll('table.sortable th').forEach(function (th, col) {
  th.style.cursor = 'pointer';
  th.addEventListener('click', function () {
    var body = th.closest('table').tBodies[0], rows = Array.from(body.rows);
    var up = th.dataset.dir !== 'up'; th.dataset.dir = up ? 'up' : 'down';
    rows.sort(function (a, b) {
      var x = a.cells[col].dataset.v, y = b.cells[col].dataset.v;
      var nx = parseFloat(x), ny = parseFloat(y);
      var c = (isNaN(nx) || isNaN(ny)) ? String(x).localeCompare(String(y)) : nx - ny;
      return up ? c : -c;
    });
    rows.forEach(function (r) { body.appendChild(r); });
  });
});
</script>"""


def figure_plan(spec: StudySpec) -> tuple[str, list[str], list[str]]:
    """Which figures a study gets (see the module docstring)."""
    replicate = [a.setting for a in spec.axes if a.random or a.setting == "init_seed"]
    shown = [a.setting for a in spec.grid_axes if a.setting not in replicate]
    return ("histogram", "lines", "heatmap")[min(len(shown), 2)], shown[:2], replicate


def write_index(folder: StudyFolder, spec: StudySpec, summary: StudySummary) -> Path:
    """Write ``summary.json`` then ``index.html`` into the study folder."""
    from ..viz.plots import png_bytes

    table = folder.read_table()
    keys = {s.key for s in spec.scenarios}
    columns = {name: table.column(name).to_pylist() for name in table.column_names}
    rows = [{name: columns[name][i] for name in columns} for i in range(table.num_rows)
            if columns["key"][i] in keys]
    rows.sort(key=lambda r: r["index"])
    kind, plotted, replicate = figure_plan(spec)
    figures = [(caption, base64.b64encode(png_bytes(fig, dpi=100)).decode("ascii"))
               for _, caption, fig in _figure_objects(kind, plotted, spec, rows)]
    page = _page(spec, summary, rows, figures, replicate)
    with atomic_group(folder.path) as group:
        group.write_bytes("summary.json", (json_text(summary, indent=2) + "\n").encode())
        group.write_bytes("index.html", page.encode(), figure=True)
    return folder.path / "index.html"


def _ok_values(rows: Sequence[dict[str, Any]], metric: str) -> list[float]:
    return [r[metric] for r in rows if r["status"] == "ok" and _finite(r[metric])]


def _finite(value: Any) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value)


def save_figures(spec: StudySpec, rows: Sequence[dict[str, Any]],
                 folder: str | os.PathLike[str], stem: str) -> list[tuple[Path, str]]:
    """Write the study's figures (:func:`figure_plan`) as ``folder/STEM_METRIC.png``."""
    from ..viz.plots import png_bytes

    kind, plotted, _ = figure_plan(spec)
    out = []
    for metric, caption, fig in _figure_objects(kind, plotted, spec, list(rows)):
        path = Path(folder) / f"{stem}_{metric}.png"
        atomic_write_bytes(path, png_bytes(fig, dpi=100))
        out.append((path, caption))
    return out


def axis_label(spec: StudySpec, name: str) -> tuple[str, Any]:
    """How a figure shows the axis over a setting."""
    if name == "c_y":
        c_x = {s.params.c_x for s in spec.scenarios}
        if len(c_x) == 1:
            value = next(iter(c_x))
            if isinstance(value, float) and value > 0:
                return f"c_y/c_x (c_x = {value:g} N s/m)", lambda v: v / value
    return AXIS_LABELS.get(name, name), lambda v: v


def is_categorical(name: str, values: Sequence[Any]) -> bool:
    """Whether a figure draws the axis over setting ``name`` as categories."""
    setting = SETTINGS.get(name)
    if setting is None or setting.kind != "float":
        return True
    return not all(_finite(v) and not isinstance(v, bool) for v in values)


def _figure_objects(kind: str, plotted: list[str], spec: StudySpec,
                    rows: Sequence[dict[str, Any]]) -> list[tuple[str, str, Any]]:
    """(metric, caption, matplotlib Figure) of each figure."""
    from matplotlib.figure import Figure

    if not rows:
        return []
    out = []
    values = {a.setting: list(a.values) for a in spec.axes}
    for metric, label, scale in METRICS:
        fig = Figure(figsize=(7.5, 4.2), layout="constrained")
        ax = fig.add_subplot()
        data = _ok_values(rows, metric)
        positive = [v for v in data if v > 0]
        log = scale == "log" or (scale == "auto" and bool(positive)
                                 and max(positive) >= 10 * min(positive))
        if kind == "heatmap":
            caption = _heatmap(fig, ax, plotted, spec, values, rows, metric, label, log)
        elif kind == "lines":
            caption = _lines(ax, plotted[0], spec, values[plotted[0]], rows, metric, label,
                             log)
        else:
            shown = [math.log10(v) for v in positive] if log else data
            ax.hist(shown, bins=min(30, max(5, len(shown) // 3 or 1)), color="#4a7bd1")
            ax.set_xlabel(("log10 " if log else "") + label)
            ax.set_ylabel("runs")
            caption = f"{label}: distribution over the {len(data)} successful runs"
        ax.set_title(label, fontsize=10)
        out.append((metric, caption, fig))
    return out


def _heatmap(fig: Any, ax: Any, plotted: list[str], spec: StudySpec,
             values: dict[str, list[Any]], rows: Sequence[dict[str, Any]], metric: str,
             label: str, log: bool) -> str:
    from matplotlib import colormaps
    from matplotlib.colors import LogNorm, Normalize

    x_name, y_name = plotted
    xs, ys = values[x_name], values[y_name]
    grid = np.full((len(ys), len(xs)), np.nan)
    counts = np.zeros((len(ys), len(xs)), dtype=int)
    cells: dict[tuple[int, int], list[float]] = {}
    for r in rows:
        j, i = xs.index(r[x_name]), ys.index(r[y_name])
        counts[i, j] += 1
        if r["status"] == "ok" and _finite(r[metric]):
            cells.setdefault((i, j), []).append(r[metric])
    for (i, j), data in cells.items():
        grid[i, j] = float(np.median(data))
    cmap = colormaps["viridis"].with_extremes(under="0.75", bad="white")
    shown = np.where(grid > 0, grid, np.nan) if log else grid
    finite = shown[np.isfinite(shown)]
    norm: Any = Normalize()
    extend = "neither"
    if log and finite.size:
        top = float(finite.max())
        low = max(float(finite.min()), top / LOG_SPAN)
        norm = LogNorm(vmin=min(low, top / 1.01), vmax=top)
        extend = "min" if finite.min() < low else "neither"
    image = ax.imshow(np.ma.masked_invalid(shown), origin="lower", aspect="auto", cmap=cmap,
                      norm=norm)
    fig.colorbar(image, ax=ax, label=label + (" (log scale)" if log else ""), extend=extend)
    x_label, x_shown = axis_label(spec, x_name)
    y_label, y_shown = axis_label(spec, y_name)
    ax.set_xticks(range(len(xs)), [_tick(x_shown(v)) for v in xs], fontsize=8)
    ax.set_yticks(range(len(ys)), [_tick(y_shown(v)) for v in ys], fontsize=8)
    ax.set_xlabel(x_label)
    ax.set_ylabel(y_label)
    for i, j in np.ndindex(grid.shape) if grid.size <= 400 else ():
        text = "x" if np.isnan(grid[i, j]) and counts[i, j] else \
            ("" if np.isnan(grid[i, j]) else f"{grid[i, j]:.3g}")
        value = shown[i, j]
        light = bool(np.isfinite(value) and (norm(value) > 0.6 or norm(value) < 0))
        ax.text(j, i, text, ha="center", va="center", fontsize=7, color="k" if light else "w")
    return (f"{label}: median over the successful runs of each ({x_label}, {y_label}) cell "
            "(x: no successful run; blank: not run yet"
            + ("; grey: more than a factor 1e6 below the largest" if extend == "min" else "")
            + ")")


def _lines(ax: Any, name: str, spec: StudySpec, xs: list[Any], rows: Sequence[dict[str, Any]],
           metric: str, label: str, log: bool) -> str:
    x_label, x_shown = axis_label(spec, name)
    numeric = not is_categorical(name, xs)
    positions = [float(x_shown(v)) for v in xs] if numeric else list(range(len(xs)))
    data = [_ok_values([r for r in rows if r[name] == v], metric) for v in xs]
    low, med, high = zip(*(np.percentile(d, [10, 50, 90]) if d else [np.nan] * 3
                           for d in data), strict=True)
    ax.fill_between(positions, low, high, color="#4a7bd1", alpha=0.25, label="10-90 %")
    ax.plot(positions, med, "o-", color="#1f4fd1", label="median")
    if not numeric:
        ax.set_xticks(positions, [_tick(x_shown(v)) for v in xs])
        ax.set_xlim(-0.5, len(xs) - 0.5)
    if log:
        ax.set_yscale("log")
    ax.set_xlabel(x_label)
    ax.set_ylabel(label)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    return (f"{label} against {x_label}: median and 10-90 % band over the successful runs at "
            "each value")


def _tick(value: Any) -> str:
    return f"{value:.3g}" if isinstance(value, float) else str(value)


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _cell(value: Any) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "<td data-v=''>-</td>"
    if isinstance(value, float):
        return f"<td data-v='{value!r}'>{value:.4g}</td>"
    return f"<td data-v='{_e(value)}'>{_e(value)}</td>"


def _page(spec: StudySpec, summary: StudySummary, rows: Sequence[dict[str, Any]],
          figures: list[tuple[str, str]], replicate: list[str]) -> str:
    title = f"Study {spec.name}"
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{_e(title)}</title>"
             "<style>body{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em;"
             "line-height:1.45}img{max-width:100%;border:1px solid #ddd}table{border-"
             "collapse:collapse;margin:.5em 0;font-size:.85em}td,th{border:1px solid #bbb;"
             "padding:2px 6px;text-align:right}th{background:#eee}figure{margin:1em 0}"
             "figcaption{color:#444;font-size:.9em}</style></head><body>",
             f"<h1>{_e(title)}</h1>"]
    if spec.description:
        parts.append(f"<p>{_e(spec.description)}</p>")
    if summary.status != "complete":
        parts.append(f"<p id='status' style='background:#fde2e1;padding:.5em'><b>"
                     f"{_e(summary.status.capitalize())}:</b> {_e(summary.note)}</p>")
    counts = ", ".join(f"{v} {k}" for k, v in summary.statuses.items())
    parts.append(f"<p>{summary.recorded} of {summary.runs} runs recorded ({_e(counts)}); "
                 f"this invocation ran {summary.ran} and skipped {summary.skipped} already "
                 f"recorded, in {summary.wall_time:.1f} s on {_e(summary.scheduler)}. Study "
                 f"hash <code>{_e(spec.study_hash[:16])}</code>. Results: "
                 f"<code>pandas.read_parquet(\"{_e(RUNS)}\")</code> in this folder; "
                 "<a href='summary.json'>summary.json</a>, <a href='study.json'>study.json"
                 "</a>.</p>")
    axes = "".join(f"<li><b>{_e(a.setting)}</b> ({_e(a.form)}"
                   + (", replicate" if a.setting in replicate else "") + f"): "
                   f"{_e(', '.join(_tick(v) for v in a.values[:12]))}"
                   + (" ..." if len(a.values) > 12 else "") + "</li>" for a in spec.axes)
    base = ", ".join(f"{k} = {_tick(v)}" for k, v in spec.base.items())
    parts.append(f"<h2>Axes</h2><p>Base: {_e(base or 'defaults')}.</p><ul>{axes}</ul>")
    parts.append("<h2>Figures</h2>")
    if not figures:
        parts.append("<p>No run recorded yet.</p>")
    for caption, data in figures:
        parts.append(f"<figure><img alt='{_e(caption)}' src='data:image/png;base64,{data}'>"
                     f"<figcaption>{_e(caption)}</figcaption></figure>")
    shown_axes = [a.setting for a in spec.axes]
    header = ["index", "key", *shown_axes, "status", "reason", *_TABLE_METRICS]
    cut = (f" The first {MAX_TABLE_ROWS} of {len(rows)} runs are listed; all are in the "
           "Parquet dataset." if len(rows) > MAX_TABLE_ROWS else "")
    parts.append(f"<h2>Runs</h2><p>Click a column header to sort.{cut}</p>"
                 "<table class='sortable'><thead><tr>"
                 + "".join(f"<th>{_e(h)}</th>" for h in header) + "</tr></thead><tbody>")
    for r in rows[:MAX_TABLE_ROWS]:
        cells = [r["index"], r["key"][:12], *(r[a] for a in shown_axes), r["status"],
                 (r["reason"] or "")[:120], *(r[m] for m in _TABLE_METRICS)]
        parts.append("<tr>" + "".join(_cell(c) for c in cells) + "</tr>")
    parts.append("</tbody></table>" + _JS + "</body></html>\n")
    return "".join(parts)

