"""Rotor model vs analytic blade-element/momentum results and physical trends.

Analytic cases use :class:`LinearAirfoil` (CL = a alpha, CD = cd0, no stall) so that the
closed forms hold; tolerances are 1 % (the model keeps the exact inflow angle and |U|^2,
the closed forms are small-angle).
"""

import numpy as np
import pytest

import rotoruq as rq
from rotoruq.errors import ParameterError
from rotoruq.rotor.aero import LinearAirfoil
from rotoruq.rotor.ground_effect import ground_effect_factor
from rotoruq.rotor.model import RotorModel
from rotoruq.rotor.presets import bo105, gvpm

A_RAD = 5.7  # lift slope [1/rad]
LIN = LinearAirfoil(cla=A_RAD * np.pi / 180, cl0=0.0, cd0=0.01)


def rigid_gvpm(**kw):
    """Untwisted GVPM rotor with a rigid pitch link and no cyclic, without the tip loss of
    the preset (the closed forms have none)."""
    kw = {"tip_loss": False, **kw}
    return gvpm(k_pitch_link=1e12, lateral_deg=0.0, longitudinal_deg=0.0,
                height_over_radius=np.inf, **kw)


def closed_form_uniform(p, theta_deg, cd0):
    """Small-angle BE + uniform momentum: thrust, torque, induced velocity."""
    th = np.deg2rad(theta_deg)
    rho, Om, R, r0, c, Nb = p.rho, p.omega, p.radius, p.root_cutout, p.chord, p.n_blades
    k = Nb * 0.5 * rho * c * A_RAD * Om**2
    a3, a2 = (R**3 - r0**3) / 3, (R**2 - r0**2) / 2
    # T = k (th a3 - (v/Om) a2) = 2 rho A v^2
    A = np.pi * R**2
    qa, qb, qc = 2 * rho * A, k * a2 / Om, -k * th * a3
    v = (-qb + np.sqrt(qb**2 - 4 * qa * qc)) / (2 * qa)
    T = 2 * rho * A * v**2
    Q = Nb * 0.5 * rho * c * Om**2 * (
        A_RAD * th * (v / Om) * a3 - A_RAD * (v / Om) ** 2 * a2 + cd0 * (R**4 - r0**4) / 4)
    return T, Q, v


@pytest.mark.parametrize("theta", [3.0, 6.0, 9.0])
def test_uniform_inflow_matches_closed_form(theta):
    p = rigid_gvpm(harmonic_inflow=False)
    m = RotorModel(p, airfoil=LIN, names_in=["collective_deg"], names_out=["thrust", "torque"])
    T, Q = m([[theta]])[0]
    T0, Q0, _ = closed_form_uniform(p, theta, 0.01)
    assert T == pytest.approx(T0, rel=0.01)
    assert Q == pytest.approx(Q0, rel=0.01)


def test_induced_power_at_momentum_limit():
    """With no profile drag, P = T v = T^1.5 / sqrt(2 rho A) (ideal induced power)."""
    p = rigid_gvpm(harmonic_inflow=False)
    af = LinearAirfoil(cla=A_RAD * np.pi / 180, cd0=0.0)
    m = RotorModel(p, airfoil=af, names_in=["collective_deg"], names_out=["thrust", "power"])
    (T, P), = m([[6.0]])
    assert P == pytest.approx(T**1.5 / np.sqrt(2 * p.rho * p.area), rel=0.01)


def test_bemt_matches_annulus_closed_form():
    """Untwisted blade, BEMT without losses: lambda(x) = s a/16 (sqrt(1 + 32 th x/(s a)) - 1)."""
    p = rigid_gvpm(harmonic_inflow=False, inflow="bemt")
    m = RotorModel(p, airfoil=LIN, names_in=["collective_deg"], names_out=["thrust"],
                   n_stations=24)
    th = np.deg2rad(7.0)
    T = m([[7.0]])[0, 0]
    s, R = p.solidity, p.radius
    x = np.linspace(p.root_cutout / R, 1, 4001)
    lam = s * A_RAD / 16 * (np.sqrt(1 + 32 * th * x / (s * A_RAD)) - 1)
    dct = 0.5 * s * A_RAD * (th * x**2 - lam * x)
    ct = np.trapezoid(dct, x)
    T0 = ct * p.rho * p.area * (p.omega * R) ** 2
    assert T == pytest.approx(T0, rel=0.01)


def test_tip_loss_reduces_thrust():
    base = rigid_gvpm(harmonic_inflow=False, inflow="bemt")
    t_plain = RotorModel(base, airfoil=LIN, names_out=["thrust"])([[6, 0, 0]])[0, 0]
    t_loss = RotorModel(base.replace(tip_loss=True), airfoil=LIN, names_out=["thrust"])(
        [[6, 0, 0]])[0, 0]
    assert 0.85 * t_plain < t_loss < t_plain


@pytest.mark.parametrize("model", ["cheeseman_bennett", "hayden", "none"])
def test_ground_effect_factor_formulas(model):
    h = np.array([4.0, 3.0, 2.0, 1.0])
    k = ground_effect_factor(h, model)
    expected = {
        "cheeseman_bennett": 1 - (1 / (4 * h)) ** 2,
        "hayden": np.minimum(1 / (0.9926 + 0.0379 * (2 / h) ** 2), 1.0),
        "none": np.ones(4),
    }[model]
    np.testing.assert_allclose(k, expected, rtol=1e-12)
    assert ground_effect_factor(np.inf, model) == 1.0


def test_model_inflow_follows_ground_effect_factor():
    p = rigid_gvpm(harmonic_inflow=False)
    m = RotorModel(p, airfoil=LIN, names_in=["collective_deg", "height_over_radius"],
                   names_out=["thrust"])
    h = np.array([4.0, 3.0, 2.0, 1.0])
    x = np.column_stack([np.full(4, 6.0), h])
    sol = m.solve(x)
    v = sol.inflow_ratio * p.omega * p.radius
    v_oge = np.sqrt(sol.thrust / (2 * p.rho * p.area))
    np.testing.assert_allclose(v / v_oge, ground_effect_factor(h), rtol=1e-6)
    assert np.all(np.diff(sol.thrust) > 0)  # closer to the ground, more thrust


def test_no_cyclic_gives_zero_hub_moments():
    m = RotorModel("gvpm", airfoil=LIN, names_out=["thrust", "roll", "pitch"])
    T, roll, pitch = m([[6.0, 0.0, 0.0]])[0]
    assert abs(roll) < 1e-9 * T * 0.485 and abs(pitch) < 1e-9 * T * 0.485


def test_cyclic_produces_moments_with_sign():
    m = RotorModel("gvpm", airfoil=LIN, names_out=["roll", "pitch"])
    y = m([[5.0, 1.0, 0.0], [5.0, -1.0, 0.0], [5.0, 0.0, 1.0], [5.0, 0.0, -1.0]])
    np.testing.assert_allclose(y[0], -y[1], rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(y[2], -y[3], rtol=1e-5, atol=1e-9)
    assert np.hypot(*y[0]) > 0.1 and np.hypot(*y[2]) > 0.1


def test_thrust_rises_with_collective_and_lift_slope():
    m = RotorModel("gvpm", airfoil=LIN, names_in=["collective_deg", "cla"], names_out=["thrust"])
    t = m([[4.0, 0.1], [5.0, 0.1], [6.0, 0.1], [6.0, 0.11]])[:, 0]
    assert t[0] < t[1] < t[2] < t[3]


def test_stiffer_pitch_link_moves_toward_rigid():
    m = RotorModel("gvpm", airfoil=LIN, names_in=["collective_deg", "k_pitch_link"],
                   names_out=["thrust", "torque"])
    y = m([[5.4, 10.0], [5.4, 15.0], [5.4, 100.0], [5.4, 1e4], [5.4, 1e9]])
    assert np.all(np.diff(y[:, 0]) > 0)
    assert abs(y[3, 0] - y[4, 0]) < 0.01 * y[4, 0]
    sol = m.solve([[5.4, 15.0], [5.4, 1e9]])
    assert sol.theta_75_deg[0] < sol.theta_75_deg[1] == pytest.approx(5.4, abs=1e-6)


def test_periodic_convergence_is_reached():
    """A step tolerance of 1e-5 rad on the blade pitch (about 0.1 deg collective) is about
    2e-4 of it: the loose solution's thrust agrees to that order (5e-4)."""
    m = RotorModel("gvpm", airfoil=LIN, tolerance=1e-10)
    sol = m.solve([[5.0, -1.0, -1.0], [6.0, 1.5, -0.5]])
    assert np.all(sol.converged) and np.all(sol.residual < 1e-10)
    loose = RotorModel("gvpm", airfoil=LIN, tolerance=1e-5).solve([[5.0, -1.0, -1.0]])
    assert loose.thrust[0] == pytest.approx(sol.thrust[0], rel=5e-4)


def test_batch_equals_one_at_a_time():
    m = RotorModel("gvpm", airfoil=LIN)
    x = np.array([[4.5, -1, 0.5], [5.5, 0.3, -1.2], [7.0, 1.0, 1.0]])
    batch = m(x)
    single = np.vstack([m(row[None]) for row in x])
    np.testing.assert_allclose(batch, single, rtol=1e-7)


def test_bad_inputs_give_nan_rows_with_reasons():
    m = RotorModel("gvpm", airfoil=LIN, names_in=["collective_deg", "k_pitch_link",
                                                "height_over_radius"], names_out=["thrust"])
    out = rq.evaluate(m, [[5, 15, 4], [5, -3, 4], [5, 15, 0.2], [np.nan, 15, 4]])
    assert np.isfinite(out.values[0, 0])
    assert "k_pitch_link must be >= 0" in out.failures[1]
    assert "below R/4" in out.failures[2]
    assert "collective_deg is nan" in out.failures[3]
    assert np.all(np.isnan(out.values[1:]))


def test_unknown_names_are_errors():
    with pytest.raises(ParameterError, match="did you mean 'k_pitch_link'"):
        RotorModel("gvpm", airfoil=LIN, names_in=["k_pitchlink"])
    with pytest.raises(ParameterError, match="unknown response"):
        RotorModel("gvpm", airfoil=LIN, names_out=["lift"])
    with pytest.raises(ParameterError, match="elastic blades"):
        RotorModel("gvpm", airfoil=LIN, names_in=["k_flap"])
    with pytest.raises(ParameterError, match="unknown rotor preset"):
        RotorModel("bo106", airfoil=LIN)


def test_bo105_preset_geometry():
    p = bo105()
    assert p.radius - p.root_cutout == pytest.approx(3.812)
    assert p.blade_mass_per_length * (p.radius**3 - p.hinge_offset**3) / 3 == pytest.approx(140.001)


def test_cl_only_replacement_keeps_table_drag():
    """Bo105 rewrites CL only (thesis 3.1.1): drag names are not parameters, drag is the table."""
    from rotoruq.rotor.airfoil import Airfoil

    both = Airfoil.bundled("naca23012", fit_machs=(0.3,))
    cl_only = Airfoil.bundled("naca23012", fit_machs=(0.3,), replace=("cl",))
    raw = Airfoil.bundled("naca23012", fit_mode=False)
    assert "cd0_m03" in both.parameter_names and "cd0_m03" not in cl_only.parameter_names
    a, m = np.array([0.0, 3.0]), np.array([0.3, 0.3])
    np.testing.assert_allclose(cl_only.coefficients(a, m)[1], raw.coefficients(a, m)[1])
    np.testing.assert_allclose(cl_only.coefficients(a, m)[0], both.coefficients(a, m)[0])
    with pytest.raises(ParameterError, match="unknown airfoil parameter"):
        cl_only.coefficients(a[None], m[None], {"cd0_m03": np.array([0.01])})


def test_presets_with_bundled_tables_converge():
    y = RotorModel("gvpm", names_out=["thrust", "torque", "roll", "pitch"])(
        [[5.4, 0.17, -0.3], [5.0, -1.0, -1.0], [8.0, 2.0, 2.0]])
    assert np.all(np.isfinite(y)) and np.all(y[:, 0] > 10)
    t = RotorModel("bo105", names_out=["thrust"])([[6.0, 0.0, -2.0]])[0, 0]
    assert 1000 < t < 10000
