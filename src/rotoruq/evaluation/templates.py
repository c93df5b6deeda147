"""Fill ``{label}`` fields of a solver input file from parameter values.

A template is ordinary text with fields in braces::

    collective = {collective_deg};          # value as written by repr(): shortest exact form
    k = {k_pitch_link:.6e};                 # a Python format spec
    h = {height_over_radius = 4.0};         # default used when the label has no value
    h = {height_over_radius = 4.0 : .3f};   # default and format spec

Literal braces are written ``{{`` / ``}}`` or ``\\{`` / ``\\}``. A field holds a label, an
optional ``= default`` (a number or a quoted string) and an optional ``:spec``; nothing is
evaluated, so a template cannot run code (unlike dprepro/aprepro expressions). Unknown labels
without a default, unbalanced braces, bad format specs and files that are not UTF-8 raise
:class:`~rotoruq.errors.InputFileError` with the file and line. Filling takes time linear in
the template's size.
"""

from __future__ import annotations

import os
from collections.abc import Collection, Mapping
from pathlib import Path

import numpy as np

from ..errors import InputFileError
from ..safety import write_file
from .dakota_files import _to_int, read_text

__all__ = ["fill_template", "fill_template_file", "template_fields", "check_template"]

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
    """``(label, default, spec)`` of a field body ``label [= default] [: spec]``.

    Parsed with string methods in one pass (linear time, whatever the field holds)."""
    bad = InputFileError(path, line, "a field '{label}', '{label = default}' or '{label:spec}'",
                         "{" + body + "}")
    s = body.strip()
    k = 0
    while k < len(s) and s[k].isascii() and (s[k].isalnum() or s[k] in "_."):
        k += 1
    name, rest = s[:k], s[k:].lstrip()
    if not name or not (name[0].isalpha() or name[0] == "_"):
        raise bad
    default: str | float | None = None
    if rest.startswith("="):
        rest = rest[1:].lstrip()
        if rest[:1] in ("'", '"'):
            end = rest.find(rest[0], 1)
            if end < 0:
                raise bad
            default, rest = rest[1:end], rest[end + 1 :].lstrip()
        else:
            end = rest.find(":")
            raw = (rest if end < 0 else rest[:end]).strip()
            rest = "" if end < 0 else rest[end:]
            if '"' in raw or "'" in raw:
                raise bad
            if raw == "":
                raise InputFileError(path, line, "a default value after '='", "{" + body + "}")
            default = _to_int(raw)
            if default is None:
                try:
                    default = float(raw)
                except ValueError:
                    raise InputFileError(path, line, "a numeric or quoted default",
                                         raw) from None
    spec = None
    if rest.startswith(":"):
        spec = rest[1:].strip()
        # a width or precision of 10000 or more characters is a typo, not a format
        if any(len(run) > 4 for run in "".join(c if c.isdigit() else " " for c in spec).split()):
            raise InputFileError(path, line, "a format spec with widths and precisions below "
                                 "10000", spec)
    elif rest:
        raise bad
    return name, default, spec


def template_fields(text: str, path: str | os.PathLike | None = None) -> list[str]:
    """Labels used by the fields of a template, in order of first use."""
    out: list[str] = []
    for piece in _scan(text, path):
        if piece[0] == "field":
            name = _parse_field(piece[1], path, piece[2])[0]
            if name not in out:
                out.append(name)
    return out


def check_template(
    text: str, labels: Collection[str], path: str | os.PathLike | None = None
) -> None:
    """Check that every field of a template parses and has a value: a label among ``labels``
    or a default. Raises :class:`~rotoruq.errors.InputFileError` naming the line otherwise."""
    known = set(labels)
    for piece in _scan(text, path):
        if piece[0] == "field":
            name, default, _ = _parse_field(piece[1], path, piece[2])
            if default is None and name not in known:
                raise InputFileError(path, piece[2], f"a value for template field {name!r} "
                                     f"(known labels: {sorted(known)})", "{" + piece[1] + "}")


def _format(value, spec: str | None, path, line, name) -> str:
    if isinstance(value, np.generic):
        value = value.item()
    if spec is None or spec == "":
        return repr(value) if isinstance(value, float) else str(value)
    try:
        return format(value, spec)
    except (ValueError, TypeError, OverflowError) as exc:
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

    Examples
    --------
    >>> fill_template("theta = {collective_deg}; k = {k_pitch_link:.3e}; h = {h = 4.0}",
    ...               {"collective_deg": 5.4, "k_pitch_link": 15.0})
    'theta = 5.4; k = 1.500e+01; h = 4.0'
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
    r"""Fill the template file ``src`` and write the result to ``dst``; returns ``dst``.

    Parameters
    ----------
    src : str or PathLike
        The template (``{label}``, ``{label = default}``, ``{label:.6e}`` fields; see
        :func:`fill_template`).
    dst : str or PathLike
        The file to write.
    values : mapping of str to object
        Label -> value of each field.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> folder = Path(tempfile.mkdtemp())
    >>> _ = (folder / "input.tpl").write_text("omega = {omega}  # rad/s\n")
    >>> out = fill_template_file(folder / "input.tpl", folder / "input.txt", {"omega": 224.6375})
    >>> out.read_text()
    'omega = 224.6375  # rad/s\n'
    """
    src, dst = Path(src), Path(dst)
    text = fill_template(read_text(src, "template file"), values, path=src)
    return write_file(dst, text.encode("utf-8"))  # never through a link planted at dst
