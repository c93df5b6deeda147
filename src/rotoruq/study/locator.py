"""Where things are in a TOML file: ``tomllib`` reports no positions for semantic errors, so
:class:`Locator` maps key paths to line numbers for the messages of
:class:`~rotoruq.errors.InputFileError`."""

from __future__ import annotations

import re

__all__ = ["Locator"]

_HEADER_ARRAY = re.compile(r"^\s*\[\[\s*([^\]]+?)\s*\]\]")
_HEADER_TABLE = re.compile(r"^\s*\[\s*([^\]]+?)\s*\]")
_BARE = r"""(?:[A-Za-z0-9_\-]+|"[^"]*"|'[^']*')"""
_KEY = re.compile(rf"^\s*({_BARE}(?:\s*\.\s*{_BARE})*)\s*=")
_INLINE_KEY = re.compile(r"""[{,]\s*([A-Za-z0-9_\-]+|"[^"]*")\s*=""")


def _split_key(text: str) -> tuple[str, ...]:
    parts = re.findall(r"""[A-Za-z0-9_\-]+|"[^"]*"|'[^']*'""", text)
    return tuple(p.strip("\"'") for p in parts)


class Locator:
    """Maps key paths of a TOML document to 1-based line numbers.

    Paths are tuples such as ``("parameters", "kp", "std")`` or ``("steps", 2, "from")``
    (array-of-tables entries are indexed from 0). :meth:`line` falls back to the longest
    known prefix, so any path gets the line of the nearest enclosing table.
    """

    def __init__(self, text: str):
        self.lines: dict[tuple, int] = {}
        counts: dict[tuple, int] = {}
        current: tuple = ()
        in_string = False
        for no, raw in enumerate(text.splitlines(), start=1):
            if raw.count('"""') % 2 == 1 or raw.count("'''") % 2 == 1:
                in_string = not in_string
                if not in_string:
                    continue
            if in_string:
                continue
            line = raw.split("#", 1)[0] if '"' not in raw and "'" not in raw else raw
            m = _HEADER_ARRAY.match(line)
            if m:
                base = self._in_array(_split_key(m.group(1)), counts)
                idx = counts.get(base, 0)
                counts[base] = idx + 1
                current = base + (idx,)
                self.lines.setdefault(current, no)
                continue
            m = _HEADER_TABLE.match(line)
            if m:
                current = self._in_array(_split_key(m.group(1)), counts)
                self.lines.setdefault(current, no)
                continue
            m = _KEY.match(line)
            if m:
                key = current + _split_key(m.group(1))
                self.lines.setdefault(key, no)
                rest = line[m.end():]
                if "{" in rest:
                    for k in _INLINE_KEY.findall(rest[rest.index("{"):]):
                        self.lines.setdefault(key + (k.strip("\"'"),), no)

    @staticmethod
    def _in_array(parts: tuple, counts: dict) -> tuple:
        """``[steps.x]`` after ``[[steps]]`` belongs to the last ``steps`` entry."""
        for k in range(len(parts) - 1, 0, -1):
            head = parts[:k]
            if head in counts:
                return head + (counts[head] - 1,) + parts[k:]
        return parts

    def line(self, *path: object) -> int | None:
        path = tuple(path)
        while path:
            if path in self.lines:
                return self.lines[path]
            path = path[:-1]
        return None
