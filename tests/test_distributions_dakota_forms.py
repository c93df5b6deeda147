"""The Dakota forms of the distributions (lognormal's three parameterisations and bounds,
Frechet, histogram bins): definitions, exact moments by quadrature, describe() round trips
and the errors. Real Dakota checks the same numbers in tests/test_dakota_distributions.py."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, stats

import rotoruq as rq
from rotoruq.errors import ParameterError
from rotoruq.params import DISTRIBUTIONS, distribution_keys
from rotoruq.params.distributions import PHI_95

NEW = [
    rq.LogNormal(mean=2.0, std=0.5),
    rq.LogNormal(lambda_=0.3, zeta=0.8),
    rq.LogNormal(mean=2.0, error_factor=3.0),
    rq.LogNormal(2.0, 0.5, lower=1.5),
    rq.LogNormal(2.0, 0.5, upper=2.5),
    rq.LogNormal(lambda_=0.3, zeta=0.8, lower=0.5, upper=4.0),
    rq.Frechet(3.0, 2.0),
    rq.Frechet(alpha=7.5, beta=0.3),
    rq.HistogramBin([0.0, 1.0, 3.0, 3.5], [1.0, 3.0, 2.0, 0.0]),
    rq.HistogramBin([0.0, 1.0, 3.0, 3.5], ordinates=[1.0, 3.0, 2.0]),
    rq.HistogramBin([5.0, 8.0, 10.0], counts=[17, 21, 0]),
]


@pytest.mark.parametrize("dist", NEW, ids=repr)
def test_moments_pdf_and_cdf_agree_by_quadrature(dist):
    lo, hi = dist.bounds
    brk = list(getattr(dist, "abscissas", None) or [])
    pts = brk[1:-1] if brk else None

    def quad(f):
        if np.isfinite(hi):
            return integrate.quad(f, lo, hi, points=pts, limit=200, epsabs=1e-13)[0]
        return integrate.quad(f, lo, np.inf, limit=200, epsabs=1e-13)[0]

    assert quad(lambda x: float(dist.pdf(x))) == pytest.approx(1.0, abs=1e-9)
    m, s = dist.moments
    assert quad(lambda x: x * float(dist.pdf(x))) == pytest.approx(m, rel=1e-8)
    assert math.sqrt(quad(lambda x: (x - m) ** 2 * float(dist.pdf(x)))) == pytest.approx(
        s, rel=1e-7)
    # (a tail ending at a bound b != 0 resolves only to ~1e-16 b in x: q from 1e-6)
    q = np.array([1e-6, 1e-3, 0.1, 0.5, 0.9, 0.999])
    x = dist.ppf(q)
    np.testing.assert_allclose(dist.cdf(x), q, rtol=1e-9)
    np.testing.assert_allclose(dist.sf(dist.isf(q)), q, rtol=1e-9)
    # exp(logpdf) is the pdf; a draw has the moments
    xs = np.linspace(lo if np.isfinite(lo) else m - 3 * s, min(hi, m + 4 * s), 17)[1:-1]
    with np.errstate(divide="ignore"):
        np.testing.assert_allclose(np.exp(dist.logpdf(xs)), dist.pdf(xs), rtol=1e-12)
    r = dist.rvs(40000, seed=3)
    assert abs(r.mean() - m) < 5 * s / math.sqrt(r.size)
    assert np.all((r >= lo) & (r <= hi))


@pytest.mark.parametrize("dist", NEW, ids=repr)
def test_describe_round_trips_in_the_form_given(dist):
    d = dist.describe()
    again = rq.make_distribution(**d)
    assert again.describe() == d and again.moments == dist.moments
    assert set(d) - {"kind"} <= set(distribution_keys(d["kind"]))
    assert d["kind"] in DISTRIBUTIONS


def test_lognormal_three_forms_are_one_distribution():
    lam, zeta = 0.3, 0.8
    a = rq.LogNormal(lambda_=lam, zeta=zeta)
    mean = math.exp(lam + zeta**2 / 2)
    std = mean * math.sqrt(math.expm1(zeta**2))
    b = rq.LogNormal(mean, std)
    c = rq.LogNormal(mean=mean, error_factor=math.exp(PHI_95 * zeta))
    ref = stats.lognorm(s=zeta, scale=math.exp(lam))
    x = np.array([0.1, 1.0, 3.0, 20.0])
    for d in (a, b, c):
        np.testing.assert_allclose(d.cdf(x), ref.cdf(x), rtol=1e-12)
        np.testing.assert_allclose([d.mean, d.std, d.lambda_, d.zeta],
                                   [mean, std, lam, zeta], rtol=1e-12)
    # Dakota: the error factor is the ratio of the 95th percentile to the median
    assert float(c.ppf(0.95) / c.ppf(0.5)) == pytest.approx(c.error_factor, rel=1e-12)
    assert a.describe() == {"kind": "lognormal", "lambda": lam, "zeta": zeta}
    assert rq.make_distribution("lognormal", **{"lambda": lam, "zeta": zeta}) == a
    # the positional form and its description are unchanged (saved fingerprints)
    assert rq.LogNormal(2.0, 0.5).describe() == {"kind": "lognormal", "mean": 2.0, "std": 0.5}


def test_bounded_lognormal_is_the_truncated_parent():
    d = rq.LogNormal(2.0, 0.5, lower=1.5, upper=3.0)
    parent = rq.LogNormal(2.0, 0.5)
    x = np.array([1.0, 1.5, 2.0, 2.9, 3.0, 4.0])
    mass = float(parent.cdf(3.0) - parent.cdf(1.5))
    ref = np.clip((parent.cdf(x) - parent.cdf(1.5)) / mass, 0, 1)
    np.testing.assert_allclose(d.cdf(x), ref, rtol=1e-12, atol=1e-15)
    assert d.bounds == (1.5, 3.0) and (d.mean, d.std) == (2.0, 0.5)  # the parent's, as Dakota
    assert d.moments[0] != 2.0


def test_histogram_bin_is_dakotas_skyline():
    # Dakota's example: (5, 17), (8, 21), (10, 0): masses 17/38 and 21/38
    d = rq.HistogramBin([5.0, 8.0, 10.0], [17.0, 21.0, 0.0])
    assert float(d.cdf(8.0)) == pytest.approx(17 / 38, rel=1e-14)
    assert float(d.pdf(9.0)) == pytest.approx(21 / 38 / 2, rel=1e-14)
    # ordinates are densities: equal widths make them counts
    e = rq.HistogramBin([0.0, 1.0, 2.0], ordinates=[1.0, 3.0, 0.0])
    f = rq.HistogramBin([0.0, 1.0, 2.0], counts=[1.0, 3.0])
    assert e.moments == pytest.approx(f.moments, rel=1e-15)
    assert float(d.to_z(d.bounds[1])) > 8 and float(d.from_z(-40.0)) == 5.0


def test_frechet_is_dakotas_type_two_extreme_value():
    d = rq.Frechet(alpha=4.0, beta=2.0)
    x = np.array([0.5, 1.0, 2.0, 5.0])
    np.testing.assert_allclose(d.cdf(x), np.exp(-((2.0 / x) ** 4)), rtol=1e-14)
    np.testing.assert_allclose(d.moments, (2.0 * math.gamma(0.75), 2.0 * math.sqrt(
        math.gamma(0.5) - math.gamma(0.75) ** 2)), rtol=1e-14)
    assert float(d.cdf(0.0)) == 0.0 and float(d.sf(-1.0)) == 1.0


@pytest.mark.parametrize("build, match", [
    (lambda: rq.LogNormal(mean=1.0, zeta=0.3), "give mean and std, or mean and error_factor, "
     "or lambda and zeta .* got mean, zeta"),
    (lambda: rq.LogNormal(mean=1.0, std=0.3, lambda_=0.0), "got mean, std, lambda"),
    (lambda: rq.LogNormal(), "got none"),
    (lambda: rq.LogNormal(mean=1.0, error_factor=0.9), "error_factor must be > 1"),
    (lambda: rq.LogNormal(lambda_=0.0, zeta=-1.0), "zeta must be a finite number > 0"),
    (lambda: rq.LogNormal(1.0, 0.3, lower=2.0, upper=1.0), "0 <= lower < upper"),
    (lambda: rq.LogNormal(1.0, 0.3, lower=-1.0), "0 <= lower < upper"),
    (lambda: rq.Frechet(2.0, 1.0), "alpha must be > 2"),
    (lambda: rq.Frechet(3.0, 0.0), "beta must be a finite number > 0"),
    (lambda: rq.HistogramBin([0.0, 1.0], [1.0, 2.0]), "last 0"),
    (lambda: rq.HistogramBin([0.0, 1.0, 1.0], [1.0, 2.0]), "strictly increasing"),
    (lambda: rq.HistogramBin([0.0, 1.0, 2.0], [1.0, -2.0]), ">= 0 with a positive total"),
    (lambda: rq.HistogramBin([0.0, 1.0, 2.0]), "give counts or ordinates"),
    (lambda: rq.HistogramBin([0.0, 1.0], [1.0], [1.0]), "give counts or ordinates"),
    (lambda: rq.make_distribution("frechet", alpha=3.0, scale=1.0), "takes alpha, beta"),
])
def test_bad_dakota_forms(build, match):
    with pytest.raises(ParameterError, match=match):
        build()
