"""Multi-fidelity UQ with MBDyn (issue 26): MBDyn's elastic GVPM rotor as the high-fidelity
model, the built-in rotor and MBDyn's rigid-blade rotor as the low-fidelity ones.

Inputs (``--case narrow``, the study's): collective U(4.5, 6.5) deg and the lift slope
``cla_m03`` N(0.108, 5.4e-3) 1/deg, hover at 4R, the GVPM rotor speed. ``--case wide`` adds the
pitch-link stiffness U(8, 14) (the feathering system the models treat differently) and the air
density U(1.15, 1.25) kg/m^3, and widens the collective to U(3, 8) deg; ``--case cyclic`` is
the narrow box with 1 deg of each cyclic and the hub moments added to the responses. MBDyn's
rigid rotor takes part in the narrow case only (its template has no pitch link nor
swashplate). Responses: thrust and power (and roll, pitch).

``--adapt linear`` (default) adapts the cheap models to the elastic one on the pilot
(``rq.multifidelity_sample(adapt="linear")``); the same runs (MBDyn's served from memory, the
measured costs passed back) also give the estimator without adaptation
(``unadapted``) and two baselines that use no cheap model at all, from the pilot's
leave-one-out fit: a regression of the elastic response on the inputs (linear, and quadratic
where the pilot has the points), i.e. the HF-run saving of a control variate on the inputs
(``inputs_only``): quoted so that the share of the multi-fidelity gain the built-in model
brings is visible.
Each model's cost is measured in the pilot (wall seconds per point: MBDyn run in-process
through :func:`rotoruq.mbdyn.run_case`, template filled, c81 written, loads extracted; the
built-in rotor batched). ``rq.multifidelity_sample`` (MFMC by default) spends ``--budget``
high-fidelity runs' worth of time after a ``--pilot``-point pilot.

Printed per response: the estimates with their standard errors, the high-fidelity runs plain
Monte Carlo needs for the same standard error of the mean and of the variance
(``n_equivalent_hf``), and that over the cost actually spent counted in high-fidelity runs
(pilot included): the target is >= 10. The standard errors and the equivalent counts come
from the pilot's covariances (``--pilot`` points, so the correlations carry that sampling
error; the JSON gives them).

``predicted_at_larger_budgets``: the same rule on the pilot's covariances at budgets of 20 to
200 elastic runs (no further runs): the pilot's fixed cost weighs less as the budget grows.

Co-kriging: on the pilot's points, the first 4 or 8 elastic MBDyn runs train (with the
built-in rotor on those points plus ``--n-lf`` LHS points) a :class:`rotoruq.CoKriging` and a
GaussianProcess on the same high-fidelity runs; the last 8 are the holdout.

Needs MBDyn ($MBDYN, PATH, or ~/.cache/mbdyn/bin/mbdyn). Run (about 5 minutes on 2 cores):
python benchmarks/multifidelity_mbdyn.py > benchmarks/results/multifidelity_mbdyn.json
python benchmarks/multifidelity_mbdyn.py --case wide --pilot 24 \
    > benchmarks/results/multifidelity_mbdyn_wide.json
python benchmarks/multifidelity_mbdyn.py --case cyclic \
    > benchmarks/results/multifidelity_mbdyn_cyclic.json
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

import rotoruq as rq
from rotoruq.mbdyn import CaseSettings, find_mbdyn, run_case
from rotoruq.mbdyn.solver import MBDynError
from rotoruq.rotor.model import RotorModel
from rotoruq.rotor.presets import get_preset
from rotoruq.steps.multifidelity import why_dearer

RESPONSES = ("thrust", "power")
FIXED = {"height_over_radius": 4.0, "omega": 224.6375}
#: case -> (responses, fixed inputs added to FIXED, whether MBDyn's rigid rotor takes part: its
#: template has no swashplate nor pitch link, so not with cyclic or the link's stiffness)
CASE_SETUP = {
    "narrow": (RESPONSES, {}, True),
    "wide": (RESPONSES, {}, False),
    "cyclic": (("thrust", "power", "roll", "pitch"),
               {"lateral_deg": -1.0, "longitudinal_deg": -1.0}, False),
}
CASES = {
    "narrow": rq.ParameterSpace({"collective_deg": rq.Uniform(4.5, 6.5),
                                 "cla_m03": rq.Normal(0.1080, 5.4e-3)}),
    "wide": rq.ParameterSpace({"collective_deg": rq.Uniform(3.0, 8.0),
                               "cla_m03": rq.Normal(0.1080, 5.4e-3),
                               "k_pitch_link": rq.Uniform(8.0, 14.0),
                               "rho": rq.Uniform(1.15, 1.25)}),
}
CASES["cyclic"] = CASES["narrow"]
SPACE = CASES["narrow"]


def locate_mbdyn() -> Path:
    return find_mbdyn(build_prefix=True)


class MBDynModel:
    """One MBDyn template as a Model: a case per row, run in ``workdir``; a failed case is a
    NaN row (its reason in ``failures``)."""

    def __init__(self, template: str, revolutions: int, mbdyn: Path, workdir: Path,
                 space: rq.ParameterSpace = SPACE, responses=RESPONSES, fixed=FIXED):
        self.names_in = space.names
        self.names_out = tuple(responses)
        self.fixed = dict(fixed)
        self.template, self.mbdyn, self.workdir = template, mbdyn, workdir
        self.settings = CaseSettings(revolutions=revolutions)
        self.preset = get_preset("gvpm")
        self.count = 0
        self.failures: list[str] = []
        self.done: dict[bytes, np.ndarray] = {}  # a second estimator on the same points

    def __call__(self, x: np.ndarray) -> np.ndarray:
        out = np.full((len(x), len(self.names_out)), np.nan)
        for i, row in enumerate(np.atleast_2d(x)):
            key = np.asarray(row, dtype=float).tobytes()
            if key in self.done:
                out[i] = self.done[key]
                continue
            self.count += 1
            inputs = {**self.fixed, **dict(zip(self.names_in, map(float, row), strict=True))}
            try:
                loads = run_case(self.workdir / f"{self.template}_{self.count}", self.preset,
                                 inputs, template=self.template, settings=self.settings,
                                 mbdyn=self.mbdyn)
            except MBDynError as exc:
                self.failures.append(str(exc))
                continue
            out[i] = [loads.response(r) for r in self.names_out]
            self.done[key] = out[i]
        return out


def inputs_only(res) -> dict:
    """HF-run saving of a control variate on the inputs alone (known means, no cheap model):
    1 / (1 - R^2) of the elastic response's leave-one-out regression on the pilot's inputs,
    linear and (where the pilot has more points than terms + 2) quadratic. The regression is
    :class:`rotoruq.LinearAdaptation` of a cheap model that knows nothing (a constant)."""
    X, Y = res.pilot_inputs, res.pilot_outputs[:, 0, :]
    ok = np.all(np.isfinite(Y), axis=1)
    X, Y = X[ok], Y[ok]
    n, d = X.shape
    z = (X - X.mean(0)) / X.std(0)
    quad = np.column_stack([z[:, i] * z[:, j] for i in range(d) for j in range(i, d)])
    features = {"linear": z}
    if n >= 1 + d + quad.shape[1] + 2:
        features["quadratic"] = np.column_stack([z, quad])
    nothing = np.stack([Y, np.zeros_like(Y)], axis=1)  # (n, 2, m): HF and the constant
    out = {}
    for name, f in features.items():
        r2 = rq.LinearAdaptation.fit(f, nothing)[0].r2_loo[1]
        out[name] = {r: {"r2_loo": float(r2[j]),
                         "fewer_hf_runs_mean": float(1 / max(1 - r2[j], 1e-12))}
                     for j, r in enumerate(res.names_out)}
    return out


def cokriging_holdout(res, builtin, n_lf: int, seed: int, space=SPACE) -> dict:
    """Co-kriging against a GP on the same elastic runs: train on the first 4 or 8 of the
    pilot's points, test on the last 8."""
    X, Y = res.pilot_inputs, res.pilot_outputs  # (n, d), (n, K, m)
    ok = np.all(np.isfinite(Y[:, 0, :]), axis=1)
    X, Y = X[ok], Y[ok]
    x_test, y_test = X[-8:], Y[-8:, 0, :]
    scale = np.std(Y[:, 0, :], axis=0)
    out = {}
    for h in (4, 8):
        if h > len(X) - 8:
            continue
        x_hf, y_hf = X[:h], Y[:h, 0, :]
        x_lf = np.vstack([x_hf, space.draw(n_lf, seed=seed)])
        y_lf = rq.evaluate(builtin, x_lf).values
        ck = rq.CoKriging(seed=seed).fit([x_lf, x_hf], [y_lf, y_hf])
        gp = rq.GaussianProcess(seed=seed).fit(x_hf, y_hf)
        pred = {"cokriging": ck.predict(x_test, return_var=False),
                "gp_hf_only": gp.predict(x_test, return_var=False, warn_distance=None)}
        out[f"n_hf_train_{h}"] = {
            "n_lf": int(len(x_lf)), "n_hf_test": int(len(x_test)),
            "rho": dict(zip(res.names_out, map(float, ck.rho[0]), strict=True)),
            "holdout_nrmse": {k: dict(zip(res.names_out, map(float, np.sqrt(np.mean(
                (p - y_test) ** 2, axis=0)) / scale), strict=True)) for k, p in pred.items()}}
    return out


def squared_deviation_correlation(out: dict, used: list[str]) -> dict[str, float]:
    """Per response, the largest |correlation| on the pilot between the elastic rotor's squared
    deviations and a used cheap model's (as the estimator used it: leave-one-out adapted
    values where ``adapt`` kept the fit), what the variance's control variate needs."""
    names = list(out["pilot"]["outputs"])
    Y = np.stack([np.asarray(out["pilot"]["outputs"][k]) for k in names], axis=1)
    x = np.asarray(out["pilot"]["inputs"])
    ok = np.all(np.isfinite(Y), axis=(1, 2))
    Y, x = Y[ok], x[ok]
    if out["adapt"] == "linear":
        Y = rq.LinearAdaptation.fit(x, Y)[1]
    d2 = (Y - Y.mean(axis=0)) ** 2
    return {q: max((abs(np.corrcoef(d2[:, 0, j], d2[:, names.index(k), j])[0, 1])
                    for k in used), default=0.0)
            for j, q in enumerate(out["responses"])}


def larger_budgets(res, budgets=(20.0, 50.0, 100.0, 200.0)) -> dict:
    """What the pilot predicts at larger budgets (in elastic runs, the pilot's cost on top):
    the same allocation rule and estimator on the pilot's covariances, no further runs."""
    from rotoruq.methods.acv import allocate, estimator_variance
    from rotoruq.methods.multifidelity import _plain_variance_runs, _sample_moments

    ok = np.all(np.isfinite(res.pilot_outputs), axis=(1, 2))
    Y = res.pilot_outputs[ok]
    if res.adapt == "linear":  # the leave-one-out adapted values, as the estimator uses
        Y = rq.LinearAdaptation.fit(res.pilot_inputs[ok], Y)[1]
    covs, m22s = _sample_moments(Y)  # (m, K, K) each, as the estimator computes them
    w = np.asarray(res.costs)
    out = {}
    for b in budgets:
        row = {}
        for j, r in enumerate(res.names_out):
            cov, m22 = covs[j], m22s[j]
            plan = allocate(cov, w, b * w[0], estimator=res.estimator)
            sub = np.ix_(plan.models, plan.models)
            spent = (res.cost_pilot + plan.cost) / w[0]
            v_mean = estimator_variance(res.estimator, plan.n_samples, "mean", cov[sub])
            v_var = estimator_variance(res.estimator, plan.n_samples, "variance", cov[sub],
                                       m22[sub])
            n_var = _plain_variance_runs(v_var, cov[0, 0], m22[0, 0])
            row[r] = {"hf_runs_main": int(plan.n_samples[0]), "spent_in_hf_runs": spent,
                      "fewer_hf_runs_mean": float(cov[0, 0] / v_mean / spent),
                      "fewer_hf_runs_variance": float(n_var / spent)}
        out[f"budget_{b:g}"] = row
    return out


def summary(out: dict) -> str:
    """The docs' paragraph for a saved run."""
    r = out["responses"]
    names = list(r)
    other = next(v for k, v in out.items() if k.startswith("same_runs_adapt_"))
    lin = out["inputs_only"]["linear"]
    fmt = " / ".join

    def each(res: dict, key: str) -> str:
        return fmt(f"{res[q][key]:.1f}x" for q in names)

    pilot = out["pilot"]["outputs"]
    hf = np.asarray(pilot["mbdyn_elastic"])
    lf = np.asarray(pilot["builtin"])
    ok = np.all(np.isfinite(hf), 1) & np.all(np.isfinite(lf), 1)
    hf, lf = hf[ok], lf[ok]
    rho = [np.corrcoef(hf[:, j], lf[:, j])[0, 1] for j in range(len(names))]
    rho_sq = [np.corrcoef((hf[:, j] - hf[:, j].mean()) ** 2,
                          (lf[:, j] - lf[:, j].mean()) ** 2)[0, 1] for j in range(len(names))]
    x = np.asarray(out["pilot"]["inputs"])[ok]
    slope = [np.linalg.lstsq(np.column_stack([np.ones(len(x)), x]), y[:, 0], rcond=None)[0][1]
             for y in (hf, lf)]
    costs = out["cost_per_run_s"]
    cheap = f"the built-in rotor ({1e3 * costs['builtin']:.2g} ms a point)"
    if "mbdyn_rigid" in costs:
        cheap += f" and MBDyn's rigid rotor ({costs['mbdyn_rigid']:.2f} s a run)"
    fixed = "".join(f", {k} = {v:g}" for k, v in out.get("fixed", {}).items())
    text = (
        f"Case {out['case']!r}: MBDyn's elastic GVPM rotor ({out['elastic_revolutions']} "
        f"revolutions, {costs['mbdyn_elastic']:.1f} s a run) with {cheap} as cheap models; "
        f"inputs {', '.join(out['inputs'])}{fixed}; {out['estimator']}, a "
        f"{out['n_pilot']}-point pilot and {out['budget_hf_runs']:g} elastic runs of budget "
        f"({out['spent_in_hf_runs']:.1f} spent, pilot included). On the pilot the built-in "
        f"rotor's thrust grows {slope[1] / slope[0]:.2g} times as fast with the collective as "
        f"the elastic rotor's; it correlates with it at {fmt(f'{v:.3f}' for v in rho)} "
        f"({fmt(names)}) and at {fmt(f'{v:.3f}' for v in rho_sq)} in the squared deviations "
        f"(the variance estimator's saving is below "
        f"{fmt(f'{1 / max(1 - v * v, 1e-12):.0f}x' for v in rho_sq)} however many cheap runs "
        f"are spent). Fewer elastic runs than plain Monte Carlo for the same standard error: "
        f"adapted (adapt=\"{out['adapt']}\") mean {each(r, 'fewer_hf_runs_mean')}, variance "
        f"{each(r, 'fewer_hf_runs_variance')}; the same runs without adaptation "
        f"(adapt=\"{other['adapt']}\") mean {each(other['responses'], 'fewer_hf_runs_mean')}, "
        f"variance {each(other['responses'], 'fewer_hf_runs_variance')}. A control variate "
        f"on the inputs alone (leave-one-out linear regression on the pilot's elastic runs, no "
        f"cheap model) would save {each(lin, 'fewer_hf_runs_mean')} for the mean")
    beaten = [q for q in names if lin[q]["fewer_hf_runs_mean"] > r[q]["fewer_hf_runs_mean"]]
    linear = [q for q in beaten if lin[q]["r2_loo"] >= 0.95]
    clauses = []
    if linear:
        r2 = fmt(f"{lin[q]['r2_loo']:.4f}" for q in linear)
        clauses.append(f"for {', '.join(linear)} the elastic rotor is so nearly linear in "
                       f"these inputs (leave-one-out R^2 {r2}) that a regression on them beats "
                       "the multi-fidelity estimator")
    rest = [q for q in beaten if q not in linear]
    if rest:
        r2 = fmt(f"{lin[q]['r2_loo']:.2f}" for q in rest)
        def builtin(q: str) -> str:
            rho = f"{r[q]['correlation_with_elastic']['builtin']:.2f}"
            if (r[q].get("adapted") or {}).get("builtin", True):
                return f"{rho} (adapted)"
            return f"{rho} (as evaluated: its linear adaptation correlated worse on the pilot)"

        clauses.append(f"for {', '.join(rest)} neither pays much: the response is not linear "
                       f"in the inputs (R^2 {r2}) and the built-in rotor correlates at "
                       f"{fmt(builtin(q) for q in rest)} only")
    used = [k for k, n in out["allocation_main"].items() if n > 0 and k != "mbdyn_elastic"]
    target = out.get("target", names[0])  # the estimator's default: the first response
    rho_used = {"mean": {q: max((abs(r[q]["correlation_with_elastic"][k]) for k in used),
                                default=0.0) for q in names},
                "variance": squared_deviation_correlation(out, used)}
    for q in names:
        for stat, of in (("mean", "it"), ("variance", "its squared deviations")):
            if r[q][f"fewer_hf_runs_{stat}"] >= 1:
                continue
            why = why_dearer(
                main=r[q][f"plain_mc_hf_runs_for_{stat}_se"] * costs["mbdyn_elastic"]
                / out["cost_main_s"],
                pilot_share=out["cost_pilot_s"] / (out["cost_pilot_s"] + out["cost_main_s"]),
                rho=rho_used[stat][q], target=None if q == target else target, of=of)
            clauses.append(f"for {q} the multi-fidelity {stat} costs more than plain Monte "
                           f"Carlo: {why}")
    text += (": " + "; ".join(clauses) + "." if clauses
             else ": the cheap model brings more than the inputs' linear trend.")
    return text


def main() -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budget", type=float, default=20.0, help="main phase, in elastic runs")
    ap.add_argument("--pilot", type=int, default=16)
    ap.add_argument("--estimator", default="mfmc", choices=("mfmc", "acvmf", "acvis"))
    ap.add_argument("--elastic-revolutions", type=int, default=8)
    ap.add_argument("--rigid-revolutions", type=int, default=40)
    ap.add_argument("--n-lf", type=int, default=200, help="built-in runs for co-kriging")
    ap.add_argument("--seed", type=int, default=26)
    ap.add_argument("--adapt", default="linear", choices=("none", "linear"))
    ap.add_argument("--case", default="narrow", choices=tuple(CASES))
    ap.add_argument("--summary", metavar="JSON", help="print the docs' paragraph for a saved run")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return {}
    space = CASES[args.case]
    responses, extra_fixed, with_rigid = CASE_SETUP[args.case]
    fixed = {k: v for k, v in {**FIXED, **extra_fixed}.items() if k not in space.names}
    mbdyn = locate_mbdyn()
    builtin = RotorModel("gvpm", names_in=list(space.names), names_out=list(responses),
                         fixed=fixed)
    with tempfile.TemporaryDirectory() as tmp:
        elastic = MBDynModel("elastic", args.elastic_revolutions, mbdyn, Path(tmp), space,
                             responses, fixed)
        models = {"mbdyn_elastic": elastic, "builtin": builtin}
        rigid = None
        if with_rigid:
            rigid = MBDynModel("rigid", args.rigid_revolutions, mbdyn, Path(tmp), space,
                               responses, fixed)
            models["mbdyn_rigid"] = rigid
        t0 = time.perf_counter()
        res = rq.multifidelity_sample(list(models.values()), space, args.budget,
                                      budget_unit="hf_runs", estimator=args.estimator,
                                      n_pilot=args.pilot, adapt=args.adapt, seed=args.seed)
        wall = time.perf_counter() - t0
        other = "none" if args.adapt == "linear" else "linear"
        runs_before = elastic.count
        res_other = rq.multifidelity_sample(list(models.values()), space, args.budget,
                                            budget_unit="hf_runs", estimator=args.estimator,
                                            n_pilot=args.pilot, adapt=other,
                                            costs=res.costs, seed=args.seed)
        extra_elastic = elastic.count - runs_before
        ck = cokriging_holdout(res, builtin, args.n_lf, args.seed, space)
        bigger = larger_budgets(res)
    w_hf = float(res.costs[0])

    def estimates(res) -> dict:
        spent_hf_runs = (res.cost_pilot + res.cost_main) / w_hf
        out = {}
        for j, r in enumerate(responses):
            n_eq = {s: float(res.n_equivalent_hf[s][j]) for s in ("mean", "variance")}
            out[r] = {
                "mean": float(res.mean[j]), "mean_se": float(res.mean_se[j]),
                "std": float(res.std[j]),
                "std_se": (float(res.variance_se[j] / (2 * res.std[j])) if res.std[j] > 0
                           else None),
                "correlation_with_elastic": dict(zip(models, map(float, res.correlation[j]),
                                                     strict=True)),
                "correlation_with_elastic_unadapted": dict(zip(
                    models, map(float, res.correlation_unadapted[j]), strict=True)),
                "adapted": (dict(zip(models, map(bool, res.adaptation.adapted[:, j]),
                                     strict=True)) if res.adaptation is not None else None),
                "plain_mc_hf_runs_for_mean_se": n_eq["mean"],
                "plain_mc_hf_runs_for_variance_se": n_eq["variance"],
                "fewer_hf_runs_mean": n_eq["mean"] / spent_hf_runs,
                "fewer_hf_runs_variance": n_eq["variance"] / spent_hf_runs}
        return {"adapt": res.adapt, "allocation_main": dict(zip(
            models, map(int, res.allocation), strict=True)),
            "spent_in_hf_runs": spent_hf_runs, "responses": out}

    main_est = estimates(res)
    spent_hf_runs, per_response = main_est["spent_in_hf_runs"], main_est["responses"]
    out = {
        "case": args.case, "inputs": list(space.names), "fixed": extra_fixed,
        "adapt": res.adapt,
        "estimator": res.estimator, "target": res.target, "n_pilot": res.n_pilot,
        "budget_hf_runs": args.budget,
        "elastic_revolutions": args.elastic_revolutions,
        "rigid_revolutions": args.rigid_revolutions,
        "cost_per_run_s": dict(zip(models, map(float, res.costs), strict=True)),
        "models_used": [list(models)[k] for k in res.models_used],
        "allocation_main": dict(zip(models, map(int, res.allocation), strict=True)),
        "elastic_runs_total": int(res.allocation[0] + res.n_pilot),
        "cost_pilot_s": res.cost_pilot, "cost_main_s": res.cost_main,
        "spent_in_hf_runs": spent_hf_runs, "wall_s": wall,
        "responses": per_response,
        "mbdyn_failures": {"elastic": len(elastic.failures),
                           "rigid": len(rigid.failures) if rigid is not None else None},
        "predicted_at_larger_budgets": bigger,
        f"same_runs_adapt_{other}": {**estimates(res_other),
                                     "elastic_runs_added": extra_elastic},
        "inputs_only": inputs_only(res),
        "cokriging": ck,
        "pilot": {"inputs": res.pilot_inputs.tolist(),
                  "outputs": {name: res.pilot_outputs[:, k, :].tolist()
                              for k, name in enumerate(models)}},
        # the target: >= 10x fewer elastic runs for the mean and std of thrust, power
        "target_met": all(v["fewer_hf_runs_mean"] >= 10 and v["fewer_hf_runs_variance"] >= 10
                          for q, v in per_response.items() if q in RESPONSES),
        "note": (f"standard errors and plain-MC counts predicted from the {res.n_pilot}-point "
                 "pilot's covariances"),
    }
    out["provenance"] = provenance()
    print(json.dumps(out, indent=2, default=lambda v: None if isinstance(v, float)
                     and math.isnan(v) else v))
    return out


if __name__ == "__main__":
    main()
