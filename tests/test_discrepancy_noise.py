"""The noise level of a function and a Hessian with steps set by it (methods/mcmc/fd_noise.py),
and the discrepancy calibration's first proposal that uses them (issue 34: a fixed small step
gave the held-out chapter's chains a proposal shaped by noise)."""

from __future__ import annotations

import numpy as np
import pytest

from rotoruq.errors import ParameterError
from rotoruq.methods.mcmc.discrepancy import _map_and_covariance
from rotoruq.methods.mcmc.fd_noise import noise_level, noisy_hessian

SIGMA = 1e-5  # the noise added to the test functions, their units


def test_noise_level_recovers_added_noise():
    """ECnoise's estimate of a known Gaussian noise on a smooth function: 200 tables of nine
    values spaced 1e-6; each estimate within a factor 4 of the noise's std, their median
    within 20 % (one table has 9 values: its estimate scatters)."""
    ratios = []
    for seed in range(200):
        rng = np.random.default_rng(seed)
        x = 0.3 + 1e-6 * np.arange(9)
        est = noise_level(np.exp(x) + SIGMA * rng.standard_normal(9))
        assert est.found and est.order >= 1
        ratios.append(est.level / SIGMA)
    ratios = np.array(ratios)
    assert np.all((ratios > 0.25) & (ratios < 4.0)), (ratios.min(), ratios.max())
    assert 0.8 < np.median(ratios) < 1.2, np.median(ratios)


def test_noise_level_of_smooth_values_is_roundoff_and_of_a_coarse_table_is_not_found():
    x = 1.0 + 1e-6 * np.arange(9)
    smooth = noise_level(np.exp(x))
    assert smooth.level < 1e-14  # only the values' rounding
    assert noise_level(np.full(9, 3.0)).level == 0.0
    # spacing 0.5: the differences of a smooth function are its derivatives, not noise
    coarse = noise_level(np.exp(0.5 * np.arange(9)))
    assert not coarse.found


def test_noise_level_refuses_too_few_or_non_finite_values():
    with pytest.raises(ParameterError, match="4 finite values"):
        noise_level([1.0, 2.0, 3.0])
    with pytest.raises(ParameterError, match="4 finite values"):
        noise_level([1.0, np.nan, 3.0, 4.0, 5.0])


A = np.array([[2.0, 0.5, 0.0], [0.5, 1.0, 0.2], [0.0, 0.2, 0.05]])


def _quadratic_plus_noise(seed):
    rng = np.random.default_rng(seed)

    def f(z):
        return 0.5 * np.einsum("ki,ij,kj->k", z, A, z) + SIGMA * rng.standard_normal(len(z))
    return f


def test_hessian_of_a_quadratic_plus_noise():
    """A known quadratic (curvatures 2 to 0.05) plus noise of std 1e-5, 50 seeds: every
    entry within 0.05 of the true Hessian (about 10 sqrt(eps_f max|f''|), the error of a
    second difference whose step balances noise and truncation), the noise found within a
    factor 4; a fixed step of 1e-3 (the former proposal's) errs by the noise over h^2, ~10."""
    for seed in range(50):
        est = noisy_hessian(_quadratic_plus_noise(seed), np.zeros(3))
        assert est.measured.all()
        assert np.abs(est.hessian - A).max() < 0.05, (seed, est.hessian)
        assert np.all((est.noise > SIGMA / 4) & (est.noise < 4 * SIGMA)), est.noise
        # the weak direction (curvature 0.05) gets a longer step than the strong one
        assert est.steps[2] > est.steps[0]
    f = _quadratic_plus_noise(0)
    h = 1e-3
    fixed = (f(np.array([[h, 0, 0]])) - 2 * f(np.zeros((1, 3))) + f(np.array([[-h, 0, 0]])))
    assert abs(fixed[0] / h**2 - A[0, 0]) > 1.0  # what the fixed step gave


def test_flat_direction_has_no_measurable_curvature():
    """A coordinate the function does not depend on: not measured, its row and column 0."""
    rng = np.random.default_rng(3)

    def f(z):
        return 0.5 * 3.0 * z[:, 0] ** 2 + SIGMA * rng.standard_normal(len(z))
    est = noisy_hessian(f, np.zeros(2))
    assert est.measured.tolist() == [True, False]
    assert abs(est.hessian[0, 0] - 3.0) < 0.05
    assert np.all(est.hessian[1] == 0) and np.all(est.hessian[:, 1] == 0)


def test_max_step_bounds_the_steps():
    est = noisy_hessian(_quadratic_plus_noise(1), np.zeros(3), max_step=[1.0, 1.0, 0.01])
    assert est.steps[2] <= 0.01
    with pytest.raises(ParameterError, match="steps > 0"):
        noisy_hessian(_quadratic_plus_noise(1), np.zeros(3), max_step=0.0)


class _NoisyGaussian:
    """A log posterior in scaled coordinates: a Gaussian of precision P, noise of std
    SIGMA on each value, -inf outside [lo, hi] (a bounded prior)."""

    def __init__(self, P, lo, hi, seed):
        self.P, self.lo, self.hi = P, lo, hi
        self.rng = np.random.default_rng(seed)

    def __call__(self, z):
        z = np.atleast_2d(z)
        v = -0.5 * np.einsum("ki,ij,kj->k", z, self.P, z) + SIGMA * self.rng.standard_normal(
            len(z))
        return np.where(np.all((z >= self.lo) & (z <= self.hi), axis=1), v, -np.inf)


def test_first_proposal_is_the_posterior_covariance_despite_noise():
    """The discrepancy calibration's first proposal (the inverse Hessian at the MAP) of a
    noisy Gaussian log posterior: its covariance within 5 % of the true one; a third,
    uniform-prior coordinate the data do not inform gets the prior's unit variance."""
    P = np.array([[4.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 0.0]])
    lo, hi = np.array([-np.inf, -np.inf, -1.7]), np.array([np.inf, np.inf, 1.7])
    post = _NoisyGaussian(P, lo, hi, seed=5)
    zm, cov, ok = _map_and_covariance(post, np.array([0.3, -0.2, 0.1]), lo, hi,
                                      np.array([False, False, True]))
    want = np.zeros((3, 3))
    want[:2, :2] = np.linalg.inv(P[:2, :2])
    want[2, 2] = 1.0
    assert ok
    assert np.allclose(cov, want, rtol=0.05, atol=0.02), cov
