"""Sampling-based forward propagation: Monte Carlo, Latin hypercube and quasi-Monte Carlo
designs, response statistics, empirical CDF/PDF and incremental growth.

Moment conventions (Dakota's): ``std`` is the sample standard deviation (ddof = 1);
``skewness`` is the bias-corrected sample skewness G1 and ``kurtosis`` the bias-corrected
**excess** kurtosis G2 (0 for a normal response), i.e. ``scipy.stats.skew(bias=False)`` and
``scipy.stats.kurtosis(fisher=True, bias=False)``.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from .._rng import SeedLike, as_generator
from ..errors import ParameterError
from ..model import Model
from ..params import PAIRINGS, ParameterSpace, restricted_pairing, unit_design
from ._common import eval_space, levels_per_response, names_or_default, nan_rows_warning

__all__ = [
    "ResponseStatistics",
    "SamplingResult",
    "response_statistics",
    "sample",
    "refine",
    "unit_to_space",
    "check_design",
    "DESIGNS",
]

DEFAULT_PERCENTILES = (1.0, 5.0, 10.0, 25.0, 50.0, 75.0, 90.0, 95.0, 99.0)
DESIGNS = ("lhs", "random", "sobol", "halton")


@dataclass(frozen=True, eq=False)
class ResponseStatistics:
    """Statistics of m responses from n samples (non-finite values left out per response).

    Attributes
    ----------
    names_out : tuple of str
        The m response names.
    n_valid : ndarray of shape (m,)
        Number of finite values used per response.
    n_dropped : ndarray of shape (m,)
        Number of values left out (failed or NaN) per response.
    mean, std, skewness, kurtosis : ndarray of shape (m,)
        Sample moments in response units (std with ddof=1; skewness G1 and excess kurtosis
        G2, both bias-corrected; a normal sample gives 0).
    mean_ci, std_ci : ndarray of shape (m, 2)
        Confidence intervals at level ``confidence`` (Student t for the mean, chi-square for
        the std, as Dakota).
    confidence : float
        The level of ``mean_ci`` and ``std_ci`` (0.95 by default).
    percentile_levels : ndarray of shape (k,)
        The percentiles reported, in percent.
    percentiles : ndarray of shape (m, k)
        The values at ``percentile_levels``, response units.
    response_levels : dict of str to ndarray
        Response name -> the levels z asked for.
    cdf_probability, ccdf_probability : dict of str to ndarray
        Response name -> empirical P(y <= z) and P(y > z) at its levels.
    probability_levels : dict of str to ndarray
        Response name -> the probabilities asked for.
    probability_response : dict of str to ndarray
        Response name -> the empirical quantiles at its probability levels.
    """

    names_out: tuple[str, ...]
    n_valid: np.ndarray
    n_dropped: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    skewness: np.ndarray
    kurtosis: np.ndarray
    mean_ci: np.ndarray
    std_ci: np.ndarray
    confidence: float
    percentile_levels: np.ndarray
    percentiles: np.ndarray
    response_levels: dict = field(default_factory=dict)
    cdf_probability: dict = field(default_factory=dict)
    ccdf_probability: dict = field(default_factory=dict)
    probability_levels: dict = field(default_factory=dict)
    probability_response: dict = field(default_factory=dict)

    def table(self) -> list[dict]:
        """One dict per response (name, mean, std, skewness, kurtosis, n_valid)."""
        return [
            {
                "response": n,
                "mean": float(self.mean[k]),
                "std": float(self.std[k]),
                "skewness": float(self.skewness[k]),
                "kurtosis": float(self.kurtosis[k]),
                "n_valid": int(self.n_valid[k]),
            }
            for k, n in enumerate(self.names_out)
        ]


def response_statistics(
    values: np.ndarray,
    names_out: Sequence[str] | None = None,
    *,
    response_levels=None,
    probability_levels=None,
    percentiles=DEFAULT_PERCENTILES,
    confidence: float = 0.95,
    warn: bool = True,
) -> ResponseStatistics:
    """Statistics of a sample of responses ``values`` (n, m); NaN/inf entries are dropped per
    response, with a RuntimeWarning saying how many (``warn=False`` silences it).

    Parameters
    ----------
    values : array_like of shape (n, m) or (n,)
        The sampled responses, one row per sample.
    names_out : sequence of str, optional
        The m response names (default ``y0``, ``y1``, ...).
    response_levels : sequence of float, mapping or sequence of sequences, optional
        Levels z (response units) for the empirical P(y <= z) / P(y > z): the same for all
        responses, a mapping name -> levels, or one sequence per response.
    probability_levels : sequence of float, mapping or sequence of sequences, optional
        Probabilities in [0, 1] mapped to empirical quantiles (response units), given like
        ``response_levels``.
    percentiles : sequence of float, optional
        Percentiles (percent) to report (default 1, 5, 10, 25, 50, 75, 90, 95, 99).
    confidence : float, optional
        Level of the mean / std confidence intervals, in (0, 1) (default 0.95).
    warn : bool, optional
        Warn when non-finite values are dropped (default True).

    Returns
    -------
    ResponseStatistics
        The statistics, one entry per response.

    Examples
    --------
    >>> import numpy as np
    >>> st = response_statistics(np.array([[1.0], [2.0], [3.0], [np.nan]]), ["y"], warn=False)
    >>> float(st.mean[0]), float(st.std[0]), int(st.n_dropped[0])     # std with ddof 1
    (2.0, 1.0, 1)
    """
    y = np.asarray(values, dtype=float)
    if y.ndim == 1:
        y = y[:, None]
    n, m = y.shape
    names = names_or_default(names_out, m, "y")
    if not 0 < confidence < 1:
        raise ParameterError(f"confidence must lie in (0, 1), got {confidence}")
    finite = np.isfinite(y)
    n_valid = finite.sum(axis=0)
    n_bad_rows = int(np.sum(~finite.all(axis=1)))
    if warn:
        nan_rows_warning(n_bad_rows, n, "response statistics")
    pct = np.asarray(percentiles, dtype=float)
    out = {k: np.full(m, np.nan) for k in ("mean", "std", "skew", "kurt")}
    mean_ci = np.full((m, 2), np.nan)
    std_ci = np.full((m, 2), np.nan)
    perc = np.full((m, pct.size), np.nan)
    rl = levels_per_response(response_levels, names, "response_levels")
    pl = levels_per_response(probability_levels, names, "probability_levels")
    cdf_p, ccdf_p, p_resp = {}, {}, {}
    a = 1.0 - confidence
    for k, name in enumerate(names):
        v = y[finite[:, k], k]
        nk = v.size
        if nk >= 1:
            out["mean"][k] = v.mean()
            perc[k] = np.percentile(v, pct)
        if nk >= 2:
            s = v.std(ddof=1)
            out["std"][k] = s
            t = stats.t.ppf(1 - a / 2, nk - 1)
            mean_ci[k] = v.mean() + np.array([-1, 1]) * t * s / np.sqrt(nk)
            std_ci[k] = np.sqrt((nk - 1) * s**2 / stats.chi2.ppf([1 - a / 2, a / 2], nk - 1))
            if s > 0:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    if nk >= 3:
                        out["skew"][k] = stats.skew(v, bias=False)
                    if nk >= 4:
                        out["kurt"][k] = stats.kurtosis(v, fisher=True, bias=False)
        z = rl[name]
        cdf_p[name] = (v[None, :] <= z[:, None]).mean(axis=1) if nk else np.full(z.size, np.nan)
        ccdf_p[name] = 1.0 - cdf_p[name]
        p = pl[name]
        if np.any((p < 0) | (p > 1)):
            raise ParameterError(f"probability_levels for {name!r} must lie in [0, 1]")
        p_resp[name] = np.quantile(v, p) if nk else np.full(p.size, np.nan)
    return ResponseStatistics(
        names_out=names,
        n_valid=n_valid,
        n_dropped=n - n_valid,
        mean=out["mean"],
        std=out["std"],
        skewness=out["skew"],
        kurtosis=out["kurt"],
        mean_ci=mean_ci,
        std_ci=std_ci,
        confidence=float(confidence),
        percentile_levels=pct,
        percentiles=perc,
        response_levels=rl,
        cdf_probability=cdf_p,
        ccdf_probability=ccdf_p,
        probability_levels=pl,
        probability_response=p_resp,
    )


@dataclass(frozen=True, eq=False)
class SamplingResult:
    """Result of :func:`sample`.

    Attributes
    ----------
    names_in, names_out : tuple of str
        The d input and m response names.
    inputs : ndarray of shape (n, d)
        Sample points, columns in ``names_in`` order, in the inputs' units.
    outputs : ndarray of shape (n, m)
        Responses (NaN rows for failed points).
    failures : dict of int to str
        Row -> reason, for the failed points.
    statistics : ResponseStatistics
        Statistics of the finite responses.
    design : str
        ``"lhs"``, ``"random"``, ``"sobol"`` or ``"halton"``.
    unit : ndarray of shape (n, d)
        The design in (0, 1)^d (used by :func:`refine`).
    n_evaluations : int
        Model evaluations made (all rows, failed ones included).
    model : Model or None
        The model that was sampled (:func:`refine` runs it again).
    space : ParameterSpace or None
        The inputs' distributions.
    options : dict
        The other arguments of :func:`sample` (pairing, levels, percentiles, confidence) and
        the generator state that :func:`refine` continues from.
    """

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    inputs: np.ndarray
    outputs: np.ndarray
    failures: dict
    statistics: ResponseStatistics
    design: str
    unit: np.ndarray = field(repr=False)
    n_evaluations: int = 0
    model: Model | None = field(default=None, repr=False)
    space: ParameterSpace | None = field(default=None, repr=False)
    options: dict = field(default_factory=dict, repr=False)

    # convenience accessors
    @property
    def n_samples(self) -> int:
        """Number of sample points n (failed ones included)."""
        return self.inputs.shape[0]

    @property
    def mean(self) -> np.ndarray:
        """Sample mean per response, shape (m,) (``statistics.mean``)."""
        return self.statistics.mean

    @property
    def std(self) -> np.ndarray:
        """Sample standard deviation per response, shape (m,) (``statistics.std``)."""
        return self.statistics.std

    @property
    def skewness(self) -> np.ndarray:
        """Sample skewness per response, shape (m,) (``statistics.skewness``)."""
        return self.statistics.skewness

    @property
    def kurtosis(self) -> np.ndarray:
        """Sample excess kurtosis per response, shape (m,) (``statistics.kurtosis``)."""
        return self.statistics.kurtosis

    def _column(self, name: str) -> np.ndarray:
        if name not in self.names_out:
            raise ParameterError(f"unknown response {name!r}; valid: {list(self.names_out)}")
        v = self.outputs[:, self.names_out.index(name)]
        return v[np.isfinite(v)]

    def ecdf(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Empirical CDF of response ``name``: sorted values (k,) and P(Y <= value) (k,).

        Parameters
        ----------
        name : str
            A response name; its k finite values are used.
        """
        v = np.sort(self._column(name))
        return v, np.arange(1, v.size + 1) / v.size

    def histogram_pdf(self, name: str, bins="auto") -> tuple[np.ndarray, np.ndarray]:
        """Histogram density: bin edges (b+1,) and densities (b,) (integrates to 1).

        Parameters
        ----------
        name : str
            A response name; its finite values are used.
        bins : int, sequence of float or str, optional
            As :func:`numpy.histogram`: a count, the edges, or a rule (default ``"auto"``).
        """
        dens, edges = np.histogram(self._column(name), bins=bins, density=True)
        return edges, dens

    def kde_pdf(self, name: str, grid=None, bw_method=None) -> tuple[np.ndarray, np.ndarray]:
        """Gaussian kernel density (scipy.stats.gaussian_kde): returns (grid, density).

        Parameters
        ----------
        name : str
            A response name; its finite values are used.
        grid : array_like, optional
            Where to evaluate the density, response units (default 200 points spanning the
            sample +- 3 bandwidths).
        bw_method : str, float or callable, optional
            The bandwidth rule of :class:`scipy.stats.gaussian_kde` (default Scott's).
        """
        v = self._column(name)
        kde = stats.gaussian_kde(v, bw_method=bw_method)
        if grid is None:
            bw = np.sqrt(kde.covariance[0, 0])
            grid = np.linspace(v.min() - 3 * bw, v.max() + 3 * bw, 200)
        grid = np.asarray(grid, dtype=float)
        return grid, kde(grid)


def unit_to_space(space: ParameterSpace, q: np.ndarray, *, paired: bool = False) -> np.ndarray:
    """Map a design in (0, 1)^d to parameter values (Nataf-correlated when the space is).

    ``paired=True`` says the design already carries the space's correlation (a restricted
    LHS aimed at :attr:`ParameterSpace.nataf`): it is then mapped by the marginals alone.
    """
    if space.correlation is None or paired:
        return space.from_unit(q)
    return space.from_u(stats.norm.ppf(np.clip(q, 1e-16, 1 - 1e-16)))


def check_design(design: str) -> str:
    """``design`` in lower case if it is one of :data:`DESIGNS`, else a ParameterError."""
    d = str(design).lower()
    if d not in DESIGNS:
        raise ParameterError(f"unknown design {design!r}; valid: {', '.join(DESIGNS)}")
    return d


def _carries_correlation(design: str, options: dict) -> bool:
    return design == "lhs" and options.get("pairing") == "restricted"


def _pair_target(space: ParameterSpace) -> np.ndarray | None:
    return space.nataf if space.correlation is not None else None


def _finish(model, space, q, design, options, previous=None):
    x = unit_to_space(space, q, paired=_carries_correlation(design, options))
    batch = eval_space(model, space, x)
    y, failures = batch.values, dict(batch.failures)
    if previous is not None:
        off = previous.inputs.shape[0]
        failures = {**previous.failures, **{i + off: r for i, r in failures.items()}}
        x = np.vstack([previous.inputs, x])
        y = np.vstack([previous.outputs, y])
        q = np.vstack([previous.unit, q])
    names_out = tuple(model.names_out)
    st = response_statistics(
        y,
        names_out,
        response_levels=options["response_levels"],
        probability_levels=options["probability_levels"],
        percentiles=options["percentiles"],
        confidence=options["confidence"],
        warn=False,
    )
    n_bad = int(np.sum(~np.all(np.isfinite(y), axis=1)))
    nan_rows_warning(n_bad, y.shape[0], f"sample ({design})")
    return SamplingResult(
        names_in=space.names,
        names_out=names_out,
        inputs=x,
        outputs=y,
        failures=failures,
        statistics=st,
        design=design,
        unit=q,
        n_evaluations=y.shape[0],
        model=model,
        space=space,
        options=options,
    )


def sample(
    model: Model,
    space: ParameterSpace,
    n_samples: int,
    *,
    design: str = "lhs",
    pairing: str = "restricted",
    response_levels=None,
    probability_levels=None,
    percentiles: Sequence[float] = DEFAULT_PERCENTILES,
    confidence: float = 0.95,
    seed: SeedLike = None,
) -> SamplingResult:
    """Propagate ``space`` through ``model`` with ``n_samples`` points in ONE batched call.

    Parameters
    ----------
    model : Model
        Inputs matched to ``space.names`` by name; called once on (n_samples, d).
    space : ParameterSpace
        The d uncertain inputs, in their own units (correlations honoured through the Nataf
        model).
    n_samples : int
        Number of samples (>= 2).
    design : str
        "lhs" (Latin hypercube), "random" (plain Monte Carlo), "sobol" or "halton"
        (scrambled, scipy.stats.qmc); drawn by :func:`rotoruq.params.unit_design`.
    pairing : str
        "lhs" only: "restricted" (default, Dakota's LHS: Iman-Conover pairing of the
        columns so the inputs' normal-score correlation is near the space's Nataf correlation,
        identity when independent; every marginal stays stratified) or "random" (columns
        paired at random, the behaviour before; with correlations the design is then
        stratified in u-space). With ``n_samples <= dim`` the pairing is random either way.
    response_levels : sequence of float, mapping or sequence of sequences, optional
        Levels z (response units) for the empirical P(y <= z) / P(y > z): the same for all
        responses, a mapping name -> levels, or one sequence per response.
    probability_levels : sequence of float, optional
        Probabilities in (0, 1) mapped to empirical quantiles (response units).
    percentiles : sequence of float
        Percentiles (percent) to report.
    confidence : float
        Level of the mean / std confidence intervals.
    seed : int, numpy Generator or None
        The same seed gives the same points, bitwise.

    Returns
    -------
    SamplingResult
        ``inputs`` (n_samples, d), ``outputs`` (n_samples, m) and their ``statistics``.
        Failed rows stay in ``outputs`` as NaN (reason in ``failures``) and are left out of
        the statistics with a RuntimeWarning giving the count.

    Examples
    --------
    y = a + b with a ~ N(10, 2) and b ~ U(0, 1): mean 10.5, std sqrt(4 + 1/12) = 2.021:

    >>> import numpy as np
    >>> import rotoruq as rq
    >>> space = rq.ParameterSpace({"a": rq.Normal(10.0, 2.0), "b": rq.Uniform(0.0, 1.0)})
    >>> model = rq.FunctionModel(lambda x: x[:, :1] + x[:, 1:], space.names, ["y"])
    >>> res = rq.sample(model, space, 1000, seed=1)
    >>> res.inputs.shape, res.outputs.shape                 # (n_samples, d), (n_samples, m)
    ((1000, 2), (1000, 1))
    >>> bool(abs(res.statistics.mean[0] - 10.5) < 0.01)
    True
    >>> bool(abs(res.statistics.std[0] - np.sqrt(4 + 1 / 12)) < 0.05)
    True
    """
    n = int(n_samples)
    if n < 2:
        raise ParameterError(f"n_samples must be >= 2, got {n_samples}")
    design = check_design(design)
    if pairing not in PAIRINGS:
        raise ParameterError(f"unknown pairing {pairing!r}; valid: {', '.join(PAIRINGS)}")
    rng = as_generator(seed)
    # a QMC design gets a generator of its own, rebuilt by refine() from this integer (scipy's
    # QMC engines spawn from a generator's seed sequence, which its state does not hold); LHS
    # and random designs draw from the caller's generator, continued by refine() from the
    # state snapshot (not the generator), so refining one result twice gives the same points
    # whatever else drew from the caller's generator
    design_seed = int(rng.integers(2**62))
    qmc_design = design in ("sobol", "halton")
    q = unit_design(n, space.dim, design=design, pairing=pairing,
                    correlation=_pair_target(space),
                    seed=np.random.default_rng(design_seed) if qmc_design else rng)
    options = {
        "pairing": pairing,
        "response_levels": response_levels,
        "probability_levels": probability_levels,
        "percentiles": tuple(percentiles),
        "confidence": confidence,
        "design_seed": design_seed,
        "rng_state": rng.bit_generator.state,
    }
    return _finish(model, space, q, design, options)


def _generator_at(state: dict) -> np.random.Generator:
    rng = np.random.Generator(getattr(np.random, state["bit_generator"])())
    rng.bit_generator.state = state
    return rng


def _lhs_extension(u_old: np.ndarray, n_more: int, rng: np.random.Generator) -> np.ndarray:
    """New points that fill the empty strata of an (n + n_more)-stratum grid per dimension.

    When ``u_old`` is an LHS of n points and ``n_more == n`` exactly n strata are empty in
    every dimension and the union is an LHS of 2n points (incremental LHS, as Dakota's
    ``refinement_samples``). Otherwise the union is LHS-like: new points go to empty strata
    first (randomly chosen), then to random strata.
    """
    n_old, d = u_old.shape
    N = n_old + n_more
    out = np.empty((n_more, d))
    for j in range(d):
        occupied = np.zeros(N, dtype=bool)
        occupied[np.minimum((u_old[:, j] * N).astype(int), N - 1)] = True
        empty = np.flatnonzero(~occupied)
        if empty.size >= n_more:
            strata = rng.choice(empty, size=n_more, replace=False)
        else:
            extra = rng.choice(np.flatnonzero(occupied), size=n_more - empty.size, replace=False)
            strata = np.concatenate([empty, extra])
        out[:, j] = (rng.permutation(strata) + rng.random(n_more)) / N
    return out


def refine(result: SamplingResult, n_samples: int, *, seed: SeedLike = None) -> SamplingResult:
    """Grow a sample by ``n_samples`` more points (one model call for the new points only).

    * "lhs": new points fill the empty strata of the finer grid (exact LHS of 2n points when
      ``n_samples == n``; LHS-like otherwise), paired among themselves as the original
      sample was (restricted or random);
    * "sobol" / "halton" / "random": the sequence is continued (the points that ``sample``
      would have drawn with the larger count and the same seed).

    ``seed`` (lhs and random) defaults to the state the original sample's generator was left in
    (continued), so a refined run is reproducible from the original seed, and refining one
    result twice gives the same points.

    Parameters
    ----------
    result : SamplingResult
        A result of :func:`sample` (it holds the model, the space and the design).
    n_samples : int
        Number of points to add (>= 1).
    seed : int, SeedSequence, Generator or None, optional
        For ``"lhs"`` and ``"random"``: the random source of the new points (default: the
        original sample's generator, continued).

    Returns
    -------
    SamplingResult
        The original and the new points together, with the statistics of all of them.

    Examples
    --------
    >>> import rotoruq as rq
    >>> space = rq.ParameterSpace({"a": rq.Uniform(0.0, 1.0)})
    >>> model = rq.FunctionModel(lambda x: 3.0 * x, space.names, ["y"])
    >>> more = rq.refine(rq.sample(model, space, 50, seed=1), 50)
    >>> more.outputs.shape                 # 100 points: an exact LHS of the finer strata
    (100, 1)
    >>> sorted((more.inputs[:, 0] * 100).astype(int).tolist()) == list(range(100))
    True
    """
    n_more = int(n_samples)
    if n_more < 1:
        raise ParameterError(f"n_samples (points to add) must be >= 1, got {n_samples}")
    if result.model is None or result.space is None:
        raise ParameterError("this SamplingResult does not carry its model and space")
    opts = dict(result.options)
    if result.design in ("lhs", "random"):
        rng = as_generator(seed) if seed is not None else _generator_at(opts["rng_state"])
        if result.design == "lhs":
            q = _lhs_extension(result.unit, n_more, rng)
            if _carries_correlation(result.design, opts):
                q = restricted_pairing(q, rng, _pair_target(result.space))
        else:
            q = unit_design(n_more, result.space.dim, design="random", seed=rng)
        opts["rng_state"] = rng.bit_generator.state
    else:
        n_old = result.n_samples
        q = unit_design(n_old + n_more, result.space.dim, design=result.design,
                        seed=np.random.default_rng(opts["design_seed"]))[n_old:]
    return _finish(result.model, result.space, q, result.design, opts, previous=result)
