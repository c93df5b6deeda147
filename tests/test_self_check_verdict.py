"""A failed self-check on the report's first screen, next to what rests on it (issue 35,
item 9): the run's verdict names the validation steps whose predictions come from a
calibration whose self-check failed (through their chain of ``from``) and marks both lines
as failed; the reference study's claims carry the failure beside the claim. Saved steps are
real result folders read back as the report reads them."""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from rotoruq.reference.claims import Claim
from rotoruq.reference.report import _verdict
from rotoruq.report.html import run_verdict, write_report
from rotoruq.report.verdict import failed_self_checks, resting_on, verdict_lines
from rotoruq.results import StepResult, load_results, save_step
from rotoruq.steps.bayes_calibration import SELF_CHECK_FAILED, bayes_warnings
from rotoruq.steps.validation import JOINT
from test_report import bayes_step  # noqa: E402
from test_vv_claims import _record  # noqa: E402

REASON = "90 % coverage 0.72 (needs 0.82 to 0.98)"


def _validation(folder, name: str, source: str | None, ratios) -> None:
    data = np.array([[25.0, 0.1, 0.2, 350.0]])
    rec = _record((JOINT,), [4.0], data[None] + 0.0, data, np.array([0.8, 0.17, 0.18, 8.0]))
    rec = dataclasses.replace(rec, error_ratio=np.asarray(ratios, float).reshape(1, 1, -1))
    arrays, meta = rec.parts()
    save_step(StepResult(name, "validation", {}, arrays, meta={
        **meta, "responses": list(rec.names_out), "source": source}), folder)


def _study(tmp_path, passed: bool):
    folder = tmp_path / ("bad" if not passed else "good")
    folder.mkdir()
    (folder / "study.json").write_text(json.dumps({"name": folder.name, "steps": [
        "bayes", "stage2", "val_chain", "val_prior"]}))
    save_step(bayes_step({"self_check_passed": passed, "self_check_reason": REASON}), folder)
    save_step(bayes_step({}, name="stage2", source="bayes.posterior"), folder)
    _validation(folder, "val_chain", "stage2.posterior", [0.5, 1.9, 2.5, 3.0])
    _validation(folder, "val_prior", None, [0.5, 0.5, 0.5, 0.5])
    return folder


def test_the_validation_resting_on_a_failed_self_check_says_so_on_the_first_screen(tmp_path):
    folder = _study(tmp_path, passed=False)
    steps = load_results(folder)
    assert failed_self_checks(steps) == {"bayes": REASON}
    assert resting_on(steps, "val_chain") == ["stage2", "bayes"]
    assert resting_on(steps, "val_prior") == []
    lines = {line.check: line for line in verdict_lines({"bad": steps})}
    val, check = lines["validation"], lines["self-check"]
    assert val.counts["on_failed_self_check"] == 4  # val_chain's 4 comparisons, not val_prior's
    assert "bad / val_chain: 2 of 4 within 2 u_val, resting on bayes, whose self-check " \
        "FAILED" in val.text
    assert val.text.endswith("bad / val_prior: 4 of 4 within 2 u_val.")
    assert check.counts == {"failed": 1, "checked": 1}
    assert f"bad / bayes ({REASON}; resting on it: stage2, val_chain)" in check.text
    html = run_verdict({"bad": steps})
    marked = [li for li in html.split("<li") if "st-fails" in li]
    assert len(marked) == 2 and "data-check='validation'" in marked[0] \
        and "data-check='self-check'" in marked[1]
    page = write_report([folder], tmp_path / "rep").read_text()
    first = page[page.index("id='verdict'"):page.index("id='vv'")]
    assert html in first


def test_a_passed_self_check_marks_nothing(tmp_path):
    steps = load_results(_study(tmp_path, passed=True))
    lines = {line.check: line for line in verdict_lines({"good": steps})}
    assert lines["validation"].counts["on_failed_self_check"] == 0
    assert "whose self-check" not in lines["validation"].text
    assert "st-fails" not in run_verdict({"good": steps})


def test_a_reference_claim_shows_the_failed_self_check_it_rests_on(tmp_path):
    bayes = bayes_step({"self_check_passed": False, "self_check_reason": REASON})
    warning = [w for w in bayes_warnings(bayes, {}) if SELF_CHECK_FAILED in w]
    assert warning and REASON in warning[0]
    on_it = Claim("k_f", "K_f within 10 %", "error", "<=", 0.1, 0.05, 0.05,
                  warnings=tuple(warning))
    other = Claim("roll", "roll within 10 %", "error", "<=", 0.1, 0.05, 0.05)
    html = _verdict([on_it, other])
    items = html.split("<li ")[1:]
    assert "data-self-check=failed" in items[0] and REASON in items[0]
    assert "data-self-check=failed" not in items[1]
