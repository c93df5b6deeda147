"""The compiled hover solve: one sample at a time, from its inputs to its hub loads.

Notation (per sample; arrays over azimuth j = 0..N_psi-1 and span stations i = 0..N_r-1)

    Omega     rotor speed [rad/s]                 rho      air density [kg/m^3]
    kappa     induced-velocity factor (ground effect x induced power factor) [-]
    R, e, c   radius, flap/lag hinge offset, chord [m]        N_b   number of blades
    r_i, w_i  Gauss stations and weights [m]; rr_i = r_i - e [m]; twist_i [rad]
    psi_j     azimuth [rad]; k = 0..H harmonic index; w_k = k Omega [rad/s]
    Q[d, k]   blade motion harmonics [rad], d = 0 flap beta, 1 lag zeta, 2 feathering theta;
              q_d(psi) = Re(sum_k Q[d, k] exp(i k psi))
    Z_k       structural operator (3x3 complex) [N m/rad]; J_k = Z_k + linear aerodynamic
              damping/stiffness: the Newton-like Jacobian (a preconditioner)
    a_lift    the sample's lift slope [1/rad] in J_k (:func:`_lift_slope`; BEMT: A0)
    K_b, C_b  flap spring [N m/rad], damper [N m s/rad]; K_l, C_l the same for lag
    K_p, C_p  feathering stiffness [N m/rad], damping [N m s/rad] (through the pitch link)
    x_ac      aerodynamic centre aft of the feathering axis [m]; cm0 added section CM [-]
    v0        uniform induced velocity [m/s]; v_r[i] BEMT annulus induced velocity [m/s];
              (vc, vs) first-harmonic (Pitt-Peters) inflow [m/s]
    U_T, U_P  in-plane and normal section velocity [m/s]; phi = atan2(U_P, U_T) inflow angle
    alpha     section angle of attack [deg]; M Mach number [-]; cl, cd, cm section coefficients
    dF_z, dF_x, dM_p  section thrust, in-plane force [N/m] and feathering moment [N m/m]
    relax     per-sample step factor [-]; size: largest step of Q [rad] and of v / (Omega R)

Stages of one iteration: :func:`_aerodynamic_loads` (section loads over the disk at the state),
:func:`_blade_root_loads` (their harmonics: the structural residual), the motion step with
the Jacobian of :func:`_structural_jacobian`, :func:`_inflow_update` (momentum); at the final
state :func:`_hub_loads` re-evaluates the equations and gives the loads. In forward flight
and when trimmed the motion, inflow and control step is :func:`_coupled_step`, one real
system over every harmonic with the Jacobian of :func:`_coupled_jacobian` (the hover blocks
plus forward flight's couplings between the harmonics, the inflow and the controls), which
each iteration corrects by Broyden's rank-one secant update from the last step.

Every sample is solved on its own by :func:`_solve_sample`: its own step control and
convergence test, no reduction across samples, sums in numpy's pairwise order; so a sample's
result is bitwise the same in any batch, chunk or thread. :func:`solve_samples` runs without
the GIL, so :func:`rotoruq.rotor.hover.solve_hover` spreads a large batch over threads. No
fast-math: the operation order is the source's. ``rotoruq.rotor._reference`` holds the numpy
implementation the tests compare this with (1e-10 relative).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from numba.core import cgutils, types
from numba.core.extending import intrinsic

from .. import _numba_cache  # noqa: F401  (the cache keyed by what the kernels compile in)

_JIT = {"cache": True, "error_model": "numpy", "nogil": True}
# small functions of scalars called per blade element: inlined into their caller (no call
# overhead). Per-element code that reads arrays is written out in its loop instead: numba
# updates the reference count of every array passed to an inlined helper, an atomic
# operation per array and call that cost 14 % of the solve (issue 12).
_INLINE = {**_JIT, "inline": "always"}
# the stages, called only from compiled code: no CPython wrapper (issue 34). Each compiled
# function's library is optimised and compiled to machine code on its own, and a wrapper
# unboxes every array of the Rotor, Table and Work tuples it takes: 42 -> 30 CPU-s of a cold
# hover build. Such a function cannot be called from Python (its entry point is null): a
# test calls it from a compiled function of its own.
_STAGE = {**_JIT, "no_cpython_wrapper": True}

A0 = 5.73           # linear-theory lift slope [1/rad]: initial inflow, BEMT preconditioner
RAD2DEG = 180.0 / np.pi
TWO_OVER_PI = 2 / np.pi
MAX_BLADE_MOTION = 2.0 * np.pi
PITCH_STEP_DEG = 1e-3   # forward-difference step in alpha of the feathering stiffness [deg]
LIFT_SECANT_DEG = 2.0   # half-width of the secant giving the Jacobian's lift slope [deg]

# Columns of the per-sample input matrix
(OMEGA, RHO, KAPPA, K_FLAP, C_FLAP, K_LAG, C_LAG, K_FEATHER, C_FEATHER, X_AC, CM0, COLLECTIVE,
 LATERAL, LONGITUDINAL, MU, LAMBDA_S, INFLOW, TRIM, THRUST_TARGET, ROLL_TARGET, PITCH_TARGET,
 GROUND_DEFICIT, N_COLUMNS) = range(23)
# Forward flight (rotor.forward): advance ratio mu = V cos(alpha_s) / (Omega R), free-stream
# inflow ratio lambda_s = mu tan(alpha_s) (alpha_s positive tilting the disk forward), the
# inflow model (GLAUERT uniform, DREES linear), the trim (NO_TRIM; WIND_TUNNEL: collective
# and cyclic solved for THRUST_TARGET [N] and zero first-harmonic flapping; HUB_MOMENTS: for
# THRUST_TARGET and the hub moments ROLL_TARGET, PITCH_TARGET [N m]; GROUND_DEFICIT: the
# hover ground-effect model's 1 - v_IGE / v_OGE at the sample's height, which forward flight
# weights by the wake skew, :func:`_ground_skew`). mu = 0 without a trim takes the hover code
# paths unchanged.
GLAUERT, DREES = 0, 1
TRIM_PITCH_LIMIT_DEG = 90.0   # |collective| + |cyclic| a trim may reach [deg]
NO_TRIM, WIND_TUNNEL, HUB_MOMENTS = 0, 1, 2
# Columns of the loads written by _hub_loads
N_LOADS = 9

# Failure reasons of the iteration (the final check's reasons are judged in hover.py)
OK, NONFINITE, TOO_LARGE, NOT_CONVERGED, TRIM_PITCH, TRIM_SINGULAR = range(6)

# Airfoil kinds
TABLE, LINEAR = 0, 1


class Rotor(NamedTuple):
    """Rotor constants and the blade grid shared by every sample of a batch."""

    radius: float
    chord: float
    hinge_offset: float
    n_blades: int
    area: float
    speed_of_sound: float
    root_cutout: float
    pitch_inertia: float
    I_flap: float
    I_lag: float
    S_flap: float
    tan_delta3: float
    solidity: float
    twist_rad: float          # total twist [rad]
    bemt: bool
    harmonic_inflow: bool
    tip_loss: bool
    pitching_moment: bool
    r: np.ndarray             # (N_r,)
    w: np.ndarray
    rr: np.ndarray
    twist: np.ndarray
    w_rr: np.ndarray          # w * rr
    w_r: np.ndarray           # w * r
    cos_psi: np.ndarray       # (N_psi,)
    sin_psi: np.ndarray
    cos_k: np.ndarray         # (K, N_psi) cos(k psi)
    sin_k: np.ndarray
    analysis: np.ndarray      # (2K, N_psi) weights: Q_k = sum_j f_j (W[k, j] + i W[K + k, j])
    sums: np.ndarray          # grid integrals, see SUM_* below


# grid integrals sum_i w_i (...) in Rotor.sums
(SUM_W_R_RR2, SUM_W_R2_RR, SUM_W_R2, SUM_W_R_RR, SUM_W_R, SUM_W_R3, SUM_W_R_RR_R,
 N_SUMS) = range(8)


class Table(NamedTuple):
    """An airfoil in the kernel's form: a bilinear table over (alpha, Mach) with the fit-row
    polynomials of :class:`rotoruq.rotor.airfoil.Airfoil`, or a linear airfoil."""

    kind: int
    alpha: np.ndarray         # (n_a,) grid [deg]
    mach: np.ndarray          # (n_m,)
    values: np.ndarray        # (3, n_a * n_m) cl, cd, cm at grid nodes (row-major alpha, Mach)
    window: np.ndarray        # (n_a,) 1 inside the fit window |alpha| <= W, else 0
    half_width: float         # W [deg]
    has_fits: bool
    replace_cd: bool
    alpha_lut: np.ndarray     # uniform-bin lookup of the alpha interval (empty: bisection)
    alpha_next: np.ndarray
    alpha_inv_dx: np.ndarray
    alpha_x0: float
    alpha_inv_h: float
    alpha_nbins: int
    mach_inv_dx: np.ndarray
    stall_pos: np.ndarray     # (n_m,) stall angles [deg] per Mach row (empty: no stall test)
    stall_neg: np.ndarray
    cda2: float               # linear airfoil's drag curvature [1/deg^2]


# ---------------------------------------------------------------------------------------------
# small numerics


@numba.njit(**_STAGE)
def _psum(x, n):
    """sum of x[0:n] in numpy's pairwise order (np.add.reduce on a contiguous row)."""
    if n < 8:
        res = -0.0
        for i in range(n):
            res += x[i]
        return res
    if n <= 128:
        r0, r1, r2, r3 = x[0], x[1], x[2], x[3]
        r4, r5, r6, r7 = x[4], x[5], x[6], x[7]
        i = 8
        stop = n - (n % 8)
        while i < stop:
            r0 += x[i]
            r1 += x[i + 1]
            r2 += x[i + 2]
            r3 += x[i + 3]
            r4 += x[i + 4]
            r5 += x[i + 5]
            r6 += x[i + 6]
            r7 += x[i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += x[i]
            i += 1
        return res
    half = n // 2
    half -= half % 8
    return _psum(x, half) + _psum(x[half:], n - half)


@numba.njit(**_INLINE)
def _nanmax(a, b):
    """np.maximum: the larger of a and b, NaN if either is NaN."""
    if a != a or b != b:
        return np.nan
    return a if a >= b else b


@numba.njit(**_INLINE)
def _nanmin(a, b):
    """np.minimum: the smaller of a and b, NaN if either is NaN."""
    if a != a or b != b:
        return np.nan
    return a if a <= b else b


@numba.njit(**_STAGE)
def _lu_solve(A, b, x):
    """x with A x = b for a small complex or real A (Gaussian elimination, partial pivoting
    on |re| + |im| as LAPACK's zgetrf; |x| for a real A, as dgetrf), written to and returned
    as x. A and b are overwritten."""
    m = b.size
    for col in range(m):
        p = col
        best = abs(A[col, col].real) + abs(A[col, col].imag)
        for row in range(col + 1, m):
            v = abs(A[row, col].real) + abs(A[row, col].imag)
            if v > best:
                best, p = v, row
        if p != col:
            for k in range(m):
                A[col, k], A[p, k] = A[p, k], A[col, k]
            b[col], b[p] = b[p], b[col]
        piv = A[col, col]
        for row in range(col + 1, m):
            f = A[row, col] / piv
            A[row, col] = f
            for k in range(col + 1, m):
                A[row, k] -= f * A[col, k]
            b[row] -= f * b[col]
    for row in range(m - 1, -1, -1):
        s = b[row]
        for k in range(row + 1, m):
            s -= A[row, k] * x[k]
        x[row] = s / A[row, row]
    return x


@numba.njit(**_INLINE)
def _lerp(a, b, t):
    """a + (b - a) t: the table's linear interpolation, in this operation order."""
    return a + (b - a) * t


@numba.njit(**_JIT)
def _mach_intervals(mach, gm, inv_dx, im_out, s_out):
    """Interval index im_out and weight s_out (N_psi, N_r) of |Mach| in the table's Mach grid
    gm, clamped; kept for the coefficients, the stall test and the pitch-stiffness difference
    of a pass. Each station's search starts from the previous azimuth's interval (in hover a
    station's Mach number barely moves): the answer of a scan from 0 (NaN: interval 0)."""
    npsi, nr = mach.shape
    n = gm.size
    for i in range(nr):
        im = 0
        for j in range(npsi):
            x = abs(mach[j, i])
            if n == 1:
                im, s = 0, 0.0
            else:
                if x != x:
                    im = 0
                else:
                    while im > 0 and x < gm[im]:
                        im -= 1
                    while im < n - 2 and x >= gm[im + 1]:
                        im += 1
                s = min(max((x - gm[im]) * inv_dx[im], 0.0), 1.0)
            im_out[j, i] = im
            s_out[j, i] = s


@numba.njit(**_STAGE)
def _coefficients(alpha, im_, s_, af, fit, linear, cl, cd, cm):
    """cl, cd, cm (N_psi, N_r) at alpha [deg, wrapped] over the disk, at the Mach intervals
    (im_, s_) of :func:`_mach_intervals`; ``fit`` (5, n_m) the sample's fit-row coefficients,
    ``linear`` (3,) its (cla, cl0, cd0) for a linear airfoil. One call per pass: the table's
    arrays are bound once. The interval searches are written out in the loop: a helper
    taking the table's arrays costs reference-count updates per element."""
    npsi, nr = alpha.shape
    if af.kind == LINEAR:
        cla, cl0, cd0, cda2 = linear[0], linear[1], linear[2], af.cda2
        for j in range(npsi):
            for i in range(nr):
                a = alpha[j, i]
                # reverse flow (forward flight): the thin airfoil's lift is pi-periodic
                if a >= 90.0:
                    a = a - 180.0
                elif a < -90.0:
                    a = a + 180.0
                cl[j, i] = cla * a + cl0
                cd[j, i] = cd0 + cda2 * (a * a)
                cm[j, i] = 0.0
        return
    ga, values, window = af.alpha, af.values, af.window
    lut, nxt, inv_dx = af.alpha_lut, af.alpha_next, af.alpha_inv_dx
    x0, inv_h, nbins, hw = af.alpha_x0, af.alpha_inv_h, af.alpha_nbins, af.half_width
    has_fits, replace_cd = af.has_fits, af.replace_cd
    nm, na = af.mach.size, ga.size
    bisect = lut.size == 0
    for j in range(npsi):
        for i in range(nr):
            a = alpha[j, i]
            # alpha interval, clamped (c81.Bracket.locate): a uniform-bin lookup, else bisection
            if bisect:
                lo, hi = 0, na - 1
                while hi - lo > 1:
                    mid = (lo + hi) // 2
                    if ga[mid] <= a:
                        lo = mid
                    else:
                        hi = mid
                ia = lo
            else:
                b = min(max((a - x0) * inv_h, 0.0), float(nbins))
                ia = lut[int(b)]
                if a >= nxt[ia]:
                    ia += 1
            t = min(max((a - ga[ia]) * inv_dx[ia], 0.0), 1.0)
            im, s = im_[j, i], s_[j, i]
            # bilinear between the nodes idx, idx + 1 (Mach), idx + nm (alpha)
            idx = ia * nm + im
            k0, k1, k2, k3 = idx, idx + nm, idx + 1, idx + nm + 1
            out0 = _lerp(_lerp(values[0, k0], values[0, k1], t),
                         _lerp(values[0, k2], values[0, k3], t), s)
            out1 = _lerp(_lerp(values[1, k0], values[1, k1], t),
                         _lerp(values[1, k2], values[1, k3], t), s)
            out2 = _lerp(_lerp(values[2, k0], values[2, k1], t),
                         _lerp(values[2, k2], values[2, k3], t), s)
            if has_fits:
                h = _lerp(window[ia], window[ia + 1], t)
                ac = min(max(a, -hw), hw)
                cla = _lerp(fit[0, im], fit[0, im + 1], s)
                cl0 = _lerp(fit[1, im], fit[1, im + 1], s)
                out0 += (cla * ac + cl0) * h
                if replace_cd:
                    cda2 = _lerp(fit[2, im], fit[2, im + 1], s)
                    cda = _lerp(fit[3, im], fit[3, im + 1], s)
                    cd0 = _lerp(fit[4, im], fit[4, im + 1], s)
                    out1 += (((cda2 * ac + cda) * ac) + cd0) * h
            cl[j, i] = out0
            cd[j, i] = out1
            cm[j, i] = out2


@numba.njit(**_INLINE)
def _wrap_deg(a):
    if -180.0 <= a < 180.0:
        return a
    return (a + 180.0) % 360.0 - 180.0


@numba.njit(**_STAGE)
def _prandtl(r, v, omega, radius, root_cutout, n_blades):
    """Prandtl tip and root loss F(r, v) and dF/dv (inflow.prandtl_loss, one station).

    One signature for every caller (a literal flag argument would compile it twice): a
    caller that needs F only drops dF/dv."""
    av = abs(v)
    ratio = av / (omega * r)
    phi = max(ratio, 1e-6)
    limited = ratio <= 1e-6
    F = 1.0
    dlogF = 0.0
    for part in range(2):
        if part == 0:
            dist = radius - r
        else:
            if not root_cutout > 0:
                continue
            dist = r - root_cutout
        f = 0.5 * n_blades * dist / (r * phi)
        fc = min(f, 50.0)
        ex = math.exp(-fc)
        Fi = TWO_OVER_PI * math.acos(ex)
        dFi = 0.0 if fc >= 50.0 else TWO_OVER_PI * ex / math.sqrt(max(1.0 - ex * ex, 1e-300))
        F = F * Fi
        dlogF = dlogF + (0.0 if limited else dFi * (-f / max(av, 1e-300))) / max(Fi, 1e-3)
    Fc = max(F, 1e-3)
    sign = 1.0 if v > 0 else (-1.0 if v < 0 else 0.0)
    return Fc, (F * dlogF * sign if F > 1e-3 else 0.0)


@numba.njit(**_STAGE)
def _uniform_tip_loss(v0, omega, rot, scratch):
    """Area (r dr) mean of the Prandtl factor over the span for one v; 1 without tip loss."""
    if not rot.tip_loss:
        return 1.0
    r_, w_r, radius, root, nb = rot.r, rot.w_r, rot.radius, rot.root_cutout, rot.n_blades
    nr = r_.size
    for i in range(nr):
        scratch[i] = _prandtl(r_[i], v0, omega, radius, root, nb)[0] * w_r[i]
    return _psum(scratch, nr) / rot.sums[SUM_W_R]


# ---------------------------------------------------------------------------------------------
# stages


@numba.njit(**_STAGE)
def _lift_slope(prm, rot, af, fit, linear, alpha_ref, ws):
    """The sample's lift slope a_lift [1/rad] for the Jacobian: the secant of cl over
    alpha_ref +- LIFT_SECANT_DEG at each station's Mach number Omega r / a, averaged with the
    flap damping's weight w r (r - e)^2, bounded to [1/2, 2] x A0 (A0 if not finite)."""
    Om, nr = prm[OMEGA], rot.r.size
    alpha, mach = ws.shifted[:2], ws.mach[:2]
    m_lo, m_hi = af.mach[0], af.mach[-1]
    for i in range(nr):
        m = Om * rot.r[i] / rot.speed_of_sound
        if af.kind == TABLE:
            m = min(max(m, m_lo), m_hi)
        alpha[0, i] = _wrap_deg(alpha_ref - LIFT_SECANT_DEG)
        alpha[1, i] = _wrap_deg(alpha_ref + LIFT_SECANT_DEG)
        mach[0, i] = m
        mach[1, i] = m
    im, s = ws.im[:2], ws.s[:2]
    if af.kind == TABLE:
        _mach_intervals(mach, af.mach, af.mach_inv_dx, im, s)
    cl, cd, cm = ws.cl2[:2], ws.cd2[:2], ws.cm2[:2]
    _coefficients(alpha, im, s, af, fit, linear, cl, cd, cm)
    for i in range(nr):
        rr = rot.rr[i]
        ws.span_line[i] = (cl[1, i] - cl[0, i]) * (rot.w_r[i] * rr * rr)
    a = _psum(ws.span_line, nr) / rot.sums[SUM_W_R_RR2] * (RAD2DEG / (2 * LIFT_SECANT_DEG))
    if not np.isfinite(a):
        return A0
    return min(max(a, 0.5 * A0), 2.0 * A0)


@numba.njit(**_INLINE)
def _glauert(v, Vx, Vz):
    """Glauert's resultant velocity at the disk V' = sqrt(Vx^2 + (Vz + v)^2) [m/s] and
    dV'/dv for induced velocity v, in-plane free stream Vx and free-stream inflow Vz."""
    Vp = math.sqrt(Vx * Vx + (Vz + v) * (Vz + v))
    return Vp, ((Vz + v) / Vp if Vp > 0 else 1.0)


@numba.njit(**_INLINE)
def _ground_skew(v, Vx, g):
    """Ground effect in forward flight relative to hover's: the factor on KAPPA (which holds
    hover's v_IGE / v_OGE = 1 - g) and its derivative in v [s/m]. Cheeseman & Bennett's image
    source seen through the wake skewed back by tan(chi) = Vx / v: v_IGE / v_OGE =
    1 - g cos^2(chi) = 1 - g v^2 / (v^2 + Vx^2), hover's at Vx = 0, 1 as Vx / v grows."""
    if g == 0.0:
        return 1.0, 0.0
    d = v * v + Vx * Vx
    if d == 0.0:
        return 1.0, 0.0
    w = v * v / d
    return (1.0 - g * w) / (1.0 - g), -g * (2.0 * v * Vx * Vx / (d * d)) / (1.0 - g)


@numba.njit(**_INLINE)
def _drees(mu, lam):
    """Drees's linear inflow (kx, ky): v(r, psi) = v0 (1 + kx r/R cos psi + ky r/R sin psi),
    kx = 4/3 (1 - cos chi - 1.8 mu^2) / sin chi, ky = -2 mu, with the wake skew angle
    chi = atan(mu / lambda) from the advance ratio mu and the inflow ratio lambda (free stream
    and induced); kx -> 0 as chi -> 0."""
    chi = math.atan2(mu, lam)
    sc = math.sin(chi)
    kx = 4.0 / 3.0 * (1.0 - math.cos(chi) - 1.8 * mu * mu) / sc if sc > 1e-12 else 0.0
    return kx, -2.0 * mu


@numba.njit(**_STAGE)
def _trim_inflow(prm, rot):
    """The trim's initial induced velocity [m/s]: momentum (Glauert) at the target thrust,
    v V' = kappa^2 T / (2 rho A), by Newton steps from the hover value."""
    Om, R = prm[OMEGA], rot.radius
    c = prm[KAPPA] ** 2 * prm[THRUST_TARGET] / (2 * prm[RHO] * rot.area)
    v = math.sqrt(abs(c))
    Vx, Vz = prm[MU] * (Om * R), prm[LAMBDA_S] * (Om * R)
    for _ in range(20):
        Vp, dVp = _glauert(v, Vx, Vz)
        v = v - (v * Vp - c) / (Vp + v * dVp)
    return v if np.isfinite(v) and v > 0 else math.sqrt(abs(c))


@numba.njit(**_STAGE)
def _structural_jacobian(prm, rot, af, fit, linear, ws):
    """Structural operator Z (K, 3, 3), the inverse of the Jacobian J_k (K, 3, 3), the joint
    (mean motion, uniform inflow) and (first harmonic, harmonic inflow) 4x4 Jacobians J0, J1
    (their momentum rows completed per iteration), the commanded-pitch forcing F_cmd (3, K),
    the initial inflow v_init [m/s] and the blade-element thrust slope k_v [N s/m]."""
    K = rot.cos_k.shape[0]
    Om, rho, kappa = prm[OMEGA], prm[RHO], prm[KAPPA]
    K_b, C_b, K_l, C_l = prm[K_FLAP], prm[C_FLAP], prm[K_LAG], prm[C_LAG]
    K_p, C_p, x_ac = prm[K_FEATHER], prm[C_FEATHER], prm[X_AC]
    e, c, R = rot.hinge_offset, rot.chord, rot.radius
    sums = rot.sums
    I_b, I_l, I_p, S = rot.I_flap, rot.I_lag, rot.pitch_inertia, rot.S_flap
    Om2 = Om**2
    Z = np.zeros((K, 3, 3), dtype=np.complex128)
    for k in range(K):
        wk = Om * k
        Z[k, 0, 0] = K_b + Om2 * (I_b + e * S) - wk**2 * I_b + 1j * wk * C_b
        Z[k, 1, 1] = K_l + Om2 * e * S - wk**2 * I_l + 1j * wk * C_l
        Z[k, 2, 2] = K_p + Om2 * I_p - wk**2 * I_p + 1j * wk * C_p
        Z[k, 2, 0] = K_p * rot.tan_delta3
    # The mean lift's pitch derivative is reduced by the inflow's response to it (BEMT: by
    # m / (m + k_v), m = 4 rho A v / kappa^2, k_v = dT_BE/dv) at the linear-theory inflow.
    th75 = np.deg2rad(prm[COLLECTIVE]) + rot.twist_rad * (
        0.75 * R - rot.root_cutout) / (R - rot.root_cutout)
    sigma = rot.solidity
    lam = sigma * A0 / 16 * (np.sqrt(1 + 32 / (sigma * A0) * np.abs(th75) * 0.75) - 1)
    v_init = max(lam, 1e-3) * Om * R * np.sqrt(max(kappa, 0.1))
    m_mom = 4 * rho * rot.area * v_init / max(kappa, 0.1) ** 2
    # the aerodynamic terms with the airfoil's own lift slope at the linear-theory angle of
    # attack at 0.75 R: with linear theory's 2 pi-like A0 the iteration contracts only by
    # the slope's relative error per step (0.2 at the gvpm preset's nominal point)
    # (BEMT keeps A0: its annulus Newton steps take their own secant slopes, and the
    # mean-pitch term's inflow factor fb was tuned with it)
    a_lift = A0 if rot.bemt else _lift_slope(prm, rot, af, fit, linear,
                                             (th75 - np.sign(th75) * lam / 0.75) * RAD2DEG, ws)
    # aerodynamic flap damping, the flap moment's pitch derivative, lag damping, and the
    # feathering moment of the lift x_ac aft of the axis (linear theory)
    c_ab = 0.5 * rho * a_lift * c * Om * sums[SUM_W_R_RR2]
    k_abt = 0.5 * rho * a_lift * c * Om**2 * sums[SUM_W_R2_RR]
    c_lag_aero = 0.5 * rho * c * Om * 0.02 * sums[SUM_W_R_RR2]
    q_tt = 0.5 * rho * c * a_lift * Om**2 * sums[SUM_W_R2]
    q_tb = 0.5 * rho * c * a_lift * Om**2 * sums[SUM_W_R_RR]
    k_v = rot.n_blades * 0.5 * rho * c * a_lift * Om * sums[SUM_W_R]
    J = Z.copy()
    Jinv = np.empty((K, 3, 3), dtype=np.complex128)
    for k in range(K):
        wk = Om * k
        J[k, 0, 0] += 1j * wk * c_ab
        J[k, 0, 2] -= k_abt
        J[k, 1, 1] += 1j * wk * c_lag_aero
        fb = m_mom / (m_mom + k_v) if (rot.bemt and k == 0) else 1.0
        J[k, 2, 2] += x_ac * q_tt * fb
        J[k, 2, 0] -= 1j * k * (x_ac * q_tb)
        for col in range(3):
            unit = np.zeros(3, dtype=np.complex128)
            unit[col] = 1.0
            x = _lu_solve(J[k].copy(), unit, np.empty(3, dtype=np.complex128))
            for d in range(3):
                Jinv[k, d, col] = x[d]
    qa = 0.5 * rho * c * a_lift * Om
    theta_cmd = np.zeros(K, dtype=np.complex128)
    theta_cmd[0] = np.deg2rad(prm[COLLECTIVE])
    if K > 1:
        theta_cmd[1] = np.deg2rad(prm[LATERAL]) - 1j * np.deg2rad(prm[LONGITUDINAL])
    F_cmd = np.zeros((3, K), dtype=np.complex128)
    for k in range(K):
        F_cmd[2, k] = (K_p + 1j * (Om * k) * C_p) * theta_cmd[k]
    J0 = np.zeros((4, 4), dtype=np.complex128)
    for a in range(3):
        for b in range(3):
            J0[a, b] = J[0, a, b]
    J0[0, 3] = 0.5 * rho * c * a_lift * Om * sums[SUM_W_R_RR]
    J0[2, 3] = -x_ac * 0.5 * rho * c * a_lift * Om * sums[SUM_W_R]
    J0[3, 2] = -rot.n_blades * 0.5 * rho * c * a_lift * Om**2 * sums[SUM_W_R2]
    J1 = np.zeros((4, 4), dtype=np.complex128)
    if K > 1:
        for a in range(3):
            for b in range(3):
                J1[a, b] = J[1, a, b]
    J1[0, 3] = qa * sums[SUM_W_R_RR_R] / R
    return Z, Jinv, J0, J1, F_cmd, v_init, k_v, qa, J, a_lift


@numba.njit(**_STAGE)
def _aerodynamic_loads(Q, v0, vc, vs, v_r, prm, rot, af, fit, linear, ws, flight):
    """Section loads over the disk (N_psi, N_r) at the state: ws.dFz, ws.dFx, ws.dMp, with
    the flow (alpha, mach) and coefficients kept for the final check. Returns True when the
    section flow is not finite somewhere (the loads there are taken at a neutral flow)."""
    Om, rho = prm[OMEGA], prm[RHO]
    R, c, a_sound = rot.radius, rot.chord, rot.speed_of_sound
    x_ac, cm0 = prm[X_AC], prm[CM0]
    r_, rr_, twist_ = rot.r, rot.rr, rot.twist
    cos_psi, sin_psi, cos_k, sin_k = rot.cos_psi, rot.sin_psi, rot.cos_k, rot.sin_k
    bemt, table, pitching_moment = rot.bemt, af.kind == TABLE, rot.pitching_moment
    m_lo, m_hi = af.mach[0], af.mach[-1]
    alpha_, mach_, qc_, cphi_, sphi_ = ws.alpha, ws.mach, ws.qc, ws.cphi, ws.sphi
    npsi, nr = cos_psi.size, r_.size
    K = Q.shape[1]
    bad = False
    # forward flight: in-plane free stream mu Omega R (tangential mu sin psi, radial mu cos
    # psi: its flap-normal part mu beta cos psi is kept, the radial flow along the blade
    # neglected) and the free-stream inflow lambda_s Omega R through the disk
    Vx, Vz = prm[MU] * (Om * R), prm[LAMBDA_S] * (Om * R)
    forward = flight is not None and Vx != 0.0
    for j in range(npsi):
        # flap beta and its psi-derivative, lag rate, feathering at psi_j: q_d(psi_j) =
        # Re(sum_k Q[d, k] exp(i k psi_j)) (written out: see _coefficients)
        beta = Q[0, 0].real * cos_k[0, j]
        theta = Q[2, 0].real * cos_k[0, j]
        dbeta = dzeta = 0.0
        for k in range(1, K):
            ck, sk = cos_k[k, j], sin_k[k, j]
            re, im = Q[0, k].real, Q[0, k].imag
            beta = beta + (re * ck - im * sk)
            dbeta = dbeta - k * (re * sk + im * ck)
            re, im = Q[1, k].real, Q[1, k].imag
            dzeta = dzeta - k * (re * sk + im * ck)
            re, im = Q[2, k].real, Q[2, k].imag
            theta = theta + (re * ck - im * sk)
        ws.beta[j] = beta
        cs = vc * cos_psi[j] + vs * sin_psi[j]
        for i in range(nr):
            r, rr = r_[i], rr_[i]
            base = v_r[i] if bemt else v0
            UT = Om * (r - rr * dzeta)
            UP = (base + (r / R) * cs) + (Om * rr) * dbeta
            if forward:
                UT = UT + Vx * sin_psi[j]
                UP = UP + (Vz + Vx * beta * cos_psi[j])
            phi = math.atan2(UP, UT)
            alpha = (theta + twist_[i] - phi) * RAD2DEG
            U2 = UT**2 + UP**2
            U = math.sqrt(U2)
            # cos(phi), sin(phi) without the trigonometric calls (equal to a few ulp)
            if U > 0:
                cphi_[j, i], sphi_[j, i] = UT / U, UP / U
            else:
                cphi_[j, i], sphi_[j, i] = math.cos(phi), math.sin(phi)
            mach = U / a_sound
            if not (np.isfinite(alpha) and np.isfinite(U2)):
                bad = True
                alpha, mach, U2 = 0.0, 0.0, 0.0
            if table:
                mach = min(max(mach, m_lo), m_hi)
            alpha_[j, i] = _wrap_deg(alpha)
            mach_[j, i] = mach
            qc_[j, i] = 0.5 * rho * U2 * c
    if table:
        _mach_intervals(mach_, af.mach, af.mach_inv_dx, ws.im, ws.s)
    _coefficients(alpha_, ws.im, ws.s, af, fit, linear, ws.cl, ws.cd, ws.cm)
    cl_, cd_, cm_ = ws.cl, ws.cd, ws.cm
    dFz, dFx, dMp = ws.dFz, ws.dFx, ws.dMp
    for j in range(npsi):
        for i in range(nr):
            cl, cd, qc = cl_[j, i], cd_[j, i], qc_[j, i]
            cphi, sphi = cphi_[j, i], sphi_[j, i]
            dFz[j, i] = qc * (cl * cphi - cd * sphi)
            dFx[j, i] = qc * (cl * sphi + cd * cphi)
            cm_sec = (cm_[j, i] if pitching_moment else 0.0) + cm0
            dMp[j, i] = qc * (c * cm_sec - x_ac * cl)
    return bad


@numba.njit(**_STAGE)
def _analyse(f, rot, out, scratch):
    """Harmonics out[k] (k = 0..K-1) of f over azimuth, one pairwise sum per weight row."""
    K, npsi = rot.cos_k.shape
    W = rot.analysis
    for k in range(K):
        for j in range(npsi):
            scratch[j] = f[j] * W[k, j]
        re = _psum(scratch, npsi)
        for j in range(npsi):
            scratch[j] = f[j] * W[K + k, j]
        out[k] = re + 1j * _psum(scratch, npsi)


@numba.njit(**_STAGE)
def _span_sum(field, weight, out, scratch):
    """out[j] = sum_i field[j, i] weight[i] (per azimuth, pairwise over the span)."""
    npsi, nr = field.shape
    for j in range(npsi):
        for i in range(nr):
            scratch[i] = field[j, i] * weight[i]
        out[j] = _psum(scratch, nr)


@numba.njit(**_STAGE)
def _blade_root_loads(Q, Z, F_cmd, rot, ws):
    """Structural residual R_dyn (3, K) = F(aero) + F_cmd - Z Q and the first harmonic of the
    blade-root thrust moment Mz1 (for the harmonic inflow)."""
    K = Q.shape[1]
    R_dyn, harm = ws.R_dyn, ws.harm
    for d in range(3):
        if d == 0:
            _span_sum(ws.dFz, rot.w_rr, ws.psi_line, ws.span_line)
        elif d == 1:
            _span_sum(ws.dFx, rot.w_rr, ws.psi_line, ws.span_line)
        else:
            _span_sum(ws.dMp, rot.w, ws.psi_line, ws.span_line)
        _analyse(ws.psi_line, rot, harm, ws.psi_scratch)
        for k in range(K):
            zq = Z[k, d, 0] * Q[0, k]
            zq = zq + Z[k, d, 1] * Q[1, k]
            zq = zq + Z[k, d, 2] * Q[2, k]
            R_dyn[d, k] = (harm[k] + F_cmd[d, k]) - zq
    Mz1 = 0.0 + 0.0j
    if rot.harmonic_inflow and K > 1:
        _span_sum(ws.dFz, rot.w_r, ws.psi_line, ws.span_line)
        _analyse(ws.psi_line, rot, harm, ws.psi_scratch)
        Mz1 = harm[1]
    return R_dyn, Mz1


@numba.njit(**_STAGE)
def _blade_thrust(rot, ws, out):
    """Per-station thrust per unit span, azimuth mean over N_b blades (N_r,) [N/m]."""
    npsi, nr = ws.dFz.shape
    dFz, scratch, cos_beta = ws.dFz, ws.psi_scratch, ws.psi_line
    for j in range(npsi):
        cos_beta[j] = math.cos(ws.beta[j])
    for i in range(nr):
        for j in range(npsi):
            scratch[j] = dFz[j, i] * cos_beta[j]
        out[i] = rot.n_blades * _psum(scratch, npsi) / npsi


@numba.njit(**_STAGE)
def _harmonic_gain(v0, prm, rot):
    Om, R = prm[OMEGA], rot.radius
    lam0 = max(abs(v0) / (Om * R), 1e-4)
    return 0.5 * rot.n_blades * prm[KAPPA] / (prm[RHO] * rot.area * Om * R**2 * lam0)


@numba.njit(**_STAGE)
def _inflow_update(st, dT_r, prm, rot, ws):
    """BEMT: a damped Newton step per annulus on dT_BE(r) = 4 pi rho F r v|v| / kappa^2 with
    the blade-element slope from the secant of the last two iterates (bounded by 1/4..4 x
    linear theory). Updates st.v_r, v_prev, dT_prev, v0 and returns the largest step of the
    inflow ratio."""
    Om, rho, kappa = prm[OMEGA], prm[RHO], prm[KAPPA]
    R, Nb, c = rot.radius, rot.n_blades, rot.chord
    relax = st.scalars[RELAX]
    nr = rot.r.size
    dv = 0.0
    for i in range(nr):
        r = rot.r[i]
        v = st.v_r[i]
        if rot.tip_loss:
            F, dF = _prandtl(r, v, Om, R, rot.root_cutout, Nb)
        else:
            F, dF = 1.0, 0.0
        lin = -Nb * 0.5 * rho * c * A0 * Om * r
        dv_prev = v - st.v_prev[i]
        if abs(dv_prev) > 1e-12 * (Om * R):
            sec = (dT_r[i] - st.dT_prev[i]) / dv_prev
            slope = _nanmin(_nanmax(sec, 4.0 * lin), 0.25 * lin)
        else:
            slope = lin
        f = dT_r[i] - 4 * np.pi * rho * F * r * v * abs(v) / kappa**2
        df = slope - 4 * np.pi * rho * r * (2 * F * abs(v) + dF * v * abs(v)) / kappa**2
        v_new = v - f / df
        st.v_prev[i] = v
        st.dT_prev[i] = dT_r[i]
        v_new = v + relax * (v_new - v)
        dv = _nanmax(dv, abs(v_new - v))
        st.v_r[i] = v_new
        ws.span_line[i] = v_new * rot.w_r[i]
    st.scalars[V0] = _psum(ws.span_line, nr) / rot.sums[SUM_W_R]
    return dv / (Om * R)


# indices of the scalar state
V0, VC, VS, RELAX, RESID, N_SCALARS = range(6)


class State(NamedTuple):
    Q: np.ndarray             # (3, K) complex
    scalars: np.ndarray       # v0, vc, vs, relax, resid
    v_r: np.ndarray           # (N_r,) BEMT annulus inflow
    v_prev: np.ndarray
    dT_prev: np.ndarray


class Work(NamedTuple):
    beta: np.ndarray          # (N_psi,)
    dFz: np.ndarray           # (N_psi, N_r)
    dFx: np.ndarray
    dMp: np.ndarray
    alpha: np.ndarray
    mach: np.ndarray
    cl: np.ndarray
    cd: np.ndarray
    cm: np.ndarray
    qc: np.ndarray
    cphi: np.ndarray
    sphi: np.ndarray
    shifted: np.ndarray       # alpha + the forward-difference step, its cl, cd, cm
    cl2: np.ndarray
    cd2: np.ndarray
    cm2: np.ndarray
    psi_line: np.ndarray      # (N_psi,)
    psi_scratch: np.ndarray
    span_line: np.ndarray     # (N_r,)
    span_scratch: np.ndarray
    dT_r: np.ndarray
    dQ: np.ndarray            # (3, K) complex: the motion step
    R_dyn: np.ndarray         # (3, K) complex: the structural residual
    harm: np.ndarray          # (K,) complex
    A: np.ndarray             # (4, 4) complex: a joint Jacobian, its LU factors
    rhs: np.ndarray           # (4,) complex
    x: np.ndarray             # (4,) complex: the joint step
    im: np.ndarray            # (N_psi, N_r) int: Mach interval of each element (table)
    s: np.ndarray             # (N_psi, N_r): its weight


@numba.njit(**_INLINE)
def _real_index(d, k, part, K):
    """Row (and column) of the real part (part 0) or imaginary part (1) of harmonic k of
    DOF d (0 flap, 2 feathering) in the coupled system: the mean, then (re, im) per
    harmonic, flap then feathering (the lag is uncoupled: stepped on its own)."""
    return (0 if d == 0 else 2 * K - 1) + (0 if k == 0 else 2 * k - 1 + part)


@numba.njit(**_STAGE)
def _coupled_jacobian(prm, rot, J, J0, k_v, a_lift, n_trim, ws):
    """The Jacobian (real, n x n) of the forward-flight harmonic balance: the flap and
    feathering harmonics (mean; real and imaginary parts of k = 1..K-1), the uniform
    inflow v0 and, trimmed, the controls (collective, lateral, longitudinal [rad]) with the
    trim's three equations (thrust; first-harmonic flapping or hub roll and pitch moments).

    The hover blocks J_k, J0 (per harmonic, complex) in real form, plus the couplings of
    forward flight from linear theory on the grid: a section's lift
    C (U_T^2 theta - U_T U_P), C = rho c a_lift / 2, with U_T = Omega r + V_x sin psi and
    U_P = v + Omega (r - e) beta' + V_x beta cos psi, so the flap moment, thrust, hub shear
    and feathering moment (x_ac) of every motion harmonic reach every harmonic (the hover
    Jacobian has only the diagonal in k). Exact for a linear airfoil at small angles; the
    momentum row's inflow slope is completed per iteration. The lag has no aerodynamic
    coupling here nor a structural one in J_k: it stays out. Returns the matrix; the
    momentum row is nQ = 2 (2K - 1), the trim rows and control columns nQ + 1..nQ + 3."""
    K = rot.cos_k.shape[0]
    nH = 2 * K - 1
    nQ = 2 * nH
    n = nQ + 1 + n_trim
    Om, R, Nb = prm[OMEGA], rot.radius, rot.n_blades
    Vx = prm[MU] * (Om * R)
    C = 0.5 * prm[RHO] * rot.chord * a_lift
    x_ac = prm[X_AC]
    e = rot.hinge_offset
    npsi, nr = rot.cos_psi.size, rot.r.size
    M = np.zeros((n, n))
    for k in range(K):
        for d in range(0, 3, 2):
            for f in range(0, 3, 2):
                z = J[k, d, f]
                r0, c0 = _real_index(d, k, 0, K), _real_index(f, k, 0, K)
                M[r0, c0] = z.real
                if k > 0:
                    M[r0, c0 + 1] = -z.imag
                    M[r0 + 1, c0] = z.imag
                    M[r0 + 1, c0 + 1] = z.real
    M[0, nQ] = J0[0, 3].real
    M[nH, nQ] = J0[2, 3].real
    # span integrals sum_i omega_i (r^2, r, 1, r (r - e), r - e) for the flap-moment weight
    # omega = w (r - e) (row 0) and the shear weight omega = w (row 1)
    S = np.zeros((2, 5))
    for i in range(nr):
        r, rr = rot.r[i], rot.rr[i]
        for row in range(2):
            wt = rot.w[i] * (rr if row == 0 else 1.0)
            S[row, 0] += wt * r * r
            S[row, 1] += wt * r
            S[row, 2] += wt
            S[row, 3] += wt * r * rr
            S[row, 4] += wt * rr
    flap_line, shear_line = np.empty(npsi), np.empty(npsi)
    full_line = np.empty(npsi)
    harm = np.empty(K, dtype=np.complex128)
    scratch = np.empty(npsi)
    dT = np.zeros(n)
    dFz1 = np.zeros(n, dtype=np.complex128)   # d(first harmonic of the hub shear)/dx
    for col in range(nQ + 1):
        d, rem = 2 * (col // nH), col % nH    # (col == nQ: the inflow)
        k, part = (0, 0) if rem == 0 else ((rem + 1) // 2, (rem + 1) % 2)
        for j in range(npsi):
            s, c = rot.sin_psi[j], rot.cos_psi[j]
            if col == nQ:
                q, dq = 1.0, 0.0
            elif part == 0:
                q, dq = rot.cos_k[k, j], -k * rot.sin_k[k, j]
            else:
                q, dq = -rot.sin_k[k, j], -k * rot.cos_k[k, j]
            for row in range(2):
                Sr2, Sr, S1, Srr_r, Srr = S[row, 0], S[row, 1], S[row, 2], S[row, 3], S[row, 4]
                if col == nQ:       # uniform inflow
                    hover = -C * Om * Sr
                    full = -C * (Om * Sr + Vx * s * S1)
                elif d == 2:        # feathering
                    hover = C * q * (Om * Om * Sr2)
                    full = C * q * (Om * Om * Sr2 + 2 * Om * Vx * s * Sr + Vx * Vx * s * s * S1)
                else:               # flap
                    hover = -C * dq * (Om * Om * Srr_r)
                    full = -C * (dq * Om * (Om * Srr_r + Vx * s * Srr)
                                 + q * Vx * c * (Om * Sr + Vx * s * S1))
                if row == 0:
                    flap_line[j] = full - hover
                else:
                    shear_line[j] = full - hover
                    full_line[j] = full
        # flap rows: A = -d(aerodynamic flap moment)/dx; feathering rows: the lift x_ac aft
        # of the axis, -x_ac x shear
        _analyse(flap_line, rot, harm, scratch)
        for kk in range(K):
            r0 = _real_index(0, kk, 0, K)
            M[r0, col] -= harm[kk].real
            if kk > 0:
                M[r0 + 1, col] -= harm[kk].imag
        if x_ac != 0:
            _analyse(shear_line, rot, harm, scratch)
            for kk in range(K):
                r0 = _real_index(2, kk, 0, K)
                M[r0, col] += x_ac * harm[kk].real
                if kk > 0:
                    M[r0 + 1, col] += x_ac * harm[kk].imag
        _analyse(full_line, rot, harm, scratch)
        dT[col] = Nb * harm[0].real
        if K > 1:
            dFz1[col] = harm[1]
    # the hover thrust derivatives are J0's (the same linear theory): keep its numbers
    dT[_real_index(2, 0, 0, K)] = -J0[3, 2].real
    dT[nQ] = -k_v
    for col in range(nQ + 1):
        M[nQ, col] = -dT[col]
    if n_trim:
        K_p, C_p = prm[K_FEATHER], prm[C_FEATHER]
        p0 = _real_index(2, 0, 0, K)
        p1 = _real_index(2, 1, 0, K)
        # commanded pitch through the pitch link: F = (K_p + i Omega C_p)(theta_1c - i theta_1s)
        M[p0, nQ + 1] = -K_p
        M[p1, nQ + 2] = -K_p
        M[p1, nQ + 3] = -Om * C_p
        M[p1 + 1, nQ + 2] = -Om * C_p
        M[p1 + 1, nQ + 3] = K_p
        for col in range(nQ + 1):
            M[nQ + 1, col] = dT[col]
        b1 = _real_index(0, 1, 0, K)
        if prm[TRIM] == WIND_TUNNEL:
            M[nQ + 2, b1] = 1.0
            M[nQ + 3, b1 + 1] = 1.0
        else:
            # hub moments N_b / 2 x the first harmonic of the root moment
            # M_1 = (K_b + i Omega C_b + e S Omega^2) B_1 + e F_z1
            g = prm[K_FLAP] + 1j * Om * prm[C_FLAP] + e * rot.S_flap * Om * Om
            for col in range(nQ + 1):
                dm = e * dFz1[col]
                if col == b1:
                    dm += g
                elif col == b1 + 1:
                    dm += 1j * g
                M[nQ + 2, col] = 0.5 * Nb * dm.imag
                M[nQ + 3, col] = -0.5 * Nb * dm.real
    return M


@numba.njit(**_STAGE)
def _coupled_step(st, prm, rot, Jinv, F_cmd, R_dyn, M, A, b, x, ws, hist):
    """The motion, inflow and (trimmed) control step of forward flight with the coupled
    Jacobian M of :func:`_coupled_jacobian`, updated in place by Broyden's rank-one step
    from the last residual and step kept in ``hist`` (3, n + 1): row 0 the last right-hand
    side and (at n) the last relaxation (0: no step yet), row 1 the last step, row 2 the
    column weights. Returns the largest motion step [rad], inflow step [-] and control step
    [rad] (relaxed)."""
    Om, rho, kappa = prm[OMEGA], prm[RHO], prm[KAPPA]
    R, Nb = rot.radius, rot.n_blades
    K = st.Q.shape[1]
    Q, sc = st.Q, st.scalars
    relax = sc[RELAX]
    nQ = 2 * (2 * K - 1)
    n = M.shape[0]
    for i in range(n):
        for j in range(n):
            A[i, j] = M[i, j]
    for d in range(0, 3, 2):
        for k in range(K):
            r0 = _real_index(d, k, 0, K)
            b[r0] = R_dyn[d, k].real
            if k > 0:
                b[r0 + 1] = R_dyn[d, k].imag
    _blade_thrust(rot, ws, ws.dT_r)
    for i in range(rot.r.size):
        ws.span_line[i] = ws.dT_r[i] * rot.w[i]
    T_be = _psum(ws.span_line, rot.r.size)
    v = sc[V0]
    F = _uniform_tip_loss(v, Om, rot, ws.span_scratch)
    mom = 2 * rho * rot.area * F / kappa**2
    Vx = prm[MU] * (Om * R)
    Vp, dVp = _glauert(v, Vx, prm[LAMBDA_S] * (Om * R))
    gs, dgs = _ground_skew(v, Vx, prm[GROUND_DEFICIT])
    # T = mom v V' / gs^2 (gs = 1 out of ground effect)
    A[nQ, nQ] += mom * ((Vp + v * dVp) - 2.0 * v * Vp * dgs / gs) / (gs * gs)
    b[nQ] = T_be - mom * v * Vp / (gs * gs)
    if n > nQ + 1:
        b[nQ + 1] = prm[THRUST_TARGET] - T_be
        if prm[TRIM] == WIND_TUNNEL:
            b[nQ + 2] = -Q[0, 1].real
            b[nQ + 3] = -Q[0, 1].imag
        else:
            _span_sum(ws.dFz, rot.w, ws.psi_line, ws.span_line)
            _analyse(ws.psi_line, rot, ws.harm, ws.psi_scratch)
            M1 = (prm[K_FLAP] + 1j * Om * prm[C_FLAP]) * Q[0, 1] + rot.hinge_offset * (
                ws.harm[1] + rot.S_flap * Om * Om * Q[0, 1])
            b[nQ + 2] = prm[ROLL_TARGET] - 0.5 * Nb * M1.imag
            b[nQ + 3] = prm[PITCH_TARGET] + 0.5 * Nb * M1.real
    if hist[0, n] != 0.0:
        # Broyden's (good) rank-one update of the linear-theory part M from the last step
        # s = relax x_prev: the secant condition A_new s = b_prev - b, where A_prev s =
        # relax b_prev, corrects M by ((1 - relax) b_prev - b) (W s)^T / (s^T W s) (W
        # weights the inflow column by 1 / (Omega R)^2: every unknown as a ratio)
        ss = 0.0
        for j in range(n):
            ss += hist[1, j] * hist[1, j] * (hist[2, j])
        if ss > 0.0:
            for i in range(n):
                y = ((1.0 - hist[0, n]) * hist[0, i] - b[i]) / ss
                for j in range(n):
                    corr = y * (hist[1, j] * hist[2, j])
                    M[i, j] += corr
                    A[i, j] += corr
    for i in range(n):
        hist[0, i] = b[i]
    _lu_solve(A, b, x)
    for i in range(n):
        hist[1, i] = relax * x[i]
    hist[0, n] = relax
    big = 0.0
    for d in range(3):
        for k in range(K):
            if d == 1:
                y = Jinv[k, 1, 0] * R_dyn[0, k]
                y = y + Jinv[k, 1, 1] * R_dyn[1, k]
                dq = relax * (y + Jinv[k, 1, 2] * R_dyn[2, k])
            else:
                r0 = _real_index(d, k, 0, K)
                dq = relax * (x[r0] + 1j * x[r0 + 1]) if k > 0 else relax * x[r0] + 0j
            Q[d, k] = Q[d, k] + dq
            big = _nanmax(big, abs(dq))
    sc[V0] = sc[V0] + relax * x[nQ]
    dv = abs(relax * x[nQ]) / (Om * R)
    d_ctrl = 0.0
    if n > nQ + 1:
        K_p, C_p = prm[K_FEATHER], prm[C_FEATHER]
        th0 = np.deg2rad(prm[COLLECTIVE]) + relax * x[nQ + 1]
        c1 = np.deg2rad(prm[LATERAL]) + relax * x[nQ + 2]
        c2 = np.deg2rad(prm[LONGITUDINAL]) + relax * x[nQ + 3]
        prm[COLLECTIVE] = th0 * RAD2DEG
        prm[LATERAL] = c1 * RAD2DEG
        prm[LONGITUDINAL] = c2 * RAD2DEG
        F_cmd[2, 0] = K_p * th0
        F_cmd[2, 1] = (K_p + 1j * Om * C_p) * (c1 - 1j * c2)
        for i in range(3):
            d_ctrl = _nanmax(d_ctrl, abs(relax * x[nQ + 1 + i]))
    return big, dv, d_ctrl


@numba.njit(**_STAGE)
def _step(st, prm, rot, af, fit, linear, Z, Jinv, J0, J1, F_cmd, k_v, qa, ws, M, A, b, x,
          flight, hist):
    """One iteration of a sample: returns (step size, flow not finite). A non-empty M (forward
    flight or a trim) takes the coupled step of :func:`_coupled_step`."""
    Om, R = prm[OMEGA], rot.radius
    sc = st.scalars
    relax = sc[RELAX]
    bad = _aerodynamic_loads(st.Q, sc[V0], sc[VC], sc[VS], st.v_r, prm, rot, af, fit,
                             linear, ws, flight)
    R_dyn, Mz1 = _blade_root_loads(st.Q, Z, F_cmd, rot, ws)
    dv1 = 0.0
    if flight is not None and M.shape[0]:
        big, dv, d_ctrl = _coupled_step(st, prm, rot, Jinv, F_cmd, R_dyn, M, A, b, x, ws,
                                        hist)
        if prm[INFLOW] == DREES and prm[MU] != 0.0:
            kx, ky = _drees(prm[MU], prm[LAMBDA_S] + sc[V0] / (Om * R))
            vc, vs = kx * sc[V0], ky * sc[V0]
            dv1 = max(abs(vc - sc[VC]), abs(vs - sc[VS])) / (Om * R)
            sc[VC], sc[VS] = vc, vs
        size = _nanmax(_nanmax(big, _nanmax(dv, dv1)), d_ctrl) / relax
    else:
        size = _hover_step(st, prm, rot, Jinv, J0, J1, k_v, qa, ws, R_dyn, Mz1)
    # per-sample step control: halve the step of a sample whose update grew (stall and strong
    # aerodynamic pitching moments make the fixed point oscillate), regrow it when it shrinks
    if size > sc[RESID]:
        sc[RELAX] = max(0.5 * relax, 0.05)
    else:
        sc[RELAX] = min(1.5 * relax, 1.0)
    sc[RESID] = size
    return size, bad


@numba.njit(**_STAGE)
def _hover_step(st, prm, rot, Jinv, J0, J1, k_v, qa, ws, R_dyn, Mz1):
    """The motion and inflow step of hover (block diagonal in the harmonics); returns the
    step size before relaxation."""
    Om, rho, kappa = prm[OMEGA], prm[RHO], prm[KAPPA]
    R = rot.radius
    K = st.Q.shape[1]
    sc = st.scalars
    relax = sc[RELAX]
    dQ = ws.dQ
    for k in range(K):
        for d in range(3):
            y = Jinv[k, d, 0] * R_dyn[0, k]
            y = y + Jinv[k, d, 1] * R_dyn[1, k]
            dQ[d, k] = y + Jinv[k, d, 2] * R_dyn[2, k]
    dv1 = 0.0
    if rot.harmonic_inflow and K > 1:
        # first harmonic: blade motion and the Pitt-Peters inflow V1 = v_c - i v_s together
        s = rot.sums
        dMz_dV = -qa * s[SUM_W_R3] / R
        dMz_dB = -1j * qa * Om * s[SUM_W_R2_RR]
        dMz_dT = qa * Om * s[SUM_W_R3]
        G = _harmonic_gain(sc[V0], prm, rot)
        V1 = sc[VC] - 1j * sc[VS]
        rhs, A = ws.rhs, ws.A
        for d in range(3):
            rhs[d] = R_dyn[d, 1]
        rhs[3] = G * Mz1 - V1
        for a in range(4):
            for b in range(4):
                A[a, b] = J1[a, b]
        A[3, 0] = -G * dMz_dB
        A[3, 2] = -G * dMz_dT
        A[3, 3] = 1.0 - G * dMz_dV
        d1 = _lu_solve(A, rhs, ws.x)
        for d in range(3):
            dQ[d, 1] = d1[d]
        V1 = V1 + relax * d1[3]
        sc[VC], sc[VS] = V1.real, -V1.imag
        dv1 = abs(d1[3]) / (Om * R)
    _blade_thrust(rot, ws, ws.dT_r)
    dv_step = 0.0
    if not rot.bemt:
        # mean blade motion and the uniform inflow together (a soft feathering restraint
        # couples the blade pitch to the lift, and the lift to the inflow)
        v = sc[V0]
        F = _uniform_tip_loss(v, Om, rot, ws.span_scratch)
        mom = 2 * rho * rot.area * F / kappa**2
        rhs, A = ws.rhs, ws.A
        for a in range(4):
            for b in range(4):
                A[a, b] = J0[a, b]
        for d in range(3):
            rhs[d] = R_dyn[d, 0]
        for i in range(rot.r.size):
            ws.span_line[i] = ws.dT_r[i] * rot.w[i]
        T_be = _psum(ws.span_line, rot.r.size)
        A[3, 3] = k_v + 2 * mom * abs(v)
        rhs[3] = T_be - mom * v * abs(v)
        d0 = _lu_solve(A, rhs, ws.x)
        for d in range(3):
            dQ[d, 0] = d0[d]
        dv_step = d0[3].real
    big = 0.0
    for d in range(3):
        for k in range(K):
            dQ[d, k] = dQ[d, k] * relax
            st.Q[d, k] = st.Q[d, k] + dQ[d, k]
            big = _nanmax(big, abs(dQ[d, k]))
    if rot.bemt:
        dv = _inflow_update(st, ws.dT_r, prm, rot, ws)
    else:
        sc[V0] = sc[V0] + relax * dv_step
        dv = abs(relax * dv_step) / (Om * R)
    return _nanmax(big, _nanmax(dv, dv1)) / relax


@numba.njit(**_STAGE)
def _hub_loads(st, prm, rot, af, fit, linear, Z, F_cmd, ws, out, flight):
    """Loads and the equation residual re-evaluated at the final state. Writes out[:] =
    thrust [N], torque [N m], equation residual [-], stalled fraction [-], min cd [-], static
    feathering stiffness [N m/rad], flow not finite (1.0) and returns the blade-root flap
    moment harmonics about the hub centre (K,) [N m]."""
    Om, rho, kappa = prm[OMEGA], prm[RHO], prm[KAPPA]
    R, Nb = rot.radius, rot.n_blades
    K = st.Q.shape[1]
    sc = st.scalars
    npsi, nr = rot.cos_psi.size, rot.r.size
    Vx, Vz = prm[MU] * (Om * R), prm[LAMBDA_S] * (Om * R)
    forward = flight is not None and Vx != 0.0
    bad = _aerodynamic_loads(st.Q, sc[V0], sc[VC], sc[VS], st.v_r, prm, rot, af, fit,
                             linear, ws, flight)
    R_dyn, Mz1 = _blade_root_loads(st.Q, Z, F_cmd, rot, ws)
    e_dyn = 0.0
    for d in range(3):
        worst = 0.0
        for k in range(K):
            a = abs(R_dyn[d, k])
            worst = a if (a > worst or a != a) else worst
        e = worst / abs(Z[0, d, d])
        e_dyn = e if (e > e_dyn or e != e) else e_dyn
    dT_r = ws.dT_r
    _blade_thrust(rot, ws, dT_r)
    for i in range(nr):
        ws.span_line[i] = dT_r[i] * rot.w[i]
    thrust = _psum(ws.span_line, nr)
    # momentum residual: the inflow-ratio change a Newton step would still make
    if rot.bemt:
        e_mom = 0.0
        for i in range(nr):
            r, v = rot.r[i], st.v_r[i]
            if rot.tip_loss:
                F, dF = _prandtl(r, v, Om, R, rot.root_cutout, Nb)
            else:
                F, dF = 1.0, 0.0
            d_be = -Nb * 0.5 * rho * rot.chord * A0 * Om * r
            f = dT_r[i] - 4 * np.pi * rho * F * r * v * abs(v) / kappa**2
            df = d_be - 4 * np.pi * rho * r * (2 * F * abs(v) + dF * v * abs(v)) / kappa**2
            step = abs((v - f / df) - v)
            e_mom = step if (step > e_mom or step != step) else e_mom
        e_mom = e_mom / (Om * R)
    else:
        v = sc[V0]
        F = _uniform_tip_loss(v, Om, rot, ws.span_scratch)
        kap = kappa * F**-0.5
        dT_be = -Nb * 0.5 * rho * rot.chord * A0 * Om * rot.sums[SUM_W_R]
        if forward:
            Vp, dVp = _glauert(v, Vx, Vz)
            gs, dgs = _ground_skew(v, Vx, prm[GROUND_DEFICIT])
            kap = kap * gs
            f = thrust - 2 * rho * rot.area * v * Vp / kap**2
            df = dT_be - 2 * rho * rot.area * ((Vp + v * dVp) - 2.0 * v * Vp * dgs / gs
                                               ) / kap**2
        else:
            f = thrust - 2 * rho * rot.area * v * abs(v) / kap**2
            df = dT_be - 4 * rho * rot.area * abs(v) / kap**2
        e_mom = abs((v - f / df) - v) / (Om * R)
    e_h = 0.0
    if rot.harmonic_inflow and not forward:
        G = _harmonic_gain(sc[V0], prm, rot)
        e_h = abs(G * Mz1 - (sc[VC] - 1j * sc[VS])) / (Om * R)
    if forward and prm[INFLOW] == DREES:
        kx, ky = _drees(prm[MU], prm[LAMBDA_S] + sc[V0] / (Om * R))
        e_h = max(abs(kx * sc[V0] - sc[VC]), abs(ky * sc[V0] - sc[VS])) / (Om * R)
    eq = max(max(e_dyn, e_mom), e_h)
    if e_dyn != e_dyn or e_mom != e_mom or e_h != e_h or not np.isfinite(eq):
        eq = np.inf

    # torque: N_b x azimuth mean of the span integral of dF_x r
    _span_sum(ws.dFx, rot.w_r, ws.psi_line, ws.span_line)
    torque = Nb * _psum(ws.psi_line, npsi) / npsi
    # blade-root flap moment about the hub centre: hinge spring/damper + offset x hinge shear
    _span_sum(ws.dFz, rot.w, ws.psi_line, ws.span_line)
    Fz = np.empty(K, dtype=np.complex128)
    _analyse(ws.psi_line, rot, Fz, ws.psi_scratch)
    M_root = np.empty(K, dtype=np.complex128)
    for k in range(K):
        wk = Om * k
        B = st.Q[0, k]
        M_root[k] = (prm[K_FLAP] + 1j * wk * prm[C_FLAP]) * B + rot.hinge_offset * (
            Fz[k] + rot.S_flap * wk**2 * B)
    # in-plane hub forces (forward flight; zero in hover by symmetry): H rearward (psi = 0),
    # Y to the advancing side (psi = 90 deg), N_b x the azimuth mean of the blade's in-plane
    # force F_x (against the rotation) and radial force -F_z sin(beta), aerodynamic only
    h_force = y_force = 0.0
    if forward:
        h_line, y_line = np.empty(npsi), np.empty(npsi)
        for j in range(npsi):
            for i in range(nr):
                ws.span_scratch[i] = ws.dFx[j, i] * rot.w[i]
            Fx = _psum(ws.span_scratch, nr)
            Fr = -ws.psi_line[j] * math.sin(ws.beta[j])
            h_line[j] = Fx * rot.sin_psi[j] + Fr * rot.cos_psi[j]
            y_line[j] = -Fx * rot.cos_psi[j] + Fr * rot.sin_psi[j]
        h_force = Nb * _psum(h_line, npsi) / npsi
        y_force = Nb * _psum(y_line, npsi) / npsi
    # stall: share of the disk's blade-element area (r dr dpsi) beyond the stall angle
    frac = 0.0
    if af.stall_pos.size:
        pos, neg, alpha, im_, s_ = af.stall_pos, af.stall_neg, ws.alpha, ws.im, ws.s
        for i in range(nr):
            for j in range(npsi):
                # stall angles linear in Mach between the rows (np.interp), clamped
                im, s = im_[j, i], s_[j, i]
                a_pos = _lerp(pos[im], pos[im + 1], s)
                a_neg = _lerp(neg[im], neg[im + 1], s)
                a = alpha[j, i]
                ws.psi_scratch[j] = 1.0 if (a > a_pos or a < a_neg) else 0.0
            ws.span_line[i] = _psum(ws.psi_scratch, npsi) * rot.w_r[i]
        frac = _psum(ws.span_line, nr) / (npsi * rot.sums[SUM_W_R])
    cd_min = np.inf
    for j in range(npsi):
        for i in range(nr):
            v = ws.cd[j, i]
            cd_min = v if (v < cd_min or v != v) else cd_min
    # static feathering stiffness: link + propeller moment I_p Omega^2 - d(mean aerodynamic
    # pitching moment)/d(pitch), the section slopes by a forward difference in alpha at the
    # converged flow; exactly zero without table CM and aerodynamic-centre offset
    dM = 0.0
    x_ac = prm[X_AC]
    if rot.pitching_moment or x_ac != 0:
        h = PITCH_STEP_DEG
        for j in range(npsi):
            for i in range(nr):
                ws.shifted[j, i] = _wrap_deg(ws.alpha[j, i] + h)
        _coefficients(ws.shifted, ws.im, ws.s, af, fit, linear, ws.cl2, ws.cd2, ws.cm2)
        for j in range(npsi):
            for i in range(nr):
                cm_d = (ws.cm2[j, i] - ws.cm[j, i]) if rot.pitching_moment else 0.0
                ws.dFx[j, i] = ws.qc[j, i] * (rot.chord * cm_d
                                              - x_ac * (ws.cl2[j, i] - ws.cl[j, i]))
        _span_sum(ws.dFx, rot.w, ws.psi_line, ws.span_line)
        dM = _psum(ws.psi_line, npsi) * (RAD2DEG / (h * npsi))
    out[0] = thrust
    out[1] = torque
    out[2] = eq
    out[3] = frac
    out[4] = cd_min
    out[5] = prm[K_FEATHER] + rot.pitch_inertia * Om**2 - dM
    out[6] = 1.0 if bad else 0.0
    out[7] = h_force
    out[8] = y_force
    return M_root


# ---------------------------------------------------------------------------------------------
# one sample, and the batch


@numba.njit(**_STAGE)
def _solve_sample(prm, rot, af, fit, linear, tolerance, max_iterations, ws, Q_out,
                  scalars_out, status_out, loads_out, M_root_out, flight):
    """Iterate one sample to convergence and evaluate its loads at the final state.

    prm : (N_COLUMNS,) inputs; ws : a :class:`Work` (every entry is written before it is
    read within a pass, so a workspace carries nothing from one sample to the next).
    Writes Q_out (3, K), scalars_out (v0, vc, vs, relax, resid), status_out (reason,
    diverging DOF, flow not finite in the last step, iterations), loads_out (see
    :func:`_hub_loads`; only when the iteration converged) and M_root_out (K,).
    """
    K = rot.cos_k.shape[0]
    nr = rot.r.size
    Z, Jinv, J0, J1, F_cmd, v_init, k_v, qa, J, a_lift = _structural_jacobian(
        prm, rot, af, fit, linear, ws)
    # initial state: pitch from the quasi-static pitch-link balance, no flap, linear-theory
    # hover inflow at 0.75 R
    Q = np.zeros((3, K), dtype=np.complex128)
    for k in range(K):
        Q[2, k] = F_cmd[2, k] / Z[k, 2, 2]
    trim = flight is not None and prm[TRIM] != NO_TRIM and K > 1
    if trim:
        v_init = _trim_inflow(prm, rot)
    # forward flight and the trims: the coupled harmonic balance (hover: M empty; the hover
    # build, flight None, compiles none of it)
    if flight is not None and (trim or prm[MU] != 0.0):
        M = _coupled_jacobian(prm, rot, J, J0, k_v, a_lift, 3 if trim else 0, ws)
    else:
        M = np.zeros((0, 0))
    A, b, x = np.empty_like(M), np.empty(M.shape[0]), np.empty(M.shape[0])
    # the coupled step's last residual and step and the column weights (Broyden)
    hist = np.zeros((3, M.shape[0] + 1))
    hist[2, :] = 1.0
    if M.shape[0]:
        hist[2, 2 * (2 * K - 1)] = 1.0 / (prm[OMEGA] * rot.radius) ** 2
    scalars = np.zeros(N_SCALARS)
    scalars[V0] = v_init
    scalars[RELAX] = 1.0
    scalars[RESID] = np.inf
    v_r = np.full(nr, v_init)
    st = State(Q, scalars, v_r, v_r.copy(), np.zeros(nr))
    reason, dof, bad, iterations = NOT_CONVERGED, 0, False, 0
    if trim and prm[TRIM] == HUB_MOMENTS:
        singular = True
        for col in range(M.shape[1]):
            if M[M.shape[0] - 2, col] != 0.0 or M[M.shape[0] - 1, col] != 0.0:
                singular = False
        if singular:
            reason = TRIM_SINGULAR
            max_iterations = 0
    # the iteration's arrays borrowed (see _borrowed): referenced here until _keep_alive
    st_, Z_, Jinv_, J0_, J1_, F_cmd_ = (_borrowed(st), _borrowed(Z), _borrowed(Jinv),
                                        _borrowed(J0), _borrowed(J1), _borrowed(F_cmd))
    M_, A_, b_, x_, hist_ = _borrowed(M), _borrowed(A), _borrowed(b), _borrowed(x), _borrowed(
        hist)
    for _ in range(max_iterations):
        size, bad = _step(st_, prm, rot, af, fit, linear, Z_, Jinv_, J0_, J1_, F_cmd_, k_v, qa,
                          ws, M_, A_, b_, x_, flight, hist_)
        iterations += 1
        if trim:
            if (abs(prm[COLLECTIVE]) + abs(prm[LATERAL]) + abs(prm[LONGITUDINAL])
                    > TRIM_PITCH_LIMIT_DEG):
                reason = TRIM_PITCH
                break
        # largest harmonic amplitude per DOF; the DOF named is np.argmax's (first NaN, else
        # first largest) and the test np.max's (NaN never exceeds the limit)
        largest, dof = -1.0, 0
        for d in range(3):
            amp = 0.0
            for k in range(K):
                a = abs(Q[d, k])
                if a != a or a > amp:
                    amp = a
                if amp != amp:
                    break
            if largest == largest and (amp != amp or amp > largest):
                largest, dof = amp, d
        if bad or not np.isfinite(size):
            reason = NONFINITE
            break
        if largest > MAX_BLADE_MOTION:
            reason = TOO_LARGE
            break
        if size < tolerance:
            reason = OK
            break
    for d in range(3):
        for k in range(K):
            Q_out[d, k] = Q[d, k]
    for j in range(N_SCALARS):
        scalars_out[j] = scalars[j]
    status_out[0] = reason
    status_out[1] = dof
    status_out[2] = 1 if bad else 0
    status_out[3] = iterations
    if reason == OK:
        M_root = _hub_loads(st, prm, rot, af, fit, linear, Z, F_cmd, ws, loads_out, flight)
        for k in range(K):
            M_root_out[k] = M_root[k]
    _keep_alive((st, Z, Jinv, J0, J1, F_cmd, M, A, b, x, hist))


@numba.njit(**_STAGE)
def _workspace(rot):
    """The scratch arrays of one solve (one per calling thread, reused sample after sample)."""
    K = rot.cos_k.shape[0]
    npsi, nr = rot.cos_psi.size, rot.r.size
    f = np.empty((15, npsi, nr))
    c = np.empty((3, 3, K), dtype=np.complex128)
    v = np.empty((3, 4), dtype=np.complex128)
    return Work(np.empty(npsi), f[0], f[1], f[2], f[3], f[4], f[5], f[6], f[7], f[8], f[9],
                f[10], f[11], f[12], f[13], f[14], np.empty(npsi), np.empty(npsi),
                np.empty(nr), np.empty(nr), np.empty(nr), c[0], c[1], c[2, 0],
                np.empty((4, 4), dtype=np.complex128), v[0], v[1],
                np.zeros((npsi, nr), dtype=np.int64), np.zeros((npsi, nr)))


def _without_meminfo(context, builder, ty, value):
    """``value`` of type ``ty`` with the meminfo of every array in it (in tuples) null."""
    if isinstance(ty, types.Array):
        ary = context.make_array(ty)(context, builder, value=value)
        ary.meminfo = cgutils.get_null_value(ary.meminfo.type)
        return ary._getvalue()
    if isinstance(ty, types.BaseTuple):
        for i, item_ty in enumerate(ty):
            item = _without_meminfo(context, builder, item_ty, builder.extract_value(value, i))
            value = builder.insert_value(value, item, i)
    return value


@intrinsic
def _borrowed(typingctx, value):
    """``value`` (an array or a tuple holding arrays) with its arrays' memory owners left out:
    views of the same memory that numba does not reference-count.

    Every array a compiled function receives is reference-counted on entry and exit, an
    atomic operation per array; the stages take the Rotor, Table and Work tuples (about 50
    arrays) and are called some 20 times per iteration: these atomic updates were 15 % of
    the solve (issue 34). NRT_incref and NRT_decref skip a null owner. The caller keeps
    ``value`` itself alive (and referenced) while the borrowed views are in use, and no view
    outlives it: none is stored in a longer-lived object or returned to Python."""
    def codegen(context, builder, sig, args):
        return _without_meminfo(context, builder, sig.args[0], args[0])
    return value(value), codegen


@numba.njit(**_STAGE)
def _keep_alive(value):
    """A use of ``value``: its reference is dropped after this call (not inlined: an inlined
    body would leave no use)."""


@numba.njit(**_JIT)
def solve_samples(prm, rot, af, fits, linear, tolerance, max_iterations, Q, scalars, status,
                  loads, M_root, flight):
    """Solve the samples of ``prm`` (n, N_COLUMNS) one after the other, writing row s of
    every output array (see :func:`_solve_sample`). Releases the GIL: threads may solve
    disjoint slices of a batch at the same time.

    ``flight`` is None for the hover build: numba leaves out every branch behind
    ``flight is not None`` when it compiles, so a hover study never compiles the forward
    flight and trim code on a cold cache (issue 34); True for the forward-flight build
    (:func:`needs_flight`), where mu = 0 rows take the hover paths."""
    ws = _workspace(rot)
    # borrowed views for the loop: rot, af and the outputs are held by the caller, ws is
    # referenced until _keep_alive
    rot_, af_, ws_ = _borrowed(rot), _borrowed(af), _borrowed(ws)
    prm_, fits_, linear_ = _borrowed(prm), _borrowed(fits), _borrowed(linear)
    Q_, scalars_, status_ = _borrowed(Q), _borrowed(scalars), _borrowed(status)
    loads_, M_root_ = _borrowed(loads), _borrowed(M_root)
    for s in range(prm.shape[0]):
        _solve_sample(prm_[s], rot_, af_, fits_[s], linear_[s], tolerance, max_iterations,
                      ws_, Q_[s], scalars_[s], status_[s], loads_[s], M_root_[s], flight)
    _keep_alive(ws)


def needs_flight(prm: np.ndarray) -> bool | None:
    """:func:`solve_samples`'s ``flight`` for the rows of ``prm`` (n, N_COLUMNS): True when a
    row is in forward flight or trimmed (or its advance ratio is not a number), else None
    (the hover build)."""
    mu = prm[:, MU]
    if np.any(mu != 0.0) or np.any(prm[:, TRIM] != NO_TRIM):
        return True
    return None
