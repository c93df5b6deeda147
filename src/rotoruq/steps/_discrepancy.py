"""The discrepancy branch of the ``bayes_calibration`` step (``discrepancy = {...}``): Bayes
calibration jointly with a Kennedy-O'Hagan additive discrepancy over a configuration variable,
its record, tables and warnings.

The step's data rows carry the configuration (``configuration = "height_over_radius"``: a
data column and a model input); inputs that vary with it in the experiment (the GVPM rotor's
speed per height) follow it through ``couple = { omega = "omega" }``: model input -> data
column, interpolated linearly in the configuration over the data's rows. Rows at a
``predict_at`` configuration are **held out**: the calibration does not see them, the
predictions there are out-of-sample. Predictions are made at the data's configurations and at
``predict_at``, with the discrepancy (``eta + delta``) and without it (``eta``); a later
``validation`` step validates both. ``n_samples`` kept steps are split over two chains.
``kind = "none"`` runs the same calibration over the configurations without a discrepancy
(the comparison a reader needs).

With ``emulator = "gp"`` (the step's default) the chains run on a GP emulator of the model
(``n_emulator_samples`` LHS points of the prior, each run at every data configuration; its
Kriging variance in the likelihood with ``emulator_variance``), checked by its leave-one-out
error and against the model at the posterior draws; ``emulator = "none"``: on the model
itself. The posterior draws and the predictions run the model itself either way.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import ParameterError
from ..params import Normal
from ..render.tables import StepTable, label, make_table
from ..results import StepRecord, StepResult, dist_to_dict
from ._common import chain_on_model, per_response
from .base import StepCheck, StepContext

__all__ = ["DiscrepancyRecord", "run_discrepancy", "discrepancy_tables",
           "discrepancy_warnings", "discrepancy_option", "check_discrepancy", "is_discrepancy",
           "extrapolation_distance", "extrapolation_note", "N_CHAINS", "BAND_LEVEL",
           "N_DRAWS"]

#: Chains the kept steps are split over (R-hat across chains).
N_CHAINS = 2
#: Level of the predictive bands recorded.
BAND_LEVEL = 0.9
#: Posterior draws of the predictions.
N_DRAWS = 1000

_KEYS = ("kind", "kernel", "degree", "amplitude_scale", "length_scale", "length_scale_log_std")


def discrepancy_option(v):
    """Option checker of ``discrepancy = { kind, kernel, degree, amplitude_scale, length_scale,
    length_scale_log_std }`` (amplitude_scale: a number or one per response)."""
    if not isinstance(v, dict):
        raise TypeError("a table { kind = \"gp\", amplitude_scale = { response = number }, "
                        "length_scale = number, ... }")
    bad = [k for k in v if k not in _KEYS]
    if bad:
        raise TypeError(f"a table with keys among {', '.join(_KEYS)} (found {', '.join(bad)})")
    if v.get("kind", "gp") not in ("gp", "polynomial", "none"):
        raise TypeError("kind = \"gp\", \"polynomial\" or \"none\" (the same calibration over "
                        "the configurations without a discrepancy)")
    if v.get("kernel", "squared_exponential") not in ("squared_exponential", "matern52"):
        raise TypeError("kernel = \"squared_exponential\" or \"matern52\"")
    for k in ("length_scale", "length_scale_log_std"):
        x = v.get(k)
        if x is not None and (isinstance(x, bool) or not isinstance(x, int | float) or x <= 0):
            raise TypeError(f"{k} = a number > 0")
    a = v.get("amplitude_scale")
    vals = a.values() if isinstance(a, dict) else [] if a is None else [a]
    if any(isinstance(x, bool) or not isinstance(x, int | float) or x <= 0 for x in vals):
        raise TypeError("amplitude_scale = a number > 0 or { response = number > 0 }")
    d = v.get("degree", 1)
    if isinstance(d, bool) or not isinstance(d, int) or d < 0:
        raise TypeError("degree = an integer >= 0")
    return dict(v)


def check_discrepancy(c: StepCheck) -> None:
    """Study-file checks of the discrepancy options (file/line errors): ``configuration``
    and the keys of ``couple`` must be inputs of the model; ``discrepancy``, ``configuration``,
    ``couple`` and ``predict_at`` go together."""
    o = c.options
    if o.get("discrepancy") is None:
        for key in ("configuration", "couple", "predict_at"):
            if o.get(key) is not None:
                c.fail((key,), f"{key} only with discrepancy = {{ ... }} (kind = \"none\" for a "
                       "calibration over the configurations without one)")
        return
    if not o.get("configuration"):
        c.fail(("discrepancy",), "configuration = \"<the model input that varies between "
               "experiments, e.g. height_over_radius>\" beside discrepancy")
    c.check_input(("configuration",), o["configuration"])
    if o.get("emulator") == "cokriging":
        c.fail(("emulator",), "emulator = \"gp\" or \"none\" beside discrepancy (a "
               "co-kriging emulator is not supported there)", "\"cokriging\"")
    if o.get("refine") is not None:
        c.fail(("refine",), "no refine = {...} beside discrepancy (the emulator is checked "
               "against the model at the posterior draws instead)")
    for key, col in (o.get("couple") or {}).items():
        c.check_input(("couple", key), key)
        if not isinstance(col, str):
            c.fail(("couple", key), f"{key} = \"<a data column>\"", repr(col))


def extrapolation_distance(points: np.ndarray, calibrated: np.ndarray) -> np.ndarray:
    """How far each of ``points`` (q,) lies outside the range of the ``calibrated``
    configurations (configuration units; 0 inside, NaN when nothing was calibrated)."""
    pts = np.asarray(points, dtype=float)
    cal = np.asarray(calibrated, dtype=float)
    if cal.size == 0:
        return np.full(pts.shape, np.nan)
    return np.maximum(0.0, np.maximum(cal.min() - pts, pts - cal.max()))


def extrapolation_note(distance: float, span: float, unit: str = "") -> str:
    """An extrapolation in words: its distance beyond the calibrated range, and how the
    discrepancy-aware 90 % band covered the truth in extrapolation on the literature's
    model-error problems (``rotoruq/data/discrepancy_coverage.json``, written by
    ``benchmarks/discrepancy_coverage.py``), with how far that falls short of 85 %."""
    import json
    from importlib import resources

    rel = f" ({distance / span:.2g} x the calibrated range)" if span > 0 else ""
    text = f"an extrapolation, {distance:g}{unit} beyond the calibrated range{rel}"
    try:
        cov = json.loads(resources.files("rotoruq.data").joinpath(
            "discrepancy_coverage.json").read_text())
    except (OSError, ValueError):
        return text
    vals = {n: float(p["coverage"]) for n, p in cov.get("problems", {}).items()}
    if not vals:
        return text
    lo, hi, target = min(vals.values()), max(vals.values()), float(cov.get("target", 0.85))
    text += (f"; on {len(vals)} model-error problems of the literature, in extrapolation, "
             f"the {100 * float(cov.get('level', 0.9)):g} % band with the discrepancy "
             f"covered the truth {lo:.2f} to {hi:.2f} of the time over "
             f"{cov.get('replications')} replications ({cov.get('benchmark')})")
    if lo < target:
        text += f", {target - lo:.2f} short of {target:g} at worst: read the band as narrower "
        text += "than its level says"
    return text


def is_discrepancy(res: StepResult) -> bool:
    """Whether ``res`` is a Bayes step calibrated through this branch."""
    rec = res.meta.get("record")
    return isinstance(rec, Mapping) and rec.get("type") == "DiscrepancyRecord"


def _empty() -> np.ndarray:
    return np.zeros(0)


@dataclass(frozen=True, eq=False)
class DiscrepancyRecord(StepRecord):
    """What a Bayes step with a discrepancy saves: d parameters, h hyperparameters,
    m responses, c data configurations, q predicted configurations.

    kind : "gp", "polynomial". configuration : the configuration variable.
    chains (chain, sample, d), hyper_chains (chain, sample, h) : the kept samples.
    mean, std, std_ratio_to_prior, std_without_discrepancy, std_ratio_to_no_discrepancy (d).
    ess, rhat (d + h) : in the order names_in + hyper_names. level_correlation (d, m) : the
    posterior correlation of each parameter with the discrepancy's mean level; confounded (d)
    1.0 / 0.0; identifiability : the finding in words. noise_std (m).
    data_configurations (c) : the configurations calibrated on; held_out : the configurations
    of data rows left out (at predict_at). predict_configurations (q) : where predicted.
    pred_model, pred_discrepancy, pred_noise (draw, q, m) : eta, delta and a new
    measurement's noise at posterior draws. band_lower, band_upper, band_lower_without,
    band_upper_without (q, m) : the :data:`BAND_LEVEL` band of a new measurement with and
    without the discrepancy. measured (q, m) : the data's mean there (NaN: no data).
    acceptance_rate; level : :data:`BAND_LEVEL`. emulator_runs : the emulator's design runs
    (0: the chains ran the model); emulator_loo_ratio, emulator_posterior_ratio (m) : its
    largest leave-one-out RMS error over the data configurations and its RMS error against
    the model at the posterior draws, over the noise std (empty: no emulator).
    quantities (d + h) : names_in + hyper_names, the labels of ``ess`` and ``rhat``.
    map_point (d) : the chains' start. std_ratio, prior_z, pileup_lo, pileup_hi (d) : the
    chain against the prior (:func:`~rotoruq.steps.bayes_calibration.chain_diagnostics`);
    correlation (d, d) : the parameters' posterior correlation. noise_model : in words.
    prediction_labels (q) : ``@<configuration>`` of each prediction; inside_band (m, q) :
    1.0 / 0.0 whether the measured mean lies in the band with the discrepancy (NaN: no data).
    extrapolation (q) : how far each prediction lies outside the calibrated configurations
    (configuration units, 0 inside; :func:`extrapolation_distance`).

    The flat view: ``mean/<p>``, ``ess/<p or hyperparameter>``, ``map/<p>``,
    ``corr/<p>/<q>``, ``noise_std/<r>``, ``inside_band/<r>@<configuration>``, ...; not the
    chains, the prediction draws or the bands.
    """

    AXES = {"chains": ("chain", "sample", "parameter"),
            "hyper_chains": ("chain", "sample", "hyperparameter"),
            "mean": ("parameter",), "std": ("parameter",),
            "std_ratio_to_prior": ("parameter",), "std_without_discrepancy": ("parameter",),
            "std_ratio_to_no_discrepancy": ("parameter",), "ess": ("quantity",),
            "rhat": ("quantity",), "level_correlation": ("parameter", "response"),
            "confounded": ("parameter",), "noise_std": ("response",),
            "data_configurations": ("configuration",), "held_out": ("held_out",),
            "predict_configurations": ("prediction",),
            "pred_model": ("draw", "prediction", "response"),
            "pred_discrepancy": ("draw", "prediction", "response"),
            "pred_noise": ("draw", "prediction", "response"),
            "band_lower": ("prediction", "response"), "band_upper": ("prediction", "response"),
            "band_lower_without": ("prediction", "response"),
            "band_upper_without": ("prediction", "response"),
            "measured": ("prediction", "response"),
            **{k: ("parameter",) for k in ("map_point", "std_ratio", "prior_z", "pileup_lo",
                                            "pileup_hi")},
            "correlation": ("parameter", "parameter"), "inside_band": ("response", "prediction"),
            "extrapolation": ("prediction",), "emulator_loo_ratio": ("response",),
            "emulator_posterior_ratio": ("response",)}
    FLAT = {**{k: None for k in (
        "chains", "hyper_chains", "data_configurations", "held_out", "predict_configurations",
        "pred_model", "pred_discrepancy", "pred_noise", "band_lower", "band_upper",
        "band_lower_without", "band_upper_without", "measured")},
        "acceptance_rate": "acceptance", "map_point": "map", "correlation": "corr"}
    LABELS = {"quantity": "quantities", "prediction": "prediction_labels"}

    kind: str
    configuration: str
    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    hyper_names: tuple[str, ...]
    chains: np.ndarray
    hyper_chains: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    std_ratio_to_prior: np.ndarray
    std_without_discrepancy: np.ndarray
    std_ratio_to_no_discrepancy: np.ndarray
    ess: np.ndarray
    rhat: np.ndarray
    level_correlation: np.ndarray
    confounded: np.ndarray
    identifiability: str
    noise_std: np.ndarray
    data_configurations: np.ndarray
    held_out: np.ndarray
    predict_configurations: np.ndarray
    pred_model: np.ndarray
    pred_discrepancy: np.ndarray
    pred_noise: np.ndarray
    band_lower: np.ndarray
    band_upper: np.ndarray
    band_lower_without: np.ndarray
    band_upper_without: np.ndarray
    measured: np.ndarray
    acceptance_rate: float
    level: float
    # added since the first records: an older record reads them empty
    quantities: tuple[str, ...] = ()
    map_point: np.ndarray = field(default_factory=_empty)
    std_ratio: np.ndarray = field(default_factory=_empty)
    prior_z: np.ndarray = field(default_factory=_empty)
    pileup_lo: np.ndarray = field(default_factory=_empty)
    pileup_hi: np.ndarray = field(default_factory=_empty)
    correlation: np.ndarray = field(default_factory=_empty)
    noise_model: str = ""
    prediction_labels: tuple[str, ...] = ()
    inside_band: np.ndarray = field(default_factory=_empty)
    extrapolation: np.ndarray = field(default_factory=_empty)
    emulator_runs: int = 0
    emulator_loo_ratio: np.ndarray = field(default_factory=_empty)
    emulator_posterior_ratio: np.ndarray = field(default_factory=_empty)


def _coupled_model(ctx: StepContext, configuration: str, couple: Mapping[str, str]):
    """The model over (parameters, configuration); coupled inputs follow the configuration
    (linear interpolation of their data columns)."""
    from ..model import FunctionModel

    cols = ctx.data_columns
    if configuration not in cols:
        raise ParameterError(f"step {ctx.name!r}: configuration = {configuration!r} is not a "
                             f"column of its data set ({', '.join(cols)})")
    x = np.asarray(cols[configuration], dtype=float)
    order = np.argsort(x)
    coupled = {}
    for inp, col in couple.items():
        if col not in cols:
            raise ParameterError(f"step {ctx.name!r}: couple = {{ {inp} = {col!r} }}: no such "
                                 f"data column ({', '.join(cols)})")
        coupled[inp] = np.asarray(cols[col], dtype=float)[order]
    names = [*ctx.space.names, configuration, *coupled]
    fixed = {k: v for k, v in ctx.fixed.items() if k not in names}
    inner = ctx.make_model(names, ctx.responses, fixed)
    xs = x[order]

    def f(z: np.ndarray) -> np.ndarray:
        extra = [np.interp(z[:, -1], xs, v) for v in coupled.values()]
        return np.asarray(inner(np.column_stack([z, *extra]) if extra else z), dtype=float)

    return FunctionModel(f, [*ctx.space.names, configuration], list(ctx.responses)), inner


def run_discrepancy(ctx: StepContext) -> StepResult:
    """Bayes calibration with a discrepancy (the ``bayes_calibration`` step with
    ``discrepancy = {...}``); see the module docstring."""
    from ..methods.mcmc.discrepancy import Discrepancy, calibrate_with_discrepancy

    o = ctx.options
    spec = dict(o["discrepancy"])
    configuration = o.get("configuration")
    if not configuration:
        raise ParameterError(f"step {ctx.name!r}: discrepancy = {{...}} needs configuration = "
                             "\"<the model input that varies between experiments>\"")
    amp = spec.get("amplitude_scale")
    if isinstance(amp, Mapping):
        missing = [r for r in ctx.responses if r not in amp]
        if missing:
            raise ParameterError(f"step {ctx.name!r}: discrepancy amplitude_scale has no value "
                                 f"for {missing}")
        spec["amplitude_scale"] = tuple(float(amp[r]) for r in ctx.responses)
    kind = spec.get("kind", "gp")
    form = None if kind == "none" else Discrepancy(**spec)
    model, inner = _coupled_model(ctx, configuration, o.get("couple") or {})
    x = np.asarray(ctx.data_columns[configuration], dtype=float)
    y = ctx.observations()
    predict = np.asarray(o.get("predict_at") or [], dtype=float)
    held = np.zeros(x.size, dtype=bool)
    for v in predict:
        held |= np.isclose(x, v)
    if held.all():
        raise ParameterError(f"step {ctx.name!r}: every data row lies at a predict_at "
                             "configuration; nothing is left to calibrate on")
    at = np.unique(np.concatenate([x[~held], predict]))
    n_samples = max(2, int(o["n_samples"]) // N_CHAINS)
    emulator = None
    if o.get("emulator", "none") != "none":
        from ..methods.mcmc import EmulatorOptions
        from ..methods.surrogate import GaussianProcess

        emulator = EmulatorOptions(GaussianProcess(trend=o["trend"]),
                                   n_emulator_samples=o["n_emulator_samples"],
                                   emulator_variance=o["emulator_variance"])
    # the design, the posterior draws and the predictions run the model (the chains too
    # without an emulator): not worth a row each in the store
    with chain_on_model(inner):
        res = calibrate_with_discrepancy(
            model, y[~held], ctx.space, configurations=x[~held], configuration_name=configuration,
            discrepancy=form, noise_std=per_response(o.get("noise_std"), ctx.responses),
            names_out=ctx.responses, sampler=o["sampler"], n_samples=n_samples,
            burn_in=int(o["burn_in"]) // N_CHAINS, n_chains=N_CHAINS, n_draws=N_DRAWS,
            predict_at=at, seed=ctx.rng, emulator=emulator)
    p = res.prediction
    assert p is not None
    lo, hi = p.interval(BAND_LEVEL)
    lo_w, hi_w = p.interval(BAND_LEVEL, discrepancy=False)
    measured = np.full((at.size, len(ctx.responses)), np.nan)
    for j, v in enumerate(at):
        rows = np.isclose(x, v)
        if rows.any():
            measured[j] = y[rows].mean(axis=0)
    inside = np.full((len(ctx.responses), at.size), np.nan)
    for k in range(len(ctx.responses)):
        for j in range(at.size):
            if np.isfinite(measured[j, k]):
                inside[k, j] = float(lo[j, k] <= measured[j, k] <= hi[j, k])
    from .bayes_calibration import chain_diagnostics  # it imports this module

    chain = res.samples
    names_in, hyper = tuple(res.names_in), tuple(res.hyper_names)
    rec = DiscrepancyRecord(
        kind=kind, configuration=configuration, names_in=names_in,
        names_out=tuple(res.names_out), hyper_names=hyper,
        chains=res.chains, hyper_chains=res.hyper_chains, mean=res.mean, std=res.std,
        std_ratio_to_prior=res.std_ratio_to_prior,
        std_without_discrepancy=res.std_without_discrepancy,
        std_ratio_to_no_discrepancy=res.std_ratio_to_no_discrepancy, ess=res.ess,
        rhat=res.rhat, level_correlation=res.level_correlation,
        confounded=np.asarray(res.confounded, dtype=float), identifiability=res.identifiability,
        noise_std=res.noise_std, data_configurations=res.configurations,
        held_out=np.unique(x[held]), predict_configurations=at, pred_model=p.model_draws,
        pred_discrepancy=p.discrepancy_draws, pred_noise=p.noise_draws, band_lower=lo,
        band_upper=hi, band_lower_without=lo_w, band_upper_without=hi_w, measured=measured,
        acceptance_rate=float(res.acceptance_rate), level=BAND_LEVEL,
        quantities=names_in + hyper, map_point=np.asarray(res.map_point, dtype=float),
        **chain_diagnostics(names_in, chain, ctx.space),
        correlation=np.atleast_2d(np.corrcoef(np.asarray(chain, dtype=float), rowvar=False)),
        noise_model=("noise_std per response" if o.get("noise_std") is not None
                     else "pooled from the repeats") + (
            "" if emulator is None else " + the emulator's Kriging variance"
            if emulator.emulator_variance else ", the emulator's mean only"),
        prediction_labels=tuple(f"@{v:g}" for v in at), inside_band=inside,
        extrapolation=extrapolation_distance(at, res.configurations),
        emulator_runs=int(res.emulator_runs), emulator_loo_ratio=res.emulator_loo_ratio,
        emulator_posterior_ratio=res.emulator_posterior_ratio)
    arrays, meta = rec.parts()
    posterior = {n: dist_to_dict(Normal(float(res.mean[j]), float(res.std[j])))
                 for j, n in enumerate(names_in)}
    arrays.update(chain=chain, data=np.asarray(y))
    return StepResult(ctx.name, ctx.type, {}, arrays, posterior, meta={
        **meta, "columns": {"chain": list(names_in), "data": list(ctx.responses)},
        "n_evaluations": int(res.n_evaluations), "noise_model": rec.noise_model,
        "prior": {n: dist_to_dict(d) for n, d in zip(ctx.space.names, ctx.space.distributions,
                                                      strict=True)}})


def _cond(v: float, held: Sequence[float] | np.ndarray, far: float = 0.0) -> str:
    return (f"{v:g}" + (" (held out)" if np.any(np.isclose(held, v)) else "")
            + (f" (extrapolation, {far:g} beyond the calibrated range)" if far > 0 else ""))


def discrepancy_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    """Posterior and identifiability; predictions with and without the discrepancy."""
    rec = DiscrepancyRecord.read(res)
    d = len(rec.names_in)
    rows = [[label(p, labels), float(rec.mean[j]), float(rec.std[j]),
             float(rec.std_ratio_to_prior[j]), float(rec.std_ratio_to_no_discrepancy[j]),
             *[float(rec.level_correlation[j, k]) for k in range(len(rec.names_out))],
             "yes" if rec.confounded[j] else "no", float(rec.ess[j]), float(rec.rhat[j])]
            for j, p in enumerate(rec.names_in)]
    rows += [[h, "", "", "", "", *[""] * len(rec.names_out), "",
              float(rec.ess[d + i]), float(rec.rhat[d + i])]
             for i, h in enumerate(rec.hyper_names)]
    out = [make_table(
        f"Calibration with a {rec.kind} discrepancy over {rec.configuration}" if rec.kind !=
        "none" else f"Calibration over {rec.configuration} without a discrepancy",
        ("parameter", "posterior mean", "posterior std", "post/prior std",
         "std / std without discrepancy",
         *[f"corr with mean discrepancy of {r}" for r in rec.names_out], "confounded", "ESS",
         "R-hat"), rows,
        f"{rec.identifiability} Calibrated on {rec.configuration} = "
        + ", ".join(f"{v:g}" for v in rec.data_configurations)
        + (f"; held out: {', '.join(f'{v:g}' for v in rec.held_out)}" if rec.held_out.size
           else "") + f"; acceptance rate {rec.acceptance_rate:.2f}." + _emulator_note(rec))]
    prow = []
    for j, v in enumerate(rec.predict_configurations):
        for k, r in enumerate(rec.names_out):
            with_d = rec.pred_model[:, j, k] + rec.pred_discrepancy[:, j, k]
            meas = float(rec.measured[j, k])
            inside = ("-" if not np.isfinite(meas) else
                      "yes" if rec.band_lower[j, k] <= meas <= rec.band_upper[j, k] else "no")
            inside_w = ("-" if not np.isfinite(meas) else
                        "yes" if rec.band_lower_without[j, k] <= meas
                        <= rec.band_upper_without[j, k] else "no")
            far = float(rec.extrapolation[j]) if rec.extrapolation.size else 0.0
            prow.append([_cond(v, rec.held_out, far), r, meas,
                         float(np.mean(rec.pred_model[:, j, k])),
                         float(np.mean(rec.pred_discrepancy[:, j, k])),
                         float(np.std(with_d, ddof=1)),
                         f"[{rec.band_lower[j, k]:.4g}, {rec.band_upper[j, k]:.4g}]", inside,
                         f"[{rec.band_lower_without[j, k]:.4g}, "
                         f"{rec.band_upper_without[j, k]:.4g}]", inside_w])
    pct = f"{100 * rec.level:g} %"
    out.append(make_table(
        f"Predictions with and without the discrepancy ({rec.configuration})",
        ("configuration", "response", "measured", "model mean", "discrepancy mean",
         "std (model + discrepancy)", f"{pct} band with discrepancy", "measured inside",
         f"{pct} band without", "measured inside (without)"), prow,
        f"Bands of a new measurement (model + discrepancy + noise, or model + noise), "
        f"equal-tailed {pct}, {rec.pred_model.shape[0]} posterior draws."))
    return out


def _emulator_note(rec: DiscrepancyRecord) -> str:
    if not rec.emulator_runs:
        return " The chains ran the model itself."
    def each(v: np.ndarray) -> str:
        return ", ".join(f"{r} {float(x):.2g}" for r, x in zip(rec.names_out, v, strict=True))
    return (f" The chains ran a GP emulator of {rec.emulator_runs} model runs (noise model: "
            f"{rec.noise_model}); its RMS error "
            f"/ noise std: leave-one-out (worst configuration) {each(rec.emulator_loo_ratio)}; "
            f"against the model at the posterior draws {each(rec.emulator_posterior_ratio)}.")


def discrepancy_warnings(res: StepResult, labels: Mapping[str, str]) -> list[str]:
    """Confounded parameters; held-out measurements outside the discrepancy-aware band."""
    from .bayes_calibration import POSTERIOR_RATIO_MAX  # it imports this module

    rec = DiscrepancyRecord.read(res)
    w = []
    for what, ratio in (("at the posterior draws", rec.emulator_posterior_ratio),
                        ("leave-one-out", rec.emulator_loo_ratio)):
        poor = [f"{r} ({float(v):.2f})" for r, v in zip(rec.names_out, ratio, strict=True)
                if not float(v) <= POSTERIOR_RATIO_MAX] if ratio.size else []  # else: no emulator
        if poor:
            w.append(f"{res.name}: emulator error {what} above {POSTERIOR_RATIO_MAX} of the "
                     f"noise std: {', '.join(poor)}; add n_emulator_samples or set "
                     "emulator = \"none\"")
    conf = [label(p, labels) for j, p in enumerate(rec.names_in) if rec.confounded[j]]
    if conf:
        w.append(f"{res.name}: parameters confounded with the discrepancy: {', '.join(conf)} "
                 f"({rec.identifiability})")
    span = float(np.ptp(rec.data_configurations)) if rec.data_configurations.size else 0.0
    for j, v in enumerate(rec.predict_configurations):
        if rec.extrapolation.size and rec.extrapolation[j] > 0 and rec.kind != "none":
            w.append(f"{res.name}: the prediction at {rec.configuration} = {v:g} is "
                     + extrapolation_note(float(rec.extrapolation[j]), span))
        if not np.any(np.isclose(rec.held_out, v)):
            continue
        for k, r in enumerate(rec.names_out):
            m = float(rec.measured[j, k])
            if np.isfinite(m) and not rec.band_lower[j, k] <= m <= rec.band_upper[j, k]:
                w.append(f"{res.name}: held-out {r} at {rec.configuration} = {v:g} ({m:.4g}) "
                         f"lies outside the {100 * rec.level:g} % band "
                         + ("with the discrepancy " if rec.kind != "none" else
                            "(no discrepancy: model + noise) ")
                         + f"[{rec.band_lower[j, k]:.4g}, {rec.band_upper[j, k]:.4g}]")
    # the parameters' R-hat and ESS are the Bayes step's own warnings; these are the
    # hyperparameters'
    hyper = rec.rhat[len(rec.names_in):]
    bad = [f"{n} ({r:.3f})" for n, r in zip(rec.hyper_names, hyper, strict=True) if r > 1.01]
    if bad:
        w.append(f"{res.name}: discrepancy hyperparameters not mixed (R-hat above 1.01): "
                 f"{', '.join(bad)}")
    return w
