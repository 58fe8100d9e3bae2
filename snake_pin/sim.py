"""Closed-loop simulation: fixed-step RK4 on ABA with zero-order-hold control, and the
``Trajectory`` it returns (save to .npz + .json summary, load, plot).

A run that diverges (non-finite state, speed or distance beyond a bound, or a controller
that raises a :class:`~snake_pin.exceptions.SnakePinError`) stops there: the trajectory
up to the last good step is kept, with ``diverged=True`` and a ``reason`` that says when
and why.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ._io import atomic_save, atomic_write_bytes
from ._validation import as_vector
from .control.base import Controller
from .exceptions import ParameterError, SnakePinError, TrajectoryFileError
from .model import Snake
from .params import SnakeParams

__all__ = ["Trajectory", "simulate"]

#: Default divergence bounds: joint/base speed [m/s or rad/s] and distance [m].
MAX_SPEED = 1.0e3
MAX_DISTANCE = 1.0e3


@dataclass
class Trajectory:
    """A recorded run: samples at every control step (plus the initial state).

    Attributes
    ----------
    t, q, dq, tau
        Times (N,), configurations and velocities (N, n + 2), applied torques (N, n - 1);
        ``tau[k]`` is held over [t[k], t[k + 1]).
    params
        The robot.
    signals
        Extra per-sample series (controller diagnostics, manipulability, ...).
    diverged, reason
        Whether the run stopped early, and why.
    meta
        Run settings (controller name, time steps, reference ...).
    summary
        Scalar results written to the JSON summary.
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    params: SnakeParams
    signals: dict[str, np.ndarray] = field(default_factory=dict)
    diverged: bool = False
    reason: str = ""
    meta: dict[str, Any] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)

    @property
    def t_end(self) -> float:
        """Time of the last sample."""
        return float(self.t[-1]) if len(self.t) else 0.0

    def __len__(self) -> int:
        return len(self.t)

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike[str]) -> tuple[Path, Path]:
        """Write ``PATH.npz`` (arrays) and ``PATH.json`` (summary), each whole or not at all."""
        base = Path(path)
        if base.suffix in (".npz", ".json"):
            base = base.with_suffix("")
        if not base.parent.exists():
            raise ParameterError(f"output directory does not exist: {base.parent}")
        header = {"params": self.params.to_dict(), "diverged": self.diverged,
                  "reason": self.reason, "meta": self.meta, "summary": self.summary,
                  "signals": sorted(self.signals)}
        arrays = {"t": self.t, "q": self.q, "dq": self.dq, "tau": self.tau,
                  "header": np.array(json.dumps(header, default=_json_default))}
        arrays.update({f"signal__{k}": v for k, v in self.signals.items()})
        npz, js = base.with_suffix(".npz"), base.with_suffix(".json")
        atomic_save(npz, lambda handle: np.savez_compressed(handle, **arrays))
        atomic_write_bytes(js, (json.dumps(self.summary_dict(), indent=2,
                                           default=_json_default) + "\n").encode())
        return npz, js

    def summary_dict(self) -> dict[str, Any]:
        """The JSON summary: run status plus :attr:`summary`."""
        return {"robot": self.params.name, "n": self.params.n, "t_end": self.t_end,
                "diverged": self.diverged, "reason": self.reason, **self.summary}

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Trajectory:
        """Read a trajectory written by :meth:`save` (TrajectoryFileError if unreadable)."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_suffix(".npz")
        if not path.is_file():
            raise TrajectoryFileError(f"no trajectory file at {path}")
        try:
            with np.load(path, allow_pickle=False) as z:
                header = json.loads(str(z["header"]))
                arrays = {k: z[k] for k in ("t", "q", "dq", "tau")}
                signals = {k.removeprefix("signal__"): z[k] for k in z.files
                           if k.startswith("signal__")}
            params = SnakeParams.from_dict(header["params"])
        except (OSError, KeyError, ValueError, json.JSONDecodeError) as exc:
            detail = str(exc).split(". ")[0][:120]
            raise TrajectoryFileError(f"{path} is not a snake_pin trajectory ({detail})") from exc
        traj = cls(params=params, signals=signals, diverged=header["diverged"],
                   reason=header["reason"], meta=header["meta"], summary=header["summary"],
                   **arrays)
        if traj.q.shape[1:] != (params.n + 2,) or traj.tau.shape[1:] != (params.n - 1,):
            raise TrajectoryFileError(f"{path}: array sizes do not match its {params.n}-link robot")
        return traj

    def plot(self, path: str | os.PathLike[str] | None = None):
        """Head position, joint angles and torques over time; saved as PNG if ``path``."""
        from .viz.plots import plot_trajectory

        return plot_trajectory(self, path)


def _json_default(value: object) -> object:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return dataclasses.asdict(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def _check_steps(t_final: float, dt: float, control_dt: float) -> tuple[int, int]:
    for name, value in (("t_final", t_final), ("dt", dt), ("control_dt", control_dt)):
        if not (math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be a positive finite number, got {value}")
    substeps = round(control_dt / dt)
    if substeps < 1 or abs(substeps * dt - control_dt) > 1e-9 * control_dt:
        raise ParameterError(f"control_dt ({control_dt}) must be a multiple of dt ({dt})")
    return substeps, math.ceil(t_final / control_dt - 1e-9)


def simulate(snake: Snake, controller: Controller, x0: np.ndarray, t_final: float, *,
             dt: float = 1e-3, control_dt: float = 1e-3, method: str = "rk4",
             max_speed: float = MAX_SPEED, max_distance: float = MAX_DISTANCE,
             progress: bool = False, meta: dict[str, Any] | None = None) -> Trajectory:
    """Simulate the closed loop from state ``x0 = [q0, dq0]`` up to ``t_final``.

    The controller is sampled every ``control_dt`` and its torque held in between (zero-
    order hold, as on a real robot). ``method="rk4"`` integrates with fixed RK4 steps of
    ``dt``; ``method="solve_ivp"`` uses scipy's adaptive RK45 over each control period
    (tight tolerances; slower, for cross-checks).

    Returns
    -------
    Trajectory
        Samples at t = 0, control_dt, 2 control_dt, ... up to t_final or divergence.
    """
    nq = snake.nq
    x = as_vector(x0, 2 * nq, "x0")
    if method not in ("rk4", "solve_ivp"):
        raise ParameterError(f"method must be 'rk4' or 'solve_ivp', got {method!r}")
    substeps, steps = _check_steps(t_final, dt, control_dt)
    accel = snake.state_derivative

    def rhs(state: np.ndarray, tau: np.ndarray) -> np.ndarray:
        return np.concatenate([state[nq:], accel(state, tau)])

    controller.reset()
    ts = np.empty(steps + 1)
    xs = np.empty((steps + 1, 2 * nq))
    taus = np.zeros((steps + 1, snake.n - 1))
    signals: dict[str, list[float]] = {}
    diverged, reason, k = False, "", 0
    ts[0], xs[0] = 0.0, x
    bar = _progress(steps, progress, getattr(controller, "name", "run"))
    for k in range(steps):
        t = k * control_dt
        try:
            tau = np.asarray(controller(x, t), dtype=float)
        except SnakePinError as exc:
            diverged, reason = True, f"controller failed at t = {t:.4f} s: {exc}"
            break
        if tau.shape != (snake.n - 1,) or not np.all(np.isfinite(tau)):
            diverged, reason = True, f"controller returned a non-finite torque at t = {t:.4f} s"
            break
        taus[k] = tau
        for name, value in controller.signals().items():
            signals.setdefault(name, []).append(value)
        if method == "rk4":
            for _ in range(substeps):
                x = _rk4_step(accel, x, tau, dt, nq)
        else:
            x = _solve_ivp_step(rhs, x, tau, t, control_dt)
        problem = _divergence(x, nq, max_speed, max_distance)
        if problem:
            diverged, reason = True, f"diverged at t = {t + control_dt:.4f} s: {problem}"
            break
        ts[k + 1], xs[k + 1] = t + control_dt, x
        if bar is not None and k % 100 == 0:
            bar.update(min(100, steps - bar.n))
    else:
        k = steps
    if bar is not None:
        bar.close()
    # Samples 0..k are good. tau[k] is the torque held after sample k: on divergence it is
    # the one that was applied when the state blew up (kept as evidence); at the end of a
    # completed run, or when the controller failed, none was applied and it stays zero.
    last = k + 1
    recorded = {name: _pad(values, last) for name, values in signals.items()}
    return Trajectory(t=ts[:last].copy(), q=xs[:last, :nq].copy(), dq=xs[:last, nq:].copy(),
                      tau=taus[:last].copy(), params=snake.params, signals=recorded,
                      diverged=diverged, reason=reason,
                      meta={"controller": getattr(controller, "name", "controller"),
                            "dt": dt, "control_dt": control_dt, "method": method,
                            **(meta or {})})


def _rk4_step(accel, x: np.ndarray, tau: np.ndarray, h: float,
              nq: int) -> np.ndarray:
    """One classical RK4 step of x' = [dq, accel(x, tau)] (the stage slopes d1..d4)."""
    d1 = np.concatenate((x[nq:], accel(x, tau)))
    x2 = x + (0.5 * h) * d1
    d2 = np.concatenate((x2[nq:], accel(x2, tau)))
    x3 = x + (0.5 * h) * d2
    d3 = np.concatenate((x3[nq:], accel(x3, tau)))
    x4 = x + h * d3
    d4 = np.concatenate((x4[nq:], accel(x4, tau)))
    return x + (h / 6.0) * (d1 + d4 + 2.0 * (d2 + d3))


def _pad(values: list[float], length: int) -> np.ndarray:
    arr = np.full(length, np.nan)
    arr[: min(length, len(values))] = values[:length]
    return arr


def _divergence(x: np.ndarray, nq: int, max_speed: float, max_distance: float) -> str:
    speed = np.abs(x[nq:]).max()  # NaN propagates and fails both comparisons below
    distance = np.abs(x[:2]).max()
    if speed <= max_speed and distance <= max_distance:
        return ""
    if not np.all(np.isfinite(x)):
        return "state is not finite"
    if speed > max_speed:
        return f"speed {speed:.3g} exceeds {max_speed:g}"
    return f"head is {distance:.3g} m away, beyond {max_distance:g} m"


def _solve_ivp_step(rhs, x: np.ndarray, tau: np.ndarray, t: float,
                    span: float) -> np.ndarray:
    from scipy.integrate import solve_ivp

    sol = solve_ivp(lambda _t, y: rhs(y, tau), (t, t + span), x, method="RK45",
                    rtol=1e-10, atol=1e-12)
    return sol.y[:, -1] if sol.success else np.full_like(x, np.nan)


def _progress(total: int, enabled: bool, label: str):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=f"simulate {label}", unit="step", leave=False)
