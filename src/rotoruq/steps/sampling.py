"""Step type ``sampling``: propagate the input distributions by a sampling design (LHS by
default), optionally with measurement noise added to the outputs.

``design = "file"`` with ``points = "points.dat"`` evaluates given points instead (a Dakota
tabular file or a CSV file, read by :func:`rotoruq.evaluation.tabular.read_table`): the
columns named as the step's inputs, in any order, other columns (``eval_id``, ``interface``,
responses) ignored; every point must lie in the support of its inputs' distributions.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..render.figures import Figure, FigureContext, load_distributions
from ..render.tables import MOMENTS, StepTable, inputs_table, make_table, moments_rows
from ..results import StepResult
from ._common import (
    LEVEL_OPTIONS,
    MOMENT_KEYS,
    MappingsRecord,
    check_levels,
    column_moments,
    input_arrays,
    level_request_of,
    mapping_fields,
    noise,
    saved_record,
)
from .base import DESIGNS, StepCheck, StepContext, StepType
from .forward_check import propagation_warnings
from .options import SIGNATURE, Option, choice, integer, number_or_table, string

__all__ = ["STEP", "SamplingRecord", "run_sampling", "sampling_tables", "sampling_figures",
           "given_points", "GIVEN"]

_SAMPLE = "rotoruq.methods.sampling:sample"
#: the ``design`` of a step that evaluates given points (``points = "file"``)
GIVEN = "file"


def given_points(ctx: StepContext) -> tuple[np.ndarray, str]:
    """The step's given points (n, d), columns in ``ctx.space.names`` order, and the file.

    ``ctx.options["points"]`` is ``{"file": <absolute path>, "sha256": <digest>}`` (the study
    file's ``points`` resolved when it was read; the digest puts the file's content in the
    step's fingerprint). Raises :class:`~rotoruq.errors.InputFileError` naming the file and
    the missing input column, or the line of a point outside its input's support.
    """
    from ..errors import InputFileError
    from ..evaluation.tabular import read_table

    spec = ctx.options["points"]
    path = Path(spec["file"])
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputFileError(path, None, "the points file the study names",
                             f"{type(exc).__name__}: {exc.strerror or exc}") from None
    if hashlib.sha256(raw).hexdigest() != spec["sha256"]:
        raise InputFileError(path, None, "the points file as it was when the study was read "
                             "(it changed since: run the study again)")
    table = read_table(path)
    names = list(ctx.space.names)
    x = table.require(names, f"the inputs of step {ctx.name!r}:")
    for j, (name, dist) in enumerate(zip(names, ctx.space.distributions, strict=True)):
        lo, hi = dist.bounds
        bad = np.flatnonzero(~((x[:, j] >= lo) & (x[:, j] <= hi)))
        if bad.size:
            k = int(bad[0])
            ident = "" if table.eval_id is None else f", eval_id {int(table.eval_id[k])}"
            raise InputFileError(
                path, table.line(k), f"point {k + 1}{ident}: {name} within the support "
                f"[{lo:g}, {hi:g}] of its {dist.kind} distribution ({bad.size} point(s) "
                "outside)", repr(float(x[k, j])))
    return x, str(path)


def check_sampling(ck: StepCheck) -> None:
    """``design = "file"`` needs ``points`` and no ``n_samples``; the other designs need
    ``n_samples`` and no ``points``."""
    o = ck.options
    if o["design"] == GIVEN:
        if o.get("points") is None:
            ck.fail((), 'points = "points.dat" (a Dakota tabular or CSV file) with '
                    'design = "file"')
        if o.get("n_samples") is not None:
            ck.fail(("n_samples",), 'no n_samples with design = "file" (the file gives the '
                    "points)", str(o["n_samples"]))
        if o.get("propagation", "joint") != "joint":
            ck.fail(("propagation",), 'no propagation with design = "file"')
    else:
        if o.get("points") is not None:
            ck.fail(("points",), f'design = "file" with points (design is {o["design"]!r})')
        if o.get("n_samples") is None:
            ck.fail((), "n_samples = <number of points> in a sampling step")
    check_levels(ck)


@dataclass(frozen=True, eq=False)
class SamplingRecord(MappingsRecord):
    """What a sampling step saves: n samples, d inputs, m responses.

    names_in (d), names_out (m); inputs (n, d) the propagated inputs; outputs (n, m) the
    responses at them, with the added noise (``outputs_clean``, saved beside the record when
    there is noise, holds them without). moments, noisy_moments (4, m): mean, std (ddof 1),
    skewness and excess kurtosis of the model's responses and of the noisy ones (NaN: too few
    finite values). noise_added : whether ``noise_std`` added noise. input_mean, input_std,
    input_lower, input_upper (d,) : the input distributions (bounds NaN when unbounded).
    propagation : "sampling" (the step's distributions), "joint" (a calibration's chain),
    "independent_normals" (normals of its moments) or "given_points" (``design = "file"``);
    dropped_correlation : (p, q, rho) the
    largest posterior correlation independent normals drop (None: none dropped). The level
    mappings (:class:`~rotoruq.steps._common.MappingsRecord`) of the saved ``outputs`` (with
    the noise), as Dakota's sampling computes them.
    """

    AXES = {"inputs": ("sample", "input"), "outputs": ("sample", "response"),
            "moments": ("statistic", "response"), "noisy_moments": ("statistic", "response"),
            "input_mean": ("input",), "input_std": ("input",), "input_lower": ("input",),
            "input_upper": ("input",), **MappingsRecord.AXES}
    # the flat view: ``mean/thrust`` (model outputs), ``noisy/mean/thrust`` (with the noise),
    # the level mappings; not the samples
    FLAT = {"inputs": None, "outputs": None, "moments": "", "noisy_moments": "noisy",
            **MappingsRecord.FLAT}
    LABELS = {"statistic": MOMENT_KEYS, **MappingsRecord.LABELS}

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    inputs: np.ndarray
    outputs: np.ndarray
    moments: np.ndarray
    noisy_moments: np.ndarray
    noise_added: bool
    input_mean: np.ndarray
    input_std: np.ndarray
    input_lower: np.ndarray
    input_upper: np.ndarray
    propagation: str
    dropped_correlation: tuple[str, str, float] | None


def run_sampling(ctx: StepContext) -> StepResult:
    """Propagate the step's inputs by a sampling design, or evaluate given points
    (``design = "file"``: :func:`given_points`); with ``from = "<bayes
    step>.posterior"`` and ``propagation = "joint"`` (default), the chain's own draws (thinned
    evenly, correlations kept) instead; ``"independent_normals"`` samples the normals of the
    posterior moments (the reference study) and warns with the correlation it drops."""
    from ..methods.levels import sample_mappings
    from ..methods.sampling import sample
    from ..model import evaluate
    from .forward_check import dropped_correlation, posterior_draws

    o = ctx.options
    propagation = o.get("propagation", "joint")
    meta: dict = {}
    given = o["design"] == GIVEN
    draws: np.ndarray | None
    if given:
        draws, meta["points_file"] = given_points(ctx)
    else:
        draws = posterior_draws(ctx.source, ctx.space.names, o["n_samples"])
    if draws is not None and (given or propagation == "joint"):
        ev = evaluate(ctx.model(), draws)
        inputs, clean = draws, np.array(ev.values, dtype=float)
        n_eval, n_fail = draws.shape[0], int(np.sum(~np.all(np.isfinite(clean), axis=1)))
        meta["propagation"] = "given_points" if given else "joint"
    else:
        res = sample(ctx.model(), ctx.space, o["n_samples"], design=o["design"],
                     seed=ctx.rng)
        inputs, clean = np.asarray(res.inputs), np.asarray(res.outputs)
        n_eval, n_fail = int(res.n_evaluations), len(res.failures)
        meta["propagation"] = "sampling" if draws is None else "independent_normals"
        dropped = None if draws is None else dropped_correlation(ctx.source, ctx.space.names)
        if dropped is not None:
            meta["dropped_correlation"] = list(dropped)
    noisy = clean + noise(ctx, o.get("noise_std"), clean.shape)
    moments, noisy_moments = column_moments(clean), column_moments(noisy)
    request = level_request_of(ctx)
    mappings = None if request is None else sample_mappings(noisy, request)
    dropped = meta.get("dropped_correlation")
    record = SamplingRecord(
        tuple(ctx.space.names), tuple(ctx.responses), inputs, noisy, moments, noisy_moments,
        bool(o.get("noise_std")), *input_arrays(ctx.space), meta["propagation"],
        None if dropped is None else (str(dropped[0]), str(dropped[1]), float(dropped[2])),
        **mapping_fields(mappings))
    arrays, rec_meta = record.parts()
    columns = {"inputs": list(ctx.space.names), "outputs": list(ctx.responses)}
    if o.get("noise_std"):
        arrays["outputs_clean"] = clean
        columns["outputs_clean"] = list(ctx.responses)
    return StepResult(ctx.name, ctx.type, {}, arrays, meta={
        "columns": columns, "n_evaluations": n_eval, "failures": n_fail, **meta, **rec_meta})


def sampling_tables(res: StepResult, labels: Mapping[str, str]) -> list[StepTable]:
    rec = SamplingRecord.read(res)
    note = {"joint": "Propagation: the calibration's chain, thinned (its correlations kept).",
            "independent_normals": "Propagation: independent normals of the posterior's "
                                   "means and stds (correlations dropped)."
            }.get(rec.propagation, "")
    out = [make_table("Response statistics (model outputs)", ("response", *MOMENTS),
                      moments_rows(rec.names_out, rec.moments), note)]
    if rec.noise_added:
        out.append(make_table("Response statistics with the added noise",
                              ("response", *MOMENTS),
                              moments_rows([f"noisy_{r}" for r in rec.names_out],
                                           rec.noisy_moments)))
    out.append(inputs_table(rec.names_in, rec.input_mean, rec.input_std, rec.input_lower,
                            rec.input_upper, labels))
    if rec.propagation == "given_points":
        out[0] = make_table(out[0].title, out[0].columns, out[0].rows,
                            f"Given points: {rec.inputs.shape[0]} points read from "
                            f"{Path(str(res.meta.get('points_file', '?'))).name} (no sampling "
                            "design).")
    out.extend(rec.mapping_tables(rec.names_out, "From the samples (Dakota's sampling "
                                  "conventions); reliabilities from the sample mean and std."))
    return out


def sampling_figures(res: StepResult, ctx: FigureContext) -> list[Figure]:
    """Distributions of the sampled responses."""
    rec = saved_record(SamplingRecord, res)
    if rec is None:
        return []
    return load_distributions(res.name, rec.names_out, [""], [rec.outputs], [None],
                              units=ctx.units)


STEP = StepType(
    "sampling", run_sampling, method=_SAMPLE, provides=("samples",), correlated=True,
    options={"n_samples": Option(integer(1), None),
             "design": Option(choice(*DESIGNS, GIVEN), SIGNATURE),
             "points": Option(string(), None),
             "noise_std": Option(number_or_table, 0.0),
             "propagation": Option(choice("joint", "independent_normals"), "joint"),
             **LEVEL_OPTIONS},
    quick={"n_samples": 40},
    check=check_sampling,
    tables=sampling_tables, figures=sampling_figures, warnings=propagation_warnings,
    modules=("rotoruq.methods.sampling", "rotoruq.methods.levels"))
