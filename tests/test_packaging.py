"""Packaging: subpackages listed, robots shipped as package data, nothing points outside."""

from __future__ import annotations

import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_every_subpackage_is_listed() -> None:
    """Each folder of snake_pin with an __init__.py is in [tool.setuptools] packages."""
    listed = set(_pyproject()["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts)
             for p in (ROOT / "snake_pin").rglob("__init__.py")}
    assert found <= listed, f"add to pyproject.toml packages: {sorted(found - listed)}"


def test_nothing_points_outside_the_repository() -> None:
    """README, docs, package and tests never refer to files outside the repository."""
    docs = [p for p in (ROOT / "docs").rglob("*") if p.suffix in (".md", ".rst", ".py")
            and "_build" not in p.parts and "generated" not in p.parts
            and "auto_examples" not in p.parts]
    texts = [ROOT / "README.md", *docs, *(ROOT / "examples").rglob("*.py"),
             *(ROOT / "snake_pin").rglob("*.py"), *(ROOT / "tests").rglob("*.py")]
    bad = [str(p.relative_to(ROOT)) for p in texts
           if p.name != "test_packaging.py"
           and any(marker in p.read_text() for marker in ("../shared", "DESIGN.md", "DESIGN §"))]
    assert not bad


def test_wheel_carries_robots_types_and_license(tmp_path: Path) -> None:
    """A built wheel holds the shipped URDFs, the example robot files, py.typed and LICENSE."""
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w",
                    str(tmp_path), str(ROOT)], check=True, capture_output=True, timeout=300)
    (wheel,) = tmp_path.glob("snake_pin-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    shipped_urdf = {p.name for p in (ROOT / "urdf").glob("*.urdf")}
    shipped_toml = {p.name for p in (ROOT / "examples" / "robots").glob("*.toml")}
    assert {Path(n).name for n in names if n.startswith("snake_pin/robots/urdf/")} \
        == shipped_urdf
    assert {Path(n).name for n in names if n.startswith("snake_pin/robots/examples/")} \
        == shipped_toml
    assert "snake_pin/py.typed" in names
    assert any(n.endswith(".dist-info/LICENSE") or "/licenses/LICENSE" in n for n in names)
