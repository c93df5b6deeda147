"""Fill ``{label}`` fields of a solver input file from parameter values.

A template is ordinary text with fields in braces::

    collective = {collective_deg};          # value as written by repr(): shortest exact form
    k = {k_pitch_link:.6e};                 # a Python format spec
    h = {height_over_radius = 4.0};         # default used when the label has no value
    h = {height_over_radius = 4.0 : .3f};   # default and format spec

Literal braces are written ``{{`` / ``}}`` or ``\\{`` / ``\\}``. A field holds a label, an
optional ``= default`` (a number or a quoted string) and an optional ``:spec``; nothing is
evaluated, so a template cannot run code (unlike dprepro/aprepro expressions). Unknown labels
without a default, unbalanced braces and bad format specs raise
:class:`~rotoruq.errors.InputFileError` with the file and line.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import InputFileError

__all__ = ["fill_template", "fill_template_file", "template_fields"]

_FIELD = re.compile(
    r"""^\s*(?P<name>[A-Za-z_][A-Za-z0-9_.]*)\s*
        (?:=\s*(?P<default>"[^"]*"|'[^']*'|[^:"']*?))?\s*
        (?::(?P<spec>[^{}]*))?$""",
    re.VERBOSE,
)


def _scan(text: str, path):
    """Yield ('text', str) and ('field', body, line) pieces."""
    i, n = 0, len(text)
    buf: list[str] = []
    line = 1
    while i < n:
        c = text[i]
        two = text[i : i + 2]
        if two in ("{{", "}}", "\\{", "\\}"):
            buf.append(two[-1] if two[0] == "\\" else c)
            i += 2
            continue
        if c == "{":
            j = text.find("}", i + 1)
            k = text.find("{", i + 1)
            if j < 0 or (0 <= k < j):
                raise InputFileError(path, line, "a closing '}' for this template field "
                                     "(write '{{' or '\\{' for a literal brace)",
                                     text[i : i + 40].splitlines()[0])
            body = text[i + 1 : j]
            if "\n" in body:
                raise InputFileError(path, line, "a template field on one line", "{" + body)
            if buf:
                yield ("text", "".join(buf))
                buf = []
            yield ("field", body, line)
            i = j + 1
            continue
        if c == "}":
            raise InputFileError(path, line, "'}}' or '\\}' for a literal closing brace", "}")
        if c == "\n":
            line += 1
        buf.append(c)
        i += 1
    if buf:
        yield ("text", "".join(buf))


def _parse_field(body: str, path, line):
    m = _FIELD.match(body)
    if not m:
        raise InputFileError(path, line, "a field '{label}', '{label = default}' or "
                             "'{label:spec}'", "{" + body + "}")
    default = m.group("default")
    if default is not None:
        default = default.strip()
        if default[:1] in ("'", '"'):
            default = default[1:-1]
        elif default == "":
            raise InputFileError(path, line, "a default value after '='", "{" + body + "}")
        else:
            try:
                default = int(default) if re.fullmatch(r"[+-]?\d+", default) else float(default)
            except ValueError:
                raise InputFileError(path, line, "a numeric or quoted default", default) from None
    spec = m.group("spec")
    return m.group("name"), default, (spec.strip() if spec is not None else None)


def template_fields(text: str, path: str | os.PathLike | None = None) -> list[str]:
    """Labels used by the fields of a template, in order of first use."""
    out: list[str] = []
    for piece in _scan(text, path):
        if piece[0] == "field":
            name = _parse_field(piece[1], path, piece[2])[0]
            if name not in out:
                out.append(name)
    return out


def _format(value, spec: str | None, path, line, name) -> str:
    if isinstance(value, np.generic):
        value = value.item()
    if spec is None or spec == "":
        return repr(value) if isinstance(value, float) else str(value)
    try:
        return format(value, spec)
    except (ValueError, TypeError) as exc:
        raise InputFileError(path, line, f"a format spec valid for {name}={value!r} ({exc})",
                             spec) from None


def fill_template(
    text: str, values: Mapping[str, object], *, path: str | os.PathLike | None = None
) -> str:
    """Return ``text`` with every field replaced by its value.

    Parameters
    ----------
    text : template text.
    values : label -> value (floats print with ``repr`` unless a spec is given).
    path : file name used in error messages.
    """
    out: list[str] = []
    for piece in _scan(text, path):
        if piece[0] == "text":
            out.append(piece[1])
            continue
        _, body, line = piece
        name, default, spec = _parse_field(body, path, line)
        if name in values:
            value = values[name]
        elif default is not None:
            value = default
        else:
            raise InputFileError(path, line, f"a value for template field {name!r} (known "
                                 f"labels: {sorted(values)})", "{" + body + "}")
        out.append(_format(value, spec, path, line, name))
    return "".join(out)


def fill_template_file(
    src: str | os.PathLike, dst: str | os.PathLike, values: Mapping[str, object]
) -> Path:
    """Fill the template file ``src`` and write the result to ``dst``; returns ``dst``."""
    src, dst = Path(src), Path(dst)
    dst.write_text(fill_template(src.read_text(), values, path=src))
    return dst
