"""The shared argument checkers of snake_pin._validation: what they accept and how they say no."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from snake_pin._validation import (
    BRIEF_CHARS,
    as_vector,
    brief,
    check_params,
    finite_number,
    flag,
    instance,
    integer,
    one_line,
    output_file,
    printable_path,
)
from snake_pin.exceptions import ConfigurationError, ParameterError
from snake_pin.params import SnakeParams


@pytest.mark.parametrize("text", ["1e-6", "2", b"0.5", bytearray(b"3")])
def test_finite_number_refuses_numeric_text(text: object) -> None:
    """Text is refused even when it reads as a number, in one line naming the argument."""
    with pytest.raises(ParameterError, match=r"^dt must be a number, got ") as info:
        finite_number(text, "dt")
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("value", [np.eye(40), np.array([1.0]), list(range(1000)),
                                   {"a": np.eye(5)}, "x" * 10_000, 10**400])
def test_finite_number_describes_a_bad_value_in_one_short_line(value: object) -> None:
    """An array, a long list or long text is described briefly: one line, bounded length."""
    with pytest.raises(ParameterError, match=r"^gain ") as info:
        finite_number(value, "gain")
    message = str(info.value)
    assert "\n" not in message and len(message) <= len("gain must be a number, got ") + 50


@pytest.mark.parametrize(("value", "expected"), [(3, 3.0), (np.float32(0.25), 0.25),
                                                 (np.array(2.5), 2.5), (1e-6, 1e-6)])
def test_finite_number_accepts_real_numbers(value: object, expected: float) -> None:
    """Python and numpy scalars (0-d arrays too) come back as the same float."""
    assert finite_number(value, "x", positive=True) == expected


@pytest.mark.parametrize(("value", "words"), [(True, "number"), (np.bool_(False), "number"),
                                              (float("nan"), "finite"), (0.0, "positive"),
                                              (-1.0, "non-negative")])
def test_finite_number_refusals(value: object, words: str) -> None:
    """Booleans, non-finite values and sign violations are refused with the reason."""
    positive = words == "positive"
    with pytest.raises(ParameterError, match=words):
        finite_number(value, "x", positive=positive, non_negative=not positive)


def test_brief_is_one_bounded_line() -> None:
    """brief keeps short scalars whole, cuts long text and names containers by type."""
    assert brief(0.5) == "0.5" and brief(None) == "None" and brief("abc") == "'abc'"
    cut = brief("line\n" * 100)
    assert "\n" not in cut and len(cut) <= BRIEF_CHARS and cut.endswith("...")
    assert brief(np.zeros((3, 4))) == "an array of shape (3, 4)"
    assert brief([1.0] * 100) == "a list" and brief(object()) == "an object"


def test_one_line_and_printable_path() -> None:
    """one_line joins whitespace and bounds the length; printable_path quotes control chars."""
    assert one_line("a\n  b\tc") == "a b c"
    assert one_line("x" * 50, 10) == "x" * 7 + "..."
    assert printable_path("dir/file.toml") == "dir/file.toml"
    assert printable_path("bad\nname") == repr("bad\nname")
    assert printable_path(b"raw.toml") == "raw.toml"


def test_integer_flag_and_params() -> None:
    """integer checks type and range, flag wants a real bool, check_params a SnakeParams."""
    assert integer(np.int64(4), "n", low=2) == 4
    for bad, words in [(True, "integer"), (2.0, "integer"), ("3", "integer"),
                       (1, ">= 2"), (9, "2..8")]:
        with pytest.raises(ParameterError, match=f"n must .*{words}"):
            integer(bad, "n", low=2, high=None if words == ">= 2" else 8)
    assert flag(np.bool_(True), "heading") is True
    with pytest.raises(ParameterError, match="heading must be True or False, got 1"):
        flag(1, "heading")
    params = SnakeParams.table1(n=3)
    assert check_params(params) is params
    with pytest.raises(ParameterError, match="robot must be a SnakeParams, got a dict"):
        check_params({"n": 3}, "robot")


def test_instance_names_the_argument_and_the_wanted_kind() -> None:
    """instance returns a value of the kind unchanged and words a refusal as 'NAME must be'."""
    params = SnakeParams.table1(n=3)
    assert instance(params, SnakeParams, "robot") is params
    with pytest.raises(ParameterError, match=r"^robot must be a SnakeParams, got None$"):
        instance(None, SnakeParams, "robot")
    with pytest.raises(ParameterError, match=r"^model must be a Pinocchio model, got 'x'$"):
        instance("x", SnakeParams, "model", "a Pinocchio model")


def test_output_file_refuses_before_anything_is_written(tmp_path: Path) -> None:
    """output_file gives the path of a SnakeParams file of the right suffix in an existing
    folder, and refuses every other case in one line naming what is wrong."""
    params = SnakeParams.table1(n=3)
    assert output_file(params, str(tmp_path / "r.toml"), ".toml", "robot file") == \
        tmp_path / "r.toml"
    (tmp_path / "file").write_text("")
    for args, words in [((None, tmp_path / "r.toml"), "^params must be a SnakeParams"),
                        ((params, 3), "^path must be a file path, got 3$"),
                        ((params, tmp_path / "r.txt"), "^robot file must end in .toml: "),
                        ((params, tmp_path / "no" / "r.toml"), "^output directory does not"),
                        ((params, tmp_path / "file" / "r.toml"), "^output directory does not")]:
        with pytest.raises(ParameterError, match=words):
            output_file(*args, ".toml", "robot file")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_as_vector_errors_are_configuration_errors() -> None:
    """as_vector refuses a wrong size and non-finite entries as ConfigurationError."""
    assert as_vector([1, 2], 2, "w").dtype == float
    with pytest.raises(ConfigurationError, match="w must have 2 entries, got 3"):
        as_vector([1, 2, 3], 2, "w")
    with pytest.raises(ConfigurationError, match="w has non-finite entries"):
        as_vector([1, np.inf], 2, "w")


def test_closed_form_modules_import_neither_pinocchio_nor_the_model() -> None:
    """paper and _validation stay plain numpy: importing them loads no Pinocchio."""
    code = ("import sys, snake_pin.paper, snake_pin._validation; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'pinocchio' "
            "or m == 'snake_pin.model'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"
