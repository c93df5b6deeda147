"""Periodic steady state of a hovering rotor, batched over samples.

One blade is solved over one revolution: in hover at constant speed every blade follows the
same periodic motion shifted by 2 pi / N_b, so hub loads follow from one blade's harmonics
(mean loads = N_b x the azimuth mean; hub roll/pitch = N_b / 2 x the first harmonic of the
blade-root flap moment). The blade motion is a Fourier series (harmonic balance) solved by a
Newton-like iteration whose Jacobian is the structural operator plus linear aerodynamic
flap damping and pitch-flap stiffness; the inflow is updated by Newton steps on momentum.
This is equivalent to time-marching to periodic steady state and averaging over the last two
revolutions, as the reference study did in MBDyn, without the transient.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from .controls import swashplate_harmonics
from .dynamics import HarmonicBasis, structural_operator
from .geometry import CANTILEVER_SPRING_FACTOR, BladeGrid
from .ground_effect import ground_effect_factor
from .inflow import A0, annulus_update, prandtl_loss, uniform_update
from .presets import RotorPreset

__all__ = ["HoverSolution", "solve_hover"]


@dataclass(frozen=True)
class HoverSolution:
    """Loads and state of a batch of hover solutions (every array has leading axis n).

    thrust [N], torque [N m] (positive = power absorbed), roll, pitch [N m] (hub moments in
    the non-rotating frame: roll positive right side down, pitch positive nose up),
    power [W], ct, cq [-]; coning_deg, theta_75_deg (mean blade pitch at 0.75 R, after the
    pitch-link deflection), inflow_ratio (mean lambda); flap/lag/pitch harmonics (n, K) in rad;
    iterations (int), residual (n,), converged (n,) bool.
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
    converged: np.ndarray
    iterations: int

    def response(self, name: str) -> np.ndarray:
        return getattr(self, name)

    @staticmethod
    def concatenate(parts: list[HoverSolution]) -> HoverSolution:
        """Join solutions of consecutive chunks along the sample axis."""
        if len(parts) == 1:
            return parts[0]
        kw = {f.name: np.concatenate([getattr(p, f.name) for p in parts])
              for f in fields(HoverSolution) if f.name != "iterations"}
        return HoverSolution(iterations=max(p.iterations for p in parts), **kw)


def _col(p, name, n):
    return np.broadcast_to(np.asarray(p[name], dtype=float), (n,))


def solve_hover(
    preset: RotorPreset,
    airfoil,
    grid: BladeGrid,
    params: dict[str, np.ndarray],
    overrides: dict[str, np.ndarray] | None = None,
    n_harmonics: int = 2,
    tol: float = 1e-9,
    max_iter: int = 80,
) -> HoverSolution:
    """Solve the periodic hover state for n samples.

    params : every entry of :data:`rotoruq.rotor.model.ROTOR_INPUTS`, arrays of shape (n,)
        (angles in deg). overrides : airfoil coefficient overrides, arrays (n,).
    """
    n = np.broadcast(*[np.asarray(v) for v in params.values()]).shape[0]
    P = {k: _col(params, k, n) for k in params}
    Nb, R, e, c = preset.n_blades, preset.radius, preset.hinge_offset, preset.chord
    r, w = grid.r, grid.w
    rr = r - e
    basis = HarmonicBasis(grid.psi, n_harmonics)
    kvec = basis.k
    K = kvec.size
    Om, rho = P["omega"], P["rho"]
    area = preset.area
    kappa = ground_effect_factor(P["height_over_radius"], preset.ground_effect)
    kappa = kappa * preset.induced_power_factor

    if preset.flap_model == "elastic":
        K_b = CANTILEVER_SPRING_FACTOR * P["ei_flap"] / grid.blade_length
    else:
        K_b = P["k_flap"]
    arm2 = preset.pitch_horn_arm**2
    K_p, C_p = P["k_pitch_link"] * arm2, P["c_pitch_link"] * arm2
    tan_d3 = np.tan(np.deg2rad(preset.delta3_deg))
    Z = structural_operator(kvec, Om, grid.I_flap, grid.S_flap, e, grid.I_lag,
                            preset.pitch_inertia, K_b, P["c_flap"], P["k_lag"], P["c_lag"],
                            K_p, C_p, tan_d3)
    # Jacobian: add linear aerodynamic flap damping and the flap moment's pitch derivative.
    wk = Om[:, None] * kvec[None, :]
    c_ab = 0.5 * rho * A0 * c * Om * np.sum(w * r * rr**2)
    k_abt = 0.5 * rho * A0 * c * Om**2 * np.sum(w * r**2 * rr)
    J = Z.copy()
    J[..., 0, 0] += 1j * wk * c_ab[:, None]
    J[..., 0, 2] -= k_abt[:, None]
    J[..., 1, 1] += 1j * wk * (0.5 * rho * c * Om * 0.02 * np.sum(w * r * rr**2))[:, None]
    Jinv = np.linalg.inv(J)
    # Linear-theory derivatives of the first harmonics of the blade's flap moment (Mf) and
    # thrust moment (Mz = sum r dFz) w.r.t. the inflow harmonic V1 and the blade motion.
    qa = 0.5 * rho * c * A0 * Om
    dMz_dV = -qa * np.sum(w * r**3) / R
    dMz_dB = -1j * qa * Om * np.sum(w * r**2 * rr)
    dMz_dT = qa * Om * np.sum(w * r**3)
    J1 = np.zeros((n, 4, 4), dtype=complex)
    J1[:, :3, :3] = J[:, 1]
    J1[:, 0, 3] = qa * np.sum(w * r * rr * r) / R

    theta_cmd = swashplate_harmonics(P["collective_deg"], P["lateral_deg"],
                                     P["longitudinal_deg"], n_harmonics)
    F_cmd = np.zeros((n, 3, K), dtype=complex)
    F_cmd[:, 2, :] = (K_p[:, None] + 1j * wk * C_p[:, None]) * theta_cmd

    # Initial state: pitch from the quasi-static pitch-link balance, no flap, hover inflow
    # of linear theory at 0.75 R.
    Q = np.zeros((n, 3, K), dtype=complex)
    Q[:, 2, :] = F_cmd[:, 2, :] / Z[:, :, 2, 2]
    sigma = preset.solidity
    th75 = theta_cmd[:, 0].real + np.deg2rad(preset.twist_deg) * (0.75 * R - preset.root_cutout) / (
        R - preset.root_cutout)
    lam = sigma * A0 / 16 * (np.sqrt(1 + 32 / (sigma * A0) * np.abs(th75) * 0.75) - 1)
    v0 = np.maximum(lam, 1e-3) * Om * R * np.sqrt(np.maximum(kappa, 0.1))
    bemt = preset.inflow == "bemt"
    v_r = np.repeat(v0[:, None], r.size, axis=1) if bemt else None
    vc = np.zeros(n)
    vs = np.zeros(n)
    cos_psi, sin_psi = np.cos(grid.psi), np.sin(grid.psi)
    a_sound = preset.speed_of_sound
    ov = overrides or {}
    resid = np.full(n, np.inf)
    relax = np.ones(n)
    converged = np.zeros(n, dtype=bool)
    it = 0

    def aero(Q, v_field):
        beta = basis.synth(Q[:, 0])                      # (n, Npsi)
        dbeta = basis.synth_d(Q[:, 0])
        dzeta = basis.synth_d(Q[:, 1])
        theta = basis.synth(Q[:, 2])
        UT = Om[:, None, None] * (r[None, None, :] - rr * dzeta[:, :, None])
        UP = v_field + Om[:, None, None] * rr * dbeta[:, :, None]
        phi = np.arctan2(UP, UT)
        alpha = np.rad2deg(theta[:, :, None] + grid.twist - phi)
        U2 = UT**2 + UP**2
        mach = np.sqrt(U2) / a_sound
        cl, cd, cm = airfoil.coefficients(alpha, mach, ov)
        qc = 0.5 * rho[:, None, None] * U2 * c
        cphi, sphi = np.cos(phi), np.sin(phi)
        dFz = qc * (cl * cphi - cd * sphi)
        dFx = qc * (cl * sphi + cd * cphi)
        cm_term = c * cm if preset.pitching_moment else 0.0
        dMp = qc * (cm_term - preset.aero_center_offset * cl)
        return beta, dFz, dFx, dMp

    def inflow_field(v_r, v0, vc, vs):
        base = v_r[:, None, :] if bemt else v0[:, None, None]
        harm = (r / R)[None, None, :] * (vc[:, None, None] * cos_psi[None, :, None]
                                          + vs[:, None, None] * sin_psi[None, :, None])
        return base + harm

    for it in range(1, max_iter + 1):  # noqa: B007
        vfield = inflow_field(v_r, v0, vc, vs)
        beta, dFz, dFx, dMp = aero(Q, vfield)
        Mf = np.einsum("npr,r->np", dFz, w * rr)
        Ml = np.einsum("npr,r->np", dFx, w * rr)
        Mp = np.einsum("npr,r->np", dMp, w)
        Fgen = np.stack([basis.analyse(Mf), basis.analyse(Ml), basis.analyse(Mp)], axis=1)
        R_dyn = Fgen + F_cmd - np.einsum("nkij,njk->nik", Z, Q)
        dQ = np.einsum("nkij,njk->nik", Jinv, R_dyn)
        if preset.harmonic_inflow:
            # First harmonic: blade motion and the Pitt-Peters inflow V1 = v_c - i v_s solved
            # together (their coupling is what makes a plain fixed point slow).
            Mz1 = basis.analyse(np.einsum("npr,r->np", dFz, w * r))[:, 1]
            lam0 = np.maximum(np.abs(v0) / (Om * R), 1e-4)
            G = 0.5 * Nb * kappa / (rho * area * Om * R**2 * lam0)
            V1 = vc - 1j * vs
            rhs = np.concatenate([R_dyn[:, :, 1], (G * Mz1 - V1)[:, None]], axis=1)
            J1[:, 3, 0] = -G * dMz_dB
            J1[:, 3, 2] = -G * dMz_dT
            J1[:, 3, 3] = 1.0 - G * dMz_dV
            d1 = np.linalg.solve(J1, rhs[..., None])[..., 0]
            dQ[:, :, 1] = d1[:, :3]
            V1 = V1 + relax * d1[:, 3]
            vc, vs = V1.real, -V1.imag
            dv1 = np.abs(d1[:, 3]) / (Om * R)
        else:
            dv1 = 0.0
        dQ *= relax[:, None, None]
        Q = Q + dQ
        # inflow
        if bemt:
            dT_r = Nb * np.mean(dFz * np.cos(beta)[:, :, None], axis=1)  # (n, Nr) per span
            F = (prandtl_loss(r[None, :], R, preset.root_cutout, Nb, v_r, Om[:, None])
                 if preset.tip_loss else 1.0)
            v_new = annulus_update(v_r, dT_r, rho[:, None], kappa[:, None], F, c, Nb,
                                   Om[:, None], r[None, :])
            v_new = v_r + relax[:, None] * (v_new - v_r)
            dv = np.max(np.abs(v_new - v_r), axis=1) / (Om * R)
            v_r = v_new
            v0 = np.sum(v_r * w * r, axis=1) / np.sum(w * r)
        else:
            T_be = Nb * np.einsum("npr,np,r->n", dFz, np.cos(beta), w) / grid.psi.size
            v_new = uniform_update(v0, T_be, rho, area, kappa, c, Nb, Om, r, w)
            v_new = v0 + relax * (v_new - v0)
            dv = np.abs(v_new - v0) / (Om * R)
            v0 = v_new
        dv = np.maximum(dv, dv1)
        new = np.maximum(np.max(np.abs(dQ), axis=(1, 2)), dv) / relax
        # Per-sample step control: halve the step of a sample whose update grew (stall and
        # strong aerodynamic pitching moments make the fixed point oscillate), regrow it when
        # the update shrinks again.
        relax = np.where(new > resid, np.maximum(0.5 * relax, 0.05),
                         np.minimum(1.5 * relax, 1.0))
        resid = new
        converged = resid < tol
        if np.all(converged | ~np.isfinite(resid)):
            break

    vfield = inflow_field(v_r, v0, vc, vs)
    beta, dFz, dFx, dMp = aero(Q, vfield)
    cosb = np.cos(beta)[:, :, None]
    thrust = Nb * np.einsum("npr,r->n", dFz * cosb, w) / grid.psi.size
    torque = Nb * np.einsum("npr,r->n", dFx, w * r) / grid.psi.size
    # Blade-root flap moment about the hub centre: hinge spring/damper + offset x hinge shear.
    Fz_k = basis.analyse(np.einsum("npr,r->np", dFz, w))
    B = Q[:, 0]
    M_root = (K_b[:, None] + 1j * wk * P["c_flap"][:, None]) * B + e * (
        Fz_k + grid.S_flap * wk**2 * B)
    roll = 0.5 * Nb * M_root[:, 1].imag
    pitch = -0.5 * Nb * M_root[:, 1].real
    vt = Om * R
    ct = thrust / (rho * area * vt**2)
    cq = torque / (rho * area * vt**2 * R)
    i75 = np.argmin(np.abs(r - 0.75 * R))
    return HoverSolution(
        thrust=thrust,
        torque=torque,
        roll=roll,
        pitch=pitch,
        power=torque * Om,
        ct=ct,
        cq=cq,
        coning_deg=np.rad2deg(Q[:, 0, 0].real),
        theta_75_deg=np.rad2deg(Q[:, 2, 0].real + grid.twist[i75]),
        inflow_ratio=v0 / vt,
        flap=Q[:, 0],
        lag=Q[:, 1],
        feather=Q[:, 2],
        residual=resid,
        converged=converged,
        iterations=it,
    )
