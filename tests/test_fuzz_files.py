"""Property-based fuzzing of the file readers: c81 tables, Dakota parameters and results files.

Every input either parses or raises a :class:`~rotoruq.errors.RotoruqError` subclass: never a
bare ``ValueError``, ``IndexError``, ``UnicodeDecodeError``... Inputs are valid files mutated
(characters inserted, deleted, replaced, lines cut) plus arbitrary bytes. ``max_examples`` is
bounded so that the whole file runs in a few seconds.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rotoruq.errors import RotoruqError
from rotoruq.evaluation.dakota_files import (
    format_parameters,
    format_results,
    parse_parameters,
    parse_results,
    read_parameters,
    read_results,
)
from rotoruq.rotor.c81 import C81Block, C81Table, read_c81, write_c81

FUZZ = settings(max_examples=300, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def _c81_texts() -> list[str]:
    mach, alpha = np.array([0.0, 0.3, 0.6]), np.array([-10.0, 0.0, 5.0, 12.0])
    vals = np.outer(alpha, 1 + mach) * 0.1
    t = C81Table("FUZZ", *(C81Block(mach, alpha, vals * k) for k in (1.0, 0.1, -0.02)))
    with tempfile.TemporaryDirectory() as d:
        return [write_c81(t, Path(d) / "a.c81").read_text(),
                write_c81(t, Path(d) / "b.c81", free_format=True).read_text()]


C81_TEXTS = _c81_texts()
PARAM_TEXTS = [
    format_parameters({"a": 1.5, "b": -2e-3, "n": 3, "s": "mesh.msh"}, {"f": 1, "g": 3},
                      analysis_components=[("comp", "drv")], eval_id="1:4:2", metadata=["m"],
                      format=fmt)
    for fmt in ("standard", "aprepro")
]
RESULT_TEXTS = [
    format_results([1.0, -2.5e-8], ["f", "g"], gradients=[[1.0, 2.0]],
                   hessians=[[[1.0, 0.5], [0.5, 2.0]]]),
    "FAIL\n",
    "1.0\n2.0\n",
]
# characters that matter to the formats, plus a few that do not
PIECE = st.sampled_from(list("0123456789 .-+eEdD\n\t[]{}=;:#\"'_ab") +
                        ["nan", "inf", "9" * 40, "\x00", "\x85", "\u2028", "é", "[[", "]]"])


def pieces(max_size: int):
    return st.lists(PIECE, min_size=1, max_size=max_size).map("".join)



@st.composite
def mutated(draw, bases: list[str]) -> str:
    """A valid text with a few random edits: insert, delete, replace or cut."""
    text = draw(st.sampled_from(bases))
    for _ in range(draw(st.integers(0, 6))):
        if not text:
            break
        i = draw(st.integers(0, len(text) - 1))
        op = draw(st.sampled_from(["insert", "delete", "replace", "cut", "dup_line",
                                   "first_lines"]))
        if op == "insert":
            text = text[:i] + draw(pieces(4)) + text[i:]
        elif op == "delete":
            text = text[:i] + text[i + draw(st.integers(1, 8)):]
        elif op == "replace":
            text = text[:i] + draw(PIECE) + text[i + 1:]
        elif op == "cut":
            text = text[:i]
        elif op == "first_lines":
            text = "".join(text.splitlines(keepends=True)[: draw(st.integers(0, 3))])
        else:
            lines = text.splitlines(keepends=True)
            j = draw(st.integers(0, len(lines) - 1))
            text = "".join(lines[: j + 1] + lines[j:])
    return text


def _any(bases):
    return st.one_of(mutated(bases), pieces(120))


def _parses_or_rotoruq_error(fn, *args, **kw) -> None:
    try:
        fn(*args, **kw)
    except RotoruqError:
        pass


@FUZZ
@given(text=_any(C81_TEXTS), raw=st.binary(max_size=64), use_raw=st.booleans())
def test_c81_reader_raises_only_rotoruq_errors(text, raw, use_raw):
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "t.c81"
        p.write_bytes(raw if use_raw else text.encode("utf-8", "surrogatepass"))
        _parses_or_rotoruq_error(read_c81, p)


@FUZZ
@given(text=_any(PARAM_TEXTS))
def test_parameters_parser_raises_only_rotoruq_errors(text):
    _parses_or_rotoruq_error(parse_parameters, text, "params.in")


@FUZZ
@given(text=_any(RESULT_TEXTS), checked=st.booleans())
def test_results_parser_raises_only_rotoruq_errors(text, checked):
    kw = {"names_out": ["f", "g"], "asv": [3, 1], "n_dvv": 2} if checked else {}
    _parses_or_rotoruq_error(parse_results, text, "results.out", **kw)


@settings(max_examples=60, deadline=None)
@given(raw=st.binary(max_size=200), kind=st.sampled_from(["params", "results"]))
def test_undecodable_files_raise_input_file_errors(raw, kind):
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "f"
        p.write_bytes(raw)
        _parses_or_rotoruq_error(read_parameters if kind == "params" else read_results, p)


@pytest.mark.parametrize("base", PARAM_TEXTS + RESULT_TEXTS[:1])
def test_mutation_bases_parse(base):
    """The fuzz inputs start from files that do parse (so the mutations test something)."""
    if "variables" in base or "DAKOTA_VARS" in base:
        assert parse_parameters(base).variables["a"] == 1.5
    else:
        assert parse_results(base).values.tolist() == [1.0, -2.5e-8]
