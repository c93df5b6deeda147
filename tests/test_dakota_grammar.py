"""Dakota's grammar as Dakota reads it (issue 32): every problem of a deck at once, output-only
keywords noted, Dakota's layouts and aliases, the forms its variables take, its direct test
functions. Decks written here (Dakota's own test suite: tests/test_dakota_suite.py); the
command line in a subprocess, as a user runs it."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from rotoruq.study.deck import DeckProblems, parse_deck, translate_deck
from rotoruq.study.schema import parse_study


def cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rotoruq.study.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


BAD = """\
environment
  graphics
method
  sampling samples 20 seed 3
    refinement_samples 5
variables
  normal_uncertain 2 means 0 0 std_deviations 1 1 descriptors 'x1' 'x2'
  discrete_design_set
    integer 1 elements 1 2 3
  binomial_uncertain 1 prob_per_trial 0.5 num_trials 4
interface
  direct analysis_drivers 'text_book'
responses
  response_functions 1
  field_responses 1
  no_gradients no_hessians
"""


def test_every_problem_of_a_deck_is_reported_at_once_through_the_cli(tmp_path):
    (tmp_path / "bad.in").write_text(BAD)
    proc = cli("dakota", "import", "bad.in", "-o", "s.toml", cwd=tmp_path)
    assert proc.returncode != 0 and not (tmp_path / "s.toml").exists()
    assert "Traceback" not in proc.stderr
    assert "4 problems, each with its line:" in proc.stderr, proc.stderr
    for line, kw in ((5, "refinement_samples"), (8, "discrete_design_set"),
                     (10, "binomial_uncertain"), (15, "field_responses")):
        assert re.search(rf"line {line}: expected .*'{kw}'", proc.stderr), proc.stderr
    # the attributes of an untranslated variable group are not listed again
    assert "'elements'" not in proc.stderr and "'prob_per_trial'" not in proc.stderr


OUTPUT_ONLY = """\
environment
  graphics
  tabular_data tabular_data_file 'x.dat'
  results_output hdf5
  output_precision 16
method
  max_iterations 50
  output verbose
  nl2sol
    convergence_tolerance 1e-8
variables
  continuous_design 2
    lower_bounds 3*-2.0
    descriptors 'x1' 'x2'
    upper_bounds 2 * 2.0
    initial_point -1.2 1.0
interface
  asynch evaluation_concurrency 4
  deactivate restart_file
  direct analysis_drivers 'rosenbrock'
responses
  calibration_terms 1
  analytic_gradients
  no_hessians
"""


def test_output_only_keywords_are_one_note_and_layouts_dakota_accepts_import(tmp_path):
    """`max_iterations` before `nl2sol`, `descriptors` before bounds, `N*value` with and
    without blanks, `asynch`: all read; what only shapes Dakota's output or scheduling is
    one note with the lines. nl2sol with no data file: the responses are the residuals."""
    (tmp_path / "ok.in").write_text(OUTPUT_ONLY.replace("3*-2.0", "2*-2.0"))
    proc = cli("dakota", "import", "ok.in", "-o", "s.toml", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    notes = [ln for ln in proc.stderr.splitlines() if ln.startswith("note:")]
    assert len(notes) == 1, proc.stderr
    for kw, line in (("graphics", 2), ("tabular_data", 3), ("results_output", 4),
                     ("hdf5", 4), ("output", 8), ("verbose", 8),
                     ("evaluation_concurrency", 18), ("deactivate", 19),
                     ("restart_file", 19)):
        assert f"{kw} (line {line})" in notes[0], notes[0]
    doc = tomllib.loads((tmp_path / "s.toml").read_text())
    assert doc["model"] == {"function": "rosenbrock", "responses": ["least_sq_term_1"]}
    step = doc["steps"][0]
    assert (step["type"], step["max_iterations"], step["tolerance"]) == (
        "least_squares", 50, 1e-8)
    assert step["x0"] == {"x1": -1.2, "x2": 1.0} and "data" not in step
    assert doc["parameters"]["x2"] == {"distribution": "uniform", "lower": -2.0, "upper": 2.0}


def test_a_wrong_count_after_a_repeat_names_the_line():
    with pytest.raises(DeckProblems) as err:
        translate_deck(parse_deck(OUTPUT_ONLY, "ok.in"))
    assert err.value.line == 12 and "2 values of lower_bounds" in str(err.value)


def test_lognormal_forms_and_the_correlation_matrix_in_dakotas_order(tmp_path):
    """Dakota 6.24's `parameters option_N` forms; the correlation matrix is in Dakota's order
    of types (normal before lognormal), whatever the deck's order."""
    deck = parse_deck("""method
  local_reliability
variables
  lognormal_uncertain 2
    parameters option_3 lambdas 0.1 0.2 zetas 0.3 0.4
    descriptors 'l1' 'l2'
  normal_uncertain = 1 nuv_means 5 nuv_std_deviations 1 descriptors 'n'
  uncertain_correlation_matrix
    1 0.5 0
    0.5 1 0
    0 0 1
interface
  direct analysis_drivers 'text_book'
responses
  response_functions 1 analytic_gradients no_hessians
""", tmp_path / "ln.in")
    study = parse_study(translate_deck(deck).text, tmp_path / "ln.toml")
    assert study.parameter("l1").kind == "lognormal"
    assert dict(study.parameter("l2").params) == {"lambda": 0.2, "zeta": 0.4}
    assert study.correlation.parameters == ("n", "l1", "l2")
    assert study.correlation.matrix[0][1] == 0.5
    assert [p.name for p in study.parameters] == ["n", "l1", "l2"]  # Dakota's order


def test_an_unknown_direct_function_lists_those_rotoruq_has(tmp_path):
    (tmp_path / "d.in").write_text(BAD.replace("text_book", "no_such_fn")
                                   .replace("    refinement_samples 5\n", "")
                                   .replace("  discrete_design_set\n    integer 1 elements 1 2 3\n",
                                            "")
                                   .replace("  binomial_uncertain 1 prob_per_trial 0.5 "
                                            "num_trials 4\n", "")
                                   .replace("  field_responses 1\n", ""))
    proc = cli("dakota", "import", "d.in", "-o", "s.toml", cwd=tmp_path)
    assert proc.returncode != 0
    assert "line 8: expected one of Dakota's test functions rotoruq has" in proc.stderr
    assert "rosenbrock" in proc.stderr and "'no_such_fn' is not one" in proc.stderr


def test_a_fork_driver_named_as_a_test_function_is_the_built_in_one(tmp_path):
    (tmp_path / "f.in").write_text("""method
  sampling samples 10 seed 2
    response_levels 0.5 1.0 compute reliabilities complementary distribution
variables
  uniform_uncertain 2 lower_bounds 0 0 upper_bounds 1 1
interface
  fork analysis_drivers 'text_book'
responses
  response_functions 1 no_gradients no_hessians
""")
    proc = cli("dakota", "import", "f.in", "-o", "s.toml", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "the fork driver 'text_book' (line 7) is not a program here" in proc.stderr
    step = tomllib.loads((tmp_path / "s.toml").read_text())["steps"][0]
    assert step["response_levels"] == {"response_fn_1": [0.5, 1.0]}
    assert (step["compute"], step["distribution"]) == ("reliabilities", "ccdf")
    run = cli("--quiet", "run", "s.toml", "--out", "out", "--no-report", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
