"""Fields of options dataclasses: default, bounds and one-line doc in one place (read by
:func:`documented`, :func:`snake_pin.control._options.check_fields` and
:mod:`snake_pin.study.spec`); a field's kind is its default's type (bool, int, a dataclass,
else a real number or a gain).
"""

from __future__ import annotations

import inspect
from dataclasses import field, fields, is_dataclass
from typing import Any, TypeVar

__all__ = ["documented", "option"]

T = TypeVar("T")


def option(default: Any, doc: str, *, unit: str = "", low: float | None = None,
           high: float | None = None, open_low: bool = False, symbol: str = "",
           size: int | None = None, entries: tuple[str, ...] = (),
           default_doc: str = "") -> Any:
    """A dataclass field with its one-line doc and domain in ``metadata``; a ``symbol`` makes
    it a gain matrix (``size`` 3 for the head, None for the joints: only the robot knows),
    definite if ``open_low``; ``entries`` names a head gain's diagonal in study files."""
    return field(default=default, metadata={
        "doc": doc, "unit": unit, "low": low, "high": high, "open_low": open_low,
        "symbol": symbol, "size": size, "entries": entries, "default_doc": default_doc})


def documented(cls: type[T]) -> type[T]:
    """Complete an options dataclass's one-line docstring with numpydoc Parameters and Raises
    sections made from its fields' metadata (the texts study files show, written once)."""
    lines = [inspect.cleandoc(cls.__doc__ or ""), "", "Parameters", "----------"]
    for f in fields(cls):  # type: ignore[arg-type]
        meta, default = f.metadata, f.default
        if meta["symbol"]:
            kind = "float or array_like"
            domain = "positive definite" if meta["open_low"] else "positive semi-definite"
        else:
            kind = type(default).__name__ if isinstance(default, (bool, int, str)) or \
                is_dataclass(default) else "float"
            low, high = meta["low"], meta["high"]
            domain = ", ".join(([] if low is None else [f"{'>' if meta['open_low'] else '>='} "
                                                        f"{low:g}"])
                               + ([] if high is None else [f"<= {high:g}"]))
        shown = meta["default_doc"] or (f"``{type(default).__name__}()``" if is_dataclass(default)
                                        else f"``{default:g}``" if type(default) is float
                                        else f"``{default}``")
        text = meta["doc"][:1].upper() + meta["doc"][1:].replace("|", "\\|")
        lines += [f"{f.name} : {kind}{' or None' if default is None else ''}, optional",
                  f"    {meta['symbol'] + ', ' if meta['symbol'] else ''}{text}"
                  f"{' [' + meta['unit'] + ']' if meta['unit'] else ''}"
                  f"{' (' + domain + ')' if domain else ''}; default {shown}."]
    lines += ["", "Raises", "------", "ParameterError",
              "    A field outside its domain or in conflict with another (one line naming it)."]
    cls.__doc__ = "\n".join(lines)
    return cls
