"""The study runner on small analytic models: results match closed forms, are written to disk,
and a re-run reuses unchanged steps."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import numpy as np
import pytest

from rotoruq.evaluation import FunctionModel
from rotoruq.study.cli import main
from rotoruq.study.results import load_results
from rotoruq.study.runner import run_study

# y1 = 2 a + 3 b + c ;  y2 = a - b     (c is a fixed input)
COEF = np.array([[2.0, 3.0], [1.0, -1.0]])


def linear_factory(calls: list | None = None):
    def factory(inputs, responses, fixed):
        def f(x):
            if calls is not None:
                calls.append(len(x))
            full = {n: x[:, i] for i, n in enumerate(inputs)}
            a = full.get("a", np.full(len(x), fixed.get("a", 0.0)))
            b = full.get("b", np.full(len(x), fixed.get("b", 0.0)))
            c = fixed.get("c", 0.0)
            y = {"y1": 2 * a + 3 * b + c, "y2": a - b}
            return np.column_stack([y[r] for r in responses])

        return FunctionModel(f, inputs, responses)

    return factory


STUDY = """\
[study]
name = "lin"
seed = 7

[model]
command = ["unused"]
responses = ["y1", "y2"]
fixed = { c = 1.0 }

[parameters.a]
distribution = "normal"
mean = 1.0
std = 0.1

[parameters.b]
distribution = "normal"
mean = 2.0
std = 0.2

[data.obs]
c = [1.0, 2.0]
y1 = [9.0, 10.5]
y2 = [-1.0, -1.0]

[[steps]]
name = "truth"
type = "sampling"
n = 400
noise_std = { y1 = 0.5 }

[[steps]]
name = "mv"
type = "mean_value"

[[steps]]
name = "fit"
type = "least_squares"
data = "obs"
responses = ["y2"]
parameters = ["a"]

[[steps]]
name = "check"
type = "forward_check"
from = "fit.calibrated"
data = "obs"
n = 300
sweep = { c = [1.0, 2.0] }
"""


def write(tmp_path: Path, text: str = STUDY) -> Path:
    p = tmp_path / "lin.toml"
    p.write_text(textwrap.dedent(text))
    return p


def test_run_linear_study(tmp_path):
    run = run_study(write(tmp_path), model_factory=linear_factory(), log=None)
    assert run.out == tmp_path / "rotoruq-results" / "lin"
    truth = run["truth"]
    # exact: mean y1 = 2 + 6 + 1 = 9, std y1 = sqrt(0.04 + 0.36) ; LHS on 400 points
    assert truth.get("mean/y1") == pytest.approx(9.0, abs=0.01)
    assert truth.get("std/y1") == pytest.approx(np.sqrt(0.4), rel=0.03)
    noisy = truth.column("outputs", "y1") - truth.column("outputs_clean", "y1")
    assert np.std(noisy) == pytest.approx(0.5, rel=0.15)
    mv = run["mv"]  # linear model: mean value method is exact
    assert mv.get("mean/y1") == pytest.approx(9.0, rel=1e-9)
    assert mv.get("std/y2") == pytest.approx(np.sqrt(0.01 + 0.04), rel=1e-6)
    fit = run["fit"]  # y2 = a - b with b fixed at its mean 2: a = 1
    assert fit.get("value/a") == pytest.approx(1.0, abs=1e-6)
    assert set(fit.distributions) == {"a"}
    check = run["check"]
    # only `a` is uncertain now (b fixed at 2): y1 = 2a + 6 + c, sweep over c
    assert check.get("mean/y1@1") == pytest.approx(9.0, abs=0.02)
    assert check.get("mean/y1@2") == pytest.approx(10.0, abs=0.02)
    assert check.get("data/y1@2") == 10.5
    nstd = abs(10.5 - check.get("mean/y1@2")) / check.get("std/y1@2")
    assert check.get("nstd/y1@2") == pytest.approx(nstd)
    # written to disk and read back identically
    saved = load_results(run.out)
    assert list(saved) == ["truth", "mv", "fit", "check"]
    assert saved["check"].scalars == pytest.approx(dict(check.scalars))
    np.testing.assert_array_equal(saved["truth"].arrays["inputs"], truth.arrays["inputs"])
    header = (run.out / "steps" / "truth" / "inputs.csv").read_text().splitlines()[0]
    assert header == "a,b"
    assert json.loads((run.out / "study.json").read_text())["steps"][0] == "truth"


def test_rerun_reuses_and_redoes_what_changed(tmp_path):
    path = write(tmp_path)
    calls: list = []
    first = run_study(path, model_factory=linear_factory(calls), log=None)
    n_first = sum(calls)
    calls.clear()
    again = run_study(path, model_factory=linear_factory(calls), log=None)
    assert sum(calls) == 0 and set(again.reused) == {"truth", "mv", "fit", "check"}
    assert again["truth"].scalars == first["truth"].scalars
    # change the last step only: the others are reused
    path.write_text(STUDY.replace("n = 300", "n = 200"))
    third = run_study(path, model_factory=linear_factory(calls), log=None)
    assert set(third.reused) == {"truth", "mv", "fit"}
    assert 0 < sum(calls) < n_first


def test_same_seed_same_numbers(tmp_path):
    a = run_study(write(tmp_path), out=tmp_path / "a", model_factory=linear_factory(), log=None)
    b = run_study(write(tmp_path), out=tmp_path / "b", model_factory=linear_factory(), log=None)
    assert a["truth"].scalars == b["truth"].scalars


def test_quick_reduces_samples(tmp_path):
    run = run_study(write(tmp_path), quick=True, model_factory=linear_factory(), log=None)
    assert run["truth"].arrays["inputs"].shape == (40, 2)
    assert run["check"].arrays["outputs@1"].shape == (40, 2)


def test_cli_run_reports_study_errors(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[study]\nname = 1\n")
    assert main(["run", str(bad)]) == 1
    err = capsys.readouterr().err
    assert f"{bad}, line 2: expected 'name' of [study] to be a string" in err
