"""The rotor in forward flight: the hover model with a free stream, trimmed or at given controls.

The blade sees the in-plane free stream mu Omega R (tangential ``mu sin psi``, and through
the flapped blade ``mu beta cos psi`` normal to it; the radial flow along the blade is
neglected) and the free-stream inflow ``lambda_s = mu tan(alpha_s)`` through the disk, with
``alpha_s`` (``shaft_angle_deg``) positive tilting the disk forward. Sections in reverse
flow take the airfoil table's values beyond 90 deg (a linear airfoil: the thin airfoil's
pi-periodic lift). The induced inflow is Glauert's uniform momentum inflow
``T = 2 rho A v sqrt((mu Omega R)^2 + (lambda_s Omega R + v)^2) / kappa^2`` (``"glauert"``)
or Drees's linear inflow on it (``"drees"``). The flap, lag and feathering harmonics are the
hover model's harmonic balance (:mod:`rotoruq.rotor.hover`); the periodic aerodynamic
coefficients of forward flight are in the loads the balance analyses.

Wind-tunnel trim (``trim="wind_tunnel"``) solves the collective and cyclic for a thrust
(``thrust_target``) and zero first-harmonic flapping inside the same iteration; hub-moment
trim (``trim="hub_moments"``) for the thrust and the hub roll and pitch moments
(``roll_moment_target``, ``pitch_moment_target``, default 0 N m). The iteration's Jacobian
couples the harmonics, the inflow and the controls through forward flight's periodic
coefficients (linear theory on the grid), so the trim converges like the hover solve. A
point that cannot trim is a failed row with its reason. In ground effect (a finite
``height_over_radius``) the hover model's factor on the induced velocity, 1 - g, is seen
through the wake skewed by V / v (Cheeseman & Bennett): 1 - g / (1 + (mu Omega R / v)^2).
At ``advance_ratio = 0``
the solve takes the hover code paths: the answer is the hover model's, bitwise.

>>> import rotoruq as rq
>>> model = rq.ForwardRotorModel("gvpm", names_in=["advance_ratio", "thrust_target"],
...                              names_out=["power", "collective_trim_deg"],
...                              trim="wind_tunnel", fixed={"shaft_angle_deg": 4.0})
>>> y = model([[0.2, 12.0]])        # (1, 2): power [W], trimmed collective [deg]
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ParameterError
from . import _kernel as kern
from .ground_effect import ground_effect_factor
from .hover import HoverSolution, prepare, run_kernel
from .model import RESPONSES, ROTOR_INPUTS, RotorModel
from .presets import RotorPreset

__all__ = ["ForwardRotorModel", "ForwardSolution", "FORWARD_INPUTS", "FORWARD_RESPONSES",
           "INFLOW_MODELS", "MAX_ADVANCE_RATIO", "MOMENT_TARGETS", "TRIMS", "solve_forward"]

#: Inputs of forward flight, beside every hover input: advance ratio mu [-], shaft angle
#: [deg, positive tilting the disk forward], the trim's thrust [N] and the hub-moment trim's
#: roll and pitch moments [N m] (as the responses ``roll_moment``, ``pitch_moment``).
FORWARD_INPUTS = ("advance_ratio", "shaft_angle_deg", "thrust_target", "roll_moment_target",
                  "pitch_moment_target")
#: The hub-moment trim's target inputs.
MOMENT_TARGETS = ("roll_moment_target", "pitch_moment_target")
#: Responses: the hover model's loads (without its hover-named moments), the in-plane hub
#: forces H (rearward) and Y (advancing side) [N], the hub roll and pitch moments [N m], the
#: flapping beta_0 + beta_1c cos psi + beta_1s sin psi [deg] and the (trimmed) controls [deg].
FORWARD_RESPONSES = tuple(r for r in RESPONSES if r not in ("roll", "pitch")) + (
    "h_force", "y_force", "roll_moment", "pitch_moment", "beta_0_deg", "beta_1c_deg",
    "beta_1s_deg", "collective_trim_deg", "lateral_trim_deg", "longitudinal_trim_deg")
#: Induced-inflow models by name.
INFLOW_MODELS = {"glauert": kern.GLAUERT, "drees": kern.DREES}
#: Largest advance ratio accepted (first-harmonic inflow, radial flow neglected).
MAX_ADVANCE_RATIO = 0.4
#: Largest |shaft angle| accepted [deg].
MAX_SHAFT_ANGLE_DEG = 30.0
_TRIMS = {None: kern.NO_TRIM, "none": kern.NO_TRIM, "wind_tunnel": kern.WIND_TUNNEL,
          "hub_moments": kern.HUB_MOMENTS}
#: Trim modes by name (None or "none": the controls are given).
TRIMS = ("none", "wind_tunnel", "hub_moments")
_ALIASES = {"roll_moment": "roll", "pitch_moment": "pitch", "beta_0_deg": "coning_deg"}


@dataclass(frozen=True, eq=False)
class ForwardSolution(HoverSolution):
    """A :class:`~rotoruq.rotor.hover.HoverSolution` in forward flight, with (n,) arrays:

    h_force, y_force [N]: in-plane hub forces, H positive rearward (towards psi = 0), Y
    positive to the advancing side (psi = 90 deg), from the blades' aerodynamic forces;
    beta_1c_deg, beta_1s_deg [deg]: first-harmonic flapping (``coning_deg`` is beta_0);
    collective_trim_deg, lateral_trim_deg, longitudinal_trim_deg [deg]: the commands (the
    trim's solution when trimmed); advance_ratio [-]; ``inflow_ratio`` is the induced mean
    inflow v0 / (Omega R). ``roll`` and ``pitch`` are the hub moments (as responses
    ``roll_moment`` and ``pitch_moment``).
    """

    h_force: np.ndarray = None  # type: ignore[assignment]
    y_force: np.ndarray = None  # type: ignore[assignment]
    beta_1c_deg: np.ndarray = None  # type: ignore[assignment]
    beta_1s_deg: np.ndarray = None  # type: ignore[assignment]
    collective_trim_deg: np.ndarray = None  # type: ignore[assignment]
    lateral_trim_deg: np.ndarray = None  # type: ignore[assignment]
    longitudinal_trim_deg: np.ndarray = None  # type: ignore[assignment]
    advance_ratio: np.ndarray = None  # type: ignore[assignment]

    def response(self, name: str) -> np.ndarray:
        """The response ``name`` of :data:`FORWARD_RESPONSES`, shape (n,).

        Parameters
        ----------
        name : str
            A response name (``roll_moment``, ``beta_0_deg``, ... included).

        Returns
        -------
        ndarray of shape (n,)
            Its values in the units of :data:`FORWARD_RESPONSES`.
        """
        return getattr(self, _ALIASES.get(name, name))


def solve_forward(preset: RotorPreset, airfoil: Any, grid: Any,
                  params: Mapping[str, np.ndarray],
                  overrides: Mapping[str, np.ndarray] | None = None, *,
                  inflow_model: str = "glauert", trim: str | None = None,
                  n_harmonics: int = 2, tolerance: float = 1e-9, max_iterations: int = 200,
                  check_tolerance: float | None = None) -> ForwardSolution:
    """Solve the periodic forward-flight state of n samples, trimmed or at given controls.

    Parameters
    ----------
    preset : RotorPreset
        The rotor (uniform inflow: ``preset.inflow == "uniform"``).
    airfoil : Airfoil or LinearAirfoil
        Section aerodynamics.
    grid : BladeGrid
        Stations and azimuths (:func:`rotoruq.rotor.geometry.blade_grid`).
    params : mapping of str to ndarray of shape (n,)
        Every hover input of :func:`rotoruq.rotor.hover.solve_hover`, and
        ``advance_ratio`` [-], ``shaft_angle_deg`` [deg], (trimmed) ``thrust_target`` [N]
        and (hub-moment trim) ``roll_moment_target``, ``pitch_moment_target`` [N m]
        (default 0).
    overrides : mapping of str to ndarray of shape (n,), optional
        Airfoil coefficient overrides.
    inflow_model : {"glauert", "drees"}
        Uniform momentum inflow, or Drees's linear inflow.
    trim : {None, "wind_tunnel", "hub_moments"}
        None: the controls are given; ``"wind_tunnel"``: collective and cyclic solved for
        the thrust target and zero first-harmonic flapping; ``"hub_moments"``: for the
        thrust target and the hub roll and pitch moment targets (the controls given start
        either trim).
    n_harmonics, tolerance, max_iterations, check_tolerance
        As in :func:`rotoruq.rotor.hover.solve_hover`; the trim converges within the same
        iteration (its control step in rad joins the tolerance test).

    Returns
    -------
    ForwardSolution
        One row per sample; a row that did not converge or cannot trim has its reason in
        ``failure``.

    Examples
    --------
    >>> import numpy as np
    >>> from rotoruq.rotor.forward import ForwardRotorModel
    >>> m = ForwardRotorModel("gvpm")
    >>> p = {k: np.array([v]) for k, v in m.defaults().items()}
    >>> p["advance_ratio"] = np.array([0.1])
    >>> sol = solve_forward(m.preset, m.airfoil, m.grid, p)
    >>> bool(sol.converged[0])
    True
    """
    if inflow_model not in INFLOW_MODELS:
        raise ParameterError(f"unknown inflow model {inflow_model!r}; valid: "
                             f"{', '.join(INFLOW_MODELS)}")
    if trim not in _TRIMS:
        raise ParameterError(f"unknown trim {trim!r}; valid: {', '.join(TRIMS)}")
    flight = {k: params[k] for k in FORWARD_INPUTS if k in params}
    hover = {k: v for k, v in params.items() if k not in FORWARD_INPUTS}
    with np.errstate(all="ignore"):
        n, K, rot, table, fits, linear, prm = prepare(preset, airfoil, grid, hover, overrides,
                                                      n_harmonics)
        mu = np.broadcast_to(np.asarray(flight.get("advance_ratio", 0.0), float), (n,))
        alpha = np.deg2rad(np.broadcast_to(
            np.asarray(flight.get("shaft_angle_deg", 0.0), float), (n,)))
        prm[:, kern.MU] = mu
        prm[:, kern.LAMBDA_S] = mu * np.tan(alpha)
        prm[:, kern.INFLOW] = INFLOW_MODELS[inflow_model]
        prm[:, kern.TRIM] = _TRIMS[trim]
        prm[:, kern.THRUST_TARGET] = flight.get("thrust_target", np.nan)
        prm[:, kern.ROLL_TARGET] = flight.get("roll_moment_target", 0.0)
        prm[:, kern.PITCH_TARGET] = flight.get("pitch_moment_target", 0.0)
        h = np.broadcast_to(np.asarray(hover["height_over_radius"], float), (n,))
        prm[:, kern.GROUND_DEFICIT] = np.where(
            np.isinf(h), 0.0, 1.0 - ground_effect_factor(h, preset.ground_effect))
        res = run_kernel(prm, rot, table, fits, linear, n, K, tolerance, max_iterations,
                         check_tolerance, negative_power=True)
    if _TRIMS[trim] != kern.NO_TRIM:
        for i in np.flatnonzero(res.failure != ""):
            if res.failure[i].startswith("periodic solution did not converge"):
                res.failure[i] = "cannot trim: " + res.failure[i].replace(
                    "periodic solution", "the trimmed periodic solution")
    base = HoverSolution.assemble(preset, grid, prm[:, kern.OMEGA], prm[:, kern.RHO], res.Q,
                                  res.scalars[:, kern.V0], res.checked, res.M_root,
                                  res.scalars[:, kern.RESID], res.iterations, res.failure)
    valid = base.converged
    extra = {"h_force": res.checked["h_force"].copy(), "y_force": res.checked["y_force"].copy(),
             "beta_1c_deg": np.rad2deg(res.Q[:, 0, 1].real) if K > 1 else np.zeros(n),
             "beta_1s_deg": -np.rad2deg(res.Q[:, 0, 1].imag) if K > 1 else np.zeros(n),
             "collective_trim_deg": prm[:, kern.COLLECTIVE].copy(),
             "lateral_trim_deg": prm[:, kern.LATERAL].copy(),
             "longitudinal_trim_deg": prm[:, kern.LONGITUDINAL].copy()}
    for v in extra.values():
        v[~valid] = np.nan
    return ForwardSolution(**vars(base), **extra, advance_ratio=np.array(mu))


class ForwardRotorModel(RotorModel):
    """The rotor model in forward flight, following the Model protocol.

    Every input and option of :class:`~rotoruq.rotor.model.RotorModel`, and
    :data:`FORWARD_INPUTS` (``advance_ratio`` default 0, ``shaft_angle_deg`` default 0,
    ``thrust_target`` needed when trimmed); responses :data:`FORWARD_RESPONSES`.

    Parameters
    ----------
    preset : str or RotorPreset
        ``"bo105"``, ``"gvpm"`` or a :class:`RotorPreset` with uniform inflow.
    names_in : sequence of str, optional
        Batch columns: any of :data:`~rotoruq.rotor.model.ROTOR_INPUTS`,
        :data:`FORWARD_INPUTS` and the airfoil's coefficient names (default: the commands).
    names_out : sequence of str, optional
        Any of :data:`FORWARD_RESPONSES` (default: thrust, power).
    fixed : mapping of str to float, optional
        Inputs held at a value other than the default (``thrust_target`` for a trim).
    airfoil : Airfoil or LinearAirfoil, optional
        Replaces the preset's airfoil table.
    inflow_model : {"glauert", "drees"}, optional
        Uniform momentum inflow (default) or Drees's linear inflow.
    trim : {None, "wind_tunnel", "hub_moments"}, optional
        Given controls (default), wind-tunnel trim to ``thrust_target`` and zero
        first-harmonic flapping, or trim to ``thrust_target`` and the hub moments
        ``roll_moment_target``, ``pitch_moment_target`` (default 0 N m; the given controls
        are either trim's starting point).
    **options
        The solver options of :class:`~rotoruq.rotor.model.RotorModel`: ``n_stations``,
        ``n_azimuth``, ``n_harmonics``, ``tolerance``, ``max_iterations``,
        ``check_tolerance``.

    Examples
    --------
    >>> m = ForwardRotorModel("gvpm", names_in=["advance_ratio"], names_out=["thrust", "power"])
    >>> m([[0.0], [0.2]]).shape
    (2, 2)
    """

    _inputs = ROTOR_INPUTS + FORWARD_INPUTS
    _responses = FORWARD_RESPONSES

    def __init__(self, preset: str | RotorPreset = "gvpm",
                 names_in: Sequence[str] | None = None,
                 names_out: Sequence[str] | None = None,
                 fixed: Mapping[str, float] | None = None, airfoil: Any = None, *,
                 inflow_model: str = "glauert", trim: str | None = None,
                 **options: Any) -> None:
        super().__init__(preset, names_in, names_out or ("thrust", "power"), fixed, airfoil,
                         **options)
        if inflow_model not in INFLOW_MODELS:
            raise ParameterError(f"unknown inflow model {inflow_model!r}; valid: "
                                 f"{', '.join(INFLOW_MODELS)}")
        if trim not in _TRIMS:
            raise ParameterError(f"unknown trim {trim!r}; valid: {', '.join(TRIMS)}")
        if self.preset.inflow != "uniform":
            raise ParameterError(f"preset {self.preset.name!r} has inflow "
                                 f"{self.preset.inflow!r}: forward flight takes uniform "
                                 "momentum inflow (inflow_model 'glauert' or 'drees')")
        self.inflow_model, self.trim = inflow_model, trim
        given = set(self.names_in) | set(self.fixed)
        if _TRIMS[trim] != kern.NO_TRIM:
            if "thrust_target" not in given:
                raise ParameterError(f"trim={trim!r} needs 'thrust_target' [N], in "
                                     "names_in or fixed")
            if self.n_harmonics < 1:
                raise ParameterError(f"trim={trim!r} needs n_harmonics >= 1")
        elif "thrust_target" in given:
            raise ParameterError("'thrust_target' is a trim's thrust: give "
                                 "trim='wind_tunnel' or 'hub_moments', or drop it")
        for name in MOMENT_TARGETS:
            if name in given and _TRIMS[trim] != kern.HUB_MOMENTS:
                raise ParameterError(f"{name!r} is the hub-moment trim's target: give "
                                     "trim='hub_moments' or drop it")

    def __repr__(self) -> str:
        return (f"ForwardRotorModel({self.preset.name!r}, names_in={self.names_in}, "
                f"names_out={self.names_out}, inflow_model={self.inflow_model!r}, "
                f"trim={self.trim!r})")

    def defaults(self) -> dict[str, float]:
        """Value of every input when not given in the batch: the hover model's, advance
        ratio 0, shaft angle 0 deg and out of ground effect (``height_over_radius`` inf,
        whatever the preset's), then ``fixed`` (which may also give the thrust).

        Returns
        -------
        dict of str to float
            Input name to value.
        """
        d = {"advance_ratio": 0.0, "shaft_angle_deg": 0.0, **super().defaults(),
             "height_over_radius": math.inf}
        if _TRIMS[self.trim] != kern.NO_TRIM:
            # given in the batch or in fixed (checked when the model is made)
            d.setdefault("thrust_target", math.nan)
        if _TRIMS[self.trim] == kern.HUB_MOMENTS:
            d.update(dict.fromkeys(MOMENT_TARGETS, 0.0))
        d.update(self.fixed)
        return d

    def _solve_rows(self, params, overrides) -> ForwardSolution:
        return solve_forward(self.preset, self.airfoil, self.grid, params, overrides,
                             inflow_model=self.inflow_model, trim=self.trim,
                             n_harmonics=self.n_harmonics, tolerance=self.tolerance,
                             max_iterations=self.max_iterations,
                             check_tolerance=self.check_tolerance)

    def _all_valid(self, params, overrides) -> bool:
        mu, alpha = params["advance_ratio"], params["shaft_angle_deg"]
        with np.errstate(invalid="ignore"):
            ok = bool(np.all((mu >= 0) & (mu <= MAX_ADVANCE_RATIO))
                      and np.all(np.abs(alpha) <= MAX_SHAFT_ANGLE_DEG))
            if "thrust_target" in params:
                ok = ok and bool(np.all(params["thrust_target"] > 0))
        return ok and super()._all_valid(params, overrides)

    def _validate(self, params, overrides, n) -> dict[int, str]:
        failures = super()._validate(params, overrides, n)
        mu, alpha = params["advance_ratio"], params["shaft_angle_deg"]

        def fail(mask, reason):
            for i in np.flatnonzero(mask):
                failures.setdefault(int(i), reason(i))

        with np.errstate(invalid="ignore"):
            fail(~((mu >= 0) & (mu <= MAX_ADVANCE_RATIO)),
                 lambda i: f"advance_ratio {mu[i]:g} is outside [0, {MAX_ADVANCE_RATIO:g}] "
                 "(first-harmonic inflow, radial flow neglected)")
            fail(~(np.abs(alpha) <= MAX_SHAFT_ANGLE_DEG),
                 lambda i: f"shaft_angle_deg {alpha[i]:g} is outside "
                 f"[-{MAX_SHAFT_ANGLE_DEG:g}, {MAX_SHAFT_ANGLE_DEG:g}] deg")
            if "thrust_target" in params:
                T = params["thrust_target"]
                fail(~(T > 0), lambda i: f"thrust_target must be > 0 N, got {T[i]:g}")
        return failures

