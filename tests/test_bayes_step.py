"""The ``bayes_calibration`` step of a study: several chains, arviz-standard diagnostics, the
noise model (stated and calibrated), the emulator's adequacy, the self-check, the exported
chains and the errors of bad study files, on a linear-Gaussian model whose posterior is known
in closed form."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import numpy as np
import pytest

from rotoruq.errors import InputFileError
from rotoruq.methods.mcmc.export import read_chains
from rotoruq.model import FunctionModel
from rotoruq.steps.bayes_calibration import BayesRecord, bayes_tables, bayes_warnings
from rotoruq.study.runner import run_study
from rotoruq.study.schema import load_study

# y1 = a + b, y2 = a - b; prior a, b ~ N(0, 1); data rows below with noise std S
S = 0.2
Y1 = [1.1, 0.9, 1.25, 0.8, 1.05, 0.95]
Y2 = [0.3, 0.1, 0.25, 0.05, 0.2, 0.15]


def factory(inputs, responses, fixed):
    def f(x):
        full = {n: x[:, i] for i, n in enumerate(inputs)}
        a, b = full["a"], full["b"]
        y = {"y1": a + b, "y2": a - b}
        return np.column_stack([y[r] for r in responses])

    return FunctionModel(f, inputs, responses)


def study_text(step: str, y1=Y1, y2=Y2) -> str:
    return textwrap.dedent(f"""\
        [study]
        name = "lin"
        seed = 11

        [model]
        command = ["unused"]
        responses = ["y1", "y2"]

        [parameters.a]
        distribution = "normal"
        mean = 0.0
        std = 1.0

        [parameters.b]
        distribution = "normal"
        mean = 0.0
        std = 1.0

        [data.obs]
        y1 = {[float(v) for v in y1]}
        y2 = {[float(v) for v in y2]}
        """) + textwrap.dedent(step)


BAYES = """
[[steps]]
name = "bayes"
type = "bayes_calibration"
emulator = "none"
noise_std = { y1 = 0.2, y2 = 0.2 }
n_samples = 3000
burn_in = 300
"""


def exact_posterior(y1, y2, s=S):
    """Linear-Gaussian posterior of (a, b): prior N(0, I), y = G theta + noise N(0, s^2)."""
    g = np.vstack([np.tile([1.0, 1.0], (len(y1), 1)), np.tile([1.0, -1.0], (len(y2), 1))])
    y = np.concatenate([y1, y2])
    cov = np.linalg.inv(np.eye(2) + g.T @ g / s**2)
    return cov @ g.T @ y / s**2, cov


def run(tmp_path: Path, text: str, out: str = "out"):
    p = tmp_path / "study.toml"
    p.write_text(text)
    return run_study(p, out=tmp_path / out, model_factory=factory)


def test_chains_diagnostics_and_export_match_the_closed_form(tmp_path):
    res = run(tmp_path, study_text(BAYES))["bayes"]
    rec = BayesRecord.read(res)
    mean, cov = exact_posterior(Y1, Y2)
    assert rec.n_chains == 4 and rec.names_in == ("a", "b")
    assert res.arrays["chain"].shape == (4 * rec.n_draws, 2)
    # posterior mean within 5 MCSE (the chains' own error) and the std within 10 %
    assert np.all(np.abs(rec.mean - mean) < 5 * rec.mcse_mean)
    np.testing.assert_allclose(rec.std, np.sqrt(np.diag(cov)), rtol=0.1)
    assert rec.correlation[0, 1] == pytest.approx(cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1]),
                                                  abs=0.05)
    assert np.all(rec.rhat_bulk < 1.01) and np.all(rec.ess_tail > 200)
    assert rec.noise_std.tolist() == [S, S]
    assert "noise std per response (y1 0.2, y2 0.2)" in rec.noise_model
    # the chains exported for arviz are the saved chain, chain by chain
    # chains.nc with xarray and h5netcdf installed, else chains.npz
    files = sorted((tmp_path / "out" / "steps" / "bayes").glob("chains.*"))
    assert len(files) == 1
    exported = read_chains(files[0])
    assert exported.names == ("a", "b")
    assert np.array_equal(exported.chains.reshape(-1, 2), res.arrays["chain"])
    titles = [t.title for t in bayes_tables(res, {})]
    assert "Convergence (4 chains)" in titles
    assert "Noise model and emulator adequacy" in titles
    # the flat view keeps the keys of the step's numbers, derived from the record
    assert res.get("mean/a") == rec.mean[0] and res.get("corr/a/b") == rec.correlation[0, 1]
    assert res.get("noise_std/y2") == S and res.get("skewness/b") == rec.skewness[1]
    assert res.get("map/a") == rec.map_point[0] and res.get("std_ratio/b") == rec.std_ratio[1]
    assert res.get("input_std/a") == 1.0 and res.get("n_chains") == 4
    assert not json.loads((tmp_path / "out" / "steps" / "bayes" / "result.json").read_text(
    ))["scalars"]


def test_a_calibration_saved_before_its_record_still_reads(tmp_path):
    """Bayes and CUU steps saved with flat scalars only (by a rotoruq before their records)
    load; their tables show the flat view with the reason; warnings, reasons, the noise note
    and the self-check verdict have nothing to read and say nothing."""
    from rotoruq.reference.causes import calibration_design, input_recovery, target_consistency
    from rotoruq.report.html import run_verdict
    from rotoruq.report.steptables import step_tables
    from rotoruq.results import StepResult, load_step, save_step
    from rotoruq.steps.bayes_calibration import strong_correlations

    bayes = load_step(save_step(StepResult("bayes", "bayes_calibration", {
        "mean/a": 1.0, "std_ratio/a": 0.95, "pileup_hi/a": 0.4, "corr/a/b": 0.9,
        "noise_std/y1": 0.2, "self_check_passed": 0.0}, {"data": np.arange(6.0)[:, None]},
        meta={"columns": {"data": ["y1"]}}), tmp_path))
    (table,) = step_tables(bayes)
    assert ("mean/a", 1.0) in table.rows and "saved without a BayesRecord" in table.note
    assert bayes_warnings(bayes, {}) == [] and strong_correlations(bayes) == []
    assert calibration_design(bayes) == []
    assert "data-failed='0' data-checked='0'" in run_verdict({"s": {"bayes": bayes}})
    cuu = load_step(save_step(StepResult("cuu", "cuu", {
        "std/a": 0.1, "target_std/y1": 1.0, "target_std/y2": 2.0},
        {"outputs_calibrated": np.arange(8.0).reshape(4, 2)},
        meta={"columns": {"outputs_calibrated": ["y1", "y2"]}}), tmp_path))
    assert target_consistency(cuu, {}) == [] and input_recovery(cuu, bayes, {}) == ({}, [])


def test_same_seed_same_chains_bitwise(tmp_path):
    a = run(tmp_path, study_text(BAYES), "a")["bayes"]
    b = run(tmp_path, study_text(BAYES), "b")["bayes"]
    assert a.arrays["chain"].tobytes() == b.arrays["chain"].tobytes()
    assert dict(a.scalars) == dict(b.scalars)


def test_noise_multipliers_find_the_noise_the_data_carry(tmp_path):
    """Data with noise std 0.4 calibrated with a stated 0.2: each response's variance
    multiplier covers the ratio of the residual variance at the exact posterior mean to the
    stated variance (about 4)."""
    rng = np.random.default_rng(5)
    n = 40
    y1 = (1.0 + 0.4 * rng.standard_normal(n)).round(4)
    y2 = (0.2 + 0.4 * rng.standard_normal(n)).round(4)
    step = BAYES + 'noise_multipliers = "per_response"\n'
    res = run(tmp_path, study_text(step, y1, y2))["bayes"]
    rec = BayesRecord.read(res)
    assert len(rec.multiplier_names) == 2
    mean, _ = exact_posterior(y1, y2)
    for k, resid in enumerate((y1 - mean.sum(), y2 - (mean[0] - mean[1]))):
        ratio = np.mean(resid**2) / S**2
        assert rec.multiplier_lower[k] < ratio < rec.multiplier_upper[k]
        assert 2.0 < rec.multiplier_mean[k] < 8.0
    assert "noise variance multipliers calibrated (per_response" in rec.noise_model
    assert any(t.title.startswith("Noise variance multipliers") for t in bayes_tables(res, {}))


def test_self_check_is_saved_and_stated(tmp_path):
    step = BAYES + "self_check = 30\n"
    res = run(tmp_path, study_text(step))["bayes"]
    rec = BayesRecord.read(res)
    assert rec.sbc_p_value.shape == (2,) and rec.sbc_rank_histogram.shape[0] == 2
    assert rec.sbc_rank_histogram.sum() == 2 * 30
    assert np.all((rec.sbc_coverage_90 >= 0) & (rec.sbc_coverage_90 <= 1))
    assert isinstance(rec.self_check_passed, bool) and rec.self_check_reason
    verdict = "passed" if rec.self_check_passed else "FAILED"
    assert f"Self-check (simulation-based calibration): {verdict}" in [
        t.title for t in bayes_tables(res, {})]
    failed = any("self-check" in w for w in bayes_warnings(res, {}))
    assert failed is (not rec.self_check_passed)


@pytest.mark.parametrize("extra, needle, expected", [
    ("", "noise_std = {", "a noise std > 0"),
    ('noise_multipliers = ["y3"]\n', "noise_multipliers", "responses this step calibrates"),
    ("self_check = 10\n", "self_check", "self_check without noise_multipliers"),
])
def test_bad_bayes_options_name_the_line(tmp_path, extra, needle, expected):
    text = study_text(BAYES + extra)
    if not extra:
        text = text.replace("y2 = 0.2 }", "y2 = 0.0 }")
    if "self_check" in extra:
        text += 'noise_multipliers = "one"\n'
    p = tmp_path / "study.toml"
    p.write_text(text)
    with pytest.raises(InputFileError) as info:
        load_study(p)
    line = next(i for i, ln in enumerate(text.splitlines(), 1) if ln.startswith(needle))
    assert f"line {line}" in str(info.value) and expected in str(info.value), str(info.value)


def test_self_check_needs_a_stated_noise(tmp_path):
    text = study_text(BAYES.replace("noise_std = { y1 = 0.2, y2 = 0.2 }\n", "")
                      + "self_check = 10\n")
    p = tmp_path / "study.toml"
    p.write_text(text)
    with pytest.raises(InputFileError, match="noise_std per response with self_check"):
        load_study(p)


PROPAGATE = BAYES + """
[[steps]]
name = "push"
type = "sampling"
from = "bayes.posterior"
n_samples = 500
"""


def test_posterior_propagates_jointly_by_default(tmp_path):
    """Only y1 = a + b observed (a and b strongly anti-correlated), y2 = a - b pushed through
    the posterior: the draws are the chain's own rows (thinned), so the spread of y2 is the
    joint one, sqrt(c^T Sigma c) of the chain's covariance with c = (1, -1); independent
    normals of the same marginals misstate it by the correlation they drop, and say so."""
    steps = PROPAGATE.replace('emulator = "none"', 'emulator = "none"\nresponses = ["y1"]')
    text = study_text(steps + '\n[[steps]]\nname = "normals"\ntype = "sampling"\n'
                      'from = "bayes.posterior"\nn_samples = 500\n'
                      'propagation = "independent_normals"\n')
    run_ = run(tmp_path, text)
    bayes, push, normals = run_["bayes"], run_["push"], run_["normals"]
    chain = bayes.arrays["chain"]
    rows = {tuple(r) for r in chain}
    assert all(tuple(r) in rows for r in push.arrays["inputs"])
    assert push.meta["propagation"] == "joint" and not push.meta.get("dropped_correlation")
    c = np.cov(chain, rowvar=False)
    joint = np.sqrt(c[0, 0] + c[1, 1] - 2 * c[0, 1])
    assert push.get("std/y2") == pytest.approx(joint, rel=0.1)
    indep = np.sqrt(c[0, 0] + c[1, 1])
    assert normals.get("std/y2") == pytest.approx(indep, rel=0.1)
    assert abs(indep / joint - 1) > 0.2  # the test tells the two apart (exact: 0.29)
    p, q, rho = normals.meta["dropped_correlation"]
    assert (p, q) == ("a", "b") and rho == pytest.approx(np.corrcoef(chain.T)[0, 1])
    from rotoruq.steps.forward_check import propagation_warnings

    (msg,) = propagation_warnings(normals, {})
    assert "independent_normals" in msg and f"rho = {rho:+.2f}" in msg


def test_forward_check_compares_with_every_repeat(tmp_path):
    """Three repeats of one condition: the measured value is their mean, with its standard
    error; the predictive std adds the calibration's noise of that mean, noise / sqrt(3)."""
    text = study_text(BAYES + 'data = "obs"\n') + textwrap.dedent("""
        [data.repeats]
        c = [1.0, 1.0, 1.0, 2.0]
        y1 = [1.0, 1.3, 0.7, 5.0]

        [[steps]]
        name = "check"
        type = "forward_check"
        from = "bayes.posterior"
        data = "repeats"
        responses = ["y1"]
        n_samples = 400
        sweep = { c = [1.0] }
        """)

    def factory_c(inputs, responses, fixed):
        return factory(inputs, responses, {})

    p = tmp_path / "study.toml"
    p.write_text(text)
    res = run_study(p, out=tmp_path / "o", model_factory=factory_c)["check"]
    assert res.get("data/y1@1") == pytest.approx(1.0)
    assert res.get("data_n/y1@1") == 3
    assert res.get("data_sem/y1@1") == pytest.approx(0.3 / np.sqrt(3))
    tot = np.hypot(res.get("pp_std/y1@1"), 0.2 / np.sqrt(3))
    assert res.get("pp_nstd/y1@1") == pytest.approx(abs(1.0 - res.get("pp_mean/y1@1")) / tot)
    assert res.meta["propagation"] == "joint"


def test_calibrating_the_same_data_twice_is_an_error_naming_both_lines(tmp_path):
    stage2 = BAYES.replace('name = "bayes"', 'name = "again"') + 'from = "bayes.posterior"\n'
    text = study_text(BAYES + stage2)
    p = tmp_path / "study.toml"
    p.write_text(text)
    with pytest.raises(InputFileError) as info:
        load_study(p)
    lines = [i for i, ln in enumerate(text.splitlines(), 1) if ln == "[[steps]]"]
    msg = str(info.value)
    assert f"line {lines[1]}" in msg and f"(line {lines[0]})" in msg
    assert "already calibrates y1, y2 of data set 'obs'" in msg and "reuse_data" in msg
    # only the new observations: fine; or the reuse stated on purpose
    load_study(_write(tmp_path, study_text(BAYES + stage2 + 'responses = ["y2"]\n').replace(
        'emulator = "none"\nnoise_std', 'emulator = "none"\nresponses = ["y1"]\nnoise_std', 1)))
    study = load_study(_write(tmp_path, study_text(BAYES + stage2 + "reuse_data = true\n")))
    assert study.steps[1].options["reuse_data"] is True


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "s2.toml"
    p.write_text(text)
    return p
