"""CPU cost of one ``rotoruq driver`` evaluation (what Dakota pays per evaluation) against a bare
interpreter start and the rotor model itself, measured in one run.

Each repeat runs, one after the other, in fresh processes (CPU = user + system of the child,
from ``getrusage(RUSAGE_CHILDREN)``):

- ``bare``: ``python -c pass``;
- ``model``: a ``python -c`` that imports the rotor model and evaluates the one built-in point
  (import, numba kernels loaded from their cache, one evaluation): what the model costs in a
  process of its own. Inside it the split is timed with ``time.process_time``: import, kernel
  load + first evaluation, a second (warm) evaluation;
- ``driver``: ``rotoruq driver params.in results.out`` on the same point (the console script
  next to this interpreter, else ``python -m rotoruq.study.cli``), in process
  (``ROTORUQ_DRIVER_SERVER=0``);
- ``warm``: the same command on the warm path, answered by a driver server (started before
  the repeats, in a socket folder of this run, stopped at the end). The client's CPU is
  measured as above; the server's (its master and workers, from ``/proc/<pid>/stat``) is read
  before and after all warm calls and divided by their number: ``warm_total_cpu_s`` = client +
  server share. The server's start (imports, kernels, one call) is reported apart.

The children run with Python's bytecode cache allowed (``PYTHONDONTWRITEBYTECODE`` removed from
their environment), as an installed package has it; the first, untimed call writes it.

Medians over ``--repeat`` repeats. ``driver_overhead_s`` = driver - model: what the driver adds
beyond the model (reading and writing the files, argument parsing, the modules it imports that
the model does not); the kernel load counts as model time. Target: < 0.1 s.
``in_process_eval_s`` is the warm evaluation (what ``rotoruq run`` pays per point, unbatched).
Target of the warm path (issue 32): at most 0.05 s of client CPU per call.

    python benchmarks/driver_overhead.py [--repeat 7] [--summary saved.json]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_saved_summary

from rotoruq.evaluation.dakota_files import read_results, write_parameters
from rotoruq.study import cmd_serve
from rotoruq.study import driver_client as client

POINT = {"collective_deg": 8.0}
# the children: bytecode cache allowed (as an installed package has it), warm path off unless
# asked for
ENV = {**{k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"},
       client.SWITCH: "0"}
OUTPUTS = ["thrust", "torque"]

MODEL = f"""
import time
t0 = time.process_time()
import numpy as np
from rotoruq.model import evaluate
from rotoruq.rotor.model import RotorModel
m = RotorModel("gvpm", names_in={list(POINT)!r}, names_out={OUTPUTS!r})
t1 = time.process_time()
x = np.array([{list(POINT.values())!r}])
evaluate(m, x)
t2 = time.process_time()
evaluate(m, x)
t3 = time.process_time()
print(t1 - t0, t2 - t1, t3 - t2)
"""

LOADED = """
import runpy, sys
sys.argv = ["rotoruq", "driver", "params.in", "results.out"]
try:
    runpy.run_module("rotoruq.study.cli", run_name="__main__")
except SystemExit:
    pass
print(" ".join(sorted(m for m in sys.modules if m.startswith(("rotoruq", "scipy")))))
"""


def driver_command() -> list[str]:
    script = Path(sys.executable).with_name("rotoruq")
    if script.is_file():
        return [str(script), "driver"]
    return [sys.executable, "-m", "rotoruq.study.cli", "driver"]


def cpu_of(cmd: list[str], cwd: Path, env: dict | None = None) -> tuple[float, str]:
    """CPU seconds (user + system) of a child process, and its stdout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run(cmd, cwd=cwd, check=True, capture_output=True, text=True,
                         env=env or ENV).stdout
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), out


def server_cpu(folder: str) -> tuple[float, int]:
    """CPU seconds (user + system) of the server's master and workers so far, and its calls."""
    state = cmd_serve.status(folder)
    assert state is not None, "the driver server does not answer"
    tick = os.sysconf("SC_CLK_TCK")
    total = 0.0
    for pid in [state["pid"], *state["worker_pids"].split(",")]:
        fields = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()
        total += (int(fields[11]) + int(fields[12])) / tick  # utime, stime
    return total, int(state["calls"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--summary", metavar="JSON", help="print README's paragraph for a saved "
                    "result instead of running")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    work = Path(tempfile.mkdtemp(prefix="rotoruq-driver-bench-"))
    write_parameters(work / "params.in", POINT, OUTPUTS)
    drv = driver_command()
    cpu_of(drv + ["params.in", "results.out"], work)  # numba cache warm, files in the OS cache
    folder = tempfile.mkdtemp(prefix="rq-bench-")
    warm_env = {**ENV, client.SWITCH: "1", client.DIR_VAR: folder,
                client.WORKERS_VAR: str(os.cpu_count() or 1)}
    os.environ[client.DIR_VAR] = folder  # for cmd_serve.status / stop in this process
    start_cpu, _ = cpu_of(drv + ["params.in", "results_warm.out"], work, warm_env)
    server_start_cpu, _ = server_cpu(folder)
    runs: dict[str, list[float]] = {"bare": [], "model": [], "driver": [], "import": [],
                                    "kernel_first_eval": [], "warm_eval": [], "warm": []}
    server_before = server_cpu(folder)
    for _ in range(args.repeat):
        runs["warm"].append(cpu_of(drv + ["params.in", "results_warm.out"], work,
                                   warm_env)[0])
        runs["bare"].append(cpu_of([sys.executable, "-c", "pass"], work)[0])
        t, out = cpu_of([sys.executable, "-c", MODEL], work)
        runs["model"].append(t)
        for key, v in zip(("import", "kernel_first_eval", "warm_eval"), out.split(), strict=True):
            runs[key].append(float(v))
        runs["driver"].append(cpu_of(drv + ["params.in", "results.out"], work)[0])
    server_after = server_cpu(folder)
    cmd_serve.stop(folder)
    served = server_after[1] - server_before[1]
    server_share = (server_after[0] - server_before[0]) / max(served, 1)
    res = read_results(work / "results.out", names_out=OUTPUTS)
    same = (work / "results.out").read_bytes() == (work / "results_warm.out").read_bytes()
    loaded = set(cpu_of([sys.executable, "-c", LOADED], work)[1].split())
    med = {k: statistics.median(v) for k, v in runs.items()}
    out = {
        "repeats": args.repeat,
        "point": POINT,
        "driver_command": " ".join(Path(drv[0]).name if i == 0 else w
                                   for i, w in enumerate(drv)),
        "bare_python_cpu_s": round(med["bare"], 4),
        "model_process_cpu_s": round(med["model"], 4),
        "model_split_s": {"import": round(med["import"], 4),
                          "kernel_load_and_first_eval": round(med["kernel_first_eval"], 4),
                          "warm_eval": round(med["warm_eval"], 5)},
        "driver_cpu_s": round(med["driver"], 4),
        "driver_overhead_s": round(med["driver"] - med["model"], 4),
        "driver_over_bare_s": round(med["driver"] - med["bare"], 4),
        "in_process_eval_s": round(med["warm_eval"], 5),
        "target_overhead_s": 0.1,
        "meets_target": bool(med["driver"] - med["model"] < 0.1),
        "driver_loads_step_types": "rotoruq.steps" in loaded,
        "driver_loads_scipy_stats": "scipy.stats" in loaded,
        "driver_rotoruq_modules": sum(1 for m in loaded if m.startswith("rotoruq")),
        "results_ok": bool(not res.failed and len(res.values) == len(OUTPUTS)),
        "warm_path": {
            "client_cpu_s": round(med["warm"], 4),
            "server_cpu_per_call_s": round(server_share, 4),
            "warm_total_cpu_s": round(med["warm"] + server_share, 4),
            "calls_served": served,
            "server_workers": int(warm_env[client.WORKERS_VAR]),
            "first_call_client_cpu_s": round(start_cpu, 4),
            "server_start_cpu_s": round(server_start_cpu, 4),
            "results_equal_in_process": bool(same),
            "target_client_cpu_s": 0.05,
            "meets_target": bool(med["warm"] <= 0.05),
            "client_over_bare_s": round(med["warm"] - med["bare"], 4),
            "speedup_total": round(med["driver"] / (med["warm"] + server_share), 1),
        },
        "bytecode_cached": "PYTHONDONTWRITEBYTECODE" not in ENV,
        "cpus": os.cpu_count(),
    }
    out["provenance"] = provenance(modules=["rotoruq.study.cli", "rotoruq.rotor.model"])
    print(json.dumps(out, indent=1))


def summary(d: dict) -> str:
    return (f"`python benchmarks/driver_overhead.py`: one built-in rotor point through "
            f"`rotoruq driver` costs {d['driver_cpu_s']:.2f} s of CPU; the same point in a "
            f"process of its own (import, numba kernels from cache, one evaluation) "
            f"{d['model_process_cpu_s']:.2f} s, a bare `python -c pass` "
            f"{d['bare_python_cpu_s']:.3f} s: the driver adds {d['driver_overhead_s']:.3f} s "
            f"beyond the model (target < {d['target_overhead_s']} s; medians of "
            f"{d['repeats']}). In process, the warm evaluation costs "
            f"{1e3 * d['in_process_eval_s']:.2f} ms." + warm_summary(d))


def warm_summary(d: dict) -> str:
    w = d.get("warm_path")
    if not w:
        return ""
    return (f" On the warm path (a driver server holds the model) a call costs the client "
            f"{w['client_cpu_s']:.3f} s of CPU (target <= {w['target_client_cpu_s']} s: "
            f"{'met' if w['meets_target'] else 'NOT met'}; {w['client_over_bare_s']:.3f} s "
            f"beyond a bare interpreter) and the server {w['server_cpu_per_call_s']:.3f} s, "
            f"{w['warm_total_cpu_s']:.3f} s in all, {w['speedup_total']:g}x less than in "
            f"process; its results file is "
            f"{'byte for byte' if w['results_equal_in_process'] else 'NOT'} the in-process "
            f"one. Starting the server "
            f"(imports, kernels, first call) costs {w['server_start_cpu_s']:.2f} s of CPU, once.")


if __name__ == "__main__":
    main()
