"""C81 airfoil tables: reader, writer and MBDyn-style interpolation.

A C81 table holds three blocks (CL, CD, CM), each a grid of coefficients over angle of attack
(degrees) and Mach number. The traditional fixed format is

- header ``A30,6I2``: title in columns 1-30, then the counts ML NL MD ND MM NM (number of Mach
  values and of angles of attack of the CL, CD and CM blocks) in 2-character fields;
- per block, a Mach row (columns 1-7 blank, then the Mach numbers in 7-character fields, 9 per
  line, continued on further lines whose columns 1-7 are blank) followed by one row per angle
  of attack (the angle in columns 1-7, then the coefficients in 7-character fields, 9 per line,
  continuation lines with columns 1-7 blank).

Fields may touch (``-1.161-1.161``), so the fixed format is read by columns, never by
whitespace. The "free format" variant (MBDyn's ``free format``) starts with an optional
``# FREE FORMAT`` line, then ``title; ML NL MD ND MM NM``, then the same numbers separated by
whitespace.

Interpolation follows MBDyn's ``aerodc81``: the angle is wrapped to [-180, 180), the Mach
number is taken in absolute value, and the coefficient is bilinear in (alpha, Mach), clamped
to the end values outside either grid.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputFileError, ParameterError
from ..safety import write_file

__all__ = ["C81Block", "C81Table", "read_c81", "write_c81", "Bracket", "wrap_alpha"]

_FIELD = 7
_PER_LINE = 9
_BLOCKS = ("CL", "CD", "CM")


def wrap_alpha(alpha_deg):
    """Wrap angles in degrees to [-180, 180) (array in, array out; NaN stays NaN)."""
    a = np.asarray(alpha_deg, dtype=float)
    if a.size and a.min() >= -180.0 and a.max() < 180.0:  # common case: already wrapped
        return a
    return np.mod(a + 180.0, 360.0) - 180.0


class Bracket:
    """Fast location of points in a strictly increasing grid, clamped at the ends.

    ``locate(x)`` returns ``(i, t)`` with ``0 <= i <= len(grid) - 2`` and ``t`` in [0, 1] such
    that linear interpolation is ``(1 - t) * v[i] + t * v[i + 1]``. A uniform lookup table of
    bins no wider than the smallest grid spacing replaces a binary search (each bin holds at
    most one grid point), which is several times faster than ``np.searchsorted`` on 1e6 points.

    Parameters
    ----------
    grid : array_like, shape (m,)
        Strictly increasing grid, m >= 1.
    """

    _MAX_BINS = 1 << 20

    def __init__(self, grid):
        g = np.asarray(grid, dtype=float)
        if g.ndim != 1 or g.size < 1 or not np.all(np.isfinite(g)):
            raise ParameterError("grid must be a non-empty 1-D array of finite numbers")
        if g.size > 1 and np.any(np.diff(g) <= 0):
            raise ParameterError("grid must be strictly increasing")
        self.grid = g
        self._lut = None
        if g.size == 1:
            return
        self._inv_dx = 1.0 / np.diff(g)
        # Right neighbour used to step past a grid point inside a bin; +inf at the last point
        # keeps the interval index <= m - 2.
        self._next = np.append(g[1:-1], np.inf)
        span = g[-1] - g[0]
        nbins = int(math.ceil(span / float(np.min(np.diff(g))))) + 1
        if nbins > self._MAX_BINS:
            return
        self._x0 = g[0]
        self._inv_h = nbins / span
        starts = g[0] + np.arange(nbins + 1) / self._inv_h
        # Interval index of the start of each bin; the bin may still hold one more grid point.
        self._lut = np.clip(np.searchsorted(g, starts, side="right") - 1, 0, g.size - 2)
        self._nbins = nbins

    def locate(self, x):
        """Interval index and weight of each point of ``x`` (any shape); NaN gives t = NaN."""
        x = np.asarray(x, dtype=float)
        shape = x.shape
        x = x.ravel()
        g = self.grid
        if g.size == 1:
            return np.zeros(shape, dtype=np.intp), np.zeros(shape)
        inside = x.size > 0 and x.min() >= g[0] and x.max() <= g[-1]  # False if any NaN
        if self._lut is None:
            i = np.clip(np.searchsorted(g, x, side="right") - 1, 0, g.size - 2)
        else:
            b = x - self._x0
            b *= self._inv_h
            if not inside:
                np.fmax(b, 0.0, out=b)  # fmax/fmin also map NaN to a valid bin
                np.fmin(b, self._nbins, out=b)
            i = np.take(self._lut, b.astype(np.intp))
            np.take(self._next, i, out=b)
            i += x >= b
        t = np.take(g, i)
        np.subtract(x, t, out=t)
        t *= np.take(self._inv_dx, i)
        if not inside:
            np.maximum(t, 0.0, out=t)
            np.minimum(t, 1.0, out=t)
        return i.reshape(shape), t.reshape(shape)


def _readonly(a):
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class C81Block:
    """One coefficient block of a C81 table.

    Attributes
    ----------
    mach : ndarray, shape (nm,)
        Strictly increasing Mach numbers.
    alpha : ndarray, shape (na,)
        Strictly increasing angles of attack, degrees.
    values : ndarray, shape (na, nm)
        Coefficient at each (alpha, Mach).
    """

    mach: np.ndarray
    alpha: np.ndarray
    values: np.ndarray

    def __post_init__(self):
        m, a, v = _readonly(self.mach), _readonly(self.alpha), _readonly(self.values)
        if m.ndim != 1 or a.ndim != 1 or m.size < 1 or a.size < 1:
            raise ParameterError("mach and alpha must be non-empty 1-D arrays")
        if v.shape != (a.size, m.size):
            raise ParameterError(
                f"values must have shape (len(alpha), len(mach)) = {(a.size, m.size)}, "
                f"got {v.shape}"
            )
        if np.any(np.diff(m) <= 0) or np.any(np.diff(a) <= 0):
            raise ParameterError("mach and alpha must be strictly increasing")
        if not (np.all(np.isfinite(m)) and np.all(np.isfinite(a)) and np.all(np.isfinite(v))):
            raise ParameterError("C81 block entries must be finite")
        object.__setattr__(self, "mach", m)
        object.__setattr__(self, "alpha", a)
        object.__setattr__(self, "values", v)

    def interpolate(self, alpha_deg, mach):
        """Coefficient at the given angles (deg) and Mach numbers, MBDyn ``aerodc81`` semantics.

        ``alpha_deg`` and ``mach`` broadcast against each other; the result has the broadcast
        shape. Alpha is wrapped to [-180, 180), Mach taken in absolute value, bilinear inside
        the grid, clamped outside it.

        Parameters
        ----------
        alpha_deg : array_like
            Angles of attack, deg.
        mach : array_like
            Mach numbers.
        """
        a, m = np.broadcast_arrays(np.asarray(alpha_deg, float), np.asarray(mach, float))
        return self.interpolate_unwrapped(wrap_alpha(a), np.abs(m))

    def interpolate_unwrapped(self, alpha_deg, mach):
        """Bilinear, clamped interpolation without wrapping alpha or taking |Mach|.

        Parameters
        ----------
        alpha_deg : array_like
            Angles of attack, deg, within the table's range (not wrapped).
        mach : array_like
            Mach numbers (broadcast against ``alpha_deg``).
        """
        a, m = np.broadcast_arrays(np.asarray(alpha_deg, float), np.asarray(mach, float))
        ia, t = Bracket(self.alpha).locate(a)
        im, s = Bracket(self.mach).locate(m)
        v = self.values
        ia1 = np.minimum(ia + 1, v.shape[0] - 1)
        im1 = np.minimum(im + 1, v.shape[1] - 1)
        lo = (1 - t) * v[ia, im] + t * v[ia1, im]
        hi = (1 - t) * v[ia, im1] + t * v[ia1, im1]
        return (1 - s) * lo + s * hi


@dataclass(frozen=True, eq=False)
class C81Table:
    """A C81 airfoil table: title and the CL, CD and CM blocks.

    Parameters
    ----------
    title : str
        The table's title (the first 30 characters of a C81 file's first line).
    cl, cd, cm : C81Block
        Lift, drag and pitching-moment coefficients over angle of attack and Mach number.
    """

    title: str
    cl: C81Block
    cd: C81Block
    cm: C81Block

    def blocks(self) -> dict[str, C81Block]:
        """The blocks by name, ``{"CL": ..., "CD": ..., "CM": ...}``."""
        return {"CL": self.cl, "CD": self.cd, "CM": self.cm}

    def __eq__(self, other):
        if not isinstance(other, C81Table):
            return NotImplemented
        return self.title == other.title and all(
            np.array_equal(getattr(x, f), getattr(y, f))
            for x, y in zip(self.blocks().values(), other.blocks().values(), strict=True)
            for f in ("mach", "alpha", "values")
        )

    __hash__ = None  # type: ignore[assignment]  # equal tables compare equal: unhashable


# --------------------------------------------------------------------------------------------
# reading


class _Lines:
    """Line cursor that reports 1-based line numbers and raises on a premature end of file."""

    def __init__(self, path, lines):
        self.path = path
        self.lines = lines
        self.pos = 0

    def next(self, expected):
        if self.pos >= len(self.lines):
            raise InputFileError(self.path, len(self.lines) + 1, expected, "end of file")
        self.pos += 1
        return self.lines[self.pos - 1]

    @property
    def lineno(self):
        return self.pos


def _to_float(text):
    """A finite number (Fortran 'D' exponents accepted); ValueError otherwise."""
    v = float(text.strip().replace("D", "E").replace("d", "e"))
    if not math.isfinite(v):
        raise ValueError(f"non-finite {text!r}")
    return v


def _field(path, lineno, line, k, what):
    """Field k (0-based) of a fixed-format line, as a float."""
    start = _FIELD * k
    raw = line[start : start + _FIELD]
    try:
        if not raw.strip():
            raise ValueError
        return _to_float(raw)
    except ValueError:
        raise InputFileError(
            path, lineno, f"{what} (a finite number) in columns {start + 1}-{start + _FIELD}",
            raw,
        ) from None


def _read_values(cur, line, n, what):
    """n values from fields 1..9 of ``line`` and of continuation lines (blank columns 1-7)."""
    out = []
    k = 1
    while len(out) < n:
        if k > _PER_LINE:
            line = cur.next(f"a continuation line of {what}")
            if line[:_FIELD].strip():
                raise InputFileError(
                    cur.path, cur.lineno,
                    f"blank columns 1-7 on a continuation line of {what} "
                    f"(check the counts in the header)",
                    line[:_FIELD],
                )
            k = 1
        out.append(_field(cur.path, cur.lineno, line, k, f"value {len(out) + 1} of {what}"))
        k += 1
    return out


def _check_increasing(path, linenos, values, what):
    for j in range(1, len(values)):
        if not values[j] > values[j - 1]:
            raise InputFileError(
                path, linenos[j],
                f"{what} strictly increasing (greater than {values[j - 1]!r})", repr(values[j]),
            )


def _read_fixed_block(cur, name, nm, na):
    line = cur.next(f"the Mach row of the {name} block")
    if line[:_FIELD].strip():
        raise InputFileError(
            cur.path, cur.lineno,
            f"blank columns 1-7 before the Mach numbers of the {name} block "
            f"(check the counts in the header)",
            line[:_FIELD],
        )
    mach_line = cur.lineno
    mach = _read_values(cur, line, nm, f"the Mach row of the {name} block")
    _check_increasing(cur.path, [mach_line] * nm, mach, f"Mach numbers of the {name} block")
    alpha, rows, linenos = [], [], []
    for r in range(na):
        what = f"alpha row {r + 1} of {na} of the {name} block"
        line = cur.next(what)
        linenos.append(cur.lineno)
        alpha.append(_field(cur.path, cur.lineno, line, 0, f"the angle of attack of {what}"))
        vals = _read_values(cur, line, nm, what)
        rows.append(vals)
    _check_increasing(cur.path, linenos, alpha, f"angles of attack of the {name} block")
    return C81Block(np.array(mach), np.array(alpha), np.array(rows))


def _parse_fixed_counts(header):
    counts = []
    for k in range(6):
        raw = header[30 + 2 * k : 32 + 2 * k]
        try:
            counts.append(int(raw))
        except ValueError:
            return None
    return counts if all(c > 0 for c in counts) else None


def _parse_free_counts(header):
    if ";" not in header:
        return None
    title, _, rest = header.partition(";")
    parts = rest.split()
    if len(parts) != 6:
        return None
    try:
        counts = [int(p) for p in parts]
    except ValueError:
        return None
    return (title.strip(), counts) if all(c > 0 for c in counts) else None


def _read_free(path, lines, start):
    if start >= len(lines):
        raise InputFileError(path, start + 1, "a free-format header 'title; ML NL MD ND MM NM' "
                             "after '# FREE FORMAT'", "end of file")
    header = lines[start]
    parsed = _parse_free_counts(header)
    if parsed is None:
        raise InputFileError(
            path, start + 1,
            "a free-format header 'title; ML NL MD ND MM NM' with six positive integers", header,
        )
    title, counts = parsed
    tokens = []  # (value, line number)
    for j in range(start + 1, len(lines)):
        for tok in lines[j].split():
            try:
                tokens.append((_to_float(tok), j + 1))
            except ValueError:
                raise InputFileError(path, j + 1, "a finite number", tok) from None
    pos = 0

    def take(n, what):
        nonlocal pos
        if pos + n > len(tokens):
            raise InputFileError(path, len(lines) + 1, what, "end of file")
        chunk = tokens[pos : pos + n]
        pos += n
        return chunk

    blocks = []
    for b, name in enumerate(_BLOCKS):
        nm, na = counts[2 * b], counts[2 * b + 1]
        mach = take(nm, f"{nm} Mach numbers of the {name} block")
        _check_increasing(path, [t[1] for t in mach], [t[0] for t in mach],
                          f"Mach numbers of the {name} block")
        alpha, rows, linenos = [], [], []
        for r in range(na):
            row = take(nm + 1, f"alpha row {r + 1} of {na} of the {name} block ({nm + 1} numbers)")
            alpha.append(row[0][0])
            linenos.append(row[0][1])
            rows.append([t[0] for t in row[1:]])
        _check_increasing(path, linenos, alpha, f"angles of attack of the {name} block")
        blocks.append(C81Block(np.array([t[0] for t in mach]), np.array(alpha), np.array(rows)))
    if pos != len(tokens):
        raise InputFileError(path, tokens[pos][1], "end of file after the CM block",
                             repr(tokens[pos][0]))
    return C81Table(title, *blocks)


def read_c81(path) -> C81Table:
    """Read a C81 airfoil table (fixed or free format).

    Parameters
    ----------
    path : str or PathLike
        The file. The free format is recognised by a first line ``# FREE FORMAT`` or by a
        header of the form ``title; ML NL MD ND MM NM`` whose columns 31-42 are not six
        2-character counts.

    Returns
    -------
    C81Table

    Raises
    ------
    InputFileError
        Naming the file, the line and what was expected there.

    Examples
    --------
    >>> from importlib.resources import files
    >>> table = read_c81(files("rotoruq") / "data" / "airfoils" / "naca0012.c81")
    >>> table.cl.values.shape == (table.cl.alpha.size, table.cl.mach.size)    # (na, nm)
    True
    """
    path = os.fspath(path)
    try:
        text = Path(path).read_text(encoding="ascii", errors="replace")
    except OSError as exc:
        raise InputFileError(path, None, "a readable C81 file", str(exc)) from None
    lines = text.splitlines()
    if not lines:
        raise InputFileError(path, 1, "a C81 header", "empty file")
    if lines[0].strip().upper().startswith("# FREE FORMAT"):
        return _read_free(path, lines, 1)
    counts = _parse_fixed_counts(lines[0])
    if counts is None:
        if _parse_free_counts(lines[0]) is not None:
            return _read_free(path, lines, 0)
        raise InputFileError(
            path, 1,
            "six positive 2-character counts ML NL MD ND MM NM in columns 31-42 "
            "(header format A30,6I2)",
            lines[0][30:42],
        )
    cur = _Lines(path, lines)
    cur.next("the header")
    blocks = [
        _read_fixed_block(cur, name, counts[2 * b], counts[2 * b + 1])
        for b, name in enumerate(_BLOCKS)
    ]
    for j in range(cur.pos, len(lines)):
        if lines[j].strip():
            raise InputFileError(
                path, j + 1, "end of file after the CM block (check the counts in the header)",
                lines[j],
            )
    return C81Table(lines[0][:30].rstrip(), *blocks)


# --------------------------------------------------------------------------------------------
# writing


def format_field(x: float, width: int = _FIELD) -> str:
    """Shortest exact text of ``x`` within ``width`` characters, else the most precise one.

    Leading zeros are dropped (``.0125``, ``-.5``) as in classic C81 files; exponent notation
    (``1.2e-5``) is used when it is more precise than fixed notation.
    """
    x = float(x)
    if not math.isfinite(x):
        raise ParameterError(f"cannot write a non-finite value {x!r} to a C81 file")
    if x == 0.0:
        return "0."

    def squeeze(s):
        if "e" in s:
            mant, exp = s.split("e")
            exp = str(int(exp))
            s = f"{mant}e{exp}"
        if s.startswith("0."):
            s = s[1:]
        elif s.startswith("-0."):
            s = "-" + s[2:]
        elif "." not in s and "e" not in s:
            s += "."
        if s.endswith(".0") and s[-3:-2].isdigit():
            s = s[:-1]
        if s in (".", "-.", ".0", "-.0", "-0."):
            s = "0."
        return s

    exact = squeeze(repr(x))
    if len(exact) <= width and float(exact) == x:
        return exact
    best, err = None, math.inf
    for d in range(width, -1, -1):
        for s in (squeeze(f"{x:.{d}f}"), squeeze(f"{x:.{d}e}")):
            if len(s) <= width:
                e = abs(float(s) - x)
                if e < err:
                    best, err = s, e
    if best is None:
        raise ParameterError(f"value {x!r} does not fit a {width}-character C81 field")
    return best


def _fixed_row(first: str, values) -> list[str]:
    out = []
    vals = [format_field(v) for v in values]
    for k in range(0, max(len(vals), 1), _PER_LINE):
        lead = first if k == 0 else ""
        out.append(lead.ljust(_FIELD) + "".join(v.ljust(_FIELD) for v in vals[k : k + 9]))
    return [s.rstrip() for s in out]


def write_c81(table: C81Table, path, free_format: bool = False) -> Path:
    """Write a C81 table.

    Parameters
    ----------
    table : C81Table
        The table to write.
    path : str or PathLike
        The file to write (its folder must exist).
    free_format : bool
        False (default) writes the fixed format (7-character fields, values that do not fit
        are rounded to the most precise 7-character text, see :func:`format_field`; counts
        must be <= 99). True writes MBDyn's free format with full double precision.

    Returns
    -------
    Path of the written file.

    Examples
    --------
    The free format keeps every value to the last bit:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from importlib.resources import files
    >>> table = read_c81(files("rotoruq") / "data" / "airfoils" / "naca23012.c81")
    >>> path = write_c81(table, Path(tempfile.mkdtemp()) / "t.c81", free_format=True)
    >>> read_c81(path) == table
    True
    """
    path = Path(path)
    blocks = list(table.blocks().values())
    counts = []
    for b in blocks:
        counts += [b.mach.size, b.alpha.size]
    lines = []
    if free_format:
        lines.append("# FREE FORMAT")
        lines.append(f"{table.title.replace(';', ',')}; " + " ".join(map(str, counts)))
        for b in blocks:
            lines.append(" ".join(repr(float(m)) for m in b.mach))
            for a, row in zip(b.alpha, b.values, strict=True):
                lines.append(" ".join(repr(float(v)) for v in (a, *row)))
    else:
        if max(counts) > 99:
            raise ParameterError(
                f"the fixed C81 format holds at most 99 Mach numbers or angles per block "
                f"(counts {counts}); use free_format=True"
            )
        lines.append(table.title[:30].ljust(30) + "".join(f"{c:2d}" for c in counts))
        for b in blocks:
            lines += _fixed_row("", b.mach)
            for a, row in zip(b.alpha, b.values, strict=True):
                lines += _fixed_row(format_field(a), row)
    # never through a link planted at its name (an evaluation's folder: the MBDyn driver)
    return write_file(path, ("\n".join(lines) + "\n").encode("ascii"))
