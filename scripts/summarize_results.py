"""Print the docs' text for a saved result whose benchmark has no ``--summary`` of its own.

    python scripts/summarize_results.py least_squares benchmarks/results/least_squares.json

Kinds:
- ``mbdyn_rigid`` / ``mbdyn_elastic``: the two parts of ``benchmarks/mbdyn_parity.py
  --from-json`` (its own formatting), for pages that discuss them apart.
- ``fidelity_mbdyn``, ``fidelity_properties``, ``fidelity_control_chain``, ``fidelity_cyclic``,
  ``fidelity_table_4_9``, ``fidelity_bo105``, ``fidelity_ground_effect``: the rotor-model tables of
  ``scripts/rotor_fidelity.py --out scripts/results/rotor_fidelity.json`` (the checks against
  MBDyn's published runs, the GVPM loads with each chosen property varied, the pitch link's
  stiffness and which feathering terms carry K_p's effect, the cyclic response
  of thesis table 4.6, the indices of table 4.9, the Bo105 loads of table 3.11 per twist
  reading, the ground-effect ratios of tables 4.18 and 4.19).
- ``least_squares``: evaluations and final sum of squares of every solver in the same run,
  like for like (forward-difference Jacobians, every evaluated point counted): ours with its
  defaults and with Dakota's, scipy ``lm`` and ``trf``; then the comparison with real Dakota's
  nl2sol when that run had Dakota.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from pathlib import Path

SOLVERS = {"nl2sol": "ours", "nl2sol_dakota_defaults": "ours (Dakota's defaults)",
           "scipy_lm": "scipy lm", "scipy_trf": "scipy trf"}


def least_squares(res: dict) -> str:
    """Markdown table of evaluations (sum of squares) per problem and solver."""
    head = "| problem (published minimum) | " + " | ".join(SOLVERS.values()) + " |"
    lines = [head, "|---" * (len(SOLVERS) + 1) + "|"]
    for name, p in res["problems"].items():
        kind = ", large residual" if p["large_residual"] else ""
        cells = [f"{p[k]['evaluations']} ({p[k]['sumsq']:.6g})" if k in p else "-"
                 for k in SOLVERS]
        lines.append(f"| {name} ({p['published_sumsq']:g}{kind}) | " + " | ".join(cells) + " |")
    lines += ["", "Evaluations (final sum of squares); every solver with forward-difference "
              "Jacobians, every evaluated point counted by one wrapper."]
    dk = res.get("dakota", {})
    if dk.get("dakota_available"):
        parts = []
        for name, case in dk.items():
            if not isinstance(case, dict):
                continue
            ours, theirs = case["rotoruq"], case["dakota"]
            parts.append(f"{name} {ours['iterations']} vs {theirs['iterations']} iterations "
                         f"(cost excess {ours['cost_excess']:.2g} vs {theirs['cost_excess']:.2g})")
        lines += ["", f"Against Dakota's nl2sol (convergence_tolerance "
                  f"{dk['convergence_tolerance']:g}, ours vs Dakota): " + "; ".join(parts) + "."]
    return "\n".join(lines)


def fidelity_mbdyn(res: dict) -> str:
    """The model configured like the reference multibody runs, against MBDyn's numbers."""
    checks = res["mbdyn_checks"]
    if "skipped" in checks:
        raise SystemExit(f"the saved run skipped the MBDyn checks: {checks['skipped']}")
    g, b = checks["gvpm_rigid_5.4deg"], checks["bo105_6deg_whole_span_-6.2"]
    return "\n".join([
        "| case | rotoruq | MBDyn |", "|---|---|---|",
        f"| GVPM, rigid link, 5.4 deg, thrust / torque | {g['rotoruq'][0]:.4g} N / "
        f"{g['rotoruq'][1]:.4g} N m | {g['mbdyn'][0]:g} N / {g['mbdyn'][1]:g} N m |",
        f"| Bo105, 6 deg, -2 deg long., -6.2 deg whole-span twist | {b['rotoruq'][0]:.4g} N / "
        f"{b['rotoruq'][1]:.4g} N m | {b['mbdyn'][0]:g} N / {b['mbdyn'][1]:g} N m |"])


def fidelity_properties(res: dict) -> str:
    """GVPM loads at the section 4.3 commands (K_p = 15) with each chosen property varied."""
    c = res["chosen_properties"]
    lines = ["| GVPM variant | thrust [N] | roll [N m] | pitch [N m] | power [W] | thrust change |",
             "|---|---|---|---|---|---|"]
    t, r, q, w = c["preset_T_roll_pitch_P"]
    lines.append(f"| preset | {t:.4g} | {r:.3g} | {q:.3g} | {w:.4g} | - |")
    for name, v in c.items():
        if not isinstance(v, dict):
            continue
        t, r, q, w = v["T_roll_pitch_P"]
        failed = f" ({v['failures']} failed)" if v["failures"] else ""
        lines.append(f"| {name} | {t:.4g} | {r:.3g} | {q:.3g} | {w:.4g} | "
                     f"{v['thrust_change_percent']:+.2f} %{failed} |")
    return "\n".join(lines)


def fidelity_control_chain(res: dict) -> str:
    """The GVPM pitch link's stiffness and the thrust over K_p with each feathering term."""
    c = res["control_chain"]
    t10, t15, t20, rigid = c["posterior_commands_thrust_N_at_kp_10_15_20_rigid"]
    lines = [
        f"Pitch link l0 = {1e3 * c['pitch_link_length_m']:g} mm, horn "
        f"{1e3 * c['pitch_horn_arm_m']:g} mm: k_theta = {c['k_theta_at_kp15_Nm_per_rad']:.3g} "
        f"N m/rad at K_p = 15 against the propeller moment I_p Omega^2 = "
        f"{c['propeller_moment_Ip_omega2_Nm_per_rad']:.3g} N m/rad. Thrust at the posterior "
        f"commands for K_p = 10, 15, 20: {t10:.4g}, {t15:.4g}, {t20:.4g} N "
        f"({c['thrust_change_kp_10_to_20_percent']:+.1f} %; rigid link {rigid:.4g} N). The "
        f"measured 25.68 N needs a collective of {c['collective_for_measured_thrust_deg']:.2f} "
        "deg with the other posterior means.", "",
        "| feathering terms | thrust at K_p = 10, 15, 20 [N] | change 10 -> 20 |", "|---|---|---|"]
    for name, v in c["kp_effect_by_term"].items():
        thrust = ", ".join("failed" if t != t else f"{t:.4g}"  # NaN: the solve failed
                           for t in v["thrust_N_at_kp_10_15_20"])
        change = v["change_10_to_20_percent"]
        lines.append(f"| {name} | {thrust} | "
                     + ("-" if change != change else f"{change:+.1f} %") + " |")
    return "\n".join(lines)


def fidelity_cyclic(res: dict) -> str:
    """Main Sobol' indices of the cyclic commands on roll and pitch, and the flap lag."""
    c = res["cyclic_response"]
    resp = c["responses"]
    r, q = resp.index("roll"), resp.index("pitch")
    cases = ["preset", "no_ac_offset", "no_ac_offset_harmonic_inflow"]
    thesis = c["thesis_table_4_6_main"]
    lines = ["| | thesis | rotoruq preset | no a.c. offset | no a.c. offset, Pitt-Peters inflow |",
             "|---|---|---|---|---|"]
    for cmd, label in (("lateral_deg", "lateral"), ("longitudinal_deg", "longitudinal")):
        cells = [f"{thesis[cmd][r]:.3g}, {thesis[cmd][q]:.3g}"]
        cells += [f"{c[k]['main'][cmd][r]:.3f}, {c[k]['main'][cmd][q]:.3f}" for k in cases]
        lines.append(f"| {label} -> roll, pitch | " + " | ".join(cells) + " |")
    lags = [f"{c[k]['flap_lag_deg']:.0f} deg" for k in cases]
    lines.append("| flap lag behind the cyclic | 64-74 deg (implied) | " + " | ".join(lags) + " |")
    n = res.get("n_samples")
    lines += ["", f"Sobol' base samples: {n}; first flap frequency "
              f"{c['first_flap_frequency_per_rev']:.2f}/rev, Lock number {c['lock_number']:.1f}."]
    return "\n".join(lines)


def fidelity_table_4_9(res: dict) -> str:
    """Main Sobol' indices of the aerodynamic and structural inputs against thesis table 4.9."""
    t = res["table_4_9"]
    lines = ["| input | " + " | ".join(f"{y} (thesis / ours)" for y in t["responses"]) + " |",
             "|---" * (len(t["responses"]) + 1) + "|"]
    for name, ours in t["main"].items():
        cells = [f"{th:.3g} / {o:.3g}" for th, o in zip(t["thesis_main"][name], ours, strict=True)]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def fidelity_bo105(res: dict) -> str:
    """Bo105 thrust and torque at 6 deg collective, -2 deg longitudinal, per twist and fits."""
    b = res["bo105_geometry"]
    thesis = b["thesis_table_3_11_thrust_torque"]
    lines = ["| twist | lift fits | thrust [N] | torque [N m] |", "|---|---|---|---|"]
    for twist, label in (("-6.2", "-6.2 deg over the whole span"), ("-8.0", "linear -8 deg")):
        for fits, flabel in (("thesis_fits", "thesis (table 3.2)"), ("bundled_fits", "bundled")):
            t, q = b[f"twist_{twist}_{fits}"]
            lines.append(f"| {label} | {flabel} | {t:.0f} | {q:.0f} |")
    lines.append(f"| thesis table 3.11 | | {thesis[0]:.0f} | {thesis[1]:.0f} |")
    return "\n".join(lines)


def fidelity_ground_effect(res: dict) -> str:
    """C_T(h)/C_T(4R) and C_Q(h)/C_Q(4R) per ground-effect model against the GVPM test."""
    g = res["ground_effect"]
    heights = g["heights"]
    models = [k for k in g if isinstance(g[k], dict)]
    head = ", ".join(f"{h:g}R" for h in heights[1:])
    lines = [f"| model | C_T ratio at {head} | C_Q ratio at {head} |", "|---|---|---|"]

    def row(name: str, ct: list, cq: list) -> str:
        return (f"| {name} | " + ", ".join(f"{v:.3f}" for v in ct[1:]) + " | "
                + ", ".join(f"{v:.3f}" for v in cq[1:]) + " |")

    for m in models:
        lines.append(row(m, g[m]["ct_ratio"], g[m]["cq_ratio"]))
    lines.append(row("the test", g["test_ct_ratio"], g["test_cq_ratio"]))
    return "\n".join(lines)


def _parity_markdown(res: dict) -> str:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from mbdyn_parity import markdown

    return markdown(res)


def mbdyn_rigid(res: dict) -> str:
    """The rigid-blade parity table and the speed line of a saved MBDyn parity run."""
    return _parity_markdown({k: v for k, v in res.items() if k != "elastic"})


def mbdyn_elastic(res: dict) -> str:
    """The elastic GVPM table of a saved MBDyn parity run (``--elastic``)."""
    if "elastic" not in res:
        raise SystemExit("this MBDyn parity run has no elastic part (run it with --elastic)")
    full, rigid = _parity_markdown(res), mbdyn_rigid(res)
    if not full.startswith(rigid):
        raise SystemExit("mbdyn_parity.markdown no longer prints the rigid part first")
    return full[len(rigid):].strip("\n")


KINDS: dict[str, Callable[[dict], str]] = {"least_squares": least_squares,
                                           "fidelity_mbdyn": fidelity_mbdyn,
                                           "fidelity_properties": fidelity_properties,
                                           "fidelity_control_chain": fidelity_control_chain,
                                           "fidelity_cyclic": fidelity_cyclic,
                                           "fidelity_table_4_9": fidelity_table_4_9,
                                           "fidelity_bo105": fidelity_bo105,
                                           "fidelity_ground_effect": fidelity_ground_effect,
                                           "mbdyn_rigid": mbdyn_rigid,
                                           "mbdyn_elastic": mbdyn_elastic}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("kind", choices=sorted(KINDS))
    ap.add_argument("json", help="the saved result")
    args = ap.parse_args(argv)
    with open(args.json, encoding="utf-8") as fh:
        print(KINDS[args.kind](json.load(fh)))


if __name__ == "__main__":
    main()
