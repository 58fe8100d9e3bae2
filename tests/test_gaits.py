"""Posture families: the straight posture, arcs, the serpenoid and their head pose."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snake_pin import ConfigurationError, ParameterError, Serpenoid, arc, straight
from snake_pin.gaits import configuration, initial_state


def test_postures_put_the_head_pose_first() -> None:
    """q = [x_h, y_h, theta_1, phi]: arcs repeat phi0, the serpenoid follows eq. (43)."""
    assert arc(4, 0.3, x_h=1.0, theta_1=2.0).tolist() == [1.0, 0.0, 2.0, 0.3, 0.3, 0.3]
    assert straight(3, y_h=-1.0).tolist() == [0.0, -1.0, 0.0, 0.0, 0.0]
    gait = Serpenoid(5, 0.5, 1.0)
    k = 2 * math.pi / 5
    assert np.allclose(gait.configuration(y_h=0.2)[3:], k * 0.5 * np.sin(-k * np.arange(1, 5)))
    state = initial_state(4, theta_1=math.pi)
    assert state.tolist() == [0.0, 0.0, math.pi, *[math.pi / 6] * 3, *[0.0] * 6]


@pytest.mark.parametrize("call", [
    lambda: arc(5, 0.3, heading=1.0),
    lambda: straight(5, x=1.0),
    lambda: Serpenoid(5, 0.5, 1.0).configuration(theta=1.0),
])
def test_unknown_head_keywords_are_refused(call: object) -> None:
    """A misspelt head keyword is one ParameterError line, not a TypeError or ignored."""
    with pytest.raises(ParameterError, match="unknown head pose argument") as info:
        call()  # type: ignore[operator]
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(("kwargs", "word"), [
    ({"x_h": None}, "x_h"), ({"theta_1": "pi"}, "theta_1"), ({"y_h": float("inf")}, "y_h"),
    ({"x_h": True}, "x_h"),
])
def test_head_coordinates_are_finite_numbers(kwargs: dict[str, object], word: str) -> None:
    """A head coordinate that is not a finite number is refused (no object array, no inf)."""
    with pytest.raises(ParameterError, match=word):
        configuration(np.zeros(3), **kwargs)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match=word):
        arc(4, 0.1, **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize("phi", [None, "abc", [], [[0.1, 0.2]], [0.1, float("nan")], {}])
def test_joint_angles_are_a_finite_vector(phi: object) -> None:
    """configuration's phi must be a non-empty vector of finite numbers."""
    with pytest.raises(ConfigurationError, match="phi"):
        configuration(phi)  # type: ignore[arg-type]


@pytest.mark.parametrize("n", [True, 1, 2.0, "5", None])
def test_n_is_an_integer_of_at_least_two(n: object) -> None:
    """n = True (a bool), 1 or 2.0 is refused by every posture function."""
    for call in (straight, initial_state, lambda m: arc(m, 0.1), lambda m: Serpenoid(m, 0.1, 1.0)):
        with pytest.raises(ParameterError, match="n must"):
            call(n)  # type: ignore[operator]


@pytest.mark.parametrize("t", [0.0, 0.37, 2.5])
def test_serpenoid_derivatives_are_those_of_its_angles(t: float) -> None:
    """derivatives(t) is (phi, phi', phi'') of eq. (43): phi as angles(t), the rates by
    central differences of angles in time."""
    gait = Serpenoid(n=10, alpha=0.6, ts=1.3, v=2.1)
    phi, dphi, ddphi = gait.derivatives(t)
    h = 1e-4
    before, after = gait.angles(t - h), gait.angles(t + h)
    assert np.array_equal(phi, gait.angles(t))
    assert np.allclose(dphi, (after - before) / (2 * h), rtol=1e-6, atol=1e-8)
    assert np.allclose(ddphi, (after - 2 * phi + before) / h**2, rtol=1e-4, atol=1e-5)
    assert np.abs(dphi).max() > 0.1 and np.abs(ddphi).max() > 0.1  # not a still gait
