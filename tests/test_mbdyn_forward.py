"""MBDyn in forward flight (issue 38, item 5): the templates' free stream and cyclic pitch, hover
unchanged, and the parity check of ``benchmarks/forward_flight_mbdyn.py`` at one advance ratio
(the benchmark's script run from a fresh folder)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from rotoruq.errors import ParameterError
from rotoruq.evaluation.templates import fill_template
from rotoruq.mbdyn import CaseSettings, run_case, template_values
from rotoruq.mbdyn.case import template_text
from rotoruq.rotor.presets import get_preset
from test_mbdyn import MBDYN, env_with_mbdyn, needs_mbdyn

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "benchmarks" / "forward_flight_mbdyn.py"


@pytest.mark.parametrize("template", ["rigid", "elastic"])
def test_forward_inputs_fill_the_free_stream(template):
    text, path = template_text(template)
    preset = get_preset("gvpm")
    hover = fill_template(text, template_values(preset, {}, CaseSettings()), path=path)
    assert "set: real MU = 0.0;" in hover and "set: real ALPHA_S = 0.0 * pi / 180.;" in hover
    vals = template_values(preset, {"advance_ratio": 0.2, "shaft_angle_deg": 3.0,
                                    "lateral_deg": 0.5}, CaseSettings())
    filled = fill_template(text, vals, path=path)
    assert "set: real MU = 0.2;" in filled and "set: real ALPHA_S = 3.0 * pi / 180.;" in filled
    # the air moves aft in the disk plane at mu Omega R and down through the tilted disk
    assert "air properties: RHO, SOUND, cos(ALPHA_S), 0., -sin(ALPHA_S), const, V_INF;" in filled
    assert "set: real V_INF = MU * OMEGA * R / cos(ALPHA_S);" in filled
    assert "set: real LAT = 0.5 * pi / 180.;" in filled
    if template == "elastic":
        # MBDyn's default stall tolerance in hover (output unchanged), none in forward flight
        assert ', tolerance, 1e-06, free format;' in hover
        assert ', tolerance, 1e+30, free format;' in filled


@needs_mbdyn
def test_elastic_template_flies_through_the_reverse_flow_region(tmp_path):
    """A sample of the forward_flight study (K_p = 11 N, mu = 0.2, the driver's trim) whose
    elastic run stopped at step 115 (1.6 revolutions) with MBDyn's stall tolerance: the
    residual on the inboard beam of the blade leaving the reverse-flow region stayed at
    0.030 N (MBDyn's swept-flow lift jumps where its stall branch starts). Without the stall
    slope the lift is continuous and the case reaches a periodic state."""
    from rotoruq.mbdyn.driver import builtin_trim

    preset = get_preset("gvpm")
    inputs = builtin_trim(preset, {"omega": 224.6375, "thrust_target": 20.0,
                                   "shaft_angle_deg": 3.0, "advance_ratio": 0.2,
                                   "k_pitch_link": 11.0, "ei_flap": 7.0, "cla_m03": 0.108,
                                   "cd0_m03": 0.011, "height_over_radius": math.inf},
                          "drees")
    loads = run_case(tmp_path, preset, inputs, template="elastic",
                     settings=CaseSettings(revolutions=6, average=2, tolerance=0.02),
                     mbdyn=MBDYN)
    assert "tolerance, 1e+30" in (tmp_path / "rotor.mbd").read_text()
    assert 10.0 < loads.response("thrust") < 30.0 and loads.response("power") > 0.0


def test_elastic_swashplate_follows_the_hubs_azimuth():
    """The elastic template's cyclic is a function of the hub node's rotation (MBDyn's hub
    runs 0.135 deg per revolution ahead of OMEGA * Time, which drifted the cyclic's phase
    against the blades): every blade's swashplate drive reads the hub's E[3], none the
    clock."""
    text, path = template_text("elastic")
    vals = template_values(get_preset("gvpm"), {"advance_ratio": 0.3, "lateral_deg": 0.2,
                                                "longitudinal_deg": -1.3}, CaseSettings())
    filled = fill_template(text, vals, path=path)
    drives = [ln for ln in filled.splitlines() if "LAT * cos(" in ln]
    assert len(drives) == 4
    for k, ln in enumerate(drives, start=1):
        assert f"LAT * cos(Var + PSI{k}) + LON * sin(Var + PSI{k})" in ln
    assert filled.count('single, 0., 0., 1., node, HUB, structural, string, "E[3]", string,') == 4
    assert not any("OMEGA * Time" in ln for ln in filled.splitlines() if not ln.startswith("#"))


def test_bad_flight_inputs_are_refused():
    with pytest.raises(ParameterError, match=r"advance_ratio must be in \[0, 1\]"):
        template_values(get_preset("gvpm"), {"advance_ratio": -0.1}, CaseSettings())
    with pytest.raises(ParameterError, match=r"\|shaft_angle_deg\| < 90"):
        template_values(get_preset("gvpm"), {"shaft_angle_deg": 95.0}, CaseSettings())


@needs_mbdyn
def test_rigid_template_in_hover_is_unchanged(tmp_path):
    """The blades now hang on pitch joints: in hover the loads are those the benchmark saved
    before (benchmarks/results/mbdyn_parity.json, gvpm at 5.4 deg out of ground effect, 40
    revolutions) to solver precision."""
    saved = json.loads((ROOT / "benchmarks" / "results" / "mbdyn_parity.json").read_text())
    row = next(r for r in saved["parity"]["gvpm"]
               if r["collective_deg"] == 5.4 and r["height_over_radius"] == "inf")
    m = run_case(tmp_path, get_preset("gvpm"), {"collective_deg": 5.4,
                                                 "height_over_radius": math.inf},
                 settings=CaseSettings(revolutions=40), mbdyn=MBDYN)
    assert m.thrust == pytest.approx(row["mbdyn_thrust"], rel=1e-6)
    assert m.torque == pytest.approx(row["mbdyn_torque"], rel=1e-6)


@needs_mbdyn
def test_forward_flight_parity_at_mu_02(tmp_path):
    """The benchmark's check at mu = 0.2 (built-in trimmed controls flown by MBDyn's rigid
    template and by the built-in rotor on the same physics): thrust and power within 5 % at
    MBDyn's 72 steps per revolution, every load within 5 % of MBDyn extrapolated to zero time
    step (the hub moments' difference at 72 steps is MBDyn's time step)."""
    out = tmp_path / "ff.json"
    proc = subprocess.run([sys.executable, str(BENCH), "--template", "rigid", "--mu", "0.2",
                           "--out", str(out)],
                          cwd=tmp_path, env=env_with_mbdyn(), capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr
    res = json.loads(out.read_text())
    (row,) = res["rows"]
    assert row["advance_ratio"] == 0.2
    assert row["controls_deg"]["longitudinal_deg"] < 0  # the trim's cyclic is flown
    for load in ("thrust", "power"):
        assert abs(row["diff_pct"][load]) <= 5.0, (load, row)
    for load, diff in row["diff_pct_converged"].items():
        assert abs(diff) <= 5.0, (load, diff, row)
    # the moments move towards the built-in rotor's as MBDyn's step shrinks
    for load in ("roll_moment", "pitch_moment"):
        assert abs(row["diff_pct_converged"][load]) < abs(row["diff_pct"][load])
    assert res["all_converged_within_limit"]


# ------------------------------------------------------------------------------------------
# the driver's trim and the bundled study's multi-fidelity step


def test_driver_trim_flies_the_builtin_rotors_controls():
    from rotoruq.mbdyn.driver import builtin_trim
    from rotoruq.rotor.forward import ForwardRotorModel

    inputs = {"advance_ratio": 0.2, "shaft_angle_deg": 3.0, "thrust_target": 20.0,
              "cla_m03": 0.11, "height_over_radius": math.inf}
    flown = builtin_trim(get_preset("gvpm"), inputs, "drees")
    ref = ForwardRotorModel("gvpm", names_in=list(inputs), trim="wind_tunnel",
                            inflow_model="drees",
                            names_out=["collective_trim_deg", "lateral_trim_deg",
                                       "longitudinal_trim_deg"])([list(inputs.values())])[0]
    assert "thrust_target" not in flown and flown["cla_m03"] == 0.11
    assert [flown["collective_deg"], flown["lateral_deg"], flown["longitudinal_deg"]] == \
        ref.tolist()
    with pytest.raises(ParameterError, match="needs the input thrust_target"):
        builtin_trim(get_preset("gvpm"), {"advance_ratio": 0.2})
    with pytest.raises(ParameterError, match="solves the controls"):
        builtin_trim(get_preset("gvpm"), {**inputs, "collective_deg": 3.0})
    with pytest.raises(ParameterError, match="does not trim: advance_ratio 0.6"):
        builtin_trim(get_preset("gvpm"), {**inputs, "advance_ratio": 0.6})


STUDY = ROOT / "src" / "rotoruq" / "studies" / "forward_flight.toml"


@pytest.mark.parametrize("old, new, expected", [
    ('high_fidelity = "mbdyn"', 'high_fidelity = "mbdin"',
     "the name of a [models.NAME] table as the high_fidelity"),
    ('needs = ["mbdyn"]', 'needs = ["mbdin"]', "outside software among mbdyn"),
    ('responses = ["power"]\ntimeout', 'responses = ["thrust"]\ntimeout',
     "responses of [models.mbdyn] that include the responses of step"),
    ('models = ["builtin"]', 'models = ["builtin", "mbdyn"]',
     "low-fidelity models other than the high_fidelity"),
])
def test_study_multifidelity_step_is_checked(tmp_path, old, new, expected):
    from rotoruq.errors import InputFileError
    from rotoruq.study.schema import load_study

    text = STUDY.read_text()
    assert old in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(old, new))
    with pytest.raises(InputFileError, match=expected.replace("[", r"\[").replace("]", r"\]")):
        load_study(bad)


@pytest.mark.extended  # ~1 min of MBDyn on 2 cores; CI runs the step's checks and the parity
@needs_mbdyn
def test_forward_flight_study_multifidelity_with_mbdyn(tmp_path):
    """``rotoruq run forward_flight --quick`` with MBDyn, its multi-fidelity step at mu = 0.2
    alone (``--only``): MBDyn's elastic rotor flying the built-in trim is the high-fidelity
    model."""
    env = env_with_mbdyn()
    cli = [sys.executable, "-m", "rotoruq"]
    done = subprocess.run([*cli, "run", "forward_flight", "--quick", "--only",
                           "multifidelity_mu02", "--no-report", "--out", "res"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=1800)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "0 failed evaluation(s)" in done.stdout
    shown = subprocess.run([*cli, "show", "res", "multifidelity_mu02", "--json"], cwd=tmp_path,
                           env=env, capture_output=True, text=True, timeout=120)
    assert shown.returncode == 0, shown.stderr[-2000:]
    step = json.loads(shown.stdout)["steps"]["multifidelity_mu02"]
    alloc = {row[0].split(" ")[0]: row for row in step["tables"][0]["rows"]}
    assert set(alloc) == {"mbdyn", "builtin"}
    est = step["tables"][1]["rows"][0]
    assert est[0].startswith("power") and 100.0 < float(est[1]) < 400.0  # W


# ------------------------------------------------------------------------------------------
# the elastic rows: the benchmark's elastic check at mu = 0.2, short (6 revolutions, ~10
# CPU-s of MBDyn for the nominal and the stiff-link run)


@pytest.fixture(scope="module")
def elastic_row(tmp_path_factory):
    if MBDYN is None:
        pytest.skip("MBDyn not found")
    tmp = tmp_path_factory.mktemp("elastic_ff")
    out = tmp / "elastic.json"
    proc = subprocess.run([sys.executable, str(BENCH), "--template", "elastic", "--mu", "0.2",
                           "--elastic-revolutions", "6", "--elastic-tolerance", "0.05",
                           "--keep", str(tmp / "runs"), "--out", str(out)],
                          cwd=tmp, env=env_with_mbdyn(), capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    res = json.loads(out.read_text())
    (row,) = res["elastic"]["rows"]
    return res, row, tmp / "runs"


def _pitch_harmonics(mov: Path, steps: int) -> list[float]:
    """Mean, cos and sin harmonics [deg] of the blades' pitch at the feathering hinge, by
    projection over the last ``steps`` rows (whole revolutions): the root nodes' chord axis
    from their orientation matrices, their azimuth from their positions."""
    import numpy as np

    d = np.loadtxt(mov)
    out = np.zeros(3)
    for blade in (1000, 2000, 3000, 4000):
        rows = d[d[:, 0] == blade][-steps:]
        psi = np.arctan2(rows[:, 2], rows[:, 1])
        theta = np.degrees(np.arcsin(rows[:, 11]))
        out += [theta.mean(), 2 * (theta * np.cos(psi)).mean(),
                2 * (theta * np.sin(psi)).mean()]
    return (out / 4).tolist()


def _pitch_2p(mov: Path, steps: int) -> float:
    """The amplitude [deg] of the blades' 2/rev pitch at the feathering hinge, by projection
    over the last ``steps`` rows (whole revolutions)."""
    import numpy as np

    d = np.loadtxt(mov)
    c2 = s2 = 0.0
    for blade in (1000, 2000, 3000, 4000):
        rows = d[d[:, 0] == blade][-steps:]
        psi = np.arctan2(rows[:, 2], rows[:, 1])
        theta = np.degrees(np.arcsin(rows[:, 11]))
        c2 += 2 * (theta * np.cos(2 * psi)).mean() / 4
        s2 += 2 * (theta * np.sin(2 * psi)).mean() / 4
    return math.hypot(c2, s2)


@needs_mbdyn
def test_elastic_parity_rows_have_their_cause_computed(elastic_row):
    """Every elastic difference beyond 5 % carries a cause whose numbers come from this run:
    the blade pitch MBDyn flew (its first harmonics and its 2/rev), recomputed here from
    MBDyn's node output, the built-in hinge spring matched to MBDyn's tip coning with the
    stiff link, recomputed here with the built-in rotor, and the sentence quoting them."""
    res, row, runs = elastic_row
    assert "thrust" in row["beyond_limit"] and row["diff_pct"]["thrust"] > 5.0
    assert set(row["causes"]) == set(row["beyond_limit"]) == set(row["explained"])
    assert all(row["explained"].values()) and res["elastic"]["all_explained"]
    steps = res["elastic"]["average"] * res["elastic"]["steps_per_rev"]
    mine = _pitch_harmonics(runs / "elastic_mu_0.2" / "rotor.mov", steps)
    flown = [row["mbdyn_pitch_deg"][k] for k in ("collective_deg", "lateral_deg",
                                                  "longitudinal_deg")]
    assert mine == pytest.approx(flown, abs=2e-3)
    assert _pitch_2p(runs / "elastic_mu_0.2" / "rotor.mov", steps) == pytest.approx(
        row["mbdyn_pitch_2p_deg"], abs=2e-3)
    p, c = row["mbdyn_pitch_deg"], row["controls_deg"]
    # the cyclic flapping with the stiff link against the built-in hinge whose spring gives
    # MBDyn's tip coning: one number from the run fixes EI, the two cyclic ones follow
    from rotoruq.rotor.forward import ForwardRotorModel

    stiff, matched = row["stiff_link"]["mbdyn"], row["stiff_link"]["coning_matched"]
    model = ForwardRotorModel("gvpm", names_in=[*c, "advance_ratio", "shaft_angle_deg",
                                                "k_pitch_link", "ei_flap"],
                              names_out=["beta_0_deg", "beta_1c_deg", "beta_1s_deg"],
                              inflow_model="glauert")
    b0, b1c, b1s = model([[*c.values(), 0.2, 3.0, 1.0e4, matched["ei_flap"]]])[0]
    assert b0 == pytest.approx(stiff["beta_0_deg"], rel=1e-4)
    assert matched["ei_flap"] < 0.9 * matched["preset_ei_flap"]   # the tip sees a softer blade
    for k, v in (("beta_1c_deg", b1c), ("beta_1s_deg", b1s)):
        assert 100 * (v - stiff[k]) / b0 == pytest.approx(matched["diff_pct"][k], abs=1e-6)
        assert abs(matched["diff_pct"][k]) <= 5.0 < abs(row["diff_pct"][k])
        assert k in row["causes"] and f"{matched['ei_flap']:.2f} N m^2" in row["causes"][k]
        assert f": {matched['diff_pct'][k]:+.1f} %." in row["causes"][k]
        assert f"{row['mbdyn_pitch_2p_deg']:.3f} deg of 2/rev" in row["causes"][k]
    for name, text in row["causes"].items():
        assert f"{row['diff_pct'][name]:+.1f} %" in text
        assert f"{p['collective_deg']:.2f}, {p['lateral_deg']:+.2f}" in text
        assert f"against {c['collective_deg']:.2f}" in text
        assert f"{row['diff_pct_at_mbdyn_pitch'][name]:+.1f} %" in text
    sys.path.insert(0, str(BENCH.parent))
    try:
        import forward_flight_mbdyn as bench
    finally:
        sys.path.remove(str(BENCH.parent))
    table = bench.summary(runs.parent / "elastic.json")
    assert f"{row['mbdyn']['thrust']:.2f} / {row['builtin']['thrust']:.2f}" in table
    assert f"{len(row['beyond_limit'])} differences beyond 5 %" in table


@needs_mbdyn
def test_elastic_difference_is_the_blades_pitch(elastic_row):
    """The elastic thrust gap is the blade's pitch: MBDyn's blade flies below the commanded
    collective (the pitch link's deflection); the built-in rotor flown at that measured pitch
    gives MBDyn's thrust and power within 5 %, and with a stiff pitch link MBDyn's blade flies
    the commanded pitch and both rotors agree within 5 %."""
    from rotoruq.rotor.forward import ForwardRotorModel

    _, row, _ = elastic_row
    c, p = row["controls_deg"], row["mbdyn_pitch_deg"]
    assert p["collective_deg"] < c["collective_deg"] - 0.2
    names = ["collective_deg", "lateral_deg", "longitudinal_deg", "advance_ratio",
             "shaft_angle_deg", "k_pitch_link"]
    model = ForwardRotorModel("gvpm", names_in=names, names_out=["thrust", "power"],
                              inflow_model="glauert")
    at = model([[p["collective_deg"], p["lateral_deg"], p["longitudinal_deg"], 0.2, 3.0,
                 1.0e4]])[0]
    md = row["mbdyn"]
    assert at[0] == pytest.approx(row["builtin_at_mbdyn_pitch"]["thrust"], rel=1e-9)
    assert abs(at[0] - md["thrust"]) / md["thrust"] <= 0.05
    assert abs(at[1] - md["power"]) / md["power"] <= 0.05
    assert abs(row["builtin"]["thrust"] - md["thrust"]) / md["thrust"] > 0.05
    stiff = row["stiff_link"]
    assert [stiff["mbdyn_pitch_deg"][k] for k in c] == pytest.approx(list(c.values()),
                                                                   abs=0.01)
    for load in ("thrust", "power"):
        assert abs(stiff["diff_pct"][load]) <= 5.0, (load, stiff)
