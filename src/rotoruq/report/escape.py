"""Study-supplied strings made safe for a page or a terminal.

A study file, a results folder or a colleague's deck supplies names, labels, descriptions and
titles. The report writes every one of them through :func:`text` (element text and quoted
attribute values alike), builds ids and file names with :func:`slug`, and ``rotoruq show``
prints them through :func:`terminal`. Control characters (C0, DEL, C1, the bidirectional
overrides and line separators) are shown as ``\\xNN``/``\\uNNNN`` escapes: they cannot
rewrite a terminal, reorder a line or reach the HTML parser.

Examples
--------
>>> text("<img src=x onerror='alert(1)'>")
'&lt;img src=x onerror=&#x27;alert(1)&#x27;&gt;'
>>> terminal("name\\x1b]0;owned\\x07")
'name\\\\x1b]0;owned\\\\x07'
>>> slug("lin"), slug("a b/..")
('lin', 'a-b-9e4a049f')
"""

from __future__ import annotations

import hashlib
import html
import re

from ..safety import terminal_text

__all__ = ["text", "terminal", "slug", "visible", "script_json"]

_SAFE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*\Z")

#: ``s`` for a terminal line: :func:`rotoruq.safety.terminal_text` (every control character,
#: newlines included, escaped).
terminal = terminal_text


def visible(s: object, keep: str = "") -> str:
    """``s`` as a string with every control character written as an escape (``\\x1b``,
    ``\\u202e``; :func:`rotoruq.safety.terminal_text`), except tabs and newlines when
    ``keep`` is ``"\\t\\n"``."""
    if keep not in ("", "\t\n", "\n\t"):
        raise ValueError(f"keep: '' or tab and newline, not {keep!r}")
    return terminal_text(s, lines=bool(keep))


def text(s: object) -> str:
    """``s`` for HTML element text or a quoted attribute value: control characters made
    visible, ``& < > " '`` escaped. Tabs and newlines stay (they are whitespace in HTML)."""
    return html.escape(visible(s, keep="\t\n"), quote=True)


def slug(s: object) -> str:
    """A name safe as an HTML id and a file name component: ``s`` itself when it is made of
    letters, digits, ``_ . -`` (not starting with ``.`` or ``-``), else its safe characters
    joined by ``-`` and 8 hex digits of its SHA-256, so that two names never share a slug."""
    s = str(s)
    if _SAFE_NAME.match(s):
        return s
    base = re.sub(r"[^A-Za-z0-9_]+", "-", s).strip("-")[:40]
    digest = hashlib.sha256(s.encode("utf-8", "surrogatepass")).hexdigest()[:8]
    return f"{base}-{digest}" if base else f"x-{digest}"


def script_json(data: object) -> str:
    """JSON for a ``<script type="application/json">`` block: ``< > &`` written as
    ``\\u003c`` etc., so no string can close the block or open a comment."""
    import json

    return (json.dumps(data).replace("<", "\\u003c").replace(">", "\\u003e")
            .replace("&", "\\u0026"))
