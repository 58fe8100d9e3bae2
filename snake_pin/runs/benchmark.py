"""The controller benchmark on paths (:doc:`/paths`): the scenarios (:data:`SCENARIOS`), the
built-in controllers (:data:`CONTROLLERS`), the per-run metrics (``path_metrics``), the
grid run in parallel (:func:`run_benchmark`) and its files (:func:`write_benchmark`), for
``snake-pin bench-control``, ``snake-pin simulate/engine --path`` and the report.
"""

from __future__ import annotations

import csv
import io
import json
import math
import pickle
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from .. import control
from .._io import atomic_group
from .._json import json_safe
from .._validation import finite_number, integer
from ..control import Controller
from ..exceptions import ParameterError
from ..manipulability import lateral_constraint_manipulability, manipulability
from ..metrics import ERROR_WINDOW, default_error_window, torque_max
from ..model import Snake
from ..params import SnakeParams
from ..paths import Circle, LaneChange, Line, PathReference, Sinusoid, Timing, Waypoints
from ..paths import Path as Curve
from ..sim import Trajectory, simulate
from .engine import PERTURBATION, distribution, perturbations
from .parallel import SharedCluster, run_jobs
from .tracking import initial_state, tracking_params

__all__ = ["CONTROLLERS", "DEFAULT_CONTROLLERS", "ENGINE_DRAWS", "ENGINE_LAWS", "FAILED_JOINT",
           "METRIC_FIELDS", "MODELS", "PFL_CLIMB_R", "QUICK_T_FINAL", "SCENARIOS", "SPEED",
           "WAYPOINTS", "BenchmarkResult", "ControllerFactory", "run_benchmark", "write_benchmark"]

#: Reference speed along every path [m/s] (the paper's 0.1 m/s).
SPEED = 0.1
#: The longest run of the quick benchmark [s] (``quick=True``).
QUICK_T_FINAL = 12.0
#: The joint that fails (becomes passive) in the failed-joint runs, 1-based.
FAILED_JOINT = 5
#: The waypoints scenario's points [m]: a gentle S-curve over 7.5 m, first leg along +x.
WAYPOINTS = ((0.0, 0.0), (1.0, 0.0), (2.0, 0.35), (3.0, 0.25), (4.0, -0.25), (5.5, 0.0),
             (7.5, 0.3))
#: Scenario name -> the path as a function of the body length L [m].
SCENARIOS: dict[str, Callable[[float], Curve]] = {
    "line": lambda L: Line(),
    "circle_0.5L": lambda L: Circle(radius=0.5 * L),
    "circle_1L": lambda L: Circle(radius=1.0 * L),
    "circle_2L": lambda L: Circle(radius=2.0 * L),
    "lane_change": lambda L: LaneChange(),
    "sinusoid": lambda L: Sinusoid(),
    "waypoints": lambda L: Waypoints(points=WAYPOINTS),
}
#: A controller factory: ``factory(snake, reference, path) -> Controller``.
ControllerFactory = Callable[[Snake, PathReference, Curve], Controller]
#: The models a benchmark can run on.
MODELS = ("viscous", "engine")
#: Sampling of the error metrics (every this many 1 kHz samples: 10 ms) and of the
#: criteria (0.1 s).
_EVERY, _CRITERIA_DT = 10, 0.1
#: Snapshots kept per run for the path figures.
_SNAPSHOTS = 6

#: climb_R of the ``pfl_climb`` controller (its other options are PFLOptions' defaults).
PFL_CLIMB_R = 0.5


def _builtin(name: str, snake: Snake, reference: PathReference, path: Curve) -> Controller:
    """The built-in controller ``name`` of :data:`CONTROLLERS`."""
    if name == "los":
        return control.LOSController(snake, path)
    options = {"pfl_climb": {"options": control.PFLOptions(climb_R=PFL_CLIMB_R)}}.get(name, {})
    law = {"lyapunov": control.LyapunovController,
           "velocity": control.QuasiStaticLyapunovController, "pfl": control.PFLController,
           "pfl_climb": control.PFLController, "mpc": control.MPCController}[name]
    return law(snake, reference, **options)


#: Built-in controller name -> factory.
CONTROLLERS: dict[str, ControllerFactory] = {
    name: partial(_builtin, name)
    for name in ("lyapunov", "velocity", "pfl", "pfl_climb", "los", "mpc")}
#: The built-in controllers a benchmark runs when none is named: all of :data:`CONTROLLERS`.
DEFAULT_CONTROLLERS = tuple(CONTROLLERS)
#: Columns of a benchmark row (CSV order).
METRIC_FIELDS = ("scenario", "controller", "model", "failed_joint", "status", "reason",
                 "t_end", "diverged_at", "head_ct_rms", "head_ct_max", "head_ct_rms_pct",
                 "head_lag_rms", "head_error_rms", "head_error_rms_pct", "cm_ct_rms", "R_min",
                 "R_tilde_min", "lateral_min", "torque_rms", "torque_max", "body_length",
                 "draws", "head_ct_rms_pct_p10", "head_ct_rms_pct_p90", "wall_s")
#: Engine law of each head-tracking controller (:func:`~snake_pin.engine.run.run_engine`).
ENGINE_LAWS = {"lyapunov": "acceleration", "velocity": "velocity", "mpc": "mpc"}
#: Perturbed starts per engine cell: the engine is chaotic, its figures are medians.
ENGINE_DRAWS = 3


def make_scenario(name: str, body_length: float, speed: float = SPEED) -> PathReference:
    """The head reference of scenario ``name`` (circle radii in ``body_length``) at ``speed``
    along the path from s = 0."""
    _known(name, SCENARIOS, "scenario")
    return PathReference(SCENARIOS[name](body_length), Timing(speed))


def _known(name: str, known: Iterable[str], what: str, extra: str = "") -> None:
    """ParameterError unless ``name`` is one of ``known``."""
    if name not in known:
        raise ParameterError(f"unknown {what} {name!r} (expected one of "
                             f"{', '.join(known)}{extra})")


# ----------------------------------------------------------------------------- metrics
def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values)))) if values.size else math.nan


def _project(path: Curve, points: np.ndarray, s_ref: np.ndarray) -> np.ndarray:
    """Arc length of the closest path point: circles on the lap nearest the reference's,
    other paths over the span the reference covers (with a 2 m margin)."""
    if isinstance(path, Circle) and math.isinf(getattr(path, "angle", math.inf)):
        return path.project(points, hint=s_ref)
    lo, hi = float(s_ref.min()) - 2.0, float(s_ref.max()) + 2.0
    return path.project(points, span=(lo, hi))


def _cm_positions(snake: Snake, q: np.ndarray) -> np.ndarray:
    """The centre of mass (x, y) of the links at each configuration of ``q``, shape (N, 2) [m]."""
    masses = snake.params.per_link("mass")
    weights = masses / masses.sum()
    return np.array([weights @ snake.link_poses(qk)[:, :2] for qk in q])


def path_metrics(t: np.ndarray, q: np.ndarray, tau: np.ndarray, snake: Snake,
                 reference: PathReference, *, head_tracking: bool = True,
                 start: float = ERROR_WINDOW, criteria_dt: float | None = _CRITERIA_DT,
                 free_joint: int = FAILED_JOINT) -> dict[str, Any]:
    """The benchmark metrics of one run over ``t >= start`` (:doc:`/paths`; keys of
    :data:`METRIC_FIELDS` and ``D_min``, NaN where the window is empty) and ``series``, the
    criteria along the run sampled every ``criteria_dt`` (None: not computed); R~ frees
    ``free_joint``; without ``head_tracking`` the time-indexed head error is NaN."""
    path, body = reference.path, snake.params.body_length
    mask = t >= start - 1e-9
    tw, qw = t[mask], q[mask]
    out: dict[str, Any] = dict.fromkeys(
        ("head_ct_rms", "head_ct_max", "head_ct_rms_pct", "head_lag_rms", "head_error_rms",
         "cm_ct_rms", "torque_rms"), math.nan)
    if len(tw):
        s_ref = reference.timing(tw)[0]
        head = qw[:, :2]
        s_head = _project(path, head, s_ref)
        g = path.geometry(s_head)
        ct = np.linalg.norm(head - g.p, axis=1)
        lag = s_ref - s_head
        if isinstance(path, Circle) and math.isinf(getattr(path, "angle", math.inf)):
            lap = path.length
            lag = (lag + 0.5 * lap) % lap - 0.5 * lap
        cm = _cm_positions(snake, qw)
        s_cm = _project(path, cm, s_ref)
        out.update(head_ct_rms=_rms(ct), head_ct_max=float(ct.max()),
                   head_ct_rms_pct=100.0 * _rms(ct) / body, head_lag_rms=_rms(lag),
                   cm_ct_rms=_rms(np.linalg.norm(cm - path.geometry(s_cm).p, axis=1)),
                   torque_rms=_rms(tau[mask]))
        if head_tracking:
            out["head_error_rms"] = _rms(np.linalg.norm(head - reference.at(tw)[0][:, :2],
                                                        axis=1))
    series: dict[str, list[float]] = {"t": [], "R": [], "R_tilde": [], "lateral": [], "D": []}
    if criteria_dt is not None and len(t):
        times = np.arange(0.0, t[-1] + 1e-9, criteria_dt)
        idx = np.unique(np.minimum(np.searchsorted(t, times - 1e-9), len(t) - 1))
        for k in idx:
            criteria = manipulability(snake, q[k])
            series["t"].append(float(t[k]))
            series["R"].append(criteria.R)
            series["D"].append(criteria.D)
            series["R_tilde"].append(manipulability(snake, q[k], free_joint=free_joint).R)
            series["lateral"].append(lateral_constraint_manipulability(snake, q[k]).D)
    for key, name in (("R", "R_min"), ("R_tilde", "R_tilde_min"), ("lateral", "lateral_min"),
                      ("D", "D_min")):
        out[name] = float(np.min(series[key])) if series[key] else math.nan
    out["series"] = series
    return out


# ------------------------------------------------------------------------------- runs
def _engine_cell(row: dict[str, Any], scenario: str, controller: str, failed: int | None,
                 t_final: float, factory: ControllerFactory | None,
                 criteria_dt: float | None, draws: int,
                 robot: SnakeParams | None, start: float) -> dict[str, Any]:
    """An engine cell of ``run_cell``: snapshots, head path and criteria of the median draw
    (head cross-track RMS), the median end time, the status of the first draw to stop early."""
    from ..engine.run import identify_friction, run_engine

    law = ENGINE_LAWS.get(controller)
    if factory is not None or law is None:
        row.update(status="not applicable",
                   reason="the engine runs the head-tracking laws (lyapunov, velocity, mpc) only: "
                          "run_engine has no PFL, LOS or user controller")
        return row
    params = _robot(robot, "engine", failed)
    reference = make_scenario(scenario, params.body_length)
    row["body_length"] = params.body_length
    friction = identify_friction(params.replace(passive=()))
    offsets: list[np.ndarray | None] = (
        list(perturbations(draws, params.n - 1, PERTURBATION, seed=0)) if draws > 1 else [None])
    runs: list[tuple[Trajectory, dict[str, Any]]] = []
    stride = slice(None, None, _EVERY)
    for offset in offsets:
        traj = run_engine(params, t_final=t_final, friction=friction, law=law,
                          initial_offset=offset, reference=reference).trajectory
        metrics = path_metrics(traj.t[stride], traj.q[stride], traj.tau[stride],
                               Snake(traj.params), reference, start=start, criteria_dt=None)
        runs.append((traj, {**metrics, "torque_max": _nan(torque_max(traj))}))
    pct = [m["head_ct_rms_pct"] for _, m in runs]
    spread = distribution(pct)
    finite = sorted((v, k) for k, v in enumerate(pct) if math.isfinite(v))
    median = finite[(len(finite) - 1) // 2][1] if finite else 0
    traj = runs[median][0]
    if criteria_dt is not None:
        row.update(path_metrics(traj.t[stride], traj.q[stride], traj.tau[stride],
                                Snake(traj.params), reference, start=start,
                                criteria_dt=criteria_dt))
    else:
        row.update(runs[median][1])
    for key in ("head_ct_rms", "head_ct_max", "head_ct_rms_pct", "head_lag_rms",
                "head_error_rms", "cm_ct_rms", "torque_rms", "torque_max"):
        row[key] = _nan(distribution([m[key] for _, m in runs])["median"])
    bad = sorted((t for t, _ in runs if t.status != "completed"), key=lambda t: t.t_end)
    status = "completed" if not bad else bad[0].status  # the first draw to stop
    reason = "" if not bad else f"{len(bad)} of {len(runs)} draws: {bad[0].reason}"
    _finish(row, traj, status, reason)
    row.update(draws=len(runs),
               head_ct_rms_pct_p10=_nan(spread["p10"]), head_ct_rms_pct_p90=_nan(spread["p90"]),
               t_end=float(np.median([t.t_end for t, _ in runs])),
               diverged_at=float(bad[0].t_end) if bad and status in ("diverged", "failed")
               else math.nan)
    return row


def _robot(robot: SnakeParams | None, model: str, failed: int | None) -> SnakeParams:
    """The cell's robot (default: the engine preset, or the Table 1 tracking robot), with
    the failed joint passive."""
    params = robot or (SnakeParams.engine() if model == "engine" else tracking_params())
    return params.replace(passive=(failed,)) if failed else params


def _nan(value: float | None) -> float:
    """``value``, NaN for None (a row's cells are numbers)."""
    return math.nan if value is None else value


def _finish(row: dict[str, Any], traj: Trajectory, status: str, reason: str) -> None:
    """The row's status, end time, snapshots and head path from one trajectory."""
    diverged = status in ("diverged", "failed")
    times = np.linspace(0.0, traj.t_end, _SNAPSHOTS)
    idx = np.minimum(np.searchsorted(traj.t, times), len(traj) - 1)
    row.update(status=status, reason=reason, t_end=float(traj.t_end),
               diverged_at=float(traj.t_end) if diverged else math.nan,
               snapshots=[(float(traj.t[k]), traj.q[k].tolist()) for k in idx],
               head=traj.q[::100, :2].tolist())


def run_cell(scenario: str, controller: str, model: str = "viscous",
             failed: int | None = None, *, t_final: float = 60.0,
             factory: ControllerFactory | None = None,
             criteria_dt: float | None = _CRITERIA_DT,
             robot: SnakeParams | None = None, draws: int = ENGINE_DRAWS,
             engine_robot: SnakeParams | None = None,
             error_window: float | None = None) -> dict[str, Any]:
    """One cell of :func:`run_benchmark` (its arguments): the row of :data:`METRIC_FIELDS`
    plus ``series``, ``snapshots`` and ``head``; an engine cell is the median of ``draws``
    perturbed starts (:doc:`/paths`), a controller that refuses the robot "not applicable"."""
    _known(model, MODELS, "model")
    integer(draws, "draws", low=1)
    start = default_error_window(t_final) if error_window is None else float(error_window)
    wall = time.perf_counter()
    params = _robot(robot, "viscous", failed)
    reference = make_scenario(scenario, params.body_length)
    row: dict[str, Any] = dict.fromkeys(METRIC_FIELDS, math.nan)
    row.update(scenario=scenario, controller=controller, model=model, failed_joint=failed or 0,
               status="", reason="", body_length=params.body_length, draws=1, series={},
               snapshots=[], head=[])
    if factory is None:
        _known(controller, CONTROLLERS, "controller", " or a factory")
    if model == "engine":
        _engine_cell(row, scenario, controller, failed, t_final, factory, criteria_dt,
                     draws, engine_robot, start)
    else:
        snake = Snake(params)
        try:
            ctrl = (factory or CONTROLLERS[controller])(snake, reference, reference.path)
        except ParameterError as exc:
            row.update(status="not applicable", reason=str(exc))
            return row
        traj = simulate(snake, ctrl, initial_state(params), t_final,
                        meta={"scenario": scenario, "controller": controller})
        stride = slice(None, None, _EVERY)
        row.update(path_metrics(traj.t[stride], traj.q[stride], traj.tau[stride], snake,
                                reference, head_tracking=hasattr(ctrl, "reference"),
                                start=start, criteria_dt=criteria_dt),
                   torque_max=_nan(torque_max(traj)))
        _finish(row, traj, traj.status, traj.reason)
    # the time-indexed head error RMS in % of the body (NaN without one)
    row.update(head_error_rms_pct=100.0 * row["head_error_rms"] / row["body_length"],
               wall_s=time.perf_counter() - wall)
    return row


@dataclass
class BenchmarkResult:
    """The rows of a benchmark and its settings.

    Parameters
    ----------
    rows : list of dict
        One row per cell (:data:`METRIC_FIELDS` plus ``series``, ``snapshots``,
        ``head``).
    settings : dict
        ``t_final``, scenarios, controllers, models, failed joints, wall time.
    """

    rows: list[dict[str, Any]] = field(default_factory=list)
    settings: dict[str, Any] = field(default_factory=dict)

    def table(self) -> list[dict[str, Any]]:
        """Return the rows without their series (the CSV's content).

        Returns
        -------
        list of dict
            One dict per cell with the keys of :data:`METRIC_FIELDS`, in run order.
        """
        return [{k: row[k] for k in METRIC_FIELDS} for row in self.rows]

    def cell(self, scenario: str, controller: str, model: str = "viscous",
             failed: int | None = None) -> dict[str, Any]:
        """Return the row of one cell.

        Parameters
        ----------
        scenario : str
            One of :data:`SCENARIOS`.
        controller : str
            The controller's name.
        model : {"viscous", "engine"}, optional
            The plant.
        failed : int or None, optional
            The joint (1-based) made passive, or None (also 0) for none.

        Returns
        -------
        dict
            The cell's row, as ``run_cell`` returned it.

        Raises
        ------
        KeyError
            If the cell was not run.
        """
        for row in self.rows:
            if (row["scenario"], row["controller"], row["model"],
                    row["failed_joint"]) == (scenario, controller, model, failed or 0):
                return row
        raise KeyError((scenario, controller, model, failed))


def _picklable(value: object) -> bool:
    try:
        pickle.dumps(value)
    except Exception:  # anything that does not pickle runs here
        return False
    return True


def run_benchmark(scenarios: Iterable[str] | None = None,
                  controllers: Iterable[str] | Mapping[str, ControllerFactory | None]
                  | None = None,
                  models: Sequence[str] = ("viscous",),
                  failed: Sequence[int | None] = (None, FAILED_JOINT), *,
                  t_final: float = 60.0, quick: bool = False,
                  workers: int | None = None,
                  robot: SnakeParams | None = None, draws: int = ENGINE_DRAWS,
                  engine_robot: SnakeParams | None = None,
                  error_window: float | None = None,
                  cluster: SharedCluster | None = None) -> BenchmarkResult:
    """Run every cell of scenarios x controllers x models x failed joints.

    Parameters
    ----------
    scenarios : iterable of str, optional
        Names from :data:`SCENARIOS`; default all (quick: ``line`` and ``circle_1L``).
    controllers : iterable of str or mapping, optional
        Built-in names, or name -> factory (None: the built-in); default
        :data:`DEFAULT_CONTROLLERS` (quick: ``lyapunov`` and ``los``).
    models : sequence of str, optional
        From :data:`MODELS`.
    failed : sequence of int or None, optional
        None (every joint actuated) and/or failed joints.
    t_final : float, optional
        Duration of each run [s] (quick: at most 12 s).
    quick : bool, optional
        The small benchmark of ``reproduce --quick``.
    workers : int or None, optional
        Dask worker processes (default: one per core, at most one per cell).
    robot : SnakeParams or None, optional
        The viscous robot (default: the Table 1 tracking robot the LOS law is tuned for).
    draws : int, optional
        Perturbed starts per engine cell (1: one unperturbed draw).
    engine_robot : SnakeParams or None, optional
        The engine robot (default: the ``engine`` preset).
    error_window : float or None, optional
        Start of the metrics' window [s], in [0, t_final) (None: the default of ``t_final``).
    cluster : SharedCluster or None, optional
        A Dask cluster shared with other calls (unless ``workers`` is given).

    Returns
    -------
    BenchmarkResult
        One row per cell, in grid order.

    Raises
    ------
    ParameterError
        An unknown name, a non-positive t_final, an error window outside [0, t_final), bad draws.
    """
    integer(draws, "draws", low=1)
    if quick:
        scenarios = scenarios or ("line", "circle_1L")
        controllers = controllers or ("lyapunov", "los")
        t_final = min(t_final, QUICK_T_FINAL)
    names = list(scenarios or SCENARIOS)
    for name in names:
        make_scenario(name, 1.0)
    chosen: dict[str, ControllerFactory | None] = (
        dict(controllers) if isinstance(controllers, Mapping)
        else dict.fromkeys(controllers or DEFAULT_CONTROLLERS))
    for name, factory in chosen.items():
        if factory is None:
            _known(name, CONTROLLERS, "controller", " or a factory")
    for model in models:
        _known(model, MODELS, "model")
    finite_number(t_final, "t_final", positive=True)
    if error_window is None:
        error_window = default_error_window(t_final)
    elif not (isinstance(error_window, (int, float)) and not isinstance(error_window, bool)
              and math.isfinite(error_window) and 0.0 <= error_window < t_final):
        raise ParameterError(f"error_window must lie in [0, t_final = {t_final:g}) s, "
                             f"got {error_window!r}")
    cells = [(s, c, m, f) for m in models for f in failed for s in names for c in chosen]
    wall = time.perf_counter()
    pooled = [k for k, (_, c, _, _) in enumerate(cells) if _picklable(chosen[c])]
    rows: list[dict[str, Any] | None] = [None] * len(cells)
    options: dict[str, Any] = {"t_final": t_final, "robot": robot, "draws": draws,
                               "engine_robot": engine_robot, "error_window": error_window}
    jobs = [(run_cell, cells[k], {**options, "factory": chosen[cells[k][1]]})
            for k in pooled]
    for k, row in zip(pooled, run_jobs(jobs, workers, cluster=None if workers else cluster),
                      strict=True):
        rows[k] = row
    for k, (s, c, m, f) in enumerate(cells):
        if rows[k] is None:
            rows[k] = run_cell(s, c, m, f, **options, factory=chosen[c])
    settings = {"t_final": t_final, "scenarios": names, "controllers": list(chosen),
                "models": list(models), "failed": [f or 0 for f in failed],
                "speed": SPEED, "window_start": float(error_window),
                "robot": robot.to_dict() if robot is not None else None,
                "engine_draws": draws,
                "engine_robot": engine_robot.to_dict() if engine_robot is not None else None,
                "wall_s": time.perf_counter() - wall}
    return BenchmarkResult([r for r in rows if r is not None], settings)


# ---------------------------------------------------------------------------- output
def _csv_bytes(result: BenchmarkResult) -> bytes:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=METRIC_FIELDS, lineterminator="\n")
    writer.writeheader()
    for row in result.table():
        writer.writerow({k: ("" if isinstance(v, float) and math.isnan(v) else v)
                         for k, v in row.items()})
    return buf.getvalue().encode()


def _json_bytes(result: BenchmarkResult) -> bytes:
    doc = {"settings": result.settings, "rows": result.table(),
           "criteria": {f"{r['scenario']}/{r['controller']}/{r['model']}/{r['failed_joint']}":
                        r["series"] for r in result.rows if r.get("series")}}
    return json.dumps(json_safe(doc), indent=1, allow_nan=False).encode()


#: The table figures: name prefix -> (row metric, title); ``error_`` cells add the peak
#: ``|tau_i|`` (torque_max) under the head error.
_TABLES = {"table": ("head_ct_rms_pct", "Head cross-track RMS [% of body]"),
           "error": ("head_error_rms_pct", "Head error to the timed reference RMS [% of body]"
                                           "\nand peak |tau_i| [N m]")}


def _table_figure(result: BenchmarkResult, model: str, failed: int,
                  kind: str = "table") -> Any:
    import matplotlib.pyplot as plt

    metric, title = _TABLES[kind]
    rows = [r for r in result.rows if r["model"] == model and r["failed_joint"] == failed]
    scen = list(dict.fromkeys(r["scenario"] for r in rows))
    ctrl = list(dict.fromkeys(r["controller"] for r in rows))
    cell = {(r["scenario"], r["controller"]): r for r in rows}  # a grid may leave cells out
    grid = np.full((len(scen), len(ctrl)), np.nan)
    for r in rows:
        grid[scen.index(r["scenario"]), ctrl.index(r["controller"])] = r[metric]
    fig, ax = plt.subplots(figsize=(1.4 * len(ctrl) + 2.5, 0.5 * len(scen) + 1.5))
    shown = np.log10(np.clip(grid, 0.1, 1000.0))
    ax.imshow(np.ma.masked_invalid(shown), cmap="RdYlGn_r", vmin=0.0, vmax=2.0, aspect="auto")
    for i, s in enumerate(scen):
        for j, c in enumerate(ctrl):
            if (s, c) not in cell:
                continue
            r = cell[s, c]
            text = "n/a" if r["status"] == "not applicable" else (
                "-" if not np.isfinite(grid[i, j]) else
                f"{grid[i, j]:.2f}" if grid[i, j] < 1.0 else f"{grid[i, j]:.1f}")
            if r["draws"] > 1 and np.isfinite(grid[i, j]) and kind == "table":
                text += f"\n[{r['head_ct_rms_pct_p10']:.1f}, {r['head_ct_rms_pct_p90']:.1f}]"
            if kind == "error" and np.isfinite(r["torque_max"]):
                text += f"\n{r['torque_max']:.2g} N m"
            if r["status"] in ("diverged", "failed"):
                text += f"\n({r['status']} {r['t_end']:.0f} s)"
            ax.text(j, i, text, ha="center", va="center", fontsize=8)
    ax.set_xticks(range(len(ctrl)), ctrl)
    ax.set_yticks(range(len(scen)), scen)
    where = f", joint {failed} failed" if failed else ""
    draws = max((r["draws"] for r in rows), default=1)
    spread = (f"\nmedian of {draws} perturbed starts" if draws > 1 else "")
    spread += " [10-90 % range]" if draws > 1 and kind == "table" else ""
    start = result.settings.get("window_start", ERROR_WINDOW)
    ax.set_title(f"{title}\n{model}{where}, t >= {start:g} s{spread}", fontsize=9)
    return fig


def _path_figure(result: BenchmarkResult, scenario: str, model: str, failed: int) -> Any:
    import matplotlib.pyplot as plt

    from ..viz.plots import draw_snake

    rows = [r for r in result.rows if r["scenario"] == scenario and r["model"] == model
            and r["failed_joint"] == failed and r["snapshots"]]
    fig, axes = plt.subplots(1, max(len(rows), 1), figsize=(3.6 * max(len(rows), 1), 3.8),
                             squeeze=False)
    robot = result.settings.get("engine_robot" if model == "engine" else "robot")
    params = _robot(SnakeParams.from_dict(robot) if robot else None, model, failed)
    snake = Snake(params)
    reference = make_scenario(scenario, params.body_length)
    for ax, row in zip(axes[0], rows, strict=False):
        s_end = reference.timing(np.array([max(row["t_end"], 1.0)]))[0][0]
        p = reference.path.geometry(np.linspace(0.0, s_end, 400)).p
        ax.plot(p[:, 0], p[:, 1], "k--", lw=1)
        head = np.asarray(row["head"])
        ax.plot(head[:, 0], head[:, 1], color="#d9541a", lw=0.8)
        for k, (_, q) in enumerate(row["snapshots"]):
            draw_snake(ax, snake, np.asarray(q), alpha=0.3 + 0.7 * k / (_SNAPSHOTS - 1))
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        pct = row["head_ct_rms_pct"]
        draws = f"\n(median of {row['draws']} draws, this one)" if row["draws"] > 1 else ""
        ax.set_title(f"{row['controller']}: {pct:.1f} %{draws}" if np.isfinite(pct)
                     else f"{row['controller']}: {row['status']}", fontsize=9)
    fig.suptitle(f"{scenario}: path (dashed), head, body every "
                 f"{rows[0]['t_end'] / (_SNAPSHOTS - 1) if rows else 0:.0f} s", fontsize=10)
    return fig


def _claim_figure(row: dict[str, Any]) -> Any:
    import matplotlib.pyplot as plt

    series = row["series"]
    fig, ax = plt.subplots(figsize=(8, 3.6))
    ax.semilogy(series["t"], np.maximum(series["R"], 1e-16), color="#228b22",
                label="R (sliding, no lateral constraint)")
    ax.semilogy(series["t"], np.maximum(series["lateral"], 1e-16), "--", color="#1f4fd1",
                label="lateral-constraint criterion (wheels)")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("criterion (log)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title(f"{row['scenario']} ({row['controller']}): head cross-track RMS "
                 f"{row['head_ct_rms_pct']:.1f} % of body, R min {row['R_min']:.2e}, "
                 f"lateral min {row['lateral_min']:.1e}", fontsize=9)
    return fig


def write_benchmark(result: BenchmarkResult, folder: str | Path) -> dict[str, Path]:
    """Write ``benchmark.csv``, ``benchmark.json`` and the figures into ``folder`` (one set).

    Figures: ``table_<model>_<failed>.png`` (head cross-track RMS),
    ``error_<model>_<failed>.png`` (head error and peak torque),
    ``path_<scenario>_<model>_<failed>.png`` (paths with body snapshots) and
    ``claim_<scenario>.png`` (R and the lateral-constraint criterion on the circles).

    Parameters
    ----------
    result : BenchmarkResult
        What :func:`run_benchmark` returned.
    folder : str or pathlib.Path
        Output folder (created if missing).

    Returns
    -------
    dict of str to pathlib.Path
        Name -> written file.
    """
    from ..viz.plots import png_bytes

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out: dict[str, Path] = {}
    with atomic_group(folder) as group:
        out["csv"] = group.write_bytes("benchmark.csv", _csv_bytes(result))
        out["json"] = group.write_bytes("benchmark.json", _json_bytes(result))
        combos = list(dict.fromkeys((r["model"], r["failed_joint"]) for r in result.rows))
        for model, failed in combos:
            for kind in _TABLES:
                name = f"{kind}_{model}_{failed}"
                fig = _table_figure(result, model, failed, kind)
                out[name] = group.write_bytes(f"{name}.png", png_bytes(fig), figure=True)
            for scenario in dict.fromkeys(r["scenario"] for r in result.rows):
                if any(r["snapshots"] for r in result.rows if r["scenario"] == scenario
                       and r["model"] == model and r["failed_joint"] == failed):
                    name = f"path_{scenario}_{model}_{failed}"
                    fig = _path_figure(result, scenario, model, failed)
                    out[name] = group.write_bytes(f"{name}.png", png_bytes(fig),
                                                  figure=True)
        for row in result.rows:
            if (row["scenario"].startswith("circle") and row["controller"] == "lyapunov"
                    and row["model"] == "viscous" and not row["failed_joint"]
                    and row["series"].get("t")):
                name = f"claim_{row['scenario']}"
                out[name] = group.write_bytes(f"{name}.png", png_bytes(_claim_figure(row)),
                                              figure=True)
    return out
