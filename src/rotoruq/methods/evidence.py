"""Dempster-Shafer evidence theory for epistemic (:class:`~rotoruq.params.Interval`) inputs.

Every input has intervals with basic probability assignments (BPAs). A *cell* is one choice
of interval per input (cartesian product); its BPA is the product of the inputs' BPAs. On
each cell the response range [min, max] is found by efficient global optimization on one
Gaussian process over all cells (``optimizer="ego"``, the default, as Dakota's
``global_evidence ego``: see :mod:`rotoruq.methods.ego`), or estimated by sampling (all cells
in ONE batched model call) and refined by bound-constrained local optimization
(``optimizer="sampling"``: L-BFGS-B from the best samples), so that interior extrema of
non-monotone responses are found.

Cumulative belief and plausibility of a response level z (thesis section 2.3.4):

* ``CBF(z) = Bel(g <= z) = sum of BPAs of cells with max <= z``
* ``CPF(z) = Pl(g <= z)  = sum of BPAs of cells with min <= z``

and complementary ``CCBF(z) = Bel(g > z) = 1 - CPF(z)``, ``CCPF(z) = Pl(g > z) = 1 - CBF(z)``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from .._rng import SeedLike, as_generator
from ..errors import ParameterError
from ..model import Model
from ..params import Interval, ParameterSpace, unit_design
from ._common import eval_space, levels_per_response

__all__ = ["EvidenceResult", "evidence"]


def _starts(x, v, width, n):
    """Up to n start points: the best samples by v, each at least a quarter of the cell's
    (scaled) diagonal away from the previous ones, so the starts cover distinct basins."""
    order = [i for i in np.argsort(np.where(np.isfinite(v), v, np.inf)) if np.isfinite(v[i])]
    xn = x / width
    chosen: list[int] = []
    for i in order:
        if all(np.linalg.norm(xn[i] - xn[j]) > 0.25 * np.sqrt(x.shape[1]) for j in chosen):
            chosen.append(i)
            if len(chosen) == n:
                break
    return x[chosen]


def _refine(model, space, xs, y, lo, hi, cmin, cmax, n_starts, rel_step=1e-7):
    """Local min and max of every response in every cell by L-BFGS-B from the best samples.

    xs : (c, per, d) sampled points; y : (c, per, m) their responses; lo, hi : (c, d).
    Each objective call evaluates the point and its d forward-difference neighbours (steps
    taken inward at the cell's upper bound) in one batch. Returns (cmin, cmax, evaluations).
    """
    from scipy.optimize import minimize

    n_cells, _, d = xs.shape
    m = y.shape[2]
    cmin, cmax = cmin.copy(), cmax.copy()
    count = [0]

    def fg(xx, k, sign, c):
        h = rel_step * np.maximum(np.abs(xx), hi[c] - lo[c])
        h = np.where(xx + h > hi[c], -h, h)
        pts = np.repeat(xx[None, :], d + 1, axis=0)
        pts[1 + np.arange(d), np.arange(d)] += h
        v = eval_space(model, space, pts).values[:, k]
        count[0] += d + 1
        if not np.all(np.isfinite(v)):
            return np.inf, np.zeros(d)
        return sign * v[0], sign * (v[1:] - v[0]) / h

    for c in range(n_cells):
        bounds = list(zip(lo[c], hi[c], strict=True))
        for k in range(m):
            for sign in (1.0, -1.0):
                yk = sign * y[c, :, k]
                if not np.any(np.isfinite(yk)):
                    continue
                for start in _starts(xs[c], yk, (hi[c] - lo[c]), n_starts):
                    r = minimize(fg, start, args=(k, sign, c), jac=True, method="L-BFGS-B",
                                 bounds=bounds)
                    if np.isfinite(r.fun):
                        if sign > 0:
                            cmin[c, k] = min(cmin[c, k], r.fun)
                        else:
                            cmax[c, k] = max(cmax[c, k], -r.fun)
    return cmin, cmax, count[0]


@dataclass(frozen=True, eq=False)
class EvidenceResult:
    """Belief and plausibility of response levels.

    The inputs' intervals combine into c cells (one interval of each input); a cell's BPA is
    the product of its intervals' BPAs.

    Attributes
    ----------
    names_in, names_out : tuple of str
        The d input and m response names.
    cells_lower, cells_upper : ndarray of shape (c, d)
        The cells' bounds, input units.
    cell_bpa : ndarray of shape (c,)
        Basic probability assignment of each cell.
    cell_min, cell_max : ndarray of shape (c, m)
        The response's range over each cell, response units.
    response_levels : dict of str to ndarray
        Response name -> the levels z.
    cbf, cpf : dict of str to ndarray
        Response name -> cumulative belief Bel(g <= z) and plausibility Pl(g <= z) at its
        levels.
    ccbf, ccpf : dict of str to ndarray
        Response name -> complementary belief Bel(g > z) and plausibility Pl(g > z).
    n_evaluations : int
        Model evaluations (points).
    optimizer : str
        ``"ego"`` or ``"sampling"``: how the cell ranges were found.
    converged : bool
        False when EGO stopped at its evaluation budget before every cell's expected
        improvement fell below the tolerance.
    """

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    cells_lower: np.ndarray
    cells_upper: np.ndarray
    cell_bpa: np.ndarray
    cell_min: np.ndarray
    cell_max: np.ndarray
    response_levels: dict
    cbf: dict
    cpf: dict
    ccbf: dict
    ccpf: dict
    n_evaluations: int
    optimizer: str = "sampling"
    converged: bool = True

    def belief_plausibility(self, name: str, z) -> tuple[np.ndarray, np.ndarray]:
        """(Bel(g <= z), Pl(g <= z)) for response ``name`` at levels z.

        Parameters
        ----------
        name : str
            A response name.
        z : float or array_like
            Levels, response units; each result has shape (len(z),).
        """
        k = self.names_out.index(name)
        z = np.atleast_1d(np.asarray(z, dtype=float))
        bel = (self.cell_bpa[None, :] * (self.cell_max[:, k][None, :] <= z[:, None])).sum(1)
        pl = (self.cell_bpa[None, :] * (self.cell_min[:, k][None, :] <= z[:, None])).sum(1)
        return bel, pl


def evidence(
    model: Model,
    space: ParameterSpace,
    *,
    response_levels=None,
    optimizer: str = "ego",
    n_samples: int | None = None,
    optimize: bool = True,
    n_starts: int = 3,
    tolerance: float = 1e-4,
    max_evaluations: int | None = None,
    seed: SeedLike = None,
) -> EvidenceResult:
    """Dempster-Shafer belief/plausibility of response levels.

    Parameters
    ----------
    model : Model; inputs matched by name.
    space : ParameterSpace whose inputs are all :class:`Interval`.
    response_levels : levels z (same for every response, mapping, or one sequence each).
    optimizer : "ego" (default): efficient global optimization of every cell's min and max on
        one Gaussian process over the whole interval box, refined where any cell's extreme
        is uncertain, until every cell's expected improvement (divided by the response's
        observed range) is below ``tolerance``; each new point is one model call (sequential,
        for expensive models). "sampling": the sampling + local search below.
    n_samples : "ego": size of the initial Latin hypercube over the whole box (default
        ``(d + 1)(d + 2) / 2``, Dakota's). "sampling": LHS points per cell (default 100; the
        cell's corners are added); all cells go to the model in one batch of
        c * (n_samples + 2^d) points (corners only up to d = 10).
    optimize : refine each cell's min and max with L-BFGS-B from the best sample (default;
        each function value and its forward-difference gradient is one batched model call of
        d + 1 points). Without it the range is that of the samples and corners only, which
        misses interior extrema of non-monotone responses (no error bound): use
        ``optimize=False`` only for responses known to be monotone in every cell.
    n_starts : local searches per cell, response and direction, started from the best
        samples that lie in different parts of the cell (multimodal responses). Local
        optimization finds the global extremum of a cell only when one start lies in its
        basin: more samples and starts raise that chance, no setting guarantees it.
    tolerance, max_evaluations : "ego" only: the stopping expected improvement (relative to
        the response's range) and the evaluation budget (default ``100 (d + 1)`` per
        response; a ``RuntimeWarning`` and ``converged=False`` when it is reached).
    seed : int or Generator.

    Returns
    -------
    EvidenceResult

    Examples
    --------
    >>> import rotoruq as rq
    >>> sp = rq.ParameterSpace({"a": rq.Interval([(0.0, 1.0), (1.0, 3.0)], [0.4, 0.6])})
    >>> m = rq.FunctionModel(lambda x: (x[:, 0] - 0.5) ** 2, ["a"], ["g"])
    >>> r = evidence(m, sp, response_levels=[0.1], seed=1)
    >>> r.cbf["g"], r.cpf["g"]  # only the first cell's range [0, 0.25] reaches below 0.1
    (array([0.]), array([0.4]))
    """
    intervals = [dd for dd in space.distributions if isinstance(dd, Interval)]
    bad = [
        n
        for n, dd in zip(space.names, space.distributions, strict=True)
        if not isinstance(dd, Interval)
    ]
    if bad:
        raise ParameterError(f"evidence needs Interval inputs; not intervals: {bad}")
    if space.correlation is not None:
        raise ParameterError("evidence does not take correlated inputs")
    if optimizer not in ("ego", "sampling"):
        raise ParameterError(f"evidence optimizer must be 'ego' or 'sampling', got "
                             f"{optimizer!r}")
    if n_samples is not None and int(n_samples) < (2 if optimizer == "ego" else 1):
        raise ParameterError(f"n_samples must be >= {2 if optimizer == 'ego' else 1}, got "
                             f"{n_samples}")
    if optimizer == "sampling" and optimize and int(n_starts) < 1:
        raise ParameterError(f"n_starts must be >= 1, got {n_starts}")
    d = space.dim
    rng = as_generator(seed)
    ivs = [np.array(dd.intervals) for dd in intervals]
    bpas = [np.array(dd.bpa) for dd in intervals]
    combos = list(itertools.product(*[range(len(b)) for b in bpas]))
    lo = np.array([[ivs[j][c[j], 0] for j in range(d)] for c in combos])
    hi = np.array([[ivs[j][c[j], 1] for j in range(d)] for c in combos])
    bpa = np.array([np.prod([bpas[j][c[j]] for j in range(d)]) for c in combos])
    n_cells = len(combos)
    names_out = tuple(model.names_out)
    converged = True
    if optimizer == "ego":
        from .ego import box_extremes

        box = box_extremes(
            lambda xx: eval_space(model, space, xx).values, lo, hi, n_initial=n_samples,
            tolerance=tolerance,
            max_evaluations=(100 * (d + 1) * len(names_out) if max_evaluations is None
                             else int(max_evaluations)),
            seed=rng)
        cmin, cmax, n_eval, converged = box.minimum, box.maximum, box.n_evaluations, box.converged
    else:
        cmin, cmax, n_eval = _sample_and_refine(model, space, lo, hi, n_cells, d, 100 if
                                                n_samples is None else int(n_samples),
                                                optimize, n_starts, rng)
    return _result(space, names_out, response_levels, lo, hi, bpa, cmin, cmax, n_eval, optimizer,
                   converged)


def _sample_and_refine(model, space, lo, hi, n_cells, d, n_samples, optimize, n_starts, rng):
    unit = unit_design(int(n_samples), d, design="lhs", seed=rng)
    if d <= 10:
        unit = np.vstack([unit, np.array(list(itertools.product([0.0, 1.0], repeat=d)))])
    per = unit.shape[0]
    x = (lo[:, None, :] + unit[None, :, :] * (hi - lo)[:, None, :]).reshape(-1, d)
    batch = eval_space(model, space, x)
    y = batch.values.reshape(n_cells, per, -1)
    with np.errstate(invalid="ignore"):
        cmin = np.nanmin(np.where(np.isfinite(y), y, np.nan), axis=1)
        cmax = np.nanmax(np.where(np.isfinite(y), y, np.nan), axis=1)
    n_eval = x.shape[0]
    if optimize:
        cmin, cmax, extra = _refine(model, space, x.reshape(n_cells, per, d), y, lo, hi,
                                    cmin, cmax, int(n_starts))
        n_eval += extra
    return cmin, cmax, n_eval


def _result(space, names_out, response_levels, lo, hi, bpa, cmin, cmax, n_eval, optimizer,
            converged):
    rl = levels_per_response(response_levels, names_out, "response_levels")
    cbf, cpf, ccbf, ccpf = {}, {}, {}, {}
    for k, name in enumerate(names_out):
        z = rl[name]
        cbf[name] = (bpa[None, :] * (cmax[:, k][None, :] <= z[:, None])).sum(axis=1)
        cpf[name] = (bpa[None, :] * (cmin[:, k][None, :] <= z[:, None])).sum(axis=1)
        ccbf[name] = 1.0 - cpf[name]
        ccpf[name] = 1.0 - cbf[name]
    return EvidenceResult(
        names_in=space.names,
        names_out=names_out,
        cells_lower=lo,
        cells_upper=hi,
        cell_bpa=bpa,
        cell_min=cmin,
        cell_max=cmax,
        response_levels=rl,
        cbf=cbf,
        cpf=cpf,
        ccbf=ccbf,
        ccpf=ccpf,
        n_evaluations=int(n_eval),
        optimizer=optimizer,
        converged=bool(converged),
    )
