"""The MBDyn templates' verification (scripts/mbdyn_verification.py): its beam theory and decay
fit against closed forms, and its MBDyn checks run in quick mode from a fresh folder."""

from __future__ import annotations

import importlib.util
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from test_mbdyn import env_with_mbdyn, needs_mbdyn

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "mbdyn_verification.py"
_spec = importlib.util.spec_from_file_location("mbdyn_verification", SCRIPT)
assert _spec and _spec.loader
V = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(V)


def test_beam_theory_matches_the_cantilever_and_southwell():
    # non-rotating uniform cantilever: omega = 1.8751^2 sqrt(EI / (m L^4)); slowly rotating,
    # no hub offset: omega^2 = omega_0^2 + 1.193 Omega^2 (Southwell's coefficient, the
    # Rayleigh quotient of the non-rotating mode: exact as Omega -> 0)
    ei, m, L = 7.0, 0.0588, 0.425
    w0 = V.rotating_beam(ei, m, 0.0, L, 0.0)
    assert w0 == pytest.approx(1.8751040687**2 * math.sqrt(ei / (m * L**4)), rel=1e-4)
    om = 0.05 * w0
    k1 = (V.rotating_beam(ei, m, 0.0, L, om) ** 2 - w0**2) / om**2
    assert k1 == pytest.approx(1.193, abs=1e-3)
    # in plane the centrifugal term loses Omega^2
    lag = V.rotating_beam(ei, m, 0.0, L, om, inplane=True)
    assert lag**2 == pytest.approx(V.rotating_beam(ei, m, 0.0, L, om) ** 2 - om**2, rel=1e-9)


def test_static_deflection_matches_the_cantilever_under_uniform_load():
    # q L^4 / (8 EI), non-rotating
    assert V.rotating_beam(7.0, 0.0588, 0.0, 0.425, 0.0, load=lambda x: 3.0) == pytest.approx(
        3.0 * 0.425**4 / (8 * 7.0), rel=1e-6)


def test_torsion_matches_the_shaft_on_a_root_spring():
    # uniform shaft, free tip, root spring k: phi = cos(b (L - x)), b tan(b L) = k / GJ,
    # omega^2 = (GJ b^2 + prop Omega^2 I_p) / I_p
    from scipy.optimize import brentq

    gj, i_p, L, k, om = 2.0, 1e-5, 0.4, 0.5, 200.0
    b = brentq(lambda b: b * math.tan(b * L) - k / gj, 1e-9, 0.5 * math.pi / L - 1e-9)
    exact = (gj * b**2 + 0.99 * om**2 * i_p) / i_p
    assert V.rotating_torsion(gj, i_p, 0.99, k, L, om, n_el=80) ** 2 == pytest.approx(
        exact, rel=1e-4)


def test_decay_fit_recovers_frequency_and_damping():
    wn, zeta = 300.0, 0.15
    wd = wn * math.sqrt(1 - zeta**2)
    t = np.arange(0, 0.1, 1e-4)
    y = 2e-3 * np.exp(-zeta * wn * t) * np.cos(wd * t + 0.3)
    w_fit, z_fit = V.fit_decay(t, y)
    assert w_fit == pytest.approx(wn, rel=1e-6) and z_fit == pytest.approx(zeta, rel=1e-5)


def test_flap_phase_lag_sign():
    # beta = cos(psi - 30 deg) lags theta = cos(psi) by 30 deg
    lag = math.radians(30)
    assert V.phase_lag_deg((1.0, 0.0), (math.cos(lag), math.sin(lag))) == pytest.approx(30.0)


@needs_mbdyn
@pytest.mark.slow
def test_quick_run_verifies_the_templates(tmp_path):
    done = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--out", "v.json"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600,
                          env=env_with_mbdyn())
    assert done.returncode == 0, done.stderr[-3000:]
    # what tests/test_docs.py's smoke run of the scripts asks of every other one (it leaves
    # this script to this run: two MBDyn verifications would cost 30 CPU-s more)
    assert done.stdout.strip(), "mbdyn_verification.py --quick printed nothing"
    res = json.loads((tmp_path / "v.json").read_text())
    modes = res["frequencies"]["modes"]
    by_ref = {(m, c["reference"]): c for m, v in modes.items() for c in v["checks"]}
    # the elastic blade's flap and torsion against beam theory, flap also the equivalent hinge
    for key in [("flap", "beam theory"), ("torsion", "beam theory"),
                ("flap", "built-in equivalent hinge"), ("torsion", "built-in equivalent hinge")]:
        assert by_ref[key]["passed"], by_ref[key]
    for key in ("coning", "lag"):  # the statics against beam theory
        c = res["hover"]["checks"][key][0]
        assert c["reference"].startswith("beam theory") and c["passed"], c
    assert all(c["passed"] for c in res["hover"]["checks"]["flap_phase"])
    pitch = {c["reference"]: c for c in res["hover"]["checks"]["pitch"]}
    # the feathering equilibrium in vacuo; without the table's CM the pitch follows the command
    for key in ("swashplate: 1/rev amplitude / command",  # the command convention
                "swashplate: 1/rev lag behind command",
                "in vacuo: link against propeller moment",
                "air, no table CM: 1/rev amplitude / command"):
        assert pitch[key]["passed"], pitch[key]
    for c in res["loads"]["rigid"]["checks"]:
        assert c["passed"], c
    # the airfoil's a.c. brings the built-in model to MBDyn's thrust within the load tolerance
    ac = res["aero_center_offset"]["cases"]["airfoil CM slope"]
    assert abs(ac["thrust_vs_mbdyn_pct"]) < res["tolerances"]["elastic_vs_builtin_loads"]
    assert V.summary(res).count("| elastic: flap frequency") == 2
