"""MCMC efficiency: rotoruq DRAM against pymcmcstat DRAM and emcee, like for like, in one run.

Problem: 4-parameter nonlinear calibration, 200 observations
``y(t) = a exp(-b t) + c sin(w t) + noise`` (sigma 0.1), uniform priors. ESS is computed with
one estimator for every sampler (rotoruq.methods.mcmc.effective_sample_size, multi-chain,
Geyer initial monotone) after dropping the first 10 % of each chain.

Three comparisons, each repeated ``--repeats`` times with the two sides interleaved (medians
and min/max of the ratios are reported). On a machine shared with other jobs the wall-clock
ratios swing with the load; the ratios of ESS per CPU-second of each side (all samplers are
single-threaded here) are reported next to them:

1. ``one_chain``: one rotoruq DRAM chain vs one pymcmcstat DRAM chain. Held equal: the target,
   the start (our MAP point), the initial proposal covariance (ours, handed to pymcmcstat as
   ``qcov``), one delayed-rejection stage at scale 5, adaptation every 100 steps with
   eps 1e-8 and scale 2.38^2/d, the number of chain steps. The ratio uses the time of the
   chains (pymcmcstat's ``run_simulation`` and our ``sampling_seconds``); the ratio with our
   MAP / Hessian pre-solve added to our side is reported next to it.
2. ``many_chains``: 32 rotoruq DRAM chains (one batched call per step) vs emcee with 32
   walkers (vectorized). Held equal: the target, the total number of samples, 32 chains /
   walkers started from the same Laplace approximation around the MAP point.
3. ``emulator``: 100,000 DRAM steps on a 500-point GP emulator of a rotor-like model (the
   reference study's workflow), one chain, vs pymcmcstat DRAM on the same GP. Held equal: the
   GP (pymcmcstat calls its compiled mean, the fastest we have), likelihood, prior, start,
   proposal covariance, DR and AM settings, number of steps, burn-in 5,000; the likelihood
   uses the GP mean only on both sides (``emulator_variance=False``, as pymcmcstat does).
   Target: our chain under 3 s. The one-time load of the compiled kernels (a 200-step chain,
   first in the process) is timed apart as ``first_call_chain_s``. Then the same chain with
   the GP's Kriging variance in the likelihood (rotoruq's default): ``with_emulator_variance``
   (n^2/2 multiply-adds per response and step for the variance against n d for the mean).

Prints JSON (and writes it with --out). Run: python benchmarks/mcmc_efficiency.py
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
import warnings

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

import rotoruq as rq
from rotoruq.methods.mcmc import (
    ChainOptions,
    EmulatorOptions,
    NoiseModel,
    SamplerConfig,
    calibrate_bayes,
    effective_sample_size,
)
from rotoruq.methods.surrogate import GaussianProcess

T = np.linspace(0.0, 10.0, 200)
TRUE = np.array([2.0, 0.3, 0.5, 1.3])
SIGMA = 0.1
LO = np.array([0.5, 0.05, 0.0, 0.8])
HI = np.array([4.0, 1.0, 1.5, 1.8])
DR_SCALE, ADAPT_INTERVAL, AM_EPS = 5.0, 100, 1e-8


def forward(theta: np.ndarray) -> np.ndarray:
    """(k, 4) -> (k, 200)."""
    a, b, c, w = (theta[:, j : j + 1] for j in range(4))
    return a * np.exp(-b * T) + c * np.sin(w * T)


def make_problem(seed=0):
    rng = np.random.default_rng(seed)
    data = forward(TRUE[None])[0] + rng.normal(0, SIGMA, T.size)
    names = ["a", "b", "c", "w"]
    space = rq.ParameterSpace({n: rq.Uniform(lo, hi) for n, lo, hi in zip(names, LO, HI,
                                                                            strict=True)})
    model = rq.FunctionModel(forward, names, [f"y{i}" for i in range(T.size)])
    return model, space, data


def log_post(theta: np.ndarray, data: np.ndarray) -> np.ndarray:
    theta = np.atleast_2d(theta)
    inside = np.all((theta >= LO) & (theta <= HI), axis=1)
    out = np.full(theta.shape[0], -np.inf)
    if inside.any():
        r = forward(theta[inside]) - data
        out[inside] = -0.5 * (r * r).sum(1) / SIGMA**2
    return out


def ess_min(chains: np.ndarray, drop: float | int = 0.1) -> float:
    n = chains.shape[1]
    k = int(n * drop) if isinstance(drop, float) else int(drop)
    return float(effective_sample_size(chains[:, k:]).min())


def run_ours(model, space, data, budget, n_chains, seed, **kw):
    t0 = time.perf_counter()
    sampler = SamplerConfig("dram", dr_scale=DR_SCALE, adapt_interval=ADAPT_INTERVAL)
    res = calibrate_bayes(model, data, space,
                          chains=ChainOptions(sampler=sampler, n_samples=budget // n_chains,
                                              burn_in=0,
                                              n_chains=n_chains),
                          noise=NoiseModel(noise_std=SIGMA), seed=seed, **kw)
    wall = time.perf_counter() - t0
    ess = ess_min(res.chains)
    return res, {"chain_s": res.sampling_seconds, "chain_cpu_s": res.sampling_cpu_seconds,
                 "wall_with_presolve_s": wall, "ess_min": ess,
                 "ess_per_s": ess / res.sampling_seconds, "likelihood_evals":
                 res.n_likelihood_evaluations, "ess_per_eval": ess / res.n_likelihood_evaluations,
                 "acceptance": res.acceptance_rate, "n_chains": n_chains,
                 "mean": res.mean.tolist()}


def _pymcmcstat():
    import scipy

    for name in ("pi", "sin", "cos"):  # pymcmcstat 1.9 imports these from scipy
        if not hasattr(scipy, name):
            setattr(scipy, name, getattr(np, name))
    from pymcmcstat.MCMC import MCMC

    return MCMC


def run_pymcmcstat(ssfun, xdata, ydata, sigma2, nsimu, start, qcov, lo, hi, burn=0.1):
    """pymcmcstat DRAM with our settings; ssfun(q) -> sum of squares."""
    MCMC = _pymcmcstat()
    count = [0]

    def ss(q, d):
        count[0] += 1
        return ssfun(np.asarray(q, dtype=float))

    mc = MCMC()
    mc.data.add_data_set(xdata, ydata)
    mc.model_settings.define_model_settings(sos_function=ss, sigma2=sigma2)
    mc.simulation_options.define_simulation_options(
        nsimu=nsimu, updatesigma=False, method="dram", verbosity=0, waitbar=False,
        adaptint=ADAPT_INTERVAL, ntry=2, drscale=np.array([DR_SCALE, 4.0, 3.0]),
        qcov_adjust=AM_EPS, qcov=qcov, save_to_json=False, save_to_bin=False)
    for j in range(len(start)):
        mc.parameters.add_model_parameter(name=f"p{j}", theta0=float(start[j]),
                                          minimum=lo[j], maximum=hi[j], prior_mu=0.0,
                                          prior_sigma=np.inf)
    t0, c0 = time.perf_counter(), time.process_time()
    mc.run_simulation()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    chain = np.asarray(mc.simulation_results.results["chain"])[None]
    ess = ess_min(chain, burn)
    return {"chain_s": wall, "chain_cpu_s": cpu, "ess_min": ess, "likelihood_evals": count[0],
            "ess_per_s": ess / wall, "ess_per_eval": ess / count[0],
            "mean": chain[0].mean(0).tolist()}


def run_emcee(data, budget, start, cov, seed, nwalkers=32):
    import emcee

    count = [0]

    def lp(theta):
        count[0] += theta.shape[0]
        return log_post(theta, data)

    rng = np.random.default_rng(seed)
    p0 = rng.multivariate_normal(start, cov / (2.38**2 / 4), nwalkers)
    p0 = np.clip(p0, LO + 1e-9, HI - 1e-9)
    sampler = emcee.EnsembleSampler(nwalkers, 4, lp, vectorize=True)
    sampler._random = np.random.RandomState(int(rng.integers(2**31)))  # reproducible
    t0, c0 = time.perf_counter(), time.process_time()
    sampler.run_mcmc(p0, budget // nwalkers, progress=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    chains = sampler.get_chain().transpose(1, 0, 2)
    ess = ess_min(chains)
    return {"chain_s": wall, "chain_cpu_s": cpu, "ess_min": ess, "likelihood_evals": count[0],
            "ess_per_s": ess / wall, "ess_per_eval": ess / count[0], "nwalkers": nwalkers,
            "mean": chains.reshape(-1, 4).mean(0).tolist()}


def rotor_like(x):
    """A smooth 4-input, 2-response stand-in for the rotor (thrust-, torque-like)."""
    a, b, c, k = x.T
    thrust = 20 * a + 5 * b * np.sqrt(k / 15000) + 3 * c + 10 * a * b
    torque = 2 * a**2 + 40 * b + c * k / 15000 + np.sin(30 * c)
    return np.column_stack([thrust, torque])


def _spread(values):
    return {"median": statistics.median(values), "min": min(values), "max": max(values),
            "runs": values}


def _cpu_ratio(ours, base):
    """ESS per CPU-second, ours over the baseline's."""
    return (ours["ess_min"] / ours["chain_cpu_s"]) / (base["ess_min"] / base["chain_cpu_s"])


def one_chain(model, space, data, budget, seed, repeats):
    runs, ratios, ratios_wall, ratios_cpu = [], [], [], []
    for r in range(repeats):
        res, ours = run_ours(model, space, data, budget, 1, seed + r)
        pym = run_pymcmcstat(lambda q: float(((forward(q[None])[0] - data) ** 2).sum()),
                             T, data, SIGMA**2, budget, res.map_point, res.proposal_covariance,
                             LO, HI)
        ratios.append(ours["ess_per_s"] / pym["ess_per_s"])
        ratios_cpu.append(_cpu_ratio(ours, pym))
        ours_wall = ours["ess_min"] / ours["wall_with_presolve_s"]
        ratios_wall.append(ours_wall / pym["ess_per_s"])
        runs.append({"rotoruq_dram": ours, "pymcmcstat_dram": pym})
    return {"held_equal": "target, start (our MAP), initial proposal covariance, one DR stage "
                          "at scale 5, AM every 100 steps (eps 1e-8, 2.38^2/d), "
                          f"{budget} chain steps, ESS estimator",
            "ratio_ess_per_s": _spread(ratios),
            "ratio_ess_per_cpu_s": _spread(ratios_cpu),
            "ratio_ess_per_s_with_our_presolve": _spread(ratios_wall),
            "target_ratio": 3.0, "last_run": runs[-1]}


def many_chains(model, space, data, budget, n_chains, seed, repeats):
    runs, ratios, ratios_cpu = [], [], []
    for r in range(repeats):
        res, ours = run_ours(model, space, data, budget, n_chains, seed + r)
        emc = run_emcee(data, budget, res.map_point, res.proposal_covariance, seed + r,
                        nwalkers=n_chains)
        ratios.append(ours["ess_per_s"] / emc["ess_per_s"])
        ratios_cpu.append(_cpu_ratio(ours, emc))
        runs.append({"rotoruq_dram": ours, "emcee": emc})
    return {"held_equal": f"target, {budget} samples in total, {n_chains} chains / walkers "
                          "from the Laplace approximation at the MAP, ESS estimator",
            "ratio_ess_per_s_vs_emcee": _spread(ratios),
            "ratio_ess_per_cpu_s_vs_emcee": _spread(ratios_cpu), "last_run": runs[-1]}


def emulator(seed, repeats, steps=100_000, burn=5000):
    space = rq.ParameterSpace({"cla3": rq.Uniform(0.09, 0.14), "cla5": rq.Uniform(0.09, 0.14),
                               "cla6": rq.Uniform(0.09, 0.14), "kf": rq.Uniform(11000, 18000)})
    model = rq.FunctionModel(rotor_like, space.names, ["T", "Q"])
    truth = np.array([[0.1075, 0.1172, 0.1135, 15035.0]])
    data = rotor_like(truth) + np.random.default_rng(seed).normal(0, 0.5, (100, 2))
    X = space.draw(500, seed=seed)
    t0 = time.perf_counter()
    gp = GaussianProcess(trend="reduced_quadratic", seed=seed).fit(X, model(X))
    out = {"held_equal": "GP (500 points, reduced quadratic trend), likelihood (100 "
                         "experiments, variance 0.25), uniform prior, start, proposal "
                         f"covariance, DR/AM settings, {steps} steps, burn-in {burn}",
           "gp_fit_s": time.perf_counter() - t0, "loo_q2": gp.loo().q2.tolist()}
    bounds = space.bounds
    # first call in a process: load (or compile) the kernels for this posterior's types
    first = calibrate_bayes(model, data, space,
                            emulator=EmulatorOptions(gp, emulator_variance=False),
                            chains=ChainOptions(n_samples=200, burn_in=0),
                            noise=NoiseModel(noise_std=0.5),
                            seed=seed)
    calibrate_bayes(model, data, space, emulator=gp, chains=ChainOptions(n_samples=200, burn_in=0),
                    noise=NoiseModel(noise_std=0.5),
                    seed=seed)  # the variance kernel's load
    out["first_call_chain_s"] = first.sampling_seconds
    ratios, ratios_cpu, ours_s, ours_cpu = [], [], [], []
    for r in range(repeats):
        res = calibrate_bayes(model, data, space,
                              emulator=EmulatorOptions(gp, emulator_variance=False),
                              chains=ChainOptions(n_samples=steps - burn, burn_in=burn),
                              noise=NoiseModel(noise_std=0.5),
                              seed=seed + r)
        ess = float(res.ess.min())
        ours = {"chain_s": res.sampling_seconds, "chain_cpu_s": res.sampling_cpu_seconds,
                "ess_min": ess,
                "ess_per_s": ess / res.sampling_seconds, "acceptance": res.acceptance_rate,
                "likelihood_evals": res.n_likelihood_evaluations}
        ours_s.append(res.sampling_seconds)
        ours_cpu.append(res.sampling_cpu_seconds)
        pym = run_pymcmcstat(lambda q: float(((gp._mean_fast(q[None])[0] - data) ** 2).sum()),
                             np.arange(100.0), data, 0.25, steps, res.map_point,
                             res.proposal_covariance, bounds[:, 0], bounds[:, 1], burn=burn)
        ratios.append(ours["ess_per_s"] / pym["ess_per_s"])
        ratios_cpu.append(_cpu_ratio(ours, pym))
        out["last_run"] = {"rotoruq_dram": ours, "pymcmcstat_dram": pym}
    four = calibrate_bayes(model, data, space,
                           emulator=EmulatorOptions(gp, emulator_variance=False),
                           chains=ChainOptions(n_samples=steps // 4 - burn // 4, burn_in=burn // 4,
                                               n_chains=4),
                           noise=NoiseModel(noise_std=0.5), seed=seed)
    var_runs = [calibrate_bayes(model, data, space, emulator=gp,
                                chains=ChainOptions(n_samples=steps - burn, burn_in=burn),
                                noise=NoiseModel(noise_std=0.5), seed=seed + r)
                for r in range(repeats)]
    out["with_emulator_variance"] = {
        "one_chain_s": _spread([v.sampling_seconds for v in var_runs]),
        "one_chain_cpu_s": _spread([v.sampling_cpu_seconds for v in var_runs]),
        "ess_min": [float(v.ess.min()) for v in var_runs],
        "posterior_ratio": var_runs[-1].emulator_adequacy.posterior_ratio.tolist()}
    out.update({"one_chain_s": _spread(ours_s), "one_chain_cpu_s": _spread(ours_cpu),
                "ratio_ess_per_s_vs_pymcmcstat": _spread(ratios),
                "ratio_ess_per_cpu_s_vs_pymcmcstat": _spread(ratios_cpu),
                "four_chains_s": four.sampling_seconds, "target_one_chain_s": 3.0})
    return out


def summary(out: dict) -> str:
    """The README's sentence for this benchmark, from its JSON (``--summary FILE``)."""
    o, m, e = out["one_chain"], out["many_chains"], out["emulator"]

    def r(x):
        return f"{x['median']:.1f}x ({x['min']:.1f}-{x['max']:.1f})"

    return (
        f"Medians of {out['repeats']} interleaved runs (range in brackets). One DRAM chain vs "
        f"pymcmcstat DRAM: {r(o['ratio_ess_per_s'])} ESS per second of chain, "
        f"{r(o['ratio_ess_per_cpu_s'])} per CPU-second, {r(o['ratio_ess_per_s_with_our_presolve'])}"
        f" with our MAP pre-solve counted (target 3x). {m['last_run']['rotoruq_dram']['n_chains']}"
        f" chains vs emcee with as many walkers: {r(m['ratio_ess_per_s_vs_emcee'])} ESS/s, "
        f"{r(m['ratio_ess_per_cpu_s_vs_emcee'])} per CPU-second. 100,000 DRAM steps on a "
        f"500-point GP emulator, one chain: {e['one_chain_s']['median']:.2f} s "
        f"({e['one_chain_s']['min']:.2f}-{e['one_chain_s']['max']:.2f}; CPU "
        f"{e['one_chain_cpu_s']['median']:.2f} s; target < 3 s), "
        f"{r(e['ratio_ess_per_s_vs_pymcmcstat'])} pymcmcstat's ESS/s on the same GP; 4 chains "
        f"{e['four_chains_s']:.2f} s."
        + (f" With the GP's variance in the likelihood (the default): CPU "
           f"{e['with_emulator_variance']['one_chain_cpu_s']['median']:.2f} s."
           if "with_emulator_variance" in e else ""))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--budget", type=int, default=100_000, help="posterior samples per sampler")
    ap.add_argument("--chains", type=int, default=32, help="chains / walkers in part 2")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--emulator-steps", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", help="also write the JSON here")
    ap.add_argument("--summary", metavar="JSON", help="print the README sentence of a saved run")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    model, space, data = make_problem(0)
    warnings.simplefilter("ignore")
    # load compiled kernels
    calibrate_bayes(model, data, space, chains=ChainOptions(n_samples=300), seed=0)
    out = {"problem": "4 parameters, 200 observations, y = a exp(-b t) + c sin(w t)",
           "budget_samples": args.budget, "repeats": args.repeats,
           "one_chain": one_chain(model, space, data, args.budget, args.seed, args.repeats),
           "many_chains": many_chains(model, space, data, args.budget, args.chains, args.seed,
                                      args.repeats),
           "emulator": emulator(args.seed, args.repeats, args.emulator_steps,
                                args.emulator_steps // 20)}
    out["meets_targets"] = bool(
        out["one_chain"]["ratio_ess_per_s"]["median"] >= 3.0
        and out["emulator"]["one_chain_s"]["median"] < 3.0)
    out["provenance"] = provenance()
    text = json.dumps(out, indent=1)
    print(text)
    if args.out:
        with open(args.out, "w") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    main()
