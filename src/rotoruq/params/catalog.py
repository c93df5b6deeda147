"""Distributions by name: the ``distribution = "..."`` key of a study file and the ``kind`` of
:meth:`Distribution.describe`."""

from __future__ import annotations

import difflib
import inspect
from typing import Any

from ..errors import ParameterError
from . import distributions as dist
from .distributions import Distribution
from .interval import Interval

__all__ = ["DISTRIBUTIONS", "distribution_keys", "make_distribution"]

#: Distribution classes by their study-file name (``kind = "normal"``), Dakota's catalog.
DISTRIBUTIONS: dict[str, type[Distribution]] = {
    "normal": dist.Normal,
    "truncated_normal": dist.TruncatedNormal,
    "lognormal": dist.LogNormal,
    "uniform": dist.Uniform,
    "loguniform": dist.LogUniform,
    "beta": dist.Beta,
    "gamma": dist.Gamma,
    "exponential": dist.Exponential,
    "gumbel": dist.Gumbel,
    "weibull": dist.Weibull,
    "triangular": dist.Triangular,
    "frechet": dist.Frechet,
    "histogram_bin": dist.HistogramBin,
    "interval": Interval,
}


def _key(kind: str) -> str:
    return kind.strip().lower().replace("-", "_").replace(" ", "_")


def distribution_keys(kind: str) -> tuple[str, ...]:
    """The parameter keys of a distribution in study files and :meth:`Distribution.describe`
    (its fields, ``lambda_`` spelled ``lambda``), for a key of :data:`DISTRIBUTIONS`.

    Parameters
    ----------
    kind : str
        The distribution's name, a key of :data:`DISTRIBUTIONS`.

    Examples
    --------
    >>> distribution_keys("lognormal")
    ('mean', 'std', 'lambda', 'zeta', 'error_factor', 'lower', 'upper')
    """
    cls = DISTRIBUTIONS[_key(kind)]
    return tuple(n.rstrip("_") for n in inspect.signature(cls).parameters)


def make_distribution(kind: str, **params: Any) -> Distribution:
    """Build a distribution from its name (a key of :data:`DISTRIBUTIONS`) and its parameters
    under their study-file names (:func:`distribution_keys`: ``mean``, ``std``, ``lower``,
    ``upper``, ``mode``, ``alpha``, ``beta``, ``lambda``, ``zeta``, ``error_factor``,
    ``abscissas``, ``counts``, ``ordinates``, ``intervals``, ``bpa``; ``lambda_`` is accepted
    for ``lambda``).

    An unknown kind or parameter raises :class:`~rotoruq.errors.ParameterError` naming the
    valid ones.

    Parameters
    ----------
    kind : str
        The distribution's name, a key of :data:`DISTRIBUTIONS` (case, ``-`` and spaces
        ignored: ``"Truncated Normal"`` is ``truncated_normal``).
    **params
        Its defining parameters, by their study-file names.

    Examples
    --------
    >>> d = make_distribution("normal", mean=10.0, std=2.0)
    >>> float(d.mean), float(d.std)
    (10.0, 2.0)
    >>> u = make_distribution("uniform", lower=0.0, upper=3.0)
    >>> make_distribution(**u.describe()).describe()         # describe() rebuilds it
    {'kind': 'uniform', 'lower': 0.0, 'upper': 3.0}
    """
    key = _key(kind)
    if key not in DISTRIBUTIONS:
        close = difflib.get_close_matches(key, DISTRIBUTIONS, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ParameterError(
            f"unknown distribution {kind!r}{hint}; valid: {', '.join(sorted(DISTRIBUTIONS))}"
        )
    cls = DISTRIBUTIONS[key]
    params = {("lambda_" if k == "lambda" else k): v for k, v in params.items()}
    try:
        return cls(**params)
    except TypeError as exc:
        names = distribution_keys(key)
        raise ParameterError(
            f"distribution {kind!r} takes {', '.join(names)}; got "
            f"{', '.join(k.rstrip('_') for k in params)}"
        ) from exc
