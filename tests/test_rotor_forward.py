"""The rotor in forward flight (issue 38): hover limit, trim, failures, verification."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

import rotoruq as rq
from rotoruq.errors import ParameterError
from rotoruq.rotor.forward import FORWARD_RESPONSES, ForwardRotorModel
from rotoruq.rotor.model import RotorModel

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import forward_flight_verification as ffv  # noqa: E402

CONTROLS = ["collective_deg", "lateral_deg", "longitudinal_deg"]
POINTS = np.array([[5.0, -1.0, -1.0], [6.0, 0.5, -0.5], [4.0, 0.0, 0.0]])
TRIMMED = ["thrust", "power", "beta_1c_deg", "beta_1s_deg", "collective_trim_deg",
           "lateral_trim_deg", "longitudinal_trim_deg"]


@pytest.mark.parametrize("preset", ["gvpm", "bo105"])
def test_zero_advance_ratio_is_the_hover_model(preset):
    hover = RotorModel(preset, names_in=CONTROLS, names_out=["thrust", "torque", "roll", "pitch"])
    fwd = ForwardRotorModel(preset, names_in=CONTROLS + ["advance_ratio"],
                            names_out=["thrust", "torque", "roll_moment", "pitch_moment"],
                            fixed={"height_over_radius":
                                   hover.defaults()["height_over_radius"]})
    a = hover(POINTS)
    b = fwd(np.column_stack([POINTS, np.zeros(len(POINTS))]))
    assert np.all(np.isfinite(a))
    # the same code paths: equal bitwise (the issue asks 1e-10)
    np.testing.assert_array_equal(a, b)


def test_small_advance_ratio_approaches_hover():
    hover = ForwardRotorModel("gvpm", names_in=CONTROLS + ["advance_ratio"],
                              names_out=["thrust", "power"])
    x = np.column_stack([POINTS, np.zeros(3)])
    y0 = hover(x)
    x[:, 3] = 1e-6
    y1 = hover(x)
    # Glauert's inflow and the blade's free-stream terms are continuous at mu = 0
    np.testing.assert_allclose(y1, y0, rtol=1e-4)
    assert not np.array_equal(y1, y0)


def test_forward_flight_loads_have_the_expected_signs():
    m = ForwardRotorModel("gvpm", names_in=CONTROLS + ["advance_ratio"],
                          names_out=["h_force", "y_force", "beta_1c_deg", "thrust"])
    y = m([[6.0, 0.0, 0.0, 0.0], [6.0, 0.0, 0.0, 0.2]])
    np.testing.assert_allclose(y[0, :3], 0.0, atol=1e-10)
    # at fixed controls the advancing side's lift flaps the disk back (beta_1c < 0: the
    # blade is down over the tail, psi = 0), the profile drag and the tilt point H
    # rearward, and the thrust grows with mu at fixed collective (1 + 3/2 mu^2)
    assert y[1, 2] < -0.5 and y[1, 0] > 0 and y[1, 3] > y[0, 3]


def _trimmed(**kw):
    return ForwardRotorModel("gvpm", names_in=["advance_ratio", "thrust_target"],
                             names_out=TRIMMED, trim="wind_tunnel",
                             fixed={"shaft_angle_deg": 3.0}, **kw)


def test_wind_tunnel_trim_reaches_its_targets_and_agrees_with_the_given_controls():
    mus = [0.0, 0.1, 0.2, 0.3, 0.4]
    m = _trimmed(tolerance=1e-11)
    y = m(np.column_stack([mus, np.full(5, 20.0)]))
    assert np.all(np.isfinite(y))
    np.testing.assert_allclose(y[:, 0], 20.0, rtol=1e-8)
    np.testing.assert_allclose(y[:, 2:4], 0.0, atol=1e-8)
    # the trimmed controls given back to the untrimmed model give the same state
    free = ForwardRotorModel("gvpm", names_in=CONTROLS + ["advance_ratio"],
                             names_out=["thrust", "power", "beta_1c_deg", "beta_1s_deg"],
                             fixed={"shaft_angle_deg": 3.0}, tolerance=1e-11)
    z = free(np.column_stack([y[:, 4:7], mus]))
    np.testing.assert_allclose(z[:, :2], y[:, :2], rtol=1e-7)
    np.testing.assert_allclose(z[:, 2:], 0.0, atol=1e-7)


def test_a_row_trims_to_the_same_bits_alone_and_in_a_threaded_batch():
    m = _trimmed()
    rng = np.random.default_rng(3)
    x = np.column_stack([rng.uniform(0.05, 0.35, 64), rng.uniform(15.0, 25.0, 64)])
    batch = m(x)
    alone = np.vstack([m(x[i:i + 1]) for i in (0, 17, 63)])
    np.testing.assert_array_equal(batch[[0, 17, 63]], alone)


def test_a_point_that_cannot_trim_fails_with_its_reason():
    m = _trimmed()
    res = m.evaluate([[0.2, 20.0], [0.2, 2000.0]])
    assert np.all(np.isfinite(res.values[0]))
    assert set(res.failures) == {1}
    reason = res.failures[1]
    assert "cannot trim" in reason or "stall" in reason, reason


def test_drees_inflow_changes_the_lateral_flapping_only_in_forward_flight():
    kw = dict(names_in=CONTROLS + ["advance_ratio"], names_out=["thrust", "beta_1s_deg"])
    g, d = ForwardRotorModel("gvpm", **kw), ForwardRotorModel("gvpm", inflow_model="drees", **kw)
    x = np.array([[6.0, 0.0, 0.0, 0.0], [6.0, 0.0, 0.0, 0.2]])
    yg, yd = g(x), d(x)
    np.testing.assert_array_equal(yg[0], yd[0])
    # the longitudinal inflow gradient (more inflow over the tail) flaps the disk laterally
    assert abs(yd[1, 1] - yg[1, 1]) > 0.1


@pytest.mark.parametrize(("kwargs", "message"), [
    (dict(names_in=["advance_ratio", "thrust_target"]), "thrust_target"),
    (dict(trim="wind_tunnel"), "needs 'thrust_target'"),
    (dict(inflow_model="pitt"), "unknown inflow model 'pitt'"),
    (dict(trim="free_flight", fixed={"thrust_target": 1.0}), "unknown trim"),
    (dict(names_out=["roll"]), "unknown response 'roll'"),
])
def test_bad_options_are_named(kwargs, message):
    with pytest.raises(ParameterError, match=message):
        ForwardRotorModel("gvpm", **kwargs)


def test_bemt_preset_is_refused():
    with pytest.raises(ParameterError, match="uniform"):
        ForwardRotorModel(rq.get_preset("gvpm").replace(inflow="bemt"))


def test_out_of_range_rows_fail_with_their_reason():
    m = ForwardRotorModel("gvpm", names_in=["advance_ratio", "shaft_angle_deg",
                                           "height_over_radius"])
    res = m.evaluate([[0.5, 0.0, np.inf], [0.2, 45.0, np.inf], [0.2, 0.0, 0.25],
                      [0.2, 0.0, np.inf], [0.2, 0.0, 2.0]])
    assert "advance_ratio 0.5 is outside [0, 0.4]" in res.failures[0]
    assert "shaft_angle_deg 45" in res.failures[1]
    # ground effect in forward flight: the hover model's validity (z > R/4)
    assert "height_over_radius 0.25 is at or below R/4" in res.failures[2]
    assert set(res.failures) == {0, 1, 2} and np.all(np.isfinite(res.values[3:]))


def test_ground_effect_in_forward_flight_is_cheeseman_bennetts_skewed_image():
    """Trimmed to one thrust at z/R = 0.8 and out of ground effect: the converged thrust
    and mean inflow satisfy Glauert's momentum with Cheeseman-Bennett's factor
    v_IGE / v_OGE = 1 - (R/4z)^2 / (1 + (V / v)^2) (no tip loss: the closed form holds to
    the solve's tolerance); at mu -> 0 it is hover's 1 - (R/4z)^2 and it tends to 1 (out of
    ground effect) as V / v grows."""
    preset = rq.get_preset("gvpm").replace(tip_loss=False)
    m = ForwardRotorModel(preset, names_in=["advance_ratio", "height_over_radius"],
                          names_out=["thrust"], trim="wind_tunnel",
                          fixed={"thrust_target": 25.0, "shaft_angle_deg": 3.0})
    mus = np.array([1e-4, 0.02, 0.05, 0.2])
    h = 0.8

    def solve(height):   # thrust [N], induced inflow ratio v0 / (Omega R) [-]
        thrust = m(np.column_stack([mus, np.full(4, height)]))[:, 0]
        return np.column_stack([thrust, m.last_solution.inflow_ratio])

    ige, oge = solve(h), solve(np.inf)
    assert np.all(np.isfinite(ige)) and np.all(np.isfinite(oge))
    R, A = preset.radius, np.pi * preset.radius**2
    d = m.defaults()
    OmR, rho = d["omega"] * R, d["rho"]
    g = (0.25 / h) ** 2
    ratio = []
    for (T, lam), (T_o, lam_o), mu in zip(ige, oge, mus, strict=True):
        v, v_o, Vx, Vz = lam * OmR, lam_o * OmR, mu * OmR, mu * np.tan(np.deg2rad(3.0)) * OmR
        kappa = preset.induced_power_factor * (1 - g * v**2 / (v**2 + Vx**2))
        np.testing.assert_allclose(T, 2 * rho * A * v * np.hypot(Vx, Vz + v) / kappa**2,
                                   rtol=1e-7)
        np.testing.assert_allclose(T, 25.0, rtol=1e-9)
        np.testing.assert_allclose(T_o, 2 * rho * A * v_o * np.hypot(Vx, Vz + v_o)
                                   / preset.induced_power_factor**2, rtol=1e-7)
        ratio.append(1 - g * v**2 / (v**2 + Vx**2))
    # mu -> 0: hover's factor; growing mu: out of ground effect
    np.testing.assert_allclose(ratio[0], 1 - g, rtol=1e-5)
    assert ratio[0] < ratio[1] < ratio[2] < ratio[3] and 1 - ratio[3] < 0.01 * g
    # the induced inflow is lower in ground effect, by less as mu grows
    drop = 1 - ige[:, 1] / oge[:, 1]
    assert np.all(drop > 0) and np.all(np.diff(drop) < 0)


def test_every_response_is_available():
    m = ForwardRotorModel("gvpm", names_in=["advance_ratio"], names_out=FORWARD_RESPONSES)
    y = m([[0.15]])
    assert y.shape == (1, len(FORWARD_RESPONSES)) and np.all(np.isfinite(y))


# --- verification (benchmarks/forward_flight_verification.py): the checks, recomputed --------

def test_closed_forms_of_the_centrally_hinged_rotor():
    res = ffv.closed_forms()
    assert res["worst_relative_error"] <= 0.01, res
    # the comparison can fail: the full span's reverse flow, which the closed forms ignore,
    # is visible at mu = 0.3
    assert ffv.closed_forms(0.0)["rows"][2]["ct"]["relative_error"] > 0.02


def test_power_curve_shape():
    res = ffv.power_curve()
    assert res["induced_falls"] and res["induced_relative_error"] < 1e-8
    assert abs(res["K"] / res["K_expected"] - 1) <= 0.01
    assert abs(res["K_full_span"] - 3.0) <= 0.05


def test_gci_at_mu_0_3():
    res = ffv.gci()
    for name in ("power", "collective_trim_deg", "h_force"):
        assert res[name]["gci_fine"] < 0.01, res[name]


def test_the_saved_verification_passed():
    d = json.loads((ROOT / "benchmarks/results/forward_flight_verification.json").read_text())
    assert d["closed_forms"]["passed"] and d["power_curve"]["passed"] and d["gci"]["passed"]
    assert "commit" in d["provenance"]


# --- the bundled study, through the CLI in a fresh folder ------------------------------------

@pytest.mark.slow
def test_bundled_forward_flight_study_runs_from_the_cli(tmp_path):
    import os
    import subprocess

    # where MBDyn is not built: its multi-fidelity step is skipped, saying why
    env = {k: v for k, v in os.environ.items() if k != "MBDYN"}
    env.update(PYTHONPATH=str(ROOT / "src"), MBDYN_PREFIX=str(tmp_path / "no-mbdyn"),
               PATH=os.pathsep.join([str(Path(sys.executable).parent), "/usr/bin", "/bin"]))
    done = subprocess.run([sys.executable, "-m", "rotoruq", "run", "forward_flight", "--quick",
                           "--no-report", "--out", "res"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "0 failed evaluation(s)" in done.stdout
    for step in ("multifidelity_mu01", "multifidelity_mu02"):
        assert (f"{step}   skipped (needs MBDyn, not found here: MBDyn executable not "
                "found" in done.stdout), done.stdout
        assert not (tmp_path / "res" / "steps" / step).exists()
    shown = {}
    for step in ("lhs", "sobol_mu01", "sobol_mu03"):
        out = subprocess.run([sys.executable, "-m", "rotoruq", "show", "res", step, "--json"],
                             cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr[-2000:]
        shown[step] = json.loads(out.stdout)["steps"][step]
    spread = {row[0]: row for row in shown["sobol_mu03"]["tables"][0]["rows"]}
    assert spread["power [W]"][1] > 0 and spread["collective_trim_deg"][2] > 0
    assert shown["sobol_mu01"]["n_evaluations"] == shown["sobol_mu03"]["n_evaluations"] > 0


def test_study_flight_table_is_checked(tmp_path):
    from rotoruq.errors import InputFileError
    from rotoruq.study.schema import load_study

    text = (ROOT / "src/rotoruq/studies/forward_flight.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('trim = "wind_tunnel"', 'trim = "free_flight"'))
    with pytest.raises(InputFileError, match="free_flight"):
        load_study(bad)
    bad.write_text(text.replace('"h_force"', '"roll"'))
    with pytest.raises(InputFileError, match="roll"):
        load_study(bad)


def test_study_builds_the_trimmed_forward_model():
    from rotoruq.study.runner import build_model
    from rotoruq.study.schema import load_study

    study = load_study(ROOT / "src/rotoruq/studies/forward_flight.toml")
    model = build_model(study, ["k_pitch_link"], ["power", "collective_trim_deg"],
                        dict(study.model.fixed))
    assert isinstance(model, ForwardRotorModel)
    assert (model.trim, model.inflow_model) == ("wind_tunnel", "drees")
    y = model([[15.0]])
    assert np.all(np.isfinite(y)) and model.last_solution.thrust[0] == pytest.approx(20.0)
