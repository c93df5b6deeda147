"""Correlated inputs in study files: the ``[correlation]`` table (Dakota's
``uncertain_correlation_matrix``), carried into the steps' parameter spaces and their
fingerprints; the step types that assume independent inputs refuse it; every bad table names
its file and line. Also the Dakota forms of the distributions in ``[parameters]``."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import rotoruq as rq
from rotoruq.errors import InputFileError, ParameterError
from rotoruq.model import FunctionModel
from rotoruq.results import load_step
from rotoruq.study.runner import run_study
from rotoruq.study.schema import parse_study

GRAD = np.array([2.0, 3.0, -1.0])  # y = 2 a + 3 b - c

DRIVER = r'''
import sys
vals = {k.strip(): float(v) for k, v in (line.split("=") for line in open("input.txt"))}
open(sys.argv[2], "w").write(f"{2 * vals['a'] + 3 * vals['b'] - vals['c']!r} y\n")
'''

PARAMETERS = """
[parameters.a]
distribution = "normal"
mean = 1.0
std = 0.5

[parameters.b]
distribution = "lognormal"
lambda = 0.0
zeta = 0.3

[parameters.c]
distribution = "histogram_bin"
abscissas = [0.0, 1.0, 3.0]
counts = [1.0, 3.0, 0.0]

[correlation]
parameters = ["a", "b", "c"]
matrix = [[1.0, 0.4, 0.0],
          [0.4, 1.0, -0.2],
          [0.0, -0.2, 1.0]]
"""
R = np.array([[1.0, 0.4, 0.0], [0.4, 1.0, -0.2], [0.0, -0.2, 1.0]])
DISTS = [rq.Normal(1.0, 0.5), rq.LogNormal(lambda_=0.0, zeta=0.3),
         rq.HistogramBin([0.0, 1.0, 3.0], [1.0, 3.0, 0.0])]


def lines(text: str, pattern: str) -> str:
    """``pattern`` with each ``<<needle>>`` replaced by the line of its first occurrence in
    ``text`` (``<<needle@k>>``: its k-th)."""
    def line(m: re.Match) -> str:
        needle, _, k = m.group(1).partition("@")
        at = -1
        for _ in range(int(k or 1)):
            at = text.index(needle, at + 1)
        return str(text[:at].count("\n") + 1)

    return re.sub(r"<<(.+?)>>", line, pattern)


def closed_form_std() -> float:
    s = np.array([d.std for d in DISTS])
    return float(np.sqrt(GRAD @ (np.outer(s, s) * R) @ GRAD))


def test_mean_value_through_the_cli_is_the_closed_form(tmp_path):
    """std = sqrt(g^T C g), C = D R D, for the linear model through an external driver."""
    (tmp_path / "driver.py").write_text(DRIVER)
    (tmp_path / "input.txt").write_text("a = {a}\nb = {b}\nc = {c}\n")
    (tmp_path / "study.toml").write_text(f"""
[study]
name = "corr"

[model]
command = [{json.dumps(sys.executable)}, "-S", "driver.py", "{{params}}", "{{results}}"]
templates = ["input.txt"]
responses = ["y"]
{PARAMETERS}
[[steps]]
name = "mv"
type = "mean_value"
""")
    proc = subprocess.run([sys.executable, "-m", "rotoruq.study.cli", "run",
                           str(tmp_path / "study.toml"), "--out", str(tmp_path / "out"),
                           "--no-report"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    mv = load_step(tmp_path / "out" / "steps" / "mv")
    mean = GRAD @ np.array([d.mean for d in DISTS])
    assert mv.get("mean/y") == pytest.approx(mean, rel=1e-12)
    assert mv.get("std/y") == pytest.approx(closed_form_std(), rel=1e-8)
    independent = float(np.sqrt(np.sum((GRAD * [d.std for d in DISTS]) ** 2)))
    assert abs(mv.get("std/y") - independent) > 0.05 * independent  # the correlation counts


def linear_factory(inputs, responses, fixed):
    def f(x):
        full = {n: x[:, i] for i, n in enumerate(inputs)}
        v = [full.get(n, np.full(len(x), fixed.get(n, 0.0))) for n in "abc"]
        return np.column_stack([GRAD @ np.array(v)])

    return FunctionModel(f, inputs, responses)


def study_text(steps: str, parameters: str = PARAMETERS) -> str:
    return textwrap.dedent("""
        [study]
        name = "corr"
        seed = 3

        [model]
        command = ["driver"]
        responses = ["y"]
        """) + parameters + textwrap.dedent(steps)


def test_sampling_reproduces_the_correlation_and_it_enters_the_fingerprint(tmp_path):
    p = tmp_path / "corr.toml"
    p.write_text(study_text("""
        [[steps]]
        name = "mc"
        type = "sampling"
        n_samples = 20000
        design = "random"
        """))
    run = run_study(p, out=tmp_path / "out", model_factory=linear_factory)
    x = run.results["mc"].arrays["inputs"]
    np.testing.assert_allclose(np.corrcoef(x.T), R, atol=0.025)
    np.testing.assert_allclose(x.std(axis=0), [d.std for d in DISTS], rtol=0.03)
    y = run.results["mc"].arrays["outputs"][:, 0]
    assert y.std() == pytest.approx(closed_form_std(), rel=0.03)
    # a changed correlation changes the step's `inputs` identity (and only that part)
    before = run.results["mc"].meta["identity"]
    p.write_text(p.read_text().replace("0.4, 1.0, -0.2", "0.3, 1.0, -0.2")
                 .replace("[1.0, 0.4, 0.0]", "[1.0, 0.3, 0.0]"))
    again = run_study(p, out=tmp_path / "out2", model_factory=linear_factory)
    after = again.results["mc"].meta["identity"]
    assert [k for k in before if before[k] != after[k]] == ["inputs"]


def test_the_study_space_carries_the_correlation_of_the_listed_parameters():
    study = parse_study(study_text("""
        [parameters.d]
        distribution = "frechet"
        alpha = 4.0
        beta = 1.0

        [[steps]]
        type = "sampling"
        n_samples = 4
        """))
    space = study.space()
    assert space.names == ("a", "b", "c", "d")
    np.testing.assert_array_equal(space.correlation_matrix[:3, :3], R)
    np.testing.assert_array_equal(space.correlation_matrix[3], [0, 0, 0, 1])
    assert study.space(["a", "d"]).correlation is None
    assert study.correlation is not None
    assert study.correlation.line == int(lines(study.text, "<<[correlation]>>"))


@pytest.mark.parametrize("steps, match", [
    ("""
     [[steps]]
     name = "sobol"
     type = "sensitivity"
     n_samples = 8
     """, r'line <<type = "sensitivity">>: expected a step type'
         r" that honours correlated inputs "
         r"\(mean_value, pce, reliability, sampling\) for step 'sobol': a sensitivity step "
         r"assumes independent inputs, and the \[correlation\] table "
         r"\(line <<[correlation]>>\) correlates its parameters a, b, c"),
])
def test_steps_that_assume_independence_refuse_it(steps, match):
    text = study_text(steps)
    with pytest.raises(InputFileError, match=lines(text, match)):
        parse_study(text, "study.toml")


def test_a_step_over_uncorrelated_parameters_is_fine():
    study = parse_study(study_text("""
        [[steps]]
        name = "sobol"
        type = "sensitivity"
        n_samples = 8
        parameters = ["a", "c"]
        """))
    assert study.steps[0].parameters == ("a", "c")


STEPS = """
[[steps]]
type = "mean_value"
"""


def corr_table(body: str) -> str:
    return PARAMETERS.split("[correlation]")[0] + "[correlation]\n" + textwrap.dedent(body)


@pytest.mark.parametrize("body, match", [
    ('parameters = ["a", "x"]\nmatrix = [[1.0, 0.1], [0.1, 1.0]]\n',
     r'line <<"x">>: expected names of \[parameters.NAME\] tables .*\(a, b, c\), '
     r"found 'x'"),
    ('parameters = ["a", "a"]\nmatrix = [[1.0, 0.1], [0.1, 1.0]]\n',
     r'line <<"a", "a">>: expected each parameter once'),
    ('parameters = ["a", "b"]\nmatrix = [[1.0, 0.1, 0.0], [0.1, 1.0, 0.0]]\n',
     r"line <<matrix>>: expected a 2 x 2 matrix"),
    ('parameters = ["a", "b"]\nmatrix = [[1.0, 0.1], [0.2, 1.0]]\n',
     r"line <<matrix>>: expected a symmetric matrix .* row 1, column 2 \(a, b\) is 0.1 "
     r"but \(b, a\) "
     r"is 0.2"),
    ('parameters = ["a", "b"]\nmatrix = [[1.0, 0.1], [0.1, 2.0]]\n',
     r"line <<matrix>>: expected a unit diagonal"),
    ('parameters = ["a", "b", "c"]\nmatrix = [[1.0, 0.9, 0.9], [0.9, 1.0, -0.9], '
     '[0.9, -0.9, 1.0]]\n', r"line <<matrix>>: expected a positive definite matrix"),
    ('parameters = ["a", "b"]\nmatrix = [[1.0, "x"], ["x", 1.0]]\n',
     r"line <<matrix>>: expected numbers in the matrix"),
    ('parameters = ["a", "b"]\n',
     r"line <<[correlation]>>: expected matrix = \[...\] in \[correlation\]"),
    ('parameters = ["a", "b"]\nmatrix = [[1.0, 0.1], [0.1, 1.0]]\nrows = 2\n',
     r"line <<rows>>: expected one of the keys of \[correlation\]"),
    ('parameters = ["b", "c"]\nmatrix = [[1.0, 0.99], [0.99, 1.0]]\n',
     r"line <<matrix>>: expected correlations the marginals of b, c can reach"),
])
def test_bad_correlation_tables_name_file_and_line(body, match):
    text = study_text(STEPS, corr_table(body))
    with pytest.raises(InputFileError, match=lines(text, match)) as e:
        parse_study(text, "study.toml")
    assert "study.toml" in str(e.value)


@pytest.mark.parametrize("params, match", [
    ('distribution = "lognormal"\nmean = 1.0\nzeta = 0.3\n',
     r"line <<zeta = 0.3@2>>: expected a valid lognormal distribution "
     r"\(mean = <number>, std = <number> \| "
     r"mean = <number>, error_factor = <number> \| lambda = <number>, zeta = <number>"),
    ('distribution = "lognormal"\nmean = 1.0\nerror_factor = 0.5\n',
     r"line <<error_factor>>: expected .*error_factor must be > 1"),
    ('distribution = "histogram_bin"\nabscissas = [0.0, 1.0]\ncounts = 3.0\n',
     r"line <<counts@2>>: expected a list of numbers for \[parameters.e\] counts"),
    ('distribution = "histogram_bin"\nabscissas = [0.0, 1.0]\ncounts = [3.0, 1.0]\n',
     r"line <<counts@2>>: expected a valid histogram_bin distribution .*last 0"),
    ('distribution = "frechet"\nalpha = 1.5\nbeta = 1.0\n', r"alpha must be > 2"),
])
def test_bad_dakota_forms_in_parameters_name_file_and_line(params, match):
    text = study_text(STEPS, PARAMETERS.split("[correlation]")[0] + "[parameters.e]\n" + params)
    with pytest.raises(InputFileError, match=lines(text, match)):
        parse_study(text, "study.toml")


def test_the_dakota_forms_parse_and_round_trip_through_describe():
    study = parse_study(study_text(STEPS, PARAMETERS + textwrap.dedent("""
        [parameters.e]
        distribution = "lognormal"
        mean = 2.0
        error_factor = 3.0
        lower = 0.5
        upper = 10.0

        [parameters.f]
        distribution = "histogram_bin"
        abscissas = [0.0, 1.0, 2.0]
        ordinates = [1.0, 2.0, 0.0]
        """)))
    for p in study.parameters:
        d = p.distribution
        assert rq.make_distribution(**d.describe()).describe() == d.describe()
    assert study.parameter("b").distribution.describe() == {"kind": "lognormal",
                                                             "lambda": 0.0, "zeta": 0.3}
    assert study.parameter("f").distribution.moments[0] == pytest.approx(
        (1 * 0.5 + 2 * 1.5) / 3)


def test_a_step_taking_distributions_from_a_posterior_is_not_correlated(tmp_path):
    """The correlation is of [parameters] (and a step's own distributions): a step taking
    its distributions ``from`` an earlier step gets the joint law of that step."""
    from rotoruq.study.runner import _step_space
    from rotoruq.study.spec import StepSpec

    study = parse_study(study_text(STEPS))
    step = StepSpec("s", "sampling", 0, {}, source=("cal", "posterior"))

    class Source:
        type = "bayes_calibration"
        arrays: dict = {}

        def distribution_objects(self):
            return {"a": rq.Normal(1.0, 0.1), "b": rq.Normal(1.0, 0.1)}

    space, _ = _step_space(study, step, {"cal": Source()})
    assert space.correlation is None
    space, _ = _step_space(study, StepSpec("s", "sampling", 0, {}), {})
    np.testing.assert_array_equal(space.correlation_matrix, R)
    with pytest.raises(ParameterError,
                       match=lines(study.text, r"a sensitivity step assumes independent "
                                   r"inputs, and the \[correlation\] table "
                                   r"\(line <<[correlation]>>\)")):
        _step_space(study, StepSpec("s", "sensitivity", 0, {}, line=30), {})


