"""`rotoruq report` of unchanged results, as a user types it, imports neither scipy.stats nor
numba nor Matplotlib (issue 34: the rebuild in <= 2 s; scipy.stats alone cost about 1.1 CPU-s
of its 2.4): the figures come from the cache and the page is the same bytes."""

from __future__ import annotations

import re
import subprocess
import sys
import textwrap

import pytest

from _inproc import rotoruq
from rotoruq._lazy import lazy_module

STUDY = textwrap.dedent("""
    [study]
    name = "imports"
    seed = 5
    output = "out"

    [model]
    function = "text_book"
    responses = ["y1", "y2"]

    [parameters.a]
    distribution = "normal"
    mean = 0.2
    std = 0.3

    [parameters.b]
    distribution = "uniform"
    lower = -1.0
    upper = 1.0

    [[steps]]
    name = "loads"
    type = "sampling"
    n_samples = 40

    [[steps]]
    name = "indices"
    type = "sensitivity"
    n_samples = 64
    """)

#: Modules a report of unchanged results has no use for (each costs 0.3-1 CPU-s to import).
HEAVY = ("scipy.stats", "scipy.optimize", "numba", "matplotlib")


def _imported(stderr: str) -> set[str]:
    """Module names from ``python -X importtime``'s lines."""
    return {m.group(1) for m in re.finditer(r"^import time:\s+\d+ \|\s+\d+ \| +(\S+)$",
                                            stderr, re.M)}


def _page(folder) -> str:
    return re.sub(r"Generated \S+ from [^<]*", "", (folder / "index.html").read_text())


def test_an_unchanged_report_imports_no_scipy_stats_numba_or_matplotlib(tmp_path):
    (tmp_path / "s.toml").write_text(STUDY)
    # the run in this process (tests/_inproc.py): what it imports is not the question; the
    # reports below are fresh processes, whose imports are
    run = rotoruq("run", "s.toml", "-q", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    out, report = tmp_path / "out", tmp_path / "out" / "report"
    first = _page(report)
    figures = {p.name: p.read_bytes() for p in (report / "figures").iterdir()}
    assert len(figures) >= 4  # the figures were drawn (and cached) by the run
    again = subprocess.run([sys.executable, "-X", "importtime", "-m", "rotoruq", "report",
                            str(out), "-q"], capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    imported = _imported(again.stderr)
    assert "rotoruq.report.html" in imported  # the lines were read
    assert {m for m in imported if m.startswith(HEAVY)} == set()
    # the same page and figures as the run's report, which imported them all
    assert _page(report) == first
    assert {p.name: p.read_bytes() for p in (report / "figures").iterdir()} == figures
    # a report that must draw does import them (the check above can fail)
    fresh = subprocess.run([sys.executable, "-X", "importtime", "-m", "rotoruq", "report",
                            str(out), "--out", str(tmp_path / "fresh"), "-q"],
                           capture_output=True, text=True, timeout=600)
    assert fresh.returncode == 0, fresh.stderr
    assert "matplotlib" in _imported(fresh.stderr)
    assert _page(tmp_path / "fresh") == first


def test_uniform_and_normal_moments_are_scipys_bits():
    """Uniform's and Normal's moments and bounds, computed without scipy, are the bits its
    frozen distributions give; PHI_95 is scipy's quantile."""
    import numpy as np
    from scipy import stats

    from rotoruq.params.distributions import PHI_95, Normal, Uniform

    assert PHI_95 == float(stats.norm.ppf(0.95))
    rng = np.random.default_rng(11)
    lows = np.concatenate([rng.normal(size=300) * 10.0 ** rng.integers(-6, 7, 300),
                           rng.integers(-9, 9, 40).astype(float), [0.0, -0.0, 1e-300]])
    for lo in lows:
        for w in (rng.exponential() * 10.0 ** rng.integers(-8, 7), 1.0, 0.1, 3.0):
            lo, hi = float(lo), float(lo + w)
            if not lo < hi:
                continue
            ref = stats.uniform(loc=lo, scale=hi - lo)
            u = Uniform(lo, hi)
            assert u.moments == (float(ref.mean()), float(ref.std())), (lo, hi)
            assert (u.mean, u.std) == u.moments
            assert u.bounds == tuple(float(b) for b in ref.support()), (lo, hi)
    n = Normal(1.5, 0.25)
    assert n.bounds == tuple(float(b) for b in stats.norm(1.5, 0.25).support())


def test_a_lazy_module_imports_on_first_use_and_is_the_module():
    import importlib

    m = lazy_module("json")
    assert "not imported" in repr(m)
    assert m.dumps is importlib.import_module("json").dumps
    assert "(imported)" in repr(m)
    missing = lazy_module("rotoruq_no_such_module")
    with pytest.raises(ModuleNotFoundError, match="rotoruq_no_such_module"):
        getattr(missing, "anything")  # noqa: B009 - the read is the test
