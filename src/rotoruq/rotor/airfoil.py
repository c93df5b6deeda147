"""Airfoil coefficients with per-sample perturbations of the linear/quadratic fits.

The reference study (thesis sections 3.1.1 and 4.2.1) fits, at chosen Mach rows of a C81 table
and over alpha in [-10, 10] deg (alpha in degrees),

    CL = cla * alpha + cl0,        CD = cda2 * alpha**2 + cda * alpha + cd0,

and treats these coefficients as uncertain; its ``airfoil.py`` rewrote the C81 file with the
perturbed fits for every sample. :class:`Airfoil` does the same without files: inside the window
|alpha| <= W the rows at the fit Mach numbers are replaced by the polynomials, either nominal
(the least-squares fits) or per sample (``overrides``), and everything else comes from the
table. Coefficients are then linear in Mach between the union of table and fit Mach rows.

Parameter names: ``<coef>_m<digits>`` with ``<coef>`` in ``cla`` (1/deg), ``cl0``, ``cda2``
(1/deg^2), ``cda`` (1/deg), ``cd0`` and the Mach row written without its decimal point (see
:func:`mach_suffix`): ``cla_m03`` is the CL slope at Mach 0.3.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from .._docs import fill_doc
from ..errors import ModelShapeError, ParameterError
from .c81 import Bracket, C81Block, C81Table, read_c81, wrap_alpha, write_c81

__all__ = [
    "FIT_COEFFICIENTS",
    "Airfoil",
    "AirfoilFit",
    "fit_airfoil",
    "mach_suffix",
    "parameter_name",
    "parse_parameter_name",
    "write_perturbed_c81",
    "BUNDLED_AIRFOILS",
]

#: The fit coefficients, in the order used internally.
FIT_COEFFICIENTS = ("cla", "cl0", "cda2", "cda", "cd0")
#: Names of the airfoil tables shipped in ``rotoruq/data/airfoils``.
BUNDLED_AIRFOILS = ("naca0012", "naca23012")

_NAME_RE = re.compile(r"^(cla|cl0|cda2|cda|cd0)_m(\d)(\d+)$")
_TOL = 1e-9
_CHUNK = 1 << 14


def mach_suffix(mach: float) -> str:
    """Suffix of a Mach row in parameter names: 0 -> "m00", 0.3 -> "m03", 0.75 -> "m075".

    The integer digit followed by the decimals, at least one (1.0 -> "m10"); at most 6
    decimals; 0 <= mach < 10.
    """
    m = float(mach)
    if not (0.0 <= m < 10.0):
        raise ParameterError(f"Mach row must be in [0, 10) to be named, got {mach!r}")
    text = f"{m:.6f}".rstrip("0")
    whole, frac = text.split(".")
    if abs(float(text) - m) > 1e-12:
        raise ParameterError(f"Mach row {mach!r} has more than 6 decimals")
    return "m" + whole + (frac or "0")


def parameter_name(coef: str, mach: float) -> str:
    """``parameter_name("cla", 0.3) == "cla_m03"``."""
    if coef not in FIT_COEFFICIENTS:
        raise ParameterError(f"unknown fit coefficient {coef!r}; valid: {FIT_COEFFICIENTS}")
    return f"{coef}_{mach_suffix(mach)}"


def parse_parameter_name(name: str) -> tuple[str, float]:
    """``parse_parameter_name("cda2_m075") == ("cda2", 0.75)``; ParameterError if malformed."""
    m = _NAME_RE.match(name)
    if m is None:
        raise ParameterError(
            f"{name!r} is not an airfoil parameter name; expected <coef>_m<digits> with coef in "
            f"{', '.join(FIT_COEFFICIENTS)} (e.g. cla_m03 for Mach 0.3, cd0_m075 for Mach 0.75)"
        )
    return m.group(1), float(f"{m.group(2)}.{m.group(3)}")


# --------------------------------------------------------------------------------------------
# fits


@dataclass(frozen=True, eq=False)
class AirfoilFit:
    """Least-squares fits of CL (linear) and CD (quadratic) in alpha (deg) per Mach row.

    Attributes
    ----------
    machs : ndarray, shape (k,)
    cla : ndarray, shape (k,)
        CL slope, 1/deg.
    cl0 : ndarray, shape (k,)
        CL at alpha = 0.
    cda2, cda, cd0 : ndarray, shape (k,)
        CD = cda2 alpha^2 + cda alpha + cd0 (1/deg^2, 1/deg, -).
    alpha_range : tuple of float
        The fitted window, deg.
    n_points_cl, n_points_cd : ndarray of int, shape (k,)
        Number of table points used in each fit.
    """

    machs: np.ndarray
    cla: np.ndarray
    cl0: np.ndarray
    cda2: np.ndarray
    cda: np.ndarray
    cd0: np.ndarray
    alpha_range: tuple[float, float] = (-10.0, 10.0)
    n_points_cl: np.ndarray | None = field(default=None)
    n_points_cd: np.ndarray | None = field(default=None)

    def coefficients(self) -> np.ndarray:
        """Array of shape (k, 5): columns cla, cl0, cda2, cda, cd0."""
        return np.stack([getattr(self, c) for c in FIT_COEFFICIENTS], axis=1)

    def as_dict(self) -> dict[str, float]:
        """Parameter name -> value, e.g. ``{"cla_m03": 0.108, ...}``."""
        return {
            parameter_name(c, m): float(getattr(self, c)[k])
            for k, m in enumerate(self.machs)
            for c in FIT_COEFFICIENTS
        }

    def to_text(self) -> str:
        """The fits as the thesis's tables 4.3/4.4 (one row per Mach number)."""
        head = f"{'Mach':>6} {'CL_alpha':>10} {'CL0':>10} {'CD_alpha2':>11} {'CD_alpha':>11} " \
               f"{'CD0':>9}"
        rows = [head, "-" * len(head)]
        def fmt(v, spec):
            text = format(0.0 if abs(v) < 1e-12 else v, spec)
            return text.replace("-", " ", 1) if float(text) == 0.0 and "-" in text else text

        for k, m in enumerate(self.machs):
            v = [getattr(self, c)[k] for c in FIT_COEFFICIENTS]
            rows.append(
                f"{m:6.3g} {fmt(v[0], '10.4f')} {fmt(v[1], '10.4f')} {fmt(v[2], '11.4e')} "
                f"{fmt(v[3], '11.3e')} {fmt(v[4], '9.4f')}"
            )
        rows.append(f"(alpha in deg, fitted over {self.alpha_range[0]:g}..{self.alpha_range[1]:g}"
                    f" deg on the table's own alpha points)")
        return "\n".join(rows)


def _column_at(block: C81Block, mach: float) -> np.ndarray:
    """Block values at its own alpha points, linearly interpolated (clamped) in Mach."""
    return block.interpolate_unwrapped(block.alpha, np.full(block.alpha.shape, float(mach)))


def fit_airfoil(table: C81Table, machs=None, alpha_range=(-10.0, 10.0)) -> AirfoilFit:
    """Fit CL = cla*alpha + cl0 and CD = cda2*alpha^2 + cda*alpha + cd0 per Mach row.

    Like Matlab's ``polyfit`` in the reference study: ordinary least squares on the table's own
    alpha points within ``alpha_range`` (inclusive, deg). For a Mach number that is not a row
    of the block, the block's columns are first interpolated linearly in Mach (clamped).

    Parameters
    ----------
    table : C81Table
    machs : array_like of float, optional
        Mach rows to fit; default: the Mach rows of the CL block.
    alpha_range : (float, float)
        Window in degrees.

    Returns
    -------
    AirfoilFit

    Examples
    --------
    A table built from CL = 0.1 alpha + 0.2 and CD = 0.01 + 1e-4 alpha^2 (alpha in deg) at two
    Mach rows; the fits recover the coefficients:

    >>> import numpy as np
    >>> from rotoruq.rotor.c81 import C81Block, C81Table
    >>> alpha, mach = np.arange(-10.0, 11.0), np.array([0.2, 0.4])     # (21,), (2,)
    >>> ones = np.ones((alpha.size, mach.size))
    >>> table = C81Table("linear", C81Block(mach, alpha, (0.1 * alpha + 0.2)[:, None] * ones),
    ...                  C81Block(mach, alpha, (0.01 + 1e-4 * alpha**2)[:, None] * ones),
    ...                  C81Block(mach, alpha, 0.0 * ones))
    >>> fit = fit_airfoil(table)
    >>> np.round(fit.cla, 10).tolist(), np.round(fit.cl0, 10).tolist()      # 1/deg, -
    ([0.1, 0.1], [0.2, 0.2])
    >>> np.round(fit.cda2, 12).tolist(), np.round(fit.cd0, 12).tolist()     # 1/deg^2, -
    ([0.0001, 0.0001], [0.01, 0.01])
    """
    lo, hi = (float(alpha_range[0]), float(alpha_range[1]))
    if not hi > lo:
        raise ParameterError(f"alpha_range must be increasing, got {alpha_range!r}")
    ms = np.atleast_1d(np.asarray(table.cl.mach if machs is None else machs, dtype=float))
    if ms.ndim != 1 or ms.size == 0 or np.any(ms < 0) or not np.all(np.isfinite(ms)):
        raise ParameterError(f"machs must be a non-empty list of Mach numbers >= 0, got {machs!r}")
    if np.unique(ms).size != ms.size:
        raise ParameterError(f"machs has repeated values: {ms.tolist()}")
    out = {c: np.empty(ms.size) for c in FIT_COEFFICIENTS}
    npts = {}
    for name, block, deg, coefs in (
        ("CL", table.cl, 1, ("cla", "cl0")),
        ("CD", table.cd, 2, ("cda2", "cda", "cd0")),
    ):
        sel = (block.alpha >= lo - _TOL) & (block.alpha <= hi + _TOL)
        if sel.sum() < deg + 1:
            raise ParameterError(
                f"the {name} block has {sel.sum()} alpha points in [{lo:g}, {hi:g}] deg; "
                f"a degree-{deg} fit needs at least {deg + 1}"
            )
        npts[name] = np.full(ms.size, int(sel.sum()))
        for k, m in enumerate(ms):
            p = np.polyfit(block.alpha[sel], _column_at(block, m)[sel], deg)
            for c, v in zip(coefs, p, strict=True):
                out[c][k] = v
    return AirfoilFit(ms, **out, alpha_range=(lo, hi),
                      n_points_cl=npts["CL"], n_points_cd=npts["CD"])


# --------------------------------------------------------------------------------------------
# the airfoil


#: the fit settings that :meth:`Airfoil.from_c81` and :meth:`Airfoil.bundled` pass on
_FIT_SETTINGS = """
fit_machs : array_like of float, optional
    Mach rows replaced by the fits (default: the CL block's rows <= 0.6); see
    :class:`Airfoil`.
alpha_window : float, optional
    Half-width of the fit window, deg (default 10).
fit_mode : bool, optional
    True (default): the fit rows are replaced by the fits; False: the raw table.
replace : tuple of str, optional
    The coefficients the fits replace, ``("cl", "cd")`` (default) or ``("cl",)``.
"""


class Airfoil:
    """C81 aerodynamics with the thesis's fit-row replacement and per-sample perturbations.

    Parameters
    ----------
    table : C81Table
        The airfoil's tables (CL, CD, CM over angle of attack and Mach number).
    fit_machs : array_like of float, optional
        Mach rows whose CL and CD are replaced inside the window by the fits (they become the
        parameters ``cla_mXX``, ``cl0_mXX``, ``cda2_mXX``, ``cda_mXX``, ``cd0_mXX``). A Mach
        number that is not a table row is inserted as a new row. Default: the CL block's
        Mach rows <= 0.6 (the range fitted in the reference study).
    alpha_window : float
        Half-width W of the window |alpha| <= W (deg) where the fits replace the table; the
        fits are made over [-W, W] as well.
    fit_mode : bool
        True (default): rows at ``fit_machs`` are replaced by the fits (the nominal model is the
        rewritten table of the reference study). False: the raw table, MBDyn semantics, no
        parameters.
    replace : ("cl", "cd") or ("cl",)
        Which coefficients the fits replace. The thesis's Bo105 study rewrote CL only (its
        parameters are CL slopes); the GVPM study rewrote CL and CD. With ("cl",) the drag
        names ``cda2_mXX``, ``cda_mXX``, ``cd0_mXX`` are not parameters.

    Notes
    -----
    At a fit row, the value is the polynomial for |alpha| <= W; between W and the next table
    angle beyond it the row goes linearly from the polynomial's value at W to the table (as a
    rewritten C81 file would, so CL and CD stay continuous); further out it is the table.
    Between Mach rows (table rows and fit rows alike) coefficients are linear in Mach, clamped
    outside; alpha is wrapped to [-180, 180); the Mach number is taken in absolute value.
    """

    def __init__(self, table: C81Table, fit_machs=None, alpha_window: float = 10.0,
                 fit_mode: bool = True, replace: tuple[str, ...] = ("cl", "cd")):
        if not isinstance(table, C81Table):
            raise ParameterError(f"table must be a C81Table, got {type(table).__name__}")
        w = float(alpha_window)
        if not (0.0 < w < 180.0):
            raise ParameterError(f"alpha_window must be in (0, 180) deg, got {alpha_window!r}")
        self._table = table
        self._window = w
        self._fit_mode = bool(fit_mode)
        if not self._fit_mode:
            machs = np.empty(0)
        elif fit_machs is None:
            machs = table.cl.mach[table.cl.mach <= 0.6 + _TOL]
        else:
            machs = np.sort(np.atleast_1d(np.asarray(fit_machs, dtype=float)))
        self._nominal: AirfoilFit | None
        if machs.size:
            self._nominal = fit_airfoil(table, machs, (-w, w))
            machs = self._nominal.machs
        else:
            self._nominal = None
        self._fit_machs = machs
        bad = sorted(set(replace) - {"cl", "cd"})
        if bad or "cl" not in replace:
            raise ParameterError(f"replace must be ('cl',) or ('cl', 'cd'), got {replace!r}")
        self._replace_cd = "cd" in replace
        names = [parameter_name(c, m) for m in machs for c in FIT_COEFFICIENTS]
        self._name_index = {n: (j // 5, j % 5) for j, n in enumerate(names)
                            if self._replace_cd or j % 5 < 2}
        self._names = list(self._name_index)
        self._build_grid()
        self._kernel_table: Any = None   # the compiled solve's form (rotor.hover.airfoil_table)

    def identity(self) -> dict:
        """Everything that sets the coefficients: the table's numbers and the fit settings."""
        t = self._table
        return {"cl": [t.cl.alpha, t.cl.mach, t.cl.values], "cd": [t.cd.alpha, t.cd.mach,
                t.cd.values], "cm": [t.cm.alpha, t.cm.mach, t.cm.values],
                "window": self._window, "fit_mode": self._fit_mode,
                "fit_machs": self._fit_machs, "replace_cd": self._replace_cd}

    # ---- construction helpers

    @classmethod
    @fill_doc(fit_settings=_FIT_SETTINGS)
    def from_c81(cls, path_or_table, fit_machs=None, alpha_window: float = 10.0,
                 fit_mode: bool = True, replace: tuple[str, ...] = ("cl", "cd")) -> Airfoil:
        """Airfoil from a C81 file path or a :class:`C81Table`.

        Parameters
        ----------
        path_or_table : str, PathLike or C81Table
            The C81 file (fixed or free format) or a table read already.
        %(fit_settings)s
        """
        table = path_or_table if isinstance(path_or_table, C81Table) else read_c81(path_or_table)
        return cls(table, fit_machs=fit_machs, alpha_window=alpha_window, fit_mode=fit_mode,
                   replace=replace)

    @classmethod
    @fill_doc(fit_settings=_FIT_SETTINGS)
    def bundled(cls, name: str, fit_machs=None, alpha_window: float = 10.0,
                fit_mode: bool = True, replace: tuple[str, ...] = ("cl", "cd")) -> Airfoil:
        """Airfoil from a table shipped with rotoruq: ``"naca0012"`` or ``"naca23012"``.

        Parameters
        ----------
        name : str
            ``"naca0012"`` or ``"naca23012"`` (a ``.c81`` suffix and the case are ignored).
        %(fit_settings)s
        """
        return cls(read_bundled(name), fit_machs=fit_machs, alpha_window=alpha_window,
                   fit_mode=fit_mode, replace=replace)

    def _build_grid(self):
        t, w = self._table, self._window
        blocks = (t.cl, t.cd, t.cm)
        alphas = [b.alpha for b in blocks]
        machs = [b.mach for b in blocks] + [self._fit_machs]
        if self._fit_machs.size:
            alphas.append(np.array([-w, w]))
        ga = _union(np.concatenate(alphas))
        gm = _union(np.concatenate(machs))
        # A single row or column is padded with a clamped copy so every cell has 2 x 2 corners.
        if ga.size == 1:
            ga = np.append(ga, ga[0] + 1.0)
        if gm.size == 1:
            gm = np.append(gm, gm[0] + 1.0)
        A, M = np.meshgrid(ga, gm, indexing="ij")
        # Bilinear interpolation on the union grid reproduces each block's own bilinear
        # interpolation exactly (every block is bilinear on each cell of the finer grid).
        raw = np.stack([b.interpolate_unwrapped(A, M) for b in blocks], axis=-1)
        self._ga, self._gm = ga, gm
        self._ba, self._bm = Bracket(ga), Bracket(gm)
        inwin = np.abs(ga) <= w + _TOL
        self._h = inwin.astype(float)
        fitcol = np.full(gm.size, -1)
        for k, m in enumerate(self._fit_machs):
            fitcol[np.argmin(np.abs(gm - m))] = k
        self._fitcol = fitcol
        mod = raw.copy()
        for j in np.flatnonzero(fitcol >= 0):
            mod[inwin, j, : 2 if self._replace_cd else 1] = 0.0
        self._raw_cols = [np.ascontiguousarray(raw[..., c].ravel()) for c in range(3)]
        self._mod_cols = [np.ascontiguousarray(mod[..., c].ravel()) for c in range(3)]
        self._coef_cols = self._coef_table(None)

    def _coef_table(self, values):
        """Per-column fit coefficients, shape (5, n * nm) (zeros at non-fit columns).

        ``values`` is None (nominal, n = 1) or an array (n, k, 5) of coefficients at fit rows.
        """
        if values is None:
            values = (self._nominal.coefficients()[None] if self._nominal is not None
                      else np.zeros((1, 0, 5)))
        out = np.zeros((values.shape[0], self._gm.size, 5))
        cols = np.flatnonzero(self._fitcol >= 0)
        out[:, cols, :] = values[:, self._fitcol[cols], :]
        return np.ascontiguousarray(np.moveaxis(out, 2, 0).reshape(5, -1))

    # ---- properties

    @property
    def table(self) -> C81Table:
        """The underlying C81 table."""
        return self._table

    @property
    def fit_machs(self) -> np.ndarray:
        """Mach rows replaced by fits, shape (k,) (empty when ``fit_mode`` is False)."""
        return self._fit_machs.copy()

    @property
    def alpha_window(self) -> float:
        """Half-width of the fit window, deg."""
        return self._window

    @property
    def fit_mode(self) -> bool:
        """Whether the fit rows are replaced by the fits (False: the raw table)."""
        return self._fit_mode

    @property
    def nominal(self) -> AirfoilFit | None:
        """The least-squares fits at ``fit_machs`` (None when there are none)."""
        return self._nominal

    @property
    def parameter_names(self) -> list[str]:
        """Every name accepted in ``overrides``: 5 per fit Mach row."""
        return list(self._names)

    @property
    def mach_range(self) -> tuple[float, float]:
        """Smallest and largest Mach number of the table (coefficients are clamped outside)."""
        return float(self._gm[0]), float(self._gm[-1])

    def stall_angles(self, mach):
        """Positive and negative stall angles [deg] at ``mach``, each of its shape.

        The angles of the largest and smallest CL of the nominal airfoil within +-30 deg,
        linear in Mach between the table's rows.

        Parameters
        ----------
        mach : array_like
            Mach numbers (any shape).
        """
        if not hasattr(self, "_stall"):
            ga = self._ga
            A, M = np.meshgrid(ga, self._gm, indexing="ij")
            cl = self.coefficients(A, M)[0]
            pos = np.where((ga >= 0) & (ga <= 30.0))[0]
            neg = np.where((ga <= 0) & (ga >= -30.0))[0]
            a_pos = ga[pos][np.argmax(cl[pos], axis=0)]
            a_neg = ga[neg][np.argmin(cl[neg], axis=0)]
            self._stall = (a_pos, a_neg)
        m = np.asarray(mach, dtype=float)
        return (np.interp(m, self._gm, self._stall[0]), np.interp(m, self._gm, self._stall[1]))

    def nominal_values(self) -> dict[str, float]:
        """Parameter name -> nominal (fitted) value."""
        return {} if self._nominal is None else self._nominal.as_dict()

    # ---- evaluation

    def _override_values(self, overrides, lead):
        """Fit coefficients per sample, shape (n, k, 5), from the overrides."""
        unknown = [n for n in overrides if n not in self._name_index]
        if unknown:
            valid = ", ".join(self._names) if self._names else "(none: no fit Mach rows)"
            raise ParameterError(
                f"unknown airfoil parameter(s) {', '.join(map(repr, unknown))}; valid names: "
                f"{valid}"
            )
        arrays = {n: np.asarray(v, dtype=float) for n, v in overrides.items()}
        sizes = {a.size for a in arrays.values() if a.ndim > 0}
        for n, a in arrays.items():
            if a.ndim > 1:
                raise ModelShapeError(f"override {n!r} must be a scalar or shape (n,), "
                                      f"got shape {a.shape}")
        if len(sizes) > 1:
            raise ModelShapeError(f"overrides have different lengths {sorted(sizes)}")
        n = sizes.pop() if sizes else 1
        if n > 1 and lead != n:
            raise ModelShapeError(
                f"overrides have {n} samples but alpha/mach have leading axis {lead}"
            )
        vals = np.broadcast_to(self._nominal.coefficients(), (n, *self._nominal.cla.shape, 5))
        vals = vals.copy()
        for name, a in arrays.items():
            k, c = self._name_index[name]
            vals[:, k, c] = a
        return vals

    def coefficients(self, alpha_deg, mach, overrides=None):
        """Lift, drag and moment coefficients.

        Parameters
        ----------
        alpha_deg : array_like
            Angle of attack, deg; any shape when ``overrides`` is None, else shape (n, ...)
            with the sample axis first.
        mach : array_like
            Mach number, broadcastable with ``alpha_deg``.
        overrides : dict[str, float or array of shape (n,)], optional
            Per-sample values of fit coefficients (names in :attr:`parameter_names`); the
            others keep their nominal values.

        Returns
        -------
        cl, cd, cm : ndarray
            Each of the broadcast shape of ``alpha_deg`` and ``mach``.
        """
        a, m = np.broadcast_arrays(np.asarray(alpha_deg, float), np.asarray(mach, float))
        shape = a.shape
        a = np.ascontiguousarray(a).ravel()
        m = np.ascontiguousarray(m).ravel()
        coef, per = None, 0
        if self._nominal is not None:
            coef = self._coef_cols
            if overrides:
                vals = self._override_values(overrides, shape[0] if len(shape) else 1)
                if vals.shape[0] > 1:
                    coef = self._coef_table(vals)
                    per = a.size // vals.shape[0]
                else:
                    coef = self._coef_table(vals)
        out = np.empty((3, a.size))
        # Chunks small enough to stay in cache: far fewer page faults and memory passes.
        for start in range(0, a.size, _CHUNK):
            stop = min(start + _CHUNK, a.size)
            self._eval_chunk(a[start:stop], m[start:stop], coef, per, start,
                             out[:, start:stop])
        return out[0].reshape(shape), out[1].reshape(shape), out[2].reshape(shape)

    def _eval_chunk(self, a, m, coef, per, start, out):
        a = wrap_alpha(a)
        m = np.abs(m)
        ia, t = self._ba.locate(a)
        im, s = self._bm.locate(m)
        nm = self._gm.size
        idx = ia * nm
        idx += im
        tables = self._raw_cols if coef is None else self._mod_cols
        tmp = np.empty_like(t)
        hi = np.empty_like(t)
        for k, v in enumerate(tables):
            lo = out[k]
            # Shifted views instead of shifted index arrays: v[nm:][idx] == v[idx + nm].
            np.take(v, idx, out=lo)
            np.take(v[nm:], idx, out=tmp)
            tmp -= lo
            tmp *= t
            lo += tmp
            np.take(v[1:], idx, out=hi)
            np.take(v[nm + 1 :], idx, out=tmp)
            tmp -= hi
            tmp *= t
            hi += tmp
            hi -= lo
            hi *= s
            lo += hi
        if coef is None:
            return
        if per:
            cidx = np.arange(start, start + a.size)
            cidx //= per
            cidx *= nm
            cidx += im
        else:
            cidx = im
        h = np.take(self._h, ia)
        np.take(self._h[1:], ia, out=tmp)
        tmp -= h
        tmp *= t
        h += tmp
        ac = np.clip(a, -self._window, self._window)
        c = []
        for col in coef:
            ci = np.take(col, cidx)
            np.take(col[1:], cidx, out=tmp)
            tmp -= ci
            tmp *= s
            ci += tmp
            c.append(ci)
        poly = c[0] * ac
        poly += c[1]
        poly *= h
        out[0] += poly
        if not self._replace_cd:
            return
        np.multiply(c[2], ac, out=poly)
        poly += c[3]
        poly *= ac
        poly += c[4]
        poly *= h
        out[1] += poly

    # ---- perturbed tables for external solvers

    def perturbed_table(self, overrides: dict[str, float] | None = None,
                        title: str | None = None) -> C81Table:
        """The C81 table with the window rewritten by the (perturbed) fits at the fit rows.

        Fit Mach numbers that are not rows of the CL/CD blocks are inserted, and the angles
        -W and +W are inserted if missing, so that an external solver interpolating the file
        (MBDyn semantics) sees the same CL as :meth:`coefficients`, and the same CD at the
        table's angles (between them a solver sees CD's quadratic as a polygon). An airfoil
        whose fits replace CL only (``replace=("cl",)``) keeps the table's CD block.

        Parameters
        ----------
        overrides : dict of str to float, optional
            Values of fit parameters (``cla_m03``, ... of :attr:`parameter_names`) in place of
            the nominal fits; None: the nominal fits.
        title : str, optional
            The new table's title (default: the original table's).
        """
        if self._nominal is None:
            raise ParameterError("this Airfoil has no fit Mach rows (fit_mode=False or empty)")
        vals = self._override_values(dict(overrides or {}), 1)[0] if overrides \
            else self._nominal.coefficients()
        w = self._window
        new = {"cd": self._table.cd}  # kept as tabulated unless the fits replace CD too
        blocks = [("cl", self._table.cl, slice(0, 2))]
        if self._replace_cd:
            blocks.append(("cd", self._table.cd, slice(2, 5)))
        for name, block, sl in blocks:
            ga = _union(np.concatenate([block.alpha, [-w, w]]))
            gm = _union(np.concatenate([block.mach, self._fit_machs]))
            A, M = np.meshgrid(ga, gm, indexing="ij")
            v = block.interpolate_unwrapped(A, M)
            inwin = np.abs(ga) <= w + _TOL
            for k, mk in enumerate(self._fit_machs):
                j = int(np.argmin(np.abs(gm - mk)))
                v[inwin, j] = np.polyval(vals[k, sl], ga[inwin])
            new[name] = C81Block(gm, ga, v)
        return C81Table(self._table.title if title is None else title, new["cl"], new["cd"],
                        self._table.cm)


def _union(x):
    """Sorted unique values, merging values closer than 1e-9."""
    x = np.sort(np.asarray(x, dtype=float))
    keep = np.concatenate([[True], np.diff(x) > _TOL])
    return x[keep]


def read_bundled(name: str) -> C81Table:
    """A C81 table shipped with rotoruq (``"naca0012"`` or ``"naca23012"``)."""
    key = name.lower().removesuffix(".c81")
    if key not in BUNDLED_AIRFOILS:
        raise ParameterError(f"unknown bundled airfoil {name!r}; available: {BUNDLED_AIRFOILS}")
    ref = resources.files("rotoruq") / "data" / "airfoils" / f"{key}.c81"
    with resources.as_file(ref) as p:
        return read_c81(p)


def write_perturbed_c81(airfoil: Airfoil, overrides: dict[str, float] | None, path,
                        free_format: bool = False) -> Path:
    """Write ``airfoil.perturbed_table(overrides)`` as a C81 file (for external solvers).

    Parameters
    ----------
    airfoil : Airfoil
        The airfoil, with fit Mach rows.
    overrides : dict of str to float or None
        Values of its fit parameters (``cla_m03``, ...); None: the nominal fits.
    path : str or PathLike
        The file to write.
    free_format : bool, optional
        False (default): the fixed C81 format; True: MBDyn's free format, full precision.

    Returns
    -------
    Path
        The c81 file written (``path``).

    Examples
    --------
    The bundled NACA 0012 with its lift slope at M = 0.3 raised to 0.11 /deg, for a solver that
    reads c81 files:

    >>> import tempfile
    >>> from pathlib import Path
    >>> path = write_perturbed_c81(Airfoil.bundled("naca0012"), {"cla_m03": 0.11},
    ...                            Path(tempfile.mkdtemp()) / "perturbed.c81")
    >>> round(Airfoil.from_c81(path).nominal_values()["cla_m03"], 6)
    0.11
    """
    return write_c81(airfoil.perturbed_table(overrides), path, free_format=free_format)
