"""snake_pin.control._options: the fields of the controllers' options dataclasses."""

from __future__ import annotations

from dataclasses import FrozenInstanceError, fields

import numpy as np
import pytest

from snake_pin import ParameterError
from snake_pin.control import LyapunovOptions, MPCOptions, PFLOptions, QuasiStaticOptions
from snake_pin.ocp import CostWeights

OPTIONS = (LyapunovOptions, PFLOptions, QuasiStaticOptions, MPCOptions, CostWeights)


@pytest.mark.parametrize("cls", OPTIONS)
def test_every_field_has_a_doc_and_is_in_the_class_docstring(cls: type) -> None:
    """Each field carries a one-line doc and the class docstring lists it."""
    for f in fields(cls):
        assert f.metadata["doc"] and "\n" not in f.metadata["doc"], f.name
        assert f.name in (cls.__doc__ or ""), f.name


@pytest.mark.parametrize("cls", OPTIONS)
def test_defaults_are_valid_and_frozen(cls: type) -> None:
    """The defaults construct, and an options object cannot be changed in place."""
    options = cls()
    with pytest.raises(FrozenInstanceError):
        options.k_w1 = 1.0  # type: ignore[attr-defined]
    assert options == cls()


def test_gains_are_stored_hashable() -> None:
    """A gain given as an array is kept as a tuple (options compare and hash)."""
    options = LyapunovOptions(k_w1=np.array([1.0, 2.0, 3.0]), k_phi=np.eye(2) * 5)
    assert options.k_w1 == (1.0, 2.0, 3.0)
    assert options.k_phi == ((5.0, 0.0), (0.0, 5.0))
    assert hash(options) == hash(LyapunovOptions(k_w1=(1, 2, 3), k_phi=((5, 0), (0, 5))))


@pytest.mark.parametrize("value", [True, "1", float("inf"), [[1.0, 2.0], [0.0, 1.0]]])
def test_a_bad_gain_is_one_line_naming_it(value: object) -> None:
    """A bool, text, an infinite or an asymmetric gain: one ParameterError line naming it."""
    with pytest.raises(ParameterError) as info:
        PFLOptions(r_v=value)
    assert "\n" not in str(info.value) and "R_v" in str(info.value)


def test_a_field_has_its_default_s_kind() -> None:
    """An int field takes any integer and stores an int, a bool field True or False only; a
    real, a bool or text in an int field, 1 in a bool field: one line naming the field."""
    options = MPCOptions(iterations=np.int64(4), feedback=np.bool_(False))
    assert type(options.iterations) is int and options.iterations == 4
    assert options.feedback is False
    for changes in ({"iterations": 2.0}, {"iterations": True}, {"step_halvings": "3"},
                    {"feedback": 1}, {"first_iterations": 0}):
        with pytest.raises(ParameterError) as info:
            MPCOptions(**changes)  # type: ignore[arg-type]
        name = next(iter(changes))
        assert "\n" not in str(info.value) and str(info.value).startswith(name), changes
