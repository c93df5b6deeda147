"""CPU seconds of the chain diagnostics and of a GP fit's likelihood gradient, this tree
against an earlier commit's code in the same process (issue 34: the diagnostics computed
once, the average ranks by runs).

The earlier commit's ``methods/mcmc/diagnostics.py`` and ``methods/surrogate.py`` are read
with ``git show`` and loaded beside this tree's; each piece runs alternately with the old and
the new code on the same inputs (chains of a Metropolis-like process that repeats its point
at 70 % of the steps, as a DRAM chain at its usual acceptance does), CPU seconds by
``time.process_time`` (comparable on a loaded machine), and the answers are asserted equal
bit for bit.

    python benchmarks/diagnostics_cpu.py --before 15b6299 \
        --json benchmarks/results/diagnostics_cpu.json
    python benchmarks/diagnostics_cpu.py --summary benchmarks/results/diagnostics_cpu.json
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_and_save, print_saved_summary  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FILES = {"diagnostics": "src/rotoruq/methods/mcmc/diagnostics.py",
         "surrogate": "src/rotoruq/methods/surrogate.py"}
PACKAGES = {"diagnostics": "rotoruq.methods.mcmc", "surrogate": "rotoruq.methods"}


def _old_modules(commit: str, folder: str) -> dict:
    """The two modules as of ``commit``, loaded inside their packages (relative imports)."""
    out = {}
    for key, rel in FILES.items():
        src = subprocess.run(["git", "show", f"{commit}:{rel}"], cwd=ROOT, check=True,
                             capture_output=True, text=True).stdout
        path = os.path.join(folder, f"{key}.py")
        Path(path).write_text(src)
        name = f"{PACKAGES[key]}._before_{key}"
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
        out[key] = mod
    return out


def _chain(rng, c: int, n: int, d: int) -> np.ndarray:
    x = rng.standard_normal((c, n, d)).cumsum(1) * 0.1 + rng.standard_normal((c, n, d))
    stay = rng.random((c, n)) < 0.7
    for k in range(1, n):
        x[:, k][stay[:, k]] = x[:, k - 1][stay[:, k]]
    return x


def _fields(record, names) -> list:
    return [getattr(record, n) for n in names]


def _same(a, b) -> bool:
    return all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b, strict=True))


def _ab(f_old, f_new, repeats: int) -> dict:
    t_old = t_new = 0.0
    for _ in range(repeats):
        t = time.process_time()
        a = f_old()
        t_old += time.process_time() - t
        t = time.process_time()
        b = f_new()
        t_new += time.process_time() - t
    assert _same(a, b), "the two versions' answers differ"
    return {"before_ms": round(t_old / repeats * 1e3, 2),
            "after_ms": round(t_new / repeats * 1e3, 2), "repeats": repeats}


def measure(commit: str) -> dict:
    from rotoruq.methods import surrogate as sg
    from rotoruq.methods._common import one_blas_thread
    from rotoruq.methods.mcmc import diagnostics as dg

    rng = np.random.default_rng(0)
    fields = ("rhat", "rhat_bulk", "rhat_folded", "ess_bulk", "ess_tail", "mcse_mean",
              "mcse_q05", "mcse_q95")
    with tempfile.TemporaryDirectory() as tmp:
        old = _old_modules(commit, tmp)
        odg, osg = old["diagnostics"], old["surrogate"]
        main = _chain(rng, 4, 23750, 9)  # a chapter's calibration: 4 chains, 9 parameters
        check = [_chain(rng, 1, n, 9) for n in (1995, 3990, 7995)]  # a self-check's chains
        pieces = {
            "diagnose, 4 x 23750 x 9": _ab(
                lambda: _fields(odg.diagnose(main), fields),
                lambda: _fields(dg.diagnose(main), fields), 5),
            "summary ESS and R-hat, 4 x 23750 x 9": _ab(
                lambda: (odg.effective_sample_size(main), odg.split_rhat(main)),
                lambda: dg.ess_and_rhat(main), 3),
            "self-check ESS, 1 x {1995, 3990, 7995} x 9": _ab(
                lambda: [odg.effective_sample_size(x) for x in check],
                lambda: [dg.effective_sample_size(x) for x in check], 10),
        }
        for n in (300, 500):  # the held-out chapter's and the experiment's emulator designs
            X = rng.random((n, 9))
            y = np.sin(X @ rng.normal(size=9))
            with one_blas_thread():
                g_old = osg.GaussianProcess(trend="reduced_quadratic").fit(X, y)
                g_new = sg.GaussianProcess(trend="reduced_quadratic").fit(X, y)
                theta = np.log(np.full(9, 0.4))
                ys = (g_new._Y[:, 0] - g_new._y_mean[0]) / g_new._y_std[0]
                pieces[f"GP likelihood and gradient, {n} points, 9 inputs"] = _ab(
                    lambda g=g_old, y=ys, t=theta: g._solve(y, t, None, True)[:2],
                    lambda g=g_new, y=ys, t=theta: g._solve(y, t, None, True)[:2], 20)
    return {"before": commit, "pieces": pieces}


def summary(result: dict) -> str:
    parts = [f"{name} {p['before_ms']:.1f} -> {p['after_ms']:.1f} ms"
             for name, p in result["pieces"].items()]
    return (f"`python benchmarks/diagnostics_cpu.py --before {result['before']}` (CPU "
            f"milliseconds a call, the code of {result['before']} -> this tree, alternated in "
            f"one process, the same bits asserted, load {result['provenance']['load'][0]}): "
            + "; ".join(parts) + ".")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--before", default="15b6299", help="the commit to compare with")
    ap.add_argument("--json", default=None, help="also write the JSON to this file")
    ap.add_argument("--summary", default=None, metavar="JSON",
                    help="print the docs' sentence for a saved run and exit")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    result = measure(args.before)
    result["provenance"] = provenance(modules=["rotoruq.methods.mcmc.diagnostics",
                                               "rotoruq.methods.surrogate"])
    print_and_save(result, args.json)


if __name__ == "__main__":
    main()
