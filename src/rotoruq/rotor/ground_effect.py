"""Ground-effect factors on the induced velocity of a hovering rotor.

Each model returns kappa(z/R) = v_IGE / v_OGE at the same thrust (kappa <= 1 near the ground,
1 out of ground effect). ``z`` is the height of the hub above the ground.

- ``cheeseman_bennett`` (default): kappa = 1 - (R / 4z)^2 (Cheeseman & Bennett 1955; MBDyn's
  rotor ``ground`` option). Equivalent to T_IGE/T_OGE = 1 / (1 - (R/4z)^2) at constant power.
- ``hayden``: kappa = 1 / (0.9926 + 0.0379 (2R/z)^2), clamped to <= 1 (Hayden 1976, a fit of
  flight-test induced power ratios).
- ``fradenburgh``: kappa = T_OGE / T_IGE of Fradenburgh's measured thrust ratio at constant
  power (the digitized curve below), read the same way as Cheeseman-Bennett (kappa = 1 / thrust
  ratio); data from z/R = 0.5, so lower heights are failures for this model.
- ``none``: kappa = 1.

Heights at or below R/4 are outside every model's validity (Cheeseman-Bennett is singular at
R/4): they are reported as failures by the rotor model, never extrapolated.
"""

from __future__ import annotations

import numpy as np

from ..errors import ParameterError

__all__ = ["GROUND_EFFECT_MODELS", "ground_effect_factor", "fradenburgh_thrust_ratio",
           "MIN_HEIGHT_OVER_RADIUS", "min_height_over_radius"]

MIN_HEIGHT_OVER_RADIUS = 0.25

# Fradenburgh (1960) thrust ratio at constant power vs z/D, digitized from the commonly
# reproduced curve (e.g. Leishman, Principles of Helicopter Aerodynamics, fig. 5.x).
# Approximate (digitized), z/D from 0.25 to 2.
_FRADENBURGH_Z_OVER_D = np.array([0.25, 0.3, 0.4, 0.5, 0.6, 0.75, 1.0, 1.25, 1.5, 2.0])
_FRADENBURGH_RATIO = np.array([1.38, 1.30, 1.20, 1.13, 1.09, 1.05, 1.02, 1.01, 1.005, 1.0])


def fradenburgh_thrust_ratio(height_over_radius) -> np.ndarray:
    """Thrust ratio T_IGE / T_OGE at constant power from the digitized Fradenburgh curve.

    Linear in z/D between points, 1 beyond z/D = 2, NaN below z/D = 0.25 (z/R = 0.5).
    """
    h = np.asarray(height_over_radius, dtype=float)
    zd = h / 2.0
    return np.interp(zd, _FRADENBURGH_Z_OVER_D, _FRADENBURGH_RATIO, left=np.nan, right=1.0)


def _cheeseman_bennett(h):
    return 1.0 - (0.25 / h) ** 2


def _hayden(h):
    return np.minimum(1.0 / (0.9926 + 0.0379 * (2.0 / h) ** 2), 1.0)


def _fradenburgh(h):
    return 1.0 / fradenburgh_thrust_ratio(h)


def _none(h):
    return np.ones_like(h)


GROUND_EFFECT_MODELS = {
    "cheeseman_bennett": _cheeseman_bennett,
    "hayden": _hayden,
    "fradenburgh": _fradenburgh,
    "none": _none,
}
_MIN_HEIGHT = {"fradenburgh": 2.0 * _FRADENBURGH_Z_OVER_D[0]}


def _model(model: str):
    try:
        return GROUND_EFFECT_MODELS[model]
    except KeyError:
        raise ParameterError(
            f"unknown ground-effect model {model!r}; valid: {', '.join(GROUND_EFFECT_MODELS)}"
        ) from None


def min_height_over_radius(model: str = "cheeseman_bennett") -> float:
    """Lowest z/R the model accepts (exclusive at R/4 for every model)."""
    _model(model)
    return float(_MIN_HEIGHT.get(model, MIN_HEIGHT_OVER_RADIUS))


def ground_effect_factor(height_over_radius, model: str = "cheeseman_bennett") -> np.ndarray:
    """Induced-velocity factor kappa = v_IGE / v_OGE, same shape as ``height_over_radius``.

    ``inf`` means out of ground effect (kappa = 1). Heights at or below R/4, or below the
    model's data, give NaN.
    """
    f = _model(model)
    h = np.asarray(height_over_radius, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(np.isinf(h), 1.0, f(np.where(np.isinf(h), 1.0, h)))
    low = (h <= MIN_HEIGHT_OVER_RADIUS) | (h < min_height_over_radius(model))
    return np.where(low, np.nan, k)
