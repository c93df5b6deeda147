"""Rotor model throughput: the compiled solve against the numpy implementation it replaced.

Both sides solve the same points with the same discretization, tolerance and iteration limit,
in one run. Three point sets: ``gvpm`` and ``bo105``, the reference study's uncertain inputs
drawn around posterior-like means (small cyclic), and ``gvpm_nominal``, the gvpm preset's own
nominal point (collective 5 deg, cyclic -1/-1 deg, the preset's pitch link and flap EI, the
airfoil's nominal fits) with 3 % normal perturbations of the same nine inputs (issue 28: the
cyclic made this set 1.5x costlier per sample before the Jacobian took the airfoil's lift
slope). ``iterations_mean``: the mean iteration count of a sample at batch 1000.

- ``compiled``: ``RotorModel.evaluate`` (validation, the compiled solve, the result), on
  ``numba.get_num_threads()`` threads for batches of 16 and more;
- ``numpy``: ``rotoruq.rotor._reference.solve_hover_reference`` on the same rows in chunks of
  128 (its best chunk size), one thread (it is numpy arithmetic on small arrays).

Evaluations per second for batches of 1, 100 and 1000, both presets; the compiled side also at
one thread (``compiled_1_thread``), with the thread scaling as wall-time speed-up
(``thread_speedup_wall``) and CPU time per sample at 2 threads and at 1
(``cpu_us_per_sample``, ``cpu_us_per_sample_1_thread``: equal when threading costs
nothing). ``compile_s``: the first call in a fresh process with an empty numba cache (the cost
paid once per install; ``first_call_cached_s`` the cost of loading the cache).
``max_relative_difference``: largest |compiled - numpy| / |numpy| of thrust, torque, roll and
pitch over the batch of 1000 (rows valid in both).

``forward``: the forward-flight rotor (``ForwardRotorModel``, issue 38) trimmed in the wind
tunnel (thrust and zero first-harmonic flapping solved by collective and cyclic) at mu = 0.2,
shaft angle 3 deg, gvpm preset, the pitch link, flap EI and airfoil fits of ``gvpm`` drawn
as above and the thrust 25 +- 1 N: trimmed evaluations per second at batch 1 and 1000, its
iterations and failures (target: >= 5,000/s at batch 1000 on 2 cores).

``--runs N`` (default 3) repeats the measurement; the JSON keeps every run and the median and
range of each figure; ``--summary`` prints README's paragraph from the saved JSON. Prints JSON
and writes ``benchmarks/results/rotor_throughput.json``. Targets (issues 12 and 28): gvpm
>= 10,000 evaluations/s at batch 1000 on 2 cores at both gvpm point sets, >= 2,000/s at
batch 1; bo105 >= 7,000/s.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

import numba
import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)

from rotoruq.rotor._reference import solve_hover_reference
from rotoruq.rotor.forward import ForwardRotorModel
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
#: point sets drawn around a preset's nominal inputs: label -> (preset, its CASES names,
#: relative standard deviation)
NOMINAL_CASES = {"gvpm_nominal": ("gvpm", 0.03)}
RESPONSES = ["thrust", "torque", "roll", "pitch"]
#: the trimmed forward-flight point set: the gvpm structural and airfoil inputs of CASES and
#: the thrust target [N] (mean, standard deviation), at FORWARD_FIXED
FORWARD_CASE = (CASES["gvpm"][0][3:] + ["thrust_target"], CASES["gvpm"][1][3:] + [25.0],
                CASES["gvpm"][2][3:] + [1.0])
FORWARD_FIXED = {"advance_ratio": 0.2, "shaft_angle_deg": 3.0}
FORWARD_RESPONSES = ["thrust", "power", "h_force", "collective_trim_deg", "lateral_trim_deg",
                     "longitudinal_trim_deg"]
BATCHES = (1, 100, 1000)
REFERENCE_CHUNK = 128
OUT = Path(__file__).parent / "results" / "rotor_throughput.json"


def _reference(model: RotorModel, x: np.ndarray) -> np.ndarray:
    n = len(x)
    cols = {name: x[:, j] for j, name in enumerate(model.names_in)}
    params = {k: cols.get(k, np.full(n, v)) for k, v in model.defaults().items()}
    over = {k: cols[k] for k in model._airfoil_names if k in cols}
    out = []
    for s in range(0, n, REFERENCE_CHUNK):
        sol = solve_hover_reference(
            model.preset, model.airfoil, model.grid, {k: v[s:s + REFERENCE_CHUNK]
                                                      for k, v in params.items()},
            {k: v[s:s + REFERENCE_CHUNK] for k, v in over.items()},
            n_harmonics=model.n_harmonics, tolerance=model.tolerance,
            max_iterations=model.max_iterations, check_tolerance=model.check_tolerance)
        out.append(np.column_stack([sol.response(r) for r in RESPONSES]))
    return np.vstack(out)


def _rate(fn, x: np.ndarray, min_seconds: float = 1.0) -> tuple[float, float]:
    """Evaluations per second of wall time and per CPU-second of this process (steadier on
    a shared machine; with 2 threads busy it is about half the wall rate): repeat until
    min_seconds have passed (at least once)."""
    reps, t0, c0 = 0, time.perf_counter(), time.process_time()
    while True:
        fn(x)
        reps += 1
        dt = time.perf_counter() - t0
        if dt >= min_seconds:
            return reps * len(x) / dt, reps * len(x) / (time.process_time() - c0)


def compile_seconds() -> dict:
    """First call in a fresh process with an empty numba cache, then with the cache."""
    code = ("import time; t=time.perf_counter(); import rotoruq.rotor.model as m; "
            "r=m.RotorModel('gvpm'); i=time.perf_counter(); r([[5.0, 0.0, 0.0]]); "
            "print(time.perf_counter()-i, i-t)")
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        for label in ("compile_s", "first_call_cached_s"):
            res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                 env=env, check=True)
            first, imp = (float(v) for v in res.stdout.split())
            out[label] = first
        out["import_s"] = imp
        shutil.rmtree(cache, ignore_errors=True)
    return out


def _around(mean: np.ndarray, std: np.ndarray, rng: np.random.Generator,
            n: int) -> np.ndarray:
    return mean + std * rng.standard_normal((n, mean.size))


def point_sets() -> dict:
    """label -> (model, draw(rng, n) -> points (n, inputs)) of every point set."""
    out: dict = {}
    for preset, (names, mean, std) in CASES.items():
        out[preset] = (RotorModel(preset, names_in=names, names_out=RESPONSES),
                       partial(_around, np.asarray(mean), np.asarray(std)))
    for label, (preset, rel) in NOMINAL_CASES.items():
        model = RotorModel(preset, names_in=CASES[preset][0], names_out=RESPONSES)
        values = {**model.defaults(), **model.airfoil.nominal_values()}
        nominal = np.array([values[name] for name in model.names_in])
        out[label] = (model, partial(_around, nominal, rel * np.abs(nominal)))
    return out


def forward_run(rng: np.random.Generator) -> dict:
    """Trimmed forward-flight evaluations per second (wall and per CPU-second)."""
    names, mean, std = FORWARD_CASE
    model = ForwardRotorModel("gvpm", names_in=names, names_out=FORWARD_RESPONSES,
                              fixed=FORWARD_FIXED, trim="wind_tunnel")
    res: dict = {}
    for n in (1, 1000):
        x = _around(np.asarray(mean), np.asarray(std), rng, n)
        batch = model.evaluate(x)
        row: dict = {}
        row["compiled"], row["compiled_per_cpu_s"] = _rate(model, x)
        if n == 1000:
            row["iterations_mean"] = float(np.mean(model.last_solution.iterations))
            row["failures"] = len(batch.failures)
        res[f"batch_{n}"] = row
    return res


def one_run(rng: np.random.Generator, threads: int) -> dict:
    out: dict = {"forward": forward_run(rng)}
    for preset, (model, draw) in point_sets().items():
        res: dict = {}
        for n in BATCHES:
            x = draw(rng, n)
            model(x)
            row: dict = {}
            row["compiled"], row["compiled_per_cpu_s"] = _rate(model, x)
            numba.set_num_threads(1)
            try:
                row["compiled_1_thread"], row["compiled_1_thread_per_cpu_s"] = _rate(model, x)
            finally:
                numba.set_num_threads(threads)
            row["numpy"], row["numpy_per_cpu_s"] = _rate(
                lambda z, m=model: _reference(m, z), x)
            row["speedup"] = row["compiled"] / row["numpy"]
            # 2 threads against 1: wall time, and CPU time per sample (a busy machine slows
            # the wall clock; the CPU time shows what threading itself costs)
            row["thread_speedup_wall"] = row["compiled"] / row["compiled_1_thread"]
            row["cpu_us_per_sample"] = 1e6 / row["compiled_per_cpu_s"]
            row["cpu_us_per_sample_1_thread"] = 1e6 / row["compiled_1_thread_per_cpu_s"]
            if n == max(BATCHES):
                a, b = model(x), _reference(model, x)
                ok = np.all(np.isfinite(a) & np.isfinite(b), axis=1)
                row["max_relative_difference"] = float(np.max(
                    np.abs(a[ok] - b[ok]) / np.abs(b[ok])))
                row["failures"] = int((~ok).sum())
                row["iterations_mean"] = float(np.mean(model.last_solution.iterations))
            res[f"batch_{n}"] = row
        out[preset] = res
    return out


def summarize(runs: list[dict]) -> dict:
    """Median and range over the runs of every rate and speed-up."""
    out: dict = {}
    for preset in runs[0]:
        out[preset] = {}
        for batch, row in runs[0][preset].items():
            out[preset][batch] = {}
            for key in row:
                vals = np.array([r[preset][batch][key] for r in runs], dtype=float)
                out[preset][batch][key] = [float(np.median(vals)), float(vals.min()),
                                           float(vals.max())]
    return out


def _formatter(s: dict):
    """``f(preset, batch, key, digits)``: a figure's median and range as the summary prints."""

    def f(preset, batch, key, digits=0):
        med, lo, hi = s[preset][batch][key]
        fmt = f"{{:,.{digits}f}}"
        return f"{fmt.format(med)} ({fmt.format(lo)}-{fmt.format(hi)})"

    return f


def summary_text(result: dict) -> str:
    """The README's paragraph (``--summary``) from the saved JSON."""
    s = result["summary"]
    f = _formatter(s)

    met = [k for k, ok in result["targets_met"].items() if ok]
    missed = [k for k, ok in result["targets_met"].items() if not ok]
    goals = ", ".join(f"{k} {v:,}/s" for k, v in result["targets"].items())
    targets = (f"Targets of issues 12, 28 and 38 (the medians against {goals}): met "
               f"{', '.join(met) or 'none'}; not met {', '.join(missed) or 'none'}.")
    return (
        f"Medians of {len(result['runs'])} runs (range in brackets), {result['threads']} "
        f"threads on {result['cpu_count']} shared cores (load {result['load_average']:.1f}): "
        f"gvpm {f('gvpm', 'batch_1000', 'compiled')} evaluations/s at batch 1000, "
        f"{f('gvpm', 'batch_1000', 'compiled_per_cpu_s')} per CPU-second, "
        f"{f('gvpm', 'batch_1000', 'speedup', 1)}x the numpy implementation on the same "
        f"points, {f('gvpm', 'batch_1000', 'cpu_us_per_sample_1_thread')} us of CPU per "
        f"sample on one thread, {f('gvpm', 'batch_1000', 'iterations_mean', 1)} iterations; at "
        f"the preset's nominal point (cyclic -1/-1 deg, 3 % perturbations) "
        f"{f('gvpm_nominal', 'batch_1000', 'compiled')}/s, "
        f"{f('gvpm_nominal', 'batch_1000', 'compiled_per_cpu_s')} per CPU-second, "
        f"{f('gvpm_nominal', 'batch_1000', 'cpu_us_per_sample_1_thread')} us of CPU per "
        f"sample on one thread, {f('gvpm_nominal', 'batch_1000', 'iterations_mean', 1)} "
        f"iterations; at batch 1 {f('gvpm', 'batch_1', 'compiled')}/s "
        f"({f('gvpm', 'batch_1', 'speedup', 1)}x); bo105 "
        f"{f('bo105', 'batch_1000', 'compiled')}/s at batch 1000 "
        f"({f('bo105', 'batch_1000', 'compiled_per_cpu_s')} per CPU-second, "
        f"{f('bo105', 'batch_1000', 'speedup', 1)}x). Two threads against one at batch 1000 "
        f"(gvpm): {f('gvpm', 'batch_1000', 'thread_speedup_wall', 2)}x in wall time, "
        f"{f('gvpm', 'batch_1000', 'cpu_us_per_sample')} us of CPU per sample against "
        f"{f('gvpm', 'batch_1000', 'cpu_us_per_sample_1_thread')} us on one thread "
        f"(equal: threading costs no CPU; a wall-time gain below 2x is the other jobs on the "
        f"cores; {result['cpu_count']} free cores at this CPU time per sample would give "
        f"{result['cpu_count'] * s['gvpm']['batch_1000']['compiled_per_cpu_s'][0]:,.0f}/s). "
        f"Largest relative difference from the "
        f"numpy implementation {result['max_relative_difference']:.1e}. First use compiles "
        f"the kernel in {result['compile_s']:.0f} s (once per install: numba's cache; later "
        f"processes load it in {result['first_call_cached_s']:.2f} s). {targets}"
        + (_forward_text(result, f) if "forward" in s else "")
    )


def _forward_text(result: dict, f) -> str:
    """The forward-flight sentence of the summary (issue 38)."""
    s_fwd = result["summary"]["forward"]["batch_1000"]
    return (
        f" In forward flight (gvpm, mu = 0.2, wind-tunnel trim: collective and cyclic solved "
        f"for the thrust and zero first-harmonic flapping) "
        f"{f('forward', 'batch_1000', 'compiled')} trimmed evaluations/s at batch 1000 "
        f"({f('forward', 'batch_1000', 'compiled_per_cpu_s')} per CPU-second, "
        f"{f('forward', 'batch_1000', 'iterations_mean', 1)} iterations, target 5,000/s: "
        f"{'met' if result['targets_met'].get('forward_trimmed_batch_1000') else 'not met'};"
        f" {result['cpu_count']} free cores at this CPU time per evaluation would give "
        f"{result['cpu_count'] * s_fwd['compiled_per_cpu_s'][0]:,.0f}/s),"
        f" {f('forward', 'batch_1', 'compiled')}/s at batch 1."
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--summary", action="store_true",
                        help="print the README paragraph from the saved JSON")
    parser.add_argument("--forward", action="store_true",
                        help="with --summary: the forward-flight sentence only")
    parser.add_argument("--out", type=Path, default=OUT,
                        help=f"the JSON written, or read by --summary (default {OUT.name})")
    args = parser.parse_args()
    if args.summary:
        saved = json.loads(args.out.read_text())
        if args.forward:
            print(_forward_text(saved, _formatter(saved["summary"])).strip())
        else:
            print(summary_text(saved))
        return
    rng = np.random.default_rng(0)
    threads = numba.get_num_threads()
    out: dict = {"threads": threads, "cpu_count": os.cpu_count(),
                 "load_average": os.getloadavg()[0],
                 "held_equal": "same points, preset, grid (10 stations, 36 azimuths, 2 "
                               "harmonics), tolerance 1e-8, max_iterations 200",
                 **compile_seconds()}
    out["runs"] = [one_run(rng, threads) for _ in range(args.runs)]
    out["summary"] = summarize(out["runs"])
    out["max_relative_difference"] = max(
        r[p]["batch_1000"]["max_relative_difference"] for r in out["runs"] for p in r
        if p != "forward")
    med = {p: out["summary"][p]["batch_1000"]["compiled"][0] for p in out["summary"]}
    out["targets"] = {"gvpm_batch_1000": 10000, "gvpm_nominal_batch_1000": 10000,
                      "gvpm_batch_1": 2000, "bo105_batch_1000": 7000,
                      "forward_trimmed_batch_1000": 5000}
    out["targets_met"] = {
        "gvpm_batch_1000": med["gvpm"] >= 10000,
        "gvpm_nominal_batch_1000": med["gvpm_nominal"] >= 10000,
        "gvpm_batch_1": out["summary"]["gvpm"]["batch_1"]["compiled"][0] >= 2000,
        "bo105_batch_1000": med["bo105"] >= 7000,
        "forward_trimmed_batch_1000": med["forward"] >= 5000,
    }
    out["provenance"] = provenance()
    text = json.dumps(out, indent=1)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text + "\n")
    print(json.dumps({k: v for k, v in out.items() if k != "runs"}, indent=1))
    print(summary_text(out))


if __name__ == "__main__":
    main()
