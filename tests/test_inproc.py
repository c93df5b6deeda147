"""``tests/_inproc.py`` answers as a fresh ``rotoruq`` process does: the same exit code, stdout
and stderr for a run's summary, a ``show`` and a refused command, and it leaves the test's
process as it found it (working folder, environment, the loggers the command configures).
The tests that run the CLI in their own process instead of a fresh one rely on this."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import textwrap

from _inproc import rotoruq
from rotoruq.study import console

CLI = [sys.executable, "-m", "rotoruq.study.cli"]

STUDY = textwrap.dedent("""
    [study]
    name = "same"
    seed = 3

    [model]
    function = "text_book"
    responses = ["y1", "y2"]

    [parameters.a]
    distribution = "uniform"
    lower = -1.0
    upper = 1.0

    [parameters.b]
    distribution = "normal"
    mean = 0.5
    std = 0.2

    [[steps]]
    name = "lhs"
    type = "sampling"
    n_samples = 16
    """)


def fresh(*args, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True, cwd=cwd,
                          timeout=300)


def test_in_process_and_fresh_process_say_the_same(tmp_path):
    (tmp_path / "study.toml").write_text(STUDY)
    ran = fresh("run", "study.toml", "--out", "out", "--no-report", "--quiet", cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    here = rotoruq("run", "study.toml", "--out", "out", "--no-report", "--quiet",
                   cwd=tmp_path)  # the saved step is reused: nothing to time
    assert (here.returncode, here.stdout, here.stderr) == (0, ran.stdout, ran.stderr)
    for args in (("show", "out"), ("show", "out", "nope"), ("show",)):
        want, got = fresh(*args, cwd=tmp_path), rotoruq(*args, cwd=tmp_path)
        assert (got.returncode, got.stdout, got.stderr) == (
            want.returncode, want.stdout, want.stderr), args
    assert rotoruq("show", "out", "nope", cwd=tmp_path).returncode == 1
    assert rotoruq("show", cwd=tmp_path).returncode == 2  # argparse's usage error


def test_the_call_leaves_the_folder_environment_and_loggers_as_they_were(tmp_path):
    (tmp_path / "study.toml").write_text(STUDY)
    names = ("rotoruq", console.PROGRESS_LOGGER, console.WARNINGS_LOGGER)
    before = [(list(lg.handlers), lg.level, lg.propagate)
              for lg in map(logging.getLogger, names)]
    cwd = os.getcwd()
    assert "ROTORUQ_INPROC_PROBE" not in os.environ
    proc = rotoruq("-v", "run", "study.toml", "--out", "out", "--no-report", cwd=tmp_path,
                   env={"ROTORUQ_INPROC_PROBE": "1"})
    assert proc.returncode == 0, proc.stderr
    assert "lhs" in proc.stdout and proc.args[:2] == ["rotoruq", "-v"]
    assert os.getcwd() == cwd and "ROTORUQ_INPROC_PROBE" not in os.environ
    after = [(list(lg.handlers), lg.level, lg.propagate)
             for lg in map(logging.getLogger, names)]
    assert after == before
