"""Property-based fuzzing of study files: every input either loads or raises a RotoruqError
subclass (with a message), never another exception."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rotoruq.errors import RotoruqError
from rotoruq.study.schema import load_study, parse_study

ROOT = Path(__file__).resolve().parents[1]
SEED_TEXT = """\
[study]
name = "fuzz"
seed = 3

[model]
preset = "gvpm"
responses = ["thrust", "power"]
fixed = { collective_deg = 5.4, height_over_radius = 4.0 }

[parameters.k_pitch_link]
distribution = "normal"
mean = 15.0
std = 2.0

[parameters.cla_m03]
distribution = "uniform"
lower = 0.1
upper = 0.12

[[steps]]
name = "lhs"
type = "sampling"
n_samples = 20

[[steps]]
name = "sens"
type = "sensitivity"
n_samples = 16
"""

LINES = SEED_TEXT.splitlines()
TOKENS = ["=", "[", "]", "{", "}", '"', ",", "\n", "-1", "0", "1e400", "nan", "inf", "true",
          "9" * 40, "[[steps]]", "type = \"bayes\"", "from = \"lhs\"", "n = -5",
          "distribution = \"lognormal\"", "std = 0", "\x00", "\xff", "é",
          "9" * 20_000, "-" + "1" * 5_000]  # beyond Python's 4300-digit int limit


def _check(text: str, tmp: Path | None = None) -> None:
    try:
        parse_study(text, "fuzz.toml")
    except RotoruqError as exc:
        assert str(exc)
    if tmp is not None:
        p = tmp / "fuzz.toml"
        p.write_bytes(text.encode("utf-8", "surrogatepass"))
        try:
            load_study(p)
        except RotoruqError as exc:
            assert str(exc)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(0, len(LINES) - 1), st.sampled_from(["drop", "dup", "put"]),
                          st.sampled_from(TOKENS), st.integers(0, 40)), max_size=6))
def test_mutated_study_files_parse_or_raise_rotoruq_errors(edits):
    lines = list(LINES)
    for i, op, tok, pos in edits:
        i = min(i, len(lines) - 1) if lines else 0
        if not lines:
            lines = [tok]
        elif op == "drop":
            del lines[i]
        elif op == "dup":
            lines.insert(i, lines[i])
        else:
            line = lines[i]
            lines[i] = line[:pos] + tok + line[pos:]
    _check("\n".join(lines))


@settings(max_examples=150, deadline=None)
@given(st.text(max_size=300))
def test_arbitrary_text_parses_or_raises_rotoruq_errors(text):
    _check(text)


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=200))
def test_arbitrary_bytes_load_or_raise_rotoruq_errors(tmp_path_factory, data):
    p = tmp_path_factory.mktemp("fuzz") / "study.toml"
    p.write_bytes(SEED_TEXT.encode()[:50] + data)
    try:
        load_study(p)
    except RotoruqError as exc:
        assert str(exc)


@pytest.mark.parametrize("name", ["validation.toml", "experiment.toml", "quick.toml"])
def test_bundled_studies_load(name):
    from rotoruq.study.cmd_reproduce import studies_dir

    assert load_study(studies_dir() / name).steps


ARGS = ["run", "show", "report", "evaluate", "export", "repair", "airfoil",
        "--quick", "--json", "--csv", "--out", "--only", "--why-rerun", "--preset", "gvpm",
        "--set", "collective_deg=5", "collective_deg=", "=", "nope=1", "k_pitch_link=1e400",
        "--responses", "thrust", "--dakota-tabular", "-", "missing.toml", "missing_dir",
        "\x1b[2J", "9" * 5000, "", "--", "-h"]


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.sampled_from(ARGS), min_size=1, max_size=6))
def test_cli_arguments_never_give_an_internal_error(tmp_path_factory, argv):
    """Any command line ends with a usage or one-line error, never "internal error"
    (in-process: the CLI's own top-level error handling, in a fresh empty folder)."""
    import contextlib
    import io
    import os

    from rotoruq.study.cli import main

    if argv[0] == "run" and "--quick" not in argv:
        argv = [*argv, "--quick"]  # bounded work
    folder = tmp_path_factory.mktemp("cli")
    err, out = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            try:
                code = main([*argv, "--out", str(folder / "o")] if argv[0] == "run" else argv)
            except SystemExit as exc:  # argparse: usage errors and --help
                code = exc.code
    finally:
        os.chdir(cwd)
    assert "internal error" not in err.getvalue(), (argv, err.getvalue())
    assert code in (0, 1, 2, None), (argv, code)
