"""MCMC efficiency: rotoruq DRAM vs pymcmcstat DRAM and emcee on the same posterior and budget.

Problem: 4-parameter nonlinear calibration, 200 observations
``y(t) = a exp(-b t) + c sin(w t) + noise`` (sigma 0.1), uniform priors. Every sampler gets
the same total number of posterior samples, starts at the MAP point, and (pymcmcstat) the
same initial proposal covariance as ours. ESS is computed with one estimator for all
(rotoruq.methods.mcmc.effective_sample_size, multi-chain, Geyer initial monotone) after
dropping the first 10 % of each chain. Wall time includes our MAP and Hessian pre-solve.

Second part: a 100,000-sample DRAM chain on a 500-point GP emulator (reference study
workflow), timed.

Prints JSON. Run: python benchmarks/mcmc_efficiency.py [--budget 100000]
"""

from __future__ import annotations

import argparse
import json
import time
import warnings

import numpy as np

import rotoruq as rq
from rotoruq.methods.mcmc import calibrate_bayes, effective_sample_size
from rotoruq.methods.surrogate import GaussianProcess

T = np.linspace(0.0, 10.0, 200)
TRUE = np.array([2.0, 0.3, 0.5, 1.3])
SIGMA = 0.1
LO = np.array([0.5, 0.05, 0.0, 0.8])
HI = np.array([4.0, 1.0, 1.5, 1.8])


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


def ess_min(chains: np.ndarray) -> float:
    n = chains.shape[1]
    return float(effective_sample_size(chains[:, n // 10 :]).min())


def run_ours(model, space, data, budget, n_chains, seed):
    t0 = time.perf_counter()
    res = calibrate_bayes(model, data, space, method="dram", chain_samples=budget // n_chains,
                          burn_in=0, n_chains=n_chains, data_covariance=SIGMA**2, seed=seed)
    wall = time.perf_counter() - t0
    ess = ess_min(res.chains)
    return res, {"wall_s": wall, "ess_min": ess, "likelihood_evals": res.n_likelihood_evals,
                 "ess_per_s": ess / wall, "ess_per_eval": ess / res.n_likelihood_evals,
                 "acceptance": res.acceptance_rate, "n_chains": n_chains,
                 "mean": res.mean.tolist()}


def run_pymcmcstat(data, budget, start, qcov):
    import scipy

    for name in ("pi", "sin", "cos"):  # pymcmcstat 1.9 imports these from scipy
        if not hasattr(scipy, name):
            setattr(scipy, name, getattr(np, name))
    from pymcmcstat.MCMC import MCMC

    count = [0]

    def ssfun(q, d):
        count[0] += 1
        r = forward(np.asarray(q, dtype=float)[None])[0] - d.ydata[0][:, 0]
        return float(r @ r)

    mc = MCMC()
    mc.data.add_data_set(T, data)
    mc.model_settings.define_model_settings(sos_function=ssfun, sigma2=SIGMA**2)
    mc.simulation_options.define_simulation_options(
        nsimu=budget, updatesigma=False, method="dram", verbosity=0, waitbar=False,
        adaptint=100, qcov=qcov, save_to_json=False, save_to_bin=False)
    for j, name in enumerate("abcw"):
        mc.parameters.add_model_parameter(name=name, theta0=float(start[j]), minimum=LO[j],
                                          maximum=HI[j], prior_mu=0.0, prior_sigma=np.inf)
    t0 = time.perf_counter()
    mc.run_simulation()
    wall = time.perf_counter() - t0
    chain = np.asarray(mc.simulation_results.results["chain"])[None]
    ess = ess_min(chain)
    return {"wall_s": wall, "ess_min": ess, "likelihood_evals": count[0],
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
    t0 = time.perf_counter()
    sampler.run_mcmc(p0, budget // nwalkers, progress=False)
    wall = time.perf_counter() - t0
    chains = sampler.get_chain().transpose(1, 0, 2)
    ess = ess_min(chains)
    return {"wall_s": wall, "ess_min": ess, "likelihood_evals": count[0],
            "ess_per_s": ess / wall, "ess_per_eval": ess / count[0], "nwalkers": nwalkers,
            "mean": chains.reshape(-1, 4).mean(0).tolist()}


def rotor_like(x):
    """A smooth 4-input, 2-response stand-in for the rotor (thrust-, torque-like)."""
    a, b, c, k = x.T
    thrust = 20 * a + 5 * b * np.sqrt(k / 15000) + 3 * c + 10 * a * b
    torque = 2 * a**2 + 40 * b + c * k / 15000 + np.sin(30 * c)
    return np.column_stack([thrust, torque])


def emulator_chain(seed):
    space = rq.ParameterSpace({"cla3": rq.Uniform(0.09, 0.14), "cla5": rq.Uniform(0.09, 0.14),
                               "cla6": rq.Uniform(0.09, 0.14), "kf": rq.Uniform(11000, 18000)})
    model = rq.FunctionModel(rotor_like, space.names, ["T", "Q"])
    truth = np.array([[0.1075, 0.1172, 0.1135, 15035.0]])
    data = rotor_like(truth) + np.random.default_rng(seed).normal(0, 0.5, (100, 2))
    X = space.sample(500, seed=seed)
    t0 = time.perf_counter()
    gp = GaussianProcess(trend="reduced_quadratic", seed=seed).fit(X, model(X))
    fit_s = time.perf_counter() - t0
    out = {"gp_points": 500, "gp_fit_s": fit_s, "loo_q2": gp.loo().q2.tolist()}
    for n_chains in (1, 4):
        res = calibrate_bayes(model, data, space, emulator=gp, chain_samples=100_000 // n_chains,
                              burn_in=5000 // n_chains, n_chains=n_chains, data_covariance=0.25,
                              seed=seed)
        out[f"chains_{n_chains}"] = {
            "samples_total": 100_000, "sampling_s": res.sampling_seconds,
            "ess_min": float(res.ess.min()), "acceptance": res.acceptance_rate,
            "under_10_s": res.sampling_seconds < 10.0}
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--budget", type=int, default=100_000, help="posterior samples per sampler")
    ap.add_argument("--chains", type=int, default=32, help="rotoruq chains advanced together")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    model, space, data = make_problem(0)
    warnings.simplefilter("ignore")
    ours_res, ours = run_ours(model, space, data, args.budget, args.chains, args.seed)
    qcov = ours_res.proposal_covariance
    start = ours_res.map_point
    pym = run_pymcmcstat(data, args.budget, start, qcov)
    emc = run_emcee(data, args.budget, start, qcov, args.seed)
    out = {
        "problem": "4 parameters, 200 observations, y = a exp(-b t) + c sin(w t)",
        "budget_samples": args.budget,
        "rotoruq_dram": ours, "pymcmcstat_dram": pym, "emcee": emc,
        "ratio_ess_per_s_vs_pymcmcstat": ours["ess_per_s"] / pym["ess_per_s"],
        "ratio_ess_per_s_vs_emcee": ours["ess_per_s"] / emc["ess_per_s"],
        "ratio_ess_per_eval_vs_pymcmcstat": ours["ess_per_eval"] / pym["ess_per_eval"],
        "ratio_ess_per_eval_vs_emcee": ours["ess_per_eval"] / emc["ess_per_eval"],
        "target": {"vs_pymcmcstat": 5.0, "vs_emcee": 2.0},
        "emulator_chain": emulator_chain(args.seed),
    }
    out["meets_targets"] = bool(out["ratio_ess_per_s_vs_pymcmcstat"] >= 5.0
                                and out["ratio_ess_per_s_vs_emcee"] >= 2.0
                                and out["emulator_chain"]["chains_1"]["under_10_s"])
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
