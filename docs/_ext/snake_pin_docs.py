"""Local Sphinx extension: the pages of the snake_pin site that are read off the code.

Three directives, each re-reading the package at build time, so the pages cannot drift
from the code:

``.. snake-pin-cli::``
    The command-line reference: :func:`snake_pin.cli.build_parser` is called and every
    subcommand's usage, description and options are rendered (``.. program::`` /
    ``.. option::``, so ``:option:`snake-pin sweep --points``` links work).
``.. snake-pin-equations::``
    "Equations to code": the docstrings of every public module, class, function and
    method are searched for the paper's equation numbers (``eq. (19)``, ``eqs. 10-13``,
    ``eqs. 30, 31, 42``) and a table maps each number to the objects that cite it.
``.. snake-pin-public-names:: PACKAGE``
    A table of a package's ``__all__``: each name, linked to the object where it is
    defined (documented there in full), and the first line of its docstring.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import inspect
import os
import pkgutil
import re
from collections import defaultdict
from collections.abc import Iterator
from types import ModuleType
from typing import Any

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

__all__ = ["PAPER_SECTIONS", "equation_references", "escape_text", "public_modules", "setup"]

#: Equation ranges of the paper's sections (Ariizumi and Tanaka).
PAPER_SECTIONS = (
    (1, 20, "II: the model"),
    (21, 42, "III: manipulability"),
    (43, 43, "IV: posture families"),
    (44, 67, "V: integrability"),
    (68, 82, "VI.1: PFL controller"),
    (83, 90, "VI.2: Lyapunov-like controller"),
)

_NUMBER = r"\(?(\d{1,3})\)?"
#: "eq. (19)", "Eq. 43", "eqs. (10)-(13)", "eqs. 30, 31, 42", "eqs. 3-4 and 17"
_EQ_REFERENCE = re.compile(
    rf"\b[Ee]qs?\.\s*{_NUMBER}((?:\s*(?:-|–|,|,?\s*and|to)\s*{_NUMBER})*)")
_EQ_TAIL = re.compile(rf"\s*(-|–|,|,?\s*and|to)\s*{_NUMBER}")


#: Inline constructs kept as they are in plain text: backslash escapes, inline literals,
#: roles with their text, interpreted text, strong and emphasis closed on the line.
_PROTECTED = re.compile(
    r"\\."
    r"|``.+?``"
    r"|(?::[\w:+.-]+:)?`[^`]+`(?::[\w:+.-]+:)?_{0,2}"
    r"|(?<![\w*\\])\*\*(?=\S)(?:\\.|[^*\\])+?(?<=[^\s\\])\*\*(?![\w*])"
    r"|(?<![\w*\\])\*(?=[^\s*])(?:\\.|[^*\\])+?(?<=[^\s\\])\*(?![\w*])"
)


def escape_text(line: str) -> str:
    """One line of plain text (a CLI help, a summary) with ``|`` and a lone ``*`` escaped
    for reStructuredText, outside inline literals and roles; a leading bullet is kept."""
    bullet = re.match(r"^\s*[*+-]\s+", line)
    if bullet:
        return bullet.group(0) + escape_text(line[bullet.end():])
    parts, last = [], 0
    for match in _PROTECTED.finditer(line):
        parts.append(re.sub(r"([*|])", r"\\\1", line[last:match.start()]))
        parts.append(match.group(0))
        last = match.end()
    parts.append(re.sub(r"([*|])", r"\\\1", line[last:]))
    return "".join(parts)


def _text(text: str) -> str:
    """Help or description text: inline literals and roles kept, stray markup escaped."""
    return "\n".join(escape_text(line) for line in text.splitlines())


def _sentence(text: str) -> str:
    """``text`` with a capital first letter and a full stop."""
    text = text.strip()
    if not text:
        return text
    text = text[0].upper() + text[1:]
    return text if text[-1] in ".!?)" and not text.endswith("e.g.)") else text + "."


def _indent(text: str, prefix: str = "   ") -> list[str]:
    return [prefix + line if line.strip() else "" for line in text.splitlines()]


class _RstDirective(SphinxDirective):
    """A directive that produces reStructuredText and parses it in place."""

    def rst(self) -> list[str]:  # pragma: no cover - overridden
        raise NotImplementedError

    def run(self) -> list[nodes.Node]:
        container = nodes.section()
        container.document = self.state.document
        source = self.get_source_info()[0]
        lines = StringList()
        for i, line in enumerate(self.rst()):
            lines.append(line, source, i)
        nested_parse_with_titles(self.state, lines, container)
        return list(container.children)


# ------------------------------------------------------------------------------ CLI
@contextlib.contextmanager
def _columns(width: int) -> Iterator[None]:
    """argparse wraps usage lines to $COLUMNS: fix it for a reproducible page."""
    saved = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(width)
    try:
        yield
    finally:
        if saved is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = saved


def _subcommands(parser: argparse.ArgumentParser
                 ) -> list[tuple[str, str, argparse.ArgumentParser]]:
    """(name, one-line help, parser) of each subcommand, in the parser's order."""
    found = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {choice.dest: choice.help or "" for choice in action._choices_actions}
            seen: set[int] = set()
            for name, sub in action.choices.items():
                if id(sub) in seen:  # aliases
                    continue
                seen.add(id(sub))
                found.append((name, helps.get(name, ""), sub))
    return found


def _option_lines(parser: argparse.ArgumentParser) -> list[str]:
    formatter = parser._get_formatter()
    lines: list[str] = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction | argparse._HelpAction):
            continue
        if action.help == argparse.SUPPRESS:
            continue
        if action.option_strings:
            signature = formatter._format_action_invocation(action)
        else:
            metavar = formatter._format_args(action, action.dest)
            signature = action.dest if metavar == action.dest else f"{action.dest} {metavar}"
        text = _sentence(formatter._expand_help(action)) if action.help else ""
        extra = []
        if action.required and action.option_strings:
            extra.append("Required.")
        if action.choices is not None and not isinstance(action, argparse._SubParsersAction):
            extra.append("Choices: " + ", ".join(f"``{c}``" for c in action.choices) + ".")
        default = action.default
        if (action.option_strings and default not in (None, False, [], argparse.SUPPRESS)
                and not isinstance(action, argparse._VersionAction)):
            extra.append(f"Default: ``{default!r}``.")
        if isinstance(action, argparse._AppendAction) and "repeatable" not in text.lower():
            extra.append("Repeatable.")
        body = " ".join(part for part in (_text(text), *extra) if part)
        lines += ["", f".. option:: {signature}", ""]
        lines += _indent(body or "(no description)")
    return lines


def _parser_lines(prog: str, parser: argparse.ArgumentParser, level: str,
                  summary: str = "") -> list[str]:
    title = f"``{prog}``"
    anchor = "cli-" + re.sub(r"[^a-z0-9]+", "-", prog.lower()).strip("-")
    lines = [f".. _{anchor}:", "", title, level * len(title), ""]
    if summary:
        lines += [_text(_sentence(summary)), ""]
    if parser.description and parser.description != summary:
        lines += [_text(parser.description), ""]
    lines += ["Usage:", "", ".. code-block:: text", ""]
    lines += _indent(parser.format_usage().removeprefix("usage: ").rstrip())
    lines += ["", f".. program:: {prog}"]
    lines += _option_lines(parser)
    lines.append("")
    for name, helptext, sub in _subcommands(parser):
        lines += _parser_lines(f"{prog} {name}", sub, "^" if level == "-" else '"', helptext)
    return lines


class CliReference(_RstDirective):
    """Render ``snake_pin.cli.build_parser()``: the top level, then each subcommand."""

    has_content = False

    def rst(self) -> list[str]:
        from snake_pin import cli

        self.env.note_dependency(cli.__file__)
        with _columns(88):
            parser = cli.build_parser()
            lines = [_text(parser.description or ""), "", "Usage:", "",
                     ".. code-block:: text", ""]
            lines += _indent(parser.format_usage().removeprefix("usage: ").rstrip())
            if parser.epilog:
                lines += ["", ".. code-block:: text", ""]
                lines += _indent(parser.epilog.rstrip())
            lines += ["", ".. program:: snake-pin"]
            lines += _option_lines(parser)
            lines += [""]
            for name, helptext, sub in _subcommands(parser):
                lines += _parser_lines(f"snake-pin {name}", sub, "-", helptext)
        return lines


# ------------------------------------------------------------------------ equations
def public_modules(package: str = "snake_pin") -> list[ModuleType]:
    """The package and every public submodule (no name part starting with ``_``)."""
    root = importlib.import_module(package)
    found = [root]
    for info in pkgutil.walk_packages(root.__path__, prefix=f"{package}."):
        if any(part.startswith("_") for part in info.name.split(".")):
            continue
        found.append(importlib.import_module(info.name))
    return found


def _numbers(match: re.Match[str]) -> list[int]:
    numbers = [int(match.group(1))]
    for joiner, value in _EQ_TAIL.findall(match.group(2)):
        number = int(value)
        if joiner.strip() in ("-", "–", "to") and 0 < number - numbers[-1] <= 60:
            numbers += range(numbers[-1] + 1, number + 1)
        else:
            numbers.append(number)
    return numbers


def _documented(module: ModuleType) -> Iterator[tuple[str, str, Any]]:
    """(role, full name, object) of the module and its public members defined in it."""
    yield "mod", module.__name__, module
    names = getattr(module, "__all__", None)
    if names is None:
        return
    for name in names:
        obj = getattr(module, name, None)
        if not (inspect.isclass(obj) or inspect.isfunction(obj)):
            continue
        if getattr(obj, "__module__", None) != module.__name__:
            continue  # documented where it is defined
        full = f"{module.__name__}.{name}"
        if inspect.isfunction(obj):
            yield "func", full, obj
            continue
        yield "class", full, obj
        for attr, member in vars(obj).items():
            if attr.startswith("_") and attr != "__call__":
                continue
            function = member.fget if isinstance(member, property) else member
            function = getattr(function, "__func__", function)
            if inspect.isfunction(function):
                role = "attr" if isinstance(member, property) else "meth"
                yield role, f"{full}.{attr}", function


def equation_references(modules: list[ModuleType]) -> dict[int, list[tuple[str, str]]]:
    """Equation number -> [(role, full name)] of the objects whose docstrings cite it."""
    table: dict[int, list[tuple[str, str]]] = defaultdict(list)
    for module in modules:
        for role, full, obj in _documented(module):
            doc = inspect.getdoc(obj) if role != "mod" else (obj.__doc__ or "")
            if not doc:
                continue
            cited: set[int] = set()
            for match in _EQ_REFERENCE.finditer(doc):
                cited.update(n for n in _numbers(match) if 1 <= n <= 90)
            for number in sorted(cited):
                if (role, full) not in table[number]:
                    table[number].append((role, full))
    return dict(table)


def _section(number: int) -> str:
    for low, high, name in PAPER_SECTIONS:
        if low <= number <= high:
            return name
    return ""


class EquationTable(_RstDirective):
    """The equations-to-code table, read off the docstrings at build time."""

    has_content = False

    def rst(self) -> list[str]:
        modules = public_modules()
        for module in modules:
            if module.__file__:
                self.env.note_dependency(module.__file__)
        table = equation_references(modules)
        lines = [".. list-table::", "   :header-rows: 1", "   :widths: 10 18 45 27", "",
                 "   * - eq.", "     - section", "     - functions, classes, methods",
                 "     - modules"]
        for first, last, cited in _runs(table):
            label = f"\\({first})" if first == last else f"\\({first})–({last})"
            objects = [f":py:{role}:`{full.removeprefix('snake_pin.')} <{full}>`"
                       for role, full in cited if role != "mod"]
            mods = [f":py:mod:`{full}`" for role, full in cited if role == "mod"]
            lines += [f"   * - {label}", f"     - {_section(first)}",
                      f"     - {', '.join(objects) or '—'}", f"     - {', '.join(mods) or '—'}"]
        return lines


def _runs(table: dict[int, list[tuple[str, str]]]
          ) -> list[tuple[int, int, list[tuple[str, str]]]]:
    """Consecutive equations of one section cited by the same objects, as one row."""
    rows: list[tuple[int, int, list[tuple[str, str]]]] = []
    for number in sorted(table):
        cited = sorted(table[number])
        if rows and rows[-1][1] == number - 1 and sorted(rows[-1][2]) == cited \
                and _section(rows[-1][0]) == _section(number):
            rows[-1] = (rows[-1][0], number, rows[-1][2])
        else:
            rows.append((number, number, cited))
    return rows


# ---------------------------------------------------------------------- public names
def _canonical(package: str, name: str, obj: Any) -> tuple[str, str]:
    """(role, full name) of the place where ``obj`` is documented."""
    if inspect.ismodule(obj):
        return "mod", obj.__name__
    module = getattr(obj, "__module__", None)
    qualname = getattr(obj, "__qualname__", None)
    if module and qualname and module.startswith("snake_pin") and not any(
            part.startswith("_") for part in module.split(".")):
        role = "exc" if inspect.isclass(obj) and issubclass(obj, BaseException) else \
            "class" if inspect.isclass(obj) else "func"
        return role, f"{module}.{qualname}"
    return "data", f"{package}.{name}"


def _public(package: ModuleType, name: str) -> Any:
    """``package.name``; a function named like its module (``snake_pin.manipulability``)
    is read from the module, as importing the submodule shadows the package's name."""
    obj = getattr(package, name)
    if inspect.ismodule(obj) and obj.__name__ == f"{package.__name__}.{name}" \
            and callable(getattr(obj, name, None)):
        return getattr(obj, name)
    return obj


def _summary(obj: Any) -> str:
    doc = inspect.getdoc(obj) or ""
    first = doc.strip().split("\n\n")[0].replace("\n", " ").strip()
    return escape_text(first)


class PublicNames(_RstDirective):
    """A table of ``PACKAGE.__all__``, each name linked to its documentation."""

    required_arguments = 1
    has_content = False

    def rst(self) -> list[str]:
        package = importlib.import_module(self.arguments[0])
        names = list(getattr(package, "__all__", ()))
        if not names:
            return ["The package exports no names of its own: see its modules."]
        lines = [".. list-table::", "   :header-rows: 1", "   :widths: 30 70", "",
                 "   * - name", "     - what it is"]
        for name in names:
            obj = _public(package, name)
            role, target = _canonical(package.__name__, name, obj)
            link = f":py:{role}:`{name} <{target}>`" if role != "data" else f"``{name}``"
            summary = _summary(obj) if role != "data" else ""
            lines += [f"   * - {link}", f"     - {summary or '—'}"]
        own = [name for name in names
               if getattr(_public(package, name), "__module__", None) == package.__name__]
        for name in own:  # defined in the package itself: documented here
            obj = _public(package, name)
            kind = "class" if inspect.isclass(obj) else \
                "function" if callable(obj) else "data"
            lines += ["", f".. auto{kind}:: {package.__name__}.{name}"]
        return lines


def setup(app: Sphinx) -> dict[str, Any]:
    """Register the directives."""
    app.add_directive("snake-pin-cli", CliReference)
    app.add_directive("snake-pin-equations", EquationTable)
    app.add_directive("snake-pin-public-names", PublicNames)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
