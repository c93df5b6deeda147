"""Every table of the reference study's chapters 3 and 4 (``shared/spec/thesis.md``),
transcribed as data, each cell paired with where our value comes from.

A cell is ``(thesis_value, source)``. ``source`` is

* ``"STEP:KEY"`` - scalar ``KEY`` of step ``STEP`` of the table's study (see
  :class:`rotoruq.results.StepResult`), e.g. ``"sens_aero:S/thrust/cla_m03"``;
* ``"model:PRESET:NAME"`` - a property of the rotor preset, or a nominal airfoil coefficient;
* ``"data:COLUMN@H"`` - the shipped GVPM measurements (column at H/R = H);
* ``None`` - nothing of ours to compare (the cell shows the thesis value only).

Numbers are as printed in the thesis (its misprints included, e.g. ``3.146-2`` in table
3.7 read as 3.146e-2, and ``3.4e-3`` for C_D0(0.4) in table 4.7), except the Bo105 torque
means of tables 3.11 and 3.13, given in our sign convention (positive absorbed torque; the
thesis prints MBDyn's negative sign) so that one convention holds per quantity.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ReferenceTable", "TABLES", "table"]

Cell = tuple[float | None, str | None]


@dataclass(frozen=True)
class ReferenceTable:
    """One thesis table: number ("3.4"), caption, the study it belongs to ("validation" or
    "experiment"), column headers and rows ``(label, (cell, ...))``."""

    number: str
    caption: str
    study: str
    columns: tuple[str, ...]
    rows: tuple[tuple[str, tuple[Cell, ...]], ...]
    note: str = ""


# One unit per quantity: the model's link law is per unit strain (K_p an axial stiffness EA)
_KP_UNIT = ("K_p and C_p in N and N s, the model's per-unit-strain link law (an axial "
            "stiffness EA); the thesis prints N/m and N s/m for the same numbers.")


def _t(number, caption, study, columns, rows, note="") -> ReferenceTable:
    return ReferenceTable(number, caption, study, tuple(columns),
                          tuple((lab, tuple(cells)) for lab, cells in rows), note)


# --------------------------------------------------------------------------------- chapter 3
_BO = "model:bo105:"
_CLA3 = [("C_La(0.1)", "cla_m01"), ("C_La(0.2)", "cla_m02"), ("C_La(0.3)", "cla_m03"),
         ("C_La(0.4)", "cla_m04"), ("C_La(0.5)", "cla_m05"), ("C_La(0.6)", "cla_m06")]

T3_1 = _t("3.1", "Model technical features (Bo105)", "validation", ["Value"], [
    ("Angular velocity Omega [rad/s]", [(44.4, _BO + "omega")]),
    ("Rotor radius R [m]", [(4.912, _BO + "radius")]),
    ("Hinge offset d [m]", [(0.746, _BO + "hinge_offset")]),
    ("Flap stiffness K_f [N m/rad]", [(15035.467, _BO + "k_flap")]),
    ("Flap damping C_f [N m s/rad]", [(0.0, _BO + "c_flap")]),
    ("Lag stiffness K_l [N m/rad]", [(70698.042, _BO + "k_lag")]),
    ("Lag damping C_l [N m s/rad]", [(4093.662, _BO + "c_lag")]),
    ("Pitch link length L_p [m]", [(0.2, None)]),
    ("Pitch link stiffness K_p [N]", [(1.0e9, _BO + "k_pitch_link")]),
    ("Pitch link damping C_p [N s]", [(100.0, _BO + "c_pitch_link")]),
    ("Pitch inertia I_p [kg m^2]", [(0.257, _BO + "pitch_inertia")]),
    ("Flap inertia I_f [kg m^2]", [(140.001, None)]),
    ("Lag inertia I_l [kg m^2]", [(140.257, None)]),
    ("Blade span b [m]", [(3.812, None)]),
    ("Blade chord c [m]", [(0.270, _BO + "chord")]),
    ("Twist slope [deg/m] (ours: total twist [deg])", [(-6.2, _BO + "twist_deg")]),
], note="Our twist is -6.2 deg over the whole blade (see the bo105 preset), not per metre. "
   + _KP_UNIT)

T3_2 = _t("3.2", "Interpolated aerodynamic lift coefficients (NACA 23012)", "validation",
          ["C_La [1/deg]", "C_L0"], [
    (f"Mach {m}", [(a, _BO + f"cla_m0{i}"), (b, _BO + f"cl0_m0{i}")])
    for i, m, a, b in [(1, 0.1, 0.1075, 0.1270), (2, 0.2, 0.1075, 0.1270),
                       (3, 0.3, 0.1075, 0.1270), (4, 0.4, 0.1126, 0.1270),
                       (5, 0.5, 0.1172, 0.1405), (6, 0.6, 0.1135, 0.1327)]
], note="No public NACA 23012 c81 table exists; ours are fits of the bundled table rotoruq "
   "generates itself, so differences here are differences of airfoil data.")

T3_3 = _t("3.3", "Input variable distributions (Gaussian)", "validation", ["Mean", "Std"], [
    *[(lab, [(mu, f"sens_aero:input_mean/{k}"), (sd, f"sens_aero:input_std/{k}")])
      for (lab, k), mu, sd in zip(_CLA3, [0.1075, 0.1075, 0.1075, 0.1126, 0.1172, 0.1135],
                                  [5.375e-3, 5.375e-3, 5.375e-3, 5.630e-3, 5.860e-3,
                                   5.675e-3], strict=True)],
    ("K_f [N/rad]", [(15035, "sens_struct:input_mean/k_flap"),
                     (751, "sens_struct:input_std/k_flap")]),
    ("K_l [N/rad]", [(70698, "sens_struct:input_mean/k_lag"),
                     (3534, "sens_struct:input_std/k_lag")]),
    ("K_p [N]", [(1.0e9, "sens_struct:input_mean/k_pitch_link"),
                   (5.0e7, "sens_struct:input_std/k_pitch_link")]),
])


def _sobol_rows(step, response, rows):
    return [(lab, [(s, f"{step}:S/{response}/{k}"), (t, f"{step}:T/{response}/{k}")])
            for lab, k, s, t in rows]


T3_4 = _t("3.4", "Aerodynamic sensitivity results with respect to mean thrust", "validation",
          ["Main S_i", "Total T_i"], _sobol_rows("sens_aero", "thrust", [
              ("C_La(0.1)", "cla_m01", 7.013e-4, 2.615e-4),
              ("C_La(0.2)", "cla_m02", 2.270e-3, 3.709e-3),
              ("C_La(0.3)", "cla_m03", 5.424e-1, 5.153e-1),
              ("C_La(0.4)", "cla_m04", 2.502e-3, 2.107e-3),
              ("C_La(0.5)", "cla_m05", 1.924e-1, 1.905e-1),
              ("C_La(0.6)", "cla_m06", 2.395e-1, 2.457e-1)]))

T3_5 = _t("3.5", "Structural sensitivity results with respect to mean thrust", "validation",
          ["Main S_i", "Total T_i"], _sobol_rows("sens_struct", "thrust", [
              ("K_f", "k_flap", 8.938e-1, 8.893e-1),
              ("K_l", "k_lag", 7.458e-2, 8.763e-2),
              ("K_p", "k_pitch_link", 2.417e-4, 1.185e-5)]))

T3_6 = _t("3.6", "Mixed sensitivity results with respect to mean thrust", "validation",
          ["Main S_i", "Total T_i"], _sobol_rows("sens_mixed", "thrust", [
              ("C_La(0.3)", "cla_m03", 5.424e-1, 5.153e-1),
              ("C_La(0.6)", "cla_m06", 2.396e-1, 2.457e-1),
              ("C_La(0.5)", "cla_m05", 1.924e-1, 1.905e-1),
              ("K_f", "k_flap", 7.435e-2, 8.093e-2)]))

_CAL3 = [("C_La(0.3)", "cla_m03"), ("C_La(0.5)", "cla_m05"), ("C_La(0.6)", "cla_m06"),
         ("K_f", "k_flap")]


def _moments(step, rows):
    return [(lab, [(m, f"{step}:mean/{k}"), (s, f"{step}:std/{k}"),
                   (g, f"{step}:skewness/{k}"), (c, f"{step}:kurtosis/{k}")])
            for (lab, k), (m, s, g, c) in rows]


T3_7 = _t("3.7", "Bayes calibration results", "validation",
          ["Mean", "Std", "Skewness", "Kurtosis"], _moments("bayes", zip(_CAL3, [
              (1.082e-1, 7.844e-3, -1.468e-1, -6.556e-1),
              (1.170e-1, 1.298e-2, -1.471e-1, -9.951e-1),
              (1.154e-1, 1.034e-2, 3.146e-2, -5.321e-1),
              (14995.33, 269.75, 1.936e-2, -1.1016)], strict=True)),
          note="Kurtosis is excess kurtosis (0 for a normal distribution), as Dakota prints.")

T3_8 = _t("3.8", "Prior (uniform) and calibrated distributions", "validation",
          ["Lower", "Upper", "Mean", "Std"], [
              (lab, [(lo, f"bayes:input_lower/{k}"), (hi, f"bayes:input_upper/{k}"),
                     (m, f"bayes:mean/{k}"), (s, f"bayes:std/{k}")])
              for (lab, k), (lo, hi, m, s) in zip(_CAL3, [
                  (0.09, 0.14, 0.1082, 7.844e-3), (0.09, 0.14, 0.1170, 1.298e-2),
                  (0.09, 0.14, 0.1154, 1.034e-2), (11000.0, 18000.0, 14995.33, 269.75)],
                  strict=True)])

T3_9 = _t("3.9", "Real (data-generating) and calibrated distributions", "validation",
          ["Real mean", "Real std", "Calibrated mean", "Calibrated std"], [
              (lab, [(rm, f"truth:input_mean/{k}"), (rs, f"truth:input_std/{k}"),
                     (m, f"bayes:mean/{k}"), (s, f"bayes:std/{k}")])
              for (lab, k), (rm, rs, m, s) in zip(_CAL3, [
                  (0.1075, 5.375e-3, 0.1082, 7.844e-3), (0.1172, 5.860e-3, 0.1170, 1.298e-2),
                  (0.1135, 5.675e-3, 0.1154, 1.034e-2),
                  (15035.467, 751.774, 14995.33, 269.75)], strict=True)])


def _cuu_inputs(step, truth, rows):
    return [(lab, [(em, f"{truth}:input_mean/{k}"), (es, f"{truth}:input_std/{k}"),
                   (cm, f"{step}:mean/{k}"), (cs, f"{step}:std/{k}")])
            for (lab, k), (em, es, cm, cs) in rows]


def _cuu_outputs(step, truth, rows):
    return [(lab, [(em, f"{truth}:mean/{k}"), (es, f"{truth}:std/{k}"),
                   (cm, f"{step}:calibrated_out_mean/{k}"),
                   (cs, f"{step}:calibrated_out_std/{k}")])
            for (lab, k), (em, es, cm, cs) in rows]


_IO = ["Exp. mean", "Exp. std", "Calibrated mean", "Calibrated std"]
T3_10 = _t("3.10", "Mixed CUU results (inputs)", "validation", _IO, _cuu_inputs(
    "cuu_mixed", "cuu_truth_mixed", zip(_CAL3, [
        (0.10825, 3.608e-3, 0.10825, 1.896e-3), (0.11700, 3.900e-3, 0.11700, 6.870e-3),
        (0.11538, 3.867e-3, 0.11538, 3.506e-3), (14995.33, 499.844, 14995.33, 1523.05)],
        strict=True)))

_LOADS3 = [("Thrust [N]", "thrust"), ("Torque [N m]", "torque")]
# One sign convention per quantity: torque is the torque the rotor absorbs (positive).
_TORQUE_SIGN = ("Torque is the torque the rotor absorbs (positive); the thesis prints it "
                "negative (MBDyn's sign convention), so its torque means are shown here with "
                "the sign changed. Standard deviations are unaffected.")
T3_11 = _t("3.11", "Load statistical moments (mixed CUU, LHS 300)", "validation", _IO,
           _cuu_outputs("cuu_mixed", "cuu_truth_mixed", zip(_LOADS3, [
               (2009.065, 11.453, 2009.182, 11.533),
               (2360.925, 2.100, 2360.945, 2.120)], strict=True)),
           note=_TORQUE_SIGN)

T3_12 = _t("3.12", "Aerodynamic CUU results (inputs)", "validation", _IO, _cuu_inputs(
    "cuu_aero", "cuu_truth_aero", zip(_CAL3[:3], [
        (0.10825, 3.608e-3, 0.10825, 3.223e-3), (0.11700, 3.900e-3, 0.11700, 4.356e-3),
        (0.11538, 3.867e-3, 0.11538, 3.803e-3)], strict=True)))

T3_13 = _t("3.13", "Final load statistical moments (aerodynamic CUU, LHS 300)", "validation",
           _IO, _cuu_outputs("cuu_aero", "cuu_truth_aero", zip(_LOADS3, [
               (2009.067, 11.423, 2009.102, 11.470),
               (2360.925, 2.093, 2360.931, 2.106)], strict=True)),
           note=_TORQUE_SIGN)

# --------------------------------------------------------------------------------- chapter 4
_GV = "model:gvpm:"
_LOADS4 = [("Thrust T [N]", "thrust"), ("Roll [N m]", "roll"), ("Pitch [N m]", "pitch"),
           ("Torque [N m]", "torque")]

T4_1 = _t("4.1", "Experimental load mean values", "experiment",
          ["Thrust [N]", "Roll [N m]", "Pitch [N m]", "Torque [N m]"], [
              (f"H/R = {h}", [(v, f"data:{k}@{h}") for v, (_, k) in zip(vals, _LOADS4,
                                                                        strict=True)])
              for h, vals in [(4, (25.6849, -0.0388, -0.2371, 1.5621)),
                              (3, (25.8241, -0.1483, -0.2193, 1.5835)),
                              (2, (29.0067, -0.2525, -0.3082, 1.7789)),
                              (1, (35.8256, -0.2401, -0.2490, 1.8520))]],
          note="Shipped as rotoruq/data/gvpm_measurements.csv with Omega per height.")

T4_2 = _t("4.2", "Model technical features (GVPM rotor)", "experiment", ["Value"], [
    ("Blade span b [m]", [(0.425, None)]),
    ("Hub radius r [m]", [(0.06, _GV + "root_cutout")]),
    ("Rotor radius R [m]", [(0.485, _GV + "radius")]),
    ("Blade chord c [m]", [(0.042, _GV + "chord")]),
    ("Axial stiffness EA [N]", [(1.0e6, None)]),
    ("Shear stiffness GA_y [N]", [(1.0e6, None)]),
    ("Shear stiffness GA_z [N]", [(1.0e6, None)]),
    ("Bending stiffness EI_y [N m^2]", [(7.0, _GV + "ei_flap")]),
    ("Bending stiffness EI_z [N m^2]", [(2.26e3, None)]),
    ("Torsional stiffness GJ [N m^2]", [(1.0e2, None)]),
    ("Pitch link stiffness K_p [N]", [(10.0, _GV + "k_pitch_link")]),
    ("Pitch link damping C_p [N s]", [(0.05, _GV + "c_pitch_link")]),
], note=_KP_UNIT)

T4_3 = _t("4.3", "Interpolated aerodynamic lift coefficients (NACA 0012)", "experiment",
          ["C_La [1/deg]", "C_L0"], [
              (f"Mach {m}", [(a, _GV + f"cla_m{s}"), (b, _GV + f"cl0_m{s}")])
              for s, m, a, b in [("00", 0.0, 0.1055, 0.0), ("02", 0.2, 0.1055, 0.0),
                                 ("03", 0.3, 0.1080, 0.008), ("04", 0.4, 0.1112, 0.0)]])

T4_4 = _t("4.4", "Interpolated aerodynamic drag coefficients (NACA 0012)", "experiment",
          ["C_Da2", "C_Da", "C_D0"], [
              (f"Mach {m}", [(a2, _GV + f"cda2_m{s}"), (a1, _GV + f"cda_m{s}"),
                             (c0, _GV + f"cd0_m{s}")])
              for s, m, a2, a1, c0 in [("00", 0.0, 9.2e-5, 0.0, 0.0079),
                                       ("02", 0.2, 9.2e-5, 0.0, 0.0079),
                                       ("03", 0.3, 1.025e-4, 0.0, 0.0077),
                                       ("04", 0.4, 1.554e-4, 0.0, 0.0068)]])

_CMD = [("Coll", "collective_deg"), ("Lat", "lateral_deg"), ("Long", "longitudinal_deg")]
T4_5 = _t("4.5", "Command probability distributions (uniform)", "experiment",
          ["Lower", "Upper"], [
              (lab, [(lo, f"sens_commands:input_lower/{k}"),
                     (hi, f"sens_commands:input_upper/{k}")])
              for (lab, k), (lo, hi) in zip(_CMD, [(4.0, 8.0), (-2.0, 2.0), (-2.0, 2.0)],
                                            strict=True)])

_RESP4 = ["thrust", "roll", "pitch", "power"]
_RESP4_H = ["Thrust T", "Roll M_x", "Pitch M_y", "Power P"]


def _sens4(step, rows):
    return [(lab, [(v, f"{step}:S/{r}/{k}") for v, r in zip(vals, _RESP4, strict=True)])
            for lab, k, vals in rows]


T4_6 = _t("4.6", "Command sensitivity results (main indices)", "experiment", _RESP4_H,
          _sens4("sens_commands", [
              ("Coll", "collective_deg", (9.06e-1, 6.38e-4, 2.41e-3, 9.10e-1)),
              ("Lat", "lateral_deg", (2.16e-3, 7.72e-1, 1.86e-1, 2.75e-3)),
              ("Long", "longitudinal_deg", (3.95e-4, 1.16e-1, 7.93e-1, 1.12e-3))]))

_AERO4 = [("C_La(M=0)", "cla_m00"), ("C_La(M=0.2)", "cla_m02"), ("C_La(M=0.3)", "cla_m03"),
          ("C_La(M=0.4)", "cla_m04"), ("C_D0(M=0)", "cd0_m00"), ("C_D0(M=0.2)", "cd0_m02"),
          ("C_D0(M=0.3)", "cd0_m03"), ("C_D0(M=0.4)", "cd0_m04")]
T4_7 = _t("4.7", "Overall probability distributions (Gaussian)", "experiment",
          ["Mean", "Std"], [
              *[(lab, [(m, f"sens_aero:input_mean/{k}"), (s, f"sens_aero:input_std/{k}")])
                for (lab, k), (m, s) in zip(_AERO4, [
                    (0.1055, 5.275e-3), (0.1055, 5.275e-3), (0.1080, 5.4e-3),
                    (0.1112, 5.56e-3), (0.0079, 3.95e-4), (0.0079, 3.95e-4),
                    (0.0077, 3.85e-4), (0.0068, 3.4e-3)], strict=True)],
              ("K_p", [(15.0, "sens_mixed:input_mean/k_pitch_link"),
                       (0.75, "sens_mixed:input_std/k_pitch_link")]),
              ("EI_y", [(10.0, "sens_mixed:input_mean/ei_flap"),
                        (0.5, "sens_mixed:input_std/ei_flap")]),
          ], note="C_D0(0.4): the thesis prints 3.4e-3; its own rule (mu +- 3 sigma = 15 %) "
                  "gives 3.4e-4, which we use.")

T4_8 = _t("4.8", "Aerodynamic sensitivity results (main indices)", "experiment", _RESP4_H,
          _sens4("sens_aero", [(lab, k, v) for (lab, k), v in zip(_AERO4, [
              (1.55e-2, 3.26e-3, 5.04e-4, 1.23e-2), (2.33e-1, 6.22e-1, 1.84e-1, 1.05e-1),
              (8.11e-1, 3.95e-1, 7.55e-1, 3.67e-1), (8.44e-5, 3.77e-5, 1.75e-4, 1.14e-5),
              (1.50e-6, 4.56e-6, 3.05e-7, 7.46e-4), (4.29e-5, 8.01e-5, 3.17e-4, 3.4e-1),
              (3.31e-5, 2.10e-5, 1.88e-4, 2.83e-1), (2.37e-7, 3.04e-7, 5.68e-7, 5.24e-5)],
              strict=True)]))

_MIX4 = [("C_La(M=0.2)", "cla_m02"), ("C_La(M=0.3)", "cla_m03"), ("C_D0(M=0.2)", "cd0_m02"),
         ("C_D0(M=0.3)", "cd0_m03"), ("K_p", "k_pitch_link"), ("EI_y", "ei_flap")]
T4_9 = _t("4.9", "Overall sensitivity results (main indices)", "experiment", _RESP4_H,
          _sens4("sens_mixed", [(lab, k, v) for (lab, k), v in zip(_MIX4, [
              (3.46e-2, 1.67e-1, 6.25e-2, 2.48e-2), (7.82e-1, 4.21e-1, 1.03e-1, 4.78e-1),
              (6.22e-3, 2.69e-3, 3.81e-3, 1.06e-1), (1.62e-2, 7.62e-3, 8.00e-4, 2.58e-1),
              (1.40e-1, 4.61e-1, 7.86e-1, 1.09e-1), (5.43e-2, 6.84e-3, 9.03e-2, 4.28e-2)],
              strict=True)]))

_CAL4 = _MIX4 + _CMD
T4_10 = _t("4.10", "Variable probability distributions (uniform priors)", "experiment",
           ["Lower", "Upper"], [
               (lab, [(lo, f"{st}:input_lower/{k}"), (hi, f"{st}:input_upper/{k}")])
               for (lab, k), (lo, hi), st in zip(_CAL4, [
                   (0.09, 0.125), (0.09, 0.125), (0.007, 0.015), (0.007, 0.015), (10.0, 20.0),
                   (6.0, 10.0), (4.0, 8.0), (-2.0, 2.0), (-2.0, 2.0)],
                   ["bayes"] * 4 + ["bayes_moments"] * 2 + ["bayes"] + ["bayes_moments"] * 2,
                   strict=True)],
           note="K_p, EI_y, Lat and Long are the priors of the first (moments-only) stage; the "
                "second stage uses that stage's posterior as its prior, as the thesis does.")

T4_11 = _t("4.11", "Bayes calibration results", "experiment",
           ["Mean", "Std", "Skewness", "Kurtosis"], _moments("bayes", zip(_CAL4, [
               (0.1072, 9.378e-3, -2.778e-2, -1.085), (0.1078, 9.238e-3, 4.008e-2, -1.028),
               (0.0192, 2.151e-3, 4.601e-2, -1.083), (0.0195, 2.157e-3, 8.497e-3, -1.123),
               (15.024, 2.658, 6.830e-3, -1.051), (8.499, 0.824, 2.523e-2, -1.209),
               (5.411, 0.331, -9.214e-1, 1.556), (0.1698, 0.727, -1.187e-1, -3.830e-1),
               (-0.2955, 0.756, 3.345e-1, -2.209e-1)], strict=True)))

_PRED = ["Mean", "Std", "Exp data", "N std devs"]
_PRED_ROWS = [("Thrust T [N]", "thrust"), ("Roll [N m]", "roll"), ("Pitch [N m]", "pitch"),
              ("Power P [W]", "power")]


def _pred(step, label, rows):
    return [(lab, [(m, f"{step}:mean/{k}{label}"), (s, f"{step}:std/{k}{label}"),
                   (d, f"{step}:data/{k}{label}"), (n, f"{step}:nstd/{k}{label}")])
            for (lab, k), (m, s, d, n) in rows]


T4_12 = _t("4.12", "Model (posterior LHS 500) and experimental loads at 4R", "experiment",
           _PRED, _pred("forward_4r", "@4", zip(_PRED_ROWS, [
               (26.1148, 3.5505, 25.6849, 0.12), (-0.0069, 0.5604, -0.0388, 0.057),
               (-0.2501, 0.5661, -0.2371, 0.023), (353.4290, 47.0523, 350.9062, 0.05)],
               strict=True)))

T4_13 = _t("4.13", "Command standard deviations (CUU)", "experiment",
           ["Mean", "Initial std", "Calibrated std"], [
               (lab + " [deg]", [(m, f"cuu_commands:mean/{k}"),
                                 (s0, f"cuu_commands:initial_std/{k}"),
                                 (s1, f"cuu_commands:std/{k}")])
               for (lab, k), (m, s0, s1) in zip(_CMD, [
                   (5.4114, 0.3311, 0.1292), (0.1698, 0.7268, 0.2273),
                   (-0.2955, 0.7557, 0.2282)], strict=True)])

T4_14 = _t("4.14", "Load standard deviations (LHS 500 before/after CUU)", "experiment",
           ["Initial std", "Exp std (target)", "Calibrated std"], [
               (lab, [(a, f"cuu_commands:initial_out_std/{k}"),
                      (b, f"cuu_commands:target_std/{k}"),
                      (c, f"cuu_commands:calibrated_out_std/{k}")])
               for (lab, k), (a, b, c) in zip(_PRED_ROWS, [
                   (3.000, 0.8600, 1.1638), (0.5368, 0.1670, 0.1665),
                   (0.5469, 0.1670, 0.1669), (30.3619, 11.6600, 11.6875)], strict=True)])

T4_15 = _t("4.15", "Input normal distributions for the IGE forward UQ", "experiment",
           ["Mean", "Std"], [
               (lab, [(m, f"forward_ige:input_mean/{k}"), (s, f"forward_ige:input_std/{k}")])
               for (lab, k), (m, s) in zip(_CAL4, [
                   (0.1072, 9.378e-3), (0.1075, 9.238e-3), (0.0109, 2.151e-3),
                   (0.0109, 2.157e-3), (15.0239, 2.658), (8.4990, 0.824), (5.4114, 0.331),
                   (0.1698, 0.727), (-0.2955, 0.756)], strict=True)],
           note="The thesis's C_D0 means here (0.0109) differ from its table 4.11 (0.0192, "
                "0.0195); ours are the posterior of our calibration in both places.")

T4_16 = _t("4.16", "2R altitude loads comparison", "experiment", _PRED,
           _pred("forward_ige", "@2", zip(_PRED_ROWS, [
               (27.8528, 3.8174, 29.0067, 0.3022), (-0.0071, 0.5583, -0.2525, 0.4395),
               (-0.2491, 0.5649, -0.3082, 0.1046), (362.8009, 49.1283, 399.4418, 0.7458)],
               strict=True)))

T4_17 = _t("4.17", "1R altitude loads comparison", "experiment", _PRED,
           _pred("forward_ige", "@1", zip(_PRED_ROWS, [
               (31.4166, 4.3563, 35.8256, 1.0121), (-0.0081, 0.5528, -0.2401, 0.4197),
               (-0.2472, 0.5631, -0.2490, 0.0032), (375.9794, 52.5775, 413.0807, 0.7056)],
               strict=True)))


def _coef(resp, rows):
    return [(f"{h}R", [(m, f"ground_effect:mean/{resp}@{h}"),
                       (s, f"ground_effect:std/{resp}@{h}"),
                       (d, f"ground_effect:data/{resp}@{h}"),
                       (n, f"ground_effect:nstd/{resp}@{h}")]) for h, (m, s, d, n) in rows]


T4_18 = _t("4.18", "Thrust coefficient C_T / C_T(4R test), pitch link uncertain", "experiment",
           _PRED, _coef("ct", [(4, (1.0069, 5.588e-2, 1.000, 0.1235)),
                               (3, (1.0068, 5.579e-2, 1.0060, 0.0143)),
                               (2, (1.0760, 6.267e-2, 1.1303, 0.8664)),
                               (1, (1.2305, 8.018e-2, 1.4148, 2.2985))]))

T4_19 = _t("4.19", "Torque coefficient C_Q / C_Q(4R test), pitch link uncertain", "experiment",
           _PRED, _coef("cq", [(4, (0.9970, 4.367e-2, 1.000, 0.0687)),
                               (3, (0.9970, 4.359e-2, 1.0143, 0.3968)),
                               (2, (1.0251, 4.844e-2, 1.1397, 2.3658)),
                               (1, (1.0837, 6.076e-2, 1.2026, 1.9568))]))

TABLES: tuple[ReferenceTable, ...] = (
    T3_1, T3_2, T3_3, T3_4, T3_5, T3_6, T3_7, T3_8, T3_9, T3_10, T3_11, T3_12, T3_13,
    T4_1, T4_2, T4_3, T4_4, T4_5, T4_6, T4_7, T4_8, T4_9, T4_10, T4_11, T4_12, T4_13, T4_14,
    T4_15, T4_16, T4_17, T4_18, T4_19,
)


def table(number: str) -> ReferenceTable:
    for t in TABLES:
        if t.number == number:
            return t
    raise KeyError(f"no thesis table {number!r}; tables: {', '.join(t.number for t in TABLES)}")
