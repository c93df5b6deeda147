"""Level mappings (Dakota's ``response_levels``, ``probability_levels``,
``reliability_levels``, ``gen_reliability_levels``): the one home of the mappings between
response levels z and probabilities p, reliability indices beta and generalized reliability
indices beta* that sampling, mean value, reliability, PCE and evidence report.

Conventions (Dakota's, ``distribution cumulative`` / ``complementary``):

* CDF: ``p = P(g <= z)``, ``beta = (mean - z) / std``; CCDF: ``p = P(g > z)``,
  ``beta = (z - mean) / std``; both ``beta* = -Phi^-1(p)``, ``p = Phi(-beta*)``.
* Levels are sorted as Dakota sorts them: response levels ascending; probability levels
  ascending for a CDF, descending for a CCDF; (generalized) reliability levels descending for
  a CDF, ascending for a CCDF. Rows come in that order: response, probability, reliability,
  generalized reliability levels.

From samples (:func:`sample_mappings`, Dakota's ``NonDSampling``): z -> p is the fraction of
the finite samples with ``g <= z`` (CCDF: ``1 -`` that, the fraction with ``g > z``); z -> beta
projects the moments (sample mean and std, ddof 1, unless given); p -> z interpolates the
sorted samples s_1 <= ... <= s_N at ``i = p_cdf N`` (``z = s_k + (i - k)(s_{k+1} - s_k)``,
``k = floor(i)``, ``z = s_N`` at ``k = N``; below ``i = 1`` the first slope extrapolates);
beta* -> z is p -> z with ``p = Phi(-beta*)``; beta -> z is ``mean -/+ beta std``.
From two moments (:func:`moment_mappings`, Dakota's mean value method): every column of every
row through the normal of those moments.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

from ..errors import ParameterError
from ._common import levels_per_response

__all__ = ["LevelRequest", "LevelMappings", "level_request", "sample_mappings",
           "moment_mappings", "evidence_mappings", "KINDS", "COLUMNS", "DISTRIBUTIONS",
           "COMPUTE"]

#: The four kinds of level, in Dakota's row order (and the columns of a mapping).
KINDS = ("response", "probability", "reliability", "gen_reliability")
#: Dakota's column headings of a level mapping, in :data:`KINDS` order.
COLUMNS = ("Response Level", "Probability Level", "Reliability Index", "General Rel Index")
#: ``distribution``'s choices (Dakota's ``cumulative`` / ``complementary``).
DISTRIBUTIONS = ("cdf", "ccdf")
#: ``compute``'s choices: what response levels map to (Dakota's ``compute``).
COMPUTE = ("probabilities", "reliabilities", "gen_reliabilities")


@dataclass(frozen=True, eq=False)
class LevelRequest:
    """Requested levels per response, sorted in Dakota's order.

    levels : kind (:data:`KINDS`) -> response -> 1-D array; distribution : "cdf" or "ccdf";
    compute : what response levels map to (:data:`COMPUTE`).
    """

    names_out: tuple[str, ...]
    levels: Mapping[str, Mapping[str, np.ndarray]]
    distribution: str = "cdf"
    compute: str = "probabilities"

    def count(self, name: str) -> int:
        """The number of levels of all kinds of response ``name``."""
        return sum(self.levels[k][name].size for k in KINDS)

    @property
    def empty(self) -> bool:
        return not any(self.count(r) for r in self.names_out)

    def needs_samples(self) -> bool:
        """Whether a mapping needs the response's distribution beyond its two moments
        (probability or generalized reliability levels, or response levels mapped to
        probabilities or generalized reliabilities)."""
        return any(self.levels["probability"][r].size or self.levels["gen_reliability"][r].size
                   or (self.levels["response"][r].size and self.compute != "reliabilities")
                   for r in self.names_out)


def level_request(names_out: Sequence[str], *, response_levels=None, probability_levels=None,
                  reliability_levels=None, gen_reliability_levels=None,
                  distribution: str = "cdf", compute: str = "probabilities") -> LevelRequest:
    """Check and sort requested levels (each None, one sequence for every response, or a
    mapping response -> levels). Raises :class:`~rotoruq.errors.ParameterError` for an unknown
    response, a probability outside [0, 1], a non-finite level, an unknown ``distribution``
    or ``compute``, or ``compute`` other than probabilities without response levels."""
    names_out = tuple(names_out)
    dist, comp = str(distribution).lower(), str(compute).lower()
    if dist not in DISTRIBUTIONS:
        raise ParameterError(f"distribution must be 'cdf' or 'ccdf', got {distribution!r}")
    if comp not in COMPUTE:
        raise ParameterError(f"compute must be one of {', '.join(COMPUTE)}, got {compute!r}")
    given = dict(zip(KINDS, (response_levels, probability_levels, reliability_levels,
                             gen_reliability_levels), strict=True))
    levels: dict[str, dict[str, np.ndarray]] = {}
    for kind, spec in given.items():
        per = levels_per_response(spec, names_out, f"{kind}_levels")
        for r, v in per.items():
            if not np.all(np.isfinite(v)):
                raise ParameterError(f"{kind}_levels for {r!r} must be finite, got {v}")
            if kind == "probability" and np.any((v < 0) | (v > 1)):
                raise ParameterError(f"probability_levels for {r!r} must lie in [0, 1], "
                                     f"got {v}")
            # Dakota's order: z and (CDF) p ascending, beta and beta* descending for a CDF
            ascending = kind == "response" or (kind == "probability") == (dist == "cdf")
            per[r] = np.sort(v) if ascending else -np.sort(-v)
        levels[kind] = per
    if comp != "probabilities" and given["response"] is None:
        raise ParameterError(f"compute = {comp!r} maps response levels: give response_levels")
    return LevelRequest(names_out, levels, dist, comp)


@dataclass(frozen=True, eq=False)
class LevelMappings:
    """Level mappings of m responses, as Dakota prints them.

    names_out (m); distribution "cdf"/"ccdf"; compute (see :data:`COMPUTE`);
    table : response -> (L, 4) rows of response level, probability, reliability index and
    generalized reliability index (:data:`COLUMNS`), NaN where not computed; kinds :
    response -> (L,) index into :data:`KINDS` of the requested column of each row.
    """

    names_out: tuple[str, ...]
    distribution: str
    compute: str
    table: Mapping[str, np.ndarray]
    kinds: Mapping[str, np.ndarray]

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """``(values (m, L, 4), kinds (m, L))`` padded with NaN and -1 to the longest."""
        n = max((self.table[r].shape[0] for r in self.names_out), default=0)
        values = np.full((len(self.names_out), n, 4), np.nan)
        kinds = np.full((len(self.names_out), n), -1, dtype=int)
        for k, r in enumerate(self.names_out):
            t = self.table[r]
            values[k, :t.shape[0]] = t
            kinds[k, :t.shape[0]] = self.kinds[r]
        return values, kinds


def _rows(request: LevelRequest, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(L, 4) rows with the requested column of each filled, and their kinds."""
    parts = [request.levels[k][name] for k in KINDS]
    rows = np.full((sum(p.size for p in parts), 4), np.nan)
    kinds = np.concatenate([np.full(p.size, i, dtype=int) for i, p in enumerate(parts)])
    rows[np.arange(kinds.size), kinds] = np.concatenate(parts)
    return rows, kinds


def _beta_of_z(mean: float, std: float, z: np.ndarray, cdf: bool) -> np.ndarray:
    """Reliability index of response levels z from two moments (a step for std 0)."""
    if std > 0:
        return (mean - z) / std if cdf else (z - mean) / std
    below = (mean <= z) if cdf else (mean > z)
    return np.where(below, -np.inf, np.inf)


def _gen_beta(p: np.ndarray) -> np.ndarray:
    return -stats.norm.ppf(p)


def _quantile(sorted_values: np.ndarray, p_cdf: float) -> float:
    """Dakota's p -> z on sorted samples (each sample carries 1/N; left extrapolation)."""
    n = sorted_values.size
    if n == 0:
        return float("nan")
    i = p_cdf * n
    lo = 1.0 if i < 1.0 else float(np.floor(i))
    k = int(lo) - 1
    if k + 1 >= n:
        return float(sorted_values[min(k, n - 1)])
    return float(sorted_values[k] + (i - lo) * (sorted_values[k + 1] - sorted_values[k]))


def sample_mappings(values: ArrayLike | None, request: LevelRequest, *,
                    mean: ArrayLike | None = None, std: ArrayLike | None = None
                    ) -> LevelMappings:
    """Level mappings from samples ``values`` (n, m) of the responses (NaN rows of a response
    left out), as Dakota's sampling methods and its expansion sampling compute them (see the
    module's conventions); reliabilities from ``mean``, ``std`` (m,) when given (a PCE's
    moments), else the samples' mean and std (ddof 1). Only the computed column of each row
    is filled (response levels: the ``compute`` column).

    ``values`` may be None when nothing needs samples (:meth:`LevelRequest.needs_samples`).

    Examples
    --------
    >>> import numpy as np
    >>> req = level_request(["g"], response_levels=[2.0], probability_levels=[0.5])
    >>> m = sample_mappings(np.array([[1.0], [2.0], [3.0], [4.0]]), req)
    >>> m.table["g"].round(3).tolist()
    [[2.0, 0.5, nan, nan], [2.0, 0.5, nan, nan]]
    """
    names = request.names_out
    y = None if values is None else np.asarray(values, dtype=float).reshape(-1, len(names))
    if y is None and request.needs_samples():
        raise ParameterError("probability and generalized reliability mappings need samples "
                             "of the responses")
    cdf = request.distribution == "cdf"
    table, kinds = {}, {}
    for k, name in enumerate(names):
        rows, kind = _rows(request, name)
        col = np.sort(y[:, k][np.isfinite(y[:, k])]) if y is not None else np.empty(0)
        if mean is not None and std is not None:
            mu, sd = float(np.asarray(mean)[k]), float(np.asarray(std)[k])
        else:
            mu = float(np.mean(col)) if col.size else np.nan
            sd = float(np.std(col, ddof=1)) if col.size > 1 else np.nan
        z = request.levels["response"][name]
        at = kind == 0
        if request.compute == "reliabilities":
            rows[at, 2] = _beta_of_z(mu, sd, z, cdf)
        elif z.size:
            p_cdf = np.searchsorted(col, z, side="right") / col.size
            p = p_cdf if cdf else 1.0 - p_cdf
            rows[at, 1 if request.compute == "probabilities" else 3] = (
                p if request.compute == "probabilities" else _gen_beta(p))
        for kind_i, to_p in ((1, lambda v: v), (3, lambda v: stats.norm.cdf(-v))):
            at = kind == kind_i
            ps = to_p(rows[at, kind_i])
            rows[at, 0] = [_quantile(col, p if cdf else 1.0 - p) for p in ps]
        at = kind == 2
        rows[at, 0] = mu - rows[at, 2] * sd if cdf else mu + rows[at, 2] * sd
        table[name], kinds[name] = rows, kind
    return LevelMappings(names, request.distribution, request.compute, table, kinds)


def moment_mappings(mean: ArrayLike, std: ArrayLike, request: LevelRequest) -> LevelMappings:
    """Level mappings of responses with ``mean`` and ``std`` (m,) through the normal of those
    moments (Dakota's mean value method): every column of every row, ``beta = beta*``,
    ``p = Phi(-beta)``; a response with std 0 maps to beta = -/+inf, p = 1 / 0.

    Examples
    --------
    >>> req = level_request(["g"], response_levels=[1.0], reliability_levels=[2.0])
    >>> moment_mappings([1.0], [0.5], req).table["g"].round(4).tolist()
    [[1.0, 0.5, 0.0, 0.0], [0.0, 0.0228, 2.0, 2.0]]
    """
    names = request.names_out
    mu_all = np.atleast_1d(np.asarray(mean, dtype=float))
    sd_all = np.atleast_1d(np.asarray(std, dtype=float))
    cdf = request.distribution == "cdf"
    table, kinds = {}, {}
    for k, name in enumerate(names):
        mu, sd = float(mu_all[k]), float(sd_all[k])
        rows, kind = _rows(request, name)
        at = kind == 0
        rows[at, 2] = _beta_of_z(mu, sd, rows[at, 0], cdf)
        at = kind == 1
        rows[at, 2] = _gen_beta(rows[at, 1])
        at = kind == 3
        rows[at, 2] = rows[at, 3]
        beta = rows[:, 2]
        rows[:, 3] = beta
        rows[kind != 1, 1] = stats.norm.cdf(-beta[kind != 1])
        at = kind != 0
        rows[at, 0] = mu - beta[at] * sd if cdf else mu + beta[at] * sd
        table[name], kinds[name] = rows, kind
    return LevelMappings(names, request.distribution, request.compute, table, kinds)


def evidence_mappings(cell_min: ArrayLike, cell_max: ArrayLike, bpa: ArrayLike,
                      request: LevelRequest) -> dict[str, dict[str, np.ndarray]]:
    """Belief and plausibility mappings of Dempster-Shafer cells (Dakota's
    ``global_evidence``): ``cell_min``, ``cell_max`` (c, m) each cell's response range, ``bpa``
    (c,) its basic probability assignment.

    CDF: belief ``Bel(g < z)`` = BPA of the cells with max < z, plausibility ``Pl(g < z)`` =
    BPA of the cells with min < z; CCDF: belief = BPA of the cells with min >= z,
    plausibility = BPA of the cells with max >= z (Dakota's step functions at a tie); with
    ``compute = "gen_reliabilities"`` each as ``-Phi^-1``. Probability and generalized
    reliability levels map to the belief and plausibility response levels of Dakota's
    complementary step functions. ``compute = "reliabilities"`` has no meaning here (no
    moments) and raises.

    Returns quantity -> response -> levels: ``response_levels``, ``belief``,
    ``plausibility`` (their probabilities or generalized reliabilities); ``probability_levels``,
    ``belief_response``, ``plausibility_response``; ``gen_reliability_levels``,
    ``belief_gen_response``, ``plausibility_gen_response``.
    """
    if request.compute == "reliabilities" or any(
            request.levels["reliability"][r].size for r in request.names_out):
        raise ParameterError("evidence maps no reliability indices (it has no moments): use "
                             "probabilities or gen_reliabilities")
    lo_all, hi_all = np.asarray(cell_min, dtype=float), np.asarray(cell_max, dtype=float)
    w = np.asarray(bpa, dtype=float)
    cdf = request.distribution == "cdf"
    out: dict[str, dict[str, np.ndarray]] = {q: {} for q in (
        "response_levels", "belief", "plausibility", "probability_levels", "belief_response",
        "plausibility_response", "gen_reliability_levels", "belief_gen_response",
        "plausibility_gen_response")}
    for k, r in enumerate(request.names_out):
        lo, hi = lo_all[:, k], hi_all[:, k]
        # Dakota's complementary step functions: each cell's min (belief) and max
        # (plausibility) sorted, with the BPA of the cells from there on, summed and
        # subtracted in Dakota's order (a step lands where Dakota's rounding puts it)
        o_lo, o_hi = np.argsort(lo, kind="stable"), np.argsort(hi, kind="stable")
        bel_val, pl_val = lo[o_lo], hi[o_hi]
        total = 0.0
        for v in w:
            total += float(v)
        bel_fn, pl_fn = np.empty(w.size), np.empty(w.size)
        b_tot = p_tot = total
        for i in range(w.size):
            bel_fn[i], pl_fn[i] = b_tot, p_tot
            b_tot -= float(w[o_lo[i]])
            p_tot -= float(w[o_hi[i]])
        z = request.levels["response"][r]

        def at(val: np.ndarray, fn: np.ndarray, beyond: float, complement: bool,
               z: np.ndarray = z) -> np.ndarray:
            idx = np.minimum(np.searchsorted(val, z, side="left"), val.size - 1)
            got = 1.0 - fn[idx] if complement else fn[idx]
            return np.where(z > val[-1], beyond, got)

        if cdf:  # Bel(g < z), Pl(g < z)
            bel, pl = at(pl_val, pl_fn, 1.0, True), at(bel_val, bel_fn, 1.0, True)
        else:  # Bel(g >= z), Pl(g >= z)
            bel, pl = at(bel_val, bel_fn, 0.0, False), at(pl_val, pl_fn, 0.0, False)
        if request.compute == "gen_reliabilities":
            bel, pl = _gen_beta(bel), _gen_beta(pl)
        out["response_levels"][r], out["belief"][r], out["plausibility"][r] = z, bel, pl

        def inverse(cc: np.ndarray, fn: np.ndarray, val: np.ndarray) -> np.ndarray:
            idx = np.array([min(int(np.sum(fn > c)), fn.size - 1) for c in cc], dtype=int)
            return val[idx] if fn.size else np.full(cc.size, np.nan)

        p = request.levels["probability"][r]
        b = request.levels["gen_reliability"][r]
        for levels, cc, names in (
                (p, 1.0 - p if cdf else p, ("probability_levels", "belief_response",
                                             "plausibility_response")),
                (b, stats.norm.cdf(b) if cdf else stats.norm.cdf(-b),
                 ("gen_reliability_levels", "belief_gen_response",
                  "plausibility_gen_response"))):
            out[names[0]][r] = levels
            out[names[1]][r] = inverse(cc, pl_fn, pl_val) if cdf else inverse(cc, bel_fn,
                                                                              bel_val)
            out[names[2]][r] = inverse(cc, bel_fn, bel_val) if cdf else inverse(cc, pl_fn,
                                                                               pl_val)
    return out
