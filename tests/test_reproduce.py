"""The main job end to end: `snake-pin reproduce --quick` writes every section."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

from snake_pin.cli import main

SECTIONS = ("robot", "manipulability", "singular", "integrability", "pfl", "tracking", "engine")


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("report")
    assert main(["reproduce", "--quick", "-o", str(folder)]) == 0
    return folder


def test_every_section_is_in_the_page_and_summary(report: Path) -> None:
    """index.html has a section per stage with embedded figures; summary.json has their numbers."""
    html = (report / "index.html").read_text()
    summary = json.loads((report / "summary.json").read_text())
    for key in SECTIONS:
        assert f"id='{key}'" in html and key in summary
    assert html.count("data:image/png;base64,") >= 25


def test_linked_pages_exist(report: Path) -> None:
    """Every link of the page (the meshcat animations) points to a file that was written."""
    html = (report / "index.html").read_text()
    links = re.findall(r"<a href='([^'#]+)'>", html)
    assert links and all((report / link).is_file() for link in links)


def test_key_results_are_reported(report: Path) -> None:
    """The summary carries the headline numbers of each experiment."""
    summary = json.loads((report / "summary.json").read_text())
    assert summary["singular"]["singular"]["non_straight_singular_exists"] is True
    assert summary["pfl"]["isotropic"]["g_drift_max"] < 1e-8
    assert summary["tracking"]["tracking"]["R_min"] > 0
    assert summary["integrability"]["involutivity"][0][3] == "involutive"
    assert summary["engine"]["friction"]["c_y"] > summary["engine"]["friction"]["c_x"]


def test_report_is_complete_strict_json_and_in_place(report: Path) -> None:
    """The run is marked complete, summary.json is RFC 8259 (no NaN/Infinity), every file
    has the umask's mode and no staging folder is left in the output folder."""
    def refuse(constant: str) -> None:
        raise AssertionError(f"{constant} in summary.json")

    summary = json.loads((report / "summary.json").read_text(), parse_constant=refuse)
    assert summary["run"]["status"] == "complete"
    assert summary["run"]["sections"][:len(SECTIONS)] == list(SECTIONS)
    assert not [p for p in report.iterdir() if p.name.startswith(".")]
    umask = os.umask(0)
    os.umask(umask)
    assert {p.stat().st_mode & 0o777 for p in report.iterdir()} == {0o666 & ~umask}
