"""Bayesian calibration of the GVPM rotor against thrust and power, on a Gaussian-process emulator.

    python examples/bayes_calibration.py [--quick]

Synthetic "measurements": 4 repeats of thrust [N] and power [W] at 4R from a known collective
[deg] and profile drag, with the measured spreads of the reference study's 4R test (0.86 N,
11.66 W) as noise. The posterior of both inputs is sampled by DRAM on a GP emulator built from
an LHS of the prior, and the truth must lie within 4 posterior standard deviations.
``--quick`` uses a 40-point emulator and 4,000 steps (instead of 150 and 40,000).
"""

from __future__ import annotations

import argparse

import numpy as np

import rotoruq as rq

TRUTH = {"collective_deg": 5.4, "cd0_m03": 0.011}
NOISE_STD = np.array([0.86, 11.66])  # thrust [N], power [W]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small emulator and chain")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    n_emulator, n_steps = (40, 4_000) if args.quick else (150, 40_000)
    # one seed for the whole run: one stream for the data, one for the calibration
    data_seed, calibration_seed = np.random.SeedSequence(args.seed).spawn(2)

    prior = rq.ParameterSpace({"collective_deg": rq.Uniform(4.0, 7.0),
                               "cd0_m03": rq.Uniform(0.007, 0.015)})
    model = rq.RotorModel("gvpm", names_in=prior.names, names_out=["thrust", "power"],
                          fixed={"omega": 224.6375, "height_over_radius": 4.0})
    clean = model([[TRUTH[n] for n in prior.names]])                      # (1, 2)
    data = clean + np.random.default_rng(data_seed).normal(0.0, NOISE_STD, (4, 2))  # (4, 2)

    post = rq.calibrate_bayes(model, data, prior, noise=rq.NoiseModel(noise_std=NOISE_STD),
                              emulator=rq.EmulatorOptions(
                                  rq.GaussianProcess(trend="reduced_quadratic"),
                                  n_emulator_samples=n_emulator),
                              chains=rq.ChainOptions(n_samples=n_steps),
                              seed=np.random.default_rng(calibration_seed))
    print(f"emulator leave-one-out Q2: {post.emulator_loo.q2}")
    print("input           truth     posterior mean  std       ESS")
    for k, name in enumerate(post.names_in):
        print(f"{name:15s} {TRUTH[name]:<9.4g} {post.mean[k]:<15.4g} {post.std[k]:<9.3g} "
              f"{post.ess[k]:.0f}")
    z = np.abs(post.mean - [TRUTH[n] for n in post.names_in]) / post.std
    if np.any(z > 4.0):
        raise SystemExit(f"the truth is {z.max():.1f} posterior std from the posterior mean")


if __name__ == "__main__":
    main()
