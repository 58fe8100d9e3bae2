"""The unit of work of a study: run a task's scenarios, return one result row per scenario.

:func:`run_batch` is the Dask task: a run that raises becomes a ``failed`` row, and BLAS
and OpenMP pools are limited to one thread (tiny matrices, busy cores). Row columns:
:ref:`studies` (The study folder).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._validation import one_line
from ..control import LinearReference
from ..metrics import criteria_along, head_error_summary, head_position_error
from ..params import SnakeParams
from ..sim import Trajectory
from .spec import Scenario, canonical_json, law_options

__all__: list[str] = []

#: Manipulability criteria are evaluated along a run every this many seconds.
CRITERIA_PERIOD = 0.1


@dataclass
class RunOutcome:
    """What simulating one scenario gave: a trajectory, or the error that stopped it."""

    trajectory: Trajectory | None
    error: str = ""
    wall_time: float = math.nan


def run_batch(scenarios: Sequence[Scenario]) -> list[dict[str, Any]]:
    """One result row per scenario, in order; a run that raises is a ``failed`` row (a
    KeyboardInterrupt is not caught: an interrupted task is lost whole)."""
    from threadpoolctl import threadpool_limits

    rows = []
    with threadpool_limits(limits=1):
        for scenario in scenarios:
            simulate = simulate_scenario if scenario.model == "viscous" else _simulate_engine
            start = time.perf_counter()
            try:  # a RunInterrupted is a KeyboardInterrupt: not caught
                outcome = simulate(scenario)
            except Exception as exc:
                outcome = RunOutcome(None, _error_text(exc), time.perf_counter() - start)
            try:
                rows.append(result_row(scenario, outcome))
            except Exception as exc:
                rows.append(failed_row(scenario, f"metrics failed: {_error_text(exc)}",
                                       outcome.wall_time))
    return rows


def reference(scenario: Scenario) -> LinearReference:
    """The head reference of a run."""
    speed = scenario.settings.get("ref_speed", 0.1)
    heading = 0.0 if scenario.controller == "pfl" else math.pi
    return LinearReference(velocity=(speed, 0.0, 0.0), start=(0.0, 0.0, heading))


def initial_state(scenario: Scenario) -> np.ndarray:
    """The initial state of a run."""
    from ..gaits import arc

    n = scenario.params.n
    heading = reference(scenario).start[2]
    q = arc(n, scenario["init_phi"], theta_1=heading)
    q[3:] += initial_noise(scenario)
    return np.r_[q, np.zeros(n + 2)]


def initial_noise(scenario: Scenario) -> np.ndarray:
    """The offsets a run adds to its initial joint angles (either model)."""
    n = scenario.params.n
    if scenario["init_noise"] > 0:
        return np.random.default_rng(scenario["init_seed"]).normal(0.0, scenario["init_noise"],
                                                                   n - 1)
    return np.zeros(n - 1)


def build_controller(scenario: Scenario, snake: Any) -> Any:
    """The controller of a run."""
    from ..control import (
        LyapunovController,
        MPCController,
        PFLController,
        QuasiStaticLyapunovController,
    )
    from ..gaits import Serpenoid

    s = scenario.settings
    n = scenario.params.n
    gait = Serpenoid(n, s["gait_alpha"], s["gait_ts"], s["gait_v"])
    law = {"pfl": PFLController, "velocity": QuasiStaticLyapunovController,
           "mpc": MPCController}.get(scenario.controller, LyapunovController)
    return law(snake, reference(scenario), gait, options=law_options(s, n - 1))


def simulate_scenario(scenario: Scenario) -> RunOutcome:
    """One viscous-model scenario through :func:`snake_pin.sim.simulate` (may raise)."""
    from ..model import Snake
    from ..sim import simulate

    start = time.perf_counter()
    snake = Snake(scenario.params)
    controller = build_controller(scenario, snake)
    traj = simulate(snake, controller, initial_state(scenario), scenario["t_final"],
                    dt=scenario["dt"], control_dt=scenario["control_dt"])
    return RunOutcome(traj, "", time.perf_counter() - start)


@functools.lru_cache(maxsize=16)
def _engine_friction(params: SnakeParams, wheels: Any) -> dict[str, float]:
    """The identified viscous friction of a robot on its wheels, cached per worker."""
    from ..engine.run import identify_friction

    return identify_friction(params, wheels)


def _simulate_engine(scenario: Scenario) -> RunOutcome:
    """One engine scenario through :func:`snake_pin.engine.run.run_engine` (may raise)."""
    from ..engine.model import WheelSpec
    from ..engine.run import run_engine

    s = scenario.settings
    wheels = WheelSpec(radius=s["wheel_radius"], friction=s["mu"], cone=s["cone"])
    friction = _engine_friction(scenario.params.replace(passive=()), wheels)
    start = time.perf_counter()
    law = "velocity" if scenario.controller == "velocity" else "acceleration"
    run = run_engine(scenario.params, wheels=wheels, t_final=s["t_final"], friction=friction,
                     cutoff=s["cutoff"], law=law, initial_offset=initial_noise(scenario))
    return RunOutcome(run.trajectory, "", time.perf_counter() - start)


_METRICS = ("rms_head_error", "max_head_error", "rms_head_error_pct", "max_head_error_pct",
            "R_min", "R_tilde_min", "D_min", "t_end", "torque_rms")


def _settings_columns(scenario: Scenario) -> dict[str, Any]:
    row: dict[str, Any] = dict(scenario.settings)
    row["passive"] = ",".join(str(k) for k in scenario.settings["passive"])
    params = scenario.params
    for key in ("c_x", "c_y", "c_theta"):
        if key in row and row[key] is None:  # the robot's own, when it is one number
            value = getattr(params, key)
            row[key] = float(value) if not isinstance(value, tuple) else None
    row.update({"key": scenario.key, "index": scenario.index, "n": params.n,
                "body_length": float(params.body_length),
                "robot_params": canonical_json(params.to_dict())})
    return row


def failed_row(scenario: Scenario, reason: str, wall_time: float = math.nan) -> dict[str, Any]:
    """The row of a run that raised: status ``failed``, ``reason``, no metrics."""
    return {**_settings_columns(scenario), "status": "failed", "reason": reason,
            **dict.fromkeys(_METRICS), "wall_time": _finite_or_none(wall_time)}


def result_row(scenario: Scenario, outcome: RunOutcome) -> dict[str, Any]:
    """The row of a simulated scenario: its settings, status and metrics."""
    traj = outcome.trajectory
    if traj is None:
        return failed_row(scenario, outcome.error, outcome.wall_time)
    body = float(scenario.params.body_length)
    error = head_position_error(traj, reference(scenario))
    window = head_error_summary(traj, error, start=scenario["error_window"])
    rms, peak = window["rms_head_error"], window["max_head_error"]
    r_min, r_tilde_min, d_min = _criteria(traj)
    torque = traj.tau[:-1] if len(traj) > 1 else traj.tau[:0]
    return {**_settings_columns(scenario),
            "status": "ok" if traj.status == "completed" else traj.status,
            "reason": traj.reason,
            "rms_head_error": rms, "max_head_error": peak,
            "rms_head_error_pct": None if rms is None else 100.0 * rms / body,
            "max_head_error_pct": None if peak is None else 100.0 * peak / body,
            "R_min": r_min, "R_tilde_min": r_tilde_min, "D_min": d_min,
            "t_end": traj.t_end,
            "torque_rms": float(np.sqrt(np.mean(torque**2))) if torque.size else None,
            "wall_time": _finite_or_none(outcome.wall_time)}


def _criteria(traj: Trajectory) -> tuple[float | None, ...]:
    """(R_min, R~_min, D~_min) along the run every CRITERIA_PERIOD seconds: R with every joint
    actuated, R~ and D~ with the passive and failed joints free."""
    from ..manipulability import manipulability
    from ..model import Snake

    if len(traj) == 0:
        return None, None, None
    period = float(np.median(np.diff(traj.t))) if len(traj) > 1 else CRITERIA_PERIOD
    every = max(1, round(CRITERIA_PERIOD / period))
    _, d_tilde, r_tilde = criteria_along(traj, every=every)
    r = r_tilde
    if traj.params.passive:
        actuated = Snake(traj.params.replace(passive=()))
        r = np.array([manipulability(actuated, traj.q[k]).R for k in range(0, len(traj), every)])
    return float(r.min()), float(r_tilde.min()), float(d_tilde.min())


def _finite_or_none(value: float) -> float | None:
    return float(value) if value is not None and math.isfinite(value) else None


def _error_text(exc: BaseException) -> str:
    named = f"{type(exc).__name__}: {exc}" if str(exc).strip() else type(exc).__name__
    return one_line(named, 500)
