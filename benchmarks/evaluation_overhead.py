"""Per-evaluation overhead of the store and of each executor; process-pool throughput.

Prints JSON. Targets: store overhead < 1 ms per evaluation; keying an evaluation by its full
identity well under 0.1 ms per evaluation; process-pool throughput on a CPU-bound model near
(number of cores) x serial.

    python benchmarks/evaluation_overhead.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from rotoruq.evaluation.dakota_files import write_parameters
from rotoruq.evaluation.evaluator import Evaluator
from rotoruq.evaluation.executors import DaskExecutor, ProcessExecutor, SerialExecutor
from rotoruq.evaluation.external import ExternalModel
from rotoruq.evaluation.store import NewRecord, Store
from rotoruq.model import FunctionModel

DRIVER = r'''
import sys
lines = open(sys.argv[1]).read().splitlines()
n = int(lines[0].split()[0])
s = sum(float(l.split()[0]) for l in lines[1 : 1 + n])
open(sys.argv[2], "w").write(f"{s!r} f\n")
'''


def trivial(x):
    return x.sum(axis=1)


_T = np.linspace(0.0, 1.0, 100_000)


def cpu_bound(x):
    # a few ms of elementwise arithmetic per row (no BLAS, so one core per worker)
    return np.array([np.sum(np.sin(r[0] * _T) * np.cos(r[1] * _T)) for r in x])


def per_eval(fn, n: int, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best / n


def identity_cost(tmp: Path, x: np.ndarray) -> dict:
    """What keying evaluations by everything that changes their answer costs.

    Once per model object: the model's identity (configuration digest, airfoil table and files
    by content, code version); once per evaluation: the canonical key of the input vector.
    """
    from rotoruq.evaluation.identity import code_version, model_identity
    from rotoruq.evaluation.store import canonical_keys
    from rotoruq.rotor.model import RotorModel

    t0 = time.perf_counter()
    code_version.cache_clear()
    code_version()
    code = time.perf_counter() - t0
    rotor = RotorModel("gvpm", names_in=["collective_deg", "k_pitch_link"], names_out=["thrust"])
    drv = tmp / "id_driver.py"
    drv.write_text(DRIVER)
    ext = ExternalModel([sys.executable, "-S", str(drv)], ["a", "b", "c", "d"], ["f"],
                        workdir=tmp / "id_work")
    res = {"code_version_ms_once_per_process": 1e3 * code}
    for name, m in (("rotor_gvpm", rotor), ("external", ext)):
        res[f"{name}_identity_ms_once_per_model"] = 1e3 * per_eval(lambda m=m: model_identity(m),
                                                                   1, repeat=5)
    key = per_eval(lambda: canonical_keys(x), len(x), repeat=5)
    res["key_us_per_eval"] = 1e6 * key
    # an Evaluator computes the identity once; a study's step makes one Evaluator and
    # evaluates through it (1,000 to 100,000 points), a single point pays it in full
    worst_once = max(v for k, v in res.items() if k.endswith("once_per_model"))
    res["per_eval_us_1000_evals_per_model"] = 1e6 * key + 1e3 * worst_once / 1000
    res["per_eval_us_1_eval_per_model"] = 1e6 * key + 1e3 * worst_once
    res["target_us_per_eval"] = 100.0
    res["meets_target"] = bool(res["per_eval_us_1000_evals_per_model"] < 100.0)
    return res


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    n_store = 300 if args.quick else 1000
    n_ext = 20 if args.quick else 40
    cores = os.cpu_count() or 1
    rng = np.random.default_rng(0)
    out: dict = {"cores": cores}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        # -- the store on its own: one committed transaction per evaluation, then lookups
        st = Store(tmp / "raw.db")
        x = rng.normal(size=(n_store, 4))
        kw = dict(study="b", model="m", names_in="abcd", names_out=("f",))
        t0 = time.perf_counter()
        for i in range(n_store):
            st.add([NewRecord(x[i], x[i, :1])], **kw)
        commit = (time.perf_counter() - t0) / n_store
        t0 = time.perf_counter()
        st.lookup(x, study="b", model="m")
        lookup = (time.perf_counter() - t0) / n_store
        out["store"] = {"commit_ms_per_eval": 1e3 * commit, "lookup_ms_per_eval": 1e3 * lookup,
                        "target_ms": 1.0, "meets_target": bool(commit + lookup < 1e-3)}
        out["identity"] = identity_cost(tmp, x)

        # -- Evaluator overhead on a trivial vectorized model, per executor
        model = FunctionModel(trivial, ["a", "b", "c", "d"], ["f"])
        raw = per_eval(lambda: model(x), n_store)
        res = {"raw_model_us_per_eval": 1e6 * raw}
        pool = ProcessExecutor()
        execs = {"serial": SerialExecutor(), "processes": pool}
        dask = None
        try:
            dask = DaskExecutor(n_workers=min(2, cores))
            _ = dask.client  # start the local cluster outside the timing
            execs["dask_local"] = dask
        except Exception as exc:  # report, do not fail the benchmark
            res["dask_error"] = str(exc)
        for name, ex in execs.items():
            ev = Evaluator(model, executor=ex)
            ev.evaluate(x[:8])  # warm the workers
            res[f"{name}_no_store_us_per_eval"] = 1e6 * per_eval(lambda ev=ev: ev.evaluate(x),
                                                                n_store)

            def stored(ex=ex, name=name):
                db = tmp / f"{name}-{time.perf_counter_ns()}.db"
                b = Evaluator(model, executor=ex, store=db).evaluate(x)
                assert not b.failures, b.failures

            res[f"{name}_with_store_us_per_eval"] = 1e6 * per_eval(stored, n_store, repeat=2)
            db = tmp / f"{name}-reuse.db"
            Evaluator(model, executor=ex, store=db).evaluate(x)
            res[f"{name}_all_reused_us_per_eval"] = 1e6 * per_eval(
                lambda ex=ex, db=db: Evaluator(model, executor=ex, store=db).evaluate(x), n_store)
        out["trivial_model"] = res

        # -- CPU-bound model: process pool throughput vs serial
        heavy = FunctionModel(cpu_bound, ["a", "b"], ["f"])
        xh = rng.normal(size=(100 if args.quick else 200, 2))
        t_serial = per_eval(lambda: Evaluator(heavy).evaluate(xh), len(xh), repeat=2)
        t_pool = per_eval(lambda: Evaluator(heavy, executor=pool).evaluate(xh), len(xh),
                          repeat=2)
        out["cpu_bound_model"] = {
            "serial_ms_per_eval": 1e3 * t_serial, "processes_ms_per_eval": 1e3 * t_pool,
            "speedup": t_serial / t_pool, "ideal_speedup": cores,
            "efficiency": t_serial / t_pool / cores,
        }

        # -- trivial external driver: process start-up dominates; overhead of the layer
        drv = tmp / "driver.py"
        drv.write_text(DRIVER)
        ext = ExternalModel([sys.executable, "-S", str(drv)], ["a", "b", "c", "d"], ["f"],
                            workdir=tmp / "work")
        xe = rng.normal(size=(n_ext, 4))
        params = tmp / "p.in"
        write_parameters(params, dict(zip("abcd", xe[0], strict=True)), ["f"])

        def bare_runs():
            for _ in range(n_ext):
                subprocess.run([sys.executable, "-S", str(drv), str(params), str(tmp / "r.out")],
                               check=True)

        bare = per_eval(bare_runs, n_ext, repeat=2)
        eres = {"bare_subprocess_ms_per_eval": 1e3 * bare}
        for name, ex in execs.items():
            def run(ex=ex, name=name):
                db = tmp / f"ext-{name}-{time.perf_counter_ns()}.db"
                b = Evaluator(ext, executor=ex, store=db).evaluate(xe)
                assert not b.failures, b.failures  # timings of failed runs would mean nothing

            t = per_eval(run, n_ext, repeat=2)
            eres[f"{name}_ms_per_eval"] = 1e3 * t
            eres[f"{name}_layer_overhead_ms_per_eval"] = 1e3 * (t - bare) if name == "serial" \
                else None
        eres = {k: v for k, v in eres.items() if v is not None}
        out["trivial_external_driver"] = eres
        pool.close()
        if dask is not None:
            dask.close()
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
