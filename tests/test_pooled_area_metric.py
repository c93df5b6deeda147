"""The area metric pooled over conditions (u-pooling, Ferson, Oberkampf and Ginzburg 2008;
issue 35, item 8) against closed forms, and the validation step that saves it and never
shows the area metric of one data row as a score of the predictions (through the CLI)."""

from __future__ import annotations

import dataclasses
import textwrap

import numpy as np
import pytest
from scipy import stats

import rotoruq as rq
from _inproc import rotoruq
from rotoruq.errors import ParameterError
from rotoruq.results import StepResult, load_step
from rotoruq.steps.validation import ONE_ROW_AREA, ValidationRecord, validation_tables


def uniform_area(u) -> float:
    """Closed form of the area between the empirical CDF of u and the uniform CDF, by
    integrating |F_n(t) - t| on a fine grid (midpoint rule, error < 1e-7 here)."""
    t = (np.arange(2_000_000) + 0.5) / 2_000_000
    fn = np.searchsorted(np.sort(u), t, side="right") / len(u)
    return float(np.mean(np.abs(fn - t)))


@pytest.mark.parametrize("u", [0.0, 0.3, 0.5, 0.9, 1.0])
def test_one_measurement_gives_the_closed_form_and_at_least_a_quarter(u):
    pred = [np.linspace(0.0, 1.0, 100_001)[:, None]]
    res = rq.pooled_area_metric(pred, np.array([[u]]))
    assert res.u[0, 0] == pytest.approx(u, abs=1e-5)
    assert res.area[0] == pytest.approx(u**2 / 2 + (1 - u) ** 2 / 2, abs=1e-5)
    assert res.area[0] >= 0.25 - 1e-12


@pytest.mark.parametrize("k", [1, 2, 5, 40])
def test_measurements_at_the_uniform_quantiles_give_one_over_4k(k):
    q = (np.arange(k) + 0.5) / k
    n = 4000
    s = (np.arange(n) + 0.5) / n                  # U(0, 1) predictions at every condition
    pred = [10.0 * c + 3.0 * s[:, None] for c in range(k)]  # other units, other offsets
    data = [np.array([[10.0 * c + 3.0 * q[c]]]) for c in range(k)]
    res = rq.pooled_area_metric(pred, data)
    np.testing.assert_allclose(res.u[:, 0], q, atol=1 / n)
    assert res.area[0] == pytest.approx(1 / (4 * k), abs=2 / n)
    assert res.n_measurements == k and res.n_conditions == k


def test_normal_predictions_pool_to_the_area_of_their_phi_values():
    """Condition c predicts N(mu_c, sigma_c) (samples at its exact quantiles); a measurement
    z_c predictive std devs away has u = Phi(z_c): the pooled area is that of the Phi's."""
    rng = np.random.default_rng(4)
    n, k = 20_000, 12
    mu, sigma = rng.uniform(-50, 50, k), rng.uniform(0.1, 30, k)
    z = rng.normal(0.4, 1.3, k)                   # a biased, too wide spread of errors
    q = stats.norm.ppf((np.arange(n) + 0.5) / n)
    pred = [np.column_stack([m + s * q, -(m + s * q)]) for m, s in zip(mu, sigma, strict=True)]
    data = [np.array([[m + s * zz, -(m + s * zz)]])
            for m, s, zz in zip(mu, sigma, z, strict=True)]
    res = rq.pooled_area_metric(pred, data)
    np.testing.assert_allclose(res.u[:, 0], stats.norm.cdf(z), atol=1 / n)
    np.testing.assert_allclose(res.u[:, 1], stats.norm.sf(z), atol=1 / n)
    assert res.area[0] == pytest.approx(uniform_area(stats.norm.cdf(z)), abs=2 / n)
    assert res.area[1] == pytest.approx(uniform_area(stats.norm.sf(z)), abs=2 / n)


def test_bad_input_is_named():
    with pytest.raises(ParameterError, match="2 conditions but data has 1"):
        rq.pooled_area_metric([np.zeros((3, 1)), np.zeros((3, 1))], [np.zeros((1, 1))])
    with pytest.raises(ParameterError, match="non-finite"):
        rq.pooled_area_metric([np.zeros((3, 1))], [np.array([[np.nan]])])


STUDY = """\
[study]
name = "pool"
seed = 3

[model]
function = "text_book"
responses = ["f"]
fixed = { c = 0.0 }

[parameters.a]
distribution = "normal"
mean = 1.0
std = 0.3

[data.obs]
c = [0.0, 1.0, 2.0, 3.0]
f = [1.02, 0.01, 1.1, 16.2]

[[steps]]
name = "val"
type = "validation"
data = "obs"
conditions = { c = [0.0, 1.0, 2.0, 3.0] }
u_systematic = 0.01
n_samples = 200
"""


def test_the_validation_step_pools_its_conditions_and_ranks_nothing_on_one_row(tmp_path):
    (tmp_path / "s.toml").write_text(textwrap.dedent(STUDY))
    # the CLI's entry point in this process (tests/_inproc.py)
    proc = rotoruq("-q", "run", "s.toml", "--out", "out", "--no-report", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    res = load_step(tmp_path / "out" / "steps" / "val")
    rec = ValidationRecord.read(res)
    again = rq.pooled_area_metric([rec.predictive[0, :, j] for j in range(4)],
                                  [rec.data[rec.data_condition == j] for j in range(4)])
    np.testing.assert_array_equal(rec.pit[0], again.u)
    np.testing.assert_array_equal(rec.pooled_area_metric[0], again.area)
    assert res.get("pooled_area_metric/f") == again.area[0]
    shown = rotoruq("show", "out", "val", cwd=tmp_path).stdout
    assert "Area metric pooled over the conditions (u-pooling)" in shown
    assert f"{again.area[0]:.4g}" in shown
    # one data row per condition: the per-condition area is no score, here or held out
    assert shown.count("one row: not a score") == 4 and " ".join(ONE_ROW_AREA.split()[:6]) in \
        " ".join(shown.split())
    held = dataclasses.replace(rec, held_out=np.array([0.0, 0.0, 0.0, 1.0]))
    arrays, meta = held.parts()
    tables = validation_tables(StepResult("val", "validation", {}, arrays, meta=meta), {})
    first = tables[0]
    assert first.title == "Held-out test"
    assert [row[-1] for row in first.rows] == ["one row: not a score (see the pooled area "
                                               "metric)"]
