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
