"""Docstring policy: numpydoc sections on the public API, and only there; no project history.

Public callables (what a public module lists in ``__all__``, and the public methods of
those classes) pass numpydoc's validation, per defining module. Private helpers say what
and why in a line or two, without numpydoc sections. No docstring or comment in the
package names an issue number or a commit hash: history goes to ``CHANGELOG.md``, figures
to ``docs/performance.rst``.
"""

from __future__ import annotations

import ast
import builtins
import importlib
import inspect
import io
import pkgutil
import re
import textwrap
import tokenize
from collections import defaultdict
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from numpydoc.docscrape import get_doc_object
from numpydoc.validate import validate

import snake_pin
from snake_pin import exceptions
from snake_pin.exceptions import ParameterError, SnakePinError

#: numpydoc checks that fail the test: no docstring (GL08), a parameter not documented
#: (PR01), a documented parameter that does not exist (PR02), a parameter or a return
#: value without a description (PR07, RT03), no Returns section where something is
#: returned (RT01), no Yields section in a generator (YD01), an unknown section (GL06),
#: no one-line summary or one that does not end with a period (SS01, SS03). Beside them,
#: RS01 (this file's own): a snake_pin error raised on purpose (``raise XError(...)`` in
#: the callable's own body) that its Raises section does not name (nor a base class).
CHECKS = frozenset({"GL06", "GL08", "PR01", "PR02", "PR07", "RT01", "RT03", "YD01",
                    "SS01", "SS03", "RS01"})

#: Modules still being edited by other helpers: skipped (the reason says how many
#: problems each has left) until they are handed over and fixed.
PENDING: frozenset[str] = frozenset()

#: Files whose private helpers still carry numpydoc sections, owned by other helpers:
#: skipped by the private-helper check until they are fixed.
SECTIONS_PENDING: frozenset[str] = frozenset()

PACKAGE = Path(snake_pin.__file__).resolve().parent
#: A numpydoc section heading (a known name underlined by dashes).
SECTION = re.compile(r"^\s*(Parameters|Other Parameters|Returns|Yields|Receives|Raises|Warns"
                     r"|Attributes)\n\s*-{3,}\s*$", re.MULTILINE)
#: Project history: an issue number, or a commit hash (7-40 hex digits, letters and digits).
HISTORY = re.compile(r"\b[Ii]ssues?\s+#?\d+|(?<![\w&])#\d{1,4}\b"
                     r"|\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,40}\b")


def _public_modules() -> list[ModuleType]:
    """``snake_pin`` and every submodule whose dotted path has no ``_`` component."""
    modules = [snake_pin]
    for info in pkgutil.walk_packages(snake_pin.__path__, "snake_pin."):
        if any(part.startswith("_") for part in info.name.split(".")):
            continue
        modules.append(importlib.import_module(info.name))
    return modules


def _members(cls: type) -> dict[str, Any]:
    """Public methods and properties that ``cls`` itself defines (not inherited ones)."""
    return {name: getattr(cls, name) for name, value in vars(cls).items()
            if not name.startswith("_")
            and (isinstance(value, (staticmethod, classmethod, property))
                 or inspect.isfunction(value))}


def _public_api() -> dict[str, dict[str, Any]]:
    """Defining module -> {qualified name: object} of its public callables (each once).

    A name counts as public when a public module lists it in ``__all__``; it is checked
    under the module that defines it (``obj.__module__``), which may be private
    (``snake_pin._json`` re-exported by ``snake_pin.report``). Classes bring their own
    public methods and properties.
    """
    api: dict[str, dict[str, Any]] = defaultdict(dict)
    for module in _public_modules():
        for name in getattr(module, "__all__", ()):
            obj: Any = getattr(module, name)
            if isinstance(obj, ModuleType) or not callable(obj):
                continue
            home = getattr(obj, "__module__", None) or ""
            if not home.startswith("snake_pin"):
                continue
            qualname = f"{home}.{obj.__qualname__}"
            api[home][qualname] = obj
            if inspect.isclass(obj):
                for member, value in _members(obj).items():
                    api[home][f"{qualname}.{member}"] = value
    return {home: dict(sorted(objs.items())) for home, objs in sorted(api.items())}


API = _public_api()


def _bodies(obj: Any) -> list[Any]:
    """The functions whose own ``raise`` statements count for ``obj``'s Raises section."""
    if inspect.isclass(obj):
        found = [vars(obj).get("__init__"), vars(obj).get("__post_init__")]
    elif isinstance(obj, property):
        found = [obj.fget]
    else:
        found = [obj]
    return [inspect.unwrap(getattr(f, "__func__", f)) for f in found if f is not None]


def _raised(function: Any) -> set[type]:
    """snake_pin errors that ``function`` raises by name in its own body (not nested defs)."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(function)))
    except (OSError, TypeError):
        return set()
    top = tree.body[0]
    if not isinstance(top, (ast.FunctionDef, ast.AsyncFunctionDef)):
        return set()
    names = getattr(function, "__globals__", {})
    out: set[type] = set()
    stack: list[ast.AST] = list(top.body)
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            continue
        if isinstance(node, ast.Raise) and node.exc is not None:
            target = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
            error = names.get(target.id) if isinstance(target, ast.Name) else None
            if isinstance(error, type) and issubclass(error, SnakePinError):
                out.add(error)
        stack.extend(ast.iter_child_nodes(node))
    return out


def _documented_errors(doc: Any) -> set[type]:
    """Exception classes named in a parsed docstring's Raises section."""
    out: set[type] = set()
    for entry in doc["Raises"]:
        for word in f"{entry.name} {entry.type}".replace(",", " ").split():
            name = word.strip("`~:").rsplit(".", 1)[-1]
            found = getattr(exceptions, name, None) or getattr(builtins, name, None)
            if isinstance(found, type):
                out.add(found)
    return out


def _problems(qualname: str, obj: Any) -> list[str]:
    """The chosen errors of one object, as ``"qualname: CODE message"`` lines."""
    doc = get_doc_object(obj)
    report = validate(doc)
    lines = [f"{qualname}: {code} {message}" for code, message in report["errors"]
             if code in CHECKS]
    documented = _documented_errors(doc)
    for error in sorted({e for f in _bodies(obj) for e in _raised(f)}, key=str):
        if not any(issubclass(error, named) for named in documented):
            lines.append(f"{qualname}: RS01 raises {error.__name__} on purpose but its "
                         f"Raises section does not name it")
    return lines


def _module_problems(module: str) -> list[str]:
    return [line for qualname, obj in API[module].items() for line in _problems(qualname, obj)]


@pytest.mark.parametrize("module", list(API))
def test_public_docstrings_are_complete(module: str) -> None:
    """Every public callable defined in the module passes the chosen numpydoc checks."""
    if module in PENDING:
        left = len(_module_problems(module))
        pytest.skip(reason=f"{module} is PENDING (another helper's): {left} problem(s) left"
                    + ("; it now passes: remove it from PENDING" if not left else ""))
    problems = _module_problems(module)
    assert not problems, "\n".join(problems)


def test_pending_names_only_real_modules() -> None:
    """PENDING names modules that exist and define public callables (no stale entries)."""
    assert PENDING <= set(API), sorted(PENDING - set(API))


def test_api_walk_covers_the_package_exports() -> None:
    """The walk finds every callable ``snake_pin`` exports, and the methods of classes."""
    found = {name for objs in API.values() for name in objs}
    assert "snake_pin.model.Snake.inertia_matrix" in found
    assert "snake_pin.params.SnakeParams.per_link" in found
    assert "snake_pin._json.json_safe" in found  # a private module's re-exported function
    for name in snake_pin.__all__:
        obj = getattr(snake_pin, name)
        if isinstance(obj, ModuleType) or not callable(obj):
            continue
        assert f"{obj.__module__}.{obj.__qualname__}" in found, name


def _source_files() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def _definitions(tree: ast.AST, prefix: str) -> list[tuple[str, ast.AST]]:
    """(qualified name, node) of every function and class, nested ones included."""
    found: list[tuple[str, ast.AST]] = []
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            name = f"{prefix}.{node.name}"
            found.append((name, node))
            found += _definitions(node, name)
    return found


def _private_sections(path: Path) -> list[str]:
    """Private helpers of one file whose docstrings carry numpydoc sections."""
    module = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    module = module.removesuffix(".__init__")
    public = {name for objs in API.values() for name in objs}
    return [f"{name}: a private helper with numpydoc sections (say what and why in a line "
            f"or two)" for name, node in _definitions(ast.parse(path.read_text("utf-8")), module)
            if name not in public and not name.rsplit(".", 1)[-1].startswith("__")
            and SECTION.search(ast.get_docstring(node) or "")]


def test_private_helpers_have_no_numpydoc_sections() -> None:
    """Sections are for the public API; a private helper's docstring is a line or two."""
    problems = [line for path in _source_files()
                if path.relative_to(PACKAGE.parent).as_posix() not in SECTIONS_PENDING
                for line in _private_sections(path)]
    assert not problems, "\n".join(problems)


def test_sections_pending_names_files_with_problems() -> None:
    """SECTIONS_PENDING has no stale entry: each file exists and still has a problem."""
    stale = [name for name in sorted(SECTIONS_PENDING)
             if not (PACKAGE.parent / name).exists()
             or not _private_sections(PACKAGE.parent / name)]
    assert not stale, f"remove from SECTIONS_PENDING: {stale}"


def test_no_project_history_in_docstrings_or_comments() -> None:
    """No docstring or comment of the package names an issue number or a commit hash."""
    problems = []
    for path in _source_files():
        text = path.read_text("utf-8")
        tree = ast.parse(text)
        for name, node in [("<module>", tree), *_definitions(tree, "")]:
            for match in HISTORY.finditer(ast.get_docstring(node) or ""):
                problems.append(f"{path.name}:{name.lstrip('.')}: {match.group()!r}")
        for token in tokenize.generate_tokens(io.StringIO(text).readline):
            if token.type == tokenize.COMMENT:
                for match in HISTORY.finditer(token.string):
                    problems.append(f"{path.name}:{token.start[0]}: {match.group()!r}")
    assert not problems, "\n".join(problems)


def test_history_check_catches_issue_numbers_and_hashes() -> None:
    """The history pattern finds issue numbers and commit hashes, not colours or words."""
    for text in ("see issue 13", "issue #4", "fixes #12", "as in dc0b889", "3801e7f's"):
        assert HISTORY.search(text), text
    for text in ('color="#228b22"', "deadbeef", "1234567 runs", "the issue is"):
        assert not HISTORY.search(text), text


# ------------------------------------------------------------ the checks themselves
def _documented(q: float, *, scale: float = 1.0) -> float:
    """Scale a number.

    Parameters
    ----------
    q : float
        The number.
    scale : float, optional
        The factor.

    Returns
    -------
    float
        ``scale * q``.

    Raises
    ------
    ParameterError
        If ``q`` is negative.
    """
    if q < 0:
        raise ParameterError("negative")
    return scale * q


def _undocumented_parameter(q: float, dt: float) -> float:
    """Scale a number.

    Parameters
    ----------
    q : float
        The number.

    Returns
    -------
    float
        ``dt * q``.
    """
    return dt * q


def _undocumented_error(q: float) -> float:
    """Check a number.

    Parameters
    ----------
    q : float
        The number.

    Returns
    -------
    float
        ``q``.
    """
    if q < 0:
        raise ParameterError("negative")
    return q


def test_checks_pass_a_complete_docstring() -> None:
    """A docstring with every section the checks want gives no problem."""
    assert _problems("example", _documented) == []


def test_checks_catch_an_undocumented_parameter() -> None:
    """A parameter missing from the Parameters section is reported as PR01, naming it."""
    problems = _problems("example", _undocumented_parameter)
    assert any("PR01" in line and "dt" in line for line in problems), problems


def test_checks_catch_an_undocumented_error() -> None:
    """A snake_pin error raised on purpose but not in the Raises section is RS01."""
    problems = _problems("example", _undocumented_error)
    assert problems == ["example: RS01 raises ParameterError on purpose but its Raises "
                        "section does not name it"]
