"""The report opens in a real browser (headless Debian Chromium): every figure loads, every
figure's axes are labelled with units, every table-of-contents link resolves; the first screen
shows the verdict counts, every figure is also an SVG file, and the page prints to a PDF."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import xml.etree.ElementTree as ET

import pytest

from rotoruq.report.html import write_report
from rotoruq.study.runner import run_study
from test_report import _fake_reference
from test_runner import STUDY, linear_factory

pytestmark = pytest.mark.browser

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or (
    "/usr/bin/chromium" if os.path.exists("/usr/bin/chromium") else None)

# Sets <body data-images="loaded/total" data-errors="n" data-unlabelled="n/figures"
# data-toc="resolved/links"> once the page has loaded. A figure is labelled when it declares at
# least one x and one y axis label (read from the matplotlib axes when it was drawn) and every
# label names a unit in brackets; a link resolves when an element with its id exists.
PROBE = """<script>
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;
  document.body.setAttribute('data-images', ok + '/' + imgs.length);
  document.body.setAttribute('data-errors', String(window.__errors || 0));
  var figs = Array.prototype.slice.call(document.querySelectorAll('figure'));
  var bad = figs.filter(function (f) {
    var xs = JSON.parse(f.getAttribute('data-xlabels') || '[]');
    var ys = JSON.parse(f.getAttribute('data-ylabels') || '[]');
    var all = xs.concat(ys);
    return !xs.length || !ys.length ||
      !all.every(function (l) { return /\\[[^\\]]+\\]/.test(l); });
  });
  document.body.setAttribute('data-unlabelled', bad.length + '/' + figs.length);
  var links = Array.prototype.slice.call(document.querySelectorAll('#toc a[href^="#"]'));
  var found = links.filter(function (a) {
    return document.getElementById(a.getAttribute('href').slice(1)) !== null;
  });
  document.body.setAttribute('data-toc', found.length + '/' + links.length);
});
window.__errors = 0;
window.addEventListener('error', function () { window.__errors += 1; }, true);
</script>"""


def test_report_renders_in_chromium(tmp_path):
    if CHROMIUM is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is required in CI (apt-get install chromium)")
        pytest.skip("chromium is not installed")
    p = tmp_path / "lin.toml"
    p.write_text(STUDY)
    run = run_study(p, model_factory=linear_factory())
    index = write_report([run.out], tmp_path / "report")
    probe = index.with_name("probe.html")
    probe.write_text(index.read_text().replace("<head>", "<head>" + PROBE, 1))
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
           "--no-first-run", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}",
           "--virtual-time-budget=10000", "--dump-dom", probe.as_uri()]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    m = re.search(r'data-images="(\d+)/(\d+)"', out.stdout)
    assert m, "the probe did not run: " + out.stdout[:500] + out.stderr[-1000:]
    loaded, total = int(m.group(1)), int(m.group(2))
    assert total >= 3 and loaded == total
    assert 'data-errors="0"' in out.stdout
    m = re.search(r'data-unlabelled="(\d+)/(\d+)"', out.stdout)
    assert m and m.group(1) == "0" and int(m.group(2)) == total, m and m.group(0)
    m = re.search(r'data-toc="(\d+)/(\d+)"', out.stdout)
    assert m and int(m.group(2)) >= 5 and m.group(1) == m.group(2), m and m.group(0)


# Sets <body data-counts="holds/warn/fails/na" data-counts-top="y" data-height="h"
# data-svgs="figure-id=href;..."> once the page has loaded: the verdict counts block's numbers
# and where it sits (CSS pixels from the top of the page), the window height, and each
# figure's SVG link.
FIRST_SCREEN_PROBE = """<script>
window.addEventListener('load', function () {
  var c = document.querySelector('p.counts');
  var b = document.body;
  if (c) {
    b.setAttribute('data-counts', ['holds', 'warn', 'fails', 'na'].map(function (k) {
      return c.getAttribute('data-' + k); }).join('/'));
    b.setAttribute('data-counts-top', String(Math.round(c.getBoundingClientRect().bottom)));
    b.setAttribute('data-counts-text', c.textContent);
  }
  b.setAttribute('data-height', String(window.innerHeight));
  var figs = Array.prototype.slice.call(document.querySelectorAll('figure'));
  b.setAttribute('data-svgs', figs.map(function (f) {
    var a = f.querySelector('figcaption a[href$=".svg"]');
    return f.id + '=' + (a ? a.getAttribute('href') : '');
  }).join(';'));
});
</script>"""


def _chromium(tmp_path, *args: str) -> subprocess.CompletedProcess:
    if CHROMIUM is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is required in CI (apt-get install chromium)")
        pytest.skip("chromium is not installed")
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
           "--no-first-run", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}", *args]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    return out


def test_first_screen_shows_the_verdict_and_every_figure_is_svg(tmp_path):
    from rotoruq.reference import application_for

    exp, val = _fake_reference(tmp_path)
    index = write_report([exp, val], tmp_path / "report",
                         application=application_for([exp, val]))
    claims = json.loads((tmp_path / "report" / "claims.json").read_text())
    probe = index.with_name("probe.html")
    probe.write_text(index.read_text().replace("<head>", "<head>" + FIRST_SCREEN_PROBE, 1))
    out = _chromium(tmp_path, "--window-size=1280,800", "--virtual-time-budget=10000",
                    "--dump-dom", probe.as_uri())
    body = re.search(r"<body([^>]*)>", out.stdout)
    assert body, out.stdout[:500]
    attrs = dict(re.findall(r'(data-[a-z-]+)="([^"]*)"', body.group(1)))
    # the counts, as the claims say, within the first screen of a laptop-sized window
    statuses = [c["status"] for c in claims]
    expect = [statuses.count(k) for k in ("holds", "holds, with a warning", "does not hold",
                                          "not checked")]
    assert attrs["data-counts"] == "/".join(map(str, expect))
    assert 0 < int(attrs["data-counts-top"]) <= int(attrs["data-height"])
    assert f"{len(claims)} claims of the reference study" in attrs["data-counts-text"]
    # every figure links its SVG file, which exists beside its PNG and is an SVG drawing
    links = dict(p.split("=", 1) for p in attrs["data-svgs"].split(";") if p)
    assert len(links) >= 3
    figures = tmp_path / "report" / "figures"
    for fig_id, href in links.items():
        assert href == f"figures/{fig_id.removeprefix('fig-')}.svg"
        svg = tmp_path / "report" / href
        assert svg.with_suffix(".png").is_file()
        assert ET.parse(svg).getroot().tag == "{http://www.w3.org/2000/svg}svg"
    assert sorted(p.stem for p in figures.glob("*.svg")) == sorted(
        p.stem for p in figures.glob("*.png"))
    # printed by the browser, the page is a PDF (the print CSS hides the folded contents)
    pdf = tmp_path / "report.pdf"
    _chromium(tmp_path, f"--print-to-pdf={pdf}", "--no-pdf-header-footer", index.as_uri())
    assert pdf.read_bytes()[:5] == b"%PDF-"
