"""The last faults of issue 36, each through ``rotoruq`` in a subprocess with real processes,
real symlinks and a real file-size limit: a driver's whole process tree (setsid'd grandchildren
included) ends with the run, paths created after the start never follow a planted symlink,
storage errors are one line naming the file, long driver arguments are a usage error."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

SRC = str(Path(__file__).resolve().parents[1] / "src")
CLI = [sys.executable, "-m", "rotoruq.study.cli"]
ENV = {**os.environ, "PYTHONPATH": SRC}


def run_cli(*args, cwd=None, timeout=300, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=ENV, cwd=cwd, **kw)


PARAMS = "1 variables\n5.0 collective_deg\n1 functions\n1 ASV_1:thrust\n" \
         "1 derivative_variables\n1 DVV_1:collective_deg\n0 analysis_components\n"


@pytest.mark.parametrize("where", ["params", "results", "results-deep", "path"])
def test_driver_with_an_overlong_argument_is_a_usage_error(tmp_path, where):
    """A parameters or results name over NAME_MAX (255 bytes) or a path over PATH_MAX:
    exit 2, the usage line, no traceback; a results file that can be named says FAIL (for
    Dakota's failure capture)."""
    (tmp_path / "p.in").write_text(PARAMS)
    long = "a" * 300
    args = {"params": [long, "r.out"], "results": ["p.in", long],
            "results-deep": ["p.in", f"d/{long}/r.out"], "path": ["p.in", "a/" * 3000 + "r.out"]}[where]
    proc = run_cli("driver", *args, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and "usage: rotoruq driver" in proc.stderr
    expected = "a path of 6005 bytes" if where == "path" else "a file name of 300 bytes"
    what = "params" if where == "params" else "results"
    assert f"argument {what}: {expected}" in proc.stderr
    written = sorted(p.name for p in tmp_path.iterdir())
    if where == "params":
        assert written == ["p.in", "r.out"] and (tmp_path / "r.out").read_text() == "FAIL\n"
    else:
        assert written == ["p.in"]


def test_driver_whose_results_folder_is_missing_says_so_in_one_line(tmp_path):
    (tmp_path / "p.in").write_text(PARAMS)
    proc = run_cli("driver", "p.in", "no/r.out", cwd=tmp_path)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert proc.stderr.splitlines()[-1] == ("rotoruq driver: cannot write the results file "
                                            "no/r.out: No such file or directory")
