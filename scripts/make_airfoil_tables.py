"""Generate rotoruq's bundled C81 tables: NACA 0012 (GVPM rotor) and NACA 23012 (Bo105).

Attached range: NeuralFoil (through AeroSandbox, ``pip install rotoruq[airfoil]``), run
incompressible at the Reynolds number of each rotor at each Mach row, then Prandtl-Glauert on
CL and CM, Korn/Lock wave drag on CD, and a Mach-dependent cap on CL max (shock stall).
Beyond stall: a Viterna-Corrigan extension anchored at the stall point of each Mach row (and
of each sign of alpha), mirrored to 180 deg with the usual 0.7 lift factor (AirfoilPrep);
the pitching moment beyond stall follows a centre of pressure that moves from c/4 at stall to
c/2 at 90 deg and 3c/4 near 180 deg.

Usage::

    python scripts/make_airfoil_tables.py [--outdir src/rotoruq/data/airfoils]

Prints, per table, the Reynolds number of each Mach row, the stall angles, and the CL/CD fits
of the written table (the numbers reported in ``src/rotoruq/data/airfoils/README.md``).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rotoruq.rotor.airfoil import fit_airfoil
from rotoruq.rotor.c81 import C81Block, C81Table, read_c81, write_c81

# ISA sea level
RHO = 1.225  # kg/m^3
SOUND = 340.294  # m/s
MU = 1.7894e-5  # Pa s

MACHS = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.75, 0.8])
#: Reynolds number of the M = 0 row: that of M = 0.05 (a zero-speed section carries no load).
MACH_FLOOR = 0.05
CD_MAX = 2.0  # flat plate normal to the flow, infinite aspect ratio
CD_180_FACTOR = 2.0  # CD at 180 deg (trailing edge first) = factor * CD(0)
STALL_SEARCH = (4.0, 20.0)  # deg, where CL max / min is looked for

# 89 angles: 1 deg inside +-20 deg (21 points in the +-10 deg fit window), coarser beyond.
_OUTER = np.array([22, 24, 26, 28, 30, 35, 40, 45, 50, 60, 70, 80, 90, 100, 110, 120, 130, 140,
                   150, 160, 165, 170, 175, 180], dtype=float)
ALPHAS = np.concatenate([-_OUTER[::-1], np.arange(-20.0, 21.0), _OUTER])


@dataclass(frozen=True)
class Rotor:
    key: str
    airfoil: str
    title: str
    chord: float  # m
    note: str


ROTORS = (
    Rotor("naca0012", "naca0012", "NACA 0012 ROTORUQ GVPM RE", 0.042,
          "GVPM scaled rotor: chord 0.042 m, R 0.485 m, v_tip 108.9 m/s (M_tip 0.32)"),
    Rotor("naca23012", "naca23012", "NACA 23012 ROTORUQ BO105 RE", 0.27,
          "Bo105: chord 0.27 m, R 4.912 m, Omega 44.4 rad/s (v_tip 218 m/s, M_tip 0.64)"),
)


def reynolds(mach, chord):
    """Chord Reynolds number at Mach ``mach`` (sea level), floored at Mach 0.05."""
    return RHO * np.maximum(mach, MACH_FLOOR) * SOUND * chord / MU


def neuralfoil(airfoil_name, alpha, re, mach, model_size):
    import aerosandbox as asb

    af = asb.Airfoil(airfoil_name)
    out = af.get_aero_from_neuralfoil(alpha=alpha, Re=re, mach=mach, model_size=model_size,
                                      include_360_deg_effects=False)
    return (np.asarray(out["CL"], float), np.asarray(out["CD"], float),
            np.asarray(out["CM"], float), np.asarray(out["analysis_confidence"], float))


def viterna(alpha_deg, a_s, cl_s, cd_s):
    """Viterna-Corrigan CL, CD for alpha in [a_s, 90] deg (all angles positive here)."""
    a = np.radians(alpha_deg)
    s = np.radians(a_s)
    b1 = CD_MAX
    b2 = (cd_s - CD_MAX * np.sin(s) ** 2) / np.cos(s)
    a1 = b1 / 2.0
    a2 = (cl_s - CD_MAX * np.sin(s) * np.cos(s)) * np.sin(s) / np.cos(s) ** 2
    cl = a1 * np.sin(2 * a) + a2 * np.cos(a) ** 2 / np.sin(a)
    cd = b1 * np.sin(a) ** 2 + b2 * np.cos(a)
    return cl, cd


def post_stall(alpha_deg, a_s, cl_s, cd_s, cm_s, cd0):
    """CL, CD, CM for alpha in [a_s, 180] deg from the stall point (a_s, cl_s, cd_s, cm_s)."""
    a = np.asarray(alpha_deg, float)
    cl = np.empty_like(a)
    cd = np.empty_like(a)
    front = a <= 90.0
    cl[front], cd[front] = viterna(a[front], a_s, cl_s, cd_s)
    mid = (a > 90.0) & (a <= 180.0 - a_s)
    clv, cdv = viterna(180.0 - a[mid], a_s, cl_s, cd_s)
    cl[mid], cd[mid] = -0.7 * clv, cdv
    back = a > 180.0 - a_s  # trailing edge first, attached-like: linear lift to 0 at 180 deg
    u = (180.0 - a[back]) / a_s
    cl[back] = -0.7 * cl_s * u
    cd180 = CD_180_FACTOR * cd0
    cd[back] = cd180 + (cd_s - cd180) * u**2
    # centre of pressure: c/4 at stall -> c/2 at 90 deg -> 3c/4 at 180 - a_s and beyond
    xcp = np.interp(a, [a_s, 90.0, 180.0 - a_s, 180.0], [0.25, 0.5, 0.75, 0.75])
    rad = np.radians(a)
    cn = cl * np.cos(rad) + cd * np.sin(rad)
    # continuous at stall (xcp = c/4 there): the attached CM plus the moment of the moving CN
    cm = cm_s - cn * (xcp - 0.25)
    return cl, cd, cm


def clmax_factor(mach):
    """Shock-induced loss of maximum lift: 1 up to M 0.3, then -1.4 per unit Mach, >= 0.7.

    Engineering trend of NACA 0012 / 23012 data (McCroskey 1987, AGARD-AG-303): CL max falls
    from its low-speed value to about 0.7 of it by M 0.5 and stays there up to M 0.8.
    """
    return float(np.clip(1.0 - 1.4 * (mach - 0.3), 0.7, 1.0))


def wave_drag(mach, cl, t_over_c=0.12, kappa=0.87):
    """Korn-equation drag divergence with Lock's fourth-power law (conventional sections)."""
    m_dd = kappa - t_over_c - np.abs(cl) / 10.0
    m_crit = m_dd - (0.1 / 80.0) ** (1.0 / 3.0)
    return np.where(mach > m_crit, 20.0 * np.maximum(mach - m_crit, 0.0) ** 4, 0.0)


def make_table(rotor: Rotor, model_size: str):
    cl = np.empty((ALPHAS.size, MACHS.size))
    cd = np.empty_like(cl)
    cm = np.empty_like(cl)
    info = []
    fine = np.arange(-25.0, 25.01, 0.25)
    for j, m in enumerate(MACHS):
        re = float(reynolds(m, rotor.chord))
        # incompressible section at this row's Reynolds number, then Prandtl-Glauert
        cl_i, cd_i, cm_i, conf = neuralfoil(rotor.airfoil, fine, re, 0.0, model_size)
        beta = np.sqrt(1.0 - m * m)
        cl_c, cm_c = cl_i / beta, cm_i / beta
        cd_c = cd_i + wave_drag(m, cl_c)
        stall = []
        for sign in (1.0, -1.0):
            lo, hi = STALL_SEARCH
            zone = np.flatnonzero((sign * fine >= lo) & (sign * fine <= hi))
            k_inc = zone[np.argmax(sign * cl_i[zone])]  # incompressible stall
            cap = clmax_factor(m) * sign * cl_i[k_inc]
            reach = np.flatnonzero((sign * cl_c >= cap) & (sign * fine >= 2.0)
                                   & (sign * fine <= sign * fine[k_inc]))
            k = reach[np.argmin(sign * fine[reach])] if reach.size else k_inc
            stall.append(k)
        kp, kn = stall
        a_sp, a_sn = fine[kp], fine[kn]
        cd0 = float(np.interp(0.0, fine, cd_c))
        att = (ALPHAS >= a_sn) & (ALPHAS <= a_sp)
        cl[att, j] = np.interp(ALPHAS[att], fine, cl_c)
        cd[att, j] = np.interp(ALPHAS[att], fine, cd_c)
        cm[att, j] = np.interp(ALPHAS[att], fine, cm_c)
        up = ALPHAS > a_sp
        c1, d1, m1 = post_stall(ALPHAS[up], a_sp, cl_c[kp], cd_c[kp], cm_c[kp], cd0)
        cl[up, j], cd[up, j], cm[up, j] = c1, d1, m1
        dn = ALPHAS < a_sn
        c2, d2, m2 = post_stall(-ALPHAS[dn], -a_sn, -cl_c[kn], cd_c[kn], -cm_c[kn], cd0)
        cl[dn, j], cd[dn, j], cm[dn, j] = -c2, d2, -m2
        info.append(dict(mach=m, re=re, stall_pos=a_sp, clmax=cl_c[kp], stall_neg=a_sn,
                         clmin=cl_c[kn], cd0=cd0,
                         min_confidence=float(conf[np.abs(fine) <= 10].min())))
    # +-180 deg are the same physical state
    for v in (cl, cd, cm):
        v[0] = v[-1] = 0.5 * (v[0] + v[-1])
    table = C81Table(rotor.title, C81Block(MACHS, ALPHAS, cl), C81Block(MACHS, ALPHAS, cd),
                     C81Block(MACHS, ALPHAS, cm))
    return table, info


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outdir", default=str(Path(__file__).resolve().parents[1]
                                             / "src" / "rotoruq" / "data" / "airfoils"))
    ap.add_argument("--model-size", default="xlarge")
    args = ap.parse_args(argv)
    import aerosandbox
    import neuralfoil

    print(f"aerosandbox {aerosandbox.__version__}, neuralfoil {neuralfoil.__version__}, "
          f"model_size {args.model_size}")
    outdir = Path(args.outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    for rotor in ROTORS:
        table, info = make_table(rotor, args.model_size)
        path = write_c81(table, outdir / f"{rotor.key}.c81")
        back = read_c81(path)
        print(f"\n## {rotor.key}: {rotor.note}")
        print("| Mach | Re | stall + (deg) | CL max | stall - (deg) | CL min | CD(0) |"
              " NeuralFoil confidence (min, abs(alpha)<=10) |")
        print("|---|---|---|---|---|---|---|---|")
        for d in info:
            print(f"| {d['mach']:.2f} | {d['re']:.3g} | {d['stall_pos']:.2f} | {d['clmax']:.3f} "
                  f"| {d['stall_neg']:.2f} | {d['clmin']:.3f} | {d['cd0']:.4f} "
                  f"| {d['min_confidence']:.2f} |")
        fit = fit_airfoil(back, MACHS[MACHS <= 0.7])
        print()
        print(fit.to_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
