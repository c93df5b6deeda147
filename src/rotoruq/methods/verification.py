"""Solution verification: Roache's grid convergence index (GCI) and Richardson extrapolation.

A response f is computed on grids refined by a ratio r (grid 1 the finest, 2, 3 coarser:
h2 = r21 h1, h3 = r32 h2). With three grids the observed order p solves (Celik et al. 2008,
J. Fluids Eng. 130, 078001, eqs. 3-5)

    p = |ln|e32 / e21| + q(p)| / ln r21,   q(p) = ln((r21^p - s) / (r32^p - s)),
    s = sign(e32 / e21),  e21 = f2 - f1,  e32 = f3 - f2

(q = 0 for a constant ratio: the closed form), the Richardson extrapolation is
f_ext = (r21^p f1 - f2) / (r21^p - 1), and the fine-grid index is (Roache 1994, 1998)

    GCI_fine = Fs |e21 / f1| / (r21^p - 1)

with the safety factor Fs = 1.25 for three grids (observed order) and Fs = 3 for two grids
(the order assumed: the scheme's formal order). The asymptotic-range check: Roache's ratio
GCI_32 / (r21^p GCI_21) is about 1 in the asymptotic range; with a constant ratio and the
observed order it is |f1 / f2| by construction, so it tests little: the grids are judged in the
asymptotic range when, in addition, the convergence is monotone (e21 and e32 of one sign,
|e21| < |e32|) and, when the formal order is given, the observed order is within the
tolerance of it.

**u_num.** Following ASME V&V 20-2009, the GCI is read as an expanded uncertainty whose
coverage factor is the safety factor, so the standard numerical uncertainty is u_num = GCI / Fs, in
response units |f1| GCI_fine / Fs = |f2 - f1| / (r21^p - 1): the magnitude of the Richardson
error estimate. This module takes that convention (``u_num`` fields); a more conservative
reader can use the GCI itself (``gci_fine`` times |f1|).

>>> res = grid_convergence_index(1.0 + 0.01, 1.0 + 0.04, 1.0 + 0.16, ratio=2.0)
>>> round(float(res.observed_order), 6), round(float(res.extrapolated), 6)
(2.0, 1.0)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import EvaluationError, ParameterError
from ..model import Model, evaluate

__all__ = ["GCIResult", "GridConvergenceArrays", "GRID_FIELDS", "VerificationResult",
           "grid_convergence_index", "verify_discretization"]

#: Roache's safety factors: three grids (observed order), two grids (assumed order).
SAFETY_FACTOR_THREE_GRIDS = 1.25
SAFETY_FACTOR_TWO_GRIDS = 3.0


@dataclass(frozen=True, eq=False)
class GCIResult:
    """Grid convergence index of a response (every array broadcast to one shape).

    Attributes
    ----------
    fine, medium, coarse : f1, f2, f3 (coarse is NaN with two grids).
    ratio, ratio_coarse : r21 = h2/h1, r32 = h3/h2 (> 1).
    observed_order : p (with two grids: the assumed order).
    extrapolated : Richardson extrapolation f_ext of f1, f2.
    relative_error : e_a21 = |(f1 - f2) / f1|.
    extrapolated_relative_error : e_ext21 = |(f_ext - f1) / f_ext|.
    gci_fine : Fs e_a21 / (r21^p - 1), relative to |f1| (a fraction, not a percentage).
    gci_medium : Fs e_a32 / (r32^p - 1), relative to |f2| (NaN with two grids).
    asymptotic_ratio : gci_medium / (r21^p gci_fine), Roache's check (about 1).
    in_asymptotic_range : |asymptotic_ratio - 1| <= the tolerance, monotone convergence and,
        with a formal order, |p - formal_order| <= tolerance * formal_order (False with two
        grids: nothing is observed).
    converging : |e21| < |e32| (three grids; True with two grids: it cannot be tested).
    oscillatory : e32 / e21 < 0.
    safety_factor : Fs.
    u_num : |f1| gci_fine / Fs, response units (the V&V 20 convention, see the module).
    n_grids : 2 or 3.
    """

    fine: np.ndarray
    medium: np.ndarray
    coarse: np.ndarray
    ratio: float
    ratio_coarse: float
    observed_order: np.ndarray
    extrapolated: np.ndarray
    relative_error: np.ndarray
    extrapolated_relative_error: np.ndarray
    gci_fine: np.ndarray
    gci_medium: np.ndarray
    asymptotic_ratio: np.ndarray
    in_asymptotic_range: np.ndarray
    converging: np.ndarray
    oscillatory: np.ndarray
    safety_factor: float
    u_num: np.ndarray
    n_grids: int


def _ratio(name: str, r: Any) -> float:
    try:
        v = float(r)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number > 1, got {r!r}") from None
    if not np.isfinite(v) or v <= 1.0:
        raise ParameterError(f"{name} (refinement ratio h_coarse / h_fine) must be > 1, got {r!r}")
    return v


def _observed_order(e21, e32, r21, r32, max_iterations=200):
    """Celik's fixed-point iteration (closed form when r21 == r32); NaN where undefined."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = e32 / e21
        s = np.sign(ratio)
        lnr = np.log(np.abs(ratio))
        p = np.abs(lnr) / np.log(r21)
        if r21 != r32:
            for _ in range(max_iterations):
                q = np.log((r21**p - s) / (r32**p - s))
                p_new = np.abs(lnr + q) / np.log(r21)
                done = ~(np.abs(p_new - p) > 1e-12 * np.maximum(1.0, np.abs(p_new)))
                p = p_new
                if done.all():
                    break
    return np.where(np.isfinite(p) & (p > 0), p, np.nan)


def grid_convergence_index(
    fine: npt.ArrayLike,
    medium: npt.ArrayLike,
    coarse: npt.ArrayLike | None = None,
    *,
    ratio: float,
    ratio_coarse: float | None = None,
    formal_order: float | None = None,
    safety_factor: float | None = None,
    asymptotic_tolerance: float = 0.1,
) -> GCIResult:
    """Roache's grid convergence index from two or three systematically refined solutions.

    Parameters
    ----------
    fine, medium, coarse : array_like
        f1, f2, f3 on grids 1 (finest), 2 and 3 (coarsest), broadcast together; without
        ``coarse`` the two-grid index with the assumed ``formal_order``.
    ratio : float, > 1
        r21 = h2 / h1 (e.g. 2 for doubled azimuth steps and stations).
    ratio_coarse : float, > 1, optional
        r32 = h3 / h2 (default: ``ratio``, a constant refinement).
    formal_order : float, > 0, optional
        The scheme's order; required with two grids (it is the order used); with three grids
        the observed order is compared with it in the asymptotic-range check.
    safety_factor : float, optional
        Fs (default 1.25 with three grids, 3 with two).
    asymptotic_tolerance : float
        Relative tolerance of the asymptotic-range check (Roache's ratio against 1, the
        observed order against the formal order).

    Returns
    -------
    GCIResult

    Examples
    --------
    Celik et al. (2008), table 1, first column (r21 = 1.5, r32 = 4/3):

    >>> res = grid_convergence_index(6.063, 5.972, 5.863, ratio=1.5, ratio_coarse=4 / 3)
    >>> round(float(res.observed_order), 2), round(100 * float(res.gci_fine), 1)
    (1.53, 2.2)
    """
    r21 = _ratio("ratio", ratio)
    r32 = r21 if ratio_coarse is None else _ratio("ratio_coarse", ratio_coarse)
    f1, f2 = np.asarray(fine, dtype=float), np.asarray(medium, dtype=float)
    three = coarse is not None
    f3 = np.asarray(coarse, dtype=float) if three else np.full_like(f1 * f2, np.nan)
    try:
        f1, f2, f3 = np.broadcast_arrays(f1, f2, f3)
    except ValueError:
        raise ParameterError(f"fine {f1.shape}, medium {f2.shape} and coarse {f3.shape} must "
                             "broadcast to one shape") from None
    if not (np.isfinite(f1).all() and np.isfinite(f2).all()
            and (not three or np.isfinite(f3).all())):
        raise ParameterError("grid_convergence_index needs finite solutions on every grid")
    if formal_order is not None and (not np.isfinite(formal_order) or formal_order <= 0):
        raise ParameterError(f"formal_order must be > 0, got {formal_order}")
    if not three and formal_order is None:
        raise ParameterError("two grids need the scheme's formal_order (the order is assumed, "
                             "Fs = 3); give a third grid to observe it")
    fs = float(safety_factor) if safety_factor is not None else (
        SAFETY_FACTOR_THREE_GRIDS if three else SAFETY_FACTOR_TWO_GRIDS)
    if not np.isfinite(fs) or fs < 1.0:
        raise ParameterError(f"safety_factor must be >= 1, got {safety_factor}")
    e21, e32 = f2 - f1, f3 - f2
    if three:
        p = _observed_order(e21, e32, r21, r32)
    else:
        p = np.full(f1.shape, float(formal_order))  # type: ignore[arg-type]
    with np.errstate(divide="ignore", invalid="ignore"):
        rp = r21**p
        ext = np.where(e21 == 0, f1, (rp * f1 - f2) / (rp - 1.0))
        ea21 = np.abs(e21 / f1)
        e_ext = np.where(e21 == 0, 0.0, np.abs((ext - f1) / ext))
        gci21 = np.where(e21 == 0, 0.0, fs * ea21 / (rp - 1.0))
        u_num = np.where(e21 == 0, 0.0, np.abs(e21) / (rp - 1.0))
        if three:
            gci32 = fs * np.abs(e32 / f2) / (r32**p - 1.0)
            asym = gci32 / (rp * gci21)
            converging = np.abs(e21) < np.abs(e32)
            oscillatory = e32 * e21 < 0
        else:
            gci32 = asym = np.full(f1.shape, np.nan)
            converging = np.ones(f1.shape, bool)
            oscillatory = np.zeros(f1.shape, bool)
    in_range = (np.abs(asym - 1.0) <= asymptotic_tolerance) & converging & ~oscillatory
    if three and formal_order is not None:
        in_range &= np.abs(p - formal_order) <= asymptotic_tolerance * formal_order
    return GCIResult(
        fine=f1, medium=f2, coarse=f3, ratio=r21, ratio_coarse=r32, observed_order=p,
        extrapolated=ext, relative_error=ea21, extrapolated_relative_error=e_ext,
        gci_fine=gci21, gci_medium=gci32, asymptotic_ratio=asym,
        in_asymptotic_range=np.asarray(in_range), converging=np.asarray(converging),
        oscillatory=np.asarray(oscillatory), safety_factor=fs, u_num=u_num,
        n_grids=3 if three else 2)


@dataclass(frozen=True, eq=False)
class GridConvergenceArrays:
    """The grid-convergence numbers of several points, arrays (n_points, n_responses): the
    fields a :class:`VerificationResult` and the verification step's record share.

    Attributes
    ----------
    observed_order, extrapolated, gci_fine, u_num, asymptotic_ratio : ndarray
        As in :class:`GCIResult` (response units for ``extrapolated`` and ``u_num``).
    in_asymptotic_range, converging, oscillatory : ndarray
        As in :class:`GCIResult`, boolean (1.0 / 0.0 in a saved record).
    """

    observed_order: np.ndarray
    extrapolated: np.ndarray
    gci_fine: np.ndarray
    u_num: np.ndarray
    asymptotic_ratio: np.ndarray
    in_asymptotic_range: np.ndarray
    converging: np.ndarray
    oscillatory: np.ndarray


#: The names of :class:`GridConvergenceArrays`' fields, in order.
GRID_FIELDS = tuple(f.name for f in fields(GridConvergenceArrays))


@dataclass(frozen=True, eq=False)
class VerificationResult(GridConvergenceArrays):
    """Solution verification of a model at chosen points; arrays are (n_points, n_responses).

    Attributes
    ----------
    names_in, names_out : the model's input and response names.
    levels : the discretization levels, finest first.
    x : (n_points, n_inputs) the points.
    values : (n_levels, n_points, n_responses) the responses on each level.
    observed_order, extrapolated, gci_fine, u_num, asymptotic_ratio, in_asymptotic_range,
    converging, oscillatory : as in :class:`GCIResult`.
    ratio, ratio_coarse, safety_factor : as in :class:`GCIResult`.
    n_evaluations : model evaluations spent (n_levels x n_points).
    """

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    levels: tuple
    x: np.ndarray
    values: np.ndarray
    ratio: float
    ratio_coarse: float
    safety_factor: float
    n_evaluations: int


def verify_discretization(
    model_factory: Callable[[Any], Model],
    levels: Sequence[Any],
    x: npt.ArrayLike,
    *,
    ratio: float,
    ratio_coarse: float | None = None,
    formal_order: float | None = None,
    safety_factor: float | None = None,
    asymptotic_tolerance: float = 0.1,
) -> VerificationResult:
    """Grid convergence of a model: build it at each discretization level and compare.

    Parameters
    ----------
    model_factory : callable level -> Model
        Builds the model at a discretization level: a rotor at given azimuth steps and
        stations (:class:`rotoruq.rotor.discretization.RotorDiscretization`), or an external model
        whose template takes the level as a field.
    levels : sequence of 2 or 3 levels, finest first
        Passed one by one to ``model_factory``; consecutive levels must differ by ``ratio``
        (then ``ratio_coarse``) in grid spacing.
    x : array_like, (n_points, n_inputs)
        The points, in the models' ``names_in`` order.
    ratio, ratio_coarse, formal_order, safety_factor, asymptotic_tolerance
        As in :func:`grid_convergence_index`.

    Returns
    -------
    VerificationResult

    Raises
    ------
    ParameterError
        Wrong number of levels, a ratio <= 1, models with different names.
    EvaluationError
        A point failed on some level (its reason is named).

    Examples
    --------
    A trapezoidal integral of exp over [0, 1] with n intervals (second order):

    >>> import numpy as np
    >>> from rotoruq.model import FunctionModel
    >>> def factory(n):
    ...     def f(x):
    ...         t = np.linspace(0.0, 1.0, n + 1)
    ...         return np.trapezoid(np.exp(x[:, :1] * t), t, axis=1)[:, None]
    ...     return FunctionModel(f, names_in=["a"], names_out=["integral"])
    >>> res = verify_discretization(factory, [40, 20, 10], [[1.0]], ratio=2.0)
    >>> round(float(res.observed_order[0, 0]), 2)
    2.0
    """
    levels = tuple(levels)
    if len(levels) not in (2, 3):
        raise ParameterError(f"verify_discretization needs 2 or 3 levels (finest first), got "
                             f"{len(levels)}")
    _ratio("ratio", ratio)
    if ratio_coarse is not None:
        _ratio("ratio_coarse", ratio_coarse)
    pts = np.atleast_2d(np.asarray(x, dtype=float))
    if pts.ndim != 2:
        raise ParameterError(f"x must be (n_points, n_inputs), got shape {pts.shape}")
    values = []
    names_in: tuple[str, ...] = ()
    names_out: tuple[str, ...] = ()
    for k, level in enumerate(levels):
        model = model_factory(level)
        n_in, n_out = tuple(model.names_in), tuple(model.names_out)
        if k == 0:
            names_in, names_out = n_in, n_out
            if pts.shape[1] != len(names_in):
                raise ParameterError(f"x has {pts.shape[1]} columns, the model takes "
                                     f"{len(names_in)} inputs {names_in}")
        elif (n_in, n_out) != (names_in, names_out):
            raise ParameterError(f"the model at level {level!r} has inputs {n_in} and responses "
                                 f"{n_out}; the first level's are {names_in} and {names_out}")
        batch = evaluate(model, pts)
        if batch.failures:
            i, why = sorted(batch.failures.items())[0]
            raise EvaluationError(f"discretization level {level!r}: point {i} ({pts[i]}) "
                                  f"failed: {why} ({len(batch.failures)} failed points)")
        values.append(np.asarray(batch.values, dtype=float))
    vals = np.stack(values)
    g = grid_convergence_index(vals[0], vals[1], vals[2] if len(levels) == 3 else None,
                               ratio=ratio, ratio_coarse=ratio_coarse,
                               formal_order=formal_order, safety_factor=safety_factor,
                               asymptotic_tolerance=asymptotic_tolerance)
    return VerificationResult(
        names_in=names_in, names_out=names_out, levels=levels, x=pts, values=vals,
        observed_order=g.observed_order, extrapolated=g.extrapolated, gci_fine=g.gci_fine,
        u_num=g.u_num, asymptotic_ratio=g.asymptotic_ratio,
        in_asymptotic_range=g.in_asymptotic_range, converging=g.converging,
        oscillatory=g.oscillatory, ratio=g.ratio, ratio_coarse=g.ratio_coarse,
        safety_factor=g.safety_factor, n_evaluations=int(vals.shape[0] * vals.shape[1]))
