"""Shared fixtures: robots and fixed-seed random states."""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np
import pytest

from snake_pin import Snake, SnakeParams


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


@pytest.fixture(scope="session")
def table1() -> Snake:
    return Snake(SnakeParams.table1())


def random_state(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A random configuration (joint angles within +-pi/2) and velocity."""
    q = np.r_[rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi), rng.uniform(-1.5, 1.5, n - 1)]
    return q, rng.normal(size=n + 2)


def head_first_state(rng: np.random.Generator, n: int, *, spread: float = 0.3,
                     joints: float = 1.2, speed: float = 0.3) -> np.ndarray:
    """A random state near the head-first tracking runs (theta_1 about pi): x = [q, dq]."""
    q = np.r_[rng.normal(scale=spread, size=2), np.pi + rng.normal(scale=spread),
              rng.uniform(-joints, joints, n - 1)]
    return np.r_[q, rng.normal(scale=speed, size=n + 2)]


def heterogeneous_params(rng: np.random.Generator, n: int, friction: str = "anisotropic",
                         passive: tuple[int, ...] = ()) -> SnakeParams:
    """A robot whose every per-link value is drawn within x0.2..x5 of Table 1's.

    ``friction`` is "none", "isotropic" (c_x,i = c_y,i, per link) or "anisotropic"
    (c_y,i drawn around 50 c_x,i); CM offsets anywhere within 10-90 % of each link.
    """
    def draw(value: float) -> list[float]:
        return (value * rng.uniform(0.2, 5.0, n)).tolist()

    lengths = draw(0.12)
    c_x = draw(0.5) if friction != "none" else 0.0
    c_y = {"none": 0.0, "isotropic": c_x, "anisotropic": draw(25.0)}[friction]
    return SnakeParams(n=n, link_length=lengths, mass=draw(0.182), inertia=draw(2.2e-4),
                       com_offset=(np.array(lengths) * rng.uniform(0.1, 0.9, n)).tolist(),
                       c_x=c_x, c_y=c_y, c_theta=draw(7.2e-5) if friction != "none" else 0.0,
                       passive=passive, name="heterogeneous")


def raised_without_blocking(call: Callable[[], object], what: str) -> BaseException | None:
    """What ``call`` raises (None if it returns), run in a thread: a reader that blocks
    (a FIFO opened) fails the test after 60 s instead of hanging it."""
    outcome: list[BaseException | None] = [None]

    def run() -> None:
        try:
            call()
        except BaseException as exc:  # handed to the test thread
            outcome[0] = exc

    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    worker.join(60)
    assert not worker.is_alive(), f"{what} blocked"
    return outcome[0]


@pytest.fixture
def tiny_report(monkeypatch: pytest.MonkeyPatch) -> None:
    """Shrink the quick report's longest runs for tests of how a report runs, not of its
    numbers: a failure map of 3 failed joints x 2 ratios over 1 s (errors from 0.5 s), the
    MPC's map line (no failure, joint 5 failed), engine runs and benchmark row at 0.4 s,
    the engine stage's other runs at 2 s."""
    from snake_pin.experiments import bench_control, engine, failure_map

    monkeypatch.setattr(failure_map, "QUICK",
                        failure_map.MapPlan(1.0, (0, 1, 5), (25.0, 50.0), error_window=0.5))
    monkeypatch.setattr(failure_map, "MPC_QUICK",
                        failure_map.MapPlan(0.4, (0, 5), (50.0,), error_window=0.2))
    monkeypatch.setattr(engine, "QUICK_MPC_T_FINAL", 0.4)
    monkeypatch.setattr(engine, "QUICK_T_FINAL", 2.0)
    monkeypatch.setattr(bench_control, "QUICK_MPC_T", 0.4)
