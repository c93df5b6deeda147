"""The bundled ``forward_flight`` study (issue 38, item 6), run whole: the CPU seconds of each
step and of the study, and what the multi-fidelity steps save against MBDyn alone.

Runs ``rotoruq run forward_flight --no-report`` (``--quick`` with ``--quick``) in a fresh
folder, one step at a time (``--only STEP``, each a subprocess: its CPU seconds are its own and
its children's, MBDyn's runs included; Python's start-up is in each). Then, for each
multi-fidelity step (MBDyn's elastic rotor flying the built-in rotor's trim, the built-in
rotor as the cheap model), from its saved record: the runs of each model, the pilot's
correlation, the estimate of the mean power and its standard error, and the MBDyn runs plain
Monte Carlo needs for the same standard error (``n_equivalent_hf``). The CPU seconds of one
MBDyn run are measured here (the study's ``[models.mbdyn]`` command on ``--hf-samples``
samples drawn from the study's distributions at the step's advance ratio), so "MBDyn alone"
is ``n_equivalent_hf`` times that, and the saving is it over the step's measured CPU
seconds (pilot, built-in runs, Python and the evaluation store included). CPU seconds, not
wall: the machine may be shared (``loadavg`` is recorded).

Needs MBDyn ($MBDYN, PATH, or ~/.cache/mbdyn/bin/mbdyn). Run (about 6 CPU-minutes):
python benchmarks/forward_flight_study.py --out benchmarks/results/forward_flight_study.json
python benchmarks/forward_flight_study.py --summary benchmarks/results/forward_flight_study.json
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_and_save, print_saved_summary  # noqa: E402

from rotoruq.evaluation.dakota_files import read_results, write_parameters
from rotoruq.mbdyn import find_mbdyn
from rotoruq.results import load_step
from rotoruq.steps.multifidelity import MultifidelityRecord
from rotoruq.study.schema import load_study

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "src" / "rotoruq" / "studies" / "forward_flight.toml"
OUT = ROOT / "benchmarks" / "results" / "forward_flight_study.json"


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _env() -> dict[str, str]:
    src = str(ROOT / "src")
    path = os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")])
    return {**os.environ, "PYTHONPATH": os.pathsep.join(
        [src, *filter(None, [os.environ.get("PYTHONPATH")])]), "PATH": path,
        "MBDYN": str(find_mbdyn(build_prefix=True))}


def run_steps(folder: Path, quick: bool) -> dict[str, float]:
    """Each step of the study in turn (``--only``), its CPU seconds by name."""
    study = load_study(STUDY)
    cpu: dict[str, float] = {}
    for step in study.steps:
        c0 = _children_cpu()
        done = subprocess.run([sys.executable, "-m", "rotoruq", "run", str(STUDY),
                               *(["--quick"] if quick else []), "--only", step.name,
                               "--no-report", "--out", "res"], cwd=folder, env=_env(),
                              capture_output=True, text=True)
        if done.returncode != 0:
            raise SystemExit(f"step {step.name} failed:\n{done.stdout[-3000:]}\n"
                             f"{done.stderr[-3000:]}")
        cpu[step.name] = _children_cpu() - c0
    return cpu


def mbdyn_run_cpu(folder: Path, step_name: str, n: int, seed: int) -> dict:
    """CPU seconds of the study's [models.mbdyn] command (one parameters file, one run) on
    ``n`` samples of the study's distributions at the step's operating point."""
    study = load_study(STUDY)
    step = next(s for s in study.steps if s.name == step_name)
    fixed = {**dict(study.model.fixed), **dict(step.fixed)}
    rng = np.random.default_rng(seed)
    cmd = list(study.model_spec("mbdyn").external.command)
    cpu, power = [], []
    for k in range(n):
        wd = folder / f"hf_{step_name}_{k}"
        wd.mkdir()
        sample = {p.name: float(p.distribution.ppf(rng.uniform())) for p in study.parameters}
        write_parameters(wd / "params.in", {**sample, **fixed}, ["power"])
        words = [sys.executable if w == "python" else w.format(params="params.in",
                                                               results="results.out")
                 for w in cmd]
        c0 = _children_cpu()
        done = subprocess.run(words, cwd=wd, env=_env(), capture_output=True, text=True)
        cpu.append(_children_cpu() - c0)
        if done.returncode != 0:
            raise SystemExit(f"MBDyn run failed: {done.stderr[-2000:]}")
        power.append(float(read_results(wd / "results.out").values[0]))
    return {"n": n, "cpu_s": cpu, "cpu_s_mean": float(np.mean(cpu)), "power_W": power}


def mf_summary(folder: Path, name: str, cpu_step: float, cpu_hf: float) -> dict:
    rec = MultifidelityRecord.read(load_step(folder / "res" / "steps" / name))
    k = rec.names_out.index("power")
    n_eq = rec.statistic("mean", rec.n_equivalent_hf, k)
    alone = n_eq * cpu_hf
    return {"models": list(rec.models), "runs": rec.runs.tolist(),
            "allocation": rec.allocation.tolist(), "n_pilot": rec.n_pilot,
            "costs_given": rec.cost.tolist(),
            "correlation": float(rec.correlation[1, k]), "mean_power_W": float(rec.mean[k]),
            "mean_se_W": float(rec.mean_se[k]), "std_W": float(rec.std[k]),
            "n_equivalent_hf": n_eq, "speedup_given_costs": rec.statistic("mean", rec.speedup, k),
            "cpu_s": cpu_step, "mbdyn_alone_cpu_s": alone, "saving": alone / cpu_step}


def run(quick: bool, hf_samples: int) -> dict:
    import time

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        load0 = os.getloadavg()
        t0 = time.perf_counter()
        cpu = run_steps(folder, quick)
        wall = time.perf_counter() - t0
        study = load_study(STUDY)
        mf_names = [s.name for s in study.steps if s.type == "multifidelity"]
        hf = {n: mbdyn_run_cpu(folder, n, hf_samples, seed=k)
              for k, n in enumerate(mf_names)}
        mf = {n: mf_summary(folder, n, cpu[n], hf[n]["cpu_s_mean"]) for n in mf_names}
        load1 = os.getloadavg()
    return {"quick": quick, "steps_cpu_s": cpu, "study_cpu_s": sum(cpu.values()),
            "study_wall_s": wall, "multifidelity": mf, "mbdyn_run": hf,
            "loadavg_before": list(load0), "loadavg_after": list(load1),
            "cores": os.cpu_count(), "note": "CPU seconds of each `rotoruq run --only STEP "
            "--no-report` subprocess and its children (MBDyn included; Python start-up in "
            "each); wall seconds are the machine's load"}


def summary(d: dict) -> str:
    mf = d["multifidelity"]
    rows = []
    for name, r in mf.items():
        mu = name.split("_mu")[-1]
        runs = ", ".join(f"{int(n)} {m}" for m, n in zip(r["models"], r["runs"], strict=True))
        rows.append(
            f"at mu = 0.{mu[1:]}: mean power {r['mean_power_W']:.1f} +- {r['mean_se_W']:.2f} W "
            f"({runs} runs, pilot {r['n_pilot']}; correlation {r['correlation']:.3f}) in "
            f"{r['cpu_s']:.0f} CPU-s, where MBDyn alone needs {r['n_equivalent_hf']:.0f} runs "
            f"for the same standard error, {r['mbdyn_alone_cpu_s']:.0f} CPU-s at the "
            f"{d['mbdyn_run'][name]['cpu_s_mean']:.1f} CPU-s an elastic run costs: "
            f"{r['saving']:.1f}x")
    steps = d["steps_cpu_s"]
    other = sum(v for k, v in steps.items() if k not in mf)
    return (f"The whole study{' (--quick)' if d['quick'] else ''}, without the report: "
            f"{d['study_cpu_s']:.0f} CPU-s, {sum(steps[k] for k in mf):.0f} of them in the two "
            f"multi-fidelity steps and {other:.0f} in the LHS and the three Sobol' steps "
            f"(load average {d['loadavg_before'][0]:.1f} on {d['cores']} cores). "
            "Multi-fidelity estimates with MBDyn's elastic rotor as the expensive model: "
            + "; ".join(rows) + ".")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the study's --quick run")
    ap.add_argument("--hf-samples", type=int, default=3,
                    help="MBDyn runs timed per multi-fidelity step (default 3)")
    ap.add_argument("--out", default=None, help="write the JSON here too")
    ap.add_argument("--summary", default=None, help="print the paragraph of a saved JSON")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    res = {**run(args.quick, args.hf_samples), "provenance": provenance()}
    print_and_save(res, args.out)


if __name__ == "__main__":
    main()
