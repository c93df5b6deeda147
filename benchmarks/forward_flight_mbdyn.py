"""Forward-flight parity: the built-in rotor against MBDyn's rigid-blade rotor at mu = 0.1-0.3.

MBDyn does not trim, so both models fly the same given controls: the built-in ``gvpm`` rotor
is trimmed in the wind tunnel (thrust ``THRUST`` N, zero first-harmonic flapping, shaft angle
``SHAFT_DEG`` forward, Glauert's uniform inflow) at each advance ratio, and its collective,
lateral and longitudinal cyclic are flown by

- MBDyn's ``rigid`` template (blades pitched by a total joint to the hub, free stream from
  MBDyn's air properties, uniform momentum inflow of the rotor element), and
- the built-in rotor configured as that template (:func:`rotoruq.mbdyn.rigid_equivalent`:
  rigid blades, uniform Glauert inflow, no tip loss), the same physics.

Compared: thrust, power and the hub roll and pitch moments (rigid blades do not flap: their
first-harmonic flapping becomes the hub moments), each difference in % of the MBDyn value
(moments also in % of thrust * R, their natural scale). Every difference must be within
``LIMIT_PCT`` or its cause is computed: MBDyn's time step is one (the hub moments move by
10-20 % from 72 to 144 steps per revolution at mu = 0.3), so MBDyn also runs at 2x and 4x
the steps per revolution and each load is Richardson-extrapolated to zero time step with the
observed order of the three (``converged``); the differences of that value are the ones
left to explain.

Needs MBDyn ($MBDYN, PATH, or ~/.cache/mbdyn/bin/mbdyn). Prints JSON and writes
``benchmarks/results/forward_flight_mbdyn.json``; ``--summary [JSON]`` prints the docs' table
from a saved run; ``--mu 0.2`` runs one advance ratio (the test's check).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)

from rotoruq.mbdyn import CaseSettings, find_mbdyn, rigid_equivalent, run_case
from rotoruq.rotor.forward import ForwardRotorModel
from rotoruq.rotor.presets import get_preset

OUT = Path(__file__).resolve().parent / "results" / "forward_flight_mbdyn.json"
PRESET = "gvpm"
ADVANCE_RATIOS = (0.1, 0.2, 0.3)
THRUST = 20.0          # N, the forward_flight study's trim
SHAFT_DEG = 3.0        # deg, forward tilt
LIMIT_PCT = 5.0
CONTROLS = ("collective_deg", "lateral_deg", "longitudinal_deg")
LOADS = ("thrust", "power", "roll_moment", "pitch_moment")
_MBDYN_NAME = {"thrust": "thrust", "power": "power", "roll_moment": "roll",
               "pitch_moment": "pitch"}


def trimmed_controls(mu: float) -> dict[str, float]:
    """The built-in gvpm rotor's wind-tunnel trim at ``mu``: collective, lateral and
    longitudinal cyclic [deg]."""
    model = ForwardRotorModel(PRESET, names_in=["advance_ratio"],
                              names_out=["collective_trim_deg", "lateral_trim_deg",
                                         "longitudinal_trim_deg"],
                              fixed={"thrust_target": THRUST, "shaft_angle_deg": SHAFT_DEG},
                              trim="wind_tunnel", inflow_model="glauert")
    y = model([[mu]])[0]
    if not all(math.isfinite(v) for v in y):
        raise SystemExit(f"the built-in {PRESET} rotor does not trim at mu = {mu}")
    return dict(zip(CONTROLS, map(float, y), strict=True))


def builtin_loads(controls: dict[str, float], mu: float) -> dict[str, float]:
    names = [*CONTROLS, "advance_ratio", "shaft_angle_deg"]
    model = ForwardRotorModel(rigid_equivalent(get_preset(PRESET)), names_in=names,
                              names_out=list(LOADS), inflow_model="glauert")
    y = model([[*(controls[c] for c in CONTROLS), mu, SHAFT_DEG]])[0]
    return dict(zip(LOADS, map(float, y), strict=True))


def richardson(f1: float, f2: float, f4: float) -> tuple[float, float]:
    """The value at zero step and the observed order from a quantity at steps h, h/2, h/4
    (order 1 assumed where the three are not monotone or the order is below 1)."""
    d1, d2 = f1 - f2, f2 - f4
    p = math.log2(d1 / d2) if d1 * d2 > 0 and d1 != d2 else 1.0
    p = max(p, 1.0)
    return f4 + d2 / (2**p - 1), p


def compare(mbdyn: Path, settings: CaseSettings, mu: float, workdir: Path,
            refine: bool = True) -> dict:
    """One advance ratio: controls, both models' loads and their differences; with
    ``refine`` MBDyn also at 2x and 4x the steps per revolution, extrapolated."""
    preset = get_preset(PRESET)
    controls = trimmed_controls(mu)
    inputs = {**controls, "advance_ratio": mu, "shaft_angle_deg": SHAFT_DEG,
              "height_over_radius": math.inf}
    runs, walls = [], []
    for f in (1, 2, 4) if refine else (1,):
        s = CaseSettings(settings.revolutions, settings.steps_per_rev * f, settings.average,
                         settings.tolerance, settings.timeout)
        w0 = time.perf_counter()
        m = run_case(workdir / f"mu_{mu:g}_x{f}", preset, inputs, template="rigid",
                     settings=s, mbdyn=mbdyn)
        walls.append(time.perf_counter() - w0)
        runs.append({k: m.response(_MBDYN_NAME[k]) for k in LOADS})
    b = builtin_loads(controls, mu)
    md = runs[0]
    tr = md["thrust"] * preset.radius

    def pct(ref: dict) -> dict:
        return {k: 100 * (b[k] - ref[k]) / abs(ref[k]) for k in LOADS}

    row = {"advance_ratio": mu, "controls_deg": controls, "mbdyn": md,
           "builtin": {k: b[k] for k in LOADS}, "diff_pct": pct(md),
           "diff_pct_of_thrust_radius": {k: 100 * (b[k] - md[k]) / tr
                                         for k in ("roll_moment", "pitch_moment")},
           "mbdyn_wall_s": walls}
    if refine:
        conv, order = {}, {}
        for k in LOADS:
            conv[k], order[k] = richardson(*(r[k] for r in runs))
        row.update(mbdyn_steps_per_rev=[settings.steps_per_rev * f for f in (1, 2, 4)],
                   mbdyn_refined=runs[1:], mbdyn_converged=conv, observed_order=order,
                   diff_pct_converged=pct(conv))
    final = row.get("diff_pct_converged", row["diff_pct"])
    row["within_limit"] = bool(all(abs(v) <= LIMIT_PCT for v in row["diff_pct"].values()))
    row["converged_within_limit"] = bool(all(abs(v) <= LIMIT_PCT for v in final.values()))
    return row


def run(mus, revolutions: int, refine: bool = True) -> dict:
    settings = CaseSettings(revolutions=revolutions)
    mbdyn = find_mbdyn(build_prefix=True)
    c0 = _children_cpu()
    with tempfile.TemporaryDirectory() as tmp:
        rows = [compare(mbdyn, settings, mu, Path(tmp), refine) for mu in mus]
    worst = max(abs(v) for r in rows for v in r["diff_pct"].values())
    worst_conv = max(abs(v) for r in rows
                     for v in r.get("diff_pct_converged", r["diff_pct"]).values())
    return {"preset": PRESET, "thrust_target_N": THRUST, "shaft_angle_deg": SHAFT_DEG,
            "inflow": "uniform (Glauert) in both", "limit_pct": LIMIT_PCT,
            "revolutions": settings.revolutions, "steps_per_rev": settings.steps_per_rev,
            "rows": rows, "max_abs_diff_pct": worst,
            "max_abs_diff_pct_converged": worst_conv,
            "all_within_limit": bool(all(r["within_limit"] for r in rows)),
            "all_converged_within_limit": bool(all(r["converged_within_limit"]
                                                   for r in rows)),
            "mbdyn_cpu_s": _children_cpu() - c0}


def _children_cpu() -> float:
    import resource

    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def summary(path: Path) -> str:
    res = json.loads(Path(path).read_text())
    lines = [f"Built-in {res['preset']} rotor trimmed to {res['thrust_target_N']:g} N (wind "
             f"tunnel, shaft {res['shaft_angle_deg']:g} deg forward); its controls flown by "
             "MBDyn's rigid template and by the built-in rotor with the same physics "
             f"({res['inflow']}; {res['revolutions']} revolutions, {res['steps_per_rev']} steps "
             "each; controls: collective, lateral, longitudinal). Differences: built-in minus "
             "MBDyn, in % of MBDyn's value; in brackets against MBDyn extrapolated to zero time "
             "step (72, 144, 288 steps per revolution, observed order).", "",
             "| mu | controls [deg] | thrust MBDyn / built-in [N] | diff | power [W] | diff | "
             "roll [N m] | diff | pitch [N m] | diff |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in res["rows"]:
        c, m, b, d = r["controls_deg"], r["mbdyn"], r["builtin"], r["diff_pct"]
        dc = r.get("diff_pct_converged")

        def cell(k: str, d: dict = d, dc: dict | None = dc) -> str:
            return f"{d[k]:+.2f} %" + (f" ({dc[k]:+.2f} %)" if dc else "")

        lines.append(
            f"| {r['advance_ratio']:g} | {c['collective_deg']:.2f}, {c['lateral_deg']:+.2f}, "
            f"{c['longitudinal_deg']:+.2f} | {m['thrust']:.3f} / {b['thrust']:.3f} | "
            f"{cell('thrust')} | {m['power']:.1f} / {b['power']:.1f} | {cell('power')} | "
            f"{m['roll_moment']:+.3f} / {b['roll_moment']:+.3f} | {cell('roll_moment')} | "
            f"{m['pitch_moment']:+.3f} / {b['pitch_moment']:+.3f} | {cell('pitch_moment')} |")
    lim = res["limit_pct"]
    verdict = "all within" if res["all_within_limit"] else "NOT all within"
    lines += ["", f"Largest difference {res['max_abs_diff_pct']:.2f} % at 72 steps per "
              f"revolution: {verdict} {lim:g} %."]
    if "max_abs_diff_pct_converged" in res:
        worst_tr = max(abs(v) for r in res["rows"]
                       for v in r["diff_pct_of_thrust_radius"].values())
        v2 = ("all within" if res["all_converged_within_limit"] else "NOT all within")
        lines[-1] += (f" The hub moments' differences are MBDyn's time step: they are "
                      f"{worst_tr:.2f} % of thrust x R at most, and against MBDyn extrapolated "
                      f"to zero step the largest difference is "
                      f"{res['max_abs_diff_pct_converged']:.2f} %: {v2} {lim:g} %.")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mu", type=float, action="append", default=None,
                    help="advance ratio (repeatable; default 0.1, 0.2, 0.3)")
    ap.add_argument("--revolutions", type=int, default=20)
    ap.add_argument("--no-refine", action="store_true",
                    help="MBDyn at 72 steps per revolution only (no time-step extrapolation)")
    ap.add_argument("--out", type=Path, default=None,
                    help=f"write the JSON here (default with all advance ratios: {OUT})")
    ap.add_argument("--summary", type=Path, nargs="?", const=OUT, default=None,
                    help="print the table of a saved JSON instead of running")
    args = ap.parse_args()
    if args.summary:
        print(summary(args.summary))
        return
    mus = tuple(args.mu) if args.mu else ADVANCE_RATIOS
    res = {**run(mus, args.revolutions, not args.no_refine), "provenance": provenance()}
    text = json.dumps(res, indent=2)
    out = args.out or (OUT if mus == ADVANCE_RATIOS else None)
    if out is not None:
        out.write_text(text + "\n")
    print(text)
    sys.exit(0)


if __name__ == "__main__":
    main()
