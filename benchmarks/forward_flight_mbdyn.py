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

The elastic rows (``elastic``): the built-in ``gvpm`` preset itself (elastic blades, the
pitch link K_p = ``k_pitch_link``) trimmed the same way at mu = 0 (hover), 0.1, 0.2, 0.3 and its
controls flown by MBDyn's ``elastic`` template (its swashplate, pitch link and beams, with its
structural nodes written out); compared: thrust, power and the tip-path-plane flapping
(beta_0, beta_1c, beta_1s: each blade's tip angle above the disk plane seen from the
feathering hinge, fitted to 1, cos psi, sin psi over the averaged revolutions; the cyclic ones
in % of the built-in coning, their natural scale). Where a difference is beyond ``LIMIT_PCT``
its cause is computed from the run: MBDyn's blade pitch, measured at the feathering hinge
(the root node's chord axis) and fitted the same way, against the commanded; the built-in
rotor with a stiff link (``STIFF_K_PITCH_LINK``) flown at that measured pitch; and MBDyn with
that stiff link flying the commanded controls against the built-in with it. The coning of a
bending blade depends on where it is measured: the inertia-weighted mean angle of the blade's
nodes is given beside the tip's. The cyclic flapping of the tip-path plane follows the tip's
coning: with the stiff link in both, the built-in's hinge spring (EI) is matched to MBDyn's
tip coning and the cyclic flapping compared again (``coning_matched``).

Needs MBDyn ($MBDYN, PATH, or ~/.cache/mbdyn/bin/mbdyn). Prints JSON and writes
``benchmarks/results/forward_flight_mbdyn.json``; ``--summary [JSON]`` prints the docs' table
from a saved run; ``--mu 0.2`` runs one advance ratio (the test's check); ``--template
elastic --elastic-revolutions 6 --keep DIR`` the elastic rows only, short, keeping MBDyn's
files.
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
ELASTIC_ADVANCE_RATIOS = (0.0, 0.1, 0.2, 0.3)
ELASTIC_LOADS = ("thrust", "power", "beta_0_deg", "beta_1c_deg", "beta_1s_deg")
FLAPS = ("beta_0_deg", "beta_1c_deg", "beta_1s_deg")
STIFF_K_PITCH_LINK = 1.0e4   # N: 1000x the gvpm link, its pitch then within 1e-3 deg
_OUTPUT_LINE = "    default output: none, induced velocity elements;\n"


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


def elastic_template(workdir: Path) -> Path:
    """The bundled elastic template with its structural nodes written out (positions and
    orientation matrices in ``rotor.mov``), saved in ``workdir``; the model is unchanged."""
    from rotoruq.mbdyn.case import template_text

    text, _ = template_text("elastic")
    if text.count(_OUTPUT_LINE) != 1:
        raise SystemExit("the elastic template's output line changed: update _OUTPUT_LINE")
    text = text.replace(_OUTPUT_LINE, "    default output: none, induced velocity elements, "
                        "structural nodes;\n    default orientation: orientation matrix;\n")
    workdir.mkdir(parents=True, exist_ok=True)
    path = workdir / "elastic_nodes.mbd"
    path.write_text(text)
    return path


def blade_harmonics(mov: Path, steps: int, hinge_radius: float) -> dict[str, list[float]]:
    """Mean, cos psi and sin psi harmonics [deg] over the last ``steps`` rows of each node in
    MBDyn's ``.mov`` file (orientation matrices): ``pitch`` of the blade at the feathering
    hinge (root node k000's chord axis, asin of its component along the shaft), ``pitch_tip``
    (the tip node's), ``flap_tip`` (the tip's angle above the disk plane from the hinge) and
    ``flap_weighted`` (the nodes' inertia-weighted mean angle, the tip's spread by the blade's
    bending); psi each blade's azimuth from its root node's position, the four blades
    pooled. ``pitch_higher``: the pitch's 2 and 3 per revolution harmonics (cos 2 psi,
    sin 2 psi, cos 3 psi, sin 3 psi) [deg], which the built-in rotor cannot be flown at."""
    import numpy as np

    d = np.loadtxt(mov)
    labels = np.unique(d[:, 0]).astype(int)
    n_steps = len(d) // len(labels)
    d = d[:n_steps * len(labels)].reshape(n_steps, len(labels), -1)[-steps:]
    col = {lab: i for i, lab in enumerate(labels)}
    weights = np.array([0.5, 1, 1, 1, 1, 1, 0.5])   # the template's lumped node masses
    basis, series = [], {"pitch": [], "pitch_tip": [], "flap_tip": [], "flap_weighted": []}
    for blade in range(1, 5):
        nodes = d[:, [col[1000 * blade + k] for k in range(7)]]   # (steps, 7, 19)
        x, y, z = nodes[..., 1], nodes[..., 2], nodes[..., 3]
        psi = np.arctan2(y[:, 0], x[:, 0])
        basis.append(np.c_[np.ones_like(psi), np.cos(psi), np.sin(psi)])
        r = np.hypot(x, y) - hinge_radius
        series["pitch"].append(np.degrees(np.arcsin(nodes[:, 0, 11])))   # R_32
        series["pitch_tip"].append(np.degrees(np.arcsin(nodes[:, 6, 11])))
        series["flap_tip"].append(np.degrees(np.arctan2(z[:, 6], r[:, 6])))
        series["flap_weighted"].append(np.degrees(np.arctan(
            (weights * r * z).sum(1) / (weights * r * r).sum(1))))
    a = np.vstack(basis)
    out = {k: np.linalg.lstsq(a, np.concatenate(v), rcond=None)[0].tolist()
           for k, v in series.items()}
    psi = np.arctan2(a[:, 2], a[:, 1])
    higher = np.c_[a, np.cos(2 * psi), np.sin(2 * psi), np.cos(3 * psi), np.sin(3 * psi)]
    out["pitch_higher"] = np.linalg.lstsq(higher, np.concatenate(series["pitch"]),
                                          rcond=None)[0][3:].tolist()
    return out


def builtin_elastic(controls: dict[str, float], mu: float, k_pitch_link: float,
                    ei_flap: float | None = None) -> dict[str, float]:
    """The built-in gvpm rotor (Glauert inflow) flying ``controls`` [deg] with the pitch link
    ``k_pitch_link`` [N] (and the flap stiffness ``ei_flap`` [N m^2], default the preset's)."""
    names = [*CONTROLS, "advance_ratio", "shaft_angle_deg", "k_pitch_link", "ei_flap"]
    model = ForwardRotorModel(PRESET, names_in=names, names_out=list(ELASTIC_LOADS),
                              inflow_model="glauert")
    ei = get_preset(PRESET).ei_flap if ei_flap is None else ei_flap
    y = model([[*(controls[c] for c in CONTROLS), mu, SHAFT_DEG, k_pitch_link, ei]])[0]
    return dict(zip(ELASTIC_LOADS, map(float, y), strict=True))


def coning_matched_hinge(controls: dict[str, float], mu: float, k_pitch_link: float,
                         coning_deg: float) -> tuple[float, dict[str, float]]:
    """The flap stiffness EI [N m^2] whose equivalent hinge (the built-in's spring, from the
    cantilever's first mode) cones to ``coning_deg`` flying ``controls`` [deg] with the link
    ``k_pitch_link`` [N], and the built-in rotor's loads with it: MBDyn's bending blade seen
    from its tip as a hinged blade (the built-in's coning falls with EI)."""
    from scipy.optimize import brentq

    ei0 = get_preset(PRESET).ei_flap

    def gap(ei: float) -> float:
        return builtin_elastic(controls, mu, k_pitch_link, ei)["beta_0_deg"] - coning_deg

    lo, hi = 0.25 * ei0, 4.0 * ei0
    if gap(lo) * gap(hi) > 0:
        raise SystemExit(f"no flap stiffness in [{lo:g}, {hi:g}] N m^2 cones the built-in "
                         f"rotor to {coning_deg:.4f} deg at mu = {mu:g}")
    ei = float(brentq(gap, lo, hi, xtol=1e-6 * ei0))
    return ei, builtin_elastic(controls, mu, k_pitch_link, ei)


def elastic_diffs(builtin: dict[str, float], mbdyn: dict[str, float]) -> dict[str, float]:
    """Built-in minus MBDyn [%]: thrust, power and coning of MBDyn's value, the cyclic
    flapping of the built-in coning."""
    out = {k: 100 * (builtin[k] - mbdyn[k]) / abs(mbdyn[k])
           for k in ("thrust", "power", "beta_0_deg")}
    out.update({k: 100 * (builtin[k] - mbdyn[k]) / abs(builtin["beta_0_deg"])
                for k in ("beta_1c_deg", "beta_1s_deg")})
    return out


def _mbdyn_elastic(workdir: Path, template: Path, inputs: dict, settings: CaseSettings,
                   mbdyn: Path) -> tuple[dict[str, float], dict[str, list[float]]]:
    preset = get_preset(PRESET)
    m = run_case(workdir, preset, inputs, template=template, settings=settings, mbdyn=mbdyn)
    h = blade_harmonics(workdir / "rotor.mov", settings.average * settings.steps_per_rev,
                        preset.root_cutout)
    loads = {"thrust": m.response("thrust"), "power": m.response("power")}
    loads.update(zip(FLAPS, h["flap_tip"], strict=True))
    return loads, h


def _cause(name: str, r: dict) -> str:
    """The sentence naming a difference's computed cause, from the row's numbers."""
    cmd, got = r["controls_deg"], r["mbdyn_pitch_deg"]
    at, stiff = r["diff_pct_at_mbdyn_pitch"], r["stiff_link"]["diff_pct"]
    label = {"thrust": "thrust", "power": "power", "beta_0_deg": "coning",
             "beta_1c_deg": "longitudinal flapping", "beta_1s_deg": "lateral flapping"}[name]
    text = (f"{label} {r['diff_pct'][name]:+.1f} %: MBDyn's blade flies "
            f"{got['collective_deg']:.2f}, {got['lateral_deg']:+.2f}, "
            f"{got['longitudinal_deg']:+.2f} deg at its feathering hinge against "
            f"{cmd['collective_deg']:.2f}, {cmd['lateral_deg']:+.2f}, "
            f"{cmd['longitudinal_deg']:+.2f} commanded (the pitch link's deflection: "
            f"{r['pitch_link_deflection_deg']:+.2f} deg of collective; root to tip the blade "
            f"twists {r['mbdyn_torsion_deg']:+.3f} deg); the built-in rotor flown at "
            f"that pitch: {at[name]:+.1f} %; with a stiff link "
            f"(K_p {STIFF_K_PITCH_LINK:g} N) in both: {stiff[name]:+.1f} %")
    if name == "beta_0_deg":
        w, tip = r["mbdyn_coning_weighted_deg"], r["mbdyn"]["beta_0_deg"]
        b = r["builtin_at_mbdyn_pitch"]["beta_0_deg"]
        text += (f"; the bending blade's coning is {tip:.3f} deg at the tip, {w:.3f} deg "
                 f"inertia-weighted, the built-in's equivalent hinge {b:.3f} deg at MBDyn's "
                 f"pitch ({'between the two' if r['coning_bracketed'] else 'outside both'})")
    if name in ("beta_1c_deg", "beta_1s_deg"):
        m = r["stiff_link"]["coning_matched"]
        text += (f"; MBDyn's blade also flies {r['mbdyn_pitch_2p_deg']:.3f} deg of 2/rev and "
                 f"{r['mbdyn_pitch_3p_deg']:.3f} deg of 3/rev pitch at its hinge, which the "
                 "built-in flown at MBDyn's pitch lacks")
        text += (f"; with the stiff link, the built-in's hinge spring matched to MBDyn's tip "
                 f"coning ({r['stiff_link']['mbdyn']['beta_0_deg']:.3f} deg: EI "
                 f"{m['ei_flap']:.2f} N m^2 against the preset's {m['preset_ei_flap']:g}): "
                 f"{m['diff_pct'][name]:+.1f} %")
    return text + "."


def compare_elastic(mbdyn: Path, settings: CaseSettings, mu: float, workdir: Path) -> dict:
    """One elastic row: the built-in gvpm trim flown by MBDyn's elastic template, the built-in
    rotor at the trim, and the computed causes of the differences beyond ``LIMIT_PCT``."""
    preset = get_preset(PRESET)
    controls = trimmed_controls(mu)
    template = elastic_template(workdir)
    base = {"advance_ratio": mu, "shaft_angle_deg": SHAFT_DEG, "height_over_radius": math.inf}
    c0 = _children_cpu()
    md, h = _mbdyn_elastic(workdir / f"elastic_mu_{mu:g}", template, {**controls, **base},
                           settings, mbdyn)
    stiff_md, stiff_h = _mbdyn_elastic(workdir / f"elastic_stiff_mu_{mu:g}", template,
                                       {**controls, **base,
                                        "k_pitch_link": STIFF_K_PITCH_LINK}, settings, mbdyn)
    cpu = _children_cpu() - c0
    b = builtin_elastic(controls, mu, preset.k_pitch_link)
    pitch = dict(zip(CONTROLS, h["pitch"], strict=True))
    b_at = builtin_elastic(pitch, mu, STIFF_K_PITCH_LINK)
    b_stiff = builtin_elastic(controls, mu, STIFF_K_PITCH_LINK)
    # the stiff link's pitch is the commanded one: what is left of the flapping is the blade
    ei_m, b_m = coning_matched_hinge(controls, mu, STIFF_K_PITCH_LINK, stiff_md["beta_0_deg"])
    w = h["flap_weighted"][0]
    row = {"advance_ratio": mu, "controls_deg": controls, "mbdyn": md, "builtin": b,
           "diff_pct": elastic_diffs(b, md),
           "mbdyn_pitch_deg": pitch,
           "mbdyn_tip_pitch_deg": dict(zip(CONTROLS, h["pitch_tip"], strict=True)),
           "pitch_link_deflection_deg": pitch["collective_deg"] - controls["collective_deg"],
           "mbdyn_torsion_deg": h["pitch_tip"][0] - h["pitch"][0],
           "mbdyn_pitch_2p_deg": math.hypot(*h["pitch_higher"][:2]),
           "mbdyn_pitch_3p_deg": math.hypot(*h["pitch_higher"][2:]),
           "mbdyn_coning_weighted_deg": w,
           "builtin_at_mbdyn_pitch": b_at,
           "diff_pct_at_mbdyn_pitch": elastic_diffs(b_at, md),
           "stiff_link": {"k_pitch_link_N": STIFF_K_PITCH_LINK, "mbdyn": stiff_md,
                          "mbdyn_pitch_deg": dict(zip(CONTROLS, stiff_h["pitch"],
                                                      strict=True)),
                          "builtin": b_stiff, "diff_pct": elastic_diffs(b_stiff, stiff_md),
                          "coning_matched": {"ei_flap": ei_m, "preset_ei_flap": preset.ei_flap,
                                             "builtin": b_m,
                                             "diff_pct": elastic_diffs(b_m, stiff_md)}},
           "mbdyn_cpu_s": cpu}
    row["coning_bracketed"] = bool(min(w, md["beta_0_deg"]) <= b_at["beta_0_deg"]
                                   <= max(w, md["beta_0_deg"]))
    beyond = [k for k, v in row["diff_pct"].items() if abs(v) > LIMIT_PCT]
    row["beyond_limit"] = beyond
    row["causes"] = {k: _cause(k, row) for k in beyond}
    # a cause is computed when the built-in flown at MBDyn's measured pitch, or both with a
    # stiff link, brings the difference within the limit (coning: or the built-in lies
    # between the bending blade's two coning measures; cyclic flapping: or, with the stiff
    # link, the built-in's hinge spring matched to MBDyn's tip coning)
    matched = row["stiff_link"]["coning_matched"]["diff_pct"]
    row["explained"] = {k: bool(abs(row["diff_pct_at_mbdyn_pitch"][k]) <= LIMIT_PCT
                                or abs(row["stiff_link"]["diff_pct"][k]) <= LIMIT_PCT
                                or (k == "beta_0_deg" and row["coning_bracketed"])
                                or (k in ("beta_1c_deg", "beta_1s_deg")
                                    and abs(matched[k]) <= LIMIT_PCT))
                        for k in beyond}
    if not all(row["explained"].values()):
        # is what the pitch leaves MBDyn's time step? the stiff-link case at twice the steps
        fine = CaseSettings(settings.revolutions, 2 * settings.steps_per_rev, settings.average,
                            settings.tolerance, settings.timeout)
        c0 = _children_cpu()
        fine_md, _ = _mbdyn_elastic(workdir / f"elastic_stiff_fine_mu_{mu:g}", template,
                                    {**controls, **base, "k_pitch_link": STIFF_K_PITCH_LINK},
                                    fine, mbdyn)
        row["mbdyn_cpu_s"] += _children_cpu() - c0
        row["stiff_link"]["refined"] = {"steps_per_rev": fine.steps_per_rev, "mbdyn": fine_md,
                                        "diff_pct": elastic_diffs(b_stiff, fine_md)}
    return row


def run_elastic(mus, settings: CaseSettings, workdir: Path) -> dict:
    mbdyn = find_mbdyn(build_prefix=True)
    rows = [compare_elastic(mbdyn, settings, mu, workdir) for mu in mus]
    return {"template": "elastic", "preset": PRESET,
            "k_pitch_link_N": get_preset(PRESET).k_pitch_link,
            "stiff_k_pitch_link_N": STIFF_K_PITCH_LINK, "inflow": "uniform (Glauert) in both",
            "revolutions": settings.revolutions, "steps_per_rev": settings.steps_per_rev,
            "average": settings.average, "periodicity_tolerance": settings.tolerance,
            "rows": rows,
            "all_within_limit": bool(all(not r["beyond_limit"] for r in rows)),
            "all_explained": bool(all(all(r["explained"].values()) for r in rows)),
            "mbdyn_cpu_s": sum(r["mbdyn_cpu_s"] for r in rows)}


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
    parts = []
    if "rows" in res:
        parts.append(_rigid_summary(res))
    if "elastic" in res:
        parts.append(_elastic_summary(res["elastic"], res.get("limit_pct", LIMIT_PCT)))
    return "\n\n".join(parts)


def _elastic_summary(e: dict, lim: float) -> str:
    """The docs' table of the elastic rows and the sentence of their computed causes."""
    lines = [f"Elastic rows: the built-in {e['preset']} preset (elastic blades, pitch link K_p "
             f"{e['k_pitch_link_N']:g} N) trimmed the same way, its controls flown by MBDyn's "
             f"elastic template ({e['revolutions']} revolutions, {e['steps_per_rev']} steps "
             "each). Flapping: the tip-path plane (each tip's angle from the feathering hinge; "
             "beta_1c and beta_1s differences in % of the built-in coning). Differences: "
             "built-in minus MBDyn; in brackets the built-in flown at MBDyn's measured blade "
             f"pitch, then both with a stiff pitch link (K_p {e['stiff_k_pitch_link_N']:g} N).",
             "", "| mu | commanded [deg] | MBDyn's pitch [deg] | thrust MBDyn / built-in [N] "
             "| diff | power [W] | diff | beta_0 [deg] | diff | beta_1c, beta_1s MBDyn [deg] "
             "| diff 1c | diff 1s |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in e["rows"]:
        c, p, m, b = r["controls_deg"], r["mbdyn_pitch_deg"], r["mbdyn"], r["builtin"]
        d, da, ds = r["diff_pct"], r["diff_pct_at_mbdyn_pitch"], r["stiff_link"]["diff_pct"]

        def cell(k: str, d: dict = d, da: dict = da, ds: dict = ds) -> str:
            return f"{d[k]:+.1f} % ({da[k]:+.1f} %; {ds[k]:+.1f} %)"

        lines.append(
            f"| {r['advance_ratio']:g} | {c['collective_deg']:.2f}, {c['lateral_deg']:+.2f}, "
            f"{c['longitudinal_deg']:+.2f} | {p['collective_deg']:.2f}, "
            f"{p['lateral_deg']:+.2f}, {p['longitudinal_deg']:+.2f} | "
            f"{m['thrust']:.2f} / {b['thrust']:.2f} | {cell('thrust')} | "
            f"{m['power']:.1f} / {b['power']:.1f} | {cell('power')} | "
            f"{m['beta_0_deg']:.3f} / {b['beta_0_deg']:.3f} | {cell('beta_0_deg')} | "
            f"{m['beta_1c_deg']:+.3f}, {m['beta_1s_deg']:+.3f} | {cell('beta_1c_deg')} | "
            f"{cell('beta_1s_deg')} |")
    rows = e["rows"]
    worst = max(rows, key=lambda r: abs(r["diff_pct"]["thrust"]))
    defl = [r["pitch_link_deflection_deg"] for r in rows]
    at = max(abs(r["diff_pct_at_mbdyn_pitch"][k]) for r in rows
             for k in ("thrust", "power"))
    st = max(abs(r["stiff_link"]["diff_pct"][k]) for r in rows for k in ("thrust", "power"))
    twist = max(abs(r["mbdyn_torsion_deg"]) for r in rows)
    n_beyond = sum(len(r["beyond_limit"]) for r in rows)
    n_expl = sum(sum(r["explained"].values()) for r in rows)
    lines += ["", f"{n_beyond} differences beyond {lim:g} % (largest: thrust "
              f"{worst['diff_pct']['thrust']:+.1f} % at mu = {worst['advance_ratio']:g}); "
              f"{n_expl} of them with their cause computed. MBDyn's blades fly a collective "
              f"{min(defl):+.2f} to {max(defl):+.2f} deg from the commanded at the feathering "
              f"hinge (the pitch link's deflection; root to tip the blades twist at most "
              f"{twist:.3f} deg) and a different cyclic. Flown at MBDyn's measured pitch the "
              f"built-in rotor's thrust and power are within {at:.1f} % of MBDyn's; with a "
              f"stiff link in both, within {st:.1f} %."]
    cones = [r for r in rows if "beta_0_deg" in r["beyond_limit"]]
    if cones:
        br = sum(r["coning_bracketed"] for r in cones)
        lines[-1] += (f" The coning stays apart where the pitch agrees: a bending blade's "
                      f"coning depends on where it is measured (tip "
                      f"{cones[0]['mbdyn']['beta_0_deg']:.3f} deg, inertia-weighted "
                      f"{cones[0]['mbdyn_coning_weighted_deg']:.3f} deg at mu = "
                      f"{cones[0]['advance_ratio']:g}) and the built-in equivalent hinge's lies "
                      f"between the two in {br} of {len(cones)} rows.")
    cyc = [r for r in rows if {"beta_1c_deg", "beta_1s_deg"} & set(r["beyond_limit"])]
    if cyc:
        ms = [r["stiff_link"]["coning_matched"] for r in cyc]
        worst_m = max(abs(m["diff_pct"][k]) for m in ms for k in ("beta_1c_deg", "beta_1s_deg"))
        worst_s = max(abs(r["stiff_link"]["diff_pct"][k]) for r in cyc
                      for k in ("beta_1c_deg", "beta_1s_deg"))
        lines[-1] += (f" The cyclic flapping follows the tip's coning: with the stiff link, the "
                      f"built-in's hinge spring matched to MBDyn's tip coning (EI "
                      f"{min(m['ei_flap'] for m in ms):.2f} to "
                      f"{max(m['ei_flap'] for m in ms):.2f} N m^2 against the preset's "
                      f"{ms[0]['preset_ei_flap']:g}: the bending blade seen from its tip is "
                      f"softer than the equivalent hinge) flies MBDyn's beta_1c and beta_1s "
                      f"within {worst_m:.1f} % of coning in the {len(cyc)} rows with cyclic "
                      f"differences beyond {lim:g} % (the preset's hinge: {worst_s:.1f} %).")
    left = [(r, k) for r in rows for k, ok in r["explained"].items() if not ok]
    if left:
        lines[-1] += " Not explained by the pitch: " + "; ".join(
            f"{k} at mu = {r['advance_ratio']:g} ({r['diff_pct'][k]:+.1f} %, at MBDyn's "
            f"pitch {r['diff_pct_at_mbdyn_pitch'][k]:+.1f} %, stiff link "
            f"{r['stiff_link']['diff_pct'][k]:+.1f} %)" + _time_step_note(r, k)
            for r, k in left) + "."
    return "\n".join(lines)


def _time_step_note(r: dict, k: str) -> str:
    """Whether MBDyn's time step moves a difference the pitch leaves: the stiff-link case at
    twice the steps per revolution against the row's."""
    fine = r["stiff_link"].get("refined")
    if fine is None:
        return ""
    d0, d1 = r["stiff_link"]["diff_pct"][k], fine["diff_pct"][k]
    verdict = ("not MBDyn's time step" if abs(d1 - d0) < 0.25 * abs(d0)
               else "it moves with MBDyn's time step")
    return (f"; with the stiff link at {fine['steps_per_rev']} steps per revolution "
            f"{d1:+.1f} %: {verdict}")


def _rigid_summary(res: dict) -> str:
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
                    help="advance ratio (repeatable; default 0.1, 0.2, 0.3, the elastic rows "
                    "also 0)")
    ap.add_argument("--template", choices=["rigid", "elastic", "both"], default="both",
                    help="the rows to run (default both)")
    ap.add_argument("--revolutions", type=int, default=20)
    ap.add_argument("--no-refine", action="store_true",
                    help="MBDyn at 72 steps per revolution only (no time-step extrapolation)")
    ap.add_argument("--elastic-revolutions", type=int, default=20,
                    help="revolutions of the elastic runs (default 20)")
    ap.add_argument("--elastic-tolerance", type=float, default=CaseSettings().tolerance,
                    help="periodicity tolerance of the elastic runs, relative (default "
                    f"{CaseSettings().tolerance:g})")
    ap.add_argument("--keep", type=Path, default=None,
                    help="run the elastic cases in this folder and keep MBDyn's files")
    ap.add_argument("--out", type=Path, default=None,
                    help=f"write the JSON here (default with all rows: {OUT})")
    ap.add_argument("--summary", type=Path, nargs="?", const=OUT, default=None,
                    help="print the table of a saved JSON instead of running")
    args = ap.parse_args()
    if args.summary:
        print(summary(args.summary))
        return
    res: dict = {}
    if args.template in ("rigid", "both"):
        res.update(run(tuple(args.mu) if args.mu else ADVANCE_RATIOS, args.revolutions,
                       not args.no_refine))
    if args.template in ("elastic", "both"):
        settings = CaseSettings(revolutions=args.elastic_revolutions,
                                tolerance=args.elastic_tolerance)
        mus = tuple(args.mu) if args.mu else ELASTIC_ADVANCE_RATIOS
        if args.keep is not None:
            res["elastic"] = run_elastic(mus, settings, args.keep.absolute())
        else:
            with tempfile.TemporaryDirectory() as tmp:
                res["elastic"] = run_elastic(mus, settings, Path(tmp))
    res["provenance"] = provenance()
    text = json.dumps(res, indent=2)
    out = args.out or (OUT if args.mu is None and args.template == "both" else None)
    if out is not None:
        out.write_text(text + "\n")
    print(text)
    sys.exit(0)


if __name__ == "__main__":
    main()
