"""The self-contained HTML report of ``snake-pin reproduce`` (sections of text, tables and
embedded figures; an interrupted run says so at the top) and its ``summary.json``
(written with :func:`snake_pin._json.json_text`, also importable from here).
"""

from __future__ import annotations

import base64
import html
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ._io import atomic_write_bytes
from ._json import json_safe, json_text

__all__ = ["Report", "json_safe", "json_text"]


@dataclass
class Section:
    """One report section: its anchor and summary ``key``, its ``title``, plain-text paragraphs,
    (PNG, caption) figures, (header, rows) tables, (href, label) links and its numbers."""

    key: str
    title: str
    paragraphs: list[str] = field(default_factory=list)
    figures: list[tuple[Path, str]] = field(default_factory=list)
    tables: list[tuple[list[str], list[list[Any]]]] = field(default_factory=list)
    links: list[tuple[str, str]] = field(default_factory=list)
    numbers: dict[str, Any] = field(default_factory=dict)

    def text(self, paragraph: str) -> Section:
        """Add a paragraph of plain text (escaped when written); return the section."""
        self.paragraphs.append(paragraph)
        return self

    def figure(self, path: str | os.PathLike[str], caption: str) -> Section:
        """Add a PNG figure (read when the report is written) with a caption."""
        self.figures.append((Path(path), caption))
        return self

    def table(self, header: list[str], rows: list[list[Any]]) -> Section:
        """Add a table (floats shown with 4 significant digits, None as "-")."""
        self.tables.append((header, rows))
        return self

    def link(self, href: str, label: str) -> Section:
        """Add a link, ``href`` relative to the report folder."""
        self.links.append((href, label))
        return self


@dataclass
class Report:
    """Sections in order, written as one HTML page and one JSON summary.

    Parameters
    ----------
    title
        The page's title.
    sections
        The sections, in order.
    status
        ``"complete"``, or ``"interrupted"`` for the report of a run stopped early.
    note
        One line about the run (for an interrupted one: when, and during which stage).
    """

    title: str
    sections: list[Section] = field(default_factory=list)
    status: str = "complete"
    note: str = ""

    def section(self, key: str, title: str) -> Section:
        """Append a new section.

        Parameters
        ----------
        key
            Its anchor and summary key.
        title
            Its heading.

        Returns
        -------
        Section
            The new (empty) section.
        """
        sec = Section(key, title)
        self.sections.append(sec)
        return sec

    def summary(self) -> dict[str, Any]:
        """The report's numbers.

        Returns
        -------
        dict
            Every section's numbers under its key; ``"run"``: status, note, section keys.
        """
        return {"run": {"status": self.status, "note": self.note,
                        "sections": [sec.key for sec in self.sections]},
                **{sec.key: sec.numbers for sec in self.sections}}

    def write(self, folder: str | os.PathLike[str]) -> Path:
        """Write ``index.html`` (figures embedded) and ``summary.json`` into ``folder``.

        Parameters
        ----------
        folder
            An existing folder; each file is written whole or not at all.

        Returns
        -------
        pathlib.Path
            The path of ``index.html``.
        """
        folder = Path(folder)
        parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{_e(self.title)}"
                 "</title><style>body{font-family:sans-serif;max-width:1100px;margin:auto;"
                 "padding:1em;line-height:1.45}img{max-width:100%;border:1px solid #ddd}"
                 "table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #bbb;"
                 "padding:3px 8px;text-align:right}figure{margin:1em 0}"
                 "figcaption{color:#444;font-size:.9em}</style></head><body>",
                 f"<h1>{_e(self.title)}</h1>"]
        if self.status != "complete":
            parts.append(f"<p id='status' style='background:#fde2e1;padding:.5em'><b>"
                         f"{_e(self.status.capitalize())} run:</b> {_e(self.note)}</p>")
        elif self.note:
            parts.append(f"<p id='status'>{_e(self.note)}</p>")
        parts.append("<ul>")
        parts += [f"<li><a href='#{_e(s.key)}'>{_e(s.title)}</a></li>" for s in self.sections]
        parts.append("</ul>")
        for sec in self.sections:
            parts.append(f"<h2 id='{_e(sec.key)}'>{_e(sec.title)}</h2>")
            parts += [f"<p>{_e(p)}</p>" for p in sec.paragraphs]
            for header, rows in sec.tables:
                parts.append("<table><tr>" + "".join(f"<th>{_e(h)}</th>" for h in header)
                             + "</tr>")
                parts += ["<tr>" + "".join(f"<td>{_e(_fmt(c))}</td>" for c in row) + "</tr>"
                          for row in rows]
                parts.append("</table>")
            for path, caption in sec.figures:
                data = base64.b64encode(path.read_bytes()).decode()
                parts.append(f"<figure><img alt='{_e(caption)}' src='data:image/png;base64,"
                             f"{data}'><figcaption>{_e(caption)} ({_e(path.name)})"
                             "</figcaption></figure>")
            if sec.links:
                parts.append("<ul>" + "".join(f"<li><a href='{_e(h)}'>{_e(t)}</a></li>"
                                              for h, t in sec.links) + "</ul>")
        parts.append("</body></html>\n")
        atomic_write_bytes(folder / "summary.json",
                           (json_text(self.summary(), indent=2) + "\n").encode())
        index = folder / "index.html"
        atomic_write_bytes(index, "".join(parts).encode())
        return index


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _fmt(value: object) -> str:
    return "-" if value is None else f"{value:.4g}" if isinstance(value, float) else str(value)
