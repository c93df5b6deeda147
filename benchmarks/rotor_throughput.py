"""Rotor model throughput: evaluations per second for batches of 1, 100 and 1000 samples, for
both presets, and the speed-up of a batch over a one-sample-at-a-time loop.

``frozen_vs_lockstep``: a batch of 1000 typical samples plus the 10 slowest-converging samples
of a wide draw, solved with converged samples leaving the iteration (the model) and with
every sample iterated until the slowest has converged (the lock-step baseline); the ratio of
the two times in one run, and the bitwise check that the model's rows equal the same points
solved alone.

Prints JSON. Inputs are the reference study's uncertain parameters drawn around nominal.
Target: >= 1000 gvpm evaluations per second at batch 1000 on a 2-core machine.
"""

from __future__ import annotations

import json
import time

import numpy as np

from rotoruq.rotor.model import RotorModel

CASES = {
    "gvpm": (["collective_deg", "lateral_deg", "longitudinal_deg", "k_pitch_link", "ei_flap",
              "cla_m02", "cla_m03", "cd0_m02", "cd0_m03"],
             [5.4, 0.17, -0.3, 15.0, 8.5, 0.1055, 0.108, 0.0079, 0.0077],
             [0.33, 0.7, 0.7, 2.0, 0.8, 0.005, 0.005, 0.0004, 0.0004]),
    "bo105": (["collective_deg", "longitudinal_deg", "k_flap", "k_lag", "cla_m03", "cla_m05",
               "cla_m06"],
              [6.0, -2.0, 15035.0, 70698.0, 0.1075, 0.1172, 0.1135],
              [0.1, 0.1, 751.0, 3534.0, 0.005, 0.006, 0.006]),
}


def frozen_vs_lockstep(rng) -> dict:
    names, mean, std = CASES["gvpm"]
    model = RotorModel("gvpm", names_in=names, names_out=["thrust", "torque", "roll", "pitch"])
    wide = np.asarray(mean) + 3 * np.asarray(std) * rng.standard_normal((2000, len(names)))
    model.evaluate(wide)
    sol = model.last_solution
    ok = np.flatnonzero(sol.converged)
    slow_x = wide[ok[np.argsort(sol.iterations[ok])[-10:]]]
    typical = np.asarray(mean) + np.asarray(std) * rng.standard_normal((1000, len(names)))
    x = np.vstack([typical, slow_x])
    res = {}
    for label, freeze in (("frozen", True), ("lockstep", False)):
        model._freeze = freeze
        t0 = time.perf_counter()
        y = model.evaluate(x)
        res[f"{label}_s"] = time.perf_counter() - t0
        res[f"{label}_iterations_max"] = int(model.last_solution.iterations.max())
        res[f"{label}_iterations_mean"] = float(model.last_solution.iterations.mean())
        if freeze:
            y_frozen = y.values
    model._freeze = True
    alone = np.vstack([model(row[None]) for row in x[::50]])
    res["speedup_frozen_vs_lockstep"] = res["lockstep_s"] / res["frozen_s"]
    res["bitwise_equal_to_alone"] = bool(np.array_equal(alone, y_frozen[::50],
                                                        equal_nan=True))
    return res


def main() -> None:
    rng = np.random.default_rng(0)
    out = {}
    for preset, (names, mean, std) in CASES.items():
        model = RotorModel(preset, names_in=names, names_out=["thrust", "torque", "roll", "pitch"])
        res = {}
        for n in (1, 100, 1000):
            x = np.asarray(mean) + np.asarray(std) * rng.standard_normal((n, len(names)))
            reps = max(1, 200 // n)
            t0 = time.perf_counter()
            for _ in range(reps):
                y = model.evaluate(x)
            dt = (time.perf_counter() - t0) / reps
            res[f"batch_{n}"] = {"evals_per_s": n / dt, "failures": len(y.failures)}
        # one sample at a time over 100 samples (the loop a file-driven workflow would run)
        x = np.asarray(mean) + np.asarray(std) * rng.standard_normal((100, len(names)))
        t0 = time.perf_counter()
        for row in x:
            model.evaluate(row[None])
        loop_rate = 100 / (time.perf_counter() - t0)
        res["loop_1_at_a_time_evals_per_s"] = loop_rate
        res["speedup_batch_1000_vs_loop"] = res["batch_1000"]["evals_per_s"] / loop_rate
        out[preset] = res
    out["frozen_vs_lockstep"] = frozen_vs_lockstep(rng)
    out["target_gvpm_batch_1000_evals_per_s"] = 1000
    out["target_met"] = out["gvpm"]["batch_1000"]["evals_per_s"] >= 1000
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
