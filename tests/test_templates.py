"""Template fields: values, defaults, format specs, escapes, and no code execution."""

from __future__ import annotations

import numpy as np
import pytest

from rotoruq.errors import InputFileError
from rotoruq.evaluation.templates import fill_template, fill_template_file, template_fields


def test_fields_defaults_and_specs():
    text = ("theta0 = {collective_deg};\n"
            "k = {k_pitch_link:.6e}; n = {n_blades:d}\n"
            "h = {height_over_radius = 4.0}; h2 = {height_over_radius = 4.0 : .3f}\n"
            "name = {airfoil = 'naca0012'}; w = {collective_deg:>10.2f}|\n")
    out = fill_template(text, {"collective_deg": 5.4, "k_pitch_link": 15000.0, "n_blades": 4})
    assert out == ("theta0 = 5.4;\n"
                   "k = 1.500000e+04; n = 4\n"
                   "h = 4.0; h2 = 4.000\n"
                   "name = naca0012; w =       5.40|\n")


def test_value_overrides_default_and_repr_is_exact():
    x = 0.1 + 0.2
    out = fill_template("{a = 1}", {"a": x})
    assert float(out) == x
    assert fill_template("{a}", {"a": np.float64(2.5)}) == "2.5"


def test_escapes():
    text = r"block {{ a = {a} }} and \{literal\} {{{a}}}"
    assert fill_template(text, {"a": 1}) == "block { a = 1 } and {literal} {1}"


def test_no_code_execution(tmp_path):
    marker = tmp_path / "pwned"
    evil = [
        "{__import__('os').system('touch " + str(marker) + "')}",
        "{a.__class__}",
        "{a + 1}",
        "{a = __import__('os')}",
    ]
    for t in evil:
        with pytest.raises(InputFileError):
            fill_template(t, {"a": 1.0})
    assert not marker.exists()


@pytest.mark.parametrize(
    "text, line, words",
    [
        ("ok\nx = {missing}\n", 2, "'missing'"),
        ("a\nb\n x = {a\n", 3, "closing '}'"),
        ("x = a }\n", 1, "literal closing brace"),
        ("{a:.3q}", 1, "format spec"),
        ("\n{a = }", 2, "default value"),
        ("{1abc}", 1, "field"),
    ],
)
def test_errors_name_file_and_line(text, line, words):
    with pytest.raises(InputFileError) as err:
        fill_template(text, {"a": 1.0}, path="solver.tpl")
    assert err.value.path == "solver.tpl"
    assert err.value.line == line
    assert words in str(err.value)


def test_fill_file_and_list_fields(tmp_path):
    src = tmp_path / "parameters.set"
    src.write_text("set: real K = {k_pitch_link};\nset: real T0 = {collective_deg:.4f};\n"
                   "set: real H = {h = 2};\nset: real K2 = {k_pitch_link};\n")
    assert template_fields(src.read_text()) == ["k_pitch_link", "collective_deg", "h"]
    dst = fill_template_file(src, tmp_path / "parameters_final.set",
                             {"k_pitch_link": 1.5e4, "collective_deg": 5.4})
    assert dst.read_text() == ("set: real K = 15000.0;\nset: real T0 = 5.4000;\n"
                               "set: real H = 2;\nset: real K2 = 15000.0;\n")
