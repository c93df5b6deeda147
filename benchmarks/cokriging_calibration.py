"""Co-kriging as the calibration emulator: the posterior from few high-fidelity runs (issue 26).

``calibrate_bayes(hf, ..., emulator=CoKriging(low_fidelity=lf, n_low=N))`` against a
``GaussianProcess`` emulator on the same high-fidelity runs (the same seed draws the same HF
design) and against the exact posterior (the model itself), both emulators with their
variance in the likelihood (the default):

* ``analytic``: HF ``y = 2 t + 0.1 sin(6 pi t)``, LF ``0.8 y + 0.3 (t - 0.5)``, t ~ U(0, 1),
  three experiments with noise std 0.01 at a true t drawn from the prior per seed; the exact
  posterior by quadrature on 200,001 points. For each HF design size in ``--n-hf`` with
  ``--n-low`` LF runs, over ``--seeds`` datasets.
* ``rotor``: HF the GVPM rotor at its default discretization (10 Gauss stations, 36 azimuth
  steps), LF the same rotor on a coarse grid (3 stations, 6 steps; the
  ``multifidelity_rotor`` study's pair), calibrating ``collective_deg`` ~ U(4.5, 6.5) and
  ``cla_m03`` ~ N(0.108, 0.0054) to thrust and power (height 4 R, noise 0.5 % of each
  response, two experiments); the exact posterior by long chains on the HF model itself.

Per method: the posterior mean's error in exact posterior stds (largest over parameters), the
posterior std over the exact one (per parameter), the emulator's error-to-noise ratio over
the posterior, HF and LF runs, the wall time of the calibration and of its chains, and the
chains' cost per likelihood evaluation (the GP's log posterior is one compiled kernel; the
co-kriging's runs each level's compiled GP from Python).

Run: python benchmarks/cokriging_calibration.py > benchmarks/results/cokriging_calibration.json
``--quick``: one seed, one design size, short chains (the docs' smoke run).
``--summary benchmarks/results/cokriging_calibration.json`` prints the docs' paragraph.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

import rotoruq as rq

# The analytic pair (also tests/test_cokriging_calibration.py's): noise std, quadrature grid.
NOISE = 0.01
GRID = np.linspace(0.0, 1.0, 200_001)


def hf_response(t):
    """The analytic pair's high-fidelity response (t in [0, 1])."""
    return 2.0 * t + 0.1 * np.sin(6.0 * np.pi * t)


def lf_response(t):
    """The analytic pair's low-fidelity response: scaled and biased."""
    return 0.8 * hf_response(t) + 0.3 * (t - 0.5)


def grid_moments(loglik: np.ndarray) -> tuple[float, float]:
    """Mean and std of t under a log-likelihood (flat prior) given on ``GRID``."""
    w = np.exp(loglik - loglik.max())
    w /= w.sum()
    mean = float((w * GRID).sum())
    return mean, float(np.sqrt((w * (GRID - mean) ** 2).sum()))


def exact_posterior(data: np.ndarray) -> tuple[float, float]:
    """Posterior mean and std of t on the high-fidelity model itself, data (n_exp, 1)."""
    r = data[:, 0][None, :] - hf_response(GRID)[:, None]
    return grid_moments(-0.5 * ((r / NOISE) ** 2).sum(1))


def _calibrate(model, data, prior, emulator, noise, **kw) -> tuple[rq.BayesResult, float]:
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # extrapolation / adequacy notes: measured below
        res = rq.calibrate_bayes(model, data, prior, emulator=emulator,
                                 noise=rq.NoiseModel(noise_std=noise),
                                 **kw)
    return res, time.perf_counter() - t0


def _row(res: rq.BayesResult, wall: float, mean: np.ndarray, std: np.ndarray) -> dict:
    return {
        "mean_error_in_std": float(np.max(np.abs(res.mean - mean) / std)),
        "std_ratio": [round(float(v), 4) for v in res.std / std],
        "emulator_to_noise_ratio": None if res.emulator_adequacy is None else [
            round(float(v), 4) for v in res.emulator_adequacy.posterior_ratio],
        "hf_runs": res.n_evaluations,
        "lf_runs": list(res.n_low_fidelity_evaluations),
        "seconds": round(wall, 3),
        "sampling_seconds": round(res.sampling_seconds, 3),
        "microseconds_per_likelihood": round(1e6 * res.sampling_seconds
                                             / max(res.n_likelihood_evaluations, 1), 2),
    }


def analytic(n_hf: list[int], n_low: int, seeds: int, n_samples: int) -> dict:
    prior = rq.ParameterSpace({"t": rq.Uniform(0.0, 1.0)})
    hf = rq.FunctionModel(lambda x: hf_response(x[:, :1]), ["t"], ["y"])
    lf = rq.FunctionModel(lambda x: lf_response(x[:, :1]), ["t"], ["y"])
    out: dict = {"n_low": n_low, "seeds": seeds, "by_n_hf": {}}
    for n in n_hf:
        rows: dict[str, list] = {"cokriging": [], "gp": []}
        for s in range(seeds):
            rng = np.random.default_rng(1000 + s)
            theta = rng.uniform(0.0, 1.0)
            data = hf_response(np.array([theta])) + NOISE * rng.standard_normal((3, 1))
            m, sd = exact_posterior(data)
            kw = dict(n_emulator_samples=n, n_samples=n_samples, n_chains=2, seed=s)
            for name, em in (("cokriging", rq.CoKriging(low_fidelity=lf, n_low=n_low)),
                             ("gp", rq.GaussianProcess())):
                res, wall = _calibrate(hf, data, prior, em, NOISE, **kw)
                rows[name].append(_row(res, wall, np.array([m]), np.array([sd])))
        out["by_n_hf"][str(n)] = {
            name: {"median_mean_error_in_std": float(np.median([r["mean_error_in_std"]
                                                                for r in rs])),
                   "max_mean_error_in_std": float(np.max([r["mean_error_in_std"] for r in rs])),
                   "median_std_ratio": float(np.median([r["std_ratio"][0] for r in rs])),
                   "hf_runs": rs[0]["hf_runs"], "lf_runs": rs[0]["lf_runs"],
                   "median_seconds": float(np.median([r["seconds"] for r in rs])),
                   "median_microseconds_per_likelihood": float(np.median(
                       [r["microseconds_per_likelihood"] for r in rs]))}
            for name, rs in rows.items()}
    return out


def rotor(n_hf: list[int], n_low: int, n_samples: int, n_exact: int) -> dict:
    prior = rq.ParameterSpace({"collective_deg": rq.Uniform(4.5, 6.5),
                               "cla_m03": rq.Normal(0.108, 5.4e-3)})
    kw = dict(names_in=list(prior.names), names_out=["thrust", "power"],
              fixed={"height_over_radius": 4.0})
    hf = rq.RotorModel("gvpm", **kw)
    lf = rq.RotorModel("gvpm", n_stations=3, n_azimuth=6, **kw)
    theta = np.array([[5.7, 0.111]])
    clean = hf(theta)
    noise = 0.005 * np.abs(clean[0])
    data = clean + noise * np.random.default_rng(7).standard_normal((2, 2))
    exact, wall_exact = _calibrate(hf, data, prior, None, noise, n_samples=n_exact,
                                   n_chains=2, seed=1)
    out = {"theta_true": theta[0].tolist(), "noise_std": noise.tolist(),
           "exact": {"mean": exact.mean.tolist(), "std": exact.std.tolist(),
                     "ess_min": float(exact.ess.min()), "hf_runs": exact.n_evaluations,
                     "seconds": round(wall_exact, 2)},
           "n_low": n_low, "by_n_hf": {}}
    for n in n_hf:
        ckw = dict(n_emulator_samples=n, n_samples=n_samples, n_chains=2, seed=2)
        row = out["by_n_hf"][str(n)] = {}
        for name, em in (("cokriging", rq.CoKriging(low_fidelity=lf, n_low=n_low)),
                         ("gp", rq.GaussianProcess())):
            res, wall = _calibrate(hf, data, prior, em, noise, **ckw)
            row[name] = _row(res, wall, exact.mean, exact.std)
            if name == "cokriging":
                row[name]["rho"] = res.emulator.rho[0].tolist()
    return out


def _compare(by_n_hf: dict, fmt) -> str:
    """'; '-joined ``fmt(co-kriging row, GP row)`` per HF design size, prefixed by it."""
    return "; ".join(f"{n} HF runs: " + fmt(row["cokriging"], row["gp"])
                     for n, row in sorted(by_n_hf.items(), key=lambda kv: int(kv[0])))


def summary(out: dict) -> str:
    a = out["analytic"]
    text = (f"Analytic pair, co-kriging with {a['n_low']} LF runs against a GP on the same "
            f"HF runs, posterior mean error in exact posterior stds (medians over "
            f"{a['seeds']} datasets): " + _compare(a["by_n_hf"], lambda ck, gp: (
                f"{ck['median_mean_error_in_std']:.2f} against "
                f"{gp['median_mean_error_in_std']:.2f} (std ratio "
                f"{ck['median_std_ratio']:.2f} against {gp['median_std_ratio']:.2f})")) + ".")
    r = out.get("rotor")
    if r:
        last = r["by_n_hf"][max(r["by_n_hf"], key=int)]
        text += (f" GVPM rotor, HF at 10 stations x 36 steps, {r['n_low']} LF runs at 3 x 6: "
                 + _compare(r["by_n_hf"], lambda ck, gp: (
                     f"{ck['mean_error_in_std']:.2f} against {gp['mean_error_in_std']:.2f} "
                     f"({ck['seconds']:.1f} s against {gp['seconds']:.1f} s)"))
                 + f". The co-kriging chains cost "
                 f"{last['cokriging']['microseconds_per_likelihood']:.0f} us per likelihood "
                 f"evaluation against {last['gp']['microseconds_per_likelihood']:.0f} us for "
                 "the GP's compiled kernel.")
    return text


def main() -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-hf", type=int, nargs="+", default=[4, 6, 8, 12])
    ap.add_argument("--n-low", type=int, default=40)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--n-samples", type=int, default=10_000)
    ap.add_argument("--rotor-n-hf", type=int, nargs="+", default=[4, 8])
    ap.add_argument("--rotor-n-low", type=int, default=60)
    ap.add_argument("--rotor-exact-samples", type=int, default=40_000)
    ap.add_argument("--no-rotor", action="store_true")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--summary", metavar="JSON", help="print the docs' paragraph for a saved run")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return {}
    if args.quick:
        args.n_hf, args.seeds, args.n_samples = [6], 1, 500
        args.rotor_exact_samples, args.rotor_n_low, args.rotor_n_hf = 1000, 12, [5]
    t0 = time.perf_counter()
    out: dict = {"benchmark": "cokriging_calibration",
                 "analytic": analytic(args.n_hf, args.n_low, args.seeds, args.n_samples)}
    if not args.no_rotor:
        out["rotor"] = rotor(args.rotor_n_hf, args.rotor_n_low, args.n_samples,
                             args.rotor_exact_samples)
    out["seconds"] = round(time.perf_counter() - t0, 1)
    out["summary"] = summary(out)
    out["provenance"] = provenance()
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
