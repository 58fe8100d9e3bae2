"""The package's generic argument checkers, each raising one line naming the argument
(the command line's argparse types too).

It imports neither Pinocchio nor :mod:`snake_pin.model`, so :mod:`snake_pin.paper` can use it.
"""

from __future__ import annotations

import argparse
import math
import numbers
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from .exceptions import ConfigurationError, ParameterError
from .params import SnakeParams, is_number

__all__ = ["as_vector", "brief", "check_params", "finite_number", "flag", "float_arg",
           "instance", "int_arg", "integer", "is_number", "mebibytes", "model_data",
           "number_arg", "one_line", "output_file", "printable_path", "vector"]

_T = TypeVar("_T")

#: The longest text :func:`brief` shows of a value (longer ones are cut, or named by type).
BRIEF_CHARS = 40


def mebibytes(nbytes: int) -> str:
    """A byte count in MiB for messages (``"16 MiB"``)."""
    return f"{nbytes / 2**20:.4g} MiB"


def brief(value: object) -> str:
    """``value`` for a one-line message: a scalar's or text's repr (cut), else its type."""
    if value is None or isinstance(value, (bool, int, float, str, bytes, np.generic)):
        return one_line(repr(value), BRIEF_CHARS)
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape}"
    kind = type(value).__name__
    return f"{'an' if kind[:1].lower() in 'aeiou' else 'a'} {kind}"


def one_line(text: str, limit: int = 200) -> str:
    """``text`` with its whitespace runs (newlines included) made single spaces, at most
    ``limit`` characters (a longer one ends in ``...``)."""
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def printable_path(path: object) -> str:
    """A path as one printable line (a name with control characters is quoted)."""
    raw = os.fspath(path) if isinstance(path, (str, bytes, os.PathLike)) else str(path)
    text = os.fsdecode(raw) if isinstance(raw, bytes) else raw
    return text if text.isprintable() else repr(text)



def integer(value: object, name: str, *, low: int | None = None,
            high: int | None = None) -> int:
    """``value`` as an int in ``low..high`` (a bool is refused), or ParameterError."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise ParameterError(f"{name} must be an integer, got {brief(value)}")
    number = int(value)
    if (low is not None and number < low) or (high is not None and number > high):
        span = (f"be >= {low}" if high is None else f"be <= {high}" if low is None
                else f"lie in {low}..{high}")
        raise ParameterError(f"{name} must {span}, got {number}")
    return number


def flag(value: object, name: str) -> bool:
    """``value`` as a bool: True or False only (not 0/1, not text), or ParameterError."""
    if not isinstance(value, (bool, np.bool_)):
        raise ParameterError(f"{name} must be True or False, got {brief(value)}")
    return bool(value)


def instance(value: object, kind: type[_T], name: str, what: str | None = None) -> _T:
    """``value`` if it is a ``kind``, else ParameterError: ``{name} must be {what}, got ...``
    (``what`` defaults to ``a {kind's name}``)."""
    if not isinstance(value, kind):
        raise ParameterError(f"{name} must be {what or 'a ' + kind.__name__}, "
                             f"got {brief(value)}")
    return value


def check_params(value: object, name: str = "params") -> SnakeParams:
    """``value`` if it is a :class:`~snake_pin.params.SnakeParams`, else ParameterError."""
    return instance(value, SnakeParams, name)


def output_file(params: object, path: object, suffix: str, what: str) -> Path:
    """``path`` to write ``params`` (a SnakeParams) to: a ``suffix`` file in an existing
    folder, or ParameterError naming the argument (nothing is written)."""
    check_params(params)
    if not isinstance(path, (str, os.PathLike)):
        raise ParameterError(f"path must be a file path, got {brief(path)}")
    path = Path(path)
    if path.suffix != suffix:
        raise ParameterError(f"{what} must end in {suffix}: {path}")
    if not path.parent.is_dir():
        raise ParameterError(f"output directory does not exist: {path.parent}")
    return path


def model_data(value: object, model: Any, kind: type, name: str = "data") -> Any:
    """``value`` if it is a ``kind`` (``pinocchio.Data``) of ``model``, else ParameterError."""
    data: Any = instance(value, kind, name, "a pinocchio.Data")
    if len(data.oMi) != model.njoints:
        raise ParameterError(f"{name} has {len(data.oMi)} joints, the model "
                             f"{model.njoints}: use model.createData()")
    return data


def as_vector(value: object, size: int, name: str) -> np.ndarray:
    """``value`` as a finite float vector of ``size`` entries (flattened), or ConfigurationError."""
    try:
        vec = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(f"{name} must be a vector of {size} numbers") from exc
    if vec.size != size:
        raise ConfigurationError(f"{name} must have {size} entries, got {vec.size}")
    if not np.all(np.isfinite(vec)):
        raise ConfigurationError(f"{name} has non-finite entries")
    return vec


def vector(value: object, name: str, *, size: int | None = None,
           finite: bool = True) -> np.ndarray:
    """``value`` as a non-empty 1-D float vector (of ``size`` entries; finite unless told),
    or one ConfigurationError line (:func:`as_vector` flattens instead)."""
    try:
        raw = np.asarray(value)
        if raw.dtype.kind not in "iuf":  # no text, bool or object arrays cast to floats
            raise TypeError(raw.dtype)
        vec = raw.astype(float)
    except (TypeError, ValueError) as exc:
        raise ConfigurationError(f"{name} must be a vector of numbers, got {brief(value)}") \
            from exc
    if vec.ndim != 1 or vec.size == 0 or vec.size != (size or vec.size):
        raise ConfigurationError(f"{name} must be a non-empty vector"
                                 f"{f' of {size} numbers' if size else ''}, got {brief(value)} "
                                 f"of shape {vec.shape}")
    if finite and not np.all(np.isfinite(vec)):
        raise ConfigurationError(f"{name} has non-finite entries")
    return vec


def finite_number(value: object, name: str, *, positive: bool = False,
                  non_negative: bool = False) -> float:
    """``value`` as a finite float (> 0 if ``positive``, >= 0 if ``non_negative``; no bool or
    text), or ParameterError naming ``name``."""
    if isinstance(value, (bool, np.bool_, str, bytes, bytearray)) or \
            (isinstance(value, np.ndarray) and value.ndim != 0):
        raise ParameterError(f"{name} must be a number, got {brief(value)}")
    try:
        x = float(value)  # type: ignore[arg-type]
    except OverflowError:
        raise ParameterError(f"{name} must be finite, got {brief(value)}") from None
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be a number, got {brief(value)}") from exc
    if not math.isfinite(x):
        raise ParameterError(f"{name} must be finite, got {x}")
    if positive and x <= 0.0:
        raise ParameterError(f"{name} must be positive, got {x}")
    if non_negative and x < 0.0:
        raise ParameterError(f"{name} must be non-negative, got {x}")
    return x


def number_arg(text: str) -> float:
    """A command-line argument as a finite float (an argparse type)."""
    try:
        value = float(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from exc
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def float_arg(low: float, high: float = math.inf, *, open_low: bool = False
              ) -> Callable[[str], float]:
    """An argparse type: a finite float in [low, high] ((low, high] with ``open_low``)."""
    def parse(text: str) -> float:
        value = number_arg(text)
        if value < low or (open_low and value == low) or value > high:
            left = "(" if open_low else "["
            right = f"{high:g}]" if math.isfinite(high) else "inf)"
            raise argparse.ArgumentTypeError(f"must lie in {left}{low:g}, {right}, got {text}")
        return value
    return parse


def int_arg(low: int, high: int) -> Callable[[str], int]:
    """An argparse type: an integer in low..high."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from exc
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"must lie in {low}..{high}, got {value}")
        return value
    return parse
