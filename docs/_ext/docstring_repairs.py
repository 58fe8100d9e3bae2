"""Local Sphinx extension: read the package's plain-text mathematics as text, not markup.

snake_pin's docstrings write formulas in plain text: ``|phi_i| <= pi/2``, ``q''*``,
indented formula blocks after a sentence. reStructuredText reads ``|x|`` as a
substitution, a lone ``*`` as the start of emphasis and an indented block as a quotation
(where a deeper line is an error). Until every docstring is written in reStructuredText
(issue 16, item 3), this extension repairs the docstrings as autodoc reads them, so the
build can keep warnings as errors:

* before numpydoc: an indented block that follows a paragraph (not after ``::`` or a
  directive) becomes a literal block; so does a simple table whose text crosses its
  column borders (docutils would call it malformed);
* after numpydoc: ``|`` and any ``*`` that does not close on the same line are escaped
  outside inline literals, roles, literal blocks and directives.

Each repair is logged at the "verbose" level with the object's name (``-v`` shows them), so
the docstrings can be fixed at the source; ``snake_pin_docstring_repairs = False`` in
``conf.py`` turns the repairs off.
"""

from __future__ import annotations

import re
from typing import Any

from sphinx.application import Sphinx
from sphinx.util import logging

__all__ = ["escape_markup", "literal_blocks", "setup"]

logger = logging.getLogger(__name__)

_BULLET = re.compile(r"^(\s*)([-*+•]|\d+[.)]|#\.|\(\d+\)|[a-z][.)])\s+")
_DIRECTIVE = re.compile(r"^\s*\.\.\s")
_TABLE_BORDER = re.compile(r"^(\s*)=+(\s+=+)+\s*$")
_SECTION_UNDERLINE = re.compile(r"^\s*([-=~^\"'`#*+])\1{2,}\s*$")
#: Inline constructs left alone: backslash escapes, inline literals, roles with their
#: text, interpreted text, strong and emphasis that close on the line, hyperlinks.
_PROTECTED = re.compile(
    r"\\."
    r"|``.+?``"
    r"|(?::[\w:+.-]+:)?`[^`]+`(?::[\w:+.-]+:)?_{0,2}"
    r"|(?<![\w*\\])\*\*(?=\S)(?:\\.|[^*\\])+?(?<=[^\s\\])\*\*(?![\w*])"
    r"|(?<![\w*\\])\*(?=[^\s*])(?:\\.|[^*\\])+?(?<=[^\s\\])\*(?![\w*])"
)


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def _content_indent(line: str) -> int:
    """Where the text of ``line`` starts (after a list bullet, if any)."""
    bullet = _BULLET.match(line)
    return bullet.end() if bullet else _indent(line)


def _table_end(lines: list[str], start: int) -> int:
    """Index after the simple table whose first border is ``lines[start]``."""
    borders, i = 0, start
    while i < len(lines) and lines[i].strip():
        if _TABLE_BORDER.match(lines[i]):
            borders += 1
        i += 1
        if borders == 3:
            break
    return i


def _table_is_malformed(lines: list[str]) -> bool:
    border = lines[0]
    gaps = [m.span() for m in re.finditer(r"(?<==)\s+(?==)", border)]
    for line in lines[1:]:
        if _TABLE_BORDER.match(line) or not line.strip():
            continue
        for low, high in gaps:
            if line[low:high].strip():
                return True
    return False


def literal_blocks(lines: list[str]) -> list[str]:
    """Indented blocks after a paragraph, and malformed simple tables, as literal blocks."""
    out: list[str] = []
    previous = ""          # last non-blank line written
    in_literal = -1        # indent of the line that opened a literal block or directive
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line.strip():
            out.append(line)
            i += 1
            continue
        indent = _indent(line)
        if in_literal >= 0 and indent > in_literal:
            out.append(line)
            i += 1
            continue
        in_literal = -1
        if _TABLE_BORDER.match(line):
            end = _table_end(lines, i)
            table = lines[i:end]
            if _table_is_malformed(table):
                out += ["::", ""] if out and out[-1].strip() == "" else ["", "::", ""]
                out += ["    " + row for row in table]
                previous = "    " + table[-1]
                i = end
                continue
        if previous and (previous.rstrip().endswith("::") or _DIRECTIVE.match(previous)):
            in_literal = _indent(previous)
            previous = line
            out.append(line)
            i += 1
            continue
        blank_before = i > 0 and not lines[i - 1].strip()
        if (previous and blank_before and indent > _content_indent(previous)
                and not _DIRECTIVE.match(line) and not _SECTION_UNDERLINE.match(previous)):
            out += ["::", ""]
            in_literal = _content_indent(previous)
            out.append(line)
            previous = line
            i += 1
            continue
        if _DIRECTIVE.match(line) or line.rstrip().endswith("::"):
            in_literal = indent
        out.append(line)
        previous = line
        i += 1
    return out


def _escape_text(text: str) -> str:
    bullet = re.match(r"^\s*[*+-]\s+", text)
    if bullet:
        return bullet.group(0) + _escape_text(text[bullet.end():])
    parts, last = [], 0
    for match in _PROTECTED.finditer(text):
        parts.append(re.sub(r"([*|])", r"\\\1", text[last:match.start()]))
        parts.append(match.group(0))
        last = match.end()
    parts.append(re.sub(r"([*|])", r"\\\1", text[last:]))
    return "".join(parts)


def escape_markup(lines: list[str]) -> list[str]:
    """``|`` and unclosed ``*`` escaped outside literals, roles, directives, literal blocks."""
    out: list[str] = []
    literal_indent = -1
    previous = ""
    for line in lines:
        if not line.strip():
            out.append(line)
            continue
        indent = _indent(line)
        if literal_indent >= 0 and indent > literal_indent:
            out.append(line)
            continue
        literal_indent = -1
        stripped = line.strip()
        if _DIRECTIVE.match(line) or stripped.endswith("::"):
            literal_indent = indent
            out.append(line if _DIRECTIVE.match(line) else _escape_text(line))
        elif stripped == "|" or stripped.startswith(("| ", "+-")):
            out.append(line)  # line blocks and grid tables
        elif stripped.startswith(":") and not previous.strip():
            out.append(_escape_field(line))
        else:
            out.append(_escape_text(line))
        previous = line
    return out


def _escape_field(line: str) -> str:
    """A field-list line (``:Parameters:``): escape the body only."""
    match = re.match(r"^(\s*:[^:]+:)(.*)$", line)
    return match.group(1) + _escape_text(match.group(2)) if match else _escape_text(line)


def _repair(before: bool) -> Any:
    def handler(app: Sphinx, what: str, name: str, obj: object, options: object,
                lines: list[str]) -> None:
        if not app.config.snake_pin_docstring_repairs:
            return
        repaired = literal_blocks(lines) if before else escape_markup(lines)
        if repaired != lines:
            logger.verbose("docstring repaired (%s): %s",
                        "literal blocks" if before else "escaped | and *", name)
            lines[:] = repaired
    return handler


def setup(app: Sphinx) -> dict[str, Any]:
    """Connect the repairs around numpydoc's own docstring processing (priority 500)."""
    app.add_config_value("snake_pin_docstring_repairs", True, "env", types=(bool,))
    app.connect("autodoc-process-docstring", _repair(before=True), priority=400)
    app.connect("autodoc-process-docstring", _repair(before=False), priority=600)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
