"""Periodic steady state of a hovering rotor, batched over samples.

One blade is solved over one revolution: in hover at constant speed every blade follows the
same periodic motion shifted by 2 pi / N_b, so hub loads follow from one blade's harmonics
(mean loads = N_b x the azimuth mean; hub roll/pitch = N_b / 2 x the first harmonic of the
blade-root flap moment). The blade motion is a Fourier series (harmonic balance) solved by a
Newton-like iteration whose Jacobian is the structural operator plus linear aerodynamic
flap damping and pitch-flap stiffness, with the airfoil's own lift slope at the sample's
operating point (with a fixed linear-theory slope the iteration contracted only by that
slope's error, about 0.2 per step at the gvpm preset's nominal point); the inflow is updated
by Newton steps on momentum.
This is equivalent to time-marching to periodic steady state and averaging over the last two
revolutions, as the reference study did in MBDyn, without the transient.

The solve is compiled (:mod:`rotoruq.rotor._kernel`, numba; its notation block gives the
symbols and units): each sample iterates on its own until it converges, large batches are
spread over the cores, and a sample's result is bitwise the same whatever batch, chunk or
thread count it is solved with.

Every returned row is either a converged solution whose equations were re-evaluated at the
final state (``equation_residual`` below ``check_tolerance``) or carries a failure reason:
diverged, not converged, residual check failed, or a physically invalid regime (deep stall
over the disk, torsional divergence, negative drag, negative power).
"""

from __future__ import annotations

import logging
import os
import queue
import threading
from collections.abc import Mapping
from concurrent.futures import Future
from dataclasses import dataclass, fields
from typing import Any, NamedTuple

import numba
import numpy as np

from ..errors import ParameterError
from . import _kernel as kern
from .aero import LinearAirfoil
from .airfoil import Airfoil
from .geometry import CANTILEVER_SPRING_FACTOR, BladeGrid
from .ground_effect import ground_effect_factor
from .presets import RotorPreset

log = logging.getLogger(__name__)

__all__ = ["HoverSolution", "solve_hover", "check_airfoil", "STALL_AREA_LIMIT",
           "MAX_BLADE_MOTION", "PARALLEL_MIN_BATCH"]

#: Fraction of the disk's blade-element area (weighted by r dr dpsi) beyond the airfoil's
#: stall angle above which a solution is a physically invalid regime ("deep stall").
STALL_AREA_LIMIT = 0.5
#: Blade motion harmonics beyond this amplitude [rad] mean the iteration diverged.
MAX_BLADE_MOTION = kern.MAX_BLADE_MOTION
#: Batches at least this large are spread over ``numba.get_num_threads()`` threads (smaller:
#: the calling thread alone); the results are the same either way, bitwise.
PARALLEL_MIN_BATCH = 16
#: Slices per thread of a spread batch (samples differ in cost: smaller slices balance).
SLICES_PER_THREAD = 4

class _DaemonPool:
    """``n_threads`` daemon threads that run submitted calls. Not a ThreadPoolExecutor: the
    interpreter joins those at exit, so a run ended by Ctrl-C or SIGTERM waited for the batch
    (or a first compile, minutes long) still running on them; nothing these threads compute
    is saved unless the caller gets it back, so they may simply stop with the process."""

    def __init__(self, n_threads: int) -> None:
        self._jobs: queue.SimpleQueue = queue.SimpleQueue()
        for k in range(n_threads):
            threading.Thread(target=self._work, name=f"rotoruq-rotor_{k}", daemon=True).start()

    def _work(self) -> None:
        while True:
            future, fn, args = self._jobs.get()
            if not future.set_running_or_notify_cancel():
                continue
            try:
                future.set_result(fn(*args))
            except BaseException as exc:  # noqa: BLE001 - handed to the caller
                future.set_exception(exc)

    def submit(self, fn: Any, *args: Any) -> Future:
        """Run ``fn(*args)`` on a pool thread."""
        future: Future = Future()
        self._jobs.put((future, fn, args))
        return future


_POOLS: dict[tuple[int, int], _DaemonPool] = {}


def _pool(n_threads: int) -> _DaemonPool:
    """A thread pool of this process (a forked child makes its own) with n_threads workers."""
    key = (os.getpid(), n_threads)
    pool = _POOLS.get(key)
    if pool is None:
        _POOLS.clear()
        pool = _POOLS[key] = _DaemonPool(n_threads)
    return pool


@dataclass(frozen=True, eq=False)
class HoverSolution:
    """Loads and state of a batch of hover solutions (every array has leading axis n).

    thrust [N], torque [N m] (positive = power absorbed), roll, pitch [N m] (hub moments in
    the non-rotating frame: roll positive right side down, pitch positive nose up),
    power [W], ct, cq [-]; coning_deg, theta_75_deg (mean blade pitch at 0.75 R, after the
    pitch-link deflection), inflow_ratio (mean lambda); flap/lag/feather harmonics (n, K) in
    rad; residual (n,): last iteration step [rad or inflow ratio]; equation_residual (n,): the
    equations re-evaluated at the returned state (structural residual over its k = 0
    stiffness [rad]; momentum residual as the inflow-ratio change a Newton step would make);
    stalled_fraction (n,): share of blade-element area beyond the stall angle;
    iterations (n,) int; converged (n,) bool (True only for valid rows); failure (n,) str, ""
    for a valid row, else the reason the row is NaN.
    """

    thrust: np.ndarray
    torque: np.ndarray
    roll: np.ndarray
    pitch: np.ndarray
    power: np.ndarray
    ct: np.ndarray
    cq: np.ndarray
    coning_deg: np.ndarray
    theta_75_deg: np.ndarray
    inflow_ratio: np.ndarray
    flap: np.ndarray
    lag: np.ndarray
    feather: np.ndarray
    residual: np.ndarray
    equation_residual: np.ndarray
    stalled_fraction: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    failure: np.ndarray

    def response(self, name: str) -> np.ndarray:
        return getattr(self, name)

    @staticmethod
    def concatenate(parts: list[HoverSolution]) -> HoverSolution:
        """Join solutions of consecutive chunks along the sample axis."""
        if len(parts) == 1:
            return parts[0]
        cls = type(parts[0])
        return cls(**{f.name: np.concatenate([getattr(p, f.name) for p in parts])
                      for f in fields(cls)})

    @staticmethod
    def assemble(preset: RotorPreset, grid: BladeGrid, omega: np.ndarray, rho: np.ndarray,
                 Q: np.ndarray, v0: np.ndarray, checked: Mapping[str, np.ndarray],
                 M_root: np.ndarray, residual: np.ndarray, iterations: np.ndarray,
                 failure: np.ndarray) -> HoverSolution:
        """The solution from the final states: Q (n, 3, K) motion harmonics [rad], v0 (n,)
        [m/s], ``checked`` thrust, torque, eq, stalled (n,) and M_root (n, K) [N m] from the
        final check (NaN where not checked), failure (n,) "" for a valid row."""
        valid = failure == ""
        R = preset.radius
        vt = omega * R
        area = preset.area
        thrust, torque = checked["thrust"].copy(), checked["torque"].copy()
        loads = {
            "thrust": thrust, "torque": torque,
            "roll": 0.5 * preset.n_blades * M_root[:, 1].imag,
            "pitch": -0.5 * preset.n_blades * M_root[:, 1].real,
            "power": torque * omega, "ct": thrust / (rho * area * vt**2),
            "cq": torque / (rho * area * vt**2 * R),
        }
        for v in loads.values():
            v[~valid] = np.nan
        i75 = int(np.argmin(np.abs(grid.r - 0.75 * R)))
        return HoverSolution(
            **loads,
            coning_deg=np.rad2deg(Q[:, 0, 0].real),
            theta_75_deg=np.rad2deg(Q[:, 2, 0].real + grid.twist[i75]),
            inflow_ratio=v0 / vt,
            flap=Q[:, 0],
            lag=Q[:, 1],
            feather=Q[:, 2],
            residual=residual,
            equation_residual=checked["eq"],
            stalled_fraction=checked["stalled"],
            iterations=iterations,
            converged=valid,
            failure=failure.astype(str),
        )


def check_airfoil(airfoil: Any) -> None:
    """ParameterError unless the compiled solve can take ``airfoil``: an
    :class:`~rotoruq.rotor.airfoil.Airfoil` (c81 table) or a
    :class:`~rotoruq.rotor.aero.LinearAirfoil`."""
    if not isinstance(airfoil, (Airfoil, LinearAirfoil)):
        raise ParameterError(
            f"the rotor model takes an Airfoil (a c81 table, rotoruq.rotor.airfoil.Airfoil) or a "
            f"LinearAirfoil (rotoruq.rotor.aero), got {type(airfoil).__name__}; tabulate other "
            "aerodynamics as a c81 file (rotoruq.rotor.c81.write_c81)")


def _col(p, name, n):
    v = p[name]
    if isinstance(v, np.ndarray) and v.shape == (n,) and v.dtype == np.float64:
        return v
    return np.ascontiguousarray(np.broadcast_to(np.asarray(v, dtype=float), (n,)))


def sample_columns(preset: RotorPreset, grid: BladeGrid, params: Mapping[str, np.ndarray],
                   n: int) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray]:
    """The inputs as columns of n samples (``cm0`` and ``aero_center_offset`` from the preset
    when not given) and the per-sample constants both solvers derive from them: kappa (the
    ground-effect factor times the induced power factor), K_b (the flap spring, from EI for
    elastic blades) and K_p (the feathering stiffness through the pitch link, unless
    ``k_feather`` is given)."""
    P = {k: _col(params, k, n) for k in params}
    for name in ("cm0", "aero_center_offset"):
        P.setdefault(name, np.full(n, float(getattr(preset, name))))
    kappa = ground_effect_factor(P["height_over_radius"], preset.ground_effect)
    kappa = kappa * preset.induced_power_factor
    if preset.flap_model == "elastic":
        K_b = CANTILEVER_SPRING_FACTOR * P["ei_flap"] / grid.blade_length
    else:
        K_b = P["k_flap"]
    K_p = P["k_feather"] if "k_feather" in P else preset.feathering_stiffness(P["k_pitch_link"])
    return P, kappa, K_b, K_p


def sample_inputs(preset: RotorPreset, grid: BladeGrid, params: Mapping[str, np.ndarray],
                  n: int) -> np.ndarray:
    """The per-sample input matrix of the compiled solve, (n, kern.N_COLUMNS): rotor speed,
    density, kappa, the structural constants (K_b from EI for elastic blades, K_p and C_p
    through the pitch link unless ``k_feather`` is given), x_ac, cm0 and the commands [deg]."""
    P, kappa, K_b, K_p = sample_columns(preset, grid, params, n)
    prm = np.zeros((n, kern.N_COLUMNS))   # the forward-flight columns 0: hover
    for col, value in ((kern.OMEGA, P["omega"]), (kern.RHO, P["rho"]), (kern.KAPPA, kappa),
                       (kern.K_FLAP, K_b), (kern.C_FLAP, P["c_flap"]),
                       (kern.K_LAG, P["k_lag"]), (kern.C_LAG, P["c_lag"]),
                       (kern.K_FEATHER, K_p),
                       (kern.C_FEATHER, preset.feathering_stiffness(P["c_pitch_link"])),
                       (kern.X_AC, P["aero_center_offset"]), (kern.CM0, P["cm0"]),
                       (kern.COLLECTIVE, P["collective_deg"]),
                       (kern.LATERAL, P["lateral_deg"]),
                       (kern.LONGITUDINAL, P["longitudinal_deg"])):
        prm[:, col] = value
    return prm


_CONSTANTS: dict[tuple[RotorPreset, int, int], tuple[BladeGrid, kern.Rotor]] = {}


def rotor_constants(preset: RotorPreset, grid: BladeGrid, n_harmonics: int) -> kern.Rotor:
    """The rotor and grid constants of the compiled solve (the grid integrals summed as the
    numpy implementation sums them); the last few are kept."""
    key = (preset, id(grid), n_harmonics)
    hit = _CONSTANTS.get(key)
    if hit is not None and hit[0] is grid:
        return hit[1]
    if len(_CONSTANTS) > 16:
        _CONSTANTS.clear()
    rot = _rotor_constants(preset, grid, n_harmonics)
    _CONSTANTS[key] = (grid, rot)
    return rot


def _rotor_constants(preset: RotorPreset, grid: BladeGrid, n_harmonics: int) -> kern.Rotor:
    e, R = preset.hinge_offset, preset.radius
    r, w, psi = grid.r, grid.w, grid.psi
    rr = r - e
    k = np.arange(n_harmonics + 1)
    kp = np.outer(k, psi)
    cos_k, sin_k = np.cos(kp), np.sin(kp)
    scale = np.full(k.shape, 2.0 / psi.size)
    scale[0] = 1.0 / psi.size
    analysis = np.concatenate([cos_k * scale[:, None], -sin_k * scale[:, None]])
    sums = np.empty(kern.N_SUMS)
    sums[kern.SUM_W_R_RR2] = float(np.sum(w * r * rr**2))
    sums[kern.SUM_W_R2_RR] = float(np.sum(w * r**2 * rr))
    sums[kern.SUM_W_R2] = float(np.sum(w * r**2))
    sums[kern.SUM_W_R_RR] = float(np.sum(w * r * rr))
    sums[kern.SUM_W_R] = float(np.sum(w * r))
    sums[kern.SUM_W_R3] = float(np.sum(w * r**3))
    sums[kern.SUM_W_R_RR_R] = float(np.sum(w * r * rr * r))
    return kern.Rotor(
        radius=float(R), chord=float(preset.chord), hinge_offset=float(e),
        n_blades=int(preset.n_blades), area=float(preset.area),
        speed_of_sound=float(preset.speed_of_sound), root_cutout=float(preset.root_cutout),
        pitch_inertia=float(preset.pitch_inertia), I_flap=float(grid.I_flap),
        I_lag=float(grid.I_lag), S_flap=float(grid.S_flap),
        tan_delta3=float(np.tan(np.deg2rad(preset.delta3_deg))),
        solidity=float(preset.solidity), twist_rad=float(np.deg2rad(preset.twist_deg)),
        bemt=preset.inflow == "bemt", harmonic_inflow=bool(preset.harmonic_inflow),
        tip_loss=bool(preset.tip_loss), pitching_moment=bool(preset.pitching_moment),
        r=np.ascontiguousarray(r, dtype=float), w=np.ascontiguousarray(w, dtype=float),
        rr=rr, twist=np.ascontiguousarray(grid.twist, dtype=float), w_rr=w * rr, w_r=w * r,
        cos_psi=np.cos(psi), sin_psi=np.sin(psi), cos_k=cos_k, sin_k=sin_k,
        analysis=np.ascontiguousarray(analysis), sums=sums)


_EMPTY_F = np.empty(0)
_EMPTY_I = np.empty(0, dtype=np.intp)


def airfoil_table(airfoil: Airfoil | LinearAirfoil) -> kern.Table:
    """The airfoil in the compiled solve's form (kept on a table airfoil)."""
    check_airfoil(airfoil)
    if isinstance(airfoil, LinearAirfoil):
        z = np.zeros(2)
        return kern.Table(kern.LINEAR, z, z, np.zeros((3, 4)), z, 0.0, False, False,
                          _EMPTY_I, _EMPTY_F, z, 0.0, 0.0, 0, z, _EMPTY_F, _EMPTY_F,
                          float(airfoil.cda2))
    if airfoil._kernel_table is not None:
        return airfoil._kernel_table
    ba, bm = airfoil._ba, airfoil._bm
    has_fits = airfoil.nominal is not None
    values = np.stack(airfoil._mod_cols if has_fits else airfoil._raw_cols)
    ga, gm = airfoil._ga, airfoil._gm
    A, M = np.meshgrid(ga, gm, indexing="ij")
    a_pos, a_neg = airfoil.stall_angles(gm)
    lut = ba._lut if ba._lut is not None else _EMPTY_I
    table = kern.Table(
        kern.TABLE, ga, gm, np.ascontiguousarray(values), np.ascontiguousarray(airfoil._h),
        float(airfoil.alpha_window), has_fits, bool(airfoil._replace_cd),
        np.ascontiguousarray(lut, dtype=np.intp), ba._next, ba._inv_dx,
        float(getattr(ba, "_x0", 0.0)), float(getattr(ba, "_inv_h", 0.0)),
        int(getattr(ba, "_nbins", 0)), bm._inv_dx,
        np.ascontiguousarray(a_pos, dtype=float), np.ascontiguousarray(a_neg, dtype=float),
        0.0)
    airfoil._kernel_table = table
    return table


def airfoil_samples(airfoil: Airfoil | LinearAirfoil, overrides: Mapping[str, np.ndarray],
                    n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample airfoil coefficients: the fit-row coefficients (n, 5, n_m) of a table
    airfoil and (cla, cl0, cd0) (n, 3) of a linear one (the other one is a dummy)."""
    if isinstance(airfoil, LinearAirfoil):
        unknown = sorted(set(overrides) - set(airfoil.parameter_names))
        if unknown:
            raise ParameterError(f"unknown airfoil parameter(s) {unknown}; valid names: "
                                 f"{', '.join(airfoil.parameter_names)}")
        linear = np.empty((n, 3))
        for j, name in enumerate(("cla", "cl0", "cd0")):
            linear[:, j] = _col(overrides, name, n) if name in overrides else getattr(
                airfoil, name)
        return np.zeros((n, 5, 2)), linear
    nm = airfoil._gm.size
    if airfoil.nominal is None:
        if overrides:
            airfoil._override_values(dict(overrides), n)   # raises: no parameters
        return np.zeros((n, 5, nm)), np.zeros((n, 3))
    if any(name not in airfoil._name_index for name in overrides):
        airfoil._override_values(dict(overrides), n)   # raises: names the valid parameters
    # the nominal coefficients at every Mach column, then each override at its fit row's
    # column(s) (the values Airfoil._coef_table places, without its per-call reshaping)
    fits = np.empty((n, 5, nm))
    fits[:] = airfoil._coef_cols.reshape(5, nm)
    for name in overrides:
        row, coefficient = airfoil._name_index[name]
        fits[:, coefficient, airfoil._fitcol == row] = _col(overrides, name, n)[:, None]
    return fits, np.zeros((n, 3))


def default_check_tolerance(tolerance: float, check_tolerance: float | None = None) -> float:
    """``check_tolerance``, or its default max(1e-6, 100 ``tolerance``) when None."""
    return max(1e-6, 100.0 * tolerance) if check_tolerance is None else check_tolerance


def solve_hover(
    preset: RotorPreset,
    airfoil: Airfoil | LinearAirfoil,
    grid: BladeGrid,
    params: Mapping[str, np.ndarray],
    overrides: Mapping[str, np.ndarray] | None = None,
    *,
    n_harmonics: int = 2,
    tolerance: float = 1e-9,
    max_iterations: int = 200,
    check_tolerance: float | None = None,
) -> HoverSolution:
    """Solve the periodic hover state for n samples.

    params : every entry of :data:`rotoruq.rotor.model.ROTOR_INPUTS` except the optional
        ``k_feather`` (which, when present, replaces the pitch-link stiffness), arrays of
        shape (n,) (angles in deg). overrides : airfoil coefficient overrides, arrays (n,).
    tolerance : convergence of a sample's iteration (largest step of the motion harmonics
        [rad] and of the inflow ratio). max_iterations : iterations per sample.
    check_tolerance : the equations re-evaluated at the returned state (structural residual /
        its k = 0 stiffness [rad], momentum residual as a Newton step of the inflow ratio,
        harmonic inflow [-]) must be below it (default max(1e-6, 100 tolerance)).
    A sample that fails any check has ``converged`` False and its reason in ``failure``.
    """
    with np.errstate(all="ignore"):   # absurd inputs fail per row, never for the batch
        n, K, rot, table, fits, linear, prm = prepare(preset, airfoil, grid, params,
                                                      overrides, n_harmonics)
        return _solve(preset, grid, prm, rot, table, fits, linear, n, K, tolerance,
                      max_iterations, check_tolerance)


def prepare(preset, airfoil, grid, params, overrides, n_harmonics):
    """The compiled solve's inputs of a batch: (n, K, rotor constants, airfoil table,
    per-sample fits and linear coefficients, the input matrix (n, kern.N_COLUMNS))."""
    overrides = overrides or {}
    n = np.broadcast(*[np.asarray(v) for v in params.values()]).shape[0]
    rot = rotor_constants(preset, grid, n_harmonics)
    table = airfoil_table(airfoil)
    fits, linear = airfoil_samples(airfoil, overrides, n)
    return n, n_harmonics + 1, rot, table, fits, linear, sample_inputs(preset, grid, params, n)


class KernelResult(NamedTuple):
    """The compiled solve's outputs of a batch, judged: motion harmonics Q (n, 3, K) [rad],
    scalars (n, kern.N_SCALARS), loads (n, kern.N_LOADS) re-evaluated at the final state
    (their named columns in ``checked``), blade-root flap moment harmonics M_root (n, K)
    [N m], iterations (n,) and failure (n,) ("" for a valid row)."""

    Q: np.ndarray
    scalars: np.ndarray
    checked: dict
    M_root: np.ndarray
    iterations: np.ndarray
    failure: np.ndarray


def run_kernel(prm, rot, table, fits, linear, n, K, tolerance, max_iterations,
               check_tolerance, *, negative_power=False) -> KernelResult:
    """Solve the rows of ``prm`` and judge them (:func:`judge`; ``negative_power`` lets a
    row absorb negative power: a rotor in forward flight may be driven by the wind)."""
    check_tolerance = default_check_tolerance(tolerance, check_tolerance)
    Q = np.zeros((n, 3, K), dtype=complex)
    scalars = np.zeros((n, kern.N_SCALARS))
    status = np.zeros((n, 4), dtype=np.int64)
    loads = np.full((n, kern.N_LOADS), np.nan)
    M_root = np.full((n, K), np.nan, dtype=complex)
    _solve_spread(prm, rot, table, fits, linear, float(tolerance), int(max_iterations), Q,
                  scalars, status, loads, M_root)
    iterations = status[:, 3].copy()
    failure = np.array([""] * n, dtype=object)
    for i in np.flatnonzero(status[:, 0] != kern.OK):
        failure[i] = iteration_failure(int(status[i, 0]), int(status[i, 1]),
                                       bool(status[i, 2]), int(iterations[i]),
                                       float(scalars[i, kern.RESID]))
    checked = {name: loads[:, j] for j, name in enumerate(
        ("thrust", "torque", "eq", "stalled", "cd_min", "k_eff", "bad", "h_force",
         "y_force"))}
    live = np.flatnonzero(failure == "")
    mean_pitch = Q[:, 2, 0].real
    judge(live, checked, mean_pitch, prm[:, kern.COLLECTIVE], prm[:, kern.OMEGA], failure,
          check_tolerance, negative_power=negative_power)
    return KernelResult(Q, scalars, checked, M_root, iterations, failure)


def _solve(preset, grid, prm, rot, table, fits, linear, n, K, tolerance, max_iterations,
           check_tolerance) -> HoverSolution:
    res = run_kernel(prm, rot, table, fits, linear, n, K, tolerance, max_iterations,
                     check_tolerance)
    return HoverSolution.assemble(preset, grid, prm[:, kern.OMEGA], prm[:, kern.RHO], res.Q,
                                  res.scalars[:, kern.V0], res.checked, res.M_root,
                                  res.scalars[:, kern.RESID], res.iterations, res.failure)


def _solve_spread(prm, rot, table, fits, linear, tolerance, max_iterations, *out) -> None:
    """The compiled solve of every row, on numba.get_num_threads() threads for a large batch
    (contiguous slices; each row's numbers do not depend on the slice)."""
    flight = kern.needs_flight(prm)  # a hover batch runs (and compiles) the hover build
    with compiling_kernels(flight is not None):
        _solve_threads(prm, rot, table, fits, linear, tolerance, max_iterations, flight, *out)


def _is_build(forward_flight: bool):
    """The test of a cached signature of ``solve_samples`` for the hover (``flight`` typed
    none) or the forward-flight build."""
    return lambda types: (types[-1] != "none") == forward_flight


def kernels_cached(forward_flight: bool = False) -> bool:
    """Whether numba's on-disk cache holds the rotor kernel's hover (or forward-flight)
    build for this source file.

    Reads the cache's small index (no compilation): False when the index is absent, was
    written for another version of ``_kernel.py`` (numba would recompile then), or holds
    the other build only.

    Returns
    -------
    bool
        True when the first evaluation will load compiled code instead of compiling.

    Examples
    --------
    >>> isinstance(kernels_cached(), bool)
    True
    """
    from .._compile import is_cached

    return is_cached(kern.solve_samples, _is_build(forward_flight))


def compiling_kernels(forward_flight: bool):
    """Around a solve: say once per process and build, before the first, that the rotor
    kernels are being compiled (and keep a "compiling ..." phase open while they are). The
    hover and forward-flight builds are announced each when its own code is not cached,
    and share one compile lock (one cache index)."""
    from .._compile import compiling

    family = "forward-flight rotor kernels" if forward_flight else "rotor kernels"
    return compiling(family, [kern.solve_samples], log, "30-90",
                     variant=_is_build(forward_flight), lock="rotor kernels")


def _solve_threads(prm, rot, table, fits, linear, tolerance, max_iterations, flight,
                   *out) -> None:
    n = prm.shape[0]
    n_threads = numba.get_num_threads()
    if n < PARALLEL_MIN_BATCH or n_threads < 2:
        kern.solve_samples(prm, rot, table, fits, linear, tolerance, max_iterations, *out,
                           flight)
        return
    edges = np.linspace(0, n, min(n, SLICES_PER_THREAD * n_threads) + 1).astype(int)

    def run(k: int) -> None:
        rows = slice(edges[k], edges[k + 1])
        kern.solve_samples(prm[rows], rot, table, fits[rows], linear[rows], tolerance,
                           max_iterations, *(a[rows] for a in out), flight)

    for future in [_pool(n_threads).submit(run, k) for k in range(edges.size - 1)]:
        future.result()


def iteration_failure(reason: int, dof: int, bad: bool, iterations: int,
                      last_step: float) -> str:
    """The reason text of a sample whose iteration diverged or did not converge."""
    if reason == kern.TRIM_PITCH:
        return (f"cannot trim: the trim iteration asked for a blade pitch |collective| + "
                f"|cyclic| beyond {kern.TRIM_PITCH_LIMIT_DEG:g} deg after {iterations} "
                "iterations")
    if reason == kern.TRIM_SINGULAR:
        return ("cannot trim: the hub moments do not depend on the flapping (no hinge offset, "
                "flap spring or flap damper: the hub transmits no moment); trim to zero "
                "flapping (trim='wind_tunnel') instead")
    if reason == kern.NOT_CONVERGED:
        return (f"periodic solution did not converge in {iterations} iterations "
                f"(last step {last_step:.2e})")
    name = ("flap", "lag", "pitch")[dof]
    why = ("the section flow became non-finite" if reason == kern.NONFINITE
           else f"the blade {name} exceeded 2 pi rad")
    if name == "pitch" and not bad:
        why += ": torsional divergence"
    return f"iteration diverged after {iterations} iterations ({why})"


def judge(live: np.ndarray, checked: Mapping[str, np.ndarray], mean_pitch: np.ndarray,
          collective_deg: np.ndarray, omega: np.ndarray, failure: np.ndarray,
          check_tolerance: float, *, negative_power: bool = False) -> None:
    """Failure reasons of the samples ``live`` from the state re-evaluated at convergence
    (in place): non-finite loads, residual check, deep stall, torsional divergence, negative
    drag or power. mean_pitch [rad], collective_deg [deg], omega [rad/s] per sample."""
    thrust, torque, eq = checked["thrust"], checked["torque"], checked["eq"]
    stalled, cd_min, k_eff = checked["stalled"], checked["cd_min"], checked["k_eff"]
    bad = checked["bad"]
    # the rows that may fail a test below, found with whole-array tests (a superset: each
    # is then judged row by row, the rest pass)
    th_all = np.rad2deg(mean_pitch[live])
    cmd_all = np.rad2deg(np.deg2rad(collective_deg[live]))
    with np.errstate(invalid="ignore"):
        suspect = ((bad[live] != 0) | ~np.isfinite(thrust[live]) | ~np.isfinite(torque[live])
                   | ~(eq[live] <= check_tolerance) | (stalled[live] > STALL_AREA_LIMIT)
                   | (np.sign(cmd_all) * (th_all - cmd_all) > np.maximum(2.0, np.abs(cmd_all)))
                   | (cd_min[live] < 0) | ((torque[live] < 0) & (not negative_power))
                   | ~(k_eff[live] > 0))
    for i in live[suspect]:
        frac = stalled[i]
        th = float(np.rad2deg(mean_pitch[i]))
        cmd = float(np.rad2deg(np.deg2rad(collective_deg[i])))
        if bad[i] or not np.all(np.isfinite([thrust[i], torque[i]])):
            failure[i] = "non-finite loads at the converged state"
        elif not eq[i] <= check_tolerance:
            failure[i] = (f"the equations re-evaluated at the converged state leave a residual "
                          f"{eq[i]:.2e} above {check_tolerance:.0e}")
        elif frac > STALL_AREA_LIMIT:
            msg = (f"physically invalid regime: deep stall over {100 * frac:.0f} % of the disk "
                   f"(mean blade pitch {th:.1f} deg")
            if th * cmd > 0 and abs(th) > abs(cmd) + max(2.0, 0.25 * abs(cmd)):
                msg += (f" against {cmd:.1f} deg commanded: driven into stall by torsional "
                        "divergence through the pitch link")
            else:
                msg += f", {cmd:.1f} deg commanded"
            failure[i] = msg + ")"
        elif np.sign(cmd) * (th - cmd) > max(2.0, abs(cmd)):
            failure[i] = (f"physically invalid regime: torsional divergence (the aerodynamic "
                          f"pitching moment drove the mean blade pitch {th - cmd:+.1f} deg past "
                          f"the {cmd:.1f} deg commanded)")
        elif cd_min[i] < 0:
            power = torque[i] * omega[i]
            failure[i] = (f"physically invalid regime: negative section drag coefficient "
                          f"(min cd {cd_min[i]:.3g}" + (
                              f"; negative power {power:.3g} W)" if power < 0 else ")"))
        elif torque[i] < 0 and not negative_power:
            failure[i] = (f"physically invalid regime: negative power in hover "
                          f"({torque[i] * omega[i]:.3g} W)")
        elif not k_eff[i] > 0:
            failure[i] = ("physically invalid regime: torsional divergence (the aerodynamic "
                          "pitching moment's stiffness exceeds the feathering stiffness: "
                          f"margin {k_eff[i]:.3g} N m/rad)")
