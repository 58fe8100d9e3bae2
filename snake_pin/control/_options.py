"""The controllers' options: their fields checked (:func:`check_fields`), merged with keyword
overrides (:func:`merged`), and the gains of (84) the Lyapunov-like laws share.
"""

from __future__ import annotations

from dataclasses import fields, is_dataclass, replace
from typing import Any, TypeVar

import numpy as np

from .._options import option
from .._validation import brief, finite_number, flag, instance, integer
from ..exceptions import ParameterError
from .gains import K_PHI_FIRST, K_PHI_REST, gain_matrix

T = TypeVar("T")


def tracking_gain(name: str) -> Any:
    """The field of a gain of (84) (``k_w1``, ``k_w2`` or ``k_phi``): both Lyapunov-like
    laws declare theirs with it, so that the two share one default and one domain."""
    return option(**_TRACKING_GAINS[name])


#: The gains of (84): K_w1 and K_w2 on the head, K_phi (None: :func:`default_k_phi`).
_TRACKING_GAINS: dict[str, dict[str, Any]] = {
    "k_w1": {"default": (2.0, 2.0, 3.0), "doc": "rates of the head's error", "unit": "1/s",
             "low": 0.0, "open_low": True, "symbol": "K_w1", "size": 3,
             "entries": ("x", "y", "theta")},
    "k_w2": {"default": (400.0, 400.0, 45.0), "doc": "weights of the head's error in V",
             "low": 0.0, "open_low": True, "symbol": "K_w2", "size": 3,
             "entries": ("x", "y", "theta")},
    "k_phi": {"default": None, "doc": "weights of the joints' error in V", "low": 0.0,
              "open_low": True, "symbol": "K_phi",
              "default_doc": f"{K_PHI_FIRST:g} on joint 1, {K_PHI_REST:g} on the others"},
}


def _frozen_gain(value: object, symbol: str, size: int | None, definite: bool) -> Any:
    """A gain checked and stored hashable: a float, a tuple or a tuple of rows."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        arr = np.zeros((0, 0))  # gain_matrix below says why
    order = size if size is not None else (max(arr.shape[0], 1) if arr.ndim in (1, 2) else 1)
    gain_matrix(value, order, symbol, definite=definite)
    return float(arr) if arr.ndim == 0 else tuple(
        arr.tolist() if arr.ndim == 1 else map(tuple, arr.tolist()))


def check_fields(options: Any) -> None:
    """Validate and normalise every field of an options dataclass (its ``__post_init__``):
    a field outside its domain is a ParameterError of one line naming it."""
    for f in fields(options):
        meta, value = f.metadata, getattr(options, f.name)
        if value is None and f.default is None:
            continue  # resolved per robot
        low, high = meta["low"], meta["high"]
        if meta["symbol"]:
            value = _frozen_gain(value, meta["symbol"], meta["size"], meta["open_low"])
        elif isinstance(f.default, bool):
            value = flag(value, f.name)
        elif isinstance(f.default, int):
            value = integer(value, f.name, low=None if low is None else int(low),
                            high=None if high is None else int(high))
        elif is_dataclass(f.default):
            value = instance(value, type(f.default), f.name)
        else:
            value = finite_number(value, f.name)
            if low is not None and (value < low or (meta["open_low"] and value == low)):
                word = ("positive" if meta["open_low"] else "non-negative") if low == 0 else \
                    f"{'>' if meta['open_low'] else '>='} {low:g}"
                raise ParameterError(f"{f.name} must be {word}, got {value}")
            if high is not None and value > high:
                raise ParameterError(f"{f.name} must be <= {high:g}, got {value}")
            value = 0.0 if value == 0.0 else value
        object.__setattr__(options, f.name, value)


def merged(cls: type[T], options: T | None, overrides: dict[str, object], *,
           argument: str = "options", field_word: str = "") -> T:
    """``options`` (or the defaults) with a constructor's keyword ``overrides``; a wrong
    ``options`` type (named ``argument``) or an unknown override (a ``field_word``, default
    "<class> field") is a ParameterError."""
    base = cls() if options is None else options
    if not isinstance(base, cls):
        raise ParameterError(f"{argument} must be {cls.__name__}, got {brief(base)}")
    known = [f.name for f in fields(cls)]  # type: ignore[arg-type]
    for key in overrides:
        if key not in known:
            raise ParameterError(f"unknown {field_word or cls.__name__ + ' field'} {key!r} "
                                 f"(expected one of {', '.join(known)})")
    return replace(base, **overrides) if overrides else base  # type: ignore[type-var]
