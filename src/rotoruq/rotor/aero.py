"""An analytic airfoil for verification: linear lift, quadratic drag, no stall.

It has the same ``coefficients(alpha_deg, mach, overrides)`` interface as
:class:`rotoruq.rotor.airfoil.Airfoil`, so the rotor model can be checked against
closed-form blade-element/momentum results.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["LinearAirfoil"]


@dataclass(frozen=True)
class LinearAirfoil:
    """CL = cla * alpha + cl0, CD = cd0 + cda2 * alpha^2, CM = 0 (alpha in deg, no stall).

    Overrides ``cla``, ``cl0``, ``cd0`` take per-sample arrays of shape (n,).

    Parameters
    ----------
    cla : float, optional
        Lift slope, 1/deg (default 2 pi per radian, thin-airfoil theory).
    cl0 : float, optional
        Lift coefficient at zero angle of attack (default 0).
    cd0 : float, optional
        Drag coefficient at zero angle of attack (default 0.01).
    cda2 : float, optional
        Quadratic drag coefficient, 1/deg^2 (default 0).
    """

    cla: float = 2 * np.pi * np.pi / 180.0
    cl0: float = 0.0
    cd0: float = 0.01
    cda2: float = 0.0

    parameter_names = ("cla", "cl0", "cd0")

    def coefficients(self, alpha_deg, mach, overrides=None):
        """Lift, drag and moment coefficients ``(cl, cd, cm)``, each of the shape of
        ``alpha_deg``.

        Parameters
        ----------
        alpha_deg : array_like
            Angle of attack, deg, shaped as for :meth:`rotoruq.rotor.Airfoil.coefficients`.
        mach : array_like
            Mach number (not used: the linear airfoil has no compressibility).
        overrides : mapping of str to array_like, optional
            Per-sample values of ``cla``, ``cl0`` or ``cd0`` (scalars or shape (n,)) in place
            of the fields.
        """
        a = np.asarray(alpha_deg, dtype=float)
        ov = overrides or {}

        def get(name):
            v = np.asarray(ov.get(name, getattr(self, name)), dtype=float)
            return v.reshape(v.shape + (1,) * (a.ndim - v.ndim)) if v.ndim else v

        cl = get("cla") * a + get("cl0")
        cd = get("cd0") + self.cda2 * a**2
        return cl, cd + np.zeros_like(a), np.zeros_like(a)
