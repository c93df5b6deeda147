"""The report opens in a real browser (headless Debian Chromium): every figure loads, every
figure's axes are labelled with units, and every table-of-contents link resolves."""

from __future__ import annotations

import os
import re
import shutil
import subprocess

import pytest

from rotoruq.report.html import write_report
from rotoruq.study.runner import run_study
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
