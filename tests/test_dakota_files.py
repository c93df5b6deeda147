"""Dakota parameters/results files: round trips of every format and clear errors."""

from __future__ import annotations

import time

import numpy as np
import pytest

from rotoruq.errors import InputFileError, ParameterError
from rotoruq.evaluation.dakota_files import (
    format_parameters,
    format_results,
    parse_parameters,
    parse_parameters_batch,
    parse_results,
    read_parameters,
    read_results,
    write_parameters,
    write_results,
)

# A parameters file laid out as Dakota writes it (standard format, no metadata line).
DAKOTA_STANDARD = """\
                                          2 variables
                      5.400000000000000e+00 collective_deg
                      1.500000000000000e+01 k_pitch_link
                                          3 functions
                                          1 ASV_1:thrust
                                          3 ASV_2:torque
                                          7 ASV_3:power
                                          2 derivative_variables
                                          1 DVV_1:collective_deg
                                          2 DVV_2:k_pitch_link
                                          1 analysis_components
                                  rotor.inp AC_1:mbdyn
                                          12 eval_id
"""

DAKOTA_APREPRO = """\
                    { DAKOTA_VARS     =                      2 }
                    { collective_deg  =  5.400000000000000e+00 }
                    { k_pitch_link    =  1.500000000000000e+01 }
                    { DAKOTA_FNS      =                      1 }
                    { ASV_1:thrust    =                      1 }
                    { DAKOTA_DER_VARS =                      2 }
                    { DVV_1:collective_deg =                 1 }
                    { DVV_2:k_pitch_link =                   2 }
                    { DAKOTA_AN_COMPS =                      0 }
                    { DAKOTA_EVAL_ID  =                  1:4:2 }
"""


def test_read_dakota_standard_example():
    p = parse_parameters(DAKOTA_STANDARD, "params.in")
    assert p.format == "standard"
    assert p.variables == {"collective_deg": 5.4, "k_pitch_link": 15.0}
    assert p.asv == {"thrust": 1, "torque": 3, "power": 7}
    assert p.dvv == ("collective_deg", "k_pitch_link")
    assert p.analysis_components == (("rotor.inp", "mbdyn"),)
    assert p.eval_id == "12"
    assert p.metadata == ()
    np.testing.assert_array_equal(p.values(), [5.4, 15.0])


def test_read_dakota_aprepro_example():
    p = parse_parameters(DAKOTA_APREPRO, "params.in")
    assert p.format == "aprepro"
    assert p.variables == {"collective_deg": 5.4, "k_pitch_link": 15.0}
    assert p.asv == {"thrust": 1}
    assert p.dvv == ("collective_deg", "k_pitch_link")
    assert p.eval_id == "1:4:2"


@pytest.mark.parametrize("fmt", ["standard", "aprepro"])
@pytest.mark.parametrize("metadata", [None, [], ["seconds", "memory"]])
def test_parameters_round_trip_exact(tmp_path, fmt, metadata):
    rng = np.random.default_rng(3)
    vals = {f"x{i}": float(v) for i, v in enumerate(rng.normal(size=5) * 10.0 ** rng.integers(
        -300, 300, size=5))}
    vals["n_blades"] = 4
    vals["label"] = "naca0012"
    vals["tiny"] = 5e-324
    path = write_parameters(tmp_path / "p.in", vals, {"thrust": 1, "torque": 3},
                            analysis_components=[("a.inp", "drv")], eval_id=7,
                            metadata=metadata, format=fmt)
    p = read_parameters(path)
    assert p.format == fmt
    assert p.variables == vals  # floats survive exactly (17 significant digits)
    for k in vals:
        assert type(p.variables[k]) is type(vals[k])
    assert p.asv == {"thrust": 1, "torque": 3}
    assert p.dvv == tuple(k for k, v in vals.items() if isinstance(v, float))
    assert p.analysis_components == (("a.inp", "drv"),)
    assert p.eval_id == "7"
    assert p.metadata == tuple(metadata or ())


def test_standard_layout_matches_dakota():
    text = format_parameters({"collective_deg": 5.4}, ["thrust"], eval_id=3)
    lines = text.splitlines()
    assert lines[0].split() == ["1", "variables"]
    assert lines[1].split() == ["5.4000000000000004e+00", "collective_deg"]
    assert lines[2:] == [
        f"{'1':>24} functions", f"{'1':>24} ASV_1:thrust", f"{'1':>24} derivative_variables",
        f"{'1':>24} DVV_1:collective_deg", f"{'0':>24} analysis_components",
        f"{'3':>24} eval_id",
    ]
    assert format_parameters({"a": 1.0}, ["f"], metadata=["t"]).splitlines()[-2:] == [
        f"{'1':>24} metadata", f"{'t':>24} MD_1"]  # Dakota 6.24: "seconds MD_1"


@pytest.mark.parametrize(
    "text, line, words",
    [
        ("2 variables\n1.0 a\n", None, "2 variable lines"),
        ("1 variables\n1.0 a\n1 functions\n9 ASV_1:f\n", 4, "ASV"),
        ("1 variables\n1.0D+00 a\n", 2, "Fortran"),
        ("1 variables\n1.0 a b\n", 2, "'value tag'"),
        ("1 vars\n", 1, "variables"),
        ("1 variables\n1.0 a\n0 functions\n0 derivative_variables\n0 analysis_components\n",
         None, "eval_id"),
        ("1 variables\n1.0 a\n0 functions\n0 derivative_variables\n0 analysis_components\n"
         "1 eval_id\n3 extra\n", 7, "end of file"),
        ("", None, "parameters file"),
    ],
)
def test_parameters_errors_name_file_and_line(text, line, words):
    with pytest.raises(InputFileError) as err:
        parse_parameters(text, "case/params.in")
    assert err.value.path == "case/params.in"
    assert err.value.line == line
    assert words in str(err.value)


def test_results_values_gradients_hessians_round_trip(tmp_path):
    vals = np.array([2214.0123456789, -1734.5e-3, 1e-300])
    grads = np.array([[1.0, -2.5e3], [3.25, 4e-7]])
    hess = np.array([[[1.0, 2.0], [2.0, 5.5]]])
    path = write_results(tmp_path / "r.out", vals, ["thrust", "torque", "power"],
                         gradients=grads, hessians=hess)
    r = read_results(path, names_out=["thrust", "torque", "power"], asv=[3, 7, 1], n_dvv=2)
    assert not r.failed
    np.testing.assert_array_equal(r.values, vals)
    assert r.names_out == ("thrust", "torque", "power")
    np.testing.assert_array_equal(r.gradients, grads)
    np.testing.assert_array_equal(r.hessians, hess)


def test_results_dakota_layouts():
    # unlabeled values, gradient brackets without spaces, Hessian rows over several lines
    text = "1.5\n-2.0e+01\n[1.0 2.0]\n[ 3.0 4.0 ]\n[[ 1 0\n   0 1 ]]\n[[2 1 1 2]]\n"
    r = parse_results(text)
    np.testing.assert_array_equal(r.values, [1.5, -20.0])
    assert r.names_out == (None, None)
    np.testing.assert_array_equal(r.gradients, [[1, 2], [3, 4]])
    np.testing.assert_array_equal(r.hessians, [np.eye(2), [[2, 1], [1, 2]]])
    # several values on one line, labels optional per value
    r = parse_results("1.0 a 2.0 3.0 c\n")
    np.testing.assert_array_equal(r.values, [1, 2, 3])
    assert r.names_out == ("a", None, "c")


@pytest.mark.parametrize("text", ["fail\n", "FAIL\n", "Fail: solver diverged\n", "  fail"])
def test_fail_marker_any_case(text):
    assert parse_results(text, names_out=["thrust"]).failed


def test_labels_reorder_and_mismatch():
    r = parse_results("2.0 torque\n1.0 thrust\n", names_out=["thrust", "torque"])
    np.testing.assert_array_equal(r.values, [1.0, 2.0])
    with pytest.raises(InputFileError, match="response labels"):
        parse_results("2.0 torque\n1.0 lift\n", "r.out", names_out=["thrust", "torque"])


@pytest.mark.parametrize(
    "text, line, words",
    [
        ("1.0D+03 thrust\n", 1, "Fortran-style 'D'"),
        ("1.0 thrust\n2.5d-2 torque\n", 2, "Fortran-style 'D'"),
        ("1.0\n[ 1.0 2.0D0 ]\n", 2, "Fortran-style 'D'"),
        ("thrust 1.0\n", 1, "numeric response value"),
        ("1.0\n[ 1.0 2.0\n", 2, "closing ']'"),
        ("1.0\n[ 1.0 x ]\n", 2, "numeric gradient entry"),
        ("1.0\n[[ 1 2 3 ]]\n", 2, "square Hessian"),
        ("1.0\n[ 1 2 ]\n[ 1 ]\n", 3, "same length"),
        ("1.0\n[[ 1 ]]\n[ 1 ]\n", 3, "values, then"),
    ],
)
def test_results_errors_name_file_and_line(text, line, words):
    with pytest.raises(InputFileError) as err:
        parse_results(text, "run/results.out")
    assert err.value.path == "run/results.out"
    assert err.value.line == line
    assert words in str(err.value)


def test_results_count_checked_against_asv():
    with pytest.raises(InputFileError, match="2 response values"):
        parse_results("1.0\n", names_out=["thrust", "torque"])
    with pytest.raises(InputFileError, match="1 gradients"):
        parse_results("1.0\n", names_out=["thrust"], asv=[3])
    with pytest.raises(InputFileError, match="3 entries per gradient"):
        parse_results("1.0\n[ 1 2 ]\n", names_out=["thrust"], asv=[3], n_dvv=3)


def test_missing_results_file(tmp_path):
    with pytest.raises(InputFileError, match="results file written by the driver"):
        read_results(tmp_path / "none.out")


def test_write_failed_and_format_checks(tmp_path):
    p = write_results(tmp_path / "r.out", failed=True)
    assert read_results(p).failed
    with pytest.raises(ValueError, match="labels"):
        format_results([1.0, 2.0], ["a"])
    with pytest.raises(ValueError, match="ASV code"):
        format_parameters({"a": 1.0}, {"f": 9})
    with pytest.raises(ValueError, match="without spaces"):
        format_parameters({"a": "two words"}, ["f"])


# --- hostile input: linear time, undecodable bytes -------------------------------------------

LONG = "1" * 20_000


@pytest.mark.parametrize(
    "kind, text",
    [
        ("results", f"{LONG} f\n"),  # a huge but valid number
        ("results", f"{LONG}x f\n"),  # almost a number
        ("results", f"{LONG}D f\n"),  # almost a Fortran number
        ("results", f"1.0 f\n[ {LONG}.{LONG}d ]\n"),
        ("results", "[" * 20_000 + "\n"),
        ("results", "1.0 " + "[[ ]" * 5_000 + "\n"),
        ("params", f"1 variables\n{LONG} a\n1 functions\n1 ASV_1:f\n0 derivative_variables\n"
                   "0 analysis_components\n1 eval_id\n"),
        ("params", f"{LONG} variables\n"),
        ("params", f"1 variables\n1.0 a\n1 functions\n{LONG} ASV_1:f\n"),
        ("params", "{ DAKOTA_VARS = " + " " * 20_000 + "1 \n"),
        ("params", "{ a = " + " " * 20_000 + "x" + " " * 20_000),
        ("params", "1 variables\n1.0 a\n1 functions\n1 ASV_" + LONG + ":f\n"),
        ("params", f"1 variables\n1.0 a\n0 functions\n0 derivative_variables\n"
                   f"0 analysis_components\n{':'.join([LONG] * 3)}x eval_id\n"),
    ],
)
def test_parsers_take_linear_time_on_long_tokens(kind, text):
    parse = parse_results if kind == "results" else parse_parameters
    best = float("inf")
    for _ in range(3):  # the best of three: a busy machine does not make it fail
        t0 = time.perf_counter()
        try:
            parse(text, "hostile")
        except InputFileError:
            pass
        best = min(best, time.perf_counter() - t0)
    assert best < 0.1  # milliseconds; the regex parser took 20 s on such tokens


def test_huge_integer_parses_as_a_number_not_an_error():
    v = parse_parameters(f"1 variables\n{LONG} a\n0 functions\n0 derivative_variables\n"
                         "0 analysis_components\n1 eval_id\n").variables["a"]
    assert v == float("inf") or v == int(LONG)
    assert parse_results(f"{LONG}e-19999 f\n").values[0] == pytest.approx(1.1111111111111111)


@pytest.mark.parametrize("read", [read_parameters, read_results])
def test_undecodable_files_name_file_and_line(tmp_path, read):
    p = tmp_path / "bad"
    p.write_bytes(b"1 variables\n\xff\xfe a\n")
    with pytest.raises(InputFileError) as err:
        read(p)
    assert err.value.path == str(p) and err.value.line == 2 and "UTF-8" in str(err.value)


def test_file_contents_use_the_names_of_models_and_compare_by_identity(tmp_path):
    p = read_parameters(write_parameters(tmp_path / "p.in", {"a": 1.0, "b": 2}, ["f", "g"]))
    assert p.names_in == ("a", "b") and p.names_out == ("f", "g")
    r = read_results(write_results(tmp_path / "r.out", [1.0, 2.0], ["f", "g"]),
                     names_out=["f", "g"])
    assert r.names_out == ("f", "g")
    # results hold arrays: == is identity (no "truth value of an array is ambiguous")
    again = read_results(tmp_path / "r.out")
    assert r == r and not (r == again)
    np.testing.assert_array_equal(r.values, again.values)
    with pytest.raises(ParameterError, match="needs values"):
        write_results(tmp_path / "x.out")


# --- files as Dakota 6.24 writes them (copied from its runs: analysis_components with a driver
# string holding spaces, a label holding '=', the metadata block, a batch of two evaluations)

DAKOTA_624_STANDARD = """\
                                          2 variables
                      1.000000000000000e+00 x1
                      2.000000000000000e+00 P=W
                                          2 functions
                                          1 ASV_1:f
                                          1 ASV_2:g=h
                                          2 derivative_variables
                                          1 DVV_1:x1
                                          2 DVV_2:P=W
                                          1 analysis_components
                              c1 with space AC_1:/tmp/dk/drv2.sh --set a=1
                                          1 eval_id
                                          1 metadata
                                    seconds MD_1
"""

DAKOTA_624_APREPRO = """\
                    { DAKOTA_VARS     =                      2 }
                    { x1              =  1.000000000000000e+00 }
                    { P=W             =  2.000000000000000e+00 }
                    { DAKOTA_FNS      =                      2 }
                    { ASV_1:f         =                      1 }
                    { ASV_2:g=h       =                      1 }
                    { DAKOTA_DER_VARS =                      2 }
                    { DVV_1:x1        =                      1 }
                    { DVV_2:P=W       =                      2 }
                    { DAKOTA_AN_COMPS =                      1 }
                    { AC_1:/tmp/dk/drv2.sh --set a=1 =                      "c1 with space" }
                    { DAKOTA_EVAL_ID  =                      1 }
                    { DAKOTA_METADATA =                      1 }
                    { MD_1            =                      "seconds" }
"""


@pytest.mark.parametrize("text", [DAKOTA_624_STANDARD, DAKOTA_624_APREPRO])
def test_dakota_624_components_labels_with_equals_and_metadata(text):
    p = parse_parameters(text, "params.in")
    assert p.variables == {"x1": 1.0, "P=W": 2.0}
    assert p.asv == {"f": 1, "g=h": 1}
    assert p.dvv == ("x1", "P=W")
    assert p.analysis_components == (("c1 with space", "/tmp/dk/drv2.sh --set a=1"),)
    assert p.metadata == ("seconds",)


def test_batch_files_hold_one_block_per_evaluation():
    block = DAKOTA_624_STANDARD.replace("1 eval_id", "1:{} eval_id")
    text = block.format(1) + block.format(2).replace("1.000000000000000e+00 x1", "3.5 x1")
    with pytest.raises(InputFileError, match="parse_parameters_batch"):
        parse_parameters(text, "params.in")
    blocks = parse_parameters_batch(text, "params.in")
    assert [b.eval_id for b in blocks] == ["1:1", "1:2"]
    assert [b.variables["x1"] for b in blocks] == [1.0, 3.5]
    assert parse_parameters_batch(DAKOTA_624_STANDARD)[0].metadata == ("seconds",)


def test_metadata_values_come_last_in_results():
    text = format_results([1.0, 2.0], ["f", "g"], gradients=[[1.0], [2.0]],
                          metadata={"seconds": 0.5})
    lines = text.splitlines()
    assert lines[-1].split() == ["5.0000000000000000e-01", "seconds"]
    assert lines[2].startswith("[")


# --- the driver loop (rotoruq.evaluation.driver) on a function model: fast, exact answers


def _make(args, names_in, names_out, fixed):
    """f = a * b**2, g = a + b: the deck's inputs are a and b (b may be fixed by --set)."""
    from rotoruq.model import FixedInputs, FunctionModel

    def f(x):
        return np.c_[x[:, 0] * x[:, 1] ** 2, x[:, 0] + x[:, 1]]

    model = FunctionModel(f, ["a", "b"], ["f", "g"])
    model = FixedInputs(model, fixed) if fixed else model
    if sorted(model.names_in) != sorted(names_in):
        raise ParameterError(f"inputs {names_in} are not {list(model.names_in)}")
    from rotoruq.evaluation.driver import _Ordered

    return _Ordered(model, names_in, names_out)


def _drive(tmp_path, argv, **params):
    from rotoruq.evaluation.driver import main

    write_parameters(tmp_path / "p.in", **params)
    return main([*argv, str(tmp_path / "p.in"), str(tmp_path / "r.out")], _make,
                program="test driver", description="")


def test_driver_options_never_swallow_the_appended_file_names(tmp_path, capsys):
    # --set then the two names Dakota appends; --map for a renamed variable and response
    code = _drive(tmp_path, ["--set", "b=3", "--map", "alpha=a", "--map", "F=f"],
                  variables={"alpha": 2.0}, names_out=["F"])
    assert code == 0
    r = read_results(tmp_path / "r.out", names_out=["F"])
    assert r.values.tolist() == [18.0] and r.names_out == ("F",)
    # --outputs (one value, comma list) in place of the deck's labels
    code = _drive(tmp_path, ["--outputs", "g,f"], variables={"b": 3.0, "a": 2.0},
                  names_out=["y1", "y2"])
    assert code == 0 and read_results(tmp_path / "r.out").values.tolist() == [5.0, 18.0]


@pytest.mark.parametrize("argv, params, words", [
    (["--set", "b"], {"variables": {"a": 1.0}}, "--set expects NAME=VALUE"),
    (["--set", "b=x"], {"variables": {"a": 1.0}}, "is not a number"),
    (["--bogus"], {"variables": {"a": 1.0, "b": 1.0}}, "unrecognized arguments"),
    (["--set", "b=1"], {"variables": {"a": 1.0, "b": 1.0}}, "the parameters file sets it"),
    (["--map", "c=a"], {"variables": {"a": 1.0, "b": 1.0}}, "neither variables"),
    (["--outputs", "f,g"], {"variables": {"a": 1.0, "b": 1.0}}, "2 outputs"),
    ([], {"variables": {"a": 1.0, "c": 1.0}}, "inputs ['a', 'c']"),
    ([], {"variables": {"a": 1.0, "b": 1.0}, "names_out": {"f": 5}}, "Hessians"),
    ([], {"variables": {"a": 1.0, "b": 1.0}, "metadata": ["memory"]}, "metadata ['memory']"),
])
def test_every_driver_failure_writes_fail_and_says_why(tmp_path, capsys, argv, params, words):
    params.setdefault("names_out", ["f"])
    code = _drive(tmp_path, argv, **params)
    assert code in (1, 2)
    assert words in capsys.readouterr().err
    assert read_results(tmp_path / "r.out").failed


def test_driver_asv_values_gradients_and_metadata(tmp_path):
    # f = a b^2: df/da = b^2 = 9, df/db = 2 a b = 12; g = a + b (value only)
    code = _drive(tmp_path, [], variables={"a": 2.0, "b": 3.0}, names_out={"f": 3, "g": 1},
                  dvv=["b", "a"], metadata=["seconds"])
    assert code == 0
    text = (tmp_path / "r.out").read_text()
    r = parse_results(text.rsplit("\n", 2)[0], names_out=["f", "g"], asv=[3, 1], n_dvv=2)
    np.testing.assert_allclose(r.values, [18.0, 5.0], rtol=0)
    # central differences with the project's FD step: error ~ h^2 and round-off, < 1e-8
    np.testing.assert_allclose(r.gradients, [[12.0, 9.0]], rtol=1e-8)
    assert text.splitlines()[-1].split()[1] == "seconds"
    # ASV 0: nothing asked, nothing written
    assert _drive(tmp_path, [], variables={"a": 2.0, "b": 3.0}, names_out={"f": 0}) == 0
    assert (tmp_path / "r.out").read_text() == ""


def test_driver_batch_fails_only_the_bad_block(tmp_path, capsys):
    from rotoruq.evaluation.driver import main

    one = format_parameters({"a": 2.0, "b": 3.0}, ["f"], eval_id="1:1")
    bad = format_parameters({"a": 2.0, "b": float("inf")}, ["f"], eval_id="1:2")
    (tmp_path / "p.in").write_text(one + bad + one.replace("1:1 eval_id", "1:3 eval_id"))
    assert main([str(tmp_path / "p.in"), str(tmp_path / "r.out")], _make, program="t",
                description="") == 1
    blocks = (tmp_path / "r.out").read_text().split("#\n")
    assert [parse_results(b).failed for b in blocks] == [False, True, False]
    assert parse_results(blocks[2]).values.tolist() == [18.0]
    assert "evaluation 1:2 failed" in capsys.readouterr().err


def test_named_pairs_split_at_the_last_equals_sign():
    from rotoruq.evaluation.driver import ArgumentError, named_pairs

    assert named_pairs(["P=W=power", "x=y"], "--map") == {"P=W": "power", "x": "y"}
    assert named_pairs(["omega=-2.5e1"], "--set", number=True) == {"omega": -25.0}
    with pytest.raises(ArgumentError, match="names 'x' twice"):
        named_pairs(["x=1", "x=2"], "--map")


def test_rotoruq_driver_loads_only_the_evaluation_layer_and_the_rotor(tmp_path):
    """The lean path: one evaluation of ``rotoruq driver`` (what Dakota runs per point) loads
    the evaluation layer and the rotor model, never the study's step types, the report, the
    methods, the results layer or scipy.stats."""
    import subprocess
    import sys

    write_parameters(tmp_path / "params.in", {"collective_deg": 8.0}, ["thrust"])
    probe = ("import runpy, sys\n"
             "sys.argv = ['rotoruq', 'driver', 'params.in', 'results.out']\n"
             "try:\n    runpy.run_module('rotoruq.study.cli', run_name='__main__')\n"
             "except SystemExit as e:\n    assert not e.code, e.code\n"
             "print(' '.join(sorted(sys.modules)))\n")
    out = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    loaded = set(out.stdout.split())
    assert not read_results(tmp_path / "results.out").failed
    assert "rotoruq.rotor.model" in loaded and "rotoruq.evaluation.driver" in loaded
    ours = {m for m in loaded if m.startswith("rotoruq.")}
    unwanted = sorted(m for m in ours if m.split(".")[1] in ("methods", "report", "results")
                      or (m.startswith("rotoruq.study.")
                          and m not in ("rotoruq.study.cli", "rotoruq.study.cmd_driver")))
    assert not unwanted, f"the driver loads {unwanted}"
    assert "scipy.stats" not in loaded


# --- tabular files: the layouts Dakota 6.24 writes (copied from its runs), our export

TAB_ANNOTATED = """\
%eval_id interface x1             P=W            f              g
1        NO_ID      1              2              1              2
2        NO_ID      3              4e-300         1              2
"""
TAB_CUSTOM_HEADER_ID = """\
%eval_id x1             P=W            f              g
1        1              2              1              2
2        3              4e-300         1              2
"""
TAB_CUSTOM_ID = """\
1                     1              2              1              2
2                     3         4e-300              1              2
"""
TAB_FREEFORM = """\
             1              2              1              2
             3         4e-300              1              2
"""
NAMES = ["x1", "P=W", "f", "g"]


@pytest.mark.parametrize("text, layout, names, ids, iface", [
    (TAB_ANNOTATED, "annotated", None, [1, 2], ("NO_ID", "NO_ID")),
    (TAB_CUSTOM_HEADER_ID, "custom_annotated", None, [1, 2], None),
    (TAB_CUSTOM_ID, "custom_annotated", NAMES, [1, 2], None),
    (TAB_FREEFORM, "freeform", NAMES, None, None),
])
def test_read_dakota_tabular_layouts(text, layout, names, ids, iface):
    from rotoruq.evaluation.tabular import parse_tabular

    t = parse_tabular(text, "t.dat", names=names)
    assert t.names == tuple(NAMES) and t.layout == layout and len(t) == 2
    np.testing.assert_array_equal(t.values, [[1, 2, 1, 2], [3, 4e-300, 1, 2]])
    assert (None if t.eval_id is None else t.eval_id.tolist()) == ids
    assert t.interface == iface
    np.testing.assert_array_equal(t["P=W"], [2, 4e-300])


@pytest.mark.parametrize("text, names, line, words", [
    (TAB_ANNOTATED.replace("4e-300         1", "4e-300"), None, 3, "6 columns"),
    (TAB_ANNOTATED.replace("4e-300", "4x-300"), None, 3, "a number in column 'P=W'"),
    (TAB_ANNOTATED.replace("2        NO_ID", "2.5      NO_ID"), None, 3, "integer eval_id"),
    (TAB_FREEFORM, None, 1, "a '%' header"),
    (TAB_ANNOTATED, ["x1", "f"], 1, "the columns"),
    ("", None, None, "an empty file"),
])
def test_malformed_tabular_files_name_file_and_line(text, names, line, words):
    from rotoruq.evaluation.tabular import parse_tabular

    with pytest.raises(InputFileError) as err:
        parse_tabular(text, "t.dat", names=names)
    assert err.value.line == line and words in str(err.value) and "t.dat" in str(err.value)


def _study_folder(tmp_path):
    """A study output folder: study.json with a fixed input, a store with two models."""
    from rotoruq.evaluation.store import NewRecord, Store
    from rotoruq.results import save_study_info

    out = tmp_path / "run"
    out.mkdir()
    save_study_info(out, {"name": "s", "model": {"fixed": {"omega": 230.0}}})
    store = Store(out / "evaluations.sqlite")
    x = np.array([[5.0, 1.1], [6.0, 1.2]])
    store.add([NewRecord(r, np.array([r[0] * 10, r[1] + 1])) for r in x], study="s",
              model="m1", names_in=["collective_deg", "rho"], names_out=["thrust", "torque"])
    store.add([NewRecord(np.array([1.0, 1.0]), None, status="failed")], study="s", model="m1",
              names_in=["collective_deg", "rho"], names_out=["thrust", "torque"])
    store.add([NewRecord(np.array([7.0]), np.array([1.0]))], study="s", model="m2",
              names_in=["k_flap"], names_out=["thrust"])
    store.close()
    return out, x


def test_export_columns_fixed_inputs_only_and_interface(tmp_path, capsys):
    from rotoruq.evaluation.tabular import read_tabular
    from rotoruq.study.cli import main

    out, x = _study_folder(tmp_path)
    dat = tmp_path / "t.dat"
    # two models in the store: the error lists them, --inputs picks one
    assert main(["export", str(out), "--dakota-tabular", str(dat)]) == 1
    assert "inputs collective_deg,rho -> thrust,torque" in capsys.readouterr().err
    assert main(["export", str(out), "--dakota-tabular", str(dat),
                 "--inputs", "rho,collective_deg"]) == 0
    t = read_tabular(dat)
    assert t.names == ("collective_deg", "rho", "omega", "thrust", "torque")
    np.testing.assert_array_equal(t.columns(["collective_deg", "rho"]), x)
    np.testing.assert_array_equal(t["omega"], [230.0, 230.0])
    np.testing.assert_array_equal(t["thrust"], x[:, 0] * 10)
    assert t.eval_id.tolist() == [1, 2] and t.interface == ("NO_ID", "NO_ID")
    # the deck's order, inputs only, an interface id of our own
    assert main(["export", str(out), "--dakota-tabular", str(dat), "--inputs",
                 "collective_deg,rho", "--columns", "omega,rho,collective_deg",
                 "--inputs-only", "--interface", "rotor"]) == 0
    t = read_tabular(dat)
    assert t.names == ("omega", "rho", "collective_deg") and t.interface == ("rotor",) * 2
    np.testing.assert_array_equal(t.values[:, 1:], x[:, ::-1])
    # failed evaluations on request; an unknown column is an error naming the choices
    assert main(["export", str(out / "evaluations.sqlite"), "--dakota-tabular", str(dat),
                 "--inputs", "collective_deg,rho", "--include-failed"]) == 0
    assert np.isnan(read_tabular(dat)["thrust"][2])
    assert main(["export", str(out), "--dakota-tabular", str(dat), "--inputs",
                 "collective_deg,rho", "--columns", "theta"]) == 1
    assert "columns ['theta'] are neither inputs" in capsys.readouterr().err


def test_tabular_write_read_round_trip_is_exact(tmp_path):
    from rotoruq.evaluation.tabular import read_tabular, write_tabular

    rng = np.random.default_rng(3)
    v = rng.normal(size=(5, 3)) * 10.0 ** rng.integers(-300, 300, size=(5, 3))
    for layout in ("annotated", "custom_annotated", "freeform"):
        # custom_annotated: header and eval_id, no interface column
        p = write_tabular(tmp_path / f"{layout}.dat", ["a", "b=c", "d"], v, layout=layout,
                          interface=None if layout == "custom_annotated" else "NO_ID")
        t = read_tabular(p, names=None if layout != "freeform" else ["a", "b=c", "d"])
        np.testing.assert_array_equal(t.values, v)
        assert t.layout == layout


def test_driver_batch_with_mixed_asv(tmp_path):
    """One block asks values and gradients, one only values, in aprepro: every gradient comes
    from one batched finite-difference call, values are exact."""
    from rotoruq.evaluation.driver import main

    a = format_parameters({"a": 2.0, "b": 3.0}, {"f": 3, "g": 2}, eval_id="4:1",
                          format="aprepro")
    b = format_parameters({"a": 1.0, "b": 0.5}, {"f": 1, "g": 1}, eval_id="4:2",
                          format="aprepro")
    (tmp_path / "p.in").write_text(a + b)
    assert main([str(tmp_path / "p.in"), str(tmp_path / "r.out")], _make, program="t",
                description="") == 0
    first, second = (tmp_path / "r.out").read_text().split("#\n")
    r1 = parse_results(first, names_out=["f", "g"], asv=[3, 2], n_dvv=2)
    assert r1.values.tolist() == [18.0]
    np.testing.assert_allclose(r1.gradients, [[9.0, 12.0], [1.0, 1.0]], rtol=1e-8)
    assert parse_results(second, names_out=["f", "g"]).values.tolist() == [0.25, 1.5]


def test_mbdyn_driver_honours_the_asv_without_running_mbdyn(tmp_path, monkeypatch, capsys):
    """ASV 0 asks nothing (no MBDyn run, an empty results file); Hessians are refused with
    FAIL before MBDyn is looked for; a response MBDyn does not compute is a FAIL too."""
    from rotoruq.mbdyn.driver import main

    monkeypatch.chdir(tmp_path)
    missing = str(tmp_path / "no-mbdyn")
    write_parameters("p.in", {"collective_deg": 5.0}, {"thrust": 0})
    assert main(["--mbdyn", missing, "p.in", "r.out"]) == 0
    assert (tmp_path / "r.out").read_text() == ""
    write_parameters("p.in", {"collective_deg": 5.0}, {"thrust": 4})
    assert main(["--mbdyn", missing, "p.in", "r.out"]) == 1
    assert read_results("r.out").failed and "Hessians" in capsys.readouterr().err
    write_parameters("p.in", {"collective_deg": 5.0}, ["lift"])
    assert main(["--mbdyn", missing, "p.in", "r.out"]) == 1
    assert read_results("r.out").failed and "not MBDyn hub loads" in capsys.readouterr().err


def test_export_picks_one_of_two_models_that_share_their_inputs(tmp_path, capsys):
    """Two steps asking one model for different responses store two models with the same
    inputs: --outputs picks one (the error says so)."""
    from rotoruq.evaluation.store import NewRecord, Store
    from rotoruq.evaluation.tabular import read_tabular
    from rotoruq.study.cli import main

    s = Store(tmp_path / "e.sqlite")
    s.add([NewRecord(np.array([1.0, 2.0]), np.array([3.0, 4.0]))], study="s", model="m1",
          names_in=["a", "b"], names_out=["f", "g"])
    s.add([NewRecord(np.array([5.0, 6.0]), np.array([7.0]))], study="s", model="m2",
          names_in=["a", "b"], names_out=["f"])
    dat = tmp_path / "t.dat"
    assert main(["export", str(s.path), "--dakota-tabular", str(dat), "--inputs", "a,b"]) == 1
    assert "(--inputs, --outputs)" in capsys.readouterr().err
    assert main(["export", str(s.path), "--dakota-tabular", str(dat), "--outputs", "f"]) == 0
    t = read_tabular(dat)
    assert t.names == ("a", "b", "f") and t.values.tolist() == [[5.0, 6.0, 7.0]]
