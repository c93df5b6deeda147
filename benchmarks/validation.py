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

``heldout``: the held-out validation of the GVPM ground effect, from the bundled study
``studies/heldout.toml`` (run here into a temporary folder, or read from ``--heldout DIR``,
the results folder of a run of it): at 1R, out of sample, the V&V 20 comparison error E,
u_val, |E| / u_val and the area metric of the predictions of the calibration on 4R, 3R, 2R
with the discrepancy (``with_discrepancy``), of the same posterior's model alone
(``without_discrepancy_same_posterior``), of the same calibration without a discrepancy
(``calibrated_without_discrepancy``) and of the thesis's 4R-only calibration
(``thesis_calibration``: its nine inputs and its 4R loads, joint posterior predictive); and
the coverage of the held-out test:
whether each 1R load lies inside the 90 % band of a new measurement, with and without the
discrepancy, and the fraction of the 1R loads covered.

Prints JSON. Run: python benchmarks/validation.py [--out benchmarks/results/validation.json]
[--heldout DIR] [--no-heldout]. ``--summary FILE`` prints README's paragraph from a saved JSON.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
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


HELD_OUT = 1.0


def _at(rec, height: float) -> int:
    return int(np.flatnonzero(np.isclose(rec.conditions, height))[0])


def heldout(results: Path | None = None) -> dict:
    """The 1R numbers of the bundled held-out study (run now unless ``results`` is given)."""
    from rotoruq.results import load_step
    from rotoruq.steps._discrepancy import DiscrepancyRecord
    from rotoruq.steps.validation import ValidationRecord
    from rotoruq.study.cmd_reproduce import studies_dir
    from rotoruq.study.runner import run_study

    t0 = time.perf_counter()
    tmp = None
    if results is None:
        tmp = tempfile.TemporaryDirectory()
        results = Path(tmp.name) / "heldout"
        run_study(studies_dir() / "heldout.toml", out=results)
    seconds = time.perf_counter() - t0
    out: dict = {"study": "studies/heldout.toml", "held_out_height_over_radius": HELD_OUT,
                 "study_seconds": round(seconds, 1) if tmp is not None else None,
                 "comparison": {}}
    sources = {"with_discrepancy": ("validate_heldout", 0),
               "without_discrepancy_same_posterior": ("validate_heldout", 1),
               "calibrated_without_discrepancy": ("validate_no_discrepancy", 0),
               "thesis_calibration": ("validate_thesis", 0)}
    for key, (step, p) in sources.items():
        rec = ValidationRecord.read(load_step(results / "steps" / step))
        j = _at(rec, HELD_OUT)
        out["comparison"][key] = {"prediction": rec.predictions[p], **{
            r: {"S": float(rec.simulation[p, j, m]), "D": float(rec.data_mean[p, j, m]),
                "E": float(rec.comparison_error[p, j, m]), "u_val": float(rec.u_val[p, j, m]),
                "u_input": float(rec.u_input[p, j, m]), "u_num": float(rec.u_num[p, j, m]),
                "u_D": float(rec.u_data[p, j, m]),
                "E_over_u_val": float(rec.error_ratio[p, j, m]),
                "area_metric": float(rec.area_metric[p, j, m]),
                "area_over_D": float(rec.relative_area_metric[p, j, m]),
                "thesis_sigma_distance": float(rec.sigma_distance[p, j, m])}
            for m, r in enumerate(rec.names_out)}}
    disc = DiscrepancyRecord.read(load_step(results / "steps" / "bayes_discrepancy"))
    j = int(np.flatnonzero(np.isclose(disc.predict_configurations, HELD_OUT))[0])
    meas = disc.measured[j]
    inside = (disc.band_lower[j] <= meas) & (meas <= disc.band_upper[j])
    inside_w = (disc.band_lower_without[j] <= meas) & (meas <= disc.band_upper_without[j])
    out["coverage"] = {
        "level": disc.level, "measured": dict(zip(disc.names_out, meas.tolist(), strict=True)),
        "band_with_discrepancy": {r: [float(disc.band_lower[j, m]), float(disc.band_upper[j, m])]
                                  for m, r in enumerate(disc.names_out)},
        "band_without_discrepancy": {r: [float(disc.band_lower_without[j, m]),
                                         float(disc.band_upper_without[j, m])]
                                     for m, r in enumerate(disc.names_out)},
        "inside_with_discrepancy": dict(zip(disc.names_out, inside.tolist(), strict=True)),
        "inside_without_discrepancy": dict(zip(disc.names_out, inside_w.tolist(), strict=True)),
        "inside_calibrated_without_discrepancy": _inside_no_discrepancy(results),
        "fraction_covered_with_discrepancy": float(np.mean(inside)),
        "fraction_covered_without_discrepancy": float(np.mean(inside_w)),
        "identifiability": disc.identifiability,
        "rhat_max": float(np.max(disc.rhat)), "ess_min": float(np.min(disc.ess))}
    if tmp is not None:
        tmp.cleanup()
    return out


def _inside_no_discrepancy(results: Path) -> dict:
    """1R inside the 90 % band of the calibration on 4R-2R without a discrepancy."""
    from rotoruq.results import load_step
    from rotoruq.steps._discrepancy import DiscrepancyRecord

    rec = DiscrepancyRecord.read(load_step(results / "steps" / "bayes_no_discrepancy"))
    j = int(np.flatnonzero(np.isclose(rec.predict_configurations, HELD_OUT))[0])
    m = rec.measured[j]
    inside = (rec.band_lower_without[j] <= m) & (m <= rec.band_upper_without[j])
    return dict(zip(rec.names_out, inside.tolist(), strict=True))


def heldout_summary(h: dict) -> str:
    parts = []
    for key, row in h["comparison"].items():
        cells = ", ".join(f"{r} E = {v['E']:+.3g} +- {v['u_val']:.2g} (|E|/u_val "
                          f"{v['E_over_u_val']:.2f}, area {100 * v['area_over_D']:.1f} %)"
                          for r, v in row.items() if isinstance(v, dict))
        parts.append(f"{key.replace('_', ' ')}: {cells}")
    c = h["coverage"]
    inside = ", ".join(f"{r} {'inside' if v else 'outside'}"
                       for r, v in c["inside_with_discrepancy"].items())
    inside_w = ", ".join(f"{r} {'inside' if v else 'outside'}"
                         for r, v in c["inside_without_discrepancy"].items())
    inside_c = ", ".join(f"{r} {'inside' if v else 'outside'}"
                         for r, v in c["inside_calibrated_without_discrepancy"].items())
    return ("Held-out 1R (studies/heldout.toml, calibrated on 4R, 3R, 2R): "
            + "; ".join(parts) + f". The measured 1R loads against the "
            f"{100 * c['level']:g} % band of a new measurement: with the discrepancy {inside}; "
            f"the same posterior's model alone {inside_w}; calibrated without a discrepancy "
            f"{inside_c}.")


def summary(res: dict) -> str:
    parts = []
    for name, rows in res["responses"].items():
        cells = ", ".join(
            f"{label} {r['production']['u_num']:.3g} ({100 * r['production']['u_num_over_S']:.2f} %"
            f" of |S|; actual error {r['reference_error']:.2g})" for label, r in rows.items())
        parts.append(f"{name}: {cells}")
    text = ("GVPM u_num (GCI / Fs, two grids 10/36 vs 5/18 stations/steps, assumed order "
            f"{res['assumed_order']:g}): " + "; ".join(parts) + ".")
    if "heldout" in res:
        text += " " + heldout_summary(res["heldout"])
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="also write the JSON here")
    ap.add_argument("--summary", help="print README's paragraph from a saved JSON and exit")
    ap.add_argument("--heldout", help="results folder of a run of studies/heldout.toml "
                    "(default: run it now)")
    ap.add_argument("--no-heldout", action="store_true", help="skip the held-out study")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    res = run()
    if not args.no_heldout:
        res["heldout"] = heldout(Path(args.heldout) if args.heldout else None)
    res["provenance"] = provenance()
    text = json.dumps(res, indent=2)
    print(text)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    main()
