"""``estimator="auto"``: the multi-fidelity estimator with the smallest predicted variance.

Every candidate is allocated for the same budget on the same pilot covariance and the one
whose predicted variance of the target's mean is smallest wins: the named ACV estimators
(MFMC, ACV-MF, ACV-IS), the generalized ACV families searched over model subsets and
recursion indices (GMF, GRD, GIS; Bomarito, Leser, Warner, Aquino 2022, "On the optimization
of approximate control variates with parametrically defined estimators", J. Comput. Phys.
451, 110882), and MLBLUE (Schaden, Ullmann 2020) when only the mean is asked for (it
estimates no variance). On a tie the earlier of :data:`AUTO_CANDIDATES` wins (the simpler
structure). The choice is made on the pilot alone, so the estimators stay unbiased.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from .acv import Allocation, allocate
from .mlblue import mlblue_allocate

__all__ = ["AUTO_CANDIDATES", "EstimatorChoice", "choose_estimator"]

#: The estimators ``"auto"`` compares, in the order that breaks ties.
AUTO_CANDIDATES = ("mfmc", "acvmf", "acvis", "gmf", "gis", "grd", "mlblue")


@dataclass(frozen=True, eq=False)
class EstimatorChoice:
    """The estimator ``"auto"`` chose (see :func:`choose_estimator`).

    Attributes
    ----------
    estimator : str
        The chosen estimator's name.
    plan : Allocation
        Its allocation (a ``GroupAllocation`` for "mlblue").
    candidates : tuple of (str, float)
        Every candidate's name and predicted variance of the target's mean at the budget
        (units of the response squared), smallest first; inf for one the budget cannot buy.
    reason : str
        One line saying which was chosen and why, with the runners-up.
    """

    estimator: str
    plan: Allocation
    candidates: tuple[tuple[str, float], ...]
    reason: str


def choose_estimator(cov: np.ndarray, costs, budget: float, *,
                     statistics: Sequence[str] = ("mean",), select: bool = True
                     ) -> EstimatorChoice:
    """Allocate ``budget`` with every candidate and keep the smallest predicted variance.

    Parameters
    ----------
    cov : ndarray of shape (K, K)
        Covariance of the models' target response, model 0 the high-fidelity one.
    costs : array_like of shape (K,)
        Cost of one evaluation of each model.
    budget : float
        Cost of the main phase, in the units of ``costs``.
    statistics : sequence of str
        The statistics to estimate; with "variance" MLBLUE (mean only) is not a candidate.
    select : bool
        Let the ACV allocations leave out models (:func:`rotoruq.methods.acv.allocate`).

    Returns
    -------
    EstimatorChoice

    Raises
    ------
    ParameterError
        When no candidate can spend the budget (fewer than two high-fidelity runs).

    Examples
    --------
    >>> import numpy as np
    >>> cov = np.array([[1.0, 0.95], [0.95, 1.0]])
    >>> choice = choose_estimator(cov, [1.0, 0.01], 100.0)
    >>> choice.estimator, bool(choice.plan.variance < 1.0 / 100)
    ('mfmc', True)
    """
    names = [e for e in AUTO_CANDIDATES if e != "mlblue" or "variance" not in statistics]
    plans: dict[str, Allocation] = {}
    scores: list[tuple[str, float]] = []
    why_not: list[str] = []
    for e in names:
        try:
            plan = (mlblue_allocate(cov, costs, budget) if e == "mlblue"
                    else allocate(cov, costs, budget, estimator=e, select=select))
        except ParameterError as exc:
            scores.append((e, float("inf")))
            why_not.append(f"{e}: {exc}")
            continue
        plans[e] = plan
        scores.append((e, float(plan.variance)))
    finite = [s for s in scores if np.isfinite(s[1])]
    if not finite:
        raise ParameterError("estimator 'auto': no candidate can spend the budget: "
                             + "; ".join(why_not))
    best_v = min(v for _, v in finite)
    # the first of AUTO_CANDIDATES within rounding of the smallest: the simpler structure
    chosen = next(e for e, v in scores if v <= best_v * (1.0 + 1e-9))
    ranked = tuple(sorted(scores, key=lambda s: s[1]))
    plan = plans[chosen]
    rec = f", recursion {list(plan.recursion)}" if plan.recursion else ""
    others = ", ".join(f"{e} {v:.4g} ({v / best_v:.3g}x)" for e, v in ranked if e != chosen)
    reason = (f"estimator 'auto' chose {chosen} (models {list(plan.models)}{rec}): predicted "
              f"variance {best_v:.4g} of the target's mean at budget {budget:g}, the smallest "
              f"of {len(scores)} candidates; the others: {others}")
    return EstimatorChoice(estimator=chosen, plan=plan, candidates=ranked, reason=reason)
