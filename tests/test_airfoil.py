"""Airfoil fits (thesis tables 4.3/4.4), per-sample overrides, perturbed tables, bundled tables."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rotoruq.errors import ModelShapeError, ParameterError
from rotoruq.rotor.airfoil import (
    Airfoil,
    fit_airfoil,
    mach_suffix,
    parse_parameter_name,
    read_bundled,
    write_perturbed_c81,
)
from rotoruq.rotor.c81 import C81Block, C81Table, read_c81
from rotoruq.study.cli import main

MBDYN = "data/airfoils/naca0012.c81"

CLA, CL0 = (lambda m: 0.1 + 0.02 * m), (lambda m: 0.05 - 0.01 * m)
CDA2, CDA, CD0 = (lambda m: 1e-4 * (1 + m)), (lambda m: 2e-5), (lambda m: 0.008 + 0.002 * m)


def analytic_table():
    """CL, CD exactly linear / quadratic in alpha inside +-12 deg, something else outside."""
    alpha = np.concatenate([[-180.0, -90.0, -30.0, -16.0], np.arange(-12.0, 12.5, 1.0),
                            [16.0, 30.0, 90.0, 180.0]])
    mach = np.array([0.0, 0.2, 0.4, 0.6])
    A, M = np.meshgrid(alpha, mach, indexing="ij")
    inner = np.abs(A) <= 12.0
    cl = np.where(inner, CLA(M) * A + CL0(M), np.sin(np.radians(2 * A)))
    cd = np.where(inner, CDA2(M) * A**2 + CDA(M) * A + CD0(M), 2.0 * np.sin(np.radians(A)) ** 2
                  + 0.05)
    cm = -0.1 * np.sin(np.radians(A)) * (1 + M)
    return C81Table("ANALYTIC", C81Block(mach, alpha, cl), C81Block(mach, alpha, cd),
                    C81Block(mach, alpha, cm))


# ---- names


def test_mach_suffix_and_parser():
    cases = {0.0: "m00", 0.1: "m01", 0.3: "m03", 0.75: "m075", 1.0: "m10", 0.05: "m005"}
    for m, s in cases.items():
        assert mach_suffix(m) == s
        assert parse_parameter_name(f"cla_{s}") == ("cla", m)
    assert parse_parameter_name("cda2_m075") == ("cda2", 0.75)
    for bad in ("cla_m3", "clx_m03", "cla03", "cla_m0.3"):
        with pytest.raises(ParameterError):
            parse_parameter_name(bad)
    with pytest.raises(ParameterError):
        mach_suffix(-0.1)


# ---- fits


def test_thesis_tables_4_3_and_4_4(shared_dir):
    fit = fit_airfoil(read_c81(shared_dir / MBDYN), [0.0, 0.2, 0.3, 0.4])
    # Table 4.3, to the printed digits
    assert np.round(fit.cla, 4).tolist() == [0.1055, 0.1055, 0.1080, 0.1112]
    assert np.round(fit.cl0, 3).tolist() == [0.0, 0.0, 0.008, 0.0]
    # Table 4.4, to the printed digits
    assert [float(f"{v:.2g}") for v in fit.cda2[:2]] == [9.2e-5, 9.2e-5]
    assert [float(f"{v:.4g}") for v in fit.cda2[2:]] == [1.025e-4, 1.554e-4]
    assert np.all(np.abs(fit.cda) < 1e-15)
    assert np.round(fit.cd0, 4).tolist() == [0.0079, 0.0079, 0.0077, 0.0068]
    assert fit.n_points_cl.tolist() == [11] * 4 and fit.n_points_cd.tolist() == [21] * 4


def test_fit_recovers_analytic_coefficients():
    t = analytic_table()
    for machs in ([0.0, 0.2, 0.4, 0.6], [0.1, 0.3]):  # table rows, and rows between them
        fit = fit_airfoil(t, machs)
        m = np.asarray(machs)
        np.testing.assert_allclose(fit.cla, CLA(m), rtol=1e-12)
        np.testing.assert_allclose(fit.cl0, CL0(m), rtol=1e-12)
        np.testing.assert_allclose(fit.cda2, CDA2(m), rtol=1e-9)
        np.testing.assert_allclose(fit.cda, CDA(m), rtol=1e-9)
        np.testing.assert_allclose(fit.cd0, CD0(m), rtol=1e-12)


def test_fit_needs_enough_points():
    with pytest.raises(ParameterError, match="at least"):
        fit_airfoil(analytic_table(), [0.2], alpha_range=(0.1, 0.9))


# ---- the Airfoil


def test_raw_mode_equals_mbdyn_interpolation(shared_dir):
    t = read_c81(shared_dir / MBDYN)
    af = Airfoil(t, fit_mode=False)
    assert af.parameter_names == []
    rng = np.random.default_rng(0)
    a, m = rng.uniform(-400, 400, 20000), rng.uniform(-1.2, 1.2, 20000)
    for got, block in zip(af.coefficients(a, m), (t.cl, t.cd, t.cm), strict=True):
        np.testing.assert_allclose(got, block.interpolate(a, m), rtol=0, atol=1e-12)


def test_nominal_replaces_window_with_fits(shared_dir):
    t = read_c81(shared_dir / MBDYN)
    af = Airfoil(t, fit_machs=[0.0, 0.2, 0.3, 0.4])
    fit = af.nominal
    a = np.linspace(-10, 10, 41)
    for k, m in enumerate(fit.machs):
        cl, cd, cm = af.coefficients(a, np.full_like(a, m))
        np.testing.assert_allclose(cl, fit.cla[k] * a + fit.cl0[k], atol=1e-13)
        np.testing.assert_allclose(cd, np.polyval([fit.cda2[k], fit.cda[k], fit.cd0[k]], a),
                                   atol=1e-13)
        np.testing.assert_allclose(cm, t.cm.interpolate(a, m), atol=1e-13)
    # outside the window and beyond the bridge to the next table angle: the table
    a = np.array([-40.0, -11.0, 11.0, 16.5, 90.0])
    cl, cd, _ = af.coefficients(a, np.full_like(a, 0.3))
    np.testing.assert_allclose(cl, t.cl.interpolate(a, 0.3), atol=1e-13)
    # continuity at the window edge
    eps = 1e-7
    for edge in (-10.0, 10.0):
        cl, cd, _ = af.coefficients(np.array([edge - eps, edge + eps]), 0.3)
        assert abs(cl[0] - cl[1]) < 1e-5 and abs(cd[0] - cd[1]) < 1e-5
    # Mach rows above the fits (0.5 ...) are the table
    np.testing.assert_allclose(af.coefficients(5.0, 0.6)[0], t.cl.interpolate(5.0, 0.6))


def test_overrides_per_sample():
    t = analytic_table()
    af = Airfoil(t, fit_machs=[0.2, 0.3])  # 0.3 is inserted between table rows 0.2 and 0.4
    n, p = 50, 7
    rng = np.random.default_rng(4)
    ov = {"cla_m03": rng.uniform(0.08, 0.14, n), "cd0_m02": rng.uniform(0.005, 0.02, n),
          "cl0_m02": 0.01}
    a = rng.uniform(-9.5, 9.5, (n, p))
    nom = af.nominal
    # at the fit rows: the overridden polynomial, sample by sample
    cl, cd, _ = af.coefficients(a, np.full((n, p), 0.3), ov)
    np.testing.assert_allclose(cl, ov["cla_m03"][:, None] * a + nom.cl0[1], atol=1e-12)
    cl, cd, _ = af.coefficients(a, 0.2, ov)
    np.testing.assert_allclose(cl, nom.cla[0] * a + 0.01, atol=1e-12)
    np.testing.assert_allclose(cd, nom.cda2[0] * a**2 + nom.cda[0] * a
                               + ov["cd0_m02"][:, None], atol=1e-12)
    # between Mach 0.2 and 0.3: linear in Mach
    cl25 = af.coefficients(a, 0.25, ov)[0]
    mid = 0.5 * (af.coefficients(a, 0.2, ov)[0] + af.coefficients(a, 0.3, ov)[0])
    np.testing.assert_allclose(cl25, mid, atol=1e-12)
    # between 0.3 (fit row) and 0.4 (table row): the table column at 0.4 weighs in
    cl35 = af.coefficients(a, 0.35, ov)[0]
    np.testing.assert_allclose(
        cl35, 0.5 * (ov["cla_m03"][:, None] * a + nom.cl0[1]) + 0.5 * (CLA(0.4) * a + CL0(0.4)),
        atol=1e-12)
    # far outside the window the overrides do not matter
    far = np.full((n, p), 60.0)
    np.testing.assert_allclose(af.coefficients(far, 0.3, ov)[0], af.coefficients(far, 0.3)[0])
    # scalar overrides equal constant arrays
    s1 = af.coefficients(a, 0.27, {"cla_m03": 0.11})
    s2 = af.coefficients(a, 0.27, {"cla_m03": np.full(n, 0.11)})
    for x, y in zip(s1, s2, strict=True):
        np.testing.assert_allclose(x, y, atol=1e-15)
    # NaN in one sample does not spoil the others
    bad = dict(ov, cla_m03=np.where(np.arange(n) == 3, np.nan, ov["cla_m03"]))
    cl = af.coefficients(a, 0.3, bad)[0]
    assert np.all(np.isnan(cl[3])) and np.all(np.isfinite(np.delete(cl, 3, axis=0)))


def test_override_errors():
    af = Airfoil(analytic_table(), fit_machs=[0.2])
    with pytest.raises(ParameterError) as e:
        af.coefficients(0.0, 0.2, {"cla_m03": 0.1})
    assert "cla_m02" in str(e.value) and "cd0_m02" in str(e.value)
    with pytest.raises(ModelShapeError):
        af.coefficients(np.zeros((4, 3)), 0.2, {"cla_m02": np.ones(5)})
    with pytest.raises(ModelShapeError):
        af.coefficients(np.zeros((4, 3)), 0.2, {"cla_m02": np.ones(4), "cd0_m02": np.ones(3)})


def test_perturbed_table_matches_coefficients(tmp_path):
    t = analytic_table()
    af = Airfoil(t, fit_machs=[0.2, 0.3], alpha_window=10.0)
    ov = {"cla_m03": 0.13, "cd0_m02": 0.011, "cda2_m03": 3e-4}
    pt = af.perturbed_table(ov)
    np.testing.assert_array_equal(pt.cl.mach, [0.0, 0.2, 0.3, 0.4, 0.6])
    raw = Airfoil(pt, fit_mode=False)
    rng = np.random.default_rng(5)
    a, m = rng.uniform(-180, 180, 4000), rng.uniform(0, 0.7, 4000)
    np.testing.assert_allclose(raw.coefficients(a, m)[0], af.coefficients(a, m, ov)[0],
                               atol=1e-12)
    # CD agrees on the table's angles (a solver sees the quadratic as a polygon between them)
    ag = np.repeat(pt.cd.alpha, 3)
    mg = np.tile([0.2, 0.25, 0.3], pt.cd.alpha.size)
    np.testing.assert_allclose(raw.coefficients(ag, mg)[1], af.coefficients(ag, mg, ov)[1],
                               atol=1e-12)
    # the written file holds the same numbers to the written precision, and refits to ov
    back = read_c81(write_perturbed_c81(af, ov, tmp_path / "p.c81"))
    np.testing.assert_allclose(back.cl.values, pt.cl.values, atol=5e-5)
    refit = fit_airfoil(back, [0.2, 0.3])
    assert refit.cla[1] == pytest.approx(0.13, abs=1e-5)
    assert refit.cd0[0] == pytest.approx(0.011, abs=1e-5)
    assert refit.cda2[1] == pytest.approx(3e-4, rel=1e-3)


def test_coefficients_speed_smoke():
    # correctness on a large batch (timing is in benchmarks, not here)
    af = Airfoil(analytic_table(), fit_machs=[0.2, 0.3])
    n = 2000
    a = np.random.default_rng(6).uniform(-9, 9, (n, 100))
    ov = {"cla_m02": np.linspace(0.09, 0.12, n)}
    cl = af.coefficients(a, 0.2, ov)[0]
    np.testing.assert_allclose(cl, ov["cla_m02"][:, None] * a + af.nominal.cl0[0], atol=1e-12)


# ---- bundled tables


@pytest.mark.parametrize("name", ["naca0012", "naca23012"])
def test_bundled_tables(name):
    t = read_bundled(name)
    for b in t.blocks().values():
        assert b.alpha[0] == -180.0 and b.alpha[-1] == 180.0
        assert b.mach[0] == 0.0 and b.mach[-1] >= 0.7
    af = Airfoil.bundled(name, fit_machs=[0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    for m in (0.1, 0.2, 0.3, 0.4, 0.5, 0.6):
        # secant slope over +-4 deg vs thin-airfoil 2 pi / beta: within 25 % (viscous, low Re)
        cl = t.cl.interpolate(np.array([-4.0, 4.0]), m)
        slope = (cl[1] - cl[0]) / np.radians(8.0)
        assert slope == pytest.approx(2 * np.pi / np.sqrt(1 - m * m), rel=0.25)
    cd90 = t.cd.interpolate(90.0, np.array([0.0, 0.3, 0.7]))
    assert np.all((cd90 > 1.6) & (cd90 < 2.2))
    cd0 = t.cd.interpolate(0.0, np.array([0.2, 0.4]))
    assert np.all((cd0 > 0.004) & (cd0 < 0.015))
    assert np.all(np.abs(t.cl.interpolate(np.array([-180.0, 0.0 if name == "naca0012" else 180.0]),
                                          0.3)) < 1e-9)
    assert af.nominal.cla.min() > 0.09


# ---- command line


def test_cli_fit_json(shared_dir, capsys):
    assert main(["airfoil", "fit", str(shared_dir / MBDYN), "--mach", "0", "0.2", "0.3", "0.4",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [round(v, 4) for v in out["cla_per_deg"]] == [0.1055, 0.1055, 0.108, 0.1112]
    assert round(out["parameters"]["cd0_m04"], 4) == 0.0068


def test_cli_fit_table_and_write(tmp_path, capsys):
    assert main(["airfoil", "fit", "naca0012", "--mach", "0.3"]) == 0
    assert "CL_alpha" in capsys.readouterr().out
    out = tmp_path / "o.c81"
    assert main(["airfoil", "write", "naca23012", "--set", "cla_m03=0.11", "cd0_m02=0.009",
                 "-o", str(out)]) == 0
    fit = fit_airfoil(read_c81(out), [0.2, 0.3])
    assert fit.cla[1] == pytest.approx(0.11, abs=1e-4)
    assert fit.cd0[0] == pytest.approx(0.009, abs=1e-4)
    assert main(["airfoil", "write", "naca23012", "--set", "clx_m03=1", "-o", str(out)]) == 1


def test_perturbed_table_keeps_tabulated_cd_when_fits_replace_cl_only():
    """The Bo105 study rewrote CL only: an external solver must see the table's own CD, as the
    built-in model does (CD rewritten at the fit rows moved MBDyn's Bo105 torque by 10-60 %)."""
    t = analytic_table()
    af = Airfoil(t, fit_machs=[0.2, 0.3], alpha_window=10.0, replace=("cl",))
    pt = af.perturbed_table({"cla_m03": 0.13})
    assert pt.cd is t.cd
    raw = Airfoil(pt, fit_mode=False)
    rng = np.random.default_rng(6)
    a, m = rng.uniform(-180, 180, 2000), rng.uniform(0, 0.7, 2000)
    np.testing.assert_allclose(raw.coefficients(a, m)[:2], af.coefficients(
        a, m, {"cla_m03": np.full(2000, 0.13)})[:2], atol=1e-12)
