"""``rotoruq ARGS`` through the CLI's entry point in the test's own process, as a
``subprocess.CompletedProcess``: the drop-in for a test's ``subprocess.run`` of the CLI where
the process itself is not what is tested (a run, show, export or repair of a study folder).

A fresh ``rotoruq`` process costs 1.5-2 CPU-s of interpreter start and imports before it
reads a study, and the first process to call a numba kernel loads it again; in the test's
process both are paid once per pytest worker. What only a process shows (an exit on a signal,
the compile notice, the terminal, ``python -m rotoruq``, a plugin found by its entry point)
stays a fresh process, and each command keeps fresh-process tests (tests/test_cli.py and the
first test of each file that uses this).

The command's working folder (``cwd``) and environment (``env``: the variables that differ
from this process's) are set for the call and put back afterwards, as are the loggers and the
warnings hook the command configures (later tests in the worker see pytest's).
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
import subprocess
import warnings
from collections.abc import Mapping
from pathlib import Path


def rotoruq(*args: object, cwd: str | Path | None = None,
            env: Mapping[str, str] | None = None) -> subprocess.CompletedProcess:
    """Run ``rotoruq ARGS`` here; (``args``, exit code, stdout, stderr) as a process's."""
    from rotoruq.study import console
    from rotoruq.study.cli import main

    names = ("rotoruq", console.PROGRESS_LOGGER, console.WARNINGS_LOGGER)
    saved = [(lg, list(lg.handlers), lg.level, lg.propagate)
             for lg in map(logging.getLogger, names)]
    shown = warnings.showwarning
    changed = {k: v for k, v in (env or {}).items() if os.environ.get(k) != v}
    before = {k: os.environ.get(k) for k in changed}
    here = os.getcwd()
    out, err = io.StringIO(), io.StringIO()
    argv = [str(a) for a in args]
    try:
        os.environ.update(changed)
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(argv)
            except SystemExit as exc:  # argparse's errors (exit 2), as a process would end
                code = exc.code if isinstance(exc.code, int) else (exc.code is not None)
    finally:
        os.chdir(here)
        for key, value in before.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
        warnings.showwarning = shown
        for lg, handlers, level, propagate in saved:
            lg.handlers[:] = handlers
            lg.setLevel(level)
            lg.propagate = propagate
    return subprocess.CompletedProcess(["rotoruq", *argv], int(code), out.getvalue(),
                                       err.getvalue())
