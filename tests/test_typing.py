"""Typing and layers: mypy passes on every module, import-linter's contracts hold, and no
two modules of the package import each other (not even lazily, inside a function)."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MODULES = sorted(str(p.relative_to(ROOT)) for folder in ("snake_pin", "scripts")
                 for p in (ROOT / folder).rglob("*.py"))

#: Module files still being edited by other helpers: skipped (the reason says how many
#: mypy errors each has left) until they are handed over and fixed.
PENDING: frozenset[str] = frozenset()

#: Known breaks of the import-linter contracts, as ``"importer -> imported"``: none today.
KNOWN_VIOLATIONS: frozenset[str] = frozenset()

#: Known import cycles, as sorted ``(module, module)`` pairs of modules that import each
#: other (directly or through others); none today.
KNOWN_CYCLES: frozenset[tuple[str, str]] = frozenset()

_ERROR = re.compile(r"^(?P<path>[^:\s]+\.py):(?P<line>\d+):(?:\d+:)? error: (?P<text>.*)$")
_SUMMARY = re.compile(r"^(?:Success: no issues found|Found (?P<count>\d+) errors? in \d+ files?)")
_VIOLATION = re.compile(r"^(?P<importer>\S+) is not allowed to import (?P<imported>\S+):\s*$")
_CONTRACTS = re.compile(r"^Contracts: (?P<kept>\d+) kept, (?P<broken>\d+) broken\.")


def parse_mypy(output: str) -> dict[str, list[str]]:
    """Module file -> its mypy error lines; AssertionError if the summary disagrees."""
    errors: dict[str, list[str]] = defaultdict(list)
    summary = None
    for line in output.splitlines():
        match = _ERROR.match(line)
        if match:
            errors[match["path"]].append(line)
        elif _SUMMARY.match(line):
            summary = _SUMMARY.match(line)
    assert summary is not None, f"mypy printed no summary:\n{output[-3000:]}"
    expected = int(summary["count"] or 0)
    assert sum(map(len, errors.values())) == expected, "unparsed mypy error lines"
    return dict(errors)


def parse_lint_imports(output: str) -> set[str]:
    """Broken imports ``"importer -> imported"``, and ``"MODULE is in no layer"`` for a
    module an exhaustive layers contract does not place; AssertionError if the tool did
    not finish."""
    lines = output.replace("is not allowed to import \n", "is not allowed to import ")
    lines = lines.splitlines()
    counts = next((m for m in map(_CONTRACTS.match, lines) if m), None)
    assert counts is not None, f"lint-imports printed no summary:\n{output[-3000:]}"
    found = {f"{m['importer']} -> {m['imported']}" for m in map(_VIOLATION.match, lines) if m}
    listing = False
    for line in lines:
        if line.startswith("The following modules are not listed as layers"):
            listing = True
        elif listing and line.startswith("- "):
            found.add(f"{line[2:].strip()} is in no layer")
        elif listing and line.strip():
            listing = False
    assert int(counts["broken"]) == 0 or found, "a contract is broken in an unparsed way"
    return found


@pytest.fixture(scope="module")
def mypy_errors() -> dict[str, list[str]]:
    """mypy run once over ``snake_pin/`` and ``scripts/`` (pyproject.toml's configuration)."""
    done = subprocess.run([sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode in (0, 1), f"mypy failed to run:\n{done.stdout}{done.stderr}"
    return parse_mypy(done.stdout)


@pytest.mark.parametrize("module", MODULES)
def test_module_type_checks(module: str, mypy_errors: dict[str, list[str]]) -> None:
    """mypy reports no error in the module."""
    errors = mypy_errors.get(module, [])
    if module in PENDING:
        pytest.skip(reason=f"{module} is PENDING (another helper's): {len(errors)} mypy "
                    f"error(s) left" + ("; it now passes: remove it" if not errors else ""))
    assert not errors, "\n".join(errors)


def test_mypy_checks_only_known_files(mypy_errors: dict[str, list[str]]) -> None:
    """Every file mypy reports on is a module of the package (so a test above covers it)."""
    assert set(mypy_errors) <= set(MODULES), sorted(set(mypy_errors) - set(MODULES))


def test_pending_names_real_files() -> None:
    """PENDING lists existing module files only."""
    assert PENDING <= set(MODULES), sorted(PENDING - set(MODULES))


def test_layer_contracts_hold() -> None:
    """import-linter's contracts (pyproject.toml) hold, except the known violations."""
    done = subprocess.run(
        [sys.executable, "-c", "from importlinter.cli import lint_imports_command as c; c()",
         "--no-logo"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    broken = parse_lint_imports(done.stdout)
    assert broken <= KNOWN_VIOLATIONS, f"new layer violations: {sorted(broken - KNOWN_VIOLATIONS)}"
    assert done.returncode == (1 if broken else 0), done.stdout[-3000:]


# ---------------------------------------------------------------- import cycles
def import_graph(folder: Path, package: str) -> dict[str, set[str]]:
    """Module -> the package's modules it imports, from every ``import`` statement in its
    source (module level, inside functions and under ``TYPE_CHECKING`` alike), relative
    imports resolved; a name that is not a module counts as its nearest module."""
    files = {}
    for path in folder.rglob("*.py"):
        parts = [package, *path.relative_to(folder).with_suffix("").parts]
        is_package = parts[-1] == "__init__"
        files[".".join(parts[:-1] if is_package else parts)] = (path, is_package)

    def nearest(name: str) -> str:
        while name and name not in files:
            name = name.rpartition(".")[0]
        return name

    graph: dict[str, set[str]] = {}
    for module, (path, is_package) in files.items():
        here = module.split(".") if is_package else module.split(".")[:-1]
        found: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                found.update(nearest(alias.name) for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    base = ".".join(here[:len(here) - node.level + 1] + ([base] if base else []))
                found.update(nearest(f"{base}.{alias.name}") or nearest(base)
                             for alias in node.names)
        graph[module] = {name for name in found
                         if name and name != module and name.split(".")[0] == package}
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The groups of modules that reach each other through imports (strongly connected
    components of two modules or more, Tarjan's algorithm), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    groups: list[list[str]] = []

    def visit(module: str) -> None:
        index[module] = low[module] = len(index)
        stack.append(module)
        for other in sorted(graph.get(module, ())):
            if other not in index:
                visit(other)
                low[module] = min(low[module], low[other])
            elif other in stack:
                low[module] = min(low[module], index[other])
        if low[module] == index[module]:
            group = []
            while True:
                member = stack.pop()
                group.append(member)
                if member == module:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    return sorted(groups)


def cycle_pairs(graph: dict[str, set[str]]) -> set[tuple[str, str]]:
    """The imports that close a cycle: sorted ``(module, module)`` pairs of one group of
    :func:`import_cycles` where one imports the other."""
    return {(min(a, b), max(a, b)) for group in import_cycles(graph) for a in group
            for b in graph[a] if b in group}


def test_no_import_cycles() -> None:
    """No module of snake_pin imports, even lazily, a module that imports it back."""
    graph = import_graph(ROOT / "snake_pin", "snake_pin")
    assert len(graph) > 50 and graph["snake_pin.sim"] >= {"snake_pin.model",
                                                          "snake_pin.trajectory"}
    unexpected = cycle_pairs(graph) - KNOWN_CYCLES
    assert not unexpected, (f"modules importing each other: {sorted(unexpected)} "
                            f"(cycles: {import_cycles(graph)})")


def test_cycle_check_sees_lazy_and_relative_imports(tmp_path: Path) -> None:
    """The check finds a cycle closed by a function-level relative import, and a longer
    one through a package's ``__init__``; one-way imports are no cycle."""
    package = tmp_path / "pkg"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text("from .sub import c\n")
    (package / "a.py").write_text("from . import b\nimport pkg.d\n")
    (package / "b.py").write_text("def f():\n    from .a import x\n")
    (package / "d.py").write_text("import os\n")
    (package / "sub" / "__init__.py").write_text("")
    (package / "sub" / "c.py").write_text("import os\nfrom .. import a\n")
    graph = import_graph(package, "pkg")
    assert graph["pkg.b"] == {"pkg.a"} and graph["pkg.a"] == {"pkg.b", "pkg.d"}
    assert graph["pkg.sub.c"] == {"pkg.a"}
    assert import_cycles(graph) == [["pkg.a", "pkg.b"]]
    (package / "a.py").write_text("from . import d\n")
    (package / "b.py").write_text("")
    (package / "d.py").write_text("from .sub import y\n")  # y: a name of pkg.sub
    (package / "sub" / "__init__.py").write_text("from .c import y\n")
    graph = import_graph(package, "pkg")
    assert graph["pkg.d"] == {"pkg.sub"}
    assert import_cycles(graph) == [["pkg.a", "pkg.d", "pkg.sub", "pkg.sub.c"]]
    assert cycle_pairs(graph) == {("pkg.a", "pkg.d"), ("pkg.d", "pkg.sub"),
                                  ("pkg.sub", "pkg.sub.c"), ("pkg.a", "pkg.sub.c")}


# ----------------------------------------------------------------- the parsers
_MYPY_SAMPLE = """\
snake_pin/params.py:158: error: Unsupported operand types for <= ("int" and "Integral")  [operator]
snake_pin/params.py:160: note: See https://mypy.rtfd.io
snake_pin/sim.py:12:5: error: Name "x" is not defined  [name-defined]
snake_pin/sim.py:14: error: Missing return statement  [return]
Found 3 errors in 2 files (checked 60 source files)
"""

_LINT_SAMPLE = """\
Layers: a lower layer never imports a higher one BROKEN
The closed form stays independent of Pinocchio and of the model KEPT

Contracts: 1 kept, 1 broken.

Layers: a lower layer never imports a higher one
------------------------------------------------

snake_pin.sim is not allowed to import snake_pin.viz:

- snake_pin.sim -> snake_pin.viz.plots (l.251)
"""


def test_mypy_parser_groups_errors_by_file() -> None:
    """Errors (with or without a column) go to their file; notes are not errors."""
    errors = parse_mypy(_MYPY_SAMPLE)
    assert {path: len(lines) for path, lines in errors.items()} == {
        "snake_pin/params.py": 1, "snake_pin/sim.py": 2}
    assert parse_mypy("Success: no issues found in 60 source files\n") == {}
    with pytest.raises(AssertionError):
        parse_mypy(_MYPY_SAMPLE.replace("Found 3 errors", "Found 4 errors"))


def test_lint_parser_names_the_broken_import() -> None:
    """A broken layer contract gives its importer -> imported pair; a clean run none."""
    assert parse_lint_imports(_LINT_SAMPLE) == {"snake_pin.sim -> snake_pin.viz"}
    wrapped = _LINT_SAMPLE.replace("import snake_pin.viz:", "import \nsnake_pin.viz:")
    assert parse_lint_imports(wrapped) == {"snake_pin.sim -> snake_pin.viz"}
    assert parse_lint_imports("Contracts: 2 kept, 0 broken.\n") == set()
    with pytest.raises(AssertionError):
        parse_lint_imports("Contracts: 1 kept, 1 broken.\n")


def test_lint_parser_names_a_module_in_no_layer() -> None:
    """A module that an exhaustive layers contract does not place is reported by name."""
    output = ("Contracts: 0 kept, 1 broken.\n\nThe following modules are not listed as "
              "layers:\n\n- snake_pin.newmod\n\n(Since this contract is marked as "
              "'exhaustive', every child of every container \nmust be declared as a layer.)\n")
    assert parse_lint_imports(output) == {"snake_pin.newmod is in no layer"}
