"""Sequential calibration keeps the posterior's shape (issue 35, item 7): a calibration taking
``from = "STEP.posterior"`` of an earlier calibration gets, as its prior, the kernel density of
that chain inside the earlier prior's support (:func:`rotoruq.kernel_density`),
not normals of its moments. Checked against closed forms: a uniform's excess kurtosis is -6/5,
a normal's 0, and a uniform prior's box holds all the mass."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest
from scipy import stats

from rotoruq.errors import ParameterError
from rotoruq.params.density import kernel_density
from rotoruq.study.runner import run_study


def _kurtosis(d) -> float:
    """Excess kurtosis of a distribution by its quantiles on a fine grid (exact to ~1e-4
    for these piecewise-uniform densities)."""
    z = d.ppf((np.arange(200_000) + 0.5) / 200_000)
    return float(stats.kurtosis(z))


@pytest.mark.parametrize("n", [4000, 100_000])
def test_a_uniform_sample_keeps_its_shape_and_its_box(n):
    x = np.random.default_rng(n).uniform(2.0, 5.0, n)
    d = kernel_density(x, (2.0, 5.0))
    assert d.bounds == (2.0, 5.0)  # reflected at the bounds: no mass outside, flat up to them
    assert _kurtosis(d) == pytest.approx(-1.2, abs=0.05)
    assert float(d.pdf(2.0 + 1e-9)) == pytest.approx(1 / 3, rel=0.15)
    assert d.moments[1] == pytest.approx(3 / np.sqrt(12), rel=0.02)


def test_a_normal_sample_stays_normal_and_an_inner_one_stays_inside():
    x = np.random.default_rng(1).normal(0.0, 1.0, 100_000)
    d = kernel_density(x)
    assert _kurtosis(d) == pytest.approx(0.0, abs=0.06)
    assert d.moments == pytest.approx((0.0, 1.0), abs=0.02)
    # a sample well inside its support: the density ends 4 bandwidths past the sample
    y = np.random.default_rng(2).uniform(0.3, 0.6, 10_000)
    e = kernel_density(y, (0.0, 1.0))
    assert 0.0 < e.bounds[0] < 0.3 and 0.6 < e.bounds[1] < 1.0


def test_bad_samples_are_refused_naming_what_is_wrong():
    with pytest.raises(ParameterError, match="outside the support"):
        kernel_density([0.5, 1.5], (0.0, 1.0))
    with pytest.raises(ParameterError, match="two distinct finite samples"):
        kernel_density([1.0, 1.0, np.nan])


STUDY = """\
[study]
name = "sequential"
seed = 5

[model]
function = "text_book"
responses = ["f", "c1", "c2"]

[parameters.a]
distribution = "uniform"
lower = 0.0
upper = 1.0

[parameters.b]
distribution = "uniform"
lower = 0.0
upper = 1.0

[data.obs]
f = [0.1]
c1 = [0.2]
c2 = [0.3]

[[steps]]
name = "stage1"
type = "bayes_calibration"
emulator = "none"
responses = ["f"]
noise_std = 1000.0
n_samples = 3000
burn_in = 300

[[steps]]
name = "stage2"
type = "bayes_calibration"
emulator = "none"
from = "stage1.posterior"
responses = ["c2"]
noise_std = 1000.0
n_samples = 3000
burn_in = 300
"""


def test_stage_two_prior_is_stage_one_chain_density_inside_the_box(tmp_path):
    """Data that do not inform (noise std 1000): stage 1's posterior is its uniform prior, and
    stage 2's prior must be uniform-shaped on [0, 1] too, where normals of its moments would
    put 8.3 % of their mass outside the box."""
    (tmp_path / "study.toml").write_text(textwrap.dedent(STUDY))
    run = run_study(tmp_path / "study.toml", out=tmp_path / "out")
    s1, s2 = run["stage1"], run["stage2"]
    prior2 = s2.input_distributions()
    for p in ("a", "b"):
        chain1 = s1.column("chain", p)
        assert stats.kurtosis(chain1) == pytest.approx(-1.2, abs=0.1)
        d = prior2[p]
        assert d.kind == "histogram_bin"
        lo, hi = d.bounds
        assert 0.0 <= lo and hi <= 1.0
        assert _kurtosis(d) == pytest.approx(float(stats.kurtosis(chain1)), abs=0.05)
        chain2 = s2.column("chain", p)
        assert chain2.min() >= lo and chain2.max() <= hi
        assert stats.kurtosis(chain2) == pytest.approx(-1.2, abs=0.15)
