"""Rotor fidelity against the reference study: the GVPM control chain, the cyclic response of
thesis table 4.6, the Bo105 geometry (table 3.11) and the ground-effect models, through the
API and the command line."""

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import rotoruq as rq
from _inproc import rotoruq
from rotoruq.results import load_step
from rotoruq.rotor.ground_effect import (
    fradenburgh_thrust_ratio,
    ground_effect_factor,
    min_height_over_radius,
)
from rotoruq.rotor.presets import bo105, gvpm

# thesis section 4.3 operating point at the 4R rotor speed; Bayes posterior means (table 4.11)
OP = {"omega": 224.6375, "collective_deg": 5.0, "lateral_deg": -1.0, "longitudinal_deg": -1.0}
POST = {"omega": 224.6375, "collective_deg": 5.411, "lateral_deg": 0.1698,
        "longitudinal_deg": -0.2955, "ei_flap": 8.499, "k_pitch_link": 15.024}


def cli(*args, cwd=None):
    r = subprocess.run([sys.executable, "-m", "rotoruq.study.cli", *args], capture_output=True,
                       text=True, cwd=cwd, timeout=300)
    assert r.returncode == 0, r.stderr
    return r.stdout


# ---------------------------------------------------------------------------------------------
# the control chain


def test_feathering_stiffness_from_link_geometry_is_the_documented_value():
    """K_p acts as EA over the link length: k_theta = (K_p / l0) l_h^2 = (15 / 0.02) 0.024^2
    = 0.432 N m/rad at K_p = 15 (preset docstring), about 3 I_p Omega^2."""
    p = gvpm()
    assert (p.pitch_link_length, p.pitch_horn_arm) == (0.02, 0.024)
    assert p.feathering_stiffness(15.0) == pytest.approx(0.432, rel=1e-12)
    assert p.feathering_stiffness(15.0) / (p.pitch_inertia * 224.6375**2) == pytest.approx(
        3.1, abs=0.05)
    # the feathering stiffness as an input gives bitwise the same rotor
    a = rq.RotorModel("gvpm", names_in=["k_pitch_link"], names_out=["thrust", "roll"], fixed=OP)
    b = rq.RotorModel("gvpm", names_in=["k_feather"], names_out=["thrust", "roll"], fixed=OP)
    np.testing.assert_array_equal(a([[15.0], [10.0]]), b([[p.feathering_stiffness(15.0)],
                                                          [p.feathering_stiffness(10.0)]]))
    with pytest.raises(rq.ParameterError, match="not both"):
        rq.RotorModel("gvpm", names_in=["k_feather", "k_pitch_link"])


def test_feathering_inputs_from_the_command_line():
    out = json.loads(cli("evaluate", "--preset", "gvpm", "--json", "--set",
                         "k_feather=0.432,0.432,0.432", "cm0=0,-0.005,0",
                         "aero_center_offset=-0.001,-0.001,-0.003"))
    ref = json.loads(cli("evaluate", "--preset", "gvpm", "--json", "--set", "k_pitch_link=15"))
    assert out[0]["thrust"] == pytest.approx(ref[0]["thrust"], rel=1e-9)
    assert out[1]["thrust"] < 0.8 * out[0]["thrust"]   # a nose-down section moment
    assert "torsional divergence" in out[2]["failure"]   # a.c. 3 mm ahead: no stable pitch


def test_thrust_sensitivity_to_kp_within_thesis_range():
    """Table 4.7's design (K_p ~ N(15, 0.75), lift slopes and drags at +-5 %, EI_y ~
    N(10, 0.5)) at the section 4.3 commands: the thesis's main index of K_p on thrust is 0.14
    and the lift slope at Mach 0.3 dominates (0.78); ours within a factor of two."""
    space = rq.ParameterSpace({
        "cla_m02": rq.Normal(0.1055, 5.275e-3), "cla_m03": rq.Normal(0.108, 5.4e-3),
        "cd0_m02": rq.Normal(0.0079, 3.95e-4), "cd0_m03": rq.Normal(0.0077, 3.85e-4),
        "k_pitch_link": rq.Normal(15.0, 0.75), "ei_flap": rq.Normal(10.0, 0.5)})
    m = rq.RotorModel("gvpm", names_in=space.names, names_out=["thrust"], fixed=OP)
    s = rq.sobol_indices(m, space, 128, seed=1, n_bootstrap=0)
    main = dict(zip(space.names, s.main[0], strict=True))
    assert 0.07 < main["k_pitch_link"] < 0.28
    assert main["cla_m03"] > 0.5 and main["cla_m03"] == max(main.values())


def test_propeller_moment_and_ac_offset_carry_kp_effect():
    """Over K_p 10 -> 20 the thrust rises because the link beats the propeller moment
    I_p Omega^2 theta by more; the lift's nose-up moment (a.c. ahead of the feathering axis)
    works against it and halves the effect."""
    rows = [[10.0], [20.0]]

    def rise(p):
        y = rq.RotorModel(p, names_in=["k_pitch_link"], names_out=["thrust"], fixed=POST)(rows)
        return y[1, 0] / y[0, 0] - 1

    assert 0.05 < rise(gvpm()) < 0.2
    assert rise(gvpm(aero_center_offset=0.0)) > 1.8 * rise(gvpm())
    assert rise(gvpm(pitch_inertia=2 * gvpm().pitch_inertia)) > rise(gvpm())


# ---------------------------------------------------------------------------------------------
# the cyclic response (table 4.6)


def test_cyclic_axes_and_signs_of_table_4_6():
    """Commands uniform on [4, 8] x [-2, 2] x [-2, 2] deg at K_p = 10 (table 4.5): collective
    drives thrust, lateral cyclic drives roll, longitudinal drives pitch (thesis main indices
    0.91, 0.77, 0.79; cross terms 0.19 and 0.12). At the posterior commands the hub moments
    have the measured signs (table 4.1 at 4R: roll -0.039, pitch -0.237 N m)."""
    space = rq.ParameterSpace({"collective_deg": rq.Uniform(4, 8),
                               "lateral_deg": rq.Uniform(-2, 2),
                               "longitudinal_deg": rq.Uniform(-2, 2)})
    m = rq.RotorModel("gvpm", names_in=space.names, names_out=["thrust", "roll", "pitch"],
                      fixed={"omega": 224.6375, "k_pitch_link": 10.0, "ei_flap": 10.0})
    s = rq.sobol_indices(m, space, 128, seed=2, n_bootstrap=0)
    (tc, tl, tg), (rc, rl, rg), (pc, pl, pg) = s.main
    assert tc > 0.9
    assert rl > 0.6 and rl > 3 * rg
    assert pg > 0.6 and pg > 3 * pl
    y = rq.RotorModel("gvpm", names_in=["cm0"], names_out=["roll", "pitch"], fixed=POST)([[0.0]])
    assert y[0, 0] < 0 and y[0, 1] < 0


def test_flap_lag_and_what_sets_it():
    """Flap response lag behind the cyclic: about 70 deg for the preset (the thesis's 64-74
    deg implied by table 4.6); without the feathering coupling of the a.c. offset about 37 deg,
    and with the first-harmonic (Pitt-Peters) inflow that MBDyn's Glauert inflow lacks in
    hover, about 16 deg."""
    def lag(p):
        sol = rq.RotorModel(p, names_in=["lateral_deg"], fixed={
            "omega": 224.6375, "k_pitch_link": 10.0, "ei_flap": 10.0,
            "collective_deg": 5.0}).solve([[1.0], [-1.0]])
        return -np.degrees(np.angle((sol.flap[0, 1] - sol.flap[1, 1]) / 2))

    assert 64 < lag(gvpm()) < 76
    assert 30 < lag(gvpm(aero_center_offset=0.0)) < 45
    assert lag(gvpm(aero_center_offset=0.0, harmonic_inflow=True)) < 25


# ---------------------------------------------------------------------------------------------
# Bo105 geometry (table 3.11)

THESIS_3_2 = {"cla_m01": 0.1075, "cl0_m01": 0.127, "cla_m02": 0.1075, "cl0_m02": 0.127,
              "cla_m03": 0.1075, "cl0_m03": 0.127, "cla_m04": 0.1126, "cl0_m04": 0.127,
              "cla_m05": 0.1172, "cl0_m05": 0.1405, "cla_m06": 0.1135, "cl0_m06": 0.1327}


def test_bo105_nominal_thrust_with_the_chosen_twist():
    """Linear -8 deg twist with the thesis's own lift fits (table 3.2) at 6 deg collective and
    -2 deg longitudinal: 2111 N against the thesis's 2009 N (table 3.11, +5 %); the -6.2 deg
    whole-span reading gives 2.6 x. The torque (1417 N m against 2361 N m) is not reproduced:
    the thesis's drag table is not published."""
    assert bo105().twist_deg == -8.0
    m = rq.RotorModel("bo105", names_out=["thrust", "torque"], fixed=THESIS_3_2)
    t, q = m([[6.0, 0.0, -2.0]])[0]
    assert t == pytest.approx(2009.065, rel=0.06)
    t62 = rq.RotorModel(bo105(twist_deg=-6.2), names_out=["thrust"], fixed=THESIS_3_2)(
        [[6.0, 0.0, -2.0]])[0, 0]
    assert t62 > 2.4 * 2009.065
    assert 0.5 * 2360.925 < q < 0.7 * 2360.925


# ---------------------------------------------------------------------------------------------
# ground effect


def test_fradenburgh_curve_beside_cheeseman_bennett_and_hayden():
    h = np.array([4.0, 2.0, 1.0, 0.5])
    k = ground_effect_factor(h, "fradenburgh")
    np.testing.assert_allclose(k, 1.0 / np.array([1.0, 1.02, 1.13, 1.38]), rtol=1e-12)
    assert np.isnan(ground_effect_factor(0.45, "fradenburgh"))
    assert min_height_over_radius("fradenburgh") == 0.5
    np.testing.assert_allclose(fradenburgh_thrust_ratio(h), 1 / k)
    assert gvpm().ground_effect == "cheeseman_bennett"
    # more thrust at 1R than Cheeseman-Bennett, at fixed controls
    t = {g: rq.RotorModel(gvpm(ground_effect=g), names_in=["height_over_radius"],
                          names_out=["thrust"], fixed=POST)([[4.0], [1.0]])[:, 0]
         for g in ("cheeseman_bennett", "hayden", "fradenburgh")}
    assert t["cheeseman_bennett"][1] / t["cheeseman_bennett"][0] < \
        t["fradenburgh"][1] / t["fradenburgh"][0] < 1.4148
    m = rq.RotorModel(gvpm(ground_effect="fradenburgh"), names_in=["height_over_radius"],
                      names_out=["thrust"])
    assert "below 0.5 R" in m.evaluate([[0.4]]).failures[0]


def test_fradenburgh_ground_effect_from_a_study_file(tmp_path):
    def run(model, h):
        d = tmp_path / f"{model}_{h}"
        d.mkdir()
        (d / "s.toml").write_text(textwrap.dedent(f"""
            [study]
            name = "ge"
            seed = 1
            output = "out"

            [model]
            preset = "gvpm"
            responses = ["thrust"]
            fixed = {{ omega = 223.05, height_over_radius = {h} }}
            preset_options = {{ ground_effect = "{model}" }}

            [parameters.collective_deg]
            distribution = "normal"
            mean = 5.4
            std = 0.1

            [[steps]]
            name = "mv"
            type = "mean_value"
        """))
        # in this process (tests/_inproc.py): the study file's path through the CLI is what
        # is checked, not a process; the report is not
        done = rotoruq("run", "s.toml", "--no-report", cwd=d)
        assert done.returncode == 0, done.stderr
        return load_step(d / "out" / "steps" / "mv").get("mean/thrust")

    oge = run("fradenburgh", 4.0)
    assert run("fradenburgh", 1.0) / oge > run("cheeseman_bennett", 1.0) / oge > 1.05
