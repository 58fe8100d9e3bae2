"""Shared fixtures: robots and fixed-seed random states."""

from __future__ import annotations

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
