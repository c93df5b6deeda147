"""Bayesian calibration of the GVPM preset's aerodynamic-centre offset (prints JSON).

    python scripts/aero_center_calibration.py [--out scripts/results/aero_center_calibration.json]
    python scripts/aero_center_calibration.py --quick     # short chains: a smoke run
    python scripts/aero_center_calibration.py --summary scripts/results/aero_center_calibration.json

About two minutes on one core. The ``gvpm`` preset puts the aerodynamic centre 1 mm ahead of the
feathering axis (``aero_center_offset = -0.001``), a value set to reproduce the axes of thesis
table 4.6. Here the offset is an uncertain input with a physical prior, N(x_ac, spread) from the
bundled airfoil's CM slope (``airfoil_ac_offset`` of scripts/mbdyn_verification.py: -0.19 mm,
0.44 mm), and the data decide what they can. Sections:

- ``prior``: the airfoil's x_ac - c/4 and its spread between blade stations, and where the
  preset's -1 mm falls in the prior.
- ``measured_4r``: the thesis's calibration (section 4.4: the nine inputs of table 4.10 with its
  uniform priors, the measured 4R thrust, roll, pitch and power of table 4.1, the noise the
  reference study states: 0.86 N, 0.167 N m, 0.167 N m, 11.66 W) with the offset as a tenth
  input, and the same calibration with the offset fixed at -1 mm and at the airfoil's value.
  One stage (the thesis calibrates roll and pitch first; the joint posterior is what both
  stages approximate). For the offset: posterior mean, std, 90 % interval, the tail
  probability below -1 mm, and the Savage-Dickey density ratio p(x | data) / p(x) at -1 mm and
  at the airfoil's value (the Bayes factor of fixing the offset there against calibrating it;
  their ratio is the Bayes factor of -1 mm against the airfoil's value). For each of the three
  calibrations the posterior predictive of the four measured loads against the data.
- ``mbdyn_elastic``: the offset alone calibrated to the elastic MBDyn template's thrust and power
  at the thesis's operating point (scripts/results/mbdyn_verification.json: the a.c. on the
  feathering axis and the table's pitching moment, no tuned property), with the verification's
  load tolerance (5 %) as the stated model-form noise; the built-in loads at -1 mm, at the
  airfoil's value and over the posterior against MBDyn's. The hub moments are listed, not
  calibrated: MBDyn's pitching-moment physics moves its 1/rev pitch (0.67 of the command,
  -32 deg), which no a.c. offset of the built-in model reproduces.
- ``table_4_6``, ``table_4_9``: what the -1 mm was tuned to, over the offset: the share of the
  roll moment's variance that the lateral command carries (thesis table 4.6: 0.772, K_p =
  10 N/m; from the built-in model's linear cyclic gains, S = g_lat^2 / (g_lat^2 + g_long^2):
  the commands are independent uniforms of equal range and the moments linear in them), and
  K_p's main Sobol index on thrust (table 4.9: 0.14; the table 4.7 design).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "aero_center_calibration.json"
VERIFICATION = HERE / "results" / "mbdyn_verification.json"
SEED = 26
PRESET_OFFSET = -0.001          # the gvpm preset's tuned value [m]
RESPONSES = ["thrust", "roll", "pitch", "power"]
#: the noise the reference study states (table 4.14, "Exp std"), as the bundled studies use it
NOISE = [0.86, 0.167, 0.167, 11.66]
#: thesis table 4.10: uniform priors of the nine calibrated inputs
TABLE_4_10 = {"cla_m02": (0.09, 0.125), "cla_m03": (0.09, 0.125),
              "cd0_m02": (0.007, 0.015), "cd0_m03": (0.007, 0.015),
              "k_pitch_link": (10.0, 20.0), "ei_flap": (6.0, 10.0),
              "collective_deg": (4.0, 8.0), "lateral_deg": (-2.0, 2.0),
              "longitudinal_deg": (-2.0, 2.0)}
FIXED_4R = {"omega": 224.6375, "height_over_radius": 4.0}
TABLE_4_6_LATERAL_ROLL = 0.772
TABLE_4_9_KP_THRUST = 0.140


def verification_module():
    """scripts/mbdyn_verification.py as a module (its airfoil a.c. and operating point)."""
    spec = importlib.util.spec_from_file_location("mbdyn_verification",
                                                  HERE / "mbdyn_verification.py")
    assert spec and spec.loader
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def offset_prior() -> dict:
    """The airfoil's x_ac - c/4 [m] (lift-weighted mean and spread between stations)."""
    af = verification_module().airfoil_ac_offset()
    return {"mean_m": af["x_ac_m"], "std_m": af["spread_m"]}


def _normal_pdf(x, mean, std):
    return math.exp(-0.5 * ((x - mean) / std) ** 2) / (std * math.sqrt(2 * math.pi))


def offset_posterior(chain: np.ndarray, prior: dict) -> dict:
    """The offset's posterior from its kept draws [m]: moments, 90 % interval, tail
    probabilities and Savage-Dickey density ratios at -1 mm and at the airfoil's value."""
    from scipy.stats import gaussian_kde, norm

    x = np.ravel(chain)
    kde = gaussian_kde(x)
    lo, hi = np.quantile(x, [0.001, 0.999])
    at = {"preset_-1mm": PRESET_OFFSET, "airfoil": prior["mean_m"]}
    # a kernel density estimate means nothing beyond the draws: None there
    ratio = {k: float(kde(v)[0] / _normal_pdf(v, prior["mean_m"], prior["std_m"]))
             if lo <= v <= hi else None for k, v in at.items()}
    both = None not in ratio.values()
    return {"mean_m": float(x.mean()), "std_m": float(x.std(ddof=1)),
            "interval_90_m": [float(v) for v in np.quantile(x, [0.05, 0.95])],
            "p_below_-1mm": float(np.mean(x <= PRESET_OFFSET)),
            "prior_p_below_-1mm": float(norm.cdf(PRESET_OFFSET, prior["mean_m"],
                                                 prior["std_m"])),
            "savage_dickey": ratio,
            "bayes_factor_-1mm_vs_airfoil": (ratio["preset_-1mm"] / ratio["airfoil"]
                                             if both else None),
            "std_over_prior_std": float(x.std(ddof=1) / prior["std_m"])}


def predictive_fit(pred: np.ndarray, data: np.ndarray, noise: np.ndarray) -> dict:
    """Posterior predictive (model draws plus the stated noise) of each response against the
    datum: mean, std, z = (datum - mean) / sqrt(std^2 + noise^2)."""
    mean, sd = pred.mean(0), pred.std(0, ddof=1)
    z = (data - mean) / np.sqrt(sd**2 + noise**2)
    return {"mean": [float(v) for v in mean], "std": [float(v) for v in sd],
            "z": [float(v) for v in z], "sum_z2": float(np.sum(z**2))}


def _chains(quick: bool) -> dict:
    if quick:
        return {"n_chains": 2, "n_samples": 1500, "burn_in": 500, "posterior_predictive": 200}
    return {"n_chains": 4, "n_samples": 10000, "burn_in": 2000, "posterior_predictive": 2000}


def _calibrate(model, data, space, noise, quick, seed):
    import rotoruq as rq

    return rq.calibrate_bayes(model, data, space, noise=rq.NoiseModel(noise_std=noise), seed=seed,
                              **_chains(quick))


def _summary_of(post, names) -> dict:
    return {"names": list(post.names_in), "mean": [float(v) for v in post.mean],
            "std": [float(v) for v in post.std],
            "ess_min": float(np.min(post.ess)), "rhat_max": float(np.max(post.rhat)),
            "acceptance_rate": float(post.acceptance_rate),
            "n_nan_likelihood": int(post.n_nan_likelihood),
            "sampling_seconds": float(post.sampling_seconds), "responses": names}


def measured_4r(prior: dict, quick: bool) -> dict:
    """The thesis's 4R calibration with the offset uncertain, fixed at -1 mm, fixed at the
    airfoil's value."""
    from importlib import resources

    import rotoruq as rq

    text = (resources.files("rotoruq") / "data" / "gvpm_measurements.csv").read_text()
    lines = [ln for ln in text.splitlines() if ln and not ln.startswith("#")]
    rows = np.genfromtxt(lines, delimiter=",", names=True)
    row = rows[rows["height_over_radius"] == 4.0]
    data = np.array([[float(row[r][0]) for r in RESPONSES]])
    noise = np.array(NOISE)
    dists = {k: rq.Uniform(*b) for k, b in TABLE_4_10.items()}
    out: dict = {"data": data[0].tolist(), "noise_std": NOISE, "responses": RESPONSES,
                 "priors_table_4_10": {k: list(b) for k, b in TABLE_4_10.items()}}
    cases = {"calibrated": None, "fixed_-1mm": PRESET_OFFSET, "fixed_airfoil": prior["mean_m"]}
    for i, (name, value) in enumerate(cases.items()):
        if value is None:
            space = rq.ParameterSpace({**dists, "aero_center_offset":
                                       rq.Normal(prior["mean_m"], prior["std_m"])})
            fixed = FIXED_4R
        else:
            space = rq.ParameterSpace(dists)
            fixed = {**FIXED_4R, "aero_center_offset": value}
        model = rq.RotorModel("gvpm", names_in=space.names, names_out=RESPONSES, fixed=fixed)
        post = _calibrate(model, data, space, noise, quick, np.random.SeedSequence([SEED, i]))
        res = {"offset_m": value, "posterior": _summary_of(post, RESPONSES),
               "predictive": predictive_fit(post.predictive, data[0], noise)}
        if value is None:
            j = list(post.names_in).index("aero_center_offset")
            res["offset"] = offset_posterior(post.chains[..., j], prior)
            res["offset"]["correlation"] = {n: float(post.correlation[j, k])
                                            for k, n in enumerate(post.names_in) if k != j}
        out[name] = res
    return out


def mbdyn_elastic(prior: dict, quick: bool) -> dict:
    """The offset against the elastic MBDyn template's thrust and power at the thesis's
    operating point."""
    import rotoruq as rq

    with open(VERIFICATION, encoding="utf-8") as fh:
        ver = json.load(fh)
    if "skipped" in ver:
        return {"skipped": f"{VERIFICATION.name}: {ver['skipped']}"}
    mb = ver["hover"]["mbdyn"]
    op = ver["operating_point"]
    tol = ver["tolerances"]["elastic_vs_builtin_loads"] / 100
    names = ["thrust", "power"]
    data = np.array([[mb[n] for n in names]])
    noise = tol * data[0]
    space = rq.ParameterSpace({"aero_center_offset": rq.Normal(prior["mean_m"], prior["std_m"])})
    fit = rq.RotorModel("gvpm", names_in=space.names, names_out=names, fixed=op)
    post = _calibrate(fit, data, space, noise, quick, np.random.SeedSequence([SEED, 9]))
    loads = rq.RotorModel("gvpm", names_in=space.names, names_out=RESPONSES, fixed=op)
    at = {"preset_-1mm": PRESET_OFFSET, "airfoil": prior["mean_m"],
          "posterior_mean": float(post.mean[0])}
    builtin = {k: dict(zip(RESPONSES, (float(v) for v in loads([[x]])[0]), strict=True))
               for k, x in at.items()}
    # one input: the Bayes factor of two fixed values is their likelihood ratio
    loglik = {k: -0.5 * sum(((v[n] - d) / s) ** 2 for n, d, s in zip(names, data[0], noise,
                                                                      strict=True))
              for k, v in builtin.items()}
    # the likelihood alone (no prior) on a grid: its maximum and where it falls to
    # exp(-1/2) of it, so the answer does not rest on the airfoil prior
    grid = np.linspace(-1.6e-3, 0.6e-3, 441)
    ll = -0.5 * np.sum(((fit(grid[:, None]) - data) / noise) ** 2, axis=1)
    ok = np.isfinite(ll)
    best = int(np.nanargmax(np.where(ok, ll, -np.inf)))
    inside = grid[ok & (ll >= ll[best] - 0.5)]
    return {"operating_point": op, "responses": names, "data": data[0].tolist(),
            "noise_std": noise.tolist(), "noise_source": "verification load tolerance "
            f"{100 * tol:g} % of MBDyn's loads",
            "mbdyn_loads": {r: float(mb[r]) for r in RESPONSES},
            "offset": offset_posterior(post.chains[..., 0], prior),
            "posterior": _summary_of(post, names),
            "predictive": predictive_fit(post.predictive, data[0], noise),
            "likelihood_only": {"max_m": float(grid[best]),
                                "interval_m": [float(inside.min()), float(inside.max())],
                                "grid_step_m": float(grid[1] - grid[0])},
            "builtin_loads": builtin,
            "log10_likelihood_ratio_-1mm_vs_airfoil":
                (loglik["preset_-1mm"] - loglik["airfoil"]) / math.log(10),
            "builtin_vs_mbdyn_pct": {k: {r: 100 * (v[r] / mb[r] - 1) for r in names}
                                     for k, v in builtin.items()}}


def table_4_6(prior: dict) -> dict:
    """The lateral command's share of the roll variance (thesis table 4.6) over the offset."""
    import rotoruq as rq

    # beyond -1 mm the blade on the K_p = 10 N/m link diverges in torsion (no stable pitch)
    grid = sorted([*np.linspace(PRESET_OFFSET, 0.0, 9).tolist(), prior["mean_m"]])
    fixed = {"omega": FIXED_4R["omega"], "k_pitch_link": 10.0, "ei_flap": 10.0,
             "collective_deg": 5.0}
    m = rq.RotorModel("gvpm", names_in=["aero_center_offset", "lateral_deg", "longitudinal_deg"],
                      names_out=["roll"], fixed=fixed)
    x = np.array([[a, *c] for a in grid for c in ((1, 0), (-1, 0), (0, 1), (0, -1))])
    y = m(x)[:, 0].reshape(len(grid), 4)
    g_lat, g_long = (y[:, 0] - y[:, 1]) / 2, (y[:, 2] - y[:, 3]) / 2
    share = g_lat**2 / (g_lat**2 + g_long**2)
    order = np.argsort(share)
    return {"offset_m": grid, "lateral_share_of_roll": [float(v) for v in share],
            "thesis": TABLE_4_6_LATERAL_ROLL, "k_pitch_link": 10.0,
            "offset_reproducing_thesis_m": float(np.interp(TABLE_4_6_LATERAL_ROLL,
                                                           share[order],
                                                           np.asarray(grid)[order]))}


def table_4_9(prior: dict, quick: bool) -> dict:
    """K_p's main Sobol index on thrust (thesis table 4.9: 0.14) over the offset, the table 4.7
    design at the section 4.3 commands (as scripts/rotor_fidelity.py)."""
    import rotoruq as rq

    space = rq.ParameterSpace({
        "cla_m02": rq.Normal(0.1055, 5.275e-3), "cla_m03": rq.Normal(0.108, 5.4e-3),
        "cd0_m02": rq.Normal(0.0079, 3.95e-4), "cd0_m03": rq.Normal(0.0077, 3.85e-4),
        "k_pitch_link": rq.Normal(15.0, 0.75), "ei_flap": rq.Normal(10.0, 0.5)})
    op = {"omega": FIXED_4R["omega"], "collective_deg": 5.0, "lateral_deg": -1.0,
          "longitudinal_deg": -1.0}
    grid = sorted([PRESET_OFFSET, -0.00075, -0.0005, -0.00025, prior["mean_m"], 0.0])
    main = []
    for a in grid:
        m = rq.RotorModel("gvpm", names_in=space.names, names_out=["thrust"],
                          fixed={**op, "aero_center_offset": a})
        s = rq.sobol_indices(m, space, 64 if quick else 256, seed=SEED, n_bootstrap=0)
        main.append(float(s.main[0, space.names.index("k_pitch_link")]))
    return {"offset_m": grid, "k_pitch_link_main_index_on_thrust": main,
            "thesis": TABLE_4_9_KP_THRUST,
            "offset_reproducing_thesis_m": float(np.interp(TABLE_4_9_KP_THRUST, main, grid))}


# --------------------------------------------------------------------------------------------
def summary(res: dict) -> str:
    """The docs' table from a saved run."""
    mm = 1e3
    p = res["prior"]
    lines = [f"Prior (bundled airfoil's CM slope): N({mm * p['mean_m']:+.2f} mm, "
             f"{mm * p['std_m']:.2f} mm); -1 mm is {p['preset_z']:+.2f} prior std from its mean.",
             "", "| data | offset posterior [mm] | 90 % interval [mm] | std / prior std | "
             "P(x <= -1 mm) | p(x \\| data) / p(x) at -1 mm / at airfoil | Bayes factor -1 mm : "
             "airfoil |", "|---|---|---|---|---|---|---|"]

    def num(v, fmt):
        return "beyond the draws" if v is None else f"{v:{fmt}}"

    mb = res["mbdyn_elastic"]
    for label, sec in (("measured 4R loads (table 4.1), 10 inputs", res["measured_4r"]
                        ["calibrated"]), ("MBDyn elastic thrust, power", mb)):
        o = sec["offset"]
        sd = o["savage_dickey"]
        bf = o["bayes_factor_-1mm_vs_airfoil"]
        if bf is None and "log10_likelihood_ratio_-1mm_vs_airfoil" in sec:
            bf_text = f"1e{sec['log10_likelihood_ratio_-1mm_vs_airfoil']:.0f} (likelihood ratio)"
        else:
            bf_text = num(bf, ".2f")
        lines.append(
            f"| {label} | {mm * o['mean_m']:+.2f} +- {mm * o['std_m']:.2f} | "
            f"{mm * o['interval_90_m'][0]:+.2f} .. {mm * o['interval_90_m'][1]:+.2f} | "
            f"{o['std_over_prior_std']:.2f} | {o['p_below_-1mm']:.3f} (prior "
            f"{o['prior_p_below_-1mm']:.3f}) | {num(sd['preset_-1mm'], '.2f')} / "
            f"{num(sd['airfoil'], '.2f')} | {bf_text} |")
    m4 = res["measured_4r"]
    lines += ["", "| 4R calibration | collective [deg] | " + " | ".join(
        f"{r} z" for r in m4["responses"]) + " | sum z^2 |",
        "|---|" + "---|" * (len(m4["responses"]) + 2)]
    for key, label in (("calibrated", "offset calibrated"), ("fixed_-1mm", "offset -1 mm"),
                       ("fixed_airfoil", "offset at the airfoil's value")):
        f, q = m4[key]["predictive"], m4[key]["posterior"]
        j = q["names"].index("collective_deg")
        lines.append(f"| {label} | {q['mean'][j]:.2f} +- {q['std'][j]:.2f} | "
                     + " | ".join(f"{z:+.2f}" for z in f["z"]) + f" | {f['sum_z2']:.2f} |")
    lines += ["", "z = (datum - predictive mean) / sqrt(predictive std^2 + noise^2); the "
              "calibrated offset's posterior correlation with the collective: "
              f"{m4['calibrated']['offset']['correlation']['collective_deg']:+.2f}."]
    lines += ["", "| built-in at | thrust vs MBDyn | power vs MBDyn |", "|---|---|---|"]
    for k, v in mb["builtin_vs_mbdyn_pct"].items():
        x = {"preset_-1mm": PRESET_OFFSET, "airfoil": p["mean_m"],
             "posterior_mean": mb["offset"]["mean_m"]}[k]
        lines.append(f"| {k.replace('_', ' ')} ({mm * x:+.2f} mm) | {v['thrust']:+.1f} % | "
                     f"{v['power']:+.1f} % |")
    lo = mb["likelihood_only"]
    lines += ["", f"MBDyn's thrust and power alone (no prior): likelihood maximum at "
              f"{mm * lo['max_m']:+.2f} mm, within exp(-1/2) of it from "
              f"{mm * lo['interval_m'][0]:+.2f} to {mm * lo['interval_m'][1]:+.2f} mm."]
    t = res["table_4_6"]
    lines += ["", f"Table 4.6's lateral share of the roll variance ({t['thesis']}, K_p = "
              f"{t['k_pitch_link']:g} N/m) needs x_ac = "
              f"{mm * t['offset_reproducing_thesis_m']:+.2f} mm in the built-in model "
              f"(0 mm: {t['lateral_share_of_roll'][-1]:.3f}; -1 mm: "
              f"{t['lateral_share_of_roll'][t['offset_m'].index(PRESET_OFFSET)]:.3f})."]
    t9 = res["table_4_9"]
    lines += ["", f"Table 4.9's main index of K_p on thrust ({t9['thesis']:.2f}) over x_ac: "
              + ", ".join(f"{mm * a:+.2f} mm: {v:.2f}" for a, v in
                          zip(t9["offset_m"], t9["k_pitch_link_main_index_on_thrust"],
                              strict=True))
              + f"; the thesis's value needs {mm * t9['offset_reproducing_thesis_m']:+.2f} mm."]
    return "\n".join(lines)


def readme(res: dict) -> str:
    """README's paragraph from a saved run."""
    mm = 1e3
    p, mb, m4 = res["prior"], res["mbdyn_elastic"], res["measured_4r"]["calibrated"]["offset"]
    pct = mb["builtin_vs_mbdyn_pct"]
    t6, t9 = res["table_4_6"], res["table_4_9"]
    i6 = min(range(len(t6["offset_m"])), key=lambda i: abs(t6["offset_m"][i] - p["mean_m"]))
    i9 = min(range(len(t9["offset_m"])), key=lambda i: abs(t9["offset_m"][i] - p["mean_m"]))
    lr = mb.get("log10_likelihood_ratio_-1mm_vs_airfoil")
    return (
        "The one tuned property of the `gvpm` preset, its aerodynamic centre 1 mm ahead of the "
        "feathering axis, costs the agreement with MBDyn's elastic rotor (thrust "
        f"{pct['preset_-1mm']['thrust']:+.1f} %, power {pct['preset_-1mm']['power']:+.1f} %); "
        f"the bundled airfoil's CM slope puts it {-mm * p['mean_m']:.2f} mm ahead (spread "
        f"{mm * p['std_m']:.2f} mm), where the two agree within "
        f"{max(abs(v) for v in pct['airfoil'].values()):.1f} %. "
        "`scripts/aero_center_calibration.py` calibrates the offset with that prior: the "
        f"thesis's 4R measurements cannot decide it (posterior {mm * m4['mean_m']:+.2f} +- "
        f"{mm * m4['std_m']:.2f} mm, {m4['std_over_prior_std']:.2f} of the prior's width: it "
        "trades against the collective, correlation "
        f"{m4['correlation']['collective_deg']:+.2f}; Bayes factor of -1 mm against the "
        f"airfoil's value {m4['bayes_factor_-1mm_vs_airfoil']:.2f}); MBDyn's loads reject -1 mm "
        f"(posterior {mm * mb['offset']['mean_m']:+.2f} +- {mm * mb['offset']['std_m']:.2f} mm"
        + (f", likelihood ratio 1e{lr:.0f}" if lr is not None else "") + "). What the 1 mm "
        "reproduces is the thesis's own multibody model: table 4.6's cyclic axes need "
        f"{mm * t6['offset_reproducing_thesis_m']:+.2f} mm and table 4.9's K_p index "
        f"{mm * t9['offset_reproducing_thesis_m']:+.2f} mm; at the airfoil's value they read "
        f"{t6['lateral_share_of_roll'][i6]:.2f} and "
        f"{t9['k_pitch_link_main_index_on_thrust'][i9]:.2f} against the thesis's "
        f"{t6['thesis']:.2f} and {t9['thesis']:.2f}.")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="short chains (a smoke run)")
    ap.add_argument("--out", help=f"also write the JSON to this file (the docs read {RESULTS})")
    ap.add_argument("--summary", help="print the docs' tables from this saved JSON and exit")
    ap.add_argument("--readme", help="print README's paragraph from this saved JSON and exit")
    args = ap.parse_args(argv)
    if args.summary or args.readme:
        with open(args.summary or args.readme, encoding="utf-8") as fh:
            print((summary if args.summary else readme)(json.load(fh)))
        return
    t0 = time.perf_counter()
    prior = offset_prior()
    prior["preset_z"] = (PRESET_OFFSET - prior["mean_m"]) / prior["std_m"]
    res = {"quick": args.quick, "seed": SEED, "chains": _chains(args.quick), "prior": prior,
           "measured_4r": measured_4r(prior, args.quick),
           "mbdyn_elastic": mbdyn_elastic(prior, args.quick), "table_4_6": table_4_6(prior),
           "table_4_9": table_4_9(prior, args.quick)}
    res["wall_s"] = time.perf_counter() - t0
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from _provenance import provenance  # the one helper every benchmark uses

    res["provenance"] = provenance()
    text = json.dumps(res, indent=1)
    print(text)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    sys.exit(main())
