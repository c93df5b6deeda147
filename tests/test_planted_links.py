"""Paths an evaluation creates refuse a planted symlink (issue 36): through ``rotoruq run``
(the CLI's entry point in the test's process, ``tests/_inproc.py``), with real symlinks
planted by a real driver process, in the evaluation's own folder (its results file) and at
the name of the next evaluation's folder; ``rotoruq driver`` in a fresh process. The
evaluation fails, naming the link; nothing is read or written through it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from _inproc import rotoruq

SRC = str(Path(__file__).resolve().parents[1] / "src")

# A driver that plants a link: at the name of the next evaluation's folder (`next-folder`,
# to an outside folder), or at its own results file (`results`, to a valid results file
# outside). Its own folder is <base>/<name>.<pid>.<token>.<eval_id>.
PLANTER = r'''
import os, sys
here = os.getcwd()
prefix, last = os.path.basename(here).rsplit(".", 1)
target = os.environ["TARGET"]
if os.environ["PLANT"] == "next-folder":
    os.symlink(target, os.path.join(os.path.dirname(here), f"{prefix}.{int(last) + 1}"))
    open(sys.argv[2], "w").write("1.0 y1\n2.0 y2\n")
else:
    with open(os.path.join(target, "theirs.out"), "w") as f:
        f.write("7.0 y1\n8.0 y2\n")
    os.symlink(os.path.join(target, "theirs.out"), sys.argv[2])
'''


@pytest.mark.parametrize("plant", ["next-folder", "results"])
def test_a_link_planted_where_an_evaluation_works_fails_it_naming_the_link(tmp_path, plant):
    from test_trust import external_study

    study = external_study(tmp_path, n=3)
    (tmp_path / "driver.py").write_text(PLANTER)
    target = tmp_path / "elsewhere"
    target.mkdir()
    out = tmp_path / "out"
    proc = rotoruq("run", study, "--out", out, "--no-report", cwd=tmp_path,
                   env={"PLANT": plant, "TARGET": str(target)})
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr
    (line,) = [ln for ln in proc.stderr.splitlines() if "error" in ln]
    links = [p for p in (out / "work").rglob("*") if p.is_symlink()]
    assert len(links) == 1
    if plant == "next-folder":  # evaluation 2 could not make its folder: nothing written
        assert "evaluation 2 failed" in line and "could not make a work directory" in line
        assert f"symlink planted at {links[0]} (-> {target})" in line
        assert list(target.iterdir()) == []
    else:  # evaluation 1's results file is a link: not read
        assert "evaluation 1 failed" in line and "bad results file" in line
        assert f"symlink planted at {links[0]} (-> {target / 'theirs.out'})" in line
        assert links[0].name == "results.out"
        assert [p.name for p in target.iterdir()] == ["theirs.out"]


@pytest.mark.parametrize("at", ["r.out", "r.out.tmp"])
def test_rotoruq_driver_never_writes_its_results_through_a_link(tmp_path, at):
    """`rotoruq driver p.in r.out` in a folder where a link was planted at the results file
    (refused, one line naming it) or at the temporary name the old driver used (unused)."""
    (tmp_path / "p.in").write_text("1 variables\n5.0 collective_deg\n1 functions\n"
                                   "1 ASV_1:thrust\n1 derivative_variables\n"
                                   "1 DVV_1:collective_deg\n0 analysis_components\n1 eval_id\n")
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me\n")
    (tmp_path / at).symlink_to(victim)
    proc = subprocess.run([sys.executable, "-m", "rotoruq.study.cli", "driver", "p.in",
                           "r.out", "--preset", "gvpm"], capture_output=True, text=True,
                          cwd=tmp_path, timeout=300, env={**os.environ, "PYTHONPATH": SRC})
    assert "Traceback" not in proc.stderr
    assert victim.read_text() == "keep me\n"
    if at == "r.out":
        assert proc.returncode == 1
        assert proc.stderr.splitlines()[-1].startswith(
            f"rotoruq driver: cannot write the results file: symlink planted at r.out (-> "
            f"{victim})")
    else:
        assert proc.returncode == 0, proc.stderr
        assert not (tmp_path / "r.out").is_symlink()
        assert "thrust" in (tmp_path / "r.out").read_text()


class _Fig:
    name, caption, xlabels, ylabels = "f", "a figure", ("x [m]",), ("y [N]",)
    png, svg = b"\x89PNG fake", b"<svg/>"


def test_the_figure_cache_is_held_by_its_descriptor_not_its_name(tmp_path):
    """The cache folder is opened once, without following a link: swapped for a link after
    it was opened (between check and use), the entry goes to the folder held, nothing
    through the link; a link planted at an entry's name is neither read nor replaced."""
    from rotoruq.report.figcache import CACHE_DIR, FigureCache
    from rotoruq.safety import SafeFolder

    report, elsewhere = tmp_path / "report", tmp_path / "elsewhere"
    elsewhere.mkdir()
    with SafeFolder(report) as out, FigureCache(report, out) as cache:
        assert cache.get("k0", lambda *a: a, {}) is None  # opens nothing yet: no cache folder
        cache.put("k1", [_Fig()], {})
        (report / CACHE_DIR).rename(tmp_path / "moved")
        (report / CACHE_DIR).symlink_to(elsewhere)
        cache.put("k2", [_Fig()], {})
        assert cache.get("k2", lambda *a: a, {})[0][2] == _Fig.png
        assert cache.prune() == 0
    assert list(elsewhere.iterdir()) == []
    assert sorted(p.name for p in (tmp_path / "moved").iterdir()) == ["k1", "k2"]
    # a fresh cache refuses the planted link at .figure-cache itself
    with FigureCache(report) as cache:
        assert cache.get("k1", lambda *a: a, {}) is None
        cache.put("k3", [_Fig()], {})
        assert cache.prune() == 0
    assert list(elsewhere.iterdir()) == []
    # a link planted at an entry: not read, not replaced, not removed through
    (report / CACHE_DIR).unlink()
    (tmp_path / "moved").rename(report / CACHE_DIR)
    (elsewhere / "0.png").write_bytes(b"theirs")
    (report / CACHE_DIR / "k1").rename(tmp_path / "k1-real")
    (report / CACHE_DIR / "k1").symlink_to(elsewhere)
    with FigureCache(report) as cache:
        assert cache.get("k1", lambda *a: a, {}) is None
        cache.put("k1", [_Fig()], {})
        assert cache.prune() == 2  # the unused k2 and the link k1 (the link itself)
    assert (elsewhere / "0.png").read_bytes() == b"theirs"
    assert list((report / CACHE_DIR).iterdir()) == []


def test_an_mbdyn_case_folder_planted_as_a_link_is_refused_before_mbdyn_runs(tmp_path):
    """A batch of MBDyn points runs each in ``point_<k>``: a link planted at that name is
    refused naming it, and nothing is written through it (MBDyn is never started, so the
    check needs no MBDyn build)."""
    from rotoruq.mbdyn.case import run_case
    from rotoruq.rotor.presets import get_preset
    from rotoruq.safety import UnsafePathError

    outside = tmp_path / "outside"
    outside.mkdir()
    (tmp_path / "point_1").symlink_to(outside)
    with pytest.raises(UnsafePathError, match="point_1"):
        run_case(tmp_path / "point_1", get_preset("gvpm"), {"collective_deg": 6.0},
                 mbdyn="/nonexistent/mbdyn")
    assert list(outside.iterdir()) == []
