"""Hub loads from MBDyn's rotor output (``<prefix>.rot``).

MBDyn's rotor induced-velocity element writes, per time step, its label, the aerodynamic force
on the rotor node (columns 2-4) and the moment about it (5-7) in the airframe frame, the mean
inflow (8), ..., the convergence flag of its induced-velocity iteration (15) and its iteration
count (16). rotoruq's MBDyn templates use an airframe frame x aft, y starboard, z up, with the
rotor turning counter-clockwise seen from above, so README's conventions are

- ``thrust`` = F_z [N];
- ``torque`` = -M_z [N m] (positive = power absorbed; MBDyn's aerodynamic moment about +z is
  the reaction torque, negative);
- ``roll`` = -M_x [N m] (right side down: x points aft), ``pitch`` = M_y [N m] (nose up);
- ``power`` = torque * Omega [W], ``ct`` = T / (rho A V_tip^2), ``cq`` = Q / (rho A R V_tip^2).

Templates that also write the reaction of the airframe-hub joint (``output, yes`` on it: the
``elastic`` template) get their loads from that joint instead: minus its reaction is the load
the rotor puts on the airframe, blade inertia included, what a balance under the hub
measures; with cyclic flapping the mean roll and pitch differ from the aerodynamic moments.

Loads are averaged over the last ``average`` revolutions; the run must have reached its final
step and be periodic: the mean thrust and torque over the last ``average`` revolutions must
differ from those over the ``average`` revolutions before by less than ``tolerance`` (relative),
and must not alternate from one time step to the next (a numerical limit cycle of the
inflow update, whose mean is not the steady state).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .solver import MBDynError

__all__ = ["HubLoads", "read_rotor_output", "read_joint_output", "hub_loads", "RESPONSES"]

#: Responses the extractor provides (README names and units).
RESPONSES = ("thrust", "torque", "roll", "pitch", "power", "ct", "cq")


@dataclass(frozen=True, eq=False)
class HubLoads:
    """Mean hub loads of one MBDyn run (README sign conventions, SI units).

    Attributes
    ----------
    thrust : float
        N.
    torque, roll, pitch : float
        N m.
    power : float
        W.
    ct, cq : float
        Thrust and torque coefficients.
    inflow : float
        MBDyn's mean momentum inflow, m/s.
    periodicity : float
        Relative change of the mean thrust/torque between the last two averaging windows.
    steps : int
        Rows read from the file.
    """

    thrust: float
    torque: float
    roll: float
    pitch: float
    power: float
    ct: float
    cq: float
    inflow: float
    periodicity: float
    steps: int

    def response(self, name: str) -> float:
        """The mean load ``name``, one of :data:`RESPONSES`.

        Parameters
        ----------
        name : str
            A response name (``"thrust"``, ...); another raises :class:`MBDynError`.
        """
        if name not in RESPONSES:
            raise MBDynError(f"unknown MBDyn response {name!r}; available: {', '.join(RESPONSES)}")
        return float(getattr(self, name))


def _read_table(path: Path, what: str, min_cols: int, missing: str) -> np.ndarray:
    if not path.is_file():
        raise MBDynError(f"MBDyn wrote no {what}: {path} does not exist ({missing})")
    rows = []
    with path.open() as f:
        for lineno, line in enumerate(f, 1):
            if not line.strip():
                continue
            try:
                rows.append([float(v) for v in line.split()])
            except ValueError:
                raise MBDynError(f"{path}, line {lineno}: expected numbers in MBDyn's {what}, "
                                 f"found {line.strip()[:80]!r}") from None
            if len(rows[-1]) < min_cols or len(rows[-1]) != len(rows[0]):
                raise MBDynError(f"{path}, line {lineno}: expected {max(min_cols, len(rows[0]))} "
                                 f"columns of {what}, found {len(rows[-1])}")
    if not rows:
        raise MBDynError(f"MBDyn wrote an empty {what} file {path}")
    return np.asarray(rows)


def read_rotor_output(path: str | os.PathLike) -> np.ndarray:
    """Rows of a ``.rot`` file as an array (n_steps, n_columns); :class:`MBDynError` when the
    file is missing, empty or malformed.

    Parameters
    ----------
    path : str or PathLike
        The rotor output file (MBDyn's induced velocity element output).
    """
    return _read_table(Path(path), "rotor output", 16, "did the run start? does the model "
                       "enable output of its induced velocity element?")


def read_joint_output(path: str | os.PathLike) -> np.ndarray:
    """Rows of a ``.jnt`` file holding one joint: reaction force and moment in the joint's
    local frame (columns 2-7) and in the global frame (8-13)."""
    return _read_table(Path(path), "joint output", 13, "does the model enable output of its "
                       "airframe-hub joint?")


def hub_loads(path: str | os.PathLike, *, omega: float, rho: float, radius: float,
              steps_per_rev: int, revolutions: int, average: int = 2,
              tolerance: float = 2e-3, joint: str | os.PathLike | None = None) -> HubLoads:
    """Mean hub loads over the last ``average`` revolutions of a ``.rot`` file.

    Parameters
    ----------
    path : the ``.rot`` file.
    omega : rotor speed [rad/s], for the power and the coefficients.
    rho : air density [kg/m^3], for the coefficients.
    radius : rotor radius [m], for the coefficients.
    steps_per_rev : the run's time steps per revolution.
    revolutions : the run's simulated revolutions (the file must hold at least
        revolutions * steps_per_rev rows).
    average : revolutions averaged.
    tolerance : periodicity tolerance (relative).
    joint : optional ``.jnt`` file of the airframe-hub joint alone. Its reaction in the global
        frame (columns 8-13: the airframe's; the local one turns with the hub) is minus the
        load the rotor puts on the airframe, blade inertia included: what a balance under the
        hub measures. With it, the loads come from the joint (the aerodynamic ones of the
        ``.rot`` file differ when blades flap cyclically); the ``.rot`` file still gives the
        inflow and its convergence flag.
    """
    rows = read_rotor_output(path)
    if joint is not None:
        jrows = read_joint_output(joint)
        if jrows.shape[0] != rows.shape[0]:
            raise MBDynError(f"{joint} holds {jrows.shape[0]} time steps but {path} "
                             f"{rows.shape[0]}: expected the airframe-hub joint alone")
        rows = rows.copy()
        rows[:, 1:7] = -jrows[:, 7:13]
    n_avg = average * steps_per_rev
    if 2 * n_avg > revolutions * steps_per_rev:
        raise MBDynError(f"{revolutions} revolutions are too few to average the last {average} "
                         f"and check them against the {average} before")
    need = revolutions * steps_per_rev
    if rows.shape[0] < need:
        raise MBDynError(f"MBDyn stopped early: {path} holds {rows.shape[0]} time steps of "
                         f"{need} ({rows.shape[0] / steps_per_rev:.1f} of {revolutions} "
                         "revolutions); the run did not converge")
    if not np.all(np.isfinite(rows[-2 * n_avg:])):
        raise MBDynError(f"MBDyn's rotor loads in {path} are not finite (diverged)")
    last, before = rows[-n_avg:], rows[-2 * n_avg:-n_avg]
    m_last, m_before = last.mean(axis=0), before.mean(axis=0)
    # relative change of thrust and torque between the two windows
    scale = np.maximum(np.abs(m_last[[3, 6]]), 1e-12)
    periodicity = float(np.max(np.abs(m_last[[3, 6]] - m_before[[3, 6]]) / scale))
    if periodicity > tolerance:
        raise MBDynError(
            f"MBDyn's run in {path} did not reach a periodic steady state: mean thrust/torque "
            f"changed by {periodicity:.2%} between the last two {average}-revolution windows "
            f"(tolerance {tolerance:.2%}); simulate more revolutions")
    # A mean over a window can hide a numerical limit cycle: loads that flip between two
    # values every time step (an undamped quasi-steady inflow update) average to a wrong value.
    sign = np.where(np.arange(n_avg) % 2, -1.0, 1.0)
    alternating = float(np.max(np.abs(sign @ last[:, [3, 6]]) / n_avg / scale))
    if alternating > tolerance:
        raise MBDynError(
            f"MBDyn's loads in {path} alternate between time steps (amplitude {alternating:.2%} "
            "of the mean): a numerical oscillation, not a steady state; damp the inflow update "
            "(a larger 'delay' of the induced velocity element) or shorten the time step")
    if np.any(last[:, 14] == 0):
        raise MBDynError(f"MBDyn's induced velocity iteration did not converge in the last "
                         f"{average} revolutions ({path}, column 15)")
    thrust, torque = m_last[3], -m_last[6]
    area, vtip = math.pi * radius**2, omega * radius
    return HubLoads(
        thrust=float(thrust),
        torque=float(torque),
        roll=float(-m_last[4]),
        pitch=float(m_last[5]),
        power=float(torque * omega),
        ct=float(thrust / (rho * area * vtip**2)),
        cq=float(torque / (rho * area * vtip**2 * radius)),
        inflow=float(m_last[7]),
        periodicity=periodicity,
        steps=int(rows.shape[0]),
    )
