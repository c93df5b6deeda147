"""Validation metrics: the ASME V&V 20 comparison error and the area metric.

For each condition (e.g. a rotor height H/R) and response, :func:`validate` compares the model's
predictive samples with the measured repeats:

- the **comparison error** of ASME V&V 20-2009, E = S - D, with S the simulation's prediction
  (the mean of the predictive samples, or a given value) and D the mean of the repeats, and its
  **validation uncertainty** u_val = sqrt(u_num^2 + u_input^2 + u_D^2): u_num the numerical
  (discretization) uncertainty, u_input the standard deviation of the predictive samples (the
  propagated input uncertainty), u_D = sqrt(s^2 / n_repeats + u_systematic^2) the measurement's
  (s the repeats' sample standard deviation). On data the calibration used (``calibration``)
  the comparison is a consistency check of the fit, not a validation: S and D share the
  data's noise, cov(S, D) = u_input^2 (exact for a linear-Gaussian calibration, any prior),
  so u_val = sqrt(u_num^2 + u_D^2 - u_input^2), the residual's uncertainty, not the sum
  that counts the noise twice. Where u_D^2 - u_input^2 is below three Monte Carlo standard
  errors of u_input^2 (3 sqrt(2 / (n - 1)) u_input^2, n predictive samples) the fit
  interpolates the datum and the residual's uncertainty is not resolved: u_val and |E| / u_val
  are NaN there (not judged). The model error delta_model lies in
  E +- k u_val; k = 2 by default (about 95 % coverage for a normal error; 1.96 is the exact
  normal 95 % factor, give ``coverage_factor=1.96`` for it). |E| / u_val says whether the model
  error is resolved (> k) or hidden in the uncertainty (< k).
- the **area metric** of Ferson, Oberkampf and Ginzburg (2008, Comput. Methods Appl. Mech. Engrg.
  197, 2408-2430): the area between the predictive CDF (the samples' empirical CDF) and the
  empirical CDF of the data, in the response's units. It equals the Wasserstein-1 distance of
  the two empirical distributions and, unlike "within k sigma", does not shrink as the
  predictive spread grows. With one measurement per condition it cannot judge a prediction at
  one condition (one data row: it is the prediction's mean absolute distance to that value,
  which favours a narrow prediction off the mark over a wide one around it);
  :func:`pooled_area_metric` pools the conditions instead (u-pooling, Ferson et al. 2008,
  sec. 5.2): each measurement's probability integral transform u = F_c(D) under its own
  condition's prediction, and the area between the empirical CDF of the u's and the uniform
  CDF (0 for predictions whose u's are uniform, at most 0.5).
- the reference study's own criterion beside them: the distance |S - D| in predictive standard
  deviations, and whether it is within ``n_sigma`` of them.

>>> import numpy as np
>>> import rotoruq as rq
>>> pred = [np.array([[9.0], [10.0], [11.0]])]          # 1 condition, 3 samples, 1 response
>>> data = [np.array([[10.5], [11.5]])]                 # its 2 repeats
>>> res = rq.validate(pred, data, u_num=0.1, u_systematic=0.2, names_out=["thrust"])
>>> float(res.comparison_error[0, 0])
-1.0
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..errors import ParameterError

__all__ = ["ComparisonArrays", "ValidationResult", "ComparisonError", "validate",
           "comparison_error", "area_metric", "PooledAreaMetric", "pooled_area_metric"]


@dataclass(frozen=True, eq=False)
class ComparisonError:
    """ASME V&V 20 comparison error and its validation uncertainty (arrays of one shape).

    Attributes
    ----------
    comparison_error : E = S - D, response units.
    u_val : validation uncertainty sqrt(u_num^2 + u_input^2 + u_data^2).
    coverage_factor : k of the interval E +- k u_val.
    lower, upper : E - k u_val, E + k u_val: the interval holding the model error.
    error_ratio : |E| / u_val (inf where u_val = 0 and E != 0).
    calibration : True where D was the calibration's data (a consistency check; u_val =
        sqrt(u_num^2 + max(u_data^2 - u_input^2, 0))).
    """

    comparison_error: np.ndarray
    u_val: np.ndarray
    coverage_factor: float
    lower: np.ndarray
    upper: np.ndarray
    error_ratio: np.ndarray
    calibration: np.ndarray


@dataclass(frozen=True, eq=False)
class ComparisonArrays:
    """The ASME V&V 20 comparison of a prediction with data: the fields a
    :class:`ValidationResult` (arrays (n_conditions, n_responses)) and the validation step's
    record (arrays (n_predictions, n_conditions, n_responses)) share.

    Attributes
    ----------
    simulation, data_mean, comparison_error : ndarray
        S, D and E = S - D (response units).
    u_num, u_input, u_data, u_val : ndarray
        The uncertainty budget (response units), as in :class:`ValidationResult`.
    """

    simulation: np.ndarray
    data_mean: np.ndarray
    comparison_error: np.ndarray
    u_num: np.ndarray
    u_input: np.ndarray
    u_data: np.ndarray
    u_val: np.ndarray


@dataclass(frozen=True, eq=False)
class ValidationResult(ComparisonArrays):
    """Validation metrics per condition and response; every array is (n_conditions, n_responses).

    Attributes
    ----------
    names_out : response names (columns).
    conditions : condition labels (rows), e.g. heights H/R.
    simulation : S, the prediction (mean of the predictive samples unless given).
    data_mean : D, the mean of the repeats.
    comparison_error : E = S - D.
    u_num, u_input, u_data, u_val : the uncertainty budget (response units); u_input is the
        predictive samples' standard deviation (ddof = 1), u_data = sqrt(s^2/n + u_sys^2).
    calibration : bool, True where the data were the calibration's (a consistency check,
        u_val = sqrt(u_num^2 + max(u_data^2 - u_input^2, 0)), NaN where the Monte Carlo
        error of u_input does not resolve it, see the module).
    coverage_factor : k.
    lower, upper : E -+ k u_val.
    error_ratio : |E| / u_val.
    area_metric : area between the predictive and the data's empirical CDFs (response units).
    relative_area_metric : area_metric / |D|.
    predictive_std : standard deviation of the predictive samples (= u_input).
    sigma_distance : |S - D| / predictive_std, the reference study's measure.
    n_sigma : its threshold.
    within_n_sigma : sigma_distance <= n_sigma (bool).
    n_samples, n_repeats : (n_conditions,) predictive samples and data repeats per condition.
    """

    names_out: tuple[str, ...]
    conditions: tuple
    coverage_factor: float
    lower: np.ndarray
    upper: np.ndarray
    error_ratio: np.ndarray
    area_metric: np.ndarray
    relative_area_metric: np.ndarray
    predictive_std: np.ndarray
    sigma_distance: np.ndarray
    n_sigma: float
    within_n_sigma: np.ndarray
    n_samples: np.ndarray
    n_repeats: np.ndarray
    calibration: np.ndarray


def _nonnegative(name: str, value: npt.ArrayLike) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    if np.isnan(a).any():
        raise ParameterError(f"{name} must be a number >= 0, got NaN")
    if (a < 0).any():
        raise ParameterError(f"{name} must be >= 0 (a standard uncertainty), got {a.min():g}")
    return a


def comparison_error(
    simulation: npt.ArrayLike,
    data_mean: npt.ArrayLike,
    *,
    u_num: npt.ArrayLike = 0.0,
    u_input: npt.ArrayLike = 0.0,
    u_data: npt.ArrayLike = 0.0,
    coverage_factor: float = 2.0,
    calibration: npt.ArrayLike = False,
) -> ComparisonError:
    """ASME V&V 20 comparison error E = S - D with its validation uncertainty.

    Parameters
    ----------
    simulation, data_mean : array_like
        S and D, broadcast together (response units).
    u_num, u_input, u_data : array_like, >= 0
        Standard uncertainties of the numerical solution, of the propagated inputs and of the
        data (response units), broadcast with S and D.
    coverage_factor : float, > 0
        k of the interval E +- k u_val (2: about 95 % for a normal model error).
    calibration : array_like of bool
        True where D is data the calibration behind S used: u_input is then the part of
        the data's noise the fit took in and is subtracted, u_val = sqrt(u_num^2 +
        max(u_data^2 - u_input^2, 0)) (see the module).

    Returns
    -------
    ComparisonError

    Examples
    --------
    >>> ce = comparison_error(10.0, 12.0, u_num=0.3, u_input=0.4, u_data=1.2)
    >>> float(ce.comparison_error), float(ce.u_val)
    (-2.0, 1.3)
    >>> float(comparison_error(10.0, 12.0, u_input=0.6, u_data=1.0, calibration=True).u_val)
    0.8
    """
    k = float(coverage_factor)
    if not np.isfinite(k) or k <= 0:
        raise ParameterError(f"coverage_factor must be a finite number > 0, got {coverage_factor}")
    s, d = np.asarray(simulation, dtype=float), np.asarray(data_mean, dtype=float)
    un, ui, ud = (_nonnegative(n, v) for n, v in
                  (("u_num", u_num), ("u_input", u_input), ("u_data", u_data)))
    cal = np.asarray(calibration, dtype=bool)
    try:
        s, d, un, ui, ud, cal = np.broadcast_arrays(s, d, un, ui, ud, cal)
    except ValueError:
        raise ParameterError(
            f"simulation {s.shape}, data_mean {d.shape}, u_num {un.shape}, u_input {ui.shape}, "
            f"u_data {ud.shape} and calibration {cal.shape} must broadcast to one shape"
        ) from None
    e = s - d
    # a fit's residual: S took in part of D's noise (cov(S, D) = u_input^2), so it is
    # subtracted rather than added; a nonlinear fit may pass 0, hence the floor
    u_val = np.sqrt(un**2 + np.where(cal, np.maximum(ud**2 - ui**2, 0.0), ui**2 + ud**2))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(u_val > 0, np.abs(e) / np.where(u_val > 0, u_val, 1.0),
                         np.where(e == 0, 0.0, np.inf))
    return ComparisonError(comparison_error=e, u_val=u_val, coverage_factor=k,
                           lower=e - k * u_val, upper=e + k * u_val, error_ratio=ratio,
                           calibration=cal.copy())


def area_metric(samples: npt.ArrayLike, data: npt.ArrayLike) -> float:
    """Area between the empirical CDFs of the predictive samples and of the data.

    The area metric of Ferson, Oberkampf and Ginzburg (2008): integral over y of
    |F_S(y) - F_D(y)|, both step functions, computed exactly (it is the Wasserstein-1 distance
    of the two empirical distributions).

    Parameters
    ----------
    samples : array_like, (n_samples,)
        Predictive samples of one response at one condition (response units).
    data : array_like, (n_repeats,)
        The measured repeats (one value is a single step).

    Returns
    -------
    float
        The area, in the response's units.

    Examples
    --------
    >>> area_metric([0.0, 1.0, 2.0, 3.0], [1.5])
    1.0
    """
    a = np.sort(np.asarray(samples, dtype=float).ravel())
    b = np.sort(np.asarray(data, dtype=float).ravel())
    for name, v in (("samples", a), ("data", b)):
        if v.size == 0:
            raise ParameterError(f"area_metric needs at least one value in {name}")
        if not np.isfinite(v).all():
            raise ParameterError(f"area_metric: {name} contains non-finite values")
    y = np.concatenate([a, b])
    y.sort(kind="mergesort")
    dy = np.diff(y)
    fa = np.searchsorted(a, y[:-1], side="right") / a.size
    fb = np.searchsorted(b, y[:-1], side="right") / b.size
    return float(np.sum(np.abs(fa - fb) * dy))


def _per_condition(name: str, values, n_responses: int | None) -> list[np.ndarray]:
    if isinstance(values, np.ndarray) and values.ndim == 3:
        values = list(values)
    elif isinstance(values, np.ndarray) and values.ndim == 2 and name == "data":
        values = [row[None, :] for row in values]  # one repeat per condition
    elif isinstance(values, np.ndarray):
        raise ParameterError(
            f"{name} as an array must be 3-D (n_conditions, n, n_responses)"
            + (" or 2-D (n_conditions, n_responses)" if name == "data" else "")
            + f", got shape {values.shape}; or give a list with one (n, n_responses) array "
            "per condition")
    if not isinstance(values, (Sequence, np.ndarray)) or len(values) == 0:
        raise ParameterError(f"{name} must be a sequence with one (n, n_responses) array per "
                             "condition")
    out = []
    for c, v in enumerate(values):
        a = np.asarray(v, dtype=float)
        if a.ndim == 1:
            a = a[:, None] if n_responses in (None, 1) else a[None, :]
        if a.ndim != 2 or a.shape[0] == 0:
            raise ParameterError(f"{name}[{c}] must be an (n, n_responses) array with n >= 1, "
                                 f"got shape {np.shape(v)}")
        if n_responses is not None and a.shape[1] != n_responses:
            raise ParameterError(f"{name}[{c}] has {a.shape[1]} responses, expected "
                                 f"{n_responses}")
        if not np.isfinite(a).all():
            raise ParameterError(f"{name}[{c}] contains non-finite values (drop failed "
                                 "evaluations or missing measurements before validating)")
        n_responses = a.shape[1]
        out.append(a)
    return out


def _table(name: str, value, shape: tuple[int, int]) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    try:
        return np.array(np.broadcast_to(a, shape))
    except ValueError:
        raise ParameterError(f"{name} of shape {a.shape} does not broadcast to (n_conditions, "
                             f"n_responses) = {shape}") from None


def validate(
    predictive: Sequence[npt.ArrayLike] | np.ndarray,
    data: Sequence[npt.ArrayLike] | np.ndarray,
    *,
    u_num: npt.ArrayLike = 0.0,
    u_systematic: npt.ArrayLike | None = None,
    simulation: npt.ArrayLike | None = None,
    names_out: Sequence[str] | None = None,
    conditions: Sequence | None = None,
    coverage_factor: float = 2.0,
    n_sigma: float = 1.0,
    calibration: npt.ArrayLike = False,
) -> ValidationResult:
    """V&V 20 comparison error, area metric and the "within n sigma" criterion per condition.

    Parameters
    ----------
    predictive : sequence of array_like, one (n_samples_c, n_responses) per condition
        The model's predictive samples at each condition (e.g. from the posterior predictive);
        a 3-D array (n_conditions, n_samples, n_responses) is accepted.
    data : sequence of array_like, one (n_repeats_c, n_responses) per condition
        The measured repeats at each condition; a 2-D array (n_conditions, n_responses) is one
        repeat per condition.
    u_num : array_like, >= 0
        Numerical (discretization) standard uncertainty: scalar, (n_responses,) or
        (n_conditions, n_responses) (e.g. ``VerificationResult.u_num``).
    u_systematic : array_like, >= 0, optional
        The systematic part of the measurement's standard uncertainty, same broadcasting. With a
        single repeat it must be given and stands for the whole measurement uncertainty (the
        random part cannot be estimated from one value).
    simulation : array_like (n_conditions, n_responses), optional
        S when it is not the mean of the predictive samples (e.g. the nominal model's output).
    names_out : sequence of str, optional
        Response names (default ``y0, y1, ...``).
    conditions : sequence, optional
        A label per condition (default 0, 1, ...).
    coverage_factor : float
        k of E +- k u_val (default 2; 1.96 is the normal 95 % factor).
    n_sigma : float
        Threshold of the reference study's criterion |S - D| <= n_sigma * predictive std.
    calibration : array_like of bool
        True where the data are the calibration's own (scalar, (n_responses,) or
        (n_conditions, n_responses)): a consistency check with the fit's residual
        uncertainty (see :func:`comparison_error`), not a validation.

    Returns
    -------
    ValidationResult

    Raises
    ------
    ParameterError
        Mismatched shapes, negative uncertainties, or data with a single repeat and no
        ``u_systematic``.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> pred = [rng.normal(100.0, 2.0, (500, 1)), rng.normal(120.0, 2.0, (500, 1))]
    >>> data = [np.array([[101.0], [99.0]]), np.array([[135.0], [137.0]])]
    >>> res = validate(pred, data, u_num=0.5, u_systematic=1.0, conditions=[4.0, 1.0])
    >>> res.error_ratio.shape
    (2, 1)
    """
    pred = _per_condition("predictive", predictive, None)
    n_resp = pred[0].shape[1]
    obs = _per_condition("data", data, n_resp)
    n_cond = len(pred)
    if len(obs) != n_cond:
        raise ParameterError(f"predictive has {n_cond} conditions but data has {len(obs)}")
    names = (tuple(f"y{j}" for j in range(n_resp)) if names_out is None
             else tuple(str(n) for n in names_out))
    if len(names) != n_resp:
        raise ParameterError(f"names_out has {len(names)} names for {n_resp} responses")
    labels = tuple(range(n_cond)) if conditions is None else tuple(conditions)
    if len(labels) != n_cond:
        raise ParameterError(f"conditions has {len(labels)} labels for {n_cond} conditions")
    if not np.isfinite(n_sigma) or n_sigma <= 0:
        raise ParameterError(f"n_sigma must be a finite number > 0, got {n_sigma}")
    shape = (n_cond, n_resp)
    un = _table("u_num", _nonnegative("u_num", u_num), shape)
    n_samples = np.array([p.shape[0] for p in pred])
    n_repeats = np.array([d.shape[0] for d in obs])
    if u_systematic is None:
        single = [labels[c] for c in range(n_cond) if n_repeats[c] < 2]
        if single:
            raise ParameterError(
                f"data at conditions {single} has a single repeat and no measurement "
                "uncertainty is stated: give u_systematic (the measurement's standard "
                "uncertainty) or at least two repeats")
        usys = np.zeros(shape)
    else:
        usys = _table("u_systematic", _nonnegative("u_systematic", u_systematic), shape)
    if np.any(n_samples < 2):
        raise ParameterError("predictive needs at least two samples per condition for u_input")
    s_pred = np.array([p.mean(axis=0) for p in pred])
    std_pred = np.array([p.std(axis=0, ddof=1) for p in pred])
    d_mean = np.array([d.mean(axis=0) for d in obs])
    s_rep = np.array([d.std(axis=0, ddof=1) if d.shape[0] > 1 else np.zeros(n_resp)
                      for d in obs])
    u_data = np.sqrt(s_rep**2 / n_repeats[:, None] + usys**2)
    if simulation is not None:
        s = np.asarray(simulation, dtype=float)
        if s.shape != shape:
            raise ParameterError(f"simulation must have shape {shape}, got {s.shape}")
        s_pred = s
    cal = _table("calibration", np.asarray(calibration, dtype=float), shape) > 0
    ce = comparison_error(s_pred, d_mean, u_num=un, u_input=std_pred, u_data=u_data,
                          coverage_factor=coverage_factor, calibration=cal)
    # a fit's residual variance u_D^2 - u_input^2 within Monte Carlo error of u_input^2: the
    # subtraction does not resolve it (the fit interpolates the datum), so it is not judged
    mc = 3.0 * np.sqrt(2.0 / (n_samples[:, None] - 1.0)) * std_pred**2
    unresolved = cal & (u_data**2 - std_pred**2 < mc)
    if unresolved.any():
        nan = np.where(unresolved, np.nan, 1.0)
        ce = ComparisonError(
            comparison_error=ce.comparison_error, u_val=ce.u_val * nan,
            coverage_factor=ce.coverage_factor, lower=ce.lower * nan, upper=ce.upper * nan,
            error_ratio=ce.error_ratio * nan, calibration=ce.calibration)
    area = np.array([[area_metric(pred[c][:, j], obs[c][:, j]) for j in range(n_resp)]
                     for c in range(n_cond)])
    with np.errstate(divide="ignore", invalid="ignore"):
        rel_area = np.where(d_mean != 0, area / np.abs(np.where(d_mean != 0, d_mean, 1.0)),
                            np.inf)
        dist = np.abs(ce.comparison_error)
        sigma = np.where(std_pred > 0, dist / np.where(std_pred > 0, std_pred, 1.0),
                         np.where(dist == 0, 0.0, np.inf))
    return ValidationResult(
        names_out=names, conditions=labels, simulation=s_pred, data_mean=d_mean,
        comparison_error=ce.comparison_error, u_num=un, u_input=std_pred, u_data=u_data,
        u_val=ce.u_val, coverage_factor=ce.coverage_factor, lower=ce.lower, upper=ce.upper,
        error_ratio=ce.error_ratio, area_metric=area, relative_area_metric=rel_area,
        predictive_std=std_pred, sigma_distance=sigma, n_sigma=float(n_sigma),
        within_n_sigma=sigma <= n_sigma, n_samples=n_samples, n_repeats=n_repeats,
        calibration=cal)


@dataclass(frozen=True, eq=False)
class PooledAreaMetric:
    """The area metric pooled over conditions by the probability integral transform
    (:func:`pooled_area_metric`).

    Attributes
    ----------
    u : ndarray of shape (k, m)
        u = F_c(D) of each of the k measurements (rows of every condition, in order) under
        its own condition's predictive CDF, per response; in [0, 1].
    area : ndarray of shape (m,)
        Area between the empirical CDF of u and the standard uniform CDF, per response
        (dimensionless, 0 to 0.5; 1 / (4 k) for u's at the uniform's k quantiles).
    n_measurements : int
        k, the measurements pooled.
    n_conditions : int
        The conditions they come from.
    """

    u: np.ndarray
    area: np.ndarray
    n_measurements: int
    n_conditions: int


def _uniform_area(u: np.ndarray) -> float:
    """Exact area between the empirical CDF of ``u`` (values in [0, 1]) and the uniform CDF:
    on each interval between order statistics the empirical CDF is k / n, and
    ``int_a^b |t - c| dt = (sgn(b - c) (b - c)^2 - sgn(a - c) (a - c)^2) / 2``."""
    n = u.size
    edges = np.concatenate([[0.0], np.sort(u), [1.0]])
    a, b, c = edges[:-1], edges[1:], np.arange(n + 1) / n
    return float(np.sum(np.sign(b - c) * (b - c) ** 2 - np.sign(a - c) * (a - c) ** 2) / 2)


def pooled_area_metric(predictive: Sequence[npt.ArrayLike] | np.ndarray,
                       data: Sequence[npt.ArrayLike] | np.ndarray) -> PooledAreaMetric:
    """The area metric pooled over conditions (u-pooling, Ferson, Oberkampf and Ginzburg
    2008, sec. 5.2), for predictions validated where each condition has one measurement (or
    a few).

    Each measurement D at condition c becomes u = F_c(D), its prediction's empirical CDF there
    (ties count half: ``(#{s < D} + #{s = D} / 2) / n``). If the predictions are right, the u's
    of all conditions are draws of one standard uniform, whatever the conditions' units and
    spreads; the metric is the area between the empirical CDF of the u's and the uniform CDF.
    A prediction too narrow or off the mark pushes the u's to 0 or 1 (area up to 0.5), one too
    wide bunches them at 0.5. It judges a set of conditions; a single measurement gives
    ``u^2 / 2 + (1 - u)^2 / 2``, at least 0.25, which ranks nothing.

    Parameters
    ----------
    predictive : sequence of array_like, one (n_samples_c, n_responses) per condition
        The predictive samples at each condition (response units); a 3-D array
        (n_conditions, n_samples, n_responses) is accepted.
    data : sequence of array_like, one (n_repeats_c, n_responses) per condition
        The measurements at each condition; a 2-D array (n_conditions, n_responses) is one
        measurement per condition.

    Returns
    -------
    PooledAreaMetric
        The u of every measurement (k, m) and the pooled area per response (m,).

    Raises
    ------
    ParameterError
        Mismatched conditions or responses, empty or non-finite values.

    Examples
    --------
    >>> import numpy as np
    >>> q = (np.arange(1000) + 0.5) / 1000              # predictions: U(0, 1) at 3 conditions
    >>> pred = [q[:, None], 2 * q[:, None], 10 + q[:, None]]
    >>> res = pooled_area_metric(pred, np.array([[1 / 6], [1.0], [10 + 5 / 6]]))
    >>> [round(float(u), 3) for u in res.u[:, 0]], round(float(res.area[0]), 4)
    ([0.167, 0.5, 0.833], 0.0833)
    """
    pred = _per_condition("predictive", predictive, None)
    n_resp = pred[0].shape[1]
    obs = _per_condition("data", data, n_resp)
    if len(obs) != len(pred):
        raise ParameterError(f"predictive has {len(pred)} conditions but data has {len(obs)}")
    rows = []
    for p, d in zip(pred, obs, strict=True):
        s = np.sort(p, axis=0)
        u = np.empty(d.shape)
        for j in range(n_resp):
            below = np.searchsorted(s[:, j], d[:, j], side="left")
            upto = np.searchsorted(s[:, j], d[:, j], side="right")
            u[:, j] = (below + upto) / (2.0 * s.shape[0])
        rows.append(u)
    u_all = np.concatenate(rows)
    return PooledAreaMetric(u=u_all, area=np.array([_uniform_area(u_all[:, j])
                                                    for j in range(n_resp)]),
                            n_measurements=int(u_all.shape[0]), n_conditions=len(pred))
