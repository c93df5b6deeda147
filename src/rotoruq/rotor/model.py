"""The hover rotor as a Model: named, batchable inputs in, hub loads out.

>>> import rotoruq as rq
>>> model = rq.RotorModel("gvpm", names_in=["collective_deg", "k_pitch_link"],
...                       names_out=["thrust", "power"])
>>> y = model([[5.4, 15.0], [5.0, 12.0]])          # (2, 2): thrust [N], power [W]
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import ParameterError
from ..model import EvalBatch
from .airfoil import Airfoil
from .geometry import blade_grid
from .ground_effect import MIN_HEIGHT_OVER_RADIUS, min_height_over_radius
from .hover import (  # noqa: F401  (kernels_cached: its public home stays here too)
    HoverSolution,
    check_airfoil,
    default_check_tolerance,
    kernels_cached,
    solve_hover,
)
from .presets import RotorPreset, get_preset

__all__ = ["RotorModel", "ROTOR_INPUTS", "RESPONSES", "load_airfoil"]

log = logging.getLogger(__name__)

#: The line logged before the rotor kernels compile on a cold numba cache.
COMPILE_NOTICE = "compiling rotor kernels (once per install, ~30-90 s) ..."


#: Rotor inputs every preset accepts (angles in deg, SI otherwise).
ROTOR_INPUTS = (
    "collective_deg",
    "lateral_deg",
    "longitudinal_deg",
    "omega",
    "rho",
    "height_over_radius",
    "k_flap",
    "c_flap",
    "k_lag",
    "c_lag",
    "k_pitch_link",
    "c_pitch_link",
    "ei_flap",
    "k_feather",
    "cm0",
    "aero_center_offset",
)
#: Inputs with no preset value: given only in the batch or in ``fixed``.
OPTIONAL_INPUTS = ("k_feather",)
#: Responses: thrust [N], torque [N m], roll [N m], pitch [N m], power [W], ct, cq [-].
RESPONSES = ("thrust", "torque", "roll", "pitch", "power", "ct", "cq")

_NONNEGATIVE = ("k_flap", "c_flap", "k_lag", "c_lag", "k_pitch_link", "c_pitch_link", "ei_flap",
                "k_feather")
#: Largest |collective| + |cyclic| amplitude accepted [deg]: a blade pitch beyond it is no
#: rotor operating state (the blade would face backwards).
MAX_PITCH_DEG = 90.0
_POSITIVE = ("omega", "rho")


def load_airfoil(preset: RotorPreset) -> Airfoil:
    """The preset's airfoil: a bundled table name or a path to a c81 file."""
    fit = preset.airfoil_fit_machs or None
    replace = tuple(preset.airfoil_replace)
    if Path(preset.airfoil).suffix.lower() == ".c81":
        return Airfoil.from_c81(preset.airfoil, fit_machs=fit, replace=replace)
    return Airfoil.bundled(preset.airfoil, fit_machs=fit, replace=replace)


class RotorModel:
    """Hover rotor model following the Model protocol.

    The solve is compiled (numba) and spreads large batches over numba's threads
    (``numba.set_num_threads``); a row's result does not depend on the batch, its order or
    the thread count, bitwise.

    After ``evaluate``, ``last_solution`` holds the full :class:`HoverSolution`, one row per
    input row (``failure`` gives each failed row's reason, "" for a valid row).

    Parameters
    ----------
    preset : str or RotorPreset
        ``"bo105"``, ``"gvpm"`` or a :class:`RotorPreset`.
    names_in : sequence of str
        Names of the batch columns: any of :data:`ROTOR_INPUTS` and the airfoil's coefficient
        names (``cla_m03``, ``cl0_m03``, ``cd0_m03``, ...). Default: the three commands.
    names_out : sequence of str
        Any of :data:`RESPONSES`. Default: thrust, torque.
    fixed : mapping name -> value
        Inputs held fixed at a value other than the preset's.
    airfoil : :class:`~rotoruq.rotor.airfoil.Airfoil` or
        :class:`~rotoruq.rotor.aero.LinearAirfoil`, optional
        Replaces the preset's airfoil table.
    n_stations : int, optional
        Gauss stations per blade (default 10).
    n_azimuth : int, optional
        Azimuth steps per revolution (default 36).
    n_harmonics : int, optional
        Harmonics of the blade motion in the periodic solution (default 2).
    tolerance : float, optional
        Convergence of the periodic solution: the largest change of the blade-motion
        harmonics [rad] and of the inflow ratio between iterations (default 1e-8).
    max_iterations : int, optional
        Iterations per sample before the point fails as not converged (default 200).
    check_tolerance : float, optional
        The equations re-evaluated at each returned state must leave a residual below it
        (default max(1e-6, 100 tolerance); see :func:`rotoruq.rotor.hover.solve_hover`).
    """

    #: the input and response names this model accepts (a subclass extends them)
    _inputs: tuple[str, ...] = ROTOR_INPUTS
    _responses: tuple[str, ...] = RESPONSES

    def __init__(
        self,
        preset: str | RotorPreset = "gvpm",
        names_in: Sequence[str] | None = None,
        names_out: Sequence[str] | None = None,
        fixed: Mapping[str, float] | None = None,
        airfoil: Any = None,
        n_stations: int = 10,
        n_azimuth: int = 36,
        n_harmonics: int = 2,
        tolerance: float = 1e-8,
        max_iterations: int = 200,
        check_tolerance: float | None = None,
    ) -> None:
        self.preset = get_preset(preset)
        self.airfoil = airfoil if airfoil is not None else load_airfoil(self.preset)
        check_airfoil(self.airfoil)
        self.grid = blade_grid(self.preset, n_stations, n_azimuth)
        self.n_harmonics = int(n_harmonics)
        self.tolerance, self.max_iterations = float(tolerance), int(max_iterations)
        self.check_tolerance = float(default_check_tolerance(self.tolerance, check_tolerance))
        self._airfoil_names = tuple(getattr(self.airfoil, "parameter_names", ()))
        valid = self._inputs + self._airfoil_names
        inputs = (("collective_deg", "lateral_deg", "longitudinal_deg") if names_in is None
                  else names_in)
        responses = ("thrust", "torque") if names_out is None else names_out
        for name in list(inputs) + list(fixed or {}):
            self._check_name(name, valid)
        if self.preset.flap_model == "elastic" and "k_flap" in list(inputs) + list(fixed or {}):
            raise ParameterError(
                f"preset {self.preset.name!r} has elastic blades: its flap stiffness comes from "
                "'ei_flap' (EI_y), not 'k_flap'"
            )
        if self.preset.flap_model == "hinge" and "ei_flap" in list(inputs) + list(fixed or {}):
            raise ParameterError(
                f"preset {self.preset.name!r} has rigid hinged blades: use 'k_flap', not 'ei_flap'"
            )
        given = set(inputs) | set(fixed or {})
        if "k_feather" in given and given & {"k_pitch_link"}:
            raise ParameterError(
                "give either 'k_feather' (the feathering stiffness itself, N m/rad) or "
                "'k_pitch_link' (N, acting through the link length and horn arm), not both"
            )
        if len(tuple(responses)) == 0:
            raise ParameterError("names_out is empty: name at least one response; valid: "
                                 f"{', '.join(self._responses)}")
        for name in responses:
            if name not in self._responses:
                raise ParameterError(f"unknown response {name!r}; valid: "
                                     f"{', '.join(self._responses)}")
        if len(set(inputs)) != len(tuple(inputs)):
            raise ParameterError(f"duplicate input names in {list(inputs)}")
        self.names_in = tuple(inputs)
        self.names_out = tuple(responses)
        self.fixed = {k: float(v) for k, v in (fixed or {}).items()}
        self.last_solution: HoverSolution | None = None

    @staticmethod
    def _check_name(name, valid):
        if name not in valid:
            import difflib

            close = difflib.get_close_matches(name, valid, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ParameterError(
                f"unknown rotor input {name!r}{hint}; valid: {', '.join(valid)}"
            )

    def __repr__(self) -> str:
        return (f"RotorModel({self.preset.name!r}, names_in={self.names_in}, "
                f"names_out={self.names_out})")

    def identity(self) -> dict[str, Any]:
        """Everything that can change an answer: the preset's every field, the airfoil
        table's numbers and fit settings, the fixed inputs and the solver options."""
        from dataclasses import asdict

        ident = getattr(self.airfoil, "identity", None)
        solver = {k: v for k, v in vars(self).items() if isinstance(v, (int, float, str, bool))}
        return {"preset": asdict(self.preset),
                "airfoil": ident() if callable(ident) else repr(self.airfoil),
                "grid": vars(self.grid) if hasattr(self.grid, "__dict__") else repr(self.grid),
                "fixed": dict(sorted(self.fixed.items())), "solver": solver}

    def defaults(self) -> dict[str, float]:
        """Value of every rotor input when not given in the batch (preset, then ``fixed``)."""
        p = self.preset
        unused = "ei_flap" if p.flap_model == "hinge" else "k_flap"
        d = {name: float(getattr(p, name)) for name in ROTOR_INPUTS
             if name != unused and name not in OPTIONAL_INPUTS}
        d.update(self.fixed)
        return d

    def __call__(self, x: npt.ArrayLike) -> np.ndarray:
        return self.evaluate(x).values

    def evaluate(self, x: npt.ArrayLike) -> EvalBatch:
        """Evaluate a batch; failed rows are NaN with a reason.

        Parameters
        ----------
        x : array_like of shape (n, len(names_in)) or (len(names_in),)
            Points, columns in ``names_in`` order (angles in deg, SI otherwise).

        Returns
        -------
        EvalBatch
            ``values`` (n, len(names_out)) in the units of :data:`RESPONSES`, and the
            reason of each failed row.
        """
        x = np.atleast_2d(np.asarray(x, dtype=float))
        if x.ndim != 2 or x.shape[1] != len(self.names_in):
            raise ParameterError(
                f"RotorModel expects points of shape (n, {len(self.names_in)}) for inputs "
                f"{self.names_in}, got {x.shape}"
            )
        n = x.shape[0]
        params, overrides = self._columns(x)
        failures = self._validate(params, overrides, n)
        out = np.full((n, len(self.names_out)), np.nan)
        rows = np.array([i for i in range(n) if i not in failures], dtype=np.intp) if (
            failures) else np.arange(n)
        sols = []
        if rows.size:
            if failures:
                params = {k: v[rows] for k, v in params.items()}
                overrides = {k: v[rows] for k, v in overrides.items()}
            sol = self._solve_rows(params, overrides)
            sols.append(sol)
            vals = np.column_stack([sol.response(r) for r in self.names_out])
            bad = ~sol.converged | ~np.all(np.isfinite(vals), axis=1)
            for j in np.flatnonzero(bad):
                failures[int(rows[j])] = str(sol.failure[j]) or "non-finite response"
            vals[bad] = np.nan
            out[rows] = vals
        self.last_solution = _full_solution(n, rows, sols, failures)
        return EvalBatch(out, failures)

    def _columns(self, x: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """The solve's input columns of the points ``x`` (n, len(names_in)): rotor inputs
        (defaults filled in) and airfoil overrides."""
        n = x.shape[0]
        cols = {name: x[:, j] for j, name in enumerate(self.names_in)}
        params, overrides = {}, {}
        defaults = self.defaults()
        filled = np.empty((len(defaults), n))   # one array for every defaulted column
        filled[:] = np.fromiter(defaults.values(), float, len(defaults))[:, None]
        for row, name in enumerate(defaults):
            params[name] = cols[name] if name in cols else filled[row]
        for name in OPTIONAL_INPUTS:
            if name in cols:
                params[name] = cols[name]
        for name in self._airfoil_names:
            if name in cols:
                overrides[name] = cols[name]
            elif name in self.fixed:
                overrides[name] = np.full(n, self.fixed[name])
        return params, overrides

    def section_loads(self, x: npt.ArrayLike, derivatives: Sequence[str] = ()
                      ) -> dict[str, np.ndarray]:
        """The spanwise section loads at points ``x``, which the solve itself does not return:
        thrust per unit span, Mach number and angle of attack per station (azimuth means),
        and the direct effect of airfoil fit parameters on the section thrust.

        Solved again by the numpy reference solve (``rotor/_reference.py``), which agrees
        with the compiled one to 1e-10 (``tests/test_rotor_kernel.py``): a few points, not
        a batch.

        Parameters
        ----------
        x : array_like of shape (n, len(names_in)) or (len(names_in),)
            Points, columns in ``names_in`` order.
        derivatives : sequence of str, optional
            Airfoil fit parameters (``cla_m06``, ...) whose effect on the section thrust,
            with the inflow and blade motion held, is wanted.

        Returns
        -------
        dict of str to ndarray
            ``r``, ``w`` (Nr,) station radius and span weight [m]; ``thrust_per_span``,
            ``mach``, ``alpha_deg`` (n, Nr) [N/m, -, deg]; ``failure`` (n,);
            ``d_thrust_per_span/<name>`` (n, Nr) [N/m per unit of the parameter].

        Examples
        --------
        >>> model = RotorModel("bo105", names_in=["collective_deg"], names_out=["thrust"])
        >>> out = model.section_loads([[6.0]], derivatives=["cla_m06"])
        >>> thrust = float((out["thrust_per_span"] * out["w"]).sum())
        >>> abs(thrust / float(model([[6.0]])[0, 0]) - 1) < 1e-3
        True
        """
        from ._reference import section_loads

        for name in derivatives:
            self._check_name(name, self._airfoil_names)
        x = np.atleast_2d(np.asarray(x, dtype=float))
        params, overrides = self._columns(x)
        return section_loads(self.preset, self.airfoil, self.grid, params, overrides,
                             derivatives=tuple(derivatives), n_harmonics=self.n_harmonics,
                             tolerance=self.tolerance, max_iterations=self.max_iterations)

    def _solve_rows(self, params, overrides) -> HoverSolution:
        """The solution of the valid rows (columns of ``params`` and airfoil overrides)."""
        return solve_hover(self.preset, self.airfoil, self.grid, params, overrides,
                           n_harmonics=self.n_harmonics, tolerance=self.tolerance,
                           max_iterations=self.max_iterations,
                           check_tolerance=self.check_tolerance)

    def solve(self, x: npt.ArrayLike) -> HoverSolution:
        """Full hover solution (loads, coning, pitch, inflow, harmonics) of a valid batch.

        Parameters
        ----------
        x : array_like of shape (n, len(names_in)) or (len(names_in),)
            Points, columns in ``names_in`` order; a point that fails raises
            :class:`~rotoruq.ParameterError`.
        """
        batch = self.evaluate(x)
        if batch.failures:
            raise ParameterError(f"invalid points: {batch.failures}")
        assert self.last_solution is not None
        return self.last_solution

    def _all_valid(self, params, overrides) -> bool:
        """True when no row breaks a rule of :meth:`_validate` (the same tests on stacked
        columns, a few numpy calls: the common case of a small batch costs little)."""
        h = params["height_over_radius"]
        finite = np.array([v for k, v in params.items() if k != "height_over_radius"]
                          + list(overrides.values()))
        nonneg = np.array([params[k] for k in _NONNEGATIVE if k in params])
        positive = np.array([params[k] for k in _POSITIVE])
        amp = (np.abs(params["collective_deg"]) + np.abs(params["lateral_deg"])
               + np.abs(params["longitudinal_deg"]))
        tip_mach = params["omega"] * self.preset.radius / self.preset.speed_of_sound
        h_min = min_height_over_radius(self.preset.ground_effect)
        return bool(np.isfinite(finite).all() and not np.isnan(h).any()
                    and not (nonneg < 0).any() and not (positive <= 0).any()
                    and not ((h <= MIN_HEIGHT_OVER_RADIUS) | (h < h_min)).any()
                    and not (amp > MAX_PITCH_DEG).any() and not (tip_mach >= 1.0).any())

    def _validate(self, params, overrides, n) -> dict[int, str]:
        if self._all_valid(params, overrides):
            return {}
        failures: dict[int, str] = {}

        def fail(mask, reason):
            if not mask.any():
                return
            for i in np.flatnonzero(mask):
                failures.setdefault(int(i), reason(i))

        for name, v in list(params.items()) + list(overrides.items()):
            if name == "height_over_radius":
                fail(np.isnan(v), lambda i, name=name: f"{name} is NaN")
            else:
                fail(~np.isfinite(v), lambda i, name=name, v=v: f"{name} is {v[i]}")
        for name in _NONNEGATIVE:
            if name not in params:
                continue
            v = params[name]
            fail(v < 0, lambda i, name=name, v=v: f"{name} must be >= 0, got {v[i]:g}")
        for name in _POSITIVE:
            v = params[name]
            fail(v <= 0, lambda i, name=name, v=v: f"{name} must be > 0, got {v[i]:g}")
        h = params["height_over_radius"]
        h_min = min_height_over_radius(self.preset.ground_effect)
        if h_min <= MIN_HEIGHT_OVER_RADIUS:
            why = ("is at or below R/4, outside every ground-effect model's validity "
                   "(Cheeseman-Bennett is singular at R/4)")
        else:
            why = (f"is below {h_min:g} R, the lowest height of the "
                   f"{self.preset.ground_effect!r} ground-effect data")
        fail((h <= MIN_HEIGHT_OVER_RADIUS) | (h < h_min),
             lambda i: f"height_over_radius {h[i]:g} {why}")
        amp = (np.abs(params["collective_deg"]) + np.abs(params["lateral_deg"])
               + np.abs(params["longitudinal_deg"]))
        fail(amp > MAX_PITCH_DEG,
             lambda i: f"blade pitch command |collective| + |lateral| + |longitudinal| = "
             f"{amp[i]:.3g} deg exceeds {MAX_PITCH_DEG:g} deg: no rotor operating state")
        tip_mach = params["omega"] * self.preset.radius / self.preset.speed_of_sound
        fail(tip_mach >= 1.0,
             lambda i: f"tip Mach number {tip_mach[i]:.3g} (omega {params['omega'][i]:g} rad/s) "
             "is supersonic: outside the blade-element model")
        return failures


def _full_solution(n, rows, sols, failures) -> HoverSolution | None:
    """One solution row per input row: the solved rows in place, rows rejected before the
    solve NaN (False, 0) with their reason in ``failure``."""
    if not sols:
        return None
    part = type(sols[0]).concatenate(sols)
    if rows.size == n:
        return part
    kw = {}
    for f in fields(part):
        a = getattr(part, f.name)
        if f.name == "failure":
            full = np.array([failures.get(i, "") for i in range(n)], dtype=object)
            full[rows] = a
            kw[f.name] = full.astype(str)
            continue
        fill = {"b": False, "i": 0}.get(a.dtype.kind, np.nan)
        full = np.full((n,) + a.shape[1:], fill, dtype=a.dtype)
        full[rows] = a
        kw[f.name] = full
    return type(part)(**kw)
