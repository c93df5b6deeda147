"""The ``verification`` and ``validation`` step types and the discrepancy branch of the Bayes
step, through the CLI on the GVPM rotor: the saved numbers against hand computations and
``rq.validate``, the report's V&V table, and bad input named at its study file line."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import rotoruq as rq
from _inproc import rotoruq
from rotoruq.results import load_step
from rotoruq.steps._discrepancy import DiscrepancyRecord
from rotoruq.steps.validation import WITHOUT, ValidationRecord
from rotoruq.steps.verification import VerificationRecord

HEIGHTS = [4.0, 3.0, 2.0, 1.0]
OMEGA = [224.6375, 224.5718, 224.5443, 223.0457]
U_SYS = {"thrust": 0.86, "power": 11.66}
U_NUM = {"thrust": 0.1, "power": 0.5}

HEAD = """\
[study]
name = "vv"
seed = 5

[model]
preset = "gvpm"
responses = ["thrust", "power"]
fixed = { omega = 224.6375, height_over_radius = 4.0, lateral_deg = -1.0, longitudinal_deg = -1.0 }

[data.heights]
file = "gvpm_measurements.csv"

[data.measured]
file = "gvpm_measurements.csv"
select = { height_over_radius = 4.0 }

[parameters.collective_deg]
distribution = "normal"
mean = 5.4
std = 0.5

[parameters.k_pitch_link]
distribution = "uniform"
lower = 10.0
upper = 20.0
"""

STUDY = HEAD + f"""
[[steps]]
name = "verify"
type = "verification"
parameters = ["collective_deg"]
ratio = 2
levels = 2
formal_order = 2.0
points = [{{ height_over_radius = 4.0, omega = 224.6375 }},
          {{ height_over_radius = 1.0, omega = 223.0457 }}]

[[steps]]
name = "bayes_4r"
type = "bayes_calibration"
data = "measured"
noise_std = {{ thrust = 0.86, power = 11.66 }}
emulator = "none"
n_samples = 300
burn_in = 100

[[steps]]
name = "disc"
type = "bayes_calibration"
data = "heights"
noise_std = {{ thrust = 0.86, power = 11.66 }}
configuration = "height_over_radius"
couple = {{ omega = "omega" }}
predict_at = [1.0]
discrepancy = {{ amplitude_scale = {{ thrust = 3.0, power = 40.0 }}, length_scale = 2.0 }}
n_emulator_samples = 30
n_samples = 600
burn_in = 200

[[steps]]
name = "val_4r"
type = "validation"
from = "bayes_4r.posterior"
data = "heights"
conditions = {{ height_over_radius = {HEIGHTS}, omega = {OMEGA} }}
u_systematic = {{ thrust = 0.86, power = 11.66 }}
u_num = {{ thrust = 0.1, power = 0.5 }}
n_samples = 60

[[steps]]
name = "val_disc"
type = "validation"
from = "disc.posterior"
data = "heights"
conditions = {{ height_over_radius = {HEIGHTS}, omega = {OMEGA} }}
u_systematic = {{ thrust = 0.86, power = 11.66 }}
verification = {{ ratio = 2, levels = 2, formal_order = 2.0 }}
"""


def cli(*args, cwd: Path, fresh: bool = False) -> subprocess.CompletedProcess:
    """``rotoruq ARGS`` from ``cwd``: through the CLI's entry point in this process
    (``tests/_inproc.py``), or with ``fresh`` in a new one (the module's study run)."""
    if not fresh:
        return rotoruq(*args, cwd=cwd)
    return subprocess.run([sys.executable, "-m", "rotoruq.study.cli", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd, timeout=600)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("vv")
    (tmp / "vv.toml").write_text(STUDY)
    proc = cli("run", "vv.toml", "--out", "out", cwd=tmp, fresh=True)
    assert proc.returncode == 0, proc.stderr
    return tmp / "out"


@pytest.mark.slow
def test_validation_record_is_the_vv20_budget(run_dir):
    for name in ("val_4r", "val_disc"):
        rec = ValidationRecord.read(load_step(run_dir / "steps" / name))
        assert rec.names_out == ("thrust", "power")
        assert rec.conditions.tolist() == HEIGHTS
        assert rec.n_repeats.tolist() == [1, 1, 1, 1]  # the GVPM data: one row per height
        u_num = (np.array([U_NUM["thrust"], U_NUM["power"]]) if name == "val_4r"
                 else rec.u_num[0])  # val_disc: the GCI per height (checked below)
        u_sys = np.array([U_SYS["thrust"], U_SYS["power"]])
        # the calibrations' own data, found by value: 4R for the 4R-only one, 4R-2R for the
        # one with a discrepancy (1R held out)
        cal = np.array(HEIGHTS)[:, None] >= (4.0 if name == "val_4r" else 2.0)
        np.testing.assert_array_equal(rec.calibrated(), np.repeat(cal, 2, axis=1))
        for p in range(len(rec.predictions)):
            pred = rec.predictive[p]                    # (n, c, m)
            data = np.array([rec.data[rec.data_condition == j][0] for j in range(4)])
            # by hand: E = mean(S) - D, u_val^2 = u_num^2 + std(S)^2 + u_sys^2 (one repeat);
            # on calibration data the fit's residual, u_num^2 + u_sys^2 - std(S)^2
            e = pred.mean(axis=0) - data
            var_s = pred.std(axis=0, ddof=1) ** 2
            fit = cal & (rec.predictions[p] != WITHOUT)   # the model alone was not fit
            u_val = np.sqrt(u_num**2 + np.where(fit, np.maximum(u_sys**2 - var_s, 0.0),
                                                u_sys**2 + var_s))
            # not judged where the residual variance is within 3 Monte Carlo standard
            # errors of var_s (n predictive samples)
            n = pred.shape[0]
            u_val[fit & (u_sys**2 - var_s < 3 * np.sqrt(2 / (n - 1)) * var_s)] = np.nan
            np.testing.assert_allclose(rec.comparison_error[p], e, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(rec.u_val[p], u_val, rtol=1e-12)
            np.testing.assert_allclose(rec.lower[p], e - 2.0 * u_val, rtol=1e-12, atol=1e-12)
            # ... and rq.validate on the same inputs, field by field (to summation order: the
            # saved array's memory layout differs from the one the step sliced)
            ref = rq.validate([pred[:, j] for j in range(4)],
                              [rec.data[rec.data_condition == j] for j in range(4)],
                              u_num=u_num, u_systematic=u_sys, names_out=rec.names_out,
                              conditions=HEIGHTS, calibration=fit)
            for f in ("comparison_error", "u_val", "u_input", "u_data", "error_ratio",
                      "area_metric", "relative_area_metric", "sigma_distance"):
                np.testing.assert_allclose(getattr(rec, f)[p], getattr(ref, f), rtol=1e-12,
                                           atol=1e-10, err_msg=f)
            np.testing.assert_array_equal(rec.within_n_sigma[p], ref.within_n_sigma)


@pytest.mark.slow
def test_calibration_data_are_not_counted_as_validation(run_dir):
    """The run's verdict counts only the held-out comparisons (1R, 2 predictions x 2 loads
    for the discrepancy step, 2 loads for the 4R-only one below 4R), the rest apart."""
    from rotoruq.report.verdict import verdict_lines
    from rotoruq.results import load_results

    steps = load_results(run_dir)
    line = verdict_lines({"vv": steps})[0]
    ratios = []
    for name in ("val_4r", "val_disc"):
        rec = ValidationRecord.read(steps[name])
        free = ~rec.calibrated()
        ratios += [float(v) for v in rec.error_ratio[:, free].ravel()]
    assert line.counts["comparisons"] == len(ratios) == 3 * 2 + 2 * 2
    assert line.counts["within"] == sum(v <= 2.0 for v in ratios)
    assert line.counts["calibration_data"] == 1 * 2 + 2 * 3 * 2
    assert "consistency checks" in line.text
    page = (run_dir / "report" / "index.html")
    if page.is_file():
        assert "calibration data: consistency, not validation" in page.read_text()


@pytest.mark.slow
def test_discrepancy_predictions_reach_the_validation(run_dir):
    disc = DiscrepancyRecord.read(load_step(run_dir / "steps" / "disc"))
    val = ValidationRecord.read(load_step(run_dir / "steps" / "val_disc"))
    # 1R is held out: calibrated on 4R, 3R, 2R only, predicted at all four
    assert sorted(disc.data_configurations.tolist()) == [2.0, 3.0, 4.0]
    assert disc.held_out.tolist() == [1.0]
    assert sorted(disc.predict_configurations.tolist()) == [1.0, 2.0, 3.0, 4.0]
    assert disc.chains.shape[0] == 2 and disc.hyper_names  # GP amplitude and length-scale
    # the chains ran a GP emulator of the rotor (30 design points at the 3 heights), close to
    # the rotor at the posterior draws against the noise; the predictions ran the rotor
    assert disc.emulator_runs == 30
    assert np.all(disc.emulator_loo_ratio < 0.3) and np.all(disc.emulator_posterior_ratio < 0.3)
    assert disc.noise_model.endswith("+ the emulator's Kriging variance")
    assert val.predictions == ("with discrepancy", "without discrepancy (same posterior)")
    assert val.held_out.tolist() == [0.0, 0.0, 0.0, 1.0]
    idx = [int(np.flatnonzero(np.isclose(disc.predict_configurations, h))[0]) for h in HEIGHTS]
    np.testing.assert_array_equal(val.predictive[0],
                                  disc.pred_model[:, idx] + disc.pred_discrepancy[:, idx])
    np.testing.assert_array_equal(val.predictive[1], disc.pred_model[:, idx])
    # the saved band of a new measurement is the quantiles of eta + delta + eps
    draws = disc.pred_model + disc.pred_discrepancy + disc.pred_noise
    lo, hi = np.quantile(draws, [0.05, 0.95], axis=0)
    np.testing.assert_allclose(disc.band_lower, lo)
    np.testing.assert_allclose(disc.band_upper, hi)
    one = int(np.flatnonzero(disc.predict_configurations == 1.0)[0])
    np.testing.assert_allclose(disc.measured[one], [35.8256, 413.0807])


@pytest.mark.slow
def test_verification_u_num_is_the_two_grid_gci(run_dir):
    rec = VerificationRecord.read(load_step(run_dir / "steps" / "verify"))
    assert rec.levels == ("10 stations x 36 azimuth steps", "5 stations x 18 azimuth steps")
    assert rec.safety_factor == 3.0 and rec.formal_order == 2.0
    f1, f2 = rec.values[0], rec.values[1]
    # assumed order 2, ratio 2: u_num = GCI / Fs = |f2 - f1| / (2^2 - 1)
    np.testing.assert_allclose(rec.u_num, np.abs(f2 - f1) / 3.0, rtol=1e-12)
    assert np.all(rec.u_num / np.abs(f1) < 0.01)   # under 1 % of the load on this grid
    # a validation step's verification = {...}: the GCI at each of its conditions, at the
    # means of its inputs (here the posterior means of its from step)
    val = ValidationRecord.read(load_step(run_dir / "steps" / "val_disc"))
    disc = load_step(run_dir / "steps" / "disc")
    names = ["collective_deg", "k_pitch_link"]
    x = [[disc.scalars[f"mean/{n}"] for n in names]]
    for j, (h, om) in enumerate(zip(HEIGHTS, OMEGA, strict=True)):
        factory = rq.RotorDiscretization("gvpm", names_in=names, names_out=["thrust", "power"],
                                         fixed={"omega": om, "height_over_radius": h,
                                                "lateral_deg": -1.0, "longitudinal_deg": -1.0})
        ref = rq.verify_discretization(factory, [0, -1], x, ratio=2.0, formal_order=2.0)
        for p in range(2):
            np.testing.assert_allclose(val.u_num[p, j], ref.u_num[0], rtol=1e-9)
    assert "GCI at each condition" in val.u_num_source


@pytest.mark.slow
def test_report_has_the_vv_table(run_dir):
    html = (run_dir / "report" / "index.html").read_text()
    assert "V&amp;V 20 comparison error (with discrepancy)" in html \
        or "V&V 20 comparison error (with discrepancy)" in html
    assert "Solution verification: grid convergence index" in html
    assert "Held-out test" in html and "height_over_radius = 1 (held out)" in html


def bad(tmp_path: Path, steps: str) -> tuple[subprocess.CompletedProcess, Path]:
    path = tmp_path / "bad.toml"
    path.write_text(HEAD + textwrap.dedent(steps))
    return cli("run", path.name, "--out", "out", "--no-report", cwd=tmp_path), path


def line_of(path: Path, text: str) -> int:
    return next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if text in ln)


def test_refinement_ratio_at_most_one_names_its_line(tmp_path):
    proc, path = bad(tmp_path, """
        [[steps]]
        name = "verify"
        type = "verification"
        ratio = 1.0
        """)
    assert proc.returncode != 0
    assert f"line {line_of(path, 'ratio = 1.0')}" in proc.stderr
    assert "a refinement ratio > 1" in proc.stderr


def test_configuration_the_model_does_not_take_names_its_line(tmp_path):
    proc, path = bad(tmp_path, """
        [[steps]]
        name = "val"
        type = "validation"
        data = "heights"
        u_systematic = 1.0
        conditions = { height = [4.0, 1.0] }
        """)
    assert proc.returncode != 0
    assert f"line {line_of(path, 'conditions = ')}" in proc.stderr
    assert "an input of the rotor model 'gvpm'" in proc.stderr and "height" in proc.stderr


def test_verification_point_the_model_does_not_take_names_its_line(tmp_path):
    proc, path = bad(tmp_path, """
        [[steps]]
        name = "verify"
        type = "verification"
        points = [{ h_over_r = 1.0 }]
        """)
    assert proc.returncode != 0
    assert f"line {line_of(path, 'points = ')}" in proc.stderr
    assert "h_over_r" in proc.stderr


def test_two_levels_need_a_formal_order(tmp_path):
    proc, path = bad(tmp_path, """
        [[steps]]
        name = "verify"
        type = "verification"
        levels = 2
        """)
    assert proc.returncode != 0
    assert f"line {line_of(path, 'levels = 2')}" in proc.stderr
    assert "formal_order" in proc.stderr


def test_single_rows_without_a_stated_measurement_uncertainty(tmp_path):
    proc, path = bad(tmp_path, """
        [[steps]]
        name = "val"
        type = "validation"
        data = "heights"
        n_samples = 4
        conditions = { height_over_radius = [4.0, 1.0], omega = [224.6375, 223.0457] }
        """)
    assert proc.returncode != 0
    assert "single row at height_over_radius = 4, height_over_radius = 1" in proc.stderr
    assert "u_systematic = { thrust = ..., power = ... }" in proc.stderr
    # found while the step runs (the data decide), named by the file and the step's line
    assert f"{path.name}, line {line_of(path, '[[steps]]')}: step 'val'" in proc.stderr


DRIVER = """\
import math, sys
vals = dict((k.strip(), float(v)) for k, v in (ln.split("=") for ln in open("input.txt")))
a, n = vals["a"], int(vals["n_intervals"])
h = 1.0 / n
s = h * (0.5 * (1.0 + math.exp(a)) + sum(math.exp(a * i * h) for i in range(1, n)))
open(sys.argv[2], "w").write(f"{s!r} integral\\n")
"""

EXTERNAL = """\
[study]
name = "ext"
seed = 1

[model]
command = ["{python}", "driver.py", "{{params}}", "{{results}}"]
templates = ["input.txt"]
responses = ["integral"]
fixed = {{ n_intervals = 40 }}            # the grid the study runs

[parameters.a]
distribution = "normal"
mean = 1.0
std = 0.1

[[steps]]
name = "verify"
type = "verification"
field = "n_intervals"
ratio = 2
levels = 3
"""


def test_external_model_verified_through_its_template_field(tmp_path):
    """The trapezoidal rule for int_0^1 exp(a t) dt, n intervals in a template field: second
    order, and the GCI bounds the fine grid's true error."""
    (tmp_path / "driver.py").write_text(DRIVER)
    (tmp_path / "input.txt").write_text("a = {a}\nn_intervals = {n_intervals}\n")
    (tmp_path / "ext.toml").write_text(EXTERNAL.format(python=sys.executable))
    proc = cli("run", "ext.toml", "--out", "out", "--no-report", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    rec = VerificationRecord.read(load_step(tmp_path / "out" / "steps" / "verify"))
    assert rec.levels == ("n_intervals = 40", "n_intervals = 20", "n_intervals = 10")
    exact = np.e - 1.0                                   # a = 1, the mean
    fine = float(rec.values[0, 0, 0])
    # trapezoid: error = h^2 / 12 (f'(1) - f'(0)) + O(h^4) = (e - 1) / (12 n^2)
    assert abs((fine - exact) - (np.e - 1.0) / (12 * 40**2)) < 1e-7
    assert abs(float(rec.observed_order[0, 0]) - 2.0) < 1e-3
    gci_abs = float(rec.gci_fine[0, 0]) * abs(fine)      # Fs |e21| / (r^p - 1)
    assert abs(fine - exact) <= gci_abs
    np.testing.assert_allclose(rec.u_num[0, 0], gci_abs / 1.25, rtol=1e-12)


LINEAR = """\
[study]
name = "lin"
seed = 11

[model]
command = ["unused"]
responses = ["y"]
fixed = { c = 0.0 }

[parameters.a]
distribution = "normal"
mean = 1.0
std = 0.2

[data.obs]
c = [0.0, 0.0, 0.0, 2.0, 2.0]
y = [2.1, 1.9, 2.3, 5.0, 5.4]

[[steps]]
name = "val"
type = "validation"
data = "obs"
conditions = { c = [0.0, 2.0] }
u_num = 0.05
u_systematic = 0.1
n_samples = 400
"""


def test_repeats_and_input_distributions_by_hand(tmp_path):
    """y = 2 a + c, a ~ N(1, 0.2), no ``from``: S is the LHS mean of 2 a + c, u_input its std,
    u_D = sqrt(s^2 / n + u_sys^2) from the repeats; the record equals that, by hand."""
    from rotoruq.model import FunctionModel
    from rotoruq.study.runner import run_study

    def factory(inputs, responses, fixed):
        return FunctionModel(lambda x: 2.0 * x[:, :1] + fixed["c"], inputs, responses)

    (tmp_path / "lin.toml").write_text(LINEAR)
    run = run_study(tmp_path / "lin.toml", out=tmp_path / "out", model_factory=factory)
    rec = ValidationRecord.read(run["val"])
    assert rec.predictions == ("input distributions",)
    assert rec.n_repeats.tolist() == [3, 2]
    obs = {0: np.array([2.1, 1.9, 2.3]), 1: np.array([5.0, 5.4])}
    for j, c in enumerate((0.0, 2.0)):
        s = rec.predictive[0, :, j, 0]
        a = (s - c) / 2.0                      # the same LHS sample at both conditions
        np.testing.assert_allclose(a, rec.predictive[0, :, 0, 0] / 2.0, rtol=1e-12)
        assert abs(a.mean() - 1.0) < 0.01 and abs(a.std(ddof=1) - 0.2) < 0.01
        u_d = np.sqrt(obs[j].var(ddof=1) / obs[j].size + 0.1**2)
        u_val = np.sqrt(0.05**2 + s.std(ddof=1) ** 2 + u_d**2)
        e = s.mean() - obs[j].mean()
        np.testing.assert_allclose(rec.u_data[0, j, 0], u_d, rtol=1e-12)
        np.testing.assert_allclose(rec.u_val[0, j, 0], u_val, rtol=1e-12)
        np.testing.assert_allclose(rec.comparison_error[0, j, 0], e, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(rec.error_ratio[0, j, 0], abs(e) / u_val, rtol=1e-12)
        assert rec.area_metric[0, j, 0] == rq.area_metric(s, obs[j])


def test_u_num_by_reference_to_a_verification_step(tmp_path):
    """``u_num = "verify.u_num"``: the largest u_num over the verification step's points."""
    from rotoruq.model import FunctionModel
    from rotoruq.study.runner import run_study

    def factory(inputs, responses, fixed):
        n = int(fixed["n_intervals"])

        def f(x):
            t = np.linspace(0.0, 1.0, n + 1)
            return np.trapezoid(np.exp(x[:, :1] * t), t, axis=1)[:, None] + fixed["c"]

        return FunctionModel(f, inputs, responses)

    text = LINEAR.replace("fixed = { c = 0.0 }", "fixed = { c = 0.0, n_intervals = 8 }")
    text = text.replace('[[steps]]\nname = "val"', '[[steps]]\nname = "verify"\n'
                        'type = "verification"\nfield = "n_intervals"\n'
                        'points = [{ c = 0.0 }, { c = 2.0 }]\n\n[[steps]]\nname = "val"')
    text = text.replace("u_num = 0.05", 'u_num = "verify.u_num"')
    (tmp_path / "lin.toml").write_text(text)
    run = run_study(tmp_path / "lin.toml", out=tmp_path / "out", model_factory=factory)
    ver = VerificationRecord.read(run["verify"])
    val = ValidationRecord.read(run["val"])
    assert np.all(val.u_num == ver.u_num.max(axis=0))
    assert "verify" in val.u_num_source


COUPLED = """\
[study]
name = "coupled"
seed = 4

[model]
command = ["unused"]
responses = ["y", "v"]

[parameters.a]
distribution = "normal"
mean = 1.0
std = 0.5

[data.obs]
c = [0.0, 1.0, 2.0, 3.0]
w = [1.0, 1.1, 1.2, 1.3]
y = [1.0, 2.05, 3.1, 4.2]
v = [1.0, 1.1, 1.2, 1.3]

[[steps]]
name = "disc"
type = "bayes_calibration"
data = "obs"
noise_std = { y = 0.05, v = 0.01 }
configuration = "c"
couple = { w = "w" }
predict_at = [3.0, 1.5]
discrepancy = { amplitude_scale = { y = 0.2, v = 0.01 }, length_scale = 1.0 }
emulator = "none"
n_samples = 400
burn_in = 100
"""


def test_coupled_inputs_follow_the_configuration_and_runs_repeat_bitwise(tmp_path):
    """y = a + c, v = w with w coupled to the data's w column: the model's v at a predicted
    configuration is w interpolated there (1.3 at the held-out c = 3, 1.15 at c = 1.5); the
    row at c = 3 is held out; the same seed gives the same record bit for bit."""
    from rotoruq.model import FunctionModel
    from rotoruq.study.runner import run_study

    def factory(inputs, responses, fixed):
        def f(x):
            v = {**fixed, **{n: x[:, i] for i, n in enumerate(inputs)}}
            return np.column_stack([v["a"] + v.get("c", 0.0), v.get("w", 1.0) + 0 * x[:, 0]])

        return FunctionModel(f, inputs, responses)

    (tmp_path / "c.toml").write_text(COUPLED)
    recs = []
    for out in ("o1", "o2"):
        run = run_study(tmp_path / "c.toml", out=tmp_path / out, model_factory=factory)
        recs.append(DiscrepancyRecord.read(run["disc"]))
    rec = recs[0]
    assert rec.data_configurations.tolist() == [0.0, 1.0, 2.0]
    assert rec.held_out.tolist() == [3.0]
    at = rec.predict_configurations.tolist()
    assert at == [0.0, 1.0, 1.5, 2.0, 3.0]
    np.testing.assert_allclose(rec.pred_model[:, at.index(3.0), 1], 1.3, rtol=1e-12)
    np.testing.assert_allclose(rec.pred_model[:, at.index(1.5), 1], 1.15, rtol=1e-12)
    np.testing.assert_allclose(rec.measured[at.index(3.0)], [4.2, 1.3])
    assert np.isnan(rec.measured[at.index(1.5)]).all()      # no data there
    for f in ("chains", "hyper_chains", "pred_model", "pred_discrepancy", "band_lower"):
        np.testing.assert_array_equal(getattr(recs[0], f), getattr(recs[1], f), err_msg=f)


@pytest.mark.parametrize("extra, needle, expected", [
    ("refine = { n_samples = 10 }\n", "refine = ", "no refine = {...} beside discrepancy"),
])
def test_an_emulator_a_discrepancy_cannot_take_names_the_line(tmp_path, extra, needle,
                                                              expected):
    from rotoruq.errors import InputFileError
    from rotoruq.study.schema import load_study

    text = COUPLED.replace('emulator = "none"\n', extra)
    p = tmp_path / "c.toml"
    p.write_text(text)
    with pytest.raises(InputFileError) as info:
        load_study(p)
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if ln.startswith(needle))
    assert f"line {line}" in str(info.value) and expected in str(info.value), str(info.value)
