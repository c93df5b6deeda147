"""``result.json`` is checked like every other saved byte: a hand edit (a number, a type, a path
outside the step's folder) is never served. ``rotoruq show`` refuses the step with one line
naming the file, ``rotoruq run`` computes it again (one warning line naming the file) and the
new step equals the original bitwise, ``rotoruq repair`` moves it aside.

Every run is the CLI on a fresh folder, with the external-solver study of ``test_trust`` (a
driver of a few milliseconds per point): the study's first run in a fresh process, the
commands on the edited folders through the CLI's entry point in the test's process
(``tests/_inproc.py``: a fresh interpreter per command adds ~2 CPU-s and nothing checked here).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from _inproc import rotoruq
from rotoruq.results import (
    IncompleteStepError,
    StepResult,
    load_results,
    load_step,
    save_step,
    set_aside_damaged_steps,
)
from test_trust import cli, external_study, run_here


def _edit_mean(doc: dict) -> None:
    """A number moved by 1e-12: a scalar, or (a step whose numbers are its record) the mean
    of an input distribution, from which its flat view derives ``input_mean/``."""
    if "mean/y1" in doc["scalars"]:
        doc["scalars"]["mean/y1"] = doc["scalars"]["mean/y1"] + 1e-12
        return
    dist = next(iter(doc["meta"]["input_distributions"].values()))
    key = next(k for k, v in dist.items() if isinstance(v, float))
    dist[key] += 1e-12


EDITS = {
    "mean": _edit_mean,
    # type edits: the first two are of the shape load_step reads, caught by the checksum alone
    "distributions": lambda d: d.update(distributions={"a": 5}),
    "meta-failures": lambda d: d["meta"].update(failures=7, fixed={"c": [1, 2]}),
    "n_evaluations": lambda d: d["meta"].update(n_evaluations="40"),
    "scalar-type": lambda d: d["scalars"].update({"mean/y1": "9.1"}),
    "arrays-outside": lambda d: d.update(arrays=["../../../study"]),
    "no-checksum": lambda d: d.pop("checksum"),  # a step saved before result.json had one
    "checksum-type": lambda d: d.update(checksum=1),
    "checksum-edited": lambda d: d.update(checksum="0" * 64),
}
# the edits also run through the CLI (each costs a run)
CLI_EDITS = ["mean", "distributions", "n_evaluations", "arrays-outside", "no-checksum"]


@pytest.mark.parametrize("edit", list(EDITS))
def test_load_step_refuses_an_edited_result_json_naming_it(tmp_path, edit):
    step = save_step(StepResult("lhs", "sampling", {"mean/y1": 1.5, "std/y1": 0.25},
                                {"inputs": np.arange(6.0).reshape(3, 2)},
                                distributions={"a": {"kind": "normal", "mu": 1.0,
                                                     "sigma": 0.5}},
                                meta={"columns": {"inputs": ["a", "b"]},
                                      "n_evaluations": 3}), tmp_path)
    where = step / "result.json"
    doc = json.loads(where.read_text())
    assert load_step(step).get("mean/y1") == 1.5
    where.write_text(json.dumps(doc))  # another layout of the same document: still trusted
    assert load_step(step).get("mean/y1") == 1.5
    EDITS[edit](doc)
    where.write_text(json.dumps(doc, indent=1))
    with pytest.raises(IncompleteStepError) as info:
        load_step(step)
    assert str(where) in str(info.value) and "\n" not in str(info.value)
    (moved,) = set_aside_damaged_steps(tmp_path)
    assert moved.name == "lhs" and moved.problem == str(info.value)
    assert moved.moved_to.parent == tmp_path / "steps" and not step.exists()
    assert load_results(tmp_path) == {}


def _saved(out: Path) -> tuple[dict, dict, dict]:
    res = load_step(out / "steps" / "lhs")
    return dict(res.scalars), {k: np.asarray(v) for k, v in res.arrays.items()}, \
        dict(res.distributions)


def _assert_bitwise_equal(a, b) -> None:
    (sa, aa, da), (sb, ab, db) = a, b
    assert list(sa) == list(sb) and all(
        np.float64(sa[k]).tobytes() == np.float64(sb[k]).tobytes() for k in sa)
    assert sorted(aa) == sorted(ab)
    for k in aa:
        assert aa[k].dtype == ab[k].dtype and aa[k].tobytes() == ab[k].tobytes(), k
    assert da == db


@pytest.fixture(scope="module")
def original(tmp_path_factory) -> tuple[Path, Path]:
    """One run of the study: (study file, results folder), copied by each test."""
    tmp = tmp_path_factory.mktemp("orig")
    study = external_study(tmp / "s")
    cli("run", study, "--out", tmp / "out", "--no-report")
    return study, tmp / "out"


@pytest.mark.parametrize("edit", CLI_EDITS)
def test_an_edited_result_json_is_never_served_and_run_recomputes_it_bitwise(
        tmp_path, original, edit):
    cli = run_here
    study, orig = original
    out = tmp_path / "out"
    shutil.copytree(orig, out)
    before = _saved(out)
    where = out / "steps" / "lhs" / "result.json"
    doc = json.loads(where.read_text())
    EDITS[edit](doc)
    where.write_text(json.dumps(doc, indent=1))

    shows = [("show", out)] + ([("show", out, "--json")] if edit == "mean" else [])
    for args in shows:
        proc = cli(*args, check=False)
        assert proc.returncode == 1, proc.stdout
        assert "internal error" not in proc.stderr and proc.stderr.count("\n") == 1
        assert proc.stderr.startswith("rotoruq show: error: ") and str(where) in proc.stderr
        assert "mean" not in proc.stdout
    if edit == "mean":  # --why-rerun lists the step as one that runs again, and why
        proc = cli("show", out, "--why-rerun")
        (line,) = [ln for ln in proc.stdout.splitlines() if "incomplete" in ln]
        assert "lhs" in line and str(where) in line, proc.stdout

    proc = cli("run", study, "--out", out, "--no-report")
    (line,) = [ln for ln in proc.stderr.splitlines() if str(where) in ln]
    assert "incomplete" in line and "running it again" in line
    assert "reused" not in proc.stderr
    _assert_bitwise_equal(_saved(out), before)


def test_repair_moves_an_edited_step_aside_and_run_recomputes_it(tmp_path, original):
    cli = run_here
    study, orig = original
    out = tmp_path / "out"
    shutil.copytree(orig, out)
    before = _saved(out)
    step = out / "steps" / "lhs"
    doc = json.loads((step / "result.json").read_text())
    _edit_mean(doc)
    (step / "result.json").write_text(json.dumps(doc, indent=1))

    proc = cli("repair", out)
    assert "store intact" in proc.stdout
    (line,) = [ln for ln in proc.stdout.splitlines() if "damaged" in ln]
    assert line.startswith(f"{step}: damaged ({step / 'result.json'}: changed since the step "
                           "was saved")
    (aside,) = (out / "steps").glob(".damaged-lhs.*")
    assert str(aside) in line and not step.exists()
    assert json.loads((aside / "result.json").read_text()) == doc  # kept, not deleted
    shown = cli("show", out)  # the rest of the folder reads again: no step left to show
    assert "lhs" not in shown.stdout

    proc = cli("run", study, "--out", out, "--no-report")
    assert "reused" not in proc.stderr and "incomplete" not in proc.stderr
    _assert_bitwise_equal(_saved(out), before)
    again = cli("repair", out)
    assert "damaged" not in again.stdout and "1 saved step(s) intact" in again.stdout


def test_report_of_two_folders_of_one_study_name_is_a_clear_error(tmp_path, original):
    """`rotoruq report A B` where A and B hold one study name: one line naming both
    study.json files (the report keys its sections by study name: one would be dropped)."""
    _, orig = original
    a, b = tmp_path / "a", tmp_path / "b"
    shutil.copytree(orig, a)
    shutil.copytree(orig, b)
    proc = rotoruq("report", a, b, "--out", tmp_path / "report")
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1, proc.stderr
    assert proc.stderr.startswith(f"rotoruq report: error: {b / 'study.json'}: expected a "
                                  f"study name of its own: study 'ext' is also in "
                                  f"{a / 'study.json'} (")
    assert not (tmp_path / "report" / "index.html").exists()
    # one folder given twice: no clash
    assert rotoruq("report", a, a, "--out", tmp_path / "report").returncode == 0
