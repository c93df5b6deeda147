"""Step adapters: one small function per step type, ``run_<type>(ctx) -> StepResult``.

Each adapter calls one method of :mod:`rotoruq.methods` and flattens its result into a
:class:`~rotoruq.results.StepResult` (scalars, arrays, distributions). The runner
prepares the :class:`StepContext`; the adapters hold no study logic of their own. The
step-type registry (:mod:`rotoruq.study.steptypes`) ties each adapter to its options.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import stats

from ..errors import ParameterError
from ..params import Normal, ParameterSpace
from ..results import StepResult, dist_to_dict

__all__ = ["StepContext"]


@dataclass
class StepContext:
    """Everything a step needs.

    space : the uncertain inputs of the step (priors / input distributions), shape d.
    responses : the step's response names (m).
    fixed : the other model inputs and their values.
    make_model(inputs, responses, fixed) -> Model : builds (store-backed) models, e.g. for
        sweeps over fixed inputs.
    data : (k, m) observations of ``responses`` (None when the step has no data).
    data_columns : every column of the data set (for sweeps and normalisation).
    targets : response -> (mean, std) (CUU).
    rng : numpy Generator for this step.
    source : the saved result of the ``from`` step (None without one); a forward check uses
        its chain for the joint posterior predictive.
    """

    name: str
    type: str
    options: Mapping[str, Any]
    space: ParameterSpace
    responses: tuple[str, ...]
    fixed: Mapping[str, float]
    make_model: Callable[..., Any]
    rng: np.random.Generator
    data: np.ndarray | None = None
    data_columns: Mapping[str, np.ndarray] = field(default_factory=dict)
    targets: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    source: StepResult | None = None

    def observations(self) -> np.ndarray:
        """The step's data (k, m); a step type that needs data declares ``needs_data``."""
        if self.data is None:
            raise ParameterError(f"step {self.name!r} ({self.type}) needs data = \"NAME\"")
        return self.data

    def model(self, fixed: Mapping[str, float] | None = None) -> Any:
        f = dict(self.fixed)
        f.update(fixed or {})
        return self.make_model(self.space.names, self.responses, f)


def _stats_scalars(prefix_names: Sequence[str], values: np.ndarray, suffix: str = "") -> dict:
    """mean/std/skewness/kurtosis of each column (ddof=1, bias-corrected, excess kurtosis)."""
    out = {}
    for j, name in enumerate(prefix_names):
        v = values[:, j]
        v = v[np.isfinite(v)]
        if v.size < 2:
            continue
        out[f"mean/{name}{suffix}"] = float(np.mean(v))
        out[f"std/{name}{suffix}"] = float(np.std(v, ddof=1))
        if v.size > 3 and np.std(v) > 0:
            out[f"skewness/{name}{suffix}"] = float(stats.skew(v, bias=False))
            out[f"kurtosis/{name}{suffix}"] = float(stats.kurtosis(v, bias=False))
    return out


def _input_scalars(space: ParameterSpace) -> dict:
    out = {}
    for name, d in zip(space.names, space.distributions, strict=True):
        out[f"input_mean/{name}"] = d.mean
        out[f"input_std/{name}"] = d.std
        lo, hi = d.bounds
        if np.isfinite(lo) and np.isfinite(hi):
            out[f"input_lower/{name}"] = lo
            out[f"input_upper/{name}"] = hi
    return out


def _noise(ctx: StepContext, noise, shape) -> np.ndarray:
    if not noise:
        return np.zeros(shape)
    if isinstance(noise, Mapping):
        sd = np.array([float(noise.get(r, 0.0)) for r in ctx.responses])
    else:
        sd = np.full(shape[1], float(noise))
    return ctx.rng.normal(size=shape) * sd


# ---------------------------------------------------------------------------------------------
def run_sampling(ctx: StepContext) -> StepResult:
    from ..methods.sampling import sample

    o = ctx.options
    res = sample(ctx.model(), ctx.space, o["n_samples"], design=o["design"], seed=ctx.rng)
    clean = np.asarray(res.outputs)
    noisy = clean + _noise(ctx, o.get("noise_std"), clean.shape)
    scalars = _stats_scalars(ctx.responses, clean)
    scalars.update(_stats_scalars([f"noisy_{r}" for r in ctx.responses], noisy))
    scalars.update(_input_scalars(ctx.space))
    arrays = {"inputs": np.asarray(res.inputs), "outputs": noisy}
    columns = {"inputs": list(ctx.space.names), "outputs": list(ctx.responses)}
    if o.get("noise_std"):
        arrays["outputs_clean"] = clean
        columns["outputs_clean"] = list(ctx.responses)
    return StepResult(ctx.name, ctx.type, scalars, arrays, meta={
        "columns": columns, "n_evaluations": int(res.n_evaluations),
        "failures": len(res.failures)})


def _posterior_draws(ctx: StepContext, n: int) -> np.ndarray | None:
    """``n`` joint draws (n, d) of the step's inputs from the ``from`` step's saved chain, in
    ``ctx.space.names`` order (None when that step has no chain covering them)."""
    src = ctx.source
    if src is None or "chain" not in src.arrays:
        return None
    names = src.columns("chain")
    if not set(ctx.space.names) <= set(names):
        return None
    chain = np.asarray(src.arrays["chain"], dtype=float)
    pick = ctx.rng.choice(chain.shape[0], size=n, replace=n > chain.shape[0])
    cols = np.array([names.index(p) for p in ctx.space.names], dtype=int)
    return chain[np.ix_(pick, cols)]


def _spread(out: np.ndarray) -> tuple[float, float]:
    v = out[np.isfinite(out)]
    return float(np.mean(v)), float(np.std(v, ddof=1)) if v.size > 1 else np.nan


def run_forward_check(ctx: StepContext) -> StepResult:
    """Propagation at one or several operating points (``sweep``) compared with data.

    Two propagations when ``from`` is a Bayes step with a chain:

    * independent normals (the reference study's method, its table 4.15): LHS of the normal
      distributions built from each parameter's posterior mean and std (``mean/``, ``std/``,
      ``nstd/`` keys);
    * the joint posterior predictive: ``n`` draws of the chain itself (correlations kept)
      through the true model (``pp_mean/``, ``pp_std/``). ``pp_noise/`` is the calibration's
      noise std of that response (0 where the calibration did not observe it) and
      ``pp_nstd/`` = |data - pp_mean| / sqrt(pp_std^2 + pp_noise^2): the distance of the
      measurement from the predictive distribution of a measurement.
    """
    from ..methods.sampling import sample
    from ..model import evaluate

    o = ctx.options
    sweep = {k: list(v) for k, v in (o.get("sweep") or {}).items()}
    n_points = len(next(iter(sweep.values()))) if sweep else 1
    match = o.get("match") or (next(iter(sweep)) if sweep else None)
    cols = ctx.data_columns
    norm_row = None
    if o.get("normalize_by"):
        (key, value), = o["normalize_by"].items()
        rows = np.flatnonzero(np.isclose(cols[key], value))
        if rows.size == 0:
            raise ParameterError(f"step {ctx.name!r}: no data row with {key} = {value}")
        norm_row = int(rows[0])
    draws = _posterior_draws(ctx, o["n_samples"])
    src_noise = ctx.source.scalars if ctx.source is not None else {}
    scalars, arrays, columns, n_eval = {}, {}, {}, 0
    labels = []
    for j in range(n_points):
        point = {k: float(v[j]) for k, v in sweep.items()}
        label = f"@{point[match]:g}" if sweep and match in point else ""
        labels.append(label)
        model = ctx.model(point)
        res = sample(model, ctx.space, o["n_samples"], design=o["design"], seed=ctx.rng)
        out = np.asarray(res.outputs, dtype=float)
        n_eval += int(res.n_evaluations)
        pp = None
        if draws is not None:
            pp = np.array(evaluate(model, draws).values, dtype=float)
            n_eval += draws.shape[0]
        row = None
        if cols and match is not None and match in cols and match in point:
            rows = np.flatnonzero(np.isclose(cols[match], point[match]))
            row = int(rows[0]) if rows.size else None
        elif cols and not sweep:
            row = 0
        for k, r in enumerate(ctx.responses):
            scale = 1.0
            if norm_row is not None and r in cols:
                scale = float(cols[r][norm_row])
            out[:, k] = out[:, k] / scale
            if pp is not None:
                pp[:, k] = pp[:, k] / scale
                noise = float(src_noise.get(f"noise_std/{r}", 0.0)) / scale
                pm, ps = _spread(pp[:, k])
                scalars.update({f"pp_mean/{r}{label}": pm, f"pp_std/{r}{label}": ps,
                                f"pp_noise/{r}{label}": noise})
            if row is not None and r in cols:
                measured = float(cols[r][row]) / scale
                mean, std = _spread(out[:, k])
                scalars[f"data/{r}{label}"] = measured
                scalars[f"nstd/{r}{label}"] = abs(measured - mean) / std if std > 0 else np.inf
                if pp is not None:
                    tot = float(np.hypot(scalars[f"pp_std/{r}{label}"], noise))
                    scalars[f"pp_nstd/{r}{label}"] = (
                        abs(measured - scalars[f"pp_mean/{r}{label}"]) / tot if tot > 0
                        else np.inf)
        scalars.update(_stats_scalars(ctx.responses, out, label))
        arrays[f"outputs{label}"] = out
        columns[f"outputs{label}"] = list(ctx.responses)
        if pp is not None:
            arrays[f"pp_outputs{label}"] = pp
            columns[f"pp_outputs{label}"] = list(ctx.responses)
    scalars.update(_input_scalars(ctx.space))
    return StepResult(ctx.name, ctx.type, scalars, arrays, meta={
        "columns": columns, "n_evaluations": n_eval, "labels": labels,
        "sweep": sweep, "normalized": norm_row is not None,
        "joint_predictive": draws is not None})


# A response whose std is below this fraction of |mean| has negligible variance: its Sobol
# indices split up numerical noise and mean nothing physically.
NEGLIGIBLE_CV = 1e-4


def output_spread_scalars(responses: Sequence[str], mean, variance) -> dict:
    """``out_mean``, ``out_var``, ``out_std``, ``out_cv`` (std / |mean|) per response and
    ``negligible/<r>`` = 1 when the CV is below :data:`NEGLIGIBLE_CV`."""
    out = {}
    for k, r in enumerate(responses):
        m, v = float(mean[k]), float(variance[k])
        sd = float(np.sqrt(max(v, 0.0)))
        cv = sd / abs(m) if m != 0 else np.inf
        out.update({f"out_mean/{r}": m, f"out_var/{r}": v, f"out_std/{r}": sd,
                    f"out_cv/{r}": cv, f"negligible/{r}": float(cv < NEGLIGIBLE_CV)})
    return out


def run_sensitivity(ctx: StepContext) -> StepResult:
    """Sobol main and total indices as estimated (negative estimates kept), their bootstrap
    intervals, and the output mean/variance/CV that says whether they mean anything."""
    from ..methods.sensitivity import sobol_indices

    o = ctx.options
    res = sobol_indices(ctx.model(), ctx.space, o["n_samples"], estimator=o["estimator"],
                        design=o["design"], seed=ctx.rng)
    main, total = np.asarray(res.main), np.asarray(res.total)
    main_ci, total_ci = np.asarray(res.main_ci), np.asarray(res.total_ci)
    scalars = output_spread_scalars(ctx.responses, res.mean, res.variance)
    for k, r in enumerate(ctx.responses):
        for j, p in enumerate(ctx.space.names):
            scalars[f"S/{r}/{p}"] = float(main[k, j])
            scalars[f"T/{r}/{p}"] = float(total[k, j])
            scalars[f"S_lo/{r}/{p}"], scalars[f"S_hi/{r}/{p}"] = map(float, main_ci[k, j])
            scalars[f"T_lo/{r}/{p}"], scalars[f"T_hi/{r}/{p}"] = map(float, total_ci[k, j])
    scalars.update(_input_scalars(ctx.space))
    return StepResult(ctx.name, ctx.type, scalars, {"main": main, "total": total}, meta={
        "inputs": list(ctx.space.names), "responses": list(ctx.responses),
        "confidence": float(res.confidence),
        "n_evaluations": int(getattr(res, "n_evaluations", 0))})


def run_mean_value(ctx: StepContext) -> StepResult:
    from ..methods.reliability import mean_value

    o = ctx.options
    res = mean_value(ctx.model(), ctx.space, response_levels=o.get("response_levels"),
                     probability_levels=o.get("probability_levels"))
    scalars = {}
    for k, r in enumerate(ctx.responses):
        scalars[f"mean/{r}"] = float(res.mean[k])
        scalars[f"std/{r}"] = float(res.std[k])
        for j, p in enumerate(ctx.space.names):
            scalars[f"importance/{r}/{p}"] = float(res.importance[k, j])
    scalars.update(_input_scalars(ctx.space))
    return StepResult(ctx.name, ctx.type, scalars, {"gradient": np.asarray(res.gradient)},
                      meta={"n_evaluations": int(res.n_evaluations)})


def run_reliability(ctx: StepContext) -> StepResult:
    """MPP search (RIA for response levels, PMA for probability levels) with FORM/SORM."""
    from ..methods.reliability import mpp_search

    o = ctx.options
    res = mpp_search(ctx.model(), ctx.space, response_levels=o.get("response_levels"),
                     probability_levels=o.get("probability_levels"),
                     integration=o["integration"])
    scalars = {}
    for r in ctx.responses:
        for what in ("response_levels", "cdf_probability", "cdf_reliability",
                     "generalized_reliability", "probability_levels", "probability_response"):
            vals = getattr(res, what, {}).get(r)
            if vals is not None:
                for i, v in enumerate(np.atleast_1d(vals)):
                    scalars[f"{what}/{r}/{i}"] = float(v)
    return StepResult(ctx.name, ctx.type, scalars, meta={
        "n_evaluations": int(getattr(res, "n_evaluations", 0))})


def run_pce(ctx: StepContext) -> StepResult:
    """Polynomial chaos of total order ``order`` by ``estimator`` (quadrature, sparse grid,
    or regression on ``n_samples`` LHS points)."""
    from ..methods.pce import polynomial_chaos

    o = ctx.options
    res = polynomial_chaos(ctx.model(), ctx.space, o["order"], estimator=o["estimator"],
                           n_samples=o["n_samples"], seed=ctx.rng)
    scalars = {}
    for k, r in enumerate(ctx.responses):
        scalars[f"mean/{r}"] = float(res.mean[k])
        scalars[f"std/{r}"] = float(res.std[k])
        for j, p in enumerate(ctx.space.names):
            scalars[f"S/{r}/{p}"] = float(res.main[k, j])
            scalars[f"T/{r}/{p}"] = float(res.total[k, j])
    scalars.update(_input_scalars(ctx.space))
    return StepResult(ctx.name, ctx.type, scalars, {"main": np.asarray(res.main),
                                                    "total": np.asarray(res.total)}, meta={
        "inputs": list(ctx.space.names), "responses": list(ctx.responses),
        "n_evaluations": int(res.n_evaluations)})


def run_evidence(ctx: StepContext) -> StepResult:
    """Dempster-Shafer evidence: ``intervals = {x = [[lo, hi, bpa], ...]}`` per input."""
    from ..methods.evidence import evidence
    from ..params import Interval

    o = ctx.options
    space = ParameterSpace([
        (p, Interval(tuple((float(lo), float(hi)) for lo, hi, _ in cells),
                     tuple(float(w) for _, _, w in cells)))
        for p, cells in o["intervals"].items()])
    fixed = dict(ctx.fixed)
    fixed.update({p: d.mean for p, d in zip(ctx.space.names, ctx.space.distributions,
                                             strict=True) if p not in space.names})
    res = evidence(ctx.make_model(space.names, ctx.responses, fixed), space,
                   response_levels=o.get("response_levels"), n_samples=o["n_samples"], seed=ctx.rng)
    scalars = {}
    for r in ctx.responses:
        for what in ("response_levels", "cbf", "cpf"):
            for i, v in enumerate(np.atleast_1d(getattr(res, what).get(r, []))):
                scalars[f"{what}/{r}/{i}"] = float(v)
    return StepResult(ctx.name, ctx.type, scalars, meta={"n_evaluations": int(res.n_evaluations)})


def chain_diagnostic_scalars(names: Sequence[str], chain: np.ndarray,
                             prior: ParameterSpace) -> dict:
    """Diagnostics of a posterior sample ``chain`` (N, d) against its ``prior``:

    ``std_ratio/p`` posterior std / prior std (near 1: the data do not inform p);
    ``prior_z/p`` (posterior mean - prior mean) / prior std (beyond 3: the posterior left the
    prior's bulk); ``pileup_lo/p``, ``pileup_hi/p`` fraction of the chain in the outer 5 % of
    a bounded prior's range at each end (0.05 for a flat posterior; much more: the posterior
    piles up against the bound); ``corr/p/q`` posterior correlation.
    """
    out = {}
    chain = np.asarray(chain, dtype=float)
    for j, p in enumerate(names):
        d = prior[p]
        x = chain[:, j]
        out[f"std_ratio/{p}"] = float(np.std(x, ddof=1) / d.std) if d.std > 0 else np.nan
        out[f"prior_z/{p}"] = float((np.mean(x) - d.mean) / d.std) if d.std > 0 else np.nan
        lo, hi = d.bounds
        if np.isfinite(lo) and np.isfinite(hi) and hi > lo:
            band = 0.05 * (hi - lo)
            out[f"pileup_lo/{p}"] = float(np.mean(x < lo + band))
            out[f"pileup_hi/{p}"] = float(np.mean(x > hi - band))
    if chain.shape[1] > 1:
        c = np.corrcoef(chain, rowvar=False)
        for i, p in enumerate(names):
            for j in range(i + 1, len(names)):
                out[f"corr/{p}/{names[j]}"] = float(c[i, j])
    return out


def run_bayes_calibration(ctx: StepContext) -> StepResult:
    """Bayes calibration (DRAM on a GP emulator by default). The chain is saved (later forward
    checks push its joint samples through the model); the distributions handed on are the
    normals with the chain's mean and std, as the reference study does (its table 4.15)."""
    import warnings

    from ..methods.mcmc import calibrate_bayes

    o = ctx.options
    emulator = None
    if o["emulator"] == "gp":
        from ..methods.surrogate import GaussianProcess

        emulator = GaussianProcess(trend=o["trend"])
    sd = _per_response(o.get("noise_std"), ctx.responses)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = calibrate_bayes(
            ctx.model(), ctx.observations(), ctx.space, sampler=o["sampler"], emulator=emulator,
            n_emulator_samples=o["n_emulator_samples"], n_samples=o["n_samples"],
            burn_in=o["burn_in"], noise_std=sd,
            proposal_covariance=o["proposal"], seed=ctx.rng,
        )
    chain = np.asarray(res.chains).reshape(-1, ctx.space.dim)
    scalars = _input_scalars(ctx.space)
    for j, p in enumerate(res.names_in):
        for what in ("mean", "std", "skewness", "kurtosis", "ess", "rhat"):
            scalars[f"{what}/{p}"] = float(np.asarray(getattr(res, what))[j])
        scalars[f"map/{p}"] = float(res.map_point[j])
    scalars["acceptance"] = float(res.acceptance_rate)
    scalars["kl_divergence"] = float(res.kl_divergence)
    scalars.update(chain_diagnostic_scalars(res.names_in, chain, ctx.space))
    loo = getattr(res, "emulator_loo", None)
    if loo is not None:
        for k, r in enumerate(ctx.responses):
            scalars[f"loo_q2/{r}"] = float(np.asarray(loo.q2)[k])
            scalars[f"loo_nrmse/{r}"] = float(np.asarray(loo.nrmse)[k])
    noise = (np.ones(len(ctx.responses)) if sd is None else
             np.broadcast_to(np.asarray(sd, dtype=float), (len(ctx.responses),)))
    for r, v in zip(ctx.responses, noise, strict=True):
        scalars[f"noise_std/{r}"] = float(v)
    posterior = {p: dist_to_dict(Normal(scalars[f"mean/{p}"], scalars[f"std/{p}"]))
                 for p in res.names_in}
    arrays = {"chain": chain, "data": np.asarray(ctx.data)}
    columns = {"chain": list(res.names_in), "data": list(ctx.responses)}
    return StepResult(ctx.name, ctx.type, scalars, arrays, posterior, meta={
        "columns": columns, "n_evaluations": int(res.n_evaluations),
        "noise_model": "unit variance (none given)" if sd is None else "noise_std per response",
        "warnings": sorted({f"{w.category.__name__}: {w.message}" for w in caught})[:10],
        "prior": {p: dist_to_dict(d) for p, d in zip(ctx.space.names, ctx.space.distributions,
                                                      strict=True)}})


def _per_response(value, responses):
    if value is None or not isinstance(value, Mapping):
        return value
    return np.array([float(value[r]) for r in responses])


def run_least_squares(ctx: StepContext) -> StepResult:
    from ..methods.least_squares import calibrate

    o = ctx.options
    sd = _per_response(o.get("noise_std"), ctx.responses)
    res = calibrate(
        ctx.model(), ctx.observations(), ctx.space, noise_std=sd,
        optimizer=o["optimizer"], max_iterations=o["max_iterations"],
        max_function_evaluations=o["max_function_evaluations"],
        tolerance=o["tolerance"],
    )
    scalars = {}
    calibrated = {}
    for j, p in enumerate(res.names_in):
        scalars[f"value/{p}"] = float(res.x[j])
        s = float(res.std[j])
        scalars[f"std/{p}"] = s
        sd_p = s if np.isfinite(s) and s > 0 else ctx.space[p].std
        calibrated[p] = dist_to_dict(Normal(float(res.x[j]), sd_p))
    scalars["cost"] = float(res.cost)
    return StepResult(ctx.name, ctx.type, scalars, {"residuals": np.asarray(res.residuals)},
                      calibrated, meta={"n_evaluations": int(res.n_evaluations),
                                        "converged": bool(res.converged), "message": res.message})


def run_cuu(ctx: StepContext) -> StepResult:
    """Calibration under uncertainty (nested: inner mean value, outer least squares), then
    LHS checks of the response statistics with the initial and the calibrated inputs."""
    from ..methods.cuu import calibrate_under_uncertainty
    from ..methods.sampling import sample

    o = ctx.options
    model = ctx.model()
    targets = {r: ctx.targets[r] for r in ctx.responses if r in ctx.targets}
    stats_ = ["std"] if o["calibrate"] == "std" else (
        ["mean"] if o["calibrate"] == "mean" else ["mean", "std"])
    res = calibrate_under_uncertainty(
        model, ctx.space, calibrate={p: stats_ for p in ctx.space.names},
        targets={r: {"mean": m, "std": s} if "mean" in stats_ else {"std": s}
                 for r, (m, s) in targets.items()},
        inner=o["inner"],
        optimizer=o["optimizer"], max_iterations=o["max_iterations"],
        tolerance=o["tolerance"], seed=ctx.rng,
    )
    cal_space: ParameterSpace = res.space
    scalars = {}
    for p in ctx.space.names:
        scalars[f"initial_mean/{p}"] = ctx.space[p].mean
        scalars[f"initial_std/{p}"] = ctx.space[p].std
        scalars[f"mean/{p}"] = cal_space[p].mean
        scalars[f"std/{p}"] = cal_space[p].std
    for r, (m, s) in targets.items():
        scalars[f"target_mean/{r}"] = float(m)
        scalars[f"target_std/{r}"] = float(s)
    arrays, columns = {}, {}
    n = o.get("verify_samples", 0)
    if n:
        for tag, space in (("initial", ctx.space), ("calibrated", cal_space)):
            checked = sample(model, space, n, design=o["design"], seed=ctx.rng)
            out = np.asarray(checked.outputs)
            for k, r in enumerate(ctx.responses):
                v = out[:, k][np.isfinite(out[:, k])]
                scalars[f"{tag}_out_mean/{r}"] = float(np.mean(v))
                scalars[f"{tag}_out_std/{r}"] = float(np.std(v, ddof=1))
            arrays[f"outputs_{tag}"] = out
            columns[f"outputs_{tag}"] = list(ctx.responses)
    calibrated = {p: dist_to_dict(d) for p, d in zip(cal_space.names, cal_space.distributions,
                                                      strict=True)}
    return StepResult(ctx.name, ctx.type, scalars, arrays, calibrated, meta={
        "columns": columns, "n_evaluations": int(res.n_evaluations),
        "identifiable": bool(res.identifiable), "diagnostic": res.diagnostic,
        "condition_number": float(res.condition_number), "message": res.message})
