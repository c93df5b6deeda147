"""GVPM ground effect, held-out 1R: calibration with and without a model discrepancy.

The built-in GVPM rotor (rotor speed per height from the measured RPM, cyclic -1 deg / -1 deg as
the experiment study) is calibrated on the measured mean thrust and power at 4R, 3R and 2R
(``rotoruq/data/gvpm_measurements.csv``; noise std 0.86 N and 11.66 W, the spread of the 4R
test loads that the experiment study uses) for two inputs: collective ~ N(5.4 deg, 0.5 deg)
and K_p ~ U(10, 20). With ``Discrepancy`` (a squared-exponential GP over H/R per response,
half-normal amplitudes of scale 3 N and 40 W, about 10 % of the loads, length-scale prior
median 2 R) and without. The 1R loads are then predicted: mean, std and 90 % band of a new
observation, and whether the measured 1R loads fall inside.

This is a demonstration of the held-out validation on two inputs and the rotor itself (no
emulator), not the reference study's nine-input calibration. Prints JSON.
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from importlib import resources

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)

import rotoruq as rq
from rotoruq.methods.mcmc.discrepancy import Discrepancy, calibrate_with_discrepancy

NOISE = (0.86, 11.66)


def measurements() -> dict[str, np.ndarray]:
    text = resources.files("rotoruq.data").joinpath("gvpm_measurements.csv").read_text()
    rows = list(csv.DictReader(ln for ln in text.splitlines() if not ln.startswith("#")))
    return {k: np.array([float(r[k]) for r in rows])
            for k in ("height_over_radius", "omega", "thrust", "power")}


def gvpm_model(meas: dict[str, np.ndarray]) -> rq.FunctionModel:
    rotor = rq.RotorModel("gvpm", names_in=["collective_deg", "k_pitch_link",
                                            "height_over_radius", "omega"],
                          names_out=["thrust", "power"],
                          fixed={"lateral_deg": -1.0, "longitudinal_deg": -1.0})
    order = np.argsort(meas["height_over_radius"])
    hs, om = meas["height_over_radius"][order], meas["omega"][order]

    def f(x: np.ndarray) -> np.ndarray:
        return rotor(np.column_stack([x[:, :3], np.interp(x[:, 2], hs, om)]))

    return rq.FunctionModel(f, ["collective_deg", "k_pitch_link", "height_over_radius"],
                            ["thrust", "power"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n-samples", type=int, default=3000, help="kept steps per chain (4 chains)")
    ap.add_argument("--seed", type=int, default=22)
    args = ap.parse_args()
    meas = measurements()
    model = gvpm_model(meas)
    prior = rq.ParameterSpace({"collective_deg": rq.Normal(5.4, 0.5),
                               "k_pitch_link": rq.Uniform(10.0, 20.0)})
    h = meas["height_over_radius"]
    train = h > 1.5
    y = np.column_stack([meas["thrust"], meas["power"]])
    held = y[~train][0]
    out: dict = {"heights_train": h[train].tolist(), "noise_std": dict(zip(
        ("thrust", "power"), NOISE, strict=True)),
        "measured_1R": dict(zip(("thrust", "power"), held.round(2).tolist(), strict=True))}
    specs = {"with_discrepancy": Discrepancy(amplitude_scale=(3.0, 40.0), length_scale=2.0),
             "without_discrepancy": None}
    for label, spec in specs.items():
        t0 = time.perf_counter()
        res = calibrate_with_discrepancy(
            model, y[train], prior, configurations=h[train],
            configuration_name="height_over_radius", discrepancy=spec, noise_std=NOISE,
            n_samples=args.n_samples, n_chains=4, n_draws=2000, predict_at=[1.0],
            seed=args.seed)
        p = res.prediction
        lo, hi = p.interval(0.9)
        out[label] = {
            "posterior_mean": dict(zip(res.names_in, res.mean.round(4).tolist(), strict=True)),
            "posterior_std": dict(zip(res.names_in, res.std.round(4).tolist(), strict=True)),
            "prediction_1R_mean": dict(zip(res.names_out, p.mean[0].round(2).tolist(),
                                           strict=True)),
            "prediction_1R_std": dict(zip(res.names_out, p.std[0].round(2).tolist(),
                                          strict=True)),
            "band_90_1R": {n: [round(float(lo[0, r]), 2), round(float(hi[0, r]), 2)]
                           for r, n in enumerate(res.names_out)},
            "measured_1R_inside_band": dict(zip(
                res.names_out, ((lo[0] <= held) & (held <= hi[0])).tolist(), strict=True)),
            "model_1R_mean": dict(zip(res.names_out, p.model_draws.mean(0)[0].round(2).tolist(),
                                      strict=True)),
            "discrepancy_1R_mean": dict(zip(res.names_out, p.discrepancy_draws.mean(0)[0]
                                            .round(2).tolist(), strict=True)),
            "identifiability": res.identifiability,
            "ess_min": round(float(res.ess.min()), 1),
            "rhat_max": round(float(res.rhat.max()), 4),
            "n_evaluations": res.n_evaluations,
            "wall_seconds": round(time.perf_counter() - t0, 1),
        }
    out["provenance"] = provenance()
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
