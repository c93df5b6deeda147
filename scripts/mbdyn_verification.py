"""Verification of the MBDyn GVPM templates against beam theory and the built-in rotor (JSON).

    python scripts/mbdyn_verification.py [--out scripts/results/mbdyn_verification.json]
    python scripts/mbdyn_verification.py --quick      # shorter MBDyn runs: a smoke run
    python scripts/mbdyn_verification.py --summary scripts/results/mbdyn_verification.json

About two minutes on 2 cores (9 MBDyn runs). Needs MBDyn ($MBDYN, PATH, or
~/.cache/mbdyn/bin/mbdyn); without it the JSON says ``skipped``.

Sections (each check: MBDyn's value, the reference, the difference and pass/fail against the
stated tolerance):

- ``frequencies``: the elastic template's first flap, lag and torsion frequencies [/rev] from
  three free-decay runs in vacuo (the template filled with rho = 1e-6 kg/m^3, the pitch-link
  damping off, a force or couple on blade 1 held for half a revolution then released; a damped
  sinusoid fitted to the tip's motion in the hub frame, omega_n = sqrt(omega_d^2 + sigma^2)),
  against beam theory for the template's EI_y, EI_z, GJ and mass (a finite-element solution of
  the rotating uniform beam clamped at the hub radius, checked here against the non-rotating
  cantilever root 1.8751 and the Southwell coefficient 1.193) and against the equivalent
  hinges of the built-in model (nu_beta^2 = 1 + e S / I + K_b / (I Omega^2), K_b = 4.12 EI/L;
  nu_theta^2 = 1 + K_theta / (I_p Omega^2)). The rigid template has no blade modes (clamped).
- ``hover``: the elastic template in axisymmetric hover (collective 5 deg, K_p 15 N/m, 4R):
  blade 1's mean tip flap and lag displacement (as equivalent-hinge angles asin(w / L)) against
  the static deflection of the rotating beam with pitched principal axes under the lift and
  drag of MBDyn's own thrust, torque and inflow, the equivalent-hinge moment balance and the
  built-in model; at the thesis's operating point (cyclic -1, -1 deg) the lag of the 1/rev flap
  behind the pitch; the mean pitch in vacuo against the feathering
  equilibrium sin(theta) = K sin(theta_0) / (K + 0.99 I_p Omega^2), its rise in air (the table's
  CM zeroed) against the drag acting on the coned blade above the feathering axis, and the
  1/rev pitch against the swashplate command with and without the table's CM.
- ``loads``: thrust and power of the rigid template against the built-in model on identical
  physics (:func:`rotoruq.mbdyn.rigid_equivalent`), and of the elastic template against the
  built-in ``gvpm`` preset and against the preset with MBDyn's aerodynamic-centre physics
  (a.c. on the feathering axis, the table's pitching moment).
- ``aero_center_offset``: the built-in model's loads, coning, mean pitch and flap phase with the
  preset's 1 mm, without it, and at the value the bundled airfoil's CM slope gives
  (x_ac - c/4 = -c dCM/dCL, lift-weighted over the span's Mach numbers).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results" / "mbdyn_verification.json"
# thesis section 4.3 operating point, K_p of the thesis's calibration (as benchmarks/mbdyn_parity)
OP = {"omega": 224.6375, "collective_deg": 5.0, "lateral_deg": -1.0, "longitudinal_deg": -1.0,
      "k_pitch_link": 15.0, "height_over_radius": 4.0}
# tolerances [%] (absolute [deg] for the phase): stated once, used by every check
TOL = {"beam_theory_frequency": 2.0, "beam_theory_lag_frequency": 3.0,
       "equivalent_hinge_frequency": 5.0, "beam_static_coning": 5.0,
       "equivalent_hinge_coning": 15.0, "pitched_beam_lag": 10.0, "builtin_lag": 50.0,
       "identical_physics_loads": 0.5, "elastic_vs_builtin_loads": 5.0,
       "flap_phase_deg": 10.0, "pitch_in_vacuo": 1.0, "coning_pitch_moment": 30.0,
       "pitch_1rev_amplitude": 5.0, "swashplate_amplitude": 1.0, "swashplate_phase_deg": 1.0}
#: Southwell coefficient of the first flap mode of a uniform cantilever, no hub offset, as
#: Omega -> 0 (the Rayleigh quotient of the non-rotating mode; Bramwell, Helicopter Dynamics)
SOUTHWELL_1 = 1.193
CANTILEVER_ROOT = 1.8751040687


# --------------------------------------------------------------------------------------------
# beam theory: the rotating uniform beam by finite elements
def _hermite(n_el, e, R):
    """Nodes and element lengths of a uniform mesh on [e, R]."""
    x = np.linspace(e, R, n_el + 1)
    return x, np.diff(x)


def beam_matrices(ei, m, e, R, omega, n_el=40, inplane=False, loads=()):
    """Stiffness K, mass M (free degrees of freedom: the root at radius ``e`` clamped) and the
    consistent load vector of each callable in ``loads`` (force per length [N/m] at radius x)
    of a uniform beam rotating at ``omega``: bending EI, centrifugal tension
    m Omega^2 (R^2 - x^2) / 2, in plane also -m Omega^2. Hermite cubic elements, 4-point Gauss
    quadrature; degrees of freedom (w, w') per node, the tip's deflection last but one."""
    x, h = _hermite(n_el, e, R)
    ndof = 2 * (n_el + 1)
    K = np.zeros((ndof, ndof))
    M = np.zeros((ndof, ndof))
    F = np.zeros((len(loads), ndof))
    gp, gw = np.polynomial.legendre.leggauss(4)
    for k, hk in enumerate(h):
        idx = slice(2 * k, 2 * k + 4)
        ke = ei / hk**3 * np.array([[12, 6 * hk, -12, 6 * hk],
                                    [6 * hk, 4 * hk**2, -6 * hk, 2 * hk**2],
                                    [-12, -6 * hk, 12, -6 * hk],
                                    [6 * hk, 2 * hk**2, -6 * hk, 4 * hk**2]])
        kg = np.zeros((4, 4))
        me = np.zeros((4, 4))
        for s, w in zip(0.5 * (gp + 1), 0.5 * gw, strict=True):
            xs = x[k] + s * hk
            n = np.array([1 - 3 * s**2 + 2 * s**3, hk * (s - 2 * s**2 + s**3), 3 * s**2 - 2 * s**3,
                          hk * (-s**2 + s**3)])
            dn = np.array([-6 * s + 6 * s**2, hk * (1 - 4 * s + 3 * s**2), 6 * s - 6 * s**2,
                           hk * (-2 * s + 3 * s**2)]) / hk
            tension = m * omega**2 * (R**2 - xs**2) / 2
            kg += w * hk * tension * np.outer(dn, dn)
            me += w * hk * m * np.outer(n, n)
            for j, load in enumerate(loads):
                F[j, idx] += w * hk * load(xs) * n
        K[idx, idx] += ke + kg - (omega**2 * me if inplane else 0.0)
        M[idx, idx] += me
    free = slice(2, None)  # clamped root: deflection and slope
    return K[free, free], M[free, free], F[:, free]


def rotating_beam(ei, m, e, R, omega, n_el=40, inplane=False, load=None):
    """First bending frequency [rad/s] of the uniform beam of :func:`beam_matrices`, or with
    ``load`` (callable: force per length [N/m] at radius x) its static tip deflection [m]."""
    K, M, F = beam_matrices(ei, m, e, R, omega, n_el, inplane, () if load is None else (load,))
    if load is not None:
        return float(np.linalg.solve(K, F[0])[-2])
    from scipy.linalg import eigh

    return float(math.sqrt(eigh(K, M, eigvals_only=True)[0]))


def pitched_beam_static(ei_y, ei_z, m, e, R, omega, theta, lift, drag, n_el=40):
    """Tip deflections [m] (up, and in plane in the direction of rotation) of the uniform beam
    of :func:`beam_matrices` pitched by ``theta`` [rad]: bending EI_y about the chord and EI_z
    about the normal (energy EI_y (w'' cos - v'' sin)^2 + EI_z (w'' sin + v'' cos)^2, halved),
    under the lift ``lift`` (up) and the drag ``drag`` (against the rotation) per length."""
    kb, mm, F = beam_matrices(1.0, m, e, R, 0.0, n_el, loads=(lift, drag))
    kg = beam_matrices(0.0, m, e, R, omega, n_el)[0]
    c, s = math.cos(theta), math.sin(theta)
    ww, vv = ei_y * c**2 + ei_z * s**2, ei_y * s**2 + ei_z * c**2
    wv = (ei_z - ei_y) * s * c
    K = np.block([[ww * kb + kg, wv * kb], [wv * kb, vv * kb + kg - omega**2 * mm]])
    u = np.linalg.solve(K, np.concatenate([F[0], -F[1]]))
    n = kb.shape[0]
    return float(u[n - 2]), float(u[2 * n - 2])


def coning_moment(ei, m, e, R, omega, lift, inplane, n_el=40):
    """Moment [N m] about the feathering axis (nose up positive) of the in-plane force per
    length ``inplane`` [N/m, against the rotation] acting on the blade deflected by ``lift``
    [N/m]: the integral of inplane(x) w(x) over the span (w from the flapwise static solution),
    as the consistent load vector of ``inplane`` times the nodal deflections."""
    K, _, F = beam_matrices(ei, m, e, R, omega, n_el, False, (lift, inplane))
    return float(F[1] @ np.linalg.solve(K, F[0]))


def rotating_torsion(gj, i_p, prop_ratio, k_root, L, omega, n_el=40):
    """First torsion frequency [rad/s] of a uniform blade of torsional inertia ``i_p`` [kg m]
    per length on a root spring ``k_root`` [N m/rad], with the propeller moment
    prop_ratio * i_p Omega^2 per length (prop_ratio = (J_33 - J_22) / J_11 of the section)."""
    from scipy.linalg import eigh

    n = n_el + 1
    h = L / n_el
    K = np.zeros((n, n))
    M = np.zeros((n, n))
    for k in range(n_el):
        s = slice(k, k + 2)
        K[s, s] += gj / h * np.array([[1, -1], [-1, 1]])
        K[s, s] += prop_ratio * i_p * omega**2 * h / 6 * np.array([[2, 1], [1, 2]])
        M[s, s] += i_p * h / 6 * np.array([[2, 1], [1, 2]])
    K[0, 0] += k_root
    return float(math.sqrt(eigh(K, M, eigvals_only=True)[0]))


# --------------------------------------------------------------------------------------------
# MBDyn runs
def locate_mbdyn():
    from rotoruq.mbdyn import find_mbdyn

    return find_mbdyn(build_prefix=True)


def run_template(wd: Path, template: str, inputs: dict, settings, mbdyn, extra: str = "",
                 table_cm: bool = True):
    """Fill a bundled template with node output (orientation matrices) and ``extra`` forces
    on blade 1 (the c81 table's CM zeroed unless ``table_cm``), run MBDyn; returns the filled
    values and the wall time [s]."""
    import dataclasses

    from rotoruq.evaluation.templates import fill_template
    from rotoruq.mbdyn.case import (
        AIRFOIL_FILE,
        TEMPLATE_DEFAULTS,
        sample_table,
        template_text,
        template_values,
    )
    from rotoruq.mbdyn.solver import run_mbdyn
    from rotoruq.rotor.c81 import write_c81
    from rotoruq.rotor.model import load_airfoil
    from rotoruq.rotor.presets import gvpm

    preset = gvpm()
    text, tpath = template_text(template)
    # the template's own defaults, as the driver fills it (the rigid template's cyclic is 0
    # unless given: it has no swashplate of the preset's)
    values = template_values(preset, inputs, settings, TEMPLATE_DEFAULTS.get(template))
    filled = fill_template(text, values, path=tpath)
    out = "default output: none, induced velocity elements;"
    if out not in filled:
        raise RuntimeError(f"template {template}: expected the line {out!r}")
    filled = filled.replace(out, "default output: none, induced velocity elements, "
                            "structural nodes;\n    default orientation: orientation matrix;")
    if extra:
        filled = filled.replace("    air properties;\n", "    air properties;\n    forces: 1;\n", 1)
        i = filled.rindex("end: elements;")
        filled = filled[:i] + "    " + extra + "\n" + filled[i:]
    wd.mkdir(parents=True, exist_ok=True)
    table = sample_table(load_airfoil(preset), {})
    if not table_cm:
        table = dataclasses.replace(table, cm=dataclasses.replace(
            table.cm, values=np.zeros_like(table.cm.values)))
    write_c81(table, wd / AIRFOIL_FILE, free_format=True)
    (wd / "rotor.mbd").write_text(filled)
    t0 = time.perf_counter()
    run_mbdyn(wd / "rotor.mbd", wd / "rotor", mbdyn=mbdyn, timeout=settings.timeout)
    return values, time.perf_counter() - t0


def blade1(wd: Path, tip: int = 1006, root: int = 1000, swashplate: int = 1100):
    """Blade 1 in the hub frame from the .mov file: tip, root and swashplate-point positions
    (n, 3) [m], tip and root pitch (n,) [rad] (the chord axis's angle to the disk plane), and
    the hub's azimuth ``psi`` (n,) [rad, unwrapped]: blade 1's, which runs ahead of Omega t
    (0.135 deg per revolution at 72 steps) and which the swashplate follows."""
    a = np.loadtxt(wd / "rotor.mov")
    hub = a[a[:, 0] == 3]
    Rh = hub[:, 4:13].reshape(-1, 3, 3)
    out = {"psi": np.unwrap(np.arctan2(Rh[:, 1, 0], Rh[:, 0, 0]))}
    for name, label in (("tip", tip), ("root", root)):
        x = a[a[:, 0] == label]
        Rrel = np.einsum("nji,njk->nik", Rh, x[:, 4:13].reshape(-1, 3, 3))
        out[name + "_pos"] = np.einsum("nji,nj->ni", Rh, x[:, 1:4])
        out[name + "_pitch"] = np.arctan2(Rrel[:, 2, 1], Rrel[:, 1, 1])
    x = a[a[:, 0] == swashplate]
    out["swashplate_pos"] = np.einsum("nji,nj->ni", Rh, x[:, 1:4])
    return out


def fit_decay(t, y):
    """Undamped natural frequency [rad/s] and damping ratio of a damped sinusoid fitted to a
    free decay (least squares on the first 6 periods of the zero-crossing estimate)."""
    from scipy.optimize import least_squares

    y = y - y[-len(y) // 4:].mean()
    up = np.flatnonzero((y[:-1] < 0) & (y[1:] >= 0))
    if len(up) < 2:
        raise RuntimeError("free decay: fewer than two oscillations recorded")
    period = float(np.mean(np.diff(t[up])))
    keep = t <= t[0] + 6 * period
    tt, yy = t[keep] - t[0], y[keep]
    w0 = 2 * math.pi / period

    def res(p):
        a, b, s, w, c = p
        return np.exp(-s * tt) * (a * np.cos(w * tt) + b * np.sin(w * tt)) + c - yy

    p = least_squares(res, [yy[0], 0.0, 0.1 * w0, w0, 0.0], x_scale="jac").x
    sigma, wd = p[2], abs(p[3])
    wn = math.hypot(wd, sigma)
    return wn, sigma / wn


DECAY = {  # force on blade 1 (tip or mid-span), held for half a revolution
    "flap": "force: 9001, absolute, 1006, position, null, single, 0., 0., 1., "
            "double step, -1., {t}, 2., 0.;",
    "lag": "force: 9001, follower, 1006, position, null, single, 0., 1., 0., "
           "double step, -1., {t}, 20., 0.;",
    "torsion": "couple: 9001, follower, 1003, single, 1., 0., 0., "
               "double step, -1., {t}, 0.001, 0.;",
}


def frequencies(mbdyn, tmp: Path, quick: bool) -> dict:
    from rotoruq.mbdyn import CaseSettings
    from rotoruq.rotor.geometry import CANTILEVER_SPRING_FACTOR, blade_grid
    from rotoruq.rotor.presets import gvpm

    p = gvpm()
    om = OP["omega"]
    vac = {"omega": om, "collective_deg": 0.0, "lateral_deg": 0.0, "longitudinal_deg": 0.0,
           "k_pitch_link": OP["k_pitch_link"], "c_pitch_link": 0.0,
           "height_over_radius": math.inf, "rho": 1e-6}
    spr = 360
    settings = CaseSettings(revolutions=2 if quick else 3, steps_per_rev=spr, average=1)
    t_rel = 0.5 * 2 * math.pi / om
    e, R, m = p.root_cutout, p.radius, p.blade_mass_per_length
    L = R - e
    ei_y, ei_z, gj = p.ei_flap, TEMPLATE_EI_Z, TEMPLATE_GJ
    chord = p.chord
    i_p = m * (chord / 4) ** 2  # template: J = M (c/4)^2 about the span, 0.01 J chordwise
    k_theta = p.feathering_stiffness(OP["k_pitch_link"])
    beam = {"flap": rotating_beam(ei_y, m, e, R, om) / om,
            "lag": rotating_beam(ei_z, m, e, R, om, inplane=True) / om,
            "torsion": rotating_torsion(gj, i_p, 0.99, k_theta, L, om) / om}
    g = blade_grid(p, 10, 36)
    k_b = CANTILEVER_SPRING_FACTOR * ei_y / g.blade_length
    hinge = {"flap": math.sqrt(1 + e * g.S_flap / g.I_flap + k_b / (g.I_flap * om**2)),
             "lag": math.sqrt((p.k_lag + om**2 * e * g.S_flap) / (g.I_lag * om**2)),
             "torsion": math.sqrt(1 + k_theta / (p.pitch_inertia * om**2))}
    self_check = {
        "nonrotating_root": rotating_beam(1.0, 1.0, 0.0, 1.0, 0.0) ** 0.5,
        "nonrotating_root_exact": CANTILEVER_ROOT,
        "southwell_e0": (rotating_beam(1.0, 1.0, 0.0, 1.0, 0.1) ** 2
                         - rotating_beam(1.0, 1.0, 0.0, 1.0, 0.0) ** 2) / 0.1**2,
        "southwell_e0_literature": SOUTHWELL_1,
    }
    out: dict = {"inputs": vac, "steps_per_rev": spr, "revolutions": settings.revolutions,
                 "beam_theory_check": self_check, "modes": {}, "wall_s": 0.0,
                 "rigid_template": "no blade modes: its blades are aerodynamic bodies clamped "
                                   "to the hub (no coning, lag or elastic pitch either)"}
    for mode, force in DECAY.items():
        wd = tmp / f"decay_{mode}"
        _, wall = run_template(wd, "elastic", vac, settings, mbdyn, force.format(t=t_rel))
        out["wall_s"] += wall
        b = blade1(wd)
        sig = {"flap": b["tip_pos"][:, 2], "lag": b["tip_pos"][:, 1],
               "torsion": b["tip_pitch"]}[mode]
        t = np.arange(len(sig)) * (2 * math.pi / om) / spr
        after = t > t_rel + 1e-9
        wn, zeta = fit_decay(t[after], sig[after])
        nu = wn / om
        tol_b = TOL["beam_theory_lag_frequency" if mode == "lag" else "beam_theory_frequency"]
        out["modes"][mode] = {
            "mbdyn_per_rev": nu, "mbdyn_damping_ratio": zeta,
            "checks": [check("beam theory", nu, beam[mode], tol_b),
                       check("built-in equivalent hinge", nu, hinge[mode],
                             TOL["equivalent_hinge_frequency"])]}
    return out


# the elastic template's section properties not in the preset (elastic.mbd: EI_Z, GJ)
TEMPLATE_EI_Z = 2.26e3
TEMPLATE_GJ = 1.0e2


def check(reference: str, value: float, ref: float, tol_pct: float) -> dict:
    """One verification line: relative difference [%] against a tolerance [%]."""
    diff = 100.0 * (value / ref - 1.0) if ref != 0 else math.inf
    return {"reference": reference, "value": value, "reference_value": ref,
            "diff_pct": diff, "tolerance_pct": tol_pct, "passed": bool(abs(diff) <= tol_pct)}


def check_deg(reference: str, value: float, ref: float, tol_deg: float) -> dict:
    """One verification line on an angle [deg]: difference against a tolerance [deg]."""
    d = value - ref
    return {"reference": reference, "value": value, "reference_value": ref, "diff_deg": d,
            "tolerance_deg": tol_deg, "passed": bool(abs(d) <= tol_deg)}


def harmonic1(psi, y):
    """Mean, cosine and sine amplitudes of y(psi) (least squares over whole revolutions)."""
    A = np.column_stack([np.ones_like(psi), np.cos(psi), np.sin(psi)])
    return np.linalg.lstsq(A, y, rcond=None)[0]


def phase_lag_deg(theta1, beta1):
    """Lag [deg] of the 1/rev flap behind the 1/rev pitch, both (cos, sin) amplitudes."""
    d = math.degrees(math.atan2(beta1[1], beta1[0]) - math.atan2(theta1[1], theta1[0]))
    return (d + 180.0) % 360.0 - 180.0


def builtin_state(preset, x: dict) -> dict:
    import rotoruq as rq

    names = list(x)
    m = rq.RotorModel(preset, names_in=names, names_out=["thrust", "power", "roll", "pitch"])
    y = m([[x[n] for n in names]])[0]
    s = m.last_solution
    assert s is not None
    B, T = s.flap[0, 1], s.feather[0, 1]
    theta1 = (T.real, -T.imag)
    beta1 = (B.real, -B.imag)
    return {"thrust": float(y[0]), "power": float(y[1]), "roll": float(y[2]),
            "pitch": float(y[3]), "coning_deg": float(s.coning_deg[0]),
            "lag_deg": float(np.rad2deg(s.lag[0, 0].real)),
            "mean_pitch_deg": float(np.rad2deg(s.feather[0, 0].real)),
            **pitch_response(x, theta1, beta1)}


def pitch_response(x: dict, theta1, beta1) -> dict:
    """The blade's 1/rev pitch and flap (cos, sin amplitudes [rad]) against the swashplate
    command of ``x``: the flap's lag [deg] behind the pitch, the pitch's amplitude ratio and
    lag [deg] behind the command (none without cyclic)."""
    cmd = (x["lateral_deg"], x["longitudinal_deg"])
    if math.hypot(*cmd) == 0:
        return {}
    return {"flap_phase_lag_deg": phase_lag_deg(theta1, beta1),
            "flap_phase_lag_vs_command_deg": phase_lag_deg(cmd, beta1),
            "pitch_1rev_amplitude_ratio": math.degrees(math.hypot(*theta1)) / math.hypot(*cmd),
            "pitch_1rev_lag_vs_command_deg": phase_lag_deg(cmd, theta1)}


def elastic_hover(wd: Path, settings, mbdyn, x: dict | None = None, table_cm: bool = True):
    """The elastic template at ``x`` (default :data:`OP`): hub loads and blade 1's motion
    (means and 1/rev harmonics over the last two revolutions)."""
    from rotoruq.mbdyn import hub_loads
    from rotoruq.rotor.presets import gvpm

    p = gvpm()
    x = OP if x is None else x
    vals, wall = run_template(wd, "elastic", x, settings, mbdyn, table_cm=table_cm)
    loads = hub_loads(wd / "rotor.rot", omega=x["omega"], rho=vals["rho"], radius=p.radius,
                      steps_per_rev=settings.steps_per_rev, revolutions=settings.revolutions,
                      joint=wd / "rotor.jnt")
    b = blade1(wd)
    n = 2 * settings.steps_per_rev
    psi = b["psi"][-n:]
    L = p.radius - p.root_cutout
    w = harmonic1(psi, b["tip_pos"][-n:, 2])
    v = harmonic1(psi, b["tip_pos"][-n:, 1])
    th_root = harmonic1(psi, b["root_pitch"][-n:])
    th_tip = harmonic1(psi, b["tip_pitch"][-n:])
    mb = {"thrust": loads.thrust, "power": loads.power, "torque": loads.torque,
          "roll": loads.roll, "pitch": loads.pitch, "inflow_m_s": loads.inflow,
          "coning_deg": math.degrees(math.asin(w[0] / L)),
          "lag_deg": math.degrees(math.asin(v[0] / L)),
          "root_mean_pitch_deg": math.degrees(th_root[0]),
          "tip_mean_pitch_deg": math.degrees(th_tip[0]),
          **pitch_response(x, th_root[1:], w[1:]), "wall_s": wall}
    if "pitch_1rev_amplitude_ratio" in mb:
        # the swashplate point rises A_H (sin(theta_0 + theta_1(psi)) - sin(theta_0)): its
        # 1/rev is the command times A_H cos(theta_0)
        z = harmonic1(psi, b["swashplate_pos"][-n:, 2])[1:] / (
            p.pitch_horn_arm * math.cos(math.radians(x["collective_deg"])))
        sw = pitch_response(x, z, w[1:])
        mb["swashplate_1rev_amplitude_ratio"] = sw["pitch_1rev_amplitude_ratio"]
        mb["swashplate_1rev_lag_vs_command_deg"] = sw["pitch_1rev_lag_vs_command_deg"]
    return mb, loads, th_root, th_tip, w


def vacuum_pitch(mbdyn, tmp: Path) -> float:
    """Blade 1's mean root pitch [rad] in vacuo (rho 1e-6) at the collective of :data:`OP`."""
    from rotoruq.mbdyn import CaseSettings

    x = {**OP, "lateral_deg": 0.0, "longitudinal_deg": 0.0, "rho": 1e-6}
    st = CaseSettings(revolutions=4, average=1)
    wd = tmp / "vacuum_static"
    run_template(wd, "elastic", x, st, mbdyn)
    return float(np.mean(blade1(wd)["root_pitch"][-st.steps_per_rev:]))


def hover_and_loads(mbdyn, tmp: Path, quick: bool) -> tuple[dict, dict, dict]:
    from rotoruq.mbdyn import CaseSettings, hub_loads, rigid_equivalent
    from rotoruq.rotor.model import RotorModel
    from rotoruq.rotor.presets import gvpm

    p = gvpm()
    om = OP["omega"]
    revs = 8 if quick else 12
    settings = CaseSettings(revolutions=revs)
    mb, loads = elastic_hover(tmp / "hover_elastic", settings, mbdyn)[:2]
    nocm = elastic_hover(tmp / "hover_elastic_no_cm", settings, mbdyn, table_cm=False)[0]
    # statics in axisymmetric hover (the cyclic's 1/rev products move the mean lag)
    hover0 = {**OP, "lateral_deg": 0.0, "longitudinal_deg": 0.0}
    mb0, loads0, th_root, th_tip, _ = elastic_hover(tmp / "hover_elastic_axisymmetric",
                                                    settings, mbdyn, hover0)
    e, R = p.root_cutout, p.radius
    L = R - e
    coning, lag = mb0["coning_deg"], mb0["lag_deg"]
    # references: the lift of MBDyn's thrust and inflow, ~ (theta Omega r^2 - v r) per length
    theta = th_root[0]
    vi = loads0.inflow

    def shape(x):
        return theta * om * x**2 - vi * x

    xs = np.linspace(e, R, 2001)
    per_blade = loads0.thrust / p.n_blades
    scale = per_blade / np.trapezoid(shape(xs), xs)
    moment = scale * np.trapezoid(shape(xs) * (xs - e), xs)
    from rotoruq.rotor.geometry import CANTILEVER_SPRING_FACTOR, blade_grid

    g = blade_grid(p, 10, 36)
    k_b = CANTILEVER_SPRING_FACTOR * p.ei_flap / L
    beta_hinge = moment / (k_b + om**2 * (g.I_flap + e * g.S_flap))
    # in-plane force per length ~ r (induced drag of uniform inflow: ~ lift * v / (Omega r))
    drag_scale = loads0.torque / p.n_blades / np.trapezoid(xs * xs, xs)
    w_beam, v_beam = pitched_beam_static(p.ei_flap, TEMPLATE_EI_Z, p.blade_mass_per_length, e, R,
                                         om, 0.5 * (th_root[0] + th_tip[0]),
                                         lambda x: scale * shape(x), lambda x: drag_scale * x)
    fit = builtin_state(p, OP)
    fit0 = builtin_state(p, hover0)
    same = builtin_state(p.replace(aero_center_offset=0.0, pitching_moment=True), OP)
    # the feathering equilibrium: in vacuo the link against the propeller moment,
    # sin(theta) = K sin(theta_0) / (K + P), K = K_p l_h^2 / l_0, P = 0.99 I_p Omega^2
    # (the template's sections: J_22 = 0.01 J_11); in air without the table's CM the drag
    # acting on the coned blade above the feathering axis adds a nose-up moment
    k_theta = p.feathering_stiffness(OP["k_pitch_link"])
    prop = 0.99 * p.blade_mass_per_length * L * (p.chord / 4) ** 2 * om**2
    th0 = math.radians(OP["collective_deg"])
    theta_vac = vacuum_pitch(mbdyn, tmp)
    theta_closed = math.asin(k_theta * math.sin(th0) / (k_theta + prop))
    th_nocm = math.radians(nocm["root_mean_pitch_deg"])

    def lift_nocm(x):
        return th_nocm * om * x**2 - nocm["inflow_m_s"] * x

    lift_scale = nocm["thrust"] / p.n_blades / np.trapezoid(lift_nocm(xs), xs)
    drag_nocm = nocm["torque"] / p.n_blades / np.trapezoid(xs * xs, xs)
    m_coning = coning_moment(p.ei_flap, p.blade_mass_per_length, e, R, om,
                             lambda x: lift_scale * lift_nocm(x), lambda x: drag_nocm * x)
    rise_closed = m_coning / ((k_theta + prop) * math.cos(th_nocm))
    tol_ph = TOL["flap_phase_deg"]
    pitch_checks = [
        check("swashplate: 1/rev amplitude / command", mb["swashplate_1rev_amplitude_ratio"],
              1.0, TOL["swashplate_amplitude"]),
        check_deg("swashplate: 1/rev lag behind command",
                  mb["swashplate_1rev_lag_vs_command_deg"], 0.0, TOL["swashplate_phase_deg"]),
        check("in vacuo: link against propeller moment", math.degrees(theta_vac),
              math.degrees(theta_closed), TOL["pitch_in_vacuo"]),
        check("air, no table CM: rise over vacuo, drag on the coned blade",
              nocm["root_mean_pitch_deg"] - math.degrees(theta_vac), math.degrees(rise_closed),
              TOL["coning_pitch_moment"]),
        check("air, no table CM: 1/rev amplitude / command", nocm["pitch_1rev_amplitude_ratio"],
              1.0, TOL["pitch_1rev_amplitude"]),
        check_deg("air, no table CM: 1/rev lag behind command",
                  nocm["pitch_1rev_lag_vs_command_deg"], 0.0, tol_ph),
        check("air, table CM: 1/rev amplitude / command", mb["pitch_1rev_amplitude_ratio"], 1.0,
              TOL["pitch_1rev_amplitude"]),
        check_deg("air, table CM: 1/rev lag behind command", mb["pitch_1rev_lag_vs_command_deg"],
                  0.0, tol_ph),
    ]
    hover = {
        "mbdyn": mb, "builtin_preset": fit, "builtin_mbdyn_aero_physics": same,
        "checks": {
            "coning": [
                check("beam theory: static deflection under MBDyn's lift and drag", coning,
                      math.degrees(math.asin(w_beam / L)), TOL["beam_static_coning"]),
                check("equivalent hinge moment balance under MBDyn's lift", coning,
                      math.degrees(beta_hinge), TOL["equivalent_hinge_coning"]),
                check("built-in preset (its own thrust)", coning, fit0["coning_deg"],
                      TOL["equivalent_hinge_coning"])],
            "lag": [
                check("beam theory: pitched principal axes, MBDyn's lift and drag", lag,
                      math.degrees(math.asin(v_beam / L)), TOL["pitched_beam_lag"]),
                check("built-in preset (lag hinge in the disk plane)", lag, fit0["lag_deg"],
                      TOL["builtin_lag"])],
        },
    }
    hover["checks"]["flap_phase"] = [
        check_deg("built-in preset", mb["flap_phase_lag_deg"], fit["flap_phase_lag_deg"],
                  tol_ph),
        check_deg("MBDyn without the table CM", mb["flap_phase_lag_deg"],
                  nocm["flap_phase_lag_deg"], tol_ph)]
    hover["checks"]["pitch"] = pitch_checks
    hover["mbdyn_no_table_cm"] = nocm
    hover["mbdyn_axisymmetric"] = mb0
    hover["builtin_preset_axisymmetric"] = fit0
    hover["mbdyn_in_vacuo_mean_pitch_deg"] = math.degrees(theta_vac)
    # loads: rigid template vs the built-in model on identical physics, elastic vs built-in
    rig_in = {"omega": om, "collective_deg": OP["collective_deg"],
              "height_over_radius": OP["height_over_radius"]}
    wr = tmp / "hover_rigid"
    rvals, rwall = run_template(wr, "rigid", rig_in, settings, mbdyn)
    rl = hub_loads(wr / "rotor.rot", omega=om, rho=rvals["rho"], radius=p.radius,
                   steps_per_rev=settings.steps_per_rev, revolutions=revs)
    rb = RotorModel(rigid_equivalent(p), names_in=list(rig_in), names_out=["thrust", "power"])(
        [list(rig_in.values())])[0]
    tol_same, tol_el = TOL["identical_physics_loads"], TOL["elastic_vs_builtin_loads"]
    load_checks = {
        "rigid": {"inputs": rig_in, "mbdyn": {"thrust": rl.thrust, "power": rl.power},
                  "wall_s": rwall, "checks": [
                      check("built-in, identical physics: thrust", rl.thrust, float(rb[0]),
                            tol_same),
                      check("built-in, identical physics: power", rl.power, float(rb[1]),
                            tol_same)]},
        "elastic": {"inputs": OP, "mbdyn": {"thrust": loads.thrust, "power": loads.power},
                    "checks": [
                        check("built-in preset: thrust", loads.thrust, fit["thrust"], tol_el),
                        check("built-in preset: power", loads.power, fit["power"], tol_el),
                        check("built-in, MBDyn's a.c. physics: thrust", loads.thrust,
                              same["thrust"], tol_el),
                        check("built-in, MBDyn's a.c. physics: power", loads.power,
                              same["power"], tol_el)]},
    }
    return hover, load_checks, {"mbdyn_thrust": loads.thrust, "mbdyn_power": loads.power,
                                "mbdyn_flap_phase_lag_deg": mb["flap_phase_lag_deg"]}


def airfoil_ac_offset() -> dict:
    """x_ac - c/4 [m] from the bundled table's CM slope: -c dCM/dCL over alpha 0..8 deg at
    each blade station's Mach number, weighted by the station's lift (~ r^2 dr)."""
    from rotoruq.rotor.model import load_airfoil
    from rotoruq.rotor.presets import gvpm

    p = gvpm()
    af = load_airfoil(p)
    r = np.linspace(p.root_cutout, p.radius, 9)
    mach = OP["omega"] * r / p.speed_of_sound
    alpha = np.linspace(0.0, 8.0, 17)
    offs = []
    for mm in mach:
        cl, _, cm = af.coefficients(alpha, np.full_like(alpha, mm))
        offs.append(-p.chord * np.polyfit(cl, cm, 1)[0])
    offs_a = np.asarray(offs)
    wts = r**2 / np.sum(r**2)
    mean = float(np.sum(wts * offs_a))
    return {"x_ac_m": mean, "spread_m": float(np.sqrt(np.sum(wts * (offs_a - mean) ** 2))),
            "per_station_m": [float(v) for v in offs_a], "mach": [float(v) for v in mach],
            "alpha_range_deg": [0.0, 8.0]}


def ac_offset_study(mb: dict) -> dict:
    from rotoruq.rotor.presets import gvpm

    p = gvpm()
    af = airfoil_ac_offset()
    cases = {"preset (-1 mm)": p.aero_center_offset, "none (0 mm)": 0.0,
             "airfoil CM slope": af["x_ac_m"]}
    rows = {}
    for name, x in cases.items():
        s = builtin_state(p.replace(aero_center_offset=x), OP)
        rows[name] = {"aero_center_offset_m": x, **s,
                      "thrust_vs_mbdyn_pct": 100 * (s["thrust"] / mb["mbdyn_thrust"] - 1),
                      "power_vs_mbdyn_pct": 100 * (s["power"] / mb["mbdyn_power"] - 1)}
    return {"airfoil": af, "cases": rows, "mbdyn_elastic": mb}


def passed(res: dict) -> tuple[int, int]:
    """Passed and total checks anywhere in ``res``."""
    ok = tot = 0
    stack: list = [res]
    while stack:
        x = stack.pop()
        if isinstance(x, dict):
            if "passed" in x:
                tot += 1
                ok += bool(x["passed"])
            else:
                stack.extend(x.values())
        elif isinstance(x, list):
            stack.extend(x)
    return ok, tot


# --------------------------------------------------------------------------------------------
def _row(name, c, unit="", fmt=".4g"):
    mark = "pass" if c["passed"] else "**fail**"
    if "diff_deg" in c:
        return (f"| {name} | {c['value']:{fmt}}{unit} | {c['reference']}: "
                f"{c['reference_value']:{fmt}}{unit} | {c['diff_deg']:+.1f} deg | "
                f"{c['tolerance_deg']:g} deg | {mark} |")
    return (f"| {name} | {c['value']:{fmt}}{unit} | {c['reference']}: {c['reference_value']:{fmt}}"
            f"{unit} | {c['diff_pct']:+.2f} % | {c['tolerance_pct']:g} % | {mark} |")


def summary(res: dict) -> str:
    """The docs' tables from a saved run."""
    if "skipped" in res:
        return f"(the saved run was skipped: {res['skipped']})"
    lines = ["| quantity | MBDyn | reference | difference | tolerance | |",
             "|---|---|---|---|---|---|"]
    fr = res["frequencies"]
    for mode, v in fr["modes"].items():
        for c in v["checks"]:
            lines.append(_row(f"elastic: {mode} frequency [/rev]", c))
    h = res["hover"]["checks"]
    for key, unit in (("coning", " deg"), ("lag", " deg")):
        for c in h[key]:
            lines.append(_row(f"elastic: {key}", c, unit))
    for c in h["flap_phase"]:
        lines.append(_row("elastic: 1/rev flap lag behind pitch", c, " deg", ".1f"))
    for c in h["pitch"]:
        case, what = c["reference"].split(": ", 1)
        unit = "" if "amplitude" in what else " deg"
        shown = {**c, "reference": what, "value": round(c["value"], 4) + 0.0}
        lines.append(_row(f"elastic: pitch, {case}", shown, unit, ".3g"))
    for model in ("rigid", "elastic"):
        for c in res["loads"][model]["checks"]:
            what, q = c["reference"].rsplit(": ", 1)
            lines.append(_row(f"{model}: {q}", {**c, "reference": what},
                              " N" if q == "thrust" else " W"))
    ok, tot = passed({k: res[k] for k in ("frequencies", "hover", "loads")})
    bc = fr["beam_theory_check"]
    lines += ["", f"{ok} of {tot} checks pass. Beam theory: finite elements of the rotating "
              f"uniform beam (non-rotating root {bc['nonrotating_root']:.5f}, exact "
              f"{bc['nonrotating_root_exact']:.5f}; Southwell coefficient at e = 0 "
              f"{bc['southwell_e0']:.3f}, literature {bc['southwell_e0_literature']}). "
              f"Free decays in vacuo at {fr['steps_per_rev']} steps per revolution; "
              f"damping ratios flap {fr['modes']['flap']['mbdyn_damping_ratio']:.3f}, lag "
              f"{fr['modes']['lag']['mbdyn_damping_ratio']:.3f}, torsion "
              f"{fr['modes']['torsion']['mbdyn_damping_ratio']:.3f} (beam damping 1e-4 s)."]
    ac = res["aero_center_offset"]
    af = ac["airfoil"]
    lines += ["", "| model | x_ac [mm] | thrust [N] | power [W] | roll / pitch [N m] | "
              "coning [deg] | mean pitch [deg] | 1/rev pitch / command | flap lag behind "
              "pitch / command [deg] | thrust / power vs MBDyn |",
              "|---|---|---|---|---|---|---|---|---|---|"]

    def cells(r, mean_pitch):
        return (f"{r['thrust']:.2f} | {r['power']:.1f} | {r['roll']:+.2f} / {r['pitch']:+.2f} | "
                f"{r['coning_deg']:.3f} | {mean_pitch:.2f} | "
                f"{r['pitch_1rev_amplitude_ratio']:.2f}, {r['pitch_1rev_lag_vs_command_deg']:+.0f}"
                f" deg | {r['flap_phase_lag_deg']:.1f} / "
                f"{r['flap_phase_lag_deg'] + r['pitch_1rev_lag_vs_command_deg']:.1f}")

    for name, r in ac["cases"].items():
        lines.append(f"| built-in, {name} | {1e3 * r['aero_center_offset_m']:+.2f} | "
                     f"{cells(r, r['mean_pitch_deg'])} | {r['thrust_vs_mbdyn_pct']:+.1f} % / "
                     f"{r['power_vs_mbdyn_pct']:+.1f} % |")
    r = res["hover"]["builtin_mbdyn_aero_physics"]
    hm = res["hover"]["mbdyn"]
    lines.append(f"| built-in, a.c. on the axis, table CM (MBDyn's) | 0 | "
                 f"{cells(r, r['mean_pitch_deg'])} | "
                 f"{100 * (r['thrust'] / hm['thrust'] - 1):+.1f} % / "
                 f"{100 * (r['power'] / hm['power'] - 1):+.1f} % |")
    for name, r in (("MBDyn elastic (a.c. on the axis, table CM)", res["hover"]["mbdyn"]),
                    ("MBDyn elastic, table CM zeroed", res["hover"]["mbdyn_no_table_cm"])):
        lines.append(f"| {name} | 0 | {cells(r, r['root_mean_pitch_deg'])} | - |")
    lines += ["", f"Airfoil CM slope: x_ac - c/4 = {1e3 * af['x_ac_m']:+.2f} mm (lift-weighted "
              f"over Mach {af['mach'][0]:.2f}-{af['mach'][-1]:.2f}, spread "
              f"{1e3 * af['spread_m']:.2f} mm; minus = ahead of the quarter chord)."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="shorter MBDyn runs (2-revolution decays, 8-revolution hover)")
    ap.add_argument("--out", help=f"also write the JSON to this file (the docs read {RESULTS})")
    ap.add_argument("--summary", help="print the docs' tables from this saved JSON and exit")
    args = ap.parse_args(argv)
    if args.summary:
        with open(args.summary, encoding="utf-8") as fh:
            print(summary(json.load(fh)))
        return
    from rotoruq.mbdyn.solver import MBDynNotFoundError

    try:
        mbdyn = locate_mbdyn()
    except MBDynNotFoundError as exc:
        print(json.dumps({"skipped": str(exc)}))
        return
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        freq = frequencies(mbdyn, Path(tmp), args.quick)
        hover, loads, mb = hover_and_loads(mbdyn, Path(tmp), args.quick)
    res = {"quick": args.quick, "operating_point": OP, "tolerances": TOL,
           "frequencies": freq, "hover": hover, "loads": loads,
           "aero_center_offset": ac_offset_study(mb)}
    ok, tot = passed({k: res[k] for k in ("frequencies", "hover", "loads")})
    res["passed"], res["checks"] = ok, tot
    res["wall_s"] = time.perf_counter() - t0
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from _provenance import provenance  # the one helper every benchmark uses

    res["provenance"] = provenance()
    text = json.dumps(res, indent=1)
    print(text)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    sys.exit(main())
