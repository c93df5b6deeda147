"""Rotor definitions (:class:`RotorPreset`) and the two rotors of the reference study.

Units are SI, angles in degrees at the boundary. Every property the thesis does not give is
chosen physically here and marked "chosen" in its comment; see also README "Rotor model".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

from ..errors import ParameterError

__all__ = ["RotorPreset", "bo105", "gvpm", "get_preset", "PRESETS", "GVPM_OMEGA",
           "GVPM_PITCH_LINK_LENGTH", "GVPM_PITCH_HORN_ARM"]


@dataclass(frozen=True)
class RotorPreset:
    """Geometry, structure, operating point and model options of a hover rotor.

    Lengths in m, angles in deg, stiffnesses in N m/rad (hinges), N (pitch link, per unit strain),
    N m^2 (EI), masses in kg, inertias in kg m^2 about the hinge/feathering axis.
    :func:`get_preset` and the rotor model's inputs (:data:`ROTOR_INPUTS`) use the field
    names; ``replace(**changes)`` gives a preset with some fields changed.

    Parameters
    ----------
    name : str
        The rotor's name.
    n_blades : int
        Number of blades.
    radius : float
        Rotor radius R, m.
    root_cutout : float
        Start of the aerodynamic span r_root, m from the hub centre (where the collective and
        the twist are applied).
    hinge_offset : float
        Flap/lag hinge (or equivalent hinge) radius e, m.
    chord : float
        Blade chord, m.
    twist_deg : float
        Total linear twist from r_root (0) to R, deg.
    airfoil : str
        A bundled airfoil name (``"naca0012"``, ``"naca23012"``) or the path of a c81 file.
    blade_mass_per_length : float
        Blade mass per unit length m' over [e, R], kg/m.
    pitch_inertia : float
        Blade inertia I_p about the feathering axis, kg m^2.
    airfoil_fit_machs : tuple of float, optional
        Mach rows whose CL/CD fits are uncertain parameters (``cla_m03``...); default none.
    airfoil_replace : tuple of str, optional
        The coefficients the fits replace, ``("cl", "cd")`` (default) or ``("cl",)`` (the
        thesis's Bo105).
    flap_model : str, optional
        ``"hinge"`` (rigid blade on a spring ``k_flap``, default) or ``"elastic"`` (an
        equivalent first flap mode from ``ei_flap``).
    k_flap : float, optional
        Flap hinge spring, N m/rad (default 0).
    c_flap : float, optional
        Flap hinge damper, N m s/rad (default 0).
    ei_flap : float, optional
        Flapwise bending stiffness EI_y, N m^2 (``flap_model="elastic"``; default NaN).
    k_lag : float, optional
        Lag hinge spring, N m/rad (default 0).
    c_lag : float, optional
        Lag hinge damper, N m s/rad (default 0).
    k_pitch_link : float, optional
        Pitch-link stiffness K_p, N (an axial stiffness EA: the link's law is per unit
        strain, :meth:`feathering_stiffness`); default 1e9, rigid.
    c_pitch_link : float, optional
        Pitch-link damping, N s (per unit strain rate, like ``k_pitch_link``); default 0.
    pitch_horn_arm : float, optional
        Pitch-horn arm l_h, m (default 0.1).
    pitch_link_length : float, optional
        Pitch-link length l0, m (default 0.2).
    delta3_deg : float, optional
        Kinematic pitch-flap coupling angle, deg: dtheta = -tan(delta3) beta (default 0).
    aero_center_offset : float, optional
        Aerodynamic centre aft of the feathering axis, m (negative: ahead); default 0.
    pitching_moment : bool, optional
        Whether the airfoil's CM acts about the feathering axis (default True).
    cm0 : float, optional
        Section pitching moment coefficient added to the table's CM (default 0).
    omega : float, optional
        Rotor speed, rad/s (default 1).
    rho : float, optional
        Air density, kg/m^3 (default 1.225).
    speed_of_sound : float, optional
        m/s (default 340.3).
    collective_deg, lateral_deg, longitudinal_deg : float, optional
        Collective and cyclic pitch commands, deg (default 0).
    height_over_radius : float, optional
        Hub height over the ground divided by R (default inf: out of ground effect).
    inflow : str, optional
        ``"uniform"`` (momentum, default) or ``"bemt"`` (blade-element momentum per station).
    harmonic_inflow : bool, optional
        Add the steady Pitt-Peters first-harmonic inflow (default True).
    ground_effect : str, optional
        The ground-effect model: ``"cheeseman_bennett"`` (default), ``"hayden"``,
        ``"fradenburgh"`` or ``"none"``.
    tip_loss : bool, optional
        Prandtl tip and root loss (default False).
    induced_power_factor : float, optional
        kappa_i on the uniform induced velocity (default 1).
    notes : str, optional
        Where the numbers come from, in words (not part of the preset's identity).
    """

    name: str
    n_blades: int
    radius: float                      # R
    root_cutout: float                 # start of the aerodynamic span r_root
    hinge_offset: float                # e: flap/lag hinge (or equivalent hinge) radius
    chord: float
    twist_deg: float                   # total linear twist from r_root (0) to R
    airfoil: str                       # bundled airfoil name, or a path to a c81 file
    blade_mass_per_length: float       # m' over [e, R]
    pitch_inertia: float               # I_p about the feathering axis
    airfoil_fit_machs: tuple = ()      # Mach rows whose CL/CD fits are uncertain parameters
    airfoil_replace: tuple = ("cl", "cd")  # coefficients the fits replace (thesis: Bo105 CL only)
    # flap: "hinge" (rigid blade, spring k_flap) or "elastic" (equivalent first mode from EI)
    flap_model: str = "hinge"
    k_flap: float = 0.0
    c_flap: float = 0.0
    ei_flap: float = math.nan
    k_lag: float = 0.0
    c_lag: float = 0.0
    k_pitch_link: float = 1e9
    c_pitch_link: float = 0.0
    pitch_horn_arm: float = 0.1        # l_h [m]
    pitch_link_length: float = 0.2     # l0 [m]: the link's law is per unit strain (see below)
    delta3_deg: float = 0.0            # kinematic pitch-flap coupling: dtheta = -tan(d3) beta
    aero_center_offset: float = 0.0    # aerodynamic centre aft of the feathering axis [m]
    pitching_moment: bool = True       # apply the airfoil CM about the feathering axis
    cm0: float = 0.0                   # section pitching moment added to the table's CM [-]
    # operating point
    omega: float = 1.0
    rho: float = 1.225
    speed_of_sound: float = 340.3
    collective_deg: float = 0.0
    lateral_deg: float = 0.0
    longitudinal_deg: float = 0.0
    height_over_radius: float = math.inf
    # aerodynamic model options
    inflow: str = "uniform"            # "uniform" | "bemt"
    harmonic_inflow: bool = True       # steady Pitt-Peters first-harmonic inflow
    ground_effect: str = "cheeseman_bennett"
    tip_loss: bool = False             # Prandtl tip/root loss (BEMT and uniform)
    induced_power_factor: float = 1.0  # kappa_i on the uniform induced velocity
    notes: str = field(default="", compare=False)

    def replace(self, **changes) -> RotorPreset:
        """A copy with some fields changed.

        Parameters
        ----------
        **changes
            New values, by field name; an unknown name raises
            :class:`~rotoruq.ParameterError`.
        """
        valid = {f.name for f in fields(self)}
        bad = sorted(set(changes) - valid)
        if bad:
            raise ParameterError(f"unknown rotor properties {bad}; valid: {sorted(valid)}")
        return replace(self, **changes)

    def feathering_stiffness(self, k_pitch_link):
        """Feathering stiffness [N m/rad] (or damping [N m s/rad]) from the pitch link's.

        The reference study's multibody pitch link is a rod whose constitutive law is written
        per unit strain, so ``k_pitch_link`` [N] acts as an axial stiffness EA and the link's
        spring rate is K_p / l0; at the pitch-horn arm l_h it gives k_theta = (K_p / l0) l_h^2.

        Parameters
        ----------
        k_pitch_link : float or ndarray
            Pitch-link stiffness K_p [N] (or damping [N s]).
        """
        return k_pitch_link / self.pitch_link_length * self.pitch_horn_arm**2

    @property
    def area(self) -> float:
        """Rotor disk area pi R^2, m^2."""
        return math.pi * self.radius**2

    @property
    def solidity(self) -> float:
        """Rotor solidity N c / (pi R)."""
        return self.n_blades * self.chord / (math.pi * self.radius)


# ---------------------------------------------------------------------------------------------
def bo105(**overrides) -> RotorPreset:
    """Bo105 main rotor of the thesis's validation chapter (thesis table 3.1).

    Given by the thesis: Omega 44.4 rad/s, R 4.912 m, hinge offset 0.746 m, K_f 15035.467,
    K_l 70698.042, C_l 4093.662 (N m/rad, N m s/rad), K_p 1e9 N, C_p 100 N s (the thesis
    prints N/m, N s/m), I_p 0.257,
    I_f 140.001 kg m^2 about the hub, blade span 3.812 m, chord 0.27 m, NACA 23012, uniform
    inflow, collective 6 deg, longitudinal -2 deg.

    Chosen:

    - twist: linear, -8 deg from the blade root (r = R - b, where the collective is applied)
      to the tip, the published Bo105 blade twist. The thesis prints -6.2 deg per metre, which
      gives negative thrust at every collective from 4 to 10 deg (in MBDyn and in plain BEMT).
      Read as -6.2 deg over the whole span it gives 5216 N at the nominal inputs with the
      thesis's own NACA 23012 lift fits (table 3.2), 2.6 x the thesis's 2009 N (table 3.11);
      -8 deg gives 2111 N (+5 %). The evidence (the published twist, and the thesis's thrust
      with its own fits) decides for -8 deg. What still differs: the torque (1417 N m against
      2361 N m): no twist reproduces it, the thesis's drag table is not published
      (``scripts/rotor_fidelity.py`` regenerates these numbers).
    - blade mass per length 3.56 kg/m, uniform from the hinge to the tip, so that the flap
      inertia about the hub equals I_f = 140.0 kg m^2.
    - pitch link: length l0 = L_p = 0.2 m (table 3.1), horn arm 0.24 m (10 x the GVPM's, the
      GVPM being a 1:10 model); with K_p = 1e9 N the link is rigid whatever the arm.
    - speed of sound 340.3 m/s, rho 1.225 kg/m^3 (sea level).

    Parameters
    ----------
    **overrides
        Fields of :class:`RotorPreset` to change (``bo105(omega=40.0)``).
    """
    R, e = 4.912, 0.746
    m_per_l = 3.0 * 140.001 / (R**3 - e**3)
    p = RotorPreset(
        name="bo105",
        n_blades=4,
        radius=R,
        root_cutout=R - 3.812,
        hinge_offset=e,
        chord=0.270,
        twist_deg=-8.0,
        airfoil="naca23012",
        airfoil_fit_machs=(0.1, 0.2, 0.3, 0.4, 0.5, 0.6),
        airfoil_replace=("cl",),
        blade_mass_per_length=m_per_l,
        pitch_inertia=0.257,
        flap_model="hinge",
        k_flap=15035.467,
        c_flap=0.0,
        k_lag=70698.042,
        c_lag=4093.662,
        k_pitch_link=1.0e9,
        c_pitch_link=100.0,
        pitch_horn_arm=0.24,
        pitch_link_length=0.2,
        omega=44.4,
        collective_deg=6.0,
        lateral_deg=0.0,
        longitudinal_deg=-2.0,
        inflow="uniform",
        harmonic_inflow=False,
        notes="thesis table 3.1; linear twist -8 deg over the span (see docstring)",
    )
    return p.replace(**overrides) if overrides else p


# GVPM feathering inertia [kg m^2]: m' L (c/4)^2 (chosen: chordwise radius of gyration c/4).
_GVPM_I_P = (0.025 / 0.425) * 0.425 * (0.25 * 0.042) ** 2
# GVPM pitch link [m]: the link length at 1:10 of the Bo105's L_p = 0.2 m (thesis table 3.1;
# the GVPM fuselage is a 1:10 Bo105) and a horn arm of 24 mm (0.57 chord, chosen). With the
# per-unit-strain law the feathering stiffness is (K_p / l0) l_h^2 = 0.432 N m/rad at
# K_p = 15, about three times the propeller moment I_p Omega^2 = 0.139 N m/rad.
#: GVPM pitch-link length [m] (chosen: 1:10 of the Bo105's 0.2 m).
GVPM_PITCH_LINK_LENGTH = 0.02
#: GVPM pitch-horn arm [m] (chosen: 0.57 chord).
GVPM_PITCH_HORN_ARM = 0.024

#: Rotor speed of the GVPM experiment [rad/s]: v_tip = 108.9 m/s at H = 4R (thesis section
#: 4.2.1).
GVPM_OMEGA = 108.9 / 0.485


def gvpm(**overrides) -> RotorPreset:
    """The GVPM scaled rotor of the thesis's experimental chapter (thesis table 4.2).

    Given by the thesis: 4 untwisted rectangular blades, R 0.485 m, hub radius 0.06 m, span
    0.425 m, chord 0.042 m, NACA 0012, EI_y 7 N m^2, pitch-link stiffness 10 (N per unit
    strain here; the thesis prints N/m) and damping 0.05 N s, Omega from v_tip = 108.9
    m/s, Glauert/linear inflow (here: uniform plus the steady first-harmonic Pitt-Peters
    inflow, which reduces to uniform without cyclic), collective/lateral/longitudinal 5, -1,
    -1 deg (the sensitivity study's operating point).

    Chosen (the thesis does not give them):

    - blade mass 25 g (carbon-fibre blade), i.e. 0.0588 kg/m uniform from the hub radius.
    - feathering inertia I_p = m' L (0.25 c)^2 (chordwise radius of gyration a quarter chord).
    - elastic flap: an equivalent hinge at the hub radius with the spring that gives the
      non-rotating first cantilever frequency (1.875^2 sqrt(EI / (m' L^4))), i.e.
      k_flap = 4.12 EI_y / L; the same for lag from EI_z (stiff in plane).
    - pitch link: K_p acts as an axial stiffness EA (the multibody link's law is per unit
      strain), link length l0 = 20 mm (1:10 of the Bo105's 0.2 m), horn arm l_h = 24 mm:
      k_theta = (K_p / l0) l_h^2 = 0.432 N m/rad at K_p = 15 N (``k_feather`` sets it
      directly). No kinematic pitch-flap coupling (delta3 = 0).
    - inflow: uniform momentum with Prandtl tip and root loss (``tip_loss=True``), no
      first-harmonic inflow (``harmonic_inflow=False``): the thesis's MBDyn model uses
      Glauert's linear inflow, which is uniform in hover.
    - aerodynamic centre 1 mm ahead of the feathering axis (``aero_center_offset=-0.001``,
      2.4 % chord): the one property set to reproduce the reference study's behaviour. It is
      the feathering coupling that makes lateral cyclic drive roll and longitudinal drive
      pitch (thesis table 4.6) and K_p act on the hub moments (table 4.9); without it the
      flap response lags the cyclic by about 40 deg and the axes are rotated. It is tuned, not
      measured: the bundled table's CM slope over 0-8 deg (lift-weighted) puts the
      aerodynamic centre 0.19 mm ahead (spread 0.44 mm; about 2 mm over 4-10 deg), the GVPM
      4R loads cannot tell the values apart, and MBDyn's elastic loads put it near -0.2 mm
      (``scripts/aero_center_calibration.py``; docs/tutorials/mbdyn.md,
      "aero_center_offset").
    - no airfoil table pitching moment (``pitching_moment=False``): MBDyn's NACA 0012 table
      that the thesis used has CM = 0 for |alpha| <= 10 deg, while the bundled low-Re table's
      CM there is non-monotonic (-0.03..0.03, NeuralFoil confidence 0.83 at Re 5e4); ``cm0``
      adds a constant section moment (an uncertain input).

    Parameters
    ----------
    **overrides
        Fields of :class:`RotorPreset` to change (``gvpm(omega=230.0)``).
    """
    m_per_l = 0.025 / 0.425
    p = RotorPreset(
        name="gvpm",
        n_blades=4,
        radius=0.485,
        root_cutout=0.06,
        hinge_offset=0.06,
        chord=0.042,
        twist_deg=0.0,
        airfoil="naca0012",
        airfoil_fit_machs=(0.0, 0.2, 0.3, 0.4),
        blade_mass_per_length=m_per_l,
        pitch_inertia=_GVPM_I_P,
        flap_model="elastic",
        ei_flap=7.0,
        c_flap=0.0,
        k_lag=4.12 * 2.26e3 / 0.425,  # equivalent lag spring from EI_z (stiff in plane)
        c_lag=0.0,
        k_pitch_link=10.0,
        c_pitch_link=0.05,
        pitch_horn_arm=GVPM_PITCH_HORN_ARM,
        pitch_link_length=GVPM_PITCH_LINK_LENGTH,
        omega=GVPM_OMEGA,
        collective_deg=5.0,
        lateral_deg=-1.0,
        longitudinal_deg=-1.0,
        height_over_radius=4.0,
        inflow="uniform",
        harmonic_inflow=False,
        tip_loss=True,
        aero_center_offset=-0.001,
        pitching_moment=False,
        notes="thesis table 4.2; mass, pitch link, feathering inertia and aerodynamic-centre "
              "offset chosen (see docstring)",
    )
    return p.replace(**overrides) if overrides else p


#: The bundled rotors by name: each value makes a :class:`RotorPreset` (``gvpm(omega=230)``).
PRESETS = {"bo105": bo105, "gvpm": gvpm}


def get_preset(name: str | RotorPreset, **overrides) -> RotorPreset:
    """Return a preset by name (``"bo105"``, ``"gvpm"``) with optional property overrides.

    Parameters
    ----------
    name : str or RotorPreset
        ``"bo105"`` (thesis table 3.1) or ``"gvpm"`` (table 4.2); a preset is returned as is
        (with the overrides applied).
    **overrides
        Preset properties to replace, by field name, in SI units (m, kg/m, rad/s, ...) or
        degrees where the field name says ``_deg``.

    Returns
    -------
    RotorPreset

    Examples
    --------
    >>> p = get_preset("gvpm")
    >>> p.name, p.n_blades
    ('gvpm', 4)
    >>> get_preset("gvpm", radius=0.5).radius          # overrides: property -> value (SI)
    0.5
    """
    if isinstance(name, RotorPreset):
        return name.replace(**overrides) if overrides else name
    try:
        return PRESETS[name.lower()](**overrides)
    except KeyError:
        raise ParameterError(f"unknown rotor preset {name!r}; valid: {sorted(PRESETS)}") from None
