"""Evaluate the built-in hover rotor model: a collective sweep of the GVPM rotor at 4R.

    python examples/rotor_model.py [--quick]

Prints thrust [N], power [W] and the figure of merit per collective [deg]; ``--quick`` uses
3 collectives instead of 9.
"""

from __future__ import annotations

import argparse

import numpy as np

import rotoruq as rq


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 collectives instead of 9")
    args = ap.parse_args(argv)

    preset = rq.get_preset("gvpm")
    # one batch: every row is an operating point, columns in names_in order
    model = rq.RotorModel(preset, names_in=["collective_deg"], names_out=["thrust", "power"],
                          fixed={"omega": 224.6375, "height_over_radius": 4.0})
    collective = np.linspace(3.0, 7.0, 3 if args.quick else 9)
    batch = rq.evaluate(model, collective[:, None])     # EvalBatch: values (n, 2), failures
    if batch.failures:
        raise SystemExit(f"failed points: {batch.failures}")
    thrust, power = batch.values.T
    # ideal induced power over the actual power (momentum theory, out of ground effect)
    area = np.pi * preset.radius**2
    merit = thrust**1.5 / np.sqrt(2.0 * preset.rho * area) / power
    print("collective [deg]  thrust [N]  power [W]  figure of merit")
    for row in zip(collective, thrust, power, merit, strict=True):
        print("{:16.2f}  {:10.3f}  {:9.2f}  {:15.3f}".format(*row))
    if not (np.all(np.diff(thrust) > 0) and np.all((merit > 0) & (merit < 1))):
        raise SystemExit("thrust must grow with collective and the figure of merit lie in (0, 1)")


if __name__ == "__main__":
    main()
