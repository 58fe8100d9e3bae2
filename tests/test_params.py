"""SnakeParams: presets and validation at the boundary."""

from __future__ import annotations

import math
import re

import pytest

from snake_pin import ParameterError, SnakeParams, SnakePinError
from snake_pin.params import (
    FIELD_RANGES,
    FRICTION_RANGE,
    INERTIA_RANGE,
    LENGTH_RANGE,
    LINK_FIELDS,
    MASS_RANGE,
)


def test_table1_preset_matches_design() -> None:
    """Table 1 robot: n = 10, 2l = 0.12 m, m = 0.182 kg, J = 2.2e-4 kg m^2 (erratum 1)."""
    p = SnakeParams.table1()
    assert (p.n, p.link_length, p.mass, p.inertia) == (10, 0.12, 0.182, 2.2e-4)
    assert (p.c_x, p.c_y, p.c_theta) == (0.5, 0.5, 7.2e-5)
    assert p.half_length == pytest.approx(0.06) and p.body_length == pytest.approx(1.2)
    # J is the thin-rod value m (2l)^2 / 12 to two digits, not 0.22.
    assert p.inertia == pytest.approx(p.mass * p.link_length**2 / 12, rel=0.01)


def test_engine_preset() -> None:
    """Engine robot of Section VI.3: n = 8, 2l = 0.176 m, m = 0.417 kg, J = 1.2e-3."""
    p = SnakeParams.engine()
    assert (p.n, p.link_length, p.mass, p.inertia) == (8, 0.176, 0.417, 1.2e-3)


@pytest.mark.parametrize("changes", [
    {"n": 1}, {"n": 2.5}, {"n": True}, {"mass": 0.0}, {"mass": -1.0},
    {"link_length": 0.0}, {"inertia": -1e-4}, {"c_x": -0.1}, {"c_theta": -1.0},
    {"c_y": math.nan}, {"mass": math.inf}, {"inertia": "heavy"}, {"passive": (0,)},
    {"passive": (10,)}, {"passive": ("x",)}, {"passive": {}}, {"passive": {1: 2}},
    {"name": "no spaces"},
])
def test_invalid_parameters_raise_parameter_error(changes: dict) -> None:
    """Each out-of-domain field is refused with a ParameterError (a SnakePinError)."""
    with pytest.raises(ParameterError) as info:
        SnakeParams.table1(**changes)
    assert isinstance(info.value, SnakePinError)
    assert str(info.value)


def test_passive_indices_are_sorted_and_deduplicated() -> None:
    """Passive joints normalise to a sorted tuple and leave the rest actuated."""
    p = SnakeParams.table1(passive=[7, 5, 5])
    assert p.passive == (5, 7)
    assert p.actuated == (1, 2, 3, 4, 6, 8, 9)


def test_dict_round_trip() -> None:
    """to_dict/from_dict give back an equal object; unknown keys are refused."""
    p = SnakeParams.engine(passive=(3,))
    assert SnakeParams.from_dict(p.to_dict()) == p
    with pytest.raises(ParameterError):
        SnakeParams.from_dict({**p.to_dict(), "colour": "red"})


def test_unknown_preset() -> None:
    """An unknown preset name is a ParameterError that lists the choices."""
    with pytest.raises(ParameterError, match="table1"):
        SnakeParams.preset("python")


@pytest.mark.parametrize("key", sorted(FIELD_RANGES))
@pytest.mark.parametrize("value", [1e-300, 1e300])
def test_physically_meaningless_values_are_refused(key: str, value: float) -> None:
    """1e-300 and 1e300 of any length, mass, inertia or friction are refused, naming the
    field (and the link when the value is per link)."""
    low, high = FIELD_RANGES[key]
    bounds = re.escape(f"in [{low:g}, {high:g}]")
    with pytest.raises(ParameterError, match=rf"^{key} must be (0 or )?{bounds}"):
        SnakeParams.table1(**{key: value})
    per_link = [getattr(SnakeParams.table1(), key)] * 10
    per_link[6] = value
    got = re.escape(f"got {value:g}")
    with pytest.raises(ParameterError, match=rf"^link 7: {key} must be .*{got}$"):
        SnakeParams.table1(**{key: per_link})


@pytest.mark.parametrize("key", sorted(FIELD_RANGES))
def test_each_range_is_closed_and_nothing_beyond_it_passes(key: str) -> None:
    """The ends of each range are accepted, values just beyond them refused; friction
    may be exactly 0, geometry and mass may not."""
    low, high = FIELD_RANGES[key]
    changes = {"com_offset": None} if key == "link_length" else {}
    for ok in (low, high):
        assert SnakeParams.table1(**{key: ok}, **changes).per_link(key)[0] == ok
    for bad in (low * 0.999, high * 1.001):
        with pytest.raises(ParameterError, match="physically meaningful"):
            SnakeParams.table1(**{key: bad})
    if LINK_FIELDS[key]:
        assert SnakeParams.table1(**{key: 0.0}).per_link(key)[0] == 0.0
    else:
        with pytest.raises(ParameterError, match="must be positive"):
            SnakeParams.table1(**{key: 0.0})


def test_the_ranges_are_the_documented_ones() -> None:
    """Lengths 0.1 mm-100 m, masses 1 mg-10 t, inertias 1e-16-1e7 kg m^2, friction
    1e-12-1e6 (or 0): the constants the docs state."""
    assert (LENGTH_RANGE, MASS_RANGE, INERTIA_RANGE, FRICTION_RANGE) == (
        (1e-4, 1e2), (1e-6, 1e4), (1e-16, 1e7), (1e-12, 1e6))
    assert set(FIELD_RANGES) == set(LINK_FIELDS) - {"com_offset"}


@pytest.mark.parametrize("n", [8, 11, 18])
def test_an_out_of_range_passive_joint_names_the_robot_in_good_english(n: int) -> None:
    """A passive joint beyond n - 1 says 'the N-link snake' (never 'a 8-link', 'a 11-link')."""
    with pytest.raises(ParameterError, match=f"outside 1..{n - 1} for the {n}-link snake$"):
        SnakeParams.table1(n=n, passive=(n,))
