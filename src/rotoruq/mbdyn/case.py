"""One MBDyn case (hover or forward flight): fill a template, write the sample's c81
table, run, extract loads.

Templates are MBDyn input files with rotoruq's ``{label}`` fields
(:mod:`rotoruq.evaluation.templates`). The bundled ones live in ``rotoruq/mbdyn/templates``
(``rigid``); any other path is a user template. :func:`template_values` documents every field
rotoruq fills.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import ParameterError
from ..evaluation.templates import fill_template, template_fields
from ..safety import real_dir, write_file
from .extract import HubLoads, hub_loads
from .solver import run_mbdyn

if TYPE_CHECKING:
    from ..rotor.airfoil import Airfoil
    from ..rotor.c81 import C81Table
    from ..rotor.presets import RotorPreset

__all__ = ["TEMPLATES", "CaseSettings", "template_text", "template_values", "run_case",
           "rigid_equivalent", "sample_table", "GEOMETRY_FIELDS", "OGE_DISTANCE",
           "FLIGHT_INPUTS", "TEMPLATE_DEFAULTS"]

#: Bundled templates, by name.
TEMPLATES = ("rigid", "elastic")
#: Preset properties every template may use (lengths m, angles deg, speed of sound m/s,
#: mass per length kg/m).
GEOMETRY_FIELDS = ("radius", "root_cutout", "chord", "twist_deg", "speed_of_sound",
                   "blade_mass_per_length", "pitch_horn_arm", "pitch_link_length")
#: Out of ground effect the ground node is put this many radii below the hub (MBDyn's
#: Cheeseman-Bennett factor is then 1 - 6e-14).
OGE_DISTANCE = 1.0e6
#: Forward-flight inputs every template may use, with their hover values: the advance ratio
#: mu (free stream in the disk plane over Omega R) and the shaft angle [deg, positive tilting
#: the disk forward], as the built-in :class:`~rotoruq.rotor.forward.ForwardRotorModel`.
FLIGHT_INPUTS = {"advance_ratio": 0.0, "shaft_angle_deg": 0.0}
#: Inputs a bundled template takes a value of its own for when the case does not give them
#: (instead of the preset's): the rigid template's blades fly no cyclic unless told to, as
#: they did before they could (and as :func:`rigid_equivalent`).
TEMPLATE_DEFAULTS = {"rigid": {"lateral_deg": 0.0, "longitudinal_deg": 0.0}}
AIRFOIL_FILE = "airfoil.c81"
#: Fields rotoruq derives from rotor inputs: a template using the field uses the inputs.
DERIVED_FROM = {"ground_distance": ("height_over_radius",), "c81_stall_tolerance":
                ("advance_ratio",), "final_time": ("omega",),
                "time_step": ("omega",)}


@dataclass(frozen=True)
class CaseSettings:
    """Time integration of a case.

    Parameters
    ----------
    revolutions : int, optional
        Rotor revolutions simulated (default 12; at least ``2 * average``).
    steps_per_rev : int, optional
        Time steps per revolution (default 72; at least 8).
    average : int, optional
        The loads are averaged over the last ``average`` revolutions (default 2).
    tolerance : float, optional
        The ``average`` revolutions before them must agree within this, relative (default
        2e-3), or the case did not reach a periodic state.
    timeout : float or None, optional
        Seconds MBDyn may run (default 600; None: no limit).
    """

    revolutions: int = 12
    steps_per_rev: int = 72
    average: int = 2
    tolerance: float = 2e-3
    timeout: float | None = 600.0

    def __post_init__(self):
        if self.steps_per_rev < 8 or self.average < 1 or self.revolutions < 2 * self.average:
            raise ParameterError(f"need steps_per_rev >= 8, average >= 1 and revolutions >= "
                                 f"2 * average, got {self}")


def template_text(template: str | os.PathLike) -> tuple[str, Path]:
    """Text and path of a template: a bundled name (:data:`TEMPLATES`) or a file path."""
    if str(template) in TEMPLATES:
        ref = resources.files("rotoruq") / "mbdyn" / "templates" / f"{template}.mbd"
        return ref.read_text(), Path(str(ref))
    p = Path(template)
    if not p.is_file():
        raise ParameterError(f"MBDyn template {str(template)!r} is neither a bundled template "
                             f"({', '.join(TEMPLATES)}) nor an existing file")
    return p.read_text(), p


def template_values(preset: RotorPreset, inputs: Mapping[str, float],
                    settings: CaseSettings, defaults: Mapping[str, float] | None = None
                    ) -> dict[str, Any]:
    """Every value a template can use.

    - the rotor inputs (:data:`rotoruq.rotor.model.ROTOR_INPUTS`, deg and SI) and the
      forward-flight ones (:data:`FLIGHT_INPUTS`, hover by default): the preset's values,
      overridden by ``inputs``;
    - the preset's geometry (:data:`GEOMETRY_FIELDS`);
    - ``ground_distance`` [m]: hub height above the ground, height_over_radius * R
      (``OGE_DISTANCE`` * R when height_over_radius is inf);
    - ``airfoil_file``: the sample's c81 table (free format), written next to the input;
    - ``c81_stall_tolerance``: the ``tolerance`` of MBDyn's ``c81 data`` (how far the lift
      slope may fall below its value at zero incidence before MBDyn takes the section as
      stalled): MBDyn's default 1e-6 in hover, 1e30 (no stall found: stall slope 0) in
      forward flight. MBDyn 1.7.3's steady c81 section (``c81_aerod2_u`` in
      ``aero/aerodc81.c``) multiplies the lift by 1 / cos(gamma), gamma the spanwise sweep
      of the section's flow, only where the lift over the incidence falls below the stall
      slope, and unlike the formula it cites (COE0 in ``aero/aerod2.f``) keeps the table's
      lift elsewhere, so the lift jumps by (1 / cos(gamma) - 1) (cl - cl0) where the two
      meet. In hover gamma is near 0; in forward flight the inboard sections of the
      retreating blade see a sweep of up to MBDyn's 60 deg clamp and the jump stopped MBDyn's
      Newton iteration on the elastic blades. With the stall slope 0 the two branches meet
      where cl = cl0, so the lift is continuous: the table's lift wherever lift and incidence
      have one sign (the built-in rotor neglects the radial flow altogether), MBDyn's
      1 / cos(gamma) where they differ (reverse flow);
    - ``final_time``, ``time_step`` [s] from ``settings`` and omega.

    Parameters
    ----------
    preset : RotorPreset
        The rotor.
    inputs : mapping of str to float
        Rotor inputs overriding the preset's values (deg and SI).
    settings : CaseSettings
        The time integration.
    defaults : mapping of str to float, optional
        Values replacing the preset's for inputs ``inputs`` leaves out (a bundled template's
        :data:`TEMPLATE_DEFAULTS`).
    """
    from ..rotor.model import RotorModel

    base = {**RotorModel(preset, names_in=[]).defaults(), **FLIGHT_INPUTS}
    unknown = sorted(k for k in inputs if k not in base)
    if unknown:
        import difflib

        hints = [f"{k!r} (did you mean {c[0]!r}?)" if (c := difflib.get_close_matches(k, base, 1))
                 else repr(k) for k in unknown]
        raise ParameterError(f"{', '.join(hints)}: not rotor inputs of preset {preset.name!r}; "
                             f"valid: {', '.join(base)}")
    vals: dict[str, Any] = {**base, **dict(defaults or {}),
                            **{k: float(v) for k, v in inputs.items()}}
    vals.update({k: float(getattr(preset, k)) for k in GEOMETRY_FIELDS})
    h = vals["height_over_radius"]
    if not h > 0.25:
        raise ParameterError(f"height_over_radius must be > 0.25 (MBDyn clamps the ground "
                             f"effect below R/4), got {h}")
    mu, alpha = vals["advance_ratio"], vals["shaft_angle_deg"]
    if not 0.0 <= mu <= 1.0 or not abs(alpha) < 90.0:
        raise ParameterError(f"advance_ratio must be in [0, 1] and |shaft_angle_deg| < 90, got "
                             f"{mu} and {alpha}")
    vals["ground_distance"] = (OGE_DISTANCE if math.isinf(h) else h) * preset.radius
    vals["c81_stall_tolerance"] = 1.0e30 if mu > 0.0 else 1.0e-6
    period = 2 * math.pi / vals["omega"]
    vals["final_time"] = settings.revolutions * period
    vals["time_step"] = period / settings.steps_per_rev
    vals["airfoil_file"] = AIRFOIL_FILE
    return vals


def run_case(workdir: str | os.PathLike, preset: RotorPreset, inputs: Mapping[str, float],
             template: str | os.PathLike = "rigid", settings: CaseSettings | None = None,
             mbdyn: str | os.PathLike | None = None, airfoil: Airfoil | None = None) -> HubLoads:
    """Run one case in ``workdir`` and return its mean :class:`HubLoads`.

    ``inputs`` holds rotor inputs (``collective_deg``, ``height_over_radius``, ...), the
    forward-flight ones (``advance_ratio``, ``shaft_angle_deg``; hover when left out) and airfoil
    coefficients of the preset's fit rows (``cla_m03``, ...), which rewrite the c81 table
    (:func:`sample_table`). An input the template does not use is
    an error (it would silently do nothing). Raises :class:`~rotoruq.mbdyn.solver.MBDynError`
    when MBDyn fails, stops early or does not reach a periodic state.

    Parameters
    ----------
    workdir : str or PathLike
        The folder MBDyn runs in (created when missing): it receives ``rotor.mbd``, the c81
        table and MBDyn's output files.
    preset : RotorPreset
        The rotor.
    inputs : mapping of str to float
        Rotor inputs and airfoil coefficients (deg and SI).
    template : str or PathLike, optional
        A bundled template (:data:`TEMPLATES`, default ``"rigid"``) or a template file.
    settings : CaseSettings, optional
        The time integration (default :class:`CaseSettings()`).
    mbdyn : str or PathLike, optional
        The MBDyn executable (default: :func:`~rotoruq.mbdyn.solver.find_mbdyn`).
    airfoil : Airfoil, optional
        The airfoil whose table is written (default: the preset's).
    """
    from ..rotor.c81 import write_c81
    from ..rotor.model import load_airfoil

    settings = settings or CaseSettings()
    airfoil = airfoil if airfoil is not None else load_airfoil(preset)
    coef_names = set(getattr(airfoil, "parameter_names", ()))
    overrides = {k: float(v) for k, v in inputs.items() if k in coef_names}
    rotor_inputs = {k: v for k, v in inputs.items() if k not in coef_names}
    text, tpath = template_text(template)
    values = template_values(preset, rotor_inputs, settings,
                             TEMPLATE_DEFAULTS.get(str(template)))
    used = set(template_fields(text, tpath))
    used |= {src for f in list(used) for src in DERIVED_FROM.get(f, ())}
    unused = sorted(k for k in rotor_inputs if k not in used)
    if unused:
        raise ParameterError(f"MBDyn template {tpath.name} does not use the inputs {unused}; "
                             f"it uses {sorted(used)}")
    wd = Path(workdir).absolute()
    wd.parent.mkdir(parents=True, exist_ok=True)
    # the case's own folder (a batch's point_<k>) is never a link planted in its place
    real_dir(wd, create=True)
    write_c81(sample_table(airfoil, overrides), wd / AIRFOIL_FILE, free_format=True)
    mbd = wd / "rotor.mbd"
    write_file(mbd, fill_template(text, values, path=tpath).encode("utf-8"))
    run = run_mbdyn(mbd, wd / "rotor", mbdyn=mbdyn, timeout=settings.timeout)
    jnt = run.prefix.with_suffix(".jnt")
    return hub_loads(run.prefix.with_suffix(".rot"), omega=values["omega"], rho=values["rho"],
                     radius=preset.radius, steps_per_rev=settings.steps_per_rev,
                     revolutions=settings.revolutions, average=settings.average,
                     tolerance=settings.tolerance, joint=jnt if jnt.exists() else None)


def sample_table(airfoil: Airfoil, overrides: Mapping[str, float]) -> C81Table:
    """The c81 table of one sample, as the built-in model sees it: the airfoil's
    :meth:`~rotoruq.rotor.airfoil.Airfoil.perturbed_table` (fits at the fit rows)."""
    return airfoil.perturbed_table(dict(overrides))


def rigid_equivalent(preset: RotorPreset) -> RotorPreset:
    """The built-in model of the rigid template's physics: blades clamped at the collective
    (flap, lag and pitch-link springs effectively rigid), uniform momentum inflow without the
    first-harmonic part, no tip loss, no induced-power factor, Cheeseman-Bennett ground effect.
    Used to check the built-in rotor against MBDyn on identical physics.

    Parameters
    ----------
    preset : RotorPreset
        The rotor whose geometry, airfoil and operating point are kept.
    """
    return preset.replace(flap_model="hinge", k_flap=1e9, c_flap=0.0, k_lag=1e9, c_lag=0.0,
                          k_pitch_link=1e12, c_pitch_link=0.0, delta3_deg=0.0,
                          inflow="uniform", harmonic_inflow=False, tip_loss=False,
                          induced_power_factor=1.0, ground_effect="cheeseman_bennett",
                          lateral_deg=0.0, longitudinal_deg=0.0, ei_flap=math.nan)
