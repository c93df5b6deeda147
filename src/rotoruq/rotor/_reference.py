"""The numpy implementation of the hover solve: the test oracle of the compiled one.

Used only by the tests and benchmarks (``tests/test_rotor_kernel.py``,
``benchmarks/rotor_throughput.py``), never by the model: it is the batched numpy solve that
:mod:`rotoruq.rotor._kernel` replaced, kept to prove the compiled solve gives the same
numbers (1e-10 relative) and to measure the speed-up against; it also gives what the
compiled solve does not return, the spanwise section loads (:func:`section_loads`), which a
run records at its nominal point for the report's reasons. Arrays over (sample, azimuth,
station); a converged sample leaves the iteration (its state is frozen), every reduction runs
per sample in a fixed order, so a sample's result is bitwise the same whatever batch it is
solved in. ``freeze=False`` iterates every sample until the slowest has converged (the
lock-step baseline).
"""

from __future__ import annotations

import numpy as np

from ._kernel import LIFT_SECANT_DEG
from .controls import swashplate_harmonics
from .dynamics import HarmonicBasis, apply_blocks, fixed_sum, structural_operator
from .geometry import BladeGrid
from .hover import (
    MAX_BLADE_MOTION,
    HoverSolution,
    _col,
    default_check_tolerance,
    judge,
    sample_columns,
)
from .inflow import A0, annulus_update, prandtl_loss, uniform_update
from .presets import RotorPreset

__all__ = ["solve_hover_reference", "section_loads"]


def _wrap_deg(a):
    """Wrap to [-180, 180) only where needed, so in-range values keep their exact bits (a
    table lookup that wraps a whole array when one value is out of range would otherwise
    couple samples)."""
    if a.size == 0 or (a.min() >= -180.0 and a.max() < 180.0):
        return a
    return np.where((a >= -180.0) & (a < 180.0), a, np.mod(a + 180.0, 360.0) - 180.0)


class _Rotor:
    """Per-sample constants of a batch and the per-sample evaluation of loads and residuals.

    Every method works on any subset of the samples (``idx``) and gives bitwise the same
    numbers for a sample whatever the subset.
    """

    def __init__(self, preset: RotorPreset, airfoil, grid: BladeGrid, columns, ov, n_harmonics):
        P, kappa, K_b, K_p = columns
        self.p, self.airfoil, self.grid = preset, airfoil, grid
        self.basis = HarmonicBasis(grid.psi, n_harmonics)
        self.kvec = self.basis.k
        self.ov = ov
        self.bemt = preset.inflow == "bemt"
        e, c, R = preset.hinge_offset, preset.chord, preset.radius
        r, w = grid.r, grid.w
        self.r, self.w, self.rr = r, w, r - e
        Om, rho = P["omega"], P["rho"]
        C_p = preset.feathering_stiffness(P["c_pitch_link"])
        tan_d3 = np.tan(np.deg2rad(preset.delta3_deg))
        kvec = self.kvec
        Z = structural_operator(kvec, Om, grid.I_flap, grid.S_flap, e, grid.I_lag,
                                preset.pitch_inertia, K_b, P["c_flap"], P["k_lag"],
                                P["c_lag"], K_p, C_p, tan_d3)
        rr = self.rr
        wk = Om[:, None] * kvec[None, :]
        # The mean lift's pitch derivative is reduced by the inflow's response to it (BEMT:
        # by m / (m + k_v), m = 4 rho A v / kappa^2, k_v = dT_BE/dv), at the linear-theory
        # inflow of the initial state; the uniform inflow is solved jointly instead (J0).
        sigma = preset.solidity
        th75 = np.deg2rad(P["collective_deg"]) + np.deg2rad(preset.twist_deg) * (
            0.75 * R - preset.root_cutout) / (R - preset.root_cutout)
        lam = sigma * A0 / 16 * (np.sqrt(1 + 32 / (sigma * A0) * np.abs(th75) * 0.75) - 1)
        v_init = np.maximum(lam, 1e-3) * Om * R * np.sqrt(np.maximum(kappa, 0.1))
        m_mom = 4 * rho * preset.area * v_init / np.maximum(kappa, 0.1) ** 2
        # the aerodynamic terms with the airfoil's own lift slope (see _lift_slope)
        # (BEMT keeps A0, as the kernel)
        a_lift = (np.full(Om.shape, A0) if self.bemt else
                  self._lift_slope(Om, np.rad2deg(th75 - np.sign(th75) * lam / 0.75), ov))
        # Jacobian: the structure plus linear aerodynamic flap damping and the flap moment's
        # pitch derivative (a preconditioner: the converged state satisfies the full equations).
        c_ab = 0.5 * rho * a_lift * c * Om * float(np.sum(w * r * rr**2))
        k_abt = 0.5 * rho * a_lift * c * Om**2 * float(np.sum(w * r**2 * rr))
        J = Z.copy()
        J[..., 0, 0] += 1j * wk * c_ab[:, None]
        J[..., 0, 2] -= k_abt[:, None]
        J[..., 1, 1] += 1j * wk * (0.5 * rho * c * Om * 0.02 * float(np.sum(w * r * rr**2))
                                   )[:, None]
        # Linear-theory derivatives of the feathering moment of the lift acting x_ac aft of the
        # feathering axis: d/dtheta = -x_ac q_tt, d/dbeta_k = i k x_ac q_tb.
        x_ac = P["aero_center_offset"]
        q_tt = 0.5 * rho * c * a_lift * Om**2 * float(np.sum(w * r**2))
        q_tb = 0.5 * rho * c * a_lift * Om**2 * float(np.sum(w * r * rr))
        k_v = preset.n_blades * 0.5 * rho * c * a_lift * Om * float(np.sum(w * r))
        fb = np.ones((Om.size, kvec.size))
        if self.bemt:
            fb[:, 0] = m_mom / (m_mom + k_v)
        J[..., 2, 2] += (x_ac * q_tt)[:, None] * fb
        J[..., 2, 0] -= 1j * kvec[None, :] * (x_ac * q_tb)[:, None]
        qa = 0.5 * rho * c * a_lift * Om
        theta_cmd = swashplate_harmonics(P["collective_deg"], P["lateral_deg"],
                                         P["longitudinal_deg"], n_harmonics)
        F_cmd = np.zeros((Om.size, 3, kvec.size), dtype=complex)
        F_cmd[:, 2, :] = (K_p[:, None] + 1j * wk * C_p[:, None]) * theta_cmd
        # mean motion + uniform inflow: columns/rows 0-2 the blade, 3 the inflow v0; J0[3, 3]
        # (momentum) is set per iteration
        J0 = np.zeros((Om.size, 4, 4), dtype=complex)
        J0[:, :3, :3] = J[:, 0]
        J0[:, 0, 3] = 0.5 * rho * c * a_lift * Om * float(np.sum(w * r * rr))
        J0[:, 2, 3] = -x_ac * 0.5 * rho * c * a_lift * Om * float(np.sum(w * r))
        J0[:, 3, 2] = -preset.n_blades * 0.5 * rho * c * a_lift * Om**2 * float(
            np.sum(w * r**2))
        J1 = np.zeros((Om.size, 4, 4), dtype=complex)
        J1[:, :3, :3] = J[:, 1]
        J1[:, 0, 3] = qa * float(np.sum(w * r * rr * r)) / R
        self.C = {
            "Om": Om, "rho": rho, "kappa": kappa, "K_b": K_b, "c_flap": P["c_flap"],
            "K_p": K_p, "C_p": C_p, "Z": Z, "Jinv": np.linalg.inv(J), "J1": J1,
            "F_cmd": F_cmd, "th_cmd0": theta_cmd[:, 0].real, "qa": qa,
            "cm0": P["cm0"], "x_ac": P["aero_center_offset"], "v_init": v_init,
            "J0": J0, "k_v": k_v,
        }

    def _lift_slope(self, Om, alpha_ref, ov):
        """Lift slope [1/rad] (n,) of the Jacobian: the secant of cl over alpha_ref +-
        LIFT_SECANT_DEG at each station's Mach number Omega r / a, averaged with the flap
        damping's weight w r (r - e)^2, bounded to [1/2, 2] x A0 (A0 if not finite)."""
        h = LIFT_SECANT_DEG
        alpha = np.stack([_wrap_deg(alpha_ref - h), _wrap_deg(alpha_ref + h)], axis=1)
        alpha = np.repeat(alpha[:, :, None], self.r.size, axis=2)
        mach = np.broadcast_to(Om[:, None, None] * self.r / self.p.speed_of_sound, alpha.shape)
        lo, hi = getattr(self.airfoil, "mach_range", (-np.inf, np.inf))
        cl = self.airfoil.coefficients(alpha, np.clip(mach, lo, hi), ov)[0]
        weight = self.w * self.r * self.rr**2
        a = np.sum((cl[:, 1] - cl[:, 0]) * weight, axis=1) / float(np.sum(weight)) * (
            180.0 / np.pi / (2 * h))
        return np.where(np.isfinite(a), np.clip(a, 0.5 * A0, 2.0 * A0), A0)

    def sub(self, idx):
        """Constants and airfoil overrides of the samples ``idx`` (all when None)."""
        if idx is None:
            return self.C, self.ov
        return ({k: v[idx] for k, v in self.C.items()}, {k: v[idx] for k, v in self.ov.items()})

    def inflow_field(self, S, C):
        r, R = self.r, self.p.radius
        base = S["v_r"][:, None, :] if self.bemt else S["v0"][:, None, None]
        psi = self.grid.psi
        harm = (r / R)[None, None, :] * (S["vc"][:, None, None] * np.cos(psi)[None, :, None]
                                         + S["vs"][:, None, None] * np.sin(psi)[None, :, None])
        return base + harm

    def aero(self, S, C, ov, full=False):
        """Section loads over (n, Npsi, Nr) at the state S; ``bad`` (n,) marks samples whose
        section flow is not finite (their loads are computed at a neutral flow, not used).
        ``full`` also returns the section flow and coefficients (the iteration keeps only the
        loads: fewer live arrays, fewer cache misses)."""
        p, grid, basis, r, rr = self.p, self.grid, self.basis, self.r, self.rr
        Om, rho = C["Om"], C["rho"]
        Q = S["Q"]
        beta = basis.synth(Q[:, 0])
        dbeta = basis.synth_d(Q[:, 0])
        dzeta = basis.synth_d(Q[:, 1])
        theta = basis.synth(Q[:, 2])
        vfield = self.inflow_field(S, C)
        UT = Om[:, None, None] * (r[None, None, :] - rr * dzeta[:, :, None])
        UP = vfield + Om[:, None, None] * rr * dbeta[:, :, None]
        phi = np.arctan2(UP, UT)
        alpha = np.rad2deg(theta[:, :, None] + grid.twist - phi)
        U2 = UT**2 + UP**2
        del UT, UP, vfield
        cphi, sphi = np.cos(phi), np.sin(phi)
        del phi
        mach = np.sqrt(U2) / p.speed_of_sound
        ok = np.isfinite(alpha) & np.isfinite(U2)
        bad = ~ok.reshape(ok.shape[0], -1).all(axis=1)
        if bad.any():  # neutral flow for the diverged samples (flagged, never returned)
            alpha, mach, U2 = (np.where(ok, v, 0.0) for v in (alpha, mach, U2))
        alpha = _wrap_deg(alpha)
        lo, hi = getattr(self.airfoil, "mach_range", (-np.inf, np.inf))
        if mach.size and (mach.min() < lo or mach.max() > hi):
            # the table clamps as well, but only here is it decided per element
            mach = np.clip(mach, lo, hi)
        cl, cd, cm = self.airfoil.coefficients(alpha, mach, ov)
        qc = 0.5 * rho[:, None, None] * U2 * p.chord
        dFz = qc * (cl * cphi - cd * sphi)
        dFx = qc * (cl * sphi + cd * cphi)
        cm_sec = (cm if p.pitching_moment else 0.0) + C["cm0"][:, None, None]
        dMp = qc * (p.chord * cm_sec - C["x_ac"][:, None, None] * cl)
        out = {"beta": beta, "dFz": dFz, "dFx": dFx, "dMp": dMp, "bad": bad}
        if full:
            out.update(alpha=alpha, mach=mach, cl=cl, cd=cd, cm=cm, qc=qc)
        return out

    def residuals(self, S, C, A):
        """Structural residual harmonics (n, 3, K) and the blade-root load harmonics."""
        b, w, rr, r = self.basis, self.w, self.rr, self.r
        Mf = fixed_sum(A["dFz"], w * rr)
        Ml = fixed_sum(A["dFx"], w * rr)
        Mp = fixed_sum(A["dMp"], w)
        Fgen = np.stack([b.analyse(Mf), b.analyse(Ml), b.analyse(Mp)], axis=1)
        R_dyn = Fgen + C["F_cmd"] - apply_blocks(C["Z"], S["Q"])
        Mz1 = b.analyse(fixed_sum(A["dFz"], w * r))[:, 1]
        return R_dyn, Mz1

    def harmonic_gain(self, S, C):
        p = self.p
        R = p.radius
        lam0 = np.maximum(np.abs(S["v0"]) / (C["Om"] * R), 1e-4)
        return 0.5 * p.n_blades * C["kappa"] / (C["rho"] * p.area * C["Om"] * R**2 * lam0)

    def blade_thrust(self, A):
        """Per-station thrust per unit span, azimuth mean over N_b blades: (n, Nr)."""
        dT = A["dFz"] * np.cos(A["beta"])[:, :, None]
        return self.p.n_blades * fixed_sum(np.moveaxis(dT, 1, -1)) / self.grid.psi.size

    def tip_loss(self, v_r, Om):
        p = self.p
        if not p.tip_loss:
            return 1.0, 0.0
        return prandtl_loss(self.r[None, :], p.radius, p.root_cutout, p.n_blades, v_r,
                            Om[:, None], derivative=True)

    def uniform_tip_loss(self, v0, Om):
        """Prandtl loss for the uniform inflow: annulus momentum 4 pi rho F r v^2 dr with one
        v over the span gives T = 2 rho A v^2 F_mean, F_mean the area (r dr) mean of F over the
        blade span; 1 without tip loss."""
        if not self.p.tip_loss:
            return np.ones_like(v0)
        F = prandtl_loss(self.r[None, :], self.p.radius, self.p.root_cutout,
                         self.p.n_blades, v0[:, None], Om[:, None])
        wr = self.w * self.r
        return fixed_sum(F, wr) / float(np.sum(wr))

    def step(self, S, C, ov):
        """One iteration for the samples of S; returns (new state, step size, bad flow)."""
        p, Om = self.p, C["Om"]
        R, Nb = p.radius, p.n_blades
        relax = S["relax"]
        A = self.aero(S, C, ov)
        R_dyn, Mz1 = self.residuals(S, C, A)
        dQ = apply_blocks(C["Jinv"], R_dyn)
        new = dict(S)
        if p.harmonic_inflow:
            # First harmonic: blade motion and the Pitt-Peters inflow V1 = v_c - i v_s solved
            # together (their coupling is what makes a plain fixed point slow).
            qa = C["qa"]
            r, rr, w = self.r, self.rr, self.w
            dMz_dV = -qa * float(np.sum(w * r**3)) / R
            dMz_dB = -1j * qa * Om * float(np.sum(w * r**2 * rr))
            dMz_dT = qa * Om * float(np.sum(w * r**3))
            G = self.harmonic_gain(S, C)
            V1 = S["vc"] - 1j * S["vs"]
            rhs = np.concatenate([R_dyn[:, :, 1], (G * Mz1 - V1)[:, None]], axis=1)
            J1 = C["J1"].copy()
            J1[:, 3, 0] = -G * dMz_dB
            J1[:, 3, 2] = -G * dMz_dT
            J1[:, 3, 3] = 1.0 - G * dMz_dV
            d1 = np.linalg.solve(J1, rhs[..., None])[..., 0]
            dQ[:, :, 1] = d1[:, :3]
            V1 = V1 + relax * d1[:, 3]
            new["vc"], new["vs"] = V1.real, -V1.imag
            dv1 = np.abs(d1[:, 3]) / (Om * R)
        else:
            dv1 = np.zeros_like(Om)
        dT_r = self.blade_thrust(A)
        if not self.bemt:
            # Mean blade motion and the uniform inflow solved together (a soft feathering
            # restraint couples the blade pitch to the lift, and the lift to the inflow).
            v = S["v0"]
            F = self.uniform_tip_loss(v, Om)
            mom = 2 * C["rho"] * p.area * F / C["kappa"] ** 2
            J0 = C["J0"].copy()
            J0[:, 3, 3] = C["k_v"] + 2 * mom * np.abs(v)
            rhs = np.concatenate([R_dyn[:, :, 0], (fixed_sum(dT_r, self.w) - mom * v * np.abs(v)
                                                   )[:, None]], axis=1)
            d0 = np.linalg.solve(J0, rhs[..., None])[..., 0]
            dQ[:, :, 0] = d0[:, :3]
            dv_step = d0[:, 3].real
        dQ = dQ * relax[:, None, None]
        new["Q"] = S["Q"] + dQ
        if self.bemt:
            v_r = S["v_r"]
            F, dF = self.tip_loss(v_r, Om)
            # Blade-element slope dT/dv per station: the secant of the last two iterates,
            # bounded by 1/4..4 x linear theory (the table's lift slope at low Reynolds number
            # can be twice the thin-airfoil one, and a Newton step with the wrong slope then
            # oscillates for hundreds of iterations).
            lin = -Nb * 0.5 * C["rho"][:, None] * p.chord * A0 * Om[:, None] * self.r
            dv_prev = v_r - S["v_prev"]
            use = np.abs(dv_prev) > 1e-12 * (Om * R)[:, None]
            sec = (dT_r - S["dT_prev"]) / np.where(use, dv_prev, 1.0)
            slope = np.where(use, np.clip(sec, 4.0 * lin, 0.25 * lin), lin)
            v_new = annulus_update(v_r, dT_r, C["rho"][:, None], C["kappa"][:, None], F,
                                   p.chord, Nb, Om[:, None], self.r[None, :], dF, slope)
            new["v_prev"], new["dT_prev"] = v_r, dT_r
            v_new = v_r + relax[:, None] * (v_new - v_r)
            dv = np.max(np.abs(v_new - v_r), axis=1) / (Om * R)
            new["v_r"] = v_new
            new["v0"] = fixed_sum(v_new, self.w * self.r) / float(np.sum(self.w * self.r))
        else:
            new["v0"] = S["v0"] + relax * dv_step
            dv = np.abs(relax * dv_step) / (Om * R)
        dv = np.maximum(dv, dv1)
        size = np.maximum(np.max(np.abs(dQ).reshape(dQ.shape[0], -1), axis=1), dv) / relax
        # Per-sample step control: halve the step of a sample whose update grew (stall and
        # strong aerodynamic pitching moments make the fixed point oscillate), regrow it when
        # the update shrinks again.
        new["relax"] = np.where(size > S["resid"], np.maximum(0.5 * relax, 0.05),
                                np.minimum(1.5 * relax, 1.0))
        new["resid"] = size
        return new, size, A["bad"]

    def check(self, S, C, ov):
        """Loads and the equation residual re-evaluated at the final state S."""
        p, grid, basis = self.p, self.grid, self.basis
        Om, rho = C["Om"], C["rho"]
        R, Nb = p.radius, p.n_blades
        A = self.aero(S, C, ov, full=True)
        R_dyn, Mz1 = self.residuals(S, C, A)
        scale = np.abs(np.diagonal(C["Z"][:, 0], axis1=1, axis2=2))      # (n, 3)
        e_dyn = np.max(np.abs(R_dyn).max(axis=2) / scale, axis=1)
        dT_r = self.blade_thrust(A)
        thrust = fixed_sum(dT_r, self.w)
        # momentum residual as the inflow-ratio change the Newton step would still make
        if self.bemt:
            v = S["v_r"]
            F, dF = self.tip_loss(v, Om)
            v_new = annulus_update(v, dT_r, rho[:, None], C["kappa"][:, None], F, p.chord, Nb,
                                   Om[:, None], self.r[None, :], dF)
            e_mom = np.max(np.abs(v_new - v), axis=1) / (Om * R)
        else:
            v = S["v0"]
            F = self.uniform_tip_loss(v, Om)
            v_new = uniform_update(v, thrust, rho, p.area, C["kappa"] * F ** -0.5, p.chord, Nb,
                                   Om, self.r, self.w)
            e_mom = np.abs(v_new - v) / (Om * R)
        if p.harmonic_inflow:
            G = self.harmonic_gain(S, C)
            e_h = np.abs(G * Mz1 - (S["vc"] - 1j * S["vs"])) / (Om * R)
        else:
            e_h = np.zeros_like(Om)
        eq = np.maximum(np.maximum(e_dyn, e_mom), e_h)
        eq = np.where(np.isfinite(eq), eq, np.inf)

        # loads
        npsi = grid.psi.size
        torque = Nb * fixed_sum(np.moveaxis(fixed_sum(A["dFx"], self.w * self.r), 1, -1)
                                ) / npsi
        wk = Om[:, None] * self.kvec[None, :]
        # Blade-root flap moment about the hub centre: hinge spring/damper + offset x hinge
        # shear.
        Fz_k = basis.analyse(fixed_sum(A["dFz"], self.w))
        B = S["Q"][:, 0]
        M_root = (C["K_b"][:, None] + 1j * wk * C["c_flap"][:, None]) * B + p.hinge_offset * (
            Fz_k + grid.S_flap * wk**2 * B)
        # stall: share of the disk's blade-element area (r dr dpsi) beyond the stall angle
        stall = getattr(self.airfoil, "stall_angles", None)
        if stall is not None:
            a_pos, a_neg = stall(A["mach"])
            a = A["alpha"]
            beyond = ((a > a_pos) | (a < a_neg)).astype(float)
            frac = fixed_sum(fixed_sum(np.moveaxis(beyond, 1, -1)), self.w * self.r) / (
                npsi * float(np.sum(self.w * self.r)))
        else:
            frac = np.zeros_like(Om)
        cd_min = A["cd"].reshape(A["cd"].shape[0], -1).min(axis=1)
        # Static feathering stiffness: link + propeller moment I_p Omega^2 - d(mean aerodynamic
        # pitching moment)/d(pitch), the section slopes by a forward difference in alpha at the
        # converged flow. Zero (exactly) without table CM and aerodynamic-centre offset.
        dM = np.zeros_like(Om)
        if p.pitching_moment or np.any(C["x_ac"] != 0):
            h = 1e-3  # deg
            cl2, _, cm2 = self.airfoil.coefficients(_wrap_deg(A["alpha"] + h), A["mach"], ov)
            cm_d = (cm2 - A["cm"]) if p.pitching_moment else 0.0
            dm = A["qc"] * (p.chord * cm_d - C["x_ac"][:, None, None] * (cl2 - A["cl"]))
            dM = fixed_sum(np.moveaxis(fixed_sum(dm, self.w), 1, -1)) * (
                np.rad2deg(1.0) / (h * npsi))
        k_eff = C["K_p"] + p.pitch_inertia * Om**2 - dM
        return {"thrust": thrust, "torque": torque, "M_root": M_root, "eq": eq,
                "stalled": frac, "cd_min": cd_min, "bad": A["bad"], "k_eff": k_eff}


def solve_hover_reference(
    preset: RotorPreset,
    airfoil,
    grid: BladeGrid,
    params: dict[str, np.ndarray],
    overrides: dict[str, np.ndarray] | None = None,
    *, n_harmonics: int = 2, tolerance: float = 1e-9, max_iterations: int = 200,
    check_tolerance: float | None = None, freeze: bool = True,
) -> HoverSolution:
    """The hover state of :func:`rotoruq.rotor.hover.solve_hover` (same arguments and
    result), solved in numpy: the reference the compiled kernel is tested against.

    freeze : True (default): a converged sample leaves the iteration, which makes results
        independent of the batch; False only serves as a timing baseline.
    """
    n = np.broadcast(*[np.asarray(v) for v in params.values()]).shape[0]
    columns = sample_columns(preset, grid, params, n)
    ov = {k: _col(overrides, k, n) for k in (overrides or {})}
    check_tolerance = default_check_tolerance(tolerance, check_tolerance)
    with np.errstate(all="ignore"):
        return _solve(preset, airfoil, grid, columns, ov, n, n_harmonics, tolerance,
                      max_iterations, check_tolerance, freeze)


def section_loads(preset: RotorPreset, airfoil, grid: BladeGrid, params: dict[str, np.ndarray],
                  overrides: dict[str, np.ndarray] | None = None, *,
                  derivatives: tuple[str, ...] = (), n_harmonics: int = 2,
                  tolerance: float = 1e-9, max_iterations: int = 200) -> dict[str, np.ndarray]:
    """The spanwise loads of the converged hover state: per station, azimuth means.

    Same arguments as :func:`solve_hover_reference`; ``derivatives`` names airfoil fit
    parameters (``cla_m06``, ...) whose direct effect on the section thrust is wanted.
    Returns ``r`` (Nr,) station radius [m],
    ``w`` (Nr,) its span quadrature weight [m], ``thrust_per_span`` (n, Nr) the rotor's
    thrust per unit span (all blades) [N/m] (``sum(thrust_per_span * w)`` is the thrust),
    ``mach`` and ``alpha_deg`` (n, Nr) the section Mach number and angle of attack [deg],
    ``failure`` (n,) the reason of a sample that did not converge ("" otherwise; its
    loads are NaN), and for each name in ``derivatives`` ``"d_thrust_per_span/<name>"``
    (n, Nr): d(thrust per unit span)/d(parameter) at the converged inflow and blade motion
    held fixed (the section's own response, before the inflow answers it), by a central
    difference of 1e-6 of the parameter's value.

    Examples
    --------
    >>> from rotoruq.rotor.model import RotorModel
    >>> m = RotorModel("bo105", names_in=["collective_deg"], names_out=["thrust"])
    >>> params = {k: np.array([v]) for k, v in m.defaults().items()}
    >>> out = section_loads(m.preset, m.airfoil, m.grid, params)
    >>> out["thrust_per_span"].shape == (1, out["r"].size)
    True
    """
    n = np.broadcast(*[np.asarray(v) for v in params.values()]).shape[0]
    columns = sample_columns(preset, grid, params, n)
    ov = {k: _col(overrides, k, n) for k in (overrides or {})}
    with np.errstate(all="ignore"):
        rot, S, _, failure = _iterate(preset, airfoil, grid, columns, ov, n, n_harmonics,
                                      tolerance, max_iterations, True)
        A = rot.aero(S, rot.C, ov, full=True)
        dT = rot.blade_thrust(A)
        out = {"r": rot.r.copy(), "w": rot.w.copy(), "thrust_per_span": dT,
               "mach": A["mach"].mean(axis=1), "alpha_deg": A["alpha"].mean(axis=1),
               "failure": failure.astype(str)}
        nominal = airfoil.nominal_values() if derivatives else {}
        for name in derivatives:
            base = ov[name] if name in ov else np.full(n, nominal[name])
            h = 1e-6 * np.maximum(np.abs(base), 1e-12)
            up, down = ({**ov, name: base + sign * h} for sign in (1.0, -1.0))
            out[f"d_thrust_per_span/{name}"] = (
                rot.blade_thrust(rot.aero(S, rot.C, up)) - rot.blade_thrust(
                    rot.aero(S, rot.C, down))) / (2 * h[:, None])
    bad = failure != ""
    for k, v in out.items():
        if k not in ("r", "w", "failure"):
            v[bad] = np.nan
    return out


def _iterate(preset, airfoil, grid, columns, ov, n, n_harmonics, tol, max_iter, freeze):
    """The periodic iteration: (rotor constants, final state, iterations, failure reasons)."""
    rot = _Rotor(preset, airfoil, grid, columns, ov, n_harmonics)
    C = rot.C
    r = rot.r
    K = rot.kvec.size
    # Initial state: pitch from the quasi-static pitch-link balance, no flap, hover inflow
    # of linear theory at 0.75 R.
    Q = np.zeros((n, 3, K), dtype=complex)
    Q[:, 2, :] = C["F_cmd"][:, 2, :] / C["Z"][:, :, 2, 2]
    v0 = C["v_init"]
    S = {"Q": Q, "v0": v0, "vc": np.zeros(n), "vs": np.zeros(n), "relax": np.ones(n),
         "resid": np.full(n, np.inf)}
    if rot.bemt:
        S["v_r"] = np.repeat(v0[:, None], r.size, axis=1)
        S["v_prev"] = S["v_r"].copy()
        S["dT_prev"] = np.zeros_like(S["v_r"])
    iters = np.zeros(n, dtype=np.int64)
    done = np.zeros(n, dtype=bool)
    failure = np.array([""] * n, dtype=object)
    for _ in range(max_iter):
        if done.all():
            break
        # a converged sample leaves the iteration (``freeze=False``, the lock-step baseline of
        # benchmarks/rotor_throughput.py, iterates every sample until all have converged)
        act = np.flatnonzero(~done) if freeze else np.arange(n)
        idx = None if act.size == n else act
        s = S if idx is None else {k: v[act] for k, v in S.items()}
        c, o = rot.sub(idx)
        s, size, bad = rot.step(s, c, o)
        iters[act] += 1
        amp = np.max(np.abs(s["Q"]), axis=2)                     # (n_act, 3) per DOF
        big = np.max(amp, axis=1) > MAX_BLADE_MOTION
        diverged = bad | ~np.isfinite(size) | big
        if idx is None:
            S.update(s)   # new arrays: s may hold old ones of S (v_prev), never written into
        else:
            for k in S:
                S[k][act] = s[k]
        for j in np.flatnonzero(diverged):
            i = act[j]
            dof = ("flap", "lag", "pitch")[int(np.argmax(amp[j]))]
            why = ("the section flow became non-finite" if bad[j] or not np.isfinite(size[j])
                   else f"the blade {dof} exceeded 2 pi rad")
            if dof == "pitch" and not bad[j]:
                why += ": torsional divergence"
            failure[i] = f"iteration diverged after {iters[i]} iterations ({why})"
        done[act] |= diverged | (size < tol)
    for i in np.flatnonzero(~done):
        failure[i] = (f"periodic solution did not converge in {iters[i]} iterations "
                      f"(last step {S['resid'][i]:.2e})")
    return rot, S, iters, failure


def _solve(preset, airfoil, grid, columns, ov, n, n_harmonics, tol, max_iter, check_tol,
           freeze):
    rot, S, iters, failure = _iterate(preset, airfoil, grid, columns, ov, n, n_harmonics, tol,
                                      max_iter, freeze)
    C = rot.C
    K = rot.kvec.size
    Om = C["Om"]

    # Re-evaluate the equations and the loads at the returned state of every sample.
    live = np.flatnonzero(failure == "")
    out = {k: np.full(n, np.nan) for k in ("thrust", "torque", "eq", "stalled", "cd_min",
                                               "k_eff")}
    M_root = np.full((n, K), np.nan, dtype=complex)
    if live.size:
        idx = None if live.size == n else live
        s = S if idx is None else {k: v[live] for k, v in S.items()}
        c, o = rot.sub(idx)
        chk = rot.check(s, c, o)
        for k in out:
            out[k][live] = chk[k]
        M_root[live] = chk["M_root"]
        out["bad"] = np.zeros(n)
        out["bad"][live] = chk["bad"]
        judge(live, out, S["Q"][:, 2, 0].real, columns[0]["collective_deg"], Om, failure, check_tol)
    return HoverSolution.assemble(preset, grid, Om, C["rho"], S["Q"], S["v0"],
                                  {"thrust": out["thrust"], "torque": out["torque"],
                                   "eq": out["eq"], "stalled": out["stalled"]}, M_root,
                                  S["resid"], iters, failure)
