"""Documentation: the Sphinx site builds with warnings as errors, its gallery runs, and
the generated pages (API, CLI, equations) cover what the code exports."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import snake_pin
from snake_pin.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
EXAMPLES = sorted(p for p in (ROOT / "examples").glob("*.py"))
sys.path.insert(0, str(DOCS / "_ext"))

from snake_pin_docs import _EQ_REFERENCE, _canonical, _numbers, _public, escape_text  # noqa: E402

#: The documented build command (README, docs/installation.rst) without its folders.
BUILD = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-b", "html"]
#: What the site reads besides docs/ (the gallery, and the pages' literal includes).
SOURCES = ("examples", "CITATION.cff", "CHANGELOG.md")


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The site built once by the documented command (about 30-60 s: the gallery runs).

    It builds a copy of the sources: a build writes its generated pages (API stubs, the
    gallery's pages) into the source folder, and another build of the same checkout at
    the same time (a second test run, a manual build) would clear them under it.
    """
    base = tmp_path_factory.mktemp("docs")
    shutil.copytree(DOCS, base / "src" / "docs", ignore=shutil.ignore_patterns(
        "_build", "generated", "auto_examples", "sg_execution_times.rst", "__pycache__"))
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, base / "src" / name,
                            ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(ROOT / name, base / "src" / name)
    out = base / "html"
    env = {**os.environ, "MPLBACKEND": "Agg"}
    done = subprocess.run([*BUILD, str(base / "src" / "docs"), str(out)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, f"docs build failed:\n{done.stderr[-6000:]}"
    return out


def _text(path: Path) -> str:
    return path.read_text(encoding="utf-8")


def _inventory(site: Path) -> set[str]:
    from sphinx.util.inventory import InventoryFile

    with open(site / "objects.inv", "rb") as stream:
        inventory = InventoryFile.load(stream, "", os.path.join)
    return {name for objects in inventory.values() for name in objects}


def test_build_passes_with_every_example_run(site: Path) -> None:
    """Every example ran (its page has output and a figure) and is offered as a notebook."""
    assert EXAMPLES, "the gallery has no examples"
    downloads = {p.name for p in (site / "_downloads").rglob("*")}
    for script in EXAMPLES:
        page = site / "auto_examples" / f"{script.stem}.html"
        assert page.exists(), script.name
        html = _text(page)
        assert f"sphx_glr_{script.stem}_001.png" in html, f"{script.name} drew no figure"
        assert f"{script.stem}.ipynb" in downloads, f"{script.name} has no notebook"


def test_every_public_name_is_in_the_api_reference(site: Path) -> None:
    """Each name of snake_pin.__all__ is listed on the package page and documented."""
    documented = _inventory(site)
    page = _text(site / "api" / "generated" / "snake_pin.html")
    for name in snake_pin.__all__:
        role, target = _canonical("snake_pin", name, _public(snake_pin, name))
        assert target in documented, f"{name}: {target} is not documented"
        anchor = f"module-{target}" if role == "mod" else target
        assert re.search(rf'href="[^"]*#{re.escape(anchor)}"', page), \
            f"{name} is not linked from the package page"


def test_every_public_module_has_a_page(site: Path) -> None:
    """Each public submodule of snake_pin gets its own API page."""
    from snake_pin_docs import public_modules

    for module in public_modules():
        assert (site / "api" / "generated" / f"{module.__name__}.html").exists(), \
            module.__name__


def test_cli_page_is_the_parser(site: Path) -> None:
    """The CLI page shows every subcommand and every option string of build_parser()."""
    import argparse

    html = _text(site / "cli.html")
    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    for name, command in sub.choices.items():
        assert f'id="cli-snake-pin-{name}"' in html, name
        for action in command._actions:
            for option in action.option_strings:
                if option not in ("-h", "--help"):
                    anchor = f"cmdoption-snake-pin-{name}-{option.lstrip('-')}"
                    assert f'id="{anchor}"' in html, f"snake-pin {name} {option}"


def test_equation_page_maps_eq_19_to_both_implementations(site: Path) -> None:
    """The row of eq. (19) links the closed form and the Pinocchio model's H."""
    html = _text(site / "equations.html")
    row = html.split("<p>(19)</p>", 1)[1].split("</tr>", 1)[0]
    assert "snake_pin.paper.inertia_matrix" in row
    assert "snake_pin.model.Snake.inertia_matrix" in row


def test_errata_page_keeps_every_erratum(site: Path) -> None:
    """The errata page holds the six numbered errata and both further findings."""
    html = _text(site / "errata.html")
    for marker in ("J = 2.2e-4", "H21", "c_y = 25", "2πf_c s / (s + 2πf_c)",
                   "weighted", "2π T_s / n", "n ≥ 6", "two-parameter"):
        assert marker in html, marker


@pytest.mark.parametrize(("text", "numbers"), [
    ("eq. (19)", [19]),
    ("Eq. 43", [43]),
    ("eqs. (10)-(13)", [10, 11, 12, 13]),
    ("eqs. 30, 31, 42", [30, 31, 42]),
    ("eqs. 3-4 and 17", [3, 4, 17]),
    ("eqs. (70)-(78)", list(range(70, 79))),
])
def test_equation_references_are_read(text: str, numbers: list[int]) -> None:
    """Single numbers, ranges and lists of equation numbers are all read."""
    match = _EQ_REFERENCE.search(f"as in {text}, here")
    assert match is not None and _numbers(match) == numbers


def test_plain_text_escapes_its_markup_only() -> None:
    """|x| and a lone * in CLI help are escaped; inline literals, roles and emphasis kept."""
    lines = ["|phi_i| <= pi/2 and q''* here", "``|x|`` and :func:`f` and *this*",
             "* a bullet", "- b|c"]
    assert [escape_text(line) for line in lines] == [
        r"\|phi_i\| <= pi/2 and q''\* here", "``|x|`` and :func:`f` and *this*",
        "* a bullet", r"- b\|c"]
