"""MBDyn parity and speed: the built-in rotor against MBDyn's rigid-blade model.

For both presets (rigid blades, the template ``rigid``; the built-in model configured the same
way by :func:`rotoruq.mbdyn.rigid_equivalent`), at several collectives and heights: thrust and
torque from MBDyn and from the built-in model, and their relative differences. Speed: MBDyn's
wall seconds per evaluation (template filled, c81 written, MBDyn run for the study's 40
revolutions at 72 steps per revolution, loads extracted; no interpreter start-up) against the
built-in model's evaluations per second on a batch of 1000 points, in the same run.

Needs MBDyn ($MBDYN, PATH, or ~/.cache/mbdyn/bin/mbdyn). Prints JSON; ``--markdown`` prints
README's tables instead (``--from-json run.json`` renders a saved run). ``--elastic`` adds the
elastic GVPM comparison: the nominal point, hub moments under 1 deg of lateral and longitudinal
cyclic (and the azimuth of the moment change), thrust sensitivity to K_p, ground-effect ratios.
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np
from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)

from rotoruq.mbdyn import CaseSettings, find_mbdyn, rigid_equivalent, run_case
from rotoruq.rotor.model import RotorModel
from rotoruq.rotor.presets import get_preset

CASES = {
    "gvpm": {"collective_deg": (3.0, 5.4, 8.0), "height_over_radius": (1.0, 2.0, 4.0, math.inf)},
    "bo105": {"collective_deg": (4.0, 6.0, 8.0), "height_over_radius": (1.0, math.inf)},
}


def locate_mbdyn() -> Path:
    return find_mbdyn(build_prefix=True)


def parity(mbdyn: Path, settings: CaseSettings) -> tuple[dict, list[float]]:
    out, walls = {}, []
    with tempfile.TemporaryDirectory() as tmp:
        for name, grid in CASES.items():
            preset = get_preset(name)
            builtin = RotorModel(rigid_equivalent(preset),
                                 names_in=["collective_deg", "height_over_radius"],
                                 names_out=["thrust", "torque"])
            rows = []
            for col in grid["collective_deg"]:
                for h in grid["height_over_radius"]:
                    t0 = time.perf_counter()
                    m = run_case(Path(tmp) / f"{name}_{col}_{h}", preset,
                                 {"collective_deg": col, "height_over_radius": h},
                                 settings=settings, mbdyn=mbdyn)
                    walls.append(time.perf_counter() - t0)
                    b = builtin([[col, h]])[0]
                    rows.append({
                        "collective_deg": col, "height_over_radius": "inf" if math.isinf(h)
                        else h,
                        "mbdyn_thrust": m.thrust, "builtin_thrust": float(b[0]),
                        "thrust_diff_pct": 100 * (b[0] / m.thrust - 1),
                        "mbdyn_torque": m.torque, "builtin_torque": float(b[1]),
                        "torque_diff_pct": 100 * (b[1] / m.torque - 1),
                    })
            out[name] = rows
    return out, walls


# Elastic GVPM (template ``elastic``) against the built-in ``gvpm`` preset: the nominal point,
# the cyclic response, the K_p sensitivity and the ground-effect ratios.
ELASTIC_BASE = {"collective_deg": 5.0, "lateral_deg": 0.0, "longitudinal_deg": 0.0,
                "k_pitch_link": 15.0, "height_over_radius": 4.0}
ELASTIC_CASES = {
    "nominal": {},
    "lateral_+1": {"lateral_deg": 1.0},
    "longitudinal_+1": {"longitudinal_deg": 1.0},
    "kp_10": {"k_pitch_link": 10.0},
    "kp_20": {"k_pitch_link": 20.0},
    "h_2": {"height_over_radius": 2.0},
    "h_1": {"height_over_radius": 1.0},
}


def elastic(mbdyn: Path, settings: CaseSettings) -> dict:
    """MBDyn's elastic GVPM and the built-in gvpm preset at the same inputs, with the derived
    comparisons: hub-moment response to 1 deg of cyclic (magnitude and the azimuth of the
    moment vector relative to the command: the flap phase lag seen at the hub), thrust
    sensitivity to K_p, and thrust/torque ratios in ground effect."""
    names = list(ELASTIC_BASE)
    preset = get_preset("gvpm")
    builtin = RotorModel(preset, names_in=names, names_out=["thrust", "torque", "roll", "pitch"])
    rows, walls = {}, []
    with tempfile.TemporaryDirectory() as tmp:
        for case, change in ELASTIC_CASES.items():
            x = {**ELASTIC_BASE, **change}
            t0 = time.perf_counter()
            m = run_case(Path(tmp) / case, preset, x, template="elastic", settings=settings,
                         mbdyn=mbdyn)
            walls.append(time.perf_counter() - t0)
            b = builtin([[x[n] for n in names]])[0]
            rows[case] = {"mbdyn": {"thrust": m.thrust, "torque": m.torque, "roll": m.roll,
                                    "pitch": m.pitch},
                          "builtin": dict(zip(["thrust", "torque", "roll", "pitch"],
                                              map(float, b), strict=True))}

    def derived(src: str) -> dict:
        r = {c: v[src] for c, v in rows.items()}
        nom = r["nominal"]
        out = {}
        for case in ("lateral_+1", "longitudinal_+1"):
            d_roll = r[case]["roll"] - nom["roll"]
            d_pitch = r[case]["pitch"] - nom["pitch"]
            out[f"{case}_droll"] = d_roll
            out[f"{case}_dpitch"] = d_pitch
            out[f"{case}_moment_angle_deg"] = math.degrees(math.atan2(d_pitch, d_roll))
        out["dthrust_dkp_per_Npm"] = (r["kp_20"]["thrust"] - r["kp_10"]["thrust"]) / 10.0
        out["dthrust_dkp_pct_per_Npm"] = 100 * out["dthrust_dkp_per_Npm"] / nom["thrust"]
        for h in ("h_2", "h_1"):
            out[f"thrust_ratio_{h}_vs_4R"] = r[h]["thrust"] / nom["thrust"]
            out[f"torque_ratio_{h}_vs_4R"] = r[h]["torque"] / nom["torque"]
        return out

    return {"inputs": ELASTIC_BASE, "cases": rows, "mbdyn_derived": derived("mbdyn"),
            "builtin_derived": derived("builtin"),
            "mbdyn_s_per_eval": float(np.median(walls)),
            "revolutions": settings.revolutions, "steps_per_rev": settings.steps_per_rev}


def builtin_rate(n: int = 1000) -> float:
    model = RotorModel(rigid_equivalent(get_preset("gvpm")),
                       names_in=["collective_deg", "height_over_radius"], names_out=["thrust",
                                                                                  "torque"])
    rng = np.random.default_rng(0)
    x = np.column_stack([rng.uniform(3, 8, n), rng.uniform(1, 4, n)])
    model(x[:10])  # warm caches
    t0 = time.perf_counter()
    model(x)
    return n / (time.perf_counter() - t0)


def markdown(res: dict) -> str:
    lines = ["| rotor | collective [deg] | z/R | thrust MBDyn / built-in [N] | diff | "
             "torque MBDyn / built-in [N m] | diff |", "|---|---|---|---|---|---|---|"]
    for name in CASES:
        for r in res["parity"][name]:
            lines.append(
                f"| {name} | {r['collective_deg']:g} | {r['height_over_radius']} | "
                f"{r['mbdyn_thrust']:.4g} / {r['builtin_thrust']:.4g} | "
                f"{r['thrust_diff_pct']:+.3f} % | {r['mbdyn_torque']:.4g} / "
                f"{r['builtin_torque']:.4g} | {r['torque_diff_pct']:+.3f} % |")
    s = res["speed"]
    lines.append("")
    lines.append(f"Speed (same run): MBDyn {s['mbdyn_s_per_eval']:.3f} s per evaluation "
                 f"({s['revolutions']} revolutions, {s['steps_per_rev']} steps each); built-in "
                 f"{s['builtin_evals_per_s']:.0f} evaluations/s (batch of 1000): "
                 f"{s['speedup']:.0f} x faster.")
    if "elastic" in res:
        e = res["elastic"]
        lines += ["", "| elastic GVPM (5 deg, K_p 15, 4R) | MBDyn | built-in |", "|---|---|---|"]
        for case, v in e["cases"].items():
            m, b = v["mbdyn"], v["builtin"]
            lines.append(f"| {case}: thrust [N] / torque [N m] / roll / pitch [N m] | "
                         f"{m['thrust']:.2f} / {m['torque']:.3f} / {m['roll']:+.3f} / "
                         f"{m['pitch']:+.3f} | {b['thrust']:.2f} / {b['torque']:.3f} / "
                         f"{b['roll']:+.3f} / {b['pitch']:+.3f} |")
        md, bd = e["mbdyn_derived"], e["builtin_derived"]
        for k in md:
            lines.append(f"| {k} | {md[k]:+.4g} | {bd[k]:+.4g} |")
        lines.append(f"\nElastic MBDyn: {e['mbdyn_s_per_eval']:.1f} s per evaluation "
                     f"({e['revolutions']} revolutions, {e['steps_per_rev']} steps each).")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--revolutions", type=int, default=40)
    ap.add_argument("--markdown", action="store_true", help="print README's table")
    ap.add_argument("--elastic", action="store_true",
                    help="also compare the elastic GVPM (7 MBDyn runs of the elastic template)")
    ap.add_argument("--elastic-revolutions", type=int, default=12)
    ap.add_argument("--from-json", type=Path, default=None,
                    help="print the markdown of a saved JSON run instead of running")
    args = ap.parse_args()
    if args.from_json:
        print(markdown(json.loads(args.from_json.read_text())))
        return
    settings = CaseSettings(revolutions=args.revolutions)
    mbdyn = locate_mbdyn()
    par, walls = parity(mbdyn, settings)
    rate = builtin_rate()
    s_per_eval = float(np.median(walls))
    diffs = [abs(r[k]) for rows in par.values() for r in rows
             for k in ("thrust_diff_pct", "torque_diff_pct")]
    res = {
        "parity": par,
        "max_abs_diff_pct": float(max(diffs)),
        "within_1_pct": bool(max(diffs) < 1.0),
        "speed": {"mbdyn_s_per_eval": s_per_eval, "revolutions": settings.revolutions,
                  "steps_per_rev": settings.steps_per_rev, "builtin_evals_per_s": rate,
                  "speedup": rate * s_per_eval},
    }
    if args.elastic:
        res["elastic"] = elastic(mbdyn, CaseSettings(revolutions=args.elastic_revolutions))
    res["provenance"] = provenance()
    print(markdown(res) if args.markdown else json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
