"""Where a cold first run spends its numba compile time: CPU seconds per compiled function
(issue 34).

Runs each study (``rotoruq run STUDY --quick --no-report``) in a fresh Python process with an
empty ``NUMBA_CACHE_DIR`` and records numba's compile events. A function's *inclusive* time
is the CPU time of its calling thread from the start to the end of its compilation (its
callees compile inside it); *exclusive* subtracts the callees compiled meanwhile. CPU time of
the compiling thread, not wall time: the machine is shared. Also records each function's
number of compiled signatures (one per kernel is the aim: a second one doubles its cost),
and the compiling thread's CPU per stage of numba's compiler (``phases``: its Python front
end, LLVM's optimisation of each function and of each library's final module, machine code,
...): every compiled function's library is optimised and turned into machine code again
with the code of every function it calls, so a deep call tree pays for its leaves once per
caller above them.

    python benchmarks/compile_time.py --json benchmarks/results/compile_time.json
    python benchmarks/compile_time.py --studies quick
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_and_save  # noqa: E402  (benchmarks/ is on sys.path)

STUDIES = ("quick", "validation", "experiment", "heldout")


def child(study: str, out: str) -> None:
    """Run ``study`` in this process while recording compile events; print JSON last."""
    from numba.core import event

    from rotoruq.study.cli import main as cli_main

    stack: list[list] = []  # [name, start cpu, callees' cpu]
    rows: dict[str, dict] = {}

    class Recorder(event.Listener):
        def on_start(self, ev):
            stack.append([_name(ev), time.thread_time(), 0.0])

        def on_end(self, ev):
            name, t0, inner = stack.pop()
            total = time.thread_time() - t0
            if stack:
                stack[-1][2] += total
            row = rows.setdefault(name, {"inclusive": 0.0, "exclusive": 0.0, "signatures": 0})
            row["signatures"] += 1
            row["exclusive"] += total - inner
            if not any(s[0] == name for s in stack):
                row["inclusive"] += total

    phases = _time_phases()
    c0 = time.process_time()
    with event.install_listener("numba:compile", Recorder()):
        code = cli_main(["run", study, "--quick", "--no-report", "--out", out, "-q"])
    cpu = time.process_time() - c0
    for row in rows.values():
        row["inclusive"] = round(row["inclusive"], 2)
        row["exclusive"] = round(row["exclusive"], 2)
    print(json.dumps({"exit": code, "cpu": round(cpu, 2), "functions": rows,
                      "phases": {k: round(v, 2) for k, v in sorted(
                          phases.items(), key=lambda kv: -kv[1])}}))


#: numba's compiler stages timed by :func:`_time_phases`: (module, class, method, phase)
PHASES = (("numba.core.codegen", "CPUCodeLibrary", "_optimize_functions", "llvm_opt_functions"),
          ("numba.core.codegen", "CPUCodeLibrary", "_optimize_final_module",
           "llvm_opt_final_module"),
          ("numba.core.codegen", "JITCodeLibrary", "_finalize_specific", "llvm_machine_code"),
          ("numba.core.codegen", "CPUCodeLibrary", "add_ir_module", "llvm_parse_ir"),
          ("numba.core.cpu", "CPUContext", "create_cpython_wrapper", "cpython_wrapper"),
          ("numba.core.lowering", "Lower", "lower", "lowering"),
          ("numba.core.typeinfer", "TypeInferer", "propagate", "type_inference"),
          ("numba.core.caching", "Cache", "save_overload", "cache_save"),
          ("numba.core.dispatcher", "Dispatcher", "compile", "frontend_other"))


def _time_phases() -> dict[str, float]:
    """Wrap numba's compiler stages (:data:`PHASES`) to add the CPU seconds of the calling
    thread spent in each, exclusive of the stages nested in it, to the returned dict (a
    stage numba no longer has is left out). One stack per thread: a solve spread over threads
    calls a cold kernel from each, and all but one wait in the dispatcher for its compile."""
    import importlib
    import threading

    acc: dict[str, float] = {}
    local = threading.local()

    def wrap(cls, name, phase):
        inner_fn = getattr(cls, name)

        def timed(*args, **kwargs):
            stack = local.__dict__.setdefault("stack", [])  # [phase, start cpu, nested cpu]
            stack.append([phase, time.thread_time(), 0.0])
            try:
                return inner_fn(*args, **kwargs)
            finally:
                _, t0, inner = stack.pop()
                total = time.thread_time() - t0
                if stack:
                    stack[-1][2] += total
                acc[phase] = acc.get(phase, 0.0) + total - inner

        setattr(cls, name, timed)

    for module, cls_name, name, phase in PHASES:
        cls = getattr(importlib.import_module(module), cls_name, None)
        if cls is not None and hasattr(cls, name):
            wrap(cls, name, phase)
    return acc


def _name(ev) -> str:
    disp = ev.data.get("dispatcher")
    fn = getattr(disp, "py_func", None)
    if fn is None:
        return str(disp)
    return f"{fn.__module__}.{fn.__qualname__}"


def run_study(study: str, tmp: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=os.path.join(tmp, f"numba-{study}"))
    c0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run([sys.executable, __file__, "--child", study,
                           os.path.join(tmp, f"out-{study}")],
                          env=env, capture_output=True, text=True)
    c1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        return {"error": done.stderr[-2000:]}
    got = json.loads(done.stdout.strip().splitlines()[-1])
    funcs = got["functions"]
    roots = {k: v for k, v in funcs.items()}
    compile_cpu = sum(v["exclusive"] for v in funcs.values())
    return {"process_cpu_seconds": round(c1.ru_utime + c1.ru_stime - c0.ru_utime - c0.ru_stime,
                                         2),
            "compile_thread_cpu_seconds": round(compile_cpu, 2),
            "exit": got["exit"],
            "phases": got.get("phases", {}),
            "functions": dict(sorted(roots.items(), key=lambda kv: -kv[1]["inclusive"]))}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--studies", nargs="+", default=list(STUDIES), choices=STUDIES)
    ap.add_argument("--json", default=None, help="also write the JSON to this file")
    ap.add_argument("--child", nargs=2, metavar=("STUDY", "OUT"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(*args.child)
        return
    result: dict = {"cold_numba_cache": True, "quick": True, "studies": {}}
    with tempfile.TemporaryDirectory(prefix="rotoruq-compile-") as tmp:
        for study in args.studies:
            result["studies"][study] = run_study(study, tmp)
    result["provenance"] = provenance(modules=["rotoruq.rotor._kernel",
                                               "rotoruq.methods.mcmc._kernels",
                                               "rotoruq.methods._gp_mean"])
    print_and_save(result, args.json)


if __name__ == "__main__":
    main()
