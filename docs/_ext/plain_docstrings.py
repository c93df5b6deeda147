"""Show docstrings that are not valid reStructuredText as they are written, without warnings.

The package's docstrings are read in a terminal (``help()``) as often as on this site, and
many write math in plain text (``|S - D|``, ``|alpha|``), which reST reads as substitution
references, or list attributes as indented ``name : text`` paragraphs, which reST reads as
broken definition lists. Two handlers on ``autodoc-process-docstring``:

- before numpydoc: ``|`` inside a line is escaped (``\\|``) outside inline literals and
  doctest lines, so plain-text absolute values read as written; a line that starts with
  ``| `` (a reST table row or line block) is left alone;
- after numpydoc: the result is parsed with docutils; if it still gives a formatting warning
  (unexpected indentation, unterminated markup, ...), the original docstring is shown as a
  literal block (of class ``plain-docstring``, which docs/_static/rotoruq.css wraps at
  the window's width), so the page says exactly what ``help()`` says and the build stays
  clean. ``plain_docstrings`` (the module global) records which objects were shown so, and the
  build's last lines name them.

The fallback is a safety net, not the way to write a docstring: its cause is a docstring that
lists attributes or options as ``name : text`` lines outside a numpydoc section.
``tests/test_docstrings.py`` parses every public docstring as numpydoc renders it and fails on
such problems, so the net only catches names that test allows.

Sphinx's own roles and directives (``:class:``, ``.. autosummary::``) are unknown to bare
docutils; messages about them are not formatting problems and are ignored.
"""

from __future__ import annotations

import inspect
import re

from docutils.core import publish_doctree
from docutils.utils import SystemMessage

#: objects (full names) whose docstring was shown as a literal block
plain_docstrings: list[str] = []

_LITERAL = re.compile(r"(``.*?``)")
_IGNORED = ("Unknown interpreted text role", "Unknown directive type", "No role entry",
            "No directive entry", "Trying", "Duplicate implicit target", "Duplicate explicit",
            "Unknown target name", "Hyperlink target")


def _escape_bars(line: str) -> str:
    stripped = line.lstrip()
    if not stripped or stripped == "|" or stripped.startswith(("| ", ">>>", "...")):
        return line
    parts = _LITERAL.split(line)
    return "".join(p if p.startswith("``") else re.sub(r"(?<!\\)\|", r"\\|", p) for p in parts)


def escape_bars(app, what, name, obj, options, lines):  # noqa: ARG001 (Sphinx's signature)
    lines[:] = [_escape_bars(line) for line in lines]


def _problems(text: str, env) -> list[str]:
    # Sphinx's roles and directives are registered with docutils during the build and read
    # the environment from the settings
    settings = {"env": env, "report_level": 5, "halt_level": 5, "warning_stream": False,
                "file_insertion_enabled": False, "raw_enabled": False}
    try:
        tree = publish_doctree(text, settings_overrides=settings)
    except SystemMessage as exc:  # pragma: no cover (halt_level 5 does not raise)
        return [str(exc)]
    found = []
    for node in tree.findall():
        if node.tagname == "system_message" and node["level"] >= 2:
            msg = node.astext()
            if not any(k in msg for k in _IGNORED):
                found.append(msg)
    return found


def literal_if_invalid(app, what, name, obj, options, lines):  # noqa: ARG001
    if not lines or not _problems("\n".join(lines), app.env):
        return
    original = (inspect.getdoc(obj) or "").splitlines()
    plain_docstrings.append(name)
    # the summary paragraph stays text when it is valid on its own: autosummary's tables show
    # a docstring's first paragraph, and a page's first lines read better as prose
    end = original.index("") if "" in original else len(original)
    summary, rest = original[:end], original[end:]
    if _problems("\n".join(summary), app.env):
        summary, rest = ["Shown as written:"], original
    while rest and not rest[0]:
        rest = rest[1:]
    lines[:] = summary + [""]
    if rest:
        lines += [".. rst-class:: plain-docstring", "", "::", ""]
        lines += ["    " + ln if ln else "" for ln in rest] + [""]


def report(app, exception):
    if exception is None and plain_docstrings:
        from sphinx.util import logging

        logging.getLogger(__name__).info(
            "%d docstrings shown as written (not valid reST): %s", len(plain_docstrings),
            ", ".join(sorted(set(plain_docstrings))))


def setup(app):
    app.connect("build-finished", report)
    app.connect("autodoc-process-docstring", escape_bars, priority=100)
    app.connect("autodoc-process-docstring", literal_if_invalid, priority=900)
    return {"parallel_read_safe": True}
