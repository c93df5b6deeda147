"""Forward uncertainty propagation and sensitivity of the GVPM rotor from Python.

    python examples/forward_uq.py [--quick]

Uncertain lift slope, profile drag and pitch-link stiffness (the quick study's inputs): an LHS
gives the mean, standard deviation and 5-95 % range of thrust [N] and power [W]; Sobol'
indices rank the inputs. ``--quick`` uses 40 LHS points and 32 Sobol' base samples (instead
of 400 and 256): a smoke run, with wide intervals.
"""

from __future__ import annotations

import argparse

import numpy as np

import rotoruq as rq


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small samples (a smoke run)")
    args = ap.parse_args(argv)
    n_lhs, n_sobol = (40, 32) if args.quick else (400, 256)

    space = rq.ParameterSpace({
        "cla_m03": rq.Normal(0.1080, 5.4e-3),        # lift slope at M = 0.3 [1/deg]
        "cd0_m03": rq.Uniform(0.007, 0.015),         # profile drag at M = 0.3 [-]
        "k_pitch_link": rq.Normal(15.0, 2.0),        # pitch-link stiffness [N/mm]
    })
    model = rq.RotorModel("gvpm", names_in=space.names, names_out=["thrust", "power"],
                          fixed={"omega": 224.6375, "height_over_radius": 4.0,
                                 "collective_deg": 5.4})

    lhs = rq.sample(model, space, n_lhs, design="lhs", seed=1)
    stats = lhs.statistics
    print(f"LHS of {n_lhs} points")
    for j, name in enumerate(model.names_out):
        lo, hi = np.percentile(lhs.outputs[:, j], [5, 95])
        print(f"  {name:6s} mean {stats.mean[j]:9.3f}  std {stats.std[j]:8.3f}  "
              f"5-95 % [{lo:.3f}, {hi:.3f}]")

    sens = rq.sobol_indices(model, space, n_sobol, seed=1)   # N (d + 2) evaluations
    print(f"Sobol' indices, N = {n_sobol} ({sens.n_evaluations} evaluations)")
    for j, name in enumerate(model.names_out):
        order = ", ".join(p for p, _, _ in sens.ranking(name))
        main = "  ".join(f"{p} {sens.main[j, k]:.2f}" for k, p in enumerate(space.names))
        print(f"  {name:6s} main: {main}   ranking (total): {order}")


if __name__ == "__main__":
    main()
