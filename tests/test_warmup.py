"""The MSER-5 warm-up (rotoruq.methods.mcmc.warmup) and its use in simulation-based calibration.

Closed forms: an AR(1) chain ``x_t = phi x_{t-1} + sqrt(1 - phi^2) e_t`` started at ``x_0``
relaxes as ``x_0 phi^t``: with x_0 = 30 and phi = 0.95 its mean is below 0.5 stationary
standard deviations of 0 after ``log(30 / 0.5) / -log(0.95)`` = 80 steps, so the warm-up must
cover at least the first 40 (where the drift is still above 3.8) and need not be longer than a
few relaxation times (300). A stationary chain has no drift: its MSER point is a short
truncation from the statistic's noise (over 200 seeds of 2000 independent draws the 99th
percentile was 85 draws; tested below 200).
"""

from __future__ import annotations

import numpy as np
import pytest

from rotoruq.errors import ParameterError
from rotoruq.methods.mcmc.warmup import BATCH, mser_warm_up


def _ar1(n, phi, x0, rng):
    e = rng.standard_normal(n) * np.sqrt(1.0 - phi**2)
    x = np.empty(n)
    x[0] = x0
    for t in range(1, n):
        x[t] = phi * x[t - 1] + e[t]
    return x


@pytest.mark.parametrize("seed", range(5))
def test_a_known_transient_is_found(seed):
    rng = np.random.default_rng(seed)
    x = _ar1(4000, 0.95, 30.0, rng)
    w = mser_warm_up(x)
    assert 40 <= w.steps <= 300, w
    assert w.steps % BATCH == 0 and w.settled and w.cap == 2000
    # the draws it keeps have the stationary mean (0) within their standard error
    kept = x[w.steps:]
    assert abs(kept.mean()) < 4 * np.sqrt((1 + 0.95) / (1 - 0.95) / kept.size)


def test_the_slowest_parameter_and_chain_set_the_warm_up():
    rng = np.random.default_rng(1)
    calm = rng.standard_normal((3, 3000, 2))
    calm[1, :, 1] = _ar1(3000, 0.98, 40.0, rng)  # one drifting series among six
    w = mser_warm_up(calm)
    assert w.per_series.shape == (3, 2)
    assert w.steps == w.per_series.max() == w.per_series[1, 1]
    assert w.steps >= 100  # 40 x 0.98^100 = 5.3: still drifting at 100
    assert np.delete(w.per_series.ravel(), 3).max() < 200


def test_a_stationary_chain_needs_almost_none():
    rng = np.random.default_rng(2)
    steps = [mser_warm_up(rng.standard_normal(2000)).steps for _ in range(50)]
    assert np.median(steps) <= 10 and max(steps) < 200, steps


def test_a_chain_that_never_settles_hits_the_cap():
    """A chain still drifting at its end: the truncation point is the cap (half the
    chain) and the result says it did not settle."""
    x = np.linspace(10.0, 0.0, 1000) + 0.01 * np.random.default_rng(3).standard_normal(1000)
    w = mser_warm_up(x)
    assert w.cap == 500 and w.steps == 500 and not w.settled


def test_a_trailing_part_batch_is_left_out_and_the_cap_is_whole_batches():
    rng = np.random.default_rng(4)
    x = rng.standard_normal(1003)
    w1, w2 = mser_warm_up(x), mser_warm_up(x[:1000])
    assert (w1.steps, w1.cap) == (w2.steps, w2.cap) == (w2.steps, 500)
    assert mser_warm_up(x[:53], batch=1).cap == 26


@pytest.mark.parametrize("chains, kw, match", [
    (np.zeros((2, 3, 4, 5)), {}, r"shape \(n_draws,\), \(n_draws, d\)"),
    (np.zeros(19), {}, "at least 20 draws per chain"),
    (np.zeros((2, 0, 3)), {}, "at least 20 draws"),
    (np.r_[np.zeros(30), np.nan], {}, "non-finite"),
    (np.r_[np.zeros(30), np.inf], {}, "non-finite"),
    (np.zeros(40), {"batch": 0}, "batch must be >= 1"),
])
def test_bad_input(chains, kw, match):
    with pytest.raises(ParameterError, match=match):
        mser_warm_up(chains, **kw)


def test_the_self_check_records_the_warm_up_of_each_replication():
    """simulation_based_calibration drops each replication's MSER-5 warm-up from its
    chains, records it and says so in its reason; a ``calibrate`` callable's draws are used
    as returned."""
    import rotoruq as rq

    prior = rq.ParameterSpace({"a": rq.Normal(0.0, 1.0), "b": rq.Normal(1.0, 0.5)})
    model = rq.FunctionModel(lambda x: np.column_stack([x[:, 0] + x[:, 1] ** 2,
                                                        x[:, 0] - x[:, 1]]),
                             ["a", "b"], ["y1", "y2"])
    r = rq.simulation_based_calibration(model, prior, noise_std=0.3, n_replications=10,
                                        n_draws=19, n_samples=400, seed=1)
    assert r.warm_up.shape == (10,) and r.warm_up.dtype.kind == "i"
    assert np.all(r.warm_up % BATCH == 0) and np.all(r.warm_up <= 200)
    assert 0 <= r.n_unsettled <= 10
    assert "warm-up by MSER-5 after the fixed burn-in of 200 steps" in r.reason
    assert f"largest {r.warm_up.max()} draws dropped" in r.reason
    back = type(r).from_arrays(r.to_arrays())
    np.testing.assert_array_equal(back.warm_up, r.warm_up)
    assert back.n_unsettled == r.n_unsettled

    def exact(data, *, seed):  # draws as a calibration returns them: none dropped
        return np.random.default_rng(seed).normal(size=(100, 2))

    own = rq.simulation_based_calibration(model, prior, noise_std=0.3, n_replications=4,
                                          n_draws=19, calibrate=exact, seed=2)
    assert not own.warm_up.any() and own.n_unsettled == 0 and "MSER" not in own.reason
