"""A results folder from someone else cannot run script in the report or write escape codes to
the terminal (issue 27): every study-supplied string is escaped in text and attributes, ids and
file names come from a safe slug, a Content-Security-Policy forbids inline script, and
``rotoruq show`` escapes control characters."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from html.parser import HTMLParser

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rotoruq.report.escape import slug, text, visible
from rotoruq.report.html import write_report
from rotoruq.results import StepResult, save_step

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or (
    "/usr/bin/chromium" if os.path.exists("/usr/bin/chromium") else None)


def _set(i: int) -> str:
    return f"document.documentElement.setAttribute('data-xss-{i}','1')"


# Each payload, if it ever ran, would set data-xss-<i> on the <html> element.
PAYLOADS = [
    f"<img src=x onerror=\"{_set(0)}\">",
    f"x' autofocus onfocus='{_set(1)}' y='",
    f"</script><script>{_set(2)}</script>",
    f"\" autofocus onfocus=\"{_set(3)}\" y=\"",
    f"<svg onload=\"{_set(4)}\"></svg>",
    f"<!--<script>{_set(5)}</script>-->",
    f"<iframe srcdoc='<script>parent.{_set(6)}</script>'></iframe>",
    f"<details open ontoggle=\"{_set(7)}\">",
]


def _hostile_results(root, payloads=PAYLOADS, step_name="lhs"):
    """A study output folder whose name, description, labels, units, step title and noise
    model are each a payload (what a tampered or hostile results folder may hold)."""
    out = root / "hostile"
    out.mkdir(parents=True)
    name, desc, label, unit, title, noise = (payloads * 2)[:6]
    info = {"name": name, "description": desc, "seed": 1, "quick": True,
            "study_file": payloads[-1], "steps": [step_name],
            "parameters": {"a": {"kind": "normal", "label": label, "unit": unit}},
            "model": {"preset": None}}
    (out / "study.json").write_text(json.dumps(info))
    rng = np.random.default_rng(0)
    x = rng.normal(size=(30, 1))
    y = np.column_stack([2 * x[:, 0], x[:, 0] ** 2])
    save_step(StepResult(step_name, "sampling", {"mean/y1": 0.1, "std/y1": 2.0,
                                                 "mean/y2": 1.0, "std/y2": 1.4},
                         {"inputs": x, "outputs": y},
                         meta={"columns": {"inputs": ["a"], "outputs": ["y1", "y2"]},
                               "title": title, "noise_model": noise,
                               "options": {"note": payloads[0]},
                               "failed_evaluations": {"count": 2, "reasons": {noise: 2}}}),
              out)
    return out


def _chromium_dom(page, tmp_path) -> str:
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=5000",
           "--dump-dom", page.as_uri()]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout


def _marks(dom: str) -> list[str]:
    m = re.search(r"<html[^>]*>", dom)
    assert m, dom[:300]
    return re.findall(r"data-xss-\d", m.group(0))


@pytest.mark.browser
def test_hostile_results_run_no_script_in_chromium(tmp_path):
    if CHROMIUM is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is required in CI (apt-get install chromium)")
        pytest.skip("chromium is not installed")
    index = write_report([_hostile_results(tmp_path)], tmp_path / "report", workers=1)
    page = index.read_text()
    assert "Content-Security-Policy" in page
    assert _marks(_chromium_dom(index, tmp_path)) == []
    # the escaping alone suffices: without the policy no payload runs either
    bare = index.with_name("no_csp.html")
    bare.write_text(re.sub(r"<meta http-equiv='Content-Security-Policy'[^>]*>", "", page))
    assert "Content-Security-Policy" not in bare.read_text()
    assert _marks(_chromium_dom(bare, tmp_path)) == []
    # the check can fail: the same payloads written raw (no policy) do run
    raw = index.with_name("raw.html")
    raw.write_text(f"<!DOCTYPE html><html><body><div>{PAYLOADS[0]}</div></body></html>")
    assert _marks(_chromium_dom(raw, tmp_path)) == ["data-xss-0"]


def test_ids_and_file_names_come_from_a_slug(tmp_path):
    index = write_report([_hostile_results(tmp_path)], tmp_path / "report", workers=1)
    page = index.read_text()
    for i in re.findall(r"id='([^']*)'", page):
        assert re.fullmatch(r"[A-Za-z0-9_.-]+", i), i
    for f in (tmp_path / "report").rglob("*"):
        assert f.resolve().is_relative_to((tmp_path / "report").resolve())
        assert re.fullmatch(r"[A-Za-z0-9_.-]+", f.name), f.name
    assert slug("a b") != slug("a-b") and slug("a/b") != slug("a-b")
    # the step's failed evaluations in the provenance, its reason escaped
    assert "<span data-failed='2'>2 failed evaluations in the 1 steps" in page
    # the study name, description, step title and noise model are on the page as text
    for p in (PAYLOADS[0], PAYLOADS[1], PAYLOADS[4], PAYLOADS[5]):
        assert text(p) in page


class _Page(HTMLParser):
    """Tags with their attribute names, and the page's text."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.tags: list[tuple[str, tuple[str, ...]]] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, tuple(k for k, _ in attrs)))

    def handle_data(self, data):
        self.text.append(data)


def _parse(page: str) -> _Page:
    p = _Page()
    p.feed(page)
    p.close()
    return p


def _page_for(tmp_path, name: str) -> str:
    root = tmp_path / slug(name)
    shutil.rmtree(root, ignore_errors=True)
    out = root / "r"
    out.mkdir(parents=True)
    info = {"name": name, "description": name, "seed": 3, "steps": ["s"],
            "parameters": {"a": {"kind": "normal", "label": name, "unit": name}},
            "model": {"preset": None}}
    (out / "study.json").write_text(json.dumps(info))
    save_step(StepResult("s", "mean_value_unknown", {"mean/y1": 1.0},
                         meta={"title": name, "options": {"k": name},
                               "failed_evaluations": {"count": 1, "reasons": {name: 1}}}), out)
    page = write_report([out], root / "report", workers=1).read_text()
    return re.sub(r"Generated \S+ from [^<]*", "", page)


_CHARS = st.characters(codec="utf-8", categories=["L", "N", "P", "S", "Zs", "Cc"]) | \
    st.sampled_from(list("<>&'\"/=` \x1b\x00\x07\u202e\u2028"))


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(name=st.text(_CHARS, min_size=1, max_size=24))
def test_any_name_is_text_only(tmp_path, name):
    """A name made of printable and control characters changes no tag or attribute of the
    page (same structure as a plain name) and reads back as its visible form."""
    base = _parse(_page_for(tmp_path, "plain"))
    got = _parse(_page_for(tmp_path, name))
    assert got.tags == base.tags
    shown = "".join(got.text)
    assert visible(name, keep="\t\n") in shown
    assert not re.search("[\x00-\x08\x0b-\x1f\x7f-\x9f\u202e\u2028]", shown)


def test_show_writes_no_escape_codes(tmp_path, capsys):
    from rotoruq.study.cli import main

    esc = ["x\x1b]0;owned\x07", "\x1b[2J\x1b[Hgone", "\x9b31mred", "a\u202eb"]
    # (a step name with control characters cannot be saved or loaded any more: rotoruq.safety)
    out = _hostile_results(tmp_path, esc)
    for extra in ([], ["--csv"]):
        assert main(["show", str(out), *extra]) == 0
        shown = capsys.readouterr().out
        assert "\x1b" not in shown and "\x07" not in shown and "\x9b" not in shown
        assert "\u202e" not in shown
        if not extra:  # the text view shows the study's name and the reasons, escaped
            assert "\\x1b" in shown
            assert "failed evaluations: 2" in shown and "2 x \\x1b[2J\\x1b[Hgone" in shown
    assert main(["show", str(out), "--json"]) == 0
    js = capsys.readouterr().out
    assert "\x1b" not in js
    data = json.loads(js)
    assert data["study"] == esc[0]  # JSON keeps the exact string, escaped as \u001b
    assert data["steps"]["lhs"]["failed_evaluations"] == {"count": 2,
                                                          "reasons": {esc[1]: 2}}
    assert main(["show", str(out), "nope"]) == 1
    err = capsys.readouterr().err
    assert "\x1b" not in err
