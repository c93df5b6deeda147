"""Paths an evaluation creates refuse a planted symlink (issue 36): through ``rotoruq run`` in
a subprocess, with real symlinks planted by a real driver, in the evaluation's own folder
(its results file) and at the name of the next evaluation's folder. The evaluation fails,
naming the link; nothing is read or written through it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

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
    proc = subprocess.run([sys.executable, "-m", "rotoruq.study.cli", "run", str(study),
                           "--out", str(out), "--no-report"], capture_output=True, text=True,
                          cwd=tmp_path, timeout=300,
                          env={**os.environ, "PYTHONPATH": SRC, "PLANT": plant,
                               "TARGET": str(target)})
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
