"""Numerical uncertainty u_num of the GVPM rotor model from Roache's GCI (issue 22).

At the reference study's nominal hover point (H/R = 4, Omega = 224.6375 rad/s) and at the
ground-effect height H/R = 1 (Omega = 223.0457 rad/s, the measured rotor speed), collective /
lateral / longitudinal 5 / -1 / -1 deg, pitch link K_p = 10 N (the preset), per response:

* ``production``: u_num of the model as the studies run it (10 Gauss stations, 36 azimuth
  steps): the two-grid GCI against the grid coarsened by 2 in both counts (5 stations,
  18 steps), with the assumed order 2 and Fs = 3 (the span quadrature's order with the airfoil
  table's Mach kinks, see ``rotor/discretization.py``); u_num = GCI / Fs (ASME V&V 20), and
  its size relative to |S|;
* ``three_grid``: the observed order, Roache's asymptotic-range ratio and the flags from
  levels (40, 144), (20, 72), (10, 36) refined by 2 (the GCI there is the 40-station grid's;
  in the asymptotic range only if monotone with the observed order within 10 % of 2);
* ``azimuth_only``: three-grid GCI of the production grid over azimuth steps alone
  (36, 18, 9 steps at 10 stations): the azimuth sum's part of u_num;
* ``reference_error``: the production model's actual error against a much finer solve
  (640 stations, 144 steps), to judge whether u_num covers it;
* ``iteration_error``: |S(tolerance 1e-8) - S(tolerance 1e-12)| at the production grid, the
  solver tolerance's part (the verification levels all run at 1e-12).

Prints JSON. Run: python benchmarks/validation.py [--out benchmarks/results/validation.json]
``--summary FILE`` prints README's paragraph from a saved JSON.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

import rotoruq as rq
from rotoruq.methods.verification import verify_discretization

NAMES_IN = ["collective_deg", "lateral_deg", "longitudinal_deg", "omega", "height_over_radius"]
RESPONSES = ["thrust", "power", "roll", "pitch"]
POINTS = {"4R": [5.0, -1.0, -1.0, 224.6375, 4.0], "1R": [5.0, -1.0, -1.0, 223.0457, 1.0]}
ASSUMED_ORDER = 2.0


def run() -> dict:
    x = np.array(list(POINTS.values()))
    t0 = time.perf_counter()
    factory = rq.RotorDiscretization("gvpm", names_in=NAMES_IN, names_out=RESPONSES)
    prod = rq.RotorModel("gvpm", names_in=NAMES_IN, names_out=RESPONSES)(x)
    fine_ref = rq.RotorModel("gvpm", names_in=NAMES_IN, names_out=RESPONSES, n_stations=640,
                             n_azimuth=144, tolerance=1e-12)(x)
    two = verify_discretization(factory, [0, -1], x, ratio=2.0, formal_order=ASSUMED_ORDER)
    three = verify_discretization(factory, [2, 1, 0], x, ratio=2.0,
                                  formal_order=ASSUMED_ORDER)
    azimuth = verify_discretization(
        rq.RotorDiscretization("gvpm", names_in=NAMES_IN, names_out=RESPONSES,
                               refine_stations=False), [0, -1, -2], x, ratio=2.0)
    f0 = two.values[0]
    seconds = time.perf_counter() - t0
    out: dict = {"preset": "gvpm", "points": POINTS, "names_in": NAMES_IN,
                 "assumed_order": ASSUMED_ORDER, "safety_factor_two_grids": two.safety_factor,
                 "u_num_convention": "GCI / Fs (ASME V&V 20)", "seconds": round(seconds, 2),
                 "responses": {}}
    for j, name in enumerate(RESPONSES):
        rows = {}
        for i, label in enumerate(POINTS):
            s = float(prod[i, j])
            u = float(two.u_num[i, j])
            ref_err = float(abs(f0[i, j] - fine_ref[i, j]))
            rows[label] = {
                "S": s,
                "production": {"u_num": u, "u_num_over_S": u / abs(s),
                               "gci_fine": float(two.gci_fine[i, j]),
                               "coarse_value": float(two.values[1, i, j])},
                "three_grid": {"values": [float(v) for v in three.values[:, i, j]],
                               "observed_order": float(three.observed_order[i, j]),
                               "asymptotic_ratio": float(three.asymptotic_ratio[i, j]),
                               "converging": bool(three.converging[i, j]),
                               "oscillatory": bool(three.oscillatory[i, j]),
                               "in_asymptotic_range": bool(three.in_asymptotic_range[i, j]),
                               "u_num_40_stations": float(three.u_num[i, j])},
                "azimuth_only": {"values_36_18_9": [float(v) for v in azimuth.values[:, i, j]],
                                 "u_num": float(azimuth.u_num[i, j]),
                                 "observed_order": float(azimuth.observed_order[i, j]),
                                 "oscillatory": bool(azimuth.oscillatory[i, j])},
                "reference_error": ref_err,
                "reference_error_over_u_num": ref_err / u if u > 0 else None,
                "iteration_error": float(abs(prod[i, j] - f0[i, j])),
            }
        out["responses"][name] = rows
    return out


def summary(res: dict) -> str:
    parts = []
    for name, rows in res["responses"].items():
        cells = ", ".join(
            f"{label} {r['production']['u_num']:.3g} ({100 * r['production']['u_num_over_S']:.2f} %"
            f" of |S|; actual error {r['reference_error']:.2g})" for label, r in rows.items())
        parts.append(f"{name}: {cells}")
    return ("GVPM u_num (GCI / Fs, two grids 10/36 vs 5/18 stations/steps, assumed order "
            f"{res['assumed_order']:g}): " + "; ".join(parts) + ".")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="also write the JSON here")
    ap.add_argument("--summary", help="print README's paragraph from a saved JSON and exit")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    res = run()
    text = json.dumps(res, indent=2)
    print(text)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    main()
