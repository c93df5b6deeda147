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
(moments: in % of thrust * R, their natural scale, since a trimmed rotor's moments are
small). Every difference must be within ``LIMIT_PCT`` or its cause is computed and recorded.

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


def compare(mbdyn: Path, settings: CaseSettings, mu: float, workdir: Path) -> dict:
    """One advance ratio: controls, both models' loads and their differences."""
    preset = get_preset(PRESET)
    controls = trimmed_controls(mu)
    t0 = time.process_time()
    w0 = time.perf_counter()
    m = run_case(workdir / f"mu_{mu:g}", preset,
                 {**controls, "advance_ratio": mu, "shaft_angle_deg": SHAFT_DEG,
                  "height_over_radius": math.inf}, template="rigid", settings=settings,
                 mbdyn=mbdyn)
    wall = time.perf_counter() - w0
    b = builtin_loads(controls, mu)
    md = {k: m.response(_MBDYN_NAME[k]) for k in LOADS}
    scale = {"thrust": md["thrust"], "power": md["power"],
             "roll_moment": md["thrust"] * preset.radius,
             "pitch_moment": md["thrust"] * preset.radius}
    diff = {k: 100 * (b[k] - md[k]) / abs(scale[k]) for k in LOADS}
    return {"advance_ratio": mu, "controls_deg": controls, "mbdyn": md,
            "builtin": {k: b[k] for k in LOADS},
            "diff_pct": diff,
            "within_limit": bool(all(abs(v) <= LIMIT_PCT for v in diff.values())),
            "mbdyn_inflow_ms": m.inflow,
            "mbdyn_wall_s": wall, "parent_cpu_s": time.process_time() - t0}


def run(mus, revolutions: int) -> dict:
    settings = CaseSettings(revolutions=revolutions)
    mbdyn = find_mbdyn(build_prefix=True)
    with tempfile.TemporaryDirectory() as tmp:
        rows = [compare(mbdyn, settings, mu, Path(tmp)) for mu in mus]
    worst = max(abs(v) for r in rows for v in r["diff_pct"].values())
    return {"preset": PRESET, "thrust_target_N": THRUST, "shaft_angle_deg": SHAFT_DEG,
            "inflow": "uniform (Glauert) in both", "limit_pct": LIMIT_PCT,
            "revolutions": settings.revolutions, "steps_per_rev": settings.steps_per_rev,
            "rows": rows, "max_abs_diff_pct": worst,
            "all_within_limit": bool(all(r["within_limit"] for r in rows))}


def summary(path: Path) -> str:
    res = json.loads(Path(path).read_text())
    lines = [f"Built-in {res['preset']} rotor trimmed to {res['thrust_target_N']:g} N (wind "
             f"tunnel, shaft {res['shaft_angle_deg']:g} deg forward); its controls flown by "
             "MBDyn's rigid template and by the built-in rotor with the same physics "
             f"({res['inflow']}; {res['revolutions']} revolutions, {res['steps_per_rev']} steps "
             "each). Moment differences in % of thrust x R.", "",
             "| mu | controls [deg] | thrust MBDyn / built-in [N] | diff | power [W] | diff | "
             "roll [N m] | diff | pitch [N m] | diff |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in res["rows"]:
        c, m, b, d = r["controls_deg"], r["mbdyn"], r["builtin"], r["diff_pct"]
        lines.append(
            f"| {r['advance_ratio']:g} | {c['collective_deg']:.2f}, {c['lateral_deg']:+.2f}, "
            f"{c['longitudinal_deg']:+.2f} | {m['thrust']:.3f} / {b['thrust']:.3f} | "
            f"{d['thrust']:+.2f} % | {m['power']:.1f} / {b['power']:.1f} | "
            f"{d['power']:+.2f} % | {m['roll_moment']:+.3f} / {b['roll_moment']:+.3f} | "
            f"{d['roll_moment']:+.2f} % | {m['pitch_moment']:+.3f} / "
            f"{b['pitch_moment']:+.3f} | {d['pitch_moment']:+.2f} % |")
    verdict = "all within" if res["all_within_limit"] else "NOT all within"
    lines += ["", f"Largest difference {res['max_abs_diff_pct']:.2f} %: {verdict} "
              f"{res['limit_pct']:g} %."]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mu", type=float, action="append", default=None,
                    help="advance ratio (repeatable; default 0.1, 0.2, 0.3)")
    ap.add_argument("--revolutions", type=int, default=20)
    ap.add_argument("--out", type=Path, default=None,
                    help=f"write the JSON here (default with all advance ratios: {OUT})")
    ap.add_argument("--summary", type=Path, nargs="?", const=OUT, default=None,
                    help="print the table of a saved JSON instead of running")
    args = ap.parse_args()
    if args.summary:
        print(summary(args.summary))
        return
    mus = tuple(args.mu) if args.mu else ADVANCE_RATIOS
    res = {**run(mus, args.revolutions), "provenance": provenance()}
    text = json.dumps(res, indent=2)
    out = args.out or (OUT if mus == ADVANCE_RATIOS else None)
    if out is not None:
        out.write_text(text + "\n")
    print(text)
    sys.exit(0)


if __name__ == "__main__":
    main()
