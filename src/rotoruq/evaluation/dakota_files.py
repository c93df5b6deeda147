"""Dakota parameters and results files (the fork/system interface contract).

Dakota runs an analysis driver as ``driver params.in results.out``. Before the run it writes the
parameters file; the driver writes the results file. Both formats are documented in the Dakota
User's Manual ("Dakota Parameters File Data Format", "Dakota Results File Data Format").

Parameters file, standard format (one ``value tag`` pair per line)::

                          2 variables
     5.4000000000000004e+00 collective_deg
     1.5000000000000000e+01 k_pitch_link
                          2 functions
                          1 ASV_1:thrust
                          1 ASV_2:torque
                          2 derivative_variables
                          1 DVV_1:collective_deg
                          2 DVV_2:k_pitch_link
                          0 analysis_components
                          1 eval_id
                          0 metadata

and the aprepro format, the same data as ``{ tag = value }``::

                    { DAKOTA_VARS     =                         2 }
                    { collective_deg  =    5.4000000000000004e+00 }
                    ...
                    { DAKOTA_EVAL_ID  =                         1 }

Values are written as ``%24.16e`` (17 significant digits), so a float64 survives the round trip
exactly. The trailing ``metadata`` block of recent Dakota versions is optional on reading and
written only when asked for.

Results file: one value per line with an optional label, then one gradient per requested
response in single brackets ``[ g_1 ... g_p ]``, then Hessians in double brackets
``[[ h_11 ... h_1p  h_21 ... h_pp ]]`` (rows may be spread over lines). A file whose first word
is ``fail`` (any case) reports a failed evaluation. Exponents must be ``e`` or ``E``; Fortran's
``D`` is rejected with a message saying so.

Every parse error is an :class:`~rotoruq.errors.InputFileError` naming the file and line,
undecodable (non-UTF-8) files included. The parsers run in time linear in the file size (no
regular expression that can backtrack), so a corrupt or hostile file fails fast.

Labels written to a parameters file (variables, responses, analysis components, metadata) are
checked by :func:`check_label`: a label holding white space, a newline or a brace could forge
lines of the file.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputFileError, ParameterError
from ..safety import write_file

__all__ = [
    "check_label",
    "ParametersFile",
    "ResultsFile",
    "format_parameters",
    "parse_parameters",
    "parse_parameters_batch",
    "read_parameters",
    "read_parameters_batch",
    "write_parameters",
    "format_results",
    "parse_results",
    "read_results",
    "write_results",
    "FAIL_TEXT",
]

FAIL_TEXT = "FAIL\n"

_WIDTH = 24

# ---------------------------------------------------------------------------------------------
# tokens, in linear time (str methods only: no regular expression can backtrack on them)


def _digits(s: str) -> bool:
    """True for a non-empty run of ASCII digits (str.isdigit alone accepts '²' or '٣')."""
    return s.isascii() and s.isdigit()


def _is_int(s: str) -> bool:
    return _digits(s[1:] if s[:1] in ("+", "-") and s else s)


def _is_fortran(s: str) -> bool:
    """A number with a Fortran 'D' exponent, like ``1.5D+03`` or ``-.2d-1``."""
    t = s[1:] if s[:1] in ("+", "-") and s else s
    k = max(t.find("d"), t.find("D"))
    if k < 0:
        return False
    mant, exp = t[:k], t[k + 1 :]
    if exp[:1] in ("+", "-"):
        exp = exp[1:]
    whole, dot, frac = mant.partition(".")
    if not _digits(exp) or not (whole or frac):
        return False
    return (not whole or _digits(whole)) and (not frac or _digits(frac))


def _to_int(s: str) -> int | None:
    """The integer ``s`` stands for, or None (also for integers too long to convert)."""
    if not _is_int(s):
        return None
    try:
        return int(s)
    except ValueError:  # more digits than sys.get_int_max_str_digits()
        return None


def _small_int(s: str) -> int | None:
    """A count or code: an integer of at most 18 digits, else None."""
    return _to_int(s) if len(s) <= 19 else None


def check_label(label: Any, what: str = "label") -> str:
    """Check a label written to a Dakota file or used in a file name; returns it.

    A label must be a non-empty string of printable characters without white space (the
    standard format splits on it; a newline would forge a line), without path separators
    (``/``, ``\\``), without ``..``, and without ``{``, ``}``, ``=`` or quotes (aprepro
    syntax). Raises :class:`~rotoruq.errors.ParameterError` naming ``what`` otherwise.
    """
    if not isinstance(label, str) or not label:
        raise ParameterError(f"{what} must be a non-empty string, got {label!r}")
    bad = [c for c in label if c.isspace() or not c.isprintable() or c in '/\\{}="\'']
    if bad:
        raise ParameterError(f"{what} {label!r} holds {bad[0]!r}: labels may not hold white "
                             "space, control characters, path separators, braces, '=' or "
                             "quotes")
    if ".." in label:
        raise ParameterError(f"{what} {label!r} holds '..'")
    return label


@dataclass(frozen=True, eq=False)
class ParametersFile:
    """Content of a Dakota parameters file.

    Attributes
    ----------
    variables : dict of str to float, int or str
        Label -> value, in file order.
    asv : dict of str to int
        Response label -> active set code (bit 1 value, 2 gradient, 4 Hessian).
    dvv : tuple of str
        Labels of the derivative variables (the variables gradients are taken with respect
        to).
    analysis_components : tuple of (str, str)
        (component, driver name) pairs.
    eval_id : str
        Evaluation id as written (``"12"`` or hierarchical ``"1:4:2"``).
    metadata : tuple of str
        Labels of the metadata block (empty when the file has none or an empty block).
    format : str
        ``"standard"`` or ``"aprepro"``.
    """

    variables: dict[str, float | int | str]
    asv: dict[str, int] = field(default_factory=dict)
    dvv: tuple[str, ...] = ()
    analysis_components: tuple[tuple[str, str], ...] = ()
    eval_id: str = "1"
    metadata: tuple[str, ...] = ()
    format: str = "standard"

    @property
    def names_in(self) -> tuple[str, ...]:
        """Variable labels, in file order."""
        return tuple(self.variables)

    @property
    def names_out(self) -> tuple[str, ...]:
        """Response labels (those of the ASV block), in file order."""
        return tuple(self.asv)

    def values(self) -> np.ndarray:
        """Numeric variable values as a float array (d,); string variables raise."""
        out = []
        for k, v in self.variables.items():
            if isinstance(v, str):
                raise ParameterError(f"variable {k!r} is a string ({v!r}), not a number")
            out.append(float(v))
        return np.array(out, dtype=float)


@dataclass(frozen=True, eq=False)
class ResultsFile:
    """Content of a Dakota results file.

    Attributes
    ----------
    values : ndarray of shape (k,)
        Function values in file order (k = number of values present).
    names_out : tuple of str or None
        Label of each value, or None where the value had none.
    gradients : ndarray of shape (g, p) or None
        One row per gradient block.
    hessians : ndarray of shape (h, p, p) or None
        One matrix per Hessian block.
    failed : bool
        True when the file reports a failed evaluation (``fail``).
    """

    values: np.ndarray
    names_out: tuple[str | None, ...] = ()
    gradients: np.ndarray | None = None
    hessians: np.ndarray | None = None
    failed: bool = False


# ---------------------------------------------------------------------------------------------
# parameters


def _fmt_value(v: float | int | str) -> str:
    if isinstance(v, bool):
        raise ParameterError("boolean variable values are not supported")
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, str):
        if not v or any(c.isspace() or not c.isprintable() for c in v):
            # Dakota string variables may not contain white space in the standard format
            raise ParameterError(f"string variable value {v!r} must be non-empty without "
                                 "spaces or control characters")
        return v
    return f"{float(v):.16e}"


def format_parameters(
    variables: Mapping[str, float | int | str],
    names_out: Sequence[str] | Mapping[str, int],
    *,
    asv: int | Sequence[int] = 1,
    dvv: Sequence[str] | None = None,
    analysis_components: Sequence[tuple[str, str]] = (),
    eval_id: str | int = 1,
    metadata: Sequence[str] | None = None,
    format: str = "standard",
) -> str:
    """Text of a parameters file.

    Parameters
    ----------
    variables : mapping label -> value (floats written with 17 significant digits).
    names_out : response labels, or a mapping label -> ASV code (then ``asv`` is ignored).
    asv : one code for every response, or one per response.
    dvv : derivative variable labels (default: every float-valued variable).
    analysis_components : (component, driver) pairs.
    eval_id : evaluation id.
    metadata : metadata labels; None omits the block (older Dakota versions).
    format : "standard" or "aprepro".
    """
    if format not in ("standard", "aprepro"):
        raise ParameterError(f"format must be 'standard' or 'aprepro', got {format!r}")
    codes: dict[str, int]
    if isinstance(names_out, Mapping):
        codes = {str(k): int(v) for k, v in names_out.items()}
    else:
        names = [str(r) for r in names_out]
        asv_list = [int(asv)] * len(names) if isinstance(asv, int | np.integer) else \
            [int(a) for a in asv]
        if len(asv_list) != len(names):
            raise ParameterError(f"{len(asv_list)} ASV codes for {len(names)} responses")
        codes = dict(zip(names, asv_list, strict=True))
    for k, c in codes.items():
        if not 0 <= c <= 7:
            raise ParameterError(f"ASV code of {k!r} must be in 0..7, got {c}")
    labels = [check_label(k, "variable label") for k in variables]
    for k in codes:
        check_label(k, "response label")
    for component, driver in analysis_components:
        check_label(component, "analysis component")
        check_label(driver, "analysis driver name")
    for m in metadata or ():
        check_label(m, "metadata label")
    if not _is_int(str(eval_id)) and not all(_digits(p) for p in str(eval_id).split(":")):
        raise ParameterError(f"eval_id must look like 12 or 1:4:2, got {eval_id!r}")
    if dvv is None:
        # derivatives exist only for continuous variables
        dvv = [k for k, v in variables.items() if not isinstance(v, (str, int, np.integer))]
    for k in dvv:
        if k not in variables:
            raise ParameterError(f"derivative variable {k!r} is not among the variables "
                                 f"{labels}")
    lines: list[tuple[str, str]] = []  # (value, tag)
    lines.append((str(len(labels)), "variables"))
    lines += [(_fmt_value(v), k) for k, v in variables.items()]
    lines.append((str(len(codes)), "functions"))
    lines += [(str(c), f"ASV_{i}:{k}") for i, (k, c) in enumerate(codes.items(), 1)]
    lines.append((str(len(dvv)), "derivative_variables"))
    lines += [(str(labels.index(k) + 1), f"DVV_{i}:{k}") for i, k in enumerate(dvv, 1)]
    lines.append((str(len(analysis_components)), "analysis_components"))
    lines += [(c, f"AC_{i}:{d}") for i, (c, d) in enumerate(analysis_components, 1)]
    lines.append((str(eval_id), "eval_id"))
    if metadata is not None:
        lines.append((str(len(metadata)), "metadata"))
        lines += [(str(m), f"MD_{i}") for i, m in enumerate(metadata, 1)]  # "seconds MD_1"
    if format == "standard":
        return "".join(f"{v:>{_WIDTH}} {t}\n" for v, t in lines)
    header = {
        "variables": "DAKOTA_VARS",
        "functions": "DAKOTA_FNS",
        "derivative_variables": "DAKOTA_DER_VARS",
        "analysis_components": "DAKOTA_AN_COMPS",
        "eval_id": "DAKOTA_EVAL_ID",
        "metadata": "DAKOTA_METADATA",
    }
    out = []
    for v, t in lines:
        if t.startswith("AC_"):
            v = f'"{v}"'
        if t.startswith("MD_"):  # metadata: { MD_i = "label" }
            v = f'"{v}"'
        out.append(f"{'':20}{{ {header.get(t, t):<15} = {v:>{_WIDTH}} }}\n")
    return "".join(out)


def write_parameters(
    path: str | os.PathLike,
    variables: Mapping[str, float | int | str],
    names_out: Sequence[str] | Mapping[str, int],
    **kwargs: Any,
) -> Path:
    """Write a parameters file (keywords of :func:`format_parameters`); returns the path.

    Parameters
    ----------
    path : str or PathLike
        The file to write.
    variables : mapping of str to float, int or str
        Variable label -> value (floats written with 17 significant digits).
    names_out : sequence of str, or mapping of str to int
        Response labels, or a mapping label -> ASV code.
    **kwargs
        ``asv``, ``dvv``, ``analysis_components``, ``eval_id``, ``metadata`` and ``format``
        of :func:`format_parameters`.

    Returns
    -------
    Path
        The parameters file written (``path``).

    Examples
    --------
    A parameters file for one evaluation of two variables and one response, read back:

    >>> import tempfile
    >>> from pathlib import Path
    >>> path = write_parameters(Path(tempfile.mkdtemp()) / "params.in",
    ...                         {"collective_deg": 5.4, "omega": 224.6375}, ["thrust"])
    >>> read_parameters(path).variables
    {'collective_deg': 5.4, 'omega': 224.6375}
    """
    # atomically, never through a link planted at its name
    return write_file(path, format_parameters(variables, names_out, **kwargs).encode("utf-8"))


def _aprepro_line(line: str) -> tuple[str, str] | None:
    """``(tag, value)`` of a stripped ``{ tag = value }`` line, or None.

    Dakota writes labels as they are, so a tag may hold ``=`` (``{ P=W = 1.5 }``) and, for an
    analysis component, spaces (``{ AC_1:driver --opt = "comp" }``): the value is the quoted
    string at the end, else the word after the last ``=``.
    """
    if len(line) < 2 or line[0] != "{" or line[-1] != "}":
        return None
    body = line[1:-1].strip()
    if body.endswith('"') and len(body) >= 2:
        start = body.rfind('"', 0, len(body) - 1)
        if start < 0:
            return None
        tag, eq, value = body[:start].rstrip(), "=", body[start:]
        if not tag.endswith("="):
            return None
        tag = tag[:-1]
    else:
        tag, eq, value = body.rpartition("=")
    tag, value = tag.strip(), value.strip()
    if not eq or not tag or not value:
        return None
    if any(c.isspace() for c in tag) and not tag.startswith("AC_"):
        return None
    return tag, value


def _component_split(line: str) -> tuple[str, str] | None:
    """``(component, tag)`` of a standard-format analysis component line, where both sides
    may hold spaces: ``c1 with space AC_1:driver --set a=1`` (Dakota 6.24 writes it so)."""
    k = line.find(" AC_")
    while k >= 0:
        head, colon, _ = line[k + 1 :].partition(":")
        if colon and _digits(head[3:]):
            return line[:k].strip(), line[k + 1 :]
        k = line.find(" AC_", k + 1)
    return None


def _pairs(text: str, path) -> tuple[str, list[tuple[int, str, str]]]:
    """Split a parameters file into (line number, value, tag); detect the format."""
    rows = []
    fmt = None
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line:
            continue
        pair = _aprepro_line(line) if fmt in (None, "aprepro") else None
        if pair is not None:
            fmt = "aprepro"
            tag, value = pair
            if len(value) >= 2 and value[0] == value[-1] == '"':
                value = value[1:-1]
            rows.append((lineno, value, tag))
            continue
        if fmt == "aprepro":
            raise InputFileError(path, lineno, "an aprepro '{ tag = value }' line", raw)
        fmt = "standard"
        parts = line.split()
        if len(parts) != 2:
            comp = _component_split(line)
            if comp is None:
                raise InputFileError(path, lineno, "a 'value tag' pair", raw)
            parts = list(comp)
        rows.append((lineno, parts[0], parts[1]))
    if fmt is None:
        raise InputFileError(path, None, "a Dakota parameters file", "an empty file")
    return fmt, rows


_APREPRO_HEAD = {
    "DAKOTA_VARS": "variables",
    "DAKOTA_FNS": "functions",
    "DAKOTA_DER_VARS": "derivative_variables",
    "DAKOTA_AN_COMPS": "analysis_components",
    "DAKOTA_EVAL_ID": "eval_id",
    "DAKOTA_METADATA": "metadata",
}

_FORTRAN_HINT = ("with an 'e' or 'E' exponent (Fortran-style 'D' exponents are not read; "
                 "replace D by E)")


def _number(value: str, path, lineno: int, what: str) -> float | int:
    if _is_fortran(value):
        raise InputFileError(path, lineno, f"{what} {_FORTRAN_HINT}", value)
    n = _to_int(value)
    if n is not None:
        return n
    try:
        return float(value)
    except ValueError:
        raise InputFileError(path, lineno, what, value) from None


def _indexed_tag(tag: str, prefix: str) -> str | None:
    """``label`` of a tag ``<prefix>_<i>:<label>`` (like ``ASV_2:torque``), else None."""
    head, colon, label = tag.partition(":")
    if not colon or not label or not head.startswith(prefix + "_"):
        return None
    return label if _digits(head[len(prefix) + 1 :]) else None


def _parse_blocks(text: str, path) -> list[ParametersFile]:
    """Every parameters block of a file: one, or several for Dakota's ``batch`` interface
    (blocks follow each other, each from ``<n> variables`` to its ``eval_id`` and metadata)."""
    fmt, rows = _pairs(text, path)
    if fmt == "aprepro":
        # block headers renamed; metadata items { MD_i = "label" } become (label, MD_i) as in
        # the standard format ("seconds MD_1")
        rows = [(ln, v, _APREPRO_HEAD.get(t, t)) for ln, v, t in rows]
    pos = 0

    def block(tag: str, expected_item: str) -> list[tuple[int, str, str]]:
        nonlocal pos
        if pos >= len(rows):
            raise InputFileError(path, None, f"a '<n> {tag}' line", "end of file")
        ln, v, t = rows[pos]
        n = _small_int(v)
        if t != tag or n is None or n < 0:
            raise InputFileError(path, ln, f"'<n> {tag}'", f"{v} {t}")
        items = rows[pos + 1 : pos + 1 + n]
        if len(items) < n:
            raise InputFileError(path, None, f"{n} {expected_item} lines", f"{len(items)}")
        pos += 1 + n
        return items

    out = []
    while True:
        variables: dict[str, float | int | str] = {}
        for ln, v, t in block("variables", "variable"):
            if t in variables:
                raise InputFileError(path, ln, f"a new variable label (duplicate {t!r})", t)
            if _is_fortran(v):
                _number(v, path, ln, "a variable value")
            try:
                variables[t] = _number(v, path, ln, "a number")
            except InputFileError:
                variables[t] = v  # string variable
        asv: dict[str, int] = {}
        for ln, v, t in block("functions", "ASV"):
            label, code = _indexed_tag(t, "ASV"), _small_int(v)
            if label is None or code is None or not 0 <= code <= 7:
                raise InputFileError(path, ln, "'<code 0-7> ASV_i:label'", f"{v} {t}")
            asv[label] = code
        dvv = []
        names = list(variables)
        for ln, v, t in block("derivative_variables", "DVV"):
            label, idx = _indexed_tag(t, "DVV"), _small_int(v)
            if label is None or idx is None:
                raise InputFileError(path, ln, "'<variable id> DVV_i:label'", f"{v} {t}")
            if label not in variables:
                if not 1 <= idx <= len(names):
                    raise InputFileError(path, ln, "a derivative variable among the variables",
                                         t)
                label = names[idx - 1]
            dvv.append(label)
        comps = []
        for ln, v, t in block("analysis_components", "AC"):
            label = _indexed_tag(t, "AC")
            if label is None:
                raise InputFileError(path, ln, "'<component> AC_i:driver'", f"{v} {t}")
            comps.append((v, label))
        if pos >= len(rows) or rows[pos][2] != "eval_id":
            found = "end of file" if pos >= len(rows) else f"{rows[pos][1]} {rows[pos][2]}"
            raise InputFileError(path, rows[pos][0] if pos < len(rows) else None,
                                 "'<id> eval_id'", found)
        ln, eval_id, _ = rows[pos]
        if not all(_digits(part) for part in eval_id.split(":")):
            raise InputFileError(path, ln, "an evaluation id like 12 or 1:4:2", eval_id)
        pos += 1
        metadata: tuple[str, ...] = ()
        if pos < len(rows) and rows[pos][2] == "metadata":
            items = block("metadata", "MD")
            for ln, v, t in items:
                if not (t.startswith("MD_") and _digits(t[3:])):
                    raise InputFileError(path, ln, "'<label> MD_i'", f"{v} {t}")
            metadata = tuple(v for _, v, _ in items)
        out.append(ParametersFile(variables, asv, tuple(dvv), tuple(comps), eval_id, metadata,
                                  fmt))
        if pos >= len(rows) or rows[pos][2] != "variables":
            break
    if pos < len(rows):
        ln, v, t = rows[pos]
        raise InputFileError(path, ln, "end of file after eval_id (and metadata)", f"{v} {t}")
    return out


def parse_parameters(text: str, path: str | os.PathLike | None = None) -> ParametersFile:
    r"""Parse the text of a parameters file (standard or aprepro format, detected).

    A file of several blocks (Dakota's ``batch`` interface) raises
    :class:`~rotoruq.errors.InputFileError`; read it with :func:`parse_parameters_batch`.

    Examples
    --------
    >>> p = parse_parameters("1 variables\n2.5 P=W\n1 functions\n1 ASV_1:f\n"
    ...                      "0 derivative_variables\n0 analysis_components\n3 eval_id\n")
    >>> p.variables, p.asv, p.eval_id
    ({'P=W': 2.5}, {'f': 1}, '3')
    """
    blocks = _parse_blocks(text, path)
    if len(blocks) > 1:
        raise InputFileError(path, None, "one parameters block (a batch file holds several: "
                             "read it with parse_parameters_batch)", f"{len(blocks)} blocks")
    return blocks[0]


def parse_parameters_batch(text: str, path: str | os.PathLike | None = None
                           ) -> list[ParametersFile]:
    r"""Parse a parameters file of one or more blocks (Dakota's ``batch`` interface writes one
    block per evaluation, with evaluation ids ``<batch>:<eval>``).

    Examples
    --------
    >>> one = ("1 variables\n{x} a\n1 functions\n1 ASV_1:f\n0 derivative_variables\n"
    ...        "0 analysis_components\n1:{i} eval_id\n")
    >>> blocks = parse_parameters_batch(one.format(x=1.0, i=1) + one.format(x=2.0, i=2))
    >>> [(b.eval_id, b.variables["a"]) for b in blocks]
    [('1:1', 1.0), ('1:2', 2.0)]
    """
    return _parse_blocks(text, path)


def read_text(path: str | os.PathLike, what: str) -> str:
    """A file's text, decoded as UTF-8; an undecodable or unreadable file raises
    :class:`~rotoruq.errors.InputFileError` naming the file, the line and the bad bytes."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise InputFileError(path, None, f"a readable {what}", f"{type(exc).__name__}: "
                             f"{exc.strerror or exc}") from None
    return decode_text(data, path, what)


def decode_text(data: bytes, path: str | os.PathLike | None, what: str) -> str:
    """``data`` decoded as UTF-8; undecodable bytes raise
    :class:`~rotoruq.errors.InputFileError` naming the file ``path``, the line and the bytes.

    Examples
    --------
    >>> decode_text(b"1.5 f\\n", "results.out", "Dakota results file")
    '1.5 f\\n'
    """
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise InputFileError(path, line, f"a {what} in UTF-8 text",
                             repr(data[exc.start : exc.start + 8])) from None


def read_parameters(path: str | os.PathLike) -> ParametersFile:
    """Read and parse a parameters file (standard or aprepro format).

    Parameters
    ----------
    path : str or PathLike
        The file; a malformed one raises :class:`~rotoruq.InputFileError` naming the line.

    Returns
    -------
    ParametersFile
        The variables, the active set (ASV), the derivative variables and the rest of the
        file's blocks.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> path = write_parameters(Path(tempfile.mkdtemp()) / "params.in", {"x": 1.5}, ["y", "z"])
    >>> p = read_parameters(path)
    >>> p.variables, p.asv                  # active set: 1 = value requested
    ({'x': 1.5}, {'y': 1, 'z': 1})
    """
    return parse_parameters(read_text(path, "Dakota parameters file"), path)


def read_parameters_batch(path: str | os.PathLike) -> list[ParametersFile]:
    """Read and parse a parameters file of one or more blocks (see
    :func:`parse_parameters_batch`)."""
    return parse_parameters_batch(read_text(path, "Dakota parameters file"), path)


# ---------------------------------------------------------------------------------------------
# results


def format_results(
    values: Sequence[float] | np.ndarray,
    names_out: Sequence[str] | None = None,
    *,
    gradients: np.ndarray | None = None,
    hessians: np.ndarray | None = None,
    metadata: Mapping[str, float] | None = None,
) -> str:
    """Text of a results file: values (with their response labels ``names_out``), then
    gradients, then Hessians, then the metadata values with their labels (Dakota 6.24 reads
    them last).

    values : (k,); gradients : (g, p) array or None; hessians : (h, p, p) array or None;
    metadata : label -> value, in the order of the parameters file's metadata block.
    """
    values = np.atleast_1d(np.asarray(values, dtype=float))
    if names_out is not None and len(names_out) != len(values):
        raise ParameterError(f"{len(names_out)} labels for {len(values)} values")
    out = []
    for i, v in enumerate(values):
        lab = f" {names_out[i]}" if names_out is not None else ""
        out.append(f"{v:{_WIDTH}.16e}{lab}\n")
    if gradients is not None:
        for g in np.atleast_2d(np.asarray(gradients, dtype=float)):
            out.append("[ " + " ".join(f"{e:.16e}" for e in g) + " ]\n")
    if hessians is not None:
        h = np.asarray(hessians, dtype=float)
        if h.ndim == 2:
            h = h[None]
        for m in h:
            rows = ["  ".join(f"{e:.16e}" for e in r) for r in m]
            out.append("[[ " + "\n   ".join(rows) + " ]]\n")
    for label, v in (metadata or {}).items():
        out.append(f"{float(v):{_WIDTH}.16e} {check_label(label, 'metadata label')}\n")
    return "".join(out)


def write_results(
    path: str | os.PathLike,
    values: Sequence[float] | np.ndarray | None = None,
    names_out: Sequence[str] | None = None,
    *,
    gradients: np.ndarray | None = None,
    hessians: np.ndarray | None = None,
    metadata: Mapping[str, float] | None = None,
    failed: bool = False,
) -> Path:
    """Write a results file (see :func:`format_results`); ``failed=True`` writes the ``FAIL``
    marker only.

    The file is written to a temporary name and renamed, so a reader never sees half a file.

    Parameters
    ----------
    path : str or PathLike
        The file to write.
    values : sequence of float or ndarray of shape (k,), optional
        The response values (needed unless ``failed``).
    names_out : sequence of str, optional
        Their labels, written after each value (default: no labels).
    gradients : ndarray of shape (g, p), optional
        Gradients, one row per response with a gradient.
    hessians : ndarray of shape (h, p, p), optional
        Hessians, one per response with a Hessian.
    metadata : mapping of str to float, optional
        Label -> value, in the order of the parameters file's metadata block.
    failed : bool, optional
        Write the ``FAIL`` marker only (default False).

    Returns
    -------
    Path
        The results file written (``path``).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> path = write_results(Path(tempfile.mkdtemp()) / "results.out", [25.7, 281.4],
    ...                      ["thrust", "power"])
    >>> r = read_results(path)
    >>> r.values.tolist(), r.names_out, r.failed
    ([25.7, 281.4], ('thrust', 'power'), False)
    """
    path = Path(path)
    if failed:
        text = FAIL_TEXT
    elif values is None:
        raise ParameterError("write_results needs values (or failed=True)")
    else:
        text = format_results(values, names_out, gradients=gradients, hessians=hessians,
                              metadata=metadata)
    return write_file(path, text.encode("utf-8"))  # never through a link planted at its name


def _tokens(text: str, path=None) -> list[tuple[int, str]]:
    """Words with their line numbers; ``[``, ``]``, ``[[`` and ``]]`` are tokens of their own
    (a run of three brackets is a double one then a single one). Only ``str.replace`` and
    ``str.split``: linear time."""
    out = []
    for lineno, line in enumerate(text.splitlines(), 1):
        if "\x01" in line or "\x02" in line:  # the placeholders of double brackets below
            raise InputFileError(path, lineno, "text without control characters", line)
        line = line.replace("[[", " \x01 ").replace("]]", " \x02 ")
        line = line.replace("[", " [ ").replace("]", " ] ")
        out += [(lineno, w.replace("\x01", "[[").replace("\x02", "]]")) for w in line.split()]
    return out


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def parse_results(
    text: str,
    path: str | os.PathLike | None = None,
    *,
    names_out: Sequence[str] | None = None,
    asv: Sequence[int] | None = None,
    n_dvv: int | None = None,
    by_position: bool = False,
) -> ResultsFile:
    """Parse the text of a results file.

    Parameters
    ----------
    text : str
        The file's text.
    path : str or PathLike, optional
        The file it was read from, named in the errors (:class:`~rotoruq.InputFileError`).
    names_out : sequence of str, optional
        Expected response labels, in order. When given, the number of values is checked and
        labels, where present, must match (a file whose labels are a permutation of
        ``names_out`` is reordered).
    asv : sequence of int, optional
        Active set codes per response (default: values only, i.e. all 1), which say how many
        values, gradients and Hessians the file must hold.
    n_dvv : int, optional
        Number of derivative variables (length of each gradient).
    by_position : bool, optional
        Read the values in file order whatever their labels say, as Dakota does (its own test
        drivers label every value ``g``), instead of refusing labels that are neither
        ``names_out`` nor a permutation of it; ``names_out`` of the result then keeps the
        file's labels, for the caller to compare. The number of values is still checked
        (default False).

    Returns
    -------
    ResultsFile
        The values, their labels, gradients and Hessians, and whether the file says
        ``FAIL``.
    """
    toks = _tokens(text, path)
    if toks and toks[0][1].lower().startswith("fail"):
        return ResultsFile(np.zeros(0), (), None, None, True)
    if names_out is not None and asv is None:
        asv = [1] * len(names_out)
    values: list[float] = []
    labels: list[str | None] = []
    i = 0
    while i < len(toks) and toks[i][1] not in ("[", "[["):
        ln, w = toks[i]
        if _is_fortran(w):
            raise InputFileError(path, ln, f"a response value {_FORTRAN_HINT}", w)
        if not _is_number(w):
            raise InputFileError(path, ln, "a numeric response value", w)
        values.append(float(w))
        lab = None
        if i + 1 < len(toks) and toks[i + 1][1] not in ("[", "[[") and not _is_number(
            toks[i + 1][1]
        ) and not _is_fortran(toks[i + 1][1]):
            lab = toks[i + 1][1]
            i += 1
        labels.append(lab)
        i += 1

    def bracket(open_: str, close: str, what: str) -> list[tuple[int, list[float]]]:
        nonlocal i
        blocks = []
        while i < len(toks) and toks[i][1] == open_:
            start = toks[i][0]
            i += 1
            nums = []
            while i < len(toks) and toks[i][1] != close:
                ln, w = toks[i]
                if w in ("[", "[[", "]", "]]"):
                    raise InputFileError(path, ln, f"a number or '{close}' inside a {what}", w)
                if _is_fortran(w):
                    raise InputFileError(path, ln, f"a {what} entry {_FORTRAN_HINT}", w)
                if not _is_number(w):
                    raise InputFileError(path, ln, f"a numeric {what} entry", w)
                nums.append(float(w))
                i += 1
            if i >= len(toks):
                raise InputFileError(path, start, f"a closing '{close}' for this {what}", "EOF")
            i += 1
            blocks.append((start, nums))
        return blocks

    grads = bracket("[", "]", "gradient")
    hess = bracket("[[", "]]", "Hessian")
    if i < len(toks):
        ln, w = toks[i]
        raise InputFileError(path, ln, "values, then '[ gradients ]', then '[[ Hessians ]]'", w)

    def widths_ok(blocks, size_of, what):
        sizes = {len(b) for _, b in blocks}
        if len(sizes) > 1:
            ln = next(s for s, b in blocks if len(b) != len(blocks[0][1]))
            raise InputFileError(path, ln, f"every {what} of the same length", str(sorted(sizes)))
        if blocks and n_dvv is not None and len(blocks[0][1]) != size_of(n_dvv):
            raise InputFileError(path, blocks[0][0], f"{size_of(n_dvv)} entries per {what}",
                                 str(len(blocks[0][1])))

    widths_ok(grads, lambda p: p, "gradient")
    widths_ok(hess, lambda p: p * p, "Hessian")
    g = np.array([b for _, b in grads], dtype=float) if grads else None
    h = None
    if hess:
        size = len(hess[0][1])
        p = int(round(np.sqrt(size)))
        if p * p != size:
            raise InputFileError(path, hess[0][0], "a square Hessian (p*p entries)", str(size))
        h = np.array([b for _, b in hess], dtype=float).reshape(len(hess), p, p)
    vals = np.array(values, dtype=float)
    labs = tuple(labels)
    if asv is not None:
        n_val = sum(1 for a in asv if a & 1)
        n_grad = sum(1 for a in asv if a & 2)
        n_hess = sum(1 for a in asv if a & 4)
        for what, have, want in (("response values", len(values), n_val),
                                 ("gradients", len(grads), n_grad),
                                 ("Hessians", len(hess), n_hess)):
            if have != want:
                last = toks[-1][0] if toks else None
                raise InputFileError(path, last, f"{want} {what}", f"{have}")
    if names_out is not None and asv is not None and any(lab is not None for lab in labs):
        wanted = [n for n, a in zip(names_out, asv, strict=True) if a & 1]
        if list(labs) != wanted:
            if sorted(lab or "" for lab in labs) == sorted(wanted) and None not in labs:
                order = [labs.index(n) for n in wanted]
                vals, labs = vals[order], tuple(wanted)
            elif not by_position:
                ln = toks[0][0]
                raise InputFileError(path, ln, f"response labels {wanted}", str(list(labs)))
    return ResultsFile(vals, labs, g, h, False)


def read_results(path: str | os.PathLike, **expected: Any) -> ResultsFile:
    """Read and parse a results file.

    Parameters
    ----------
    path : str or PathLike
        The file the driver wrote; a missing or malformed one raises
        :class:`~rotoruq.InputFileError`.
    **expected
        ``names_out``, ``asv``, ``n_dvv`` and ``by_position`` of :func:`parse_results`: what
        the file must hold.

    Returns
    -------
    ResultsFile
        As :func:`parse_results` gives it.

    See Also
    --------
    parse_results : The checks, on a text already read.

    Examples
    --------
    A failed evaluation is a file with ``FAIL``; reading it says so:

    >>> import tempfile
    >>> from pathlib import Path
    >>> path = write_results(Path(tempfile.mkdtemp()) / "results.out", failed=True)
    >>> read_results(path).failed
    True
    """
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, None, "a results file written by the driver", "no file")
    return parse_results(read_text(path, "Dakota results file"), path, **expected)
