"""Singular-posture search over the joint box."""

from __future__ import annotations

import numpy as np
import pytest

from snake_pin import ParameterError, Snake, SnakeParams
from snake_pin.manipulability import manipulability
from snake_pin.singular import find_singular_postures


def test_found_postures_are_singular_by_pinocchio(table1: Snake) -> None:
    """Every family the search reports has R and D numerically zero by the Pinocchio route."""
    search = find_singular_postures(table1.params, starts=10, seed=1)
    assert search.families
    for fam in search.families:
        assert np.all(np.abs(fam.phi) <= np.pi / 2 + 1e-12)
        res = manipulability(table1, np.r_[0.3, -0.1, 0.4, fam.phi])
        assert res.R < 1e-9 * search.R_typical


def test_non_straight_family_has_free_first_joint(table1: Snake) -> None:
    """The non-straight sheet found for Table 1: phi_1 varies freely along it, R stays 0."""
    search = find_singular_postures(table1.params, starts=12, seed=2)
    fam = max(search.non_straight, key=lambda f: f.members)
    for shift in (-0.8, 0.5):
        phi = fam.phi.copy()
        phi[0] = np.clip(phi[0] + shift, -np.pi / 2, np.pi / 2)
        assert manipulability(table1, np.r_[0, 0, 0, phi]).R < 1e-9 * search.R_typical


def test_search_reports_minima_and_json(table1: Snake) -> None:
    """The JSON has postures and R of the same length; R values are below the threshold."""
    search = find_singular_postures(table1.params, starts=4, seed=3)
    data = search.to_dict()
    assert len(data["postures"]) == len(data["R"])
    assert all(r <= data["threshold"] for r in data["R"])
    assert len(search.minima_R) == 4


@pytest.mark.parametrize("kwargs", [{"starts": 0}, {"bound": 0.0}, {"bound": 4.0},
                                    {"free_joint": 10}])
def test_bad_settings(kwargs: dict) -> None:
    """Bad search settings are ParameterErrors."""
    with pytest.raises(ParameterError):
        find_singular_postures(SnakeParams.table1(), **kwargs)


def test_five_links_with_free_joint_is_always_singular() -> None:
    """n = 5 with a free joint: H12~ is 4 x 3, R~ = 0 everywhere; the search says so."""
    params = SnakeParams.table1(n=5)
    snake = Snake(params)
    rng = np.random.default_rng(0)
    for _ in range(5):
        assert manipulability(snake, np.r_[0, 0, 0, rng.uniform(-1, 1, 4)], free_joint=3).R == 0
    with pytest.raises(ParameterError, match="zero at every posture"):
        find_singular_postures(params, free_joint=3, starts=2)
