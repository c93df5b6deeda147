"""The forward-flight trims (issue 38, items 2 and 3): hub-moment trim against the physics of
the hub, its failures, and the coupled Jacobian's agreement with the block iteration."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from rotoruq.errors import ParameterError
from rotoruq.rotor.forward import ForwardRotorModel

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import forward_flight_verification as ffv  # noqa: E402

OUT = ["thrust", "beta_1c_deg", "beta_1s_deg", "roll_moment", "pitch_moment",
       "collective_trim_deg", "lateral_trim_deg", "longitudinal_trim_deg"]
THRUST = 10_000.0   # [N]: C_T / sigma ~ 0.07 for the classical rotor at Omega R = 150 m/s


def _classical(trim, k_flap, **fixed):
    """The verification's centrally hinged rotor (no hinge offset), flap spring k_flap."""
    preset = dataclasses.replace(ffv.classical_rotor(), k_flap=k_flap)
    return ForwardRotorModel(preset, names_in=["advance_ratio"], names_out=OUT,
                             airfoil=ffv.linear_airfoil(), trim=trim, tolerance=1e-11,
                             fixed={"thrust_target": THRUST, "shaft_angle_deg": 4.0, **fixed})


def test_hub_moment_trim_of_a_hingeless_rotor_is_the_flap_spring_times_the_flapping():
    # no hinge offset: the hub moment is the flap spring's, N_b / 2 K_beta x the flapping
    # (roll = -N_b/2 K_b beta_1s, pitch = -N_b/2 K_b beta_1c): the trim to given moments
    # flaps the disk by exactly that much
    k_b, roll, pitch = 20_000.0, 300.0, -200.0
    m = _classical("hub_moments", k_b, roll_moment_target=roll, pitch_moment_target=pitch)
    y = m([[0.1], [0.2], [0.3]])
    assert np.all(np.isfinite(y)), m.last_solution.failure
    np.testing.assert_allclose(y[:, 0], THRUST, rtol=1e-9)
    np.testing.assert_allclose(y[:, 3], roll, rtol=1e-8)
    np.testing.assert_allclose(y[:, 4], pitch, rtol=1e-8)
    n_b = ffv.classical_rotor().n_blades
    np.testing.assert_allclose(np.deg2rad(y[:, 2]), -2 * roll / (n_b * k_b), rtol=1e-7)
    np.testing.assert_allclose(np.deg2rad(y[:, 1]), -2 * pitch / (n_b * k_b), rtol=1e-7)


def test_zero_hub_moments_and_zero_flapping_trim_coincide_without_hinge_offset():
    hub = _classical("hub_moments", 20_000.0)([[0.2]])
    tunnel = _classical("wind_tunnel", 20_000.0)([[0.2]])
    # the same state: controls to 1e-8 deg, flapping 0 (to the tolerance) in both
    np.testing.assert_allclose(hub[0, 5:], tunnel[0, 5:], atol=1e-8)
    np.testing.assert_allclose(hub[0, 1:5], 0.0, atol=1e-8)


def test_a_hub_that_transmits_no_moment_cannot_trim_to_hub_moments():
    res = _classical("hub_moments", 0.0).evaluate([[0.2]])
    assert "hub moments do not depend on the flapping" in res.failures[0]
    assert "trim='wind_tunnel'" in res.failures[0]
    assert not _classical("wind_tunnel", 0.0).evaluate([[0.2]]).failures


def test_gvpm_trims_to_hub_moments_with_its_hinge_offset():
    m = ForwardRotorModel("gvpm", names_in=["advance_ratio", "roll_moment_target",
                                           "pitch_moment_target"], names_out=OUT,
                          trim="hub_moments", tolerance=1e-11,
                          fixed={"thrust_target": 20.0, "shaft_angle_deg": 3.0})
    x = np.array([[0.1, 0.0, 0.0], [0.2, 0.5, -0.3], [0.3, -0.2, 0.4]])
    y = m(x)
    assert np.all(np.isfinite(y)), m.last_solution.failure
    np.testing.assert_allclose(y[:, 0], 20.0, rtol=1e-9)
    np.testing.assert_allclose(y[:, 3:5], x[:, 1:], atol=1e-8)
    # zero moments with a hinge offset: the flapping is not zero (the hinge shear's moment)
    assert np.all(np.abs(y[0, 1:3]) > 1e-4)


def test_the_coupled_trim_converges_in_a_few_iterations():
    # the periodic coefficients of forward flight are in the Jacobian: the trim converges
    # like hover (before: the error halved per iteration, 24 iterations at mu = 0.2)
    m = ForwardRotorModel("gvpm", names_in=["advance_ratio", "thrust_target"],
                          names_out=["thrust"], trim="wind_tunnel",
                          fixed={"shaft_angle_deg": 3.0})
    m(np.column_stack([np.full(8, 0.2), np.linspace(18.0, 28.0, 8)]))
    assert np.max(m.last_solution.iterations) <= 12


@pytest.mark.parametrize(("kwargs", "message"), [
    (dict(trim="hub_moments"), "needs 'thrust_target'"),
    (dict(trim="wind_tunnel", fixed={"thrust_target": 20.0, "roll_moment_target": 1.0}),
     "'roll_moment_target' is the hub-moment trim's target"),
    (dict(names_in=["pitch_moment_target"]), "hub-moment trim's target"),
])
def test_bad_hub_moment_options_are_named(kwargs, message):
    with pytest.raises(ParameterError, match=message):
        ForwardRotorModel("gvpm", **kwargs)
