"""JSON text of results (RFC 8259): the one way snake_pin writes JSON, NaN as ``null``."""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Mapping
from typing import Any

__all__ = ["json_safe", "json_text"]


def json_safe(value: Any) -> Any:
    """``value`` as plain JSON data.

    Parameters
    ----------
    value
        JSON data, NumPy arrays and scalars, paths or dataclasses, nested in any way.

    Returns
    -------
    Any
        The same as plain JSON data (NaN and infinities as None, keys as strings).

    Raises
    ------
    TypeError
        For anything else that JSON cannot hold.
    """
    if value is None or isinstance(value, (bool, str, int)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set, frozenset)):
        return [json_safe(v) for v in value]
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if hasattr(value, "tolist"):  # NumPy arrays and scalars
        return json_safe(value.tolist())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return json_safe(dataclasses.asdict(value))
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def json_text(value: Any, *, indent: int | None = None) -> str:
    """RFC 8259 JSON text of ``value`` after :func:`json_safe` (never NaN or Infinity).

    Parameters
    ----------
    value
        Anything :func:`json_safe` accepts.
    indent
        Indentation of nested levels (None: one line).

    Returns
    -------
    str
        The JSON text, without a trailing newline.
    """
    return json.dumps(json_safe(value), indent=indent, allow_nan=False)
