"""Shared fixtures: analytic test functions and the path to ../shared (may be absent)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

# every `rotoruq driver` of the tests runs in process (no driver server left behind);
# tests/test_driver_server.py switches the warm path on, each test with a folder of its own
os.environ["ROTORUQ_DRIVER_SERVER"] = "0"

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"


@pytest.fixture
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.skip("../shared is absent")
    return SHARED


@pytest.fixture
def rotoruq_main(capsys):
    """``rotoruq ARGS`` in this process (``rotoruq.study.cli.main``): (exit code, stdout,
    stderr), run from the current folder (``monkeypatch.chdir`` for a study's own). For checks
    of what the command says about bad input, where a fresh process would add ~2 CPU-s of
    start-up and nothing of the path (tests/test_cli.py runs the same entry point in fresh
    processes). The loggers and the warnings hook the command configures are put
    back afterwards, so later tests in this worker see pytest's."""
    import logging
    import warnings

    from rotoruq.study import console
    from rotoruq.study.cli import main

    names = ("rotoruq", console.PROGRESS_LOGGER, console.WARNINGS_LOGGER)
    saved = [(lg, list(lg.handlers), lg.level, lg.propagate)
             for lg in map(logging.getLogger, names)]
    shown = warnings.showwarning

    def run(*args) -> tuple[int, str, str]:
        try:
            code = main([str(a) for a in args])
        except SystemExit as exc:  # argparse's errors (exit 2), as a process would end
            code = exc.code
        out, err = capsys.readouterr()
        return code, out, err

    try:
        yield run
    finally:
        warnings.showwarning = shown
        for lg, handlers, level, propagate in saved:
            lg.handlers[:] = handlers
            lg.setLevel(level)
            lg.propagate = propagate


def ishigami(x: np.ndarray, a: float = 7.0, b: float = 0.1) -> np.ndarray:
    """Ishigami function on [-pi, pi]^3, shape (n,)."""
    return np.sin(x[:, 0]) + a * np.sin(x[:, 1]) ** 2 + b * x[:, 2] ** 4 * np.sin(x[:, 0])


def pytest_addoption(parser):
    parser.addoption("--extended", action="store_true",
                     help="also run the tests marked `extended`: the long versions of checks "
                          "CI runs at a smaller size (minutes each)")


# the markers of the tests the fast lane (`pytest -n 2 -m fast`) leaves out
NOT_FAST = ("slow", "mbdyn", "browser", "dakota", "extended")


def pytest_collection_modifyitems(config, items):
    """Tests that run the ``dakota`` executable (their skip condition names it) get the marker
    ``dakota``: they compare our numbers with Dakota's, which the minimum-versions lane of
    .ci/run need not repeat (they already ran at the current versions). Tests marked
    ``extended`` (the long versions of checks the suite runs at a smaller size) are skipped
    unless ``pytest --extended``. Every other test gets the marker ``fast``: the lane a
    developer runs often is ``pytest -q -n 2 -m fast`` (README, developer section).

    The test files holding ``slow`` or ``mbdyn`` tests run first, each file's tests in their
    own order: with ``-n auto`` (pytest-xdist) the minutes-long tests start at once instead
    of leaving one worker alone with them at the end. That needs ``--dist worksteal``
    (pyproject.toml's addopts): xdist's default hands each worker a fixed first chunk of the
    queue, and the worker whose chunk held these tests ran them alone while the other one
    ran out of work."""
    for item in items:
        for mark in item.iter_markers("skipif"):
            if "'dakota' executable" in str(mark.kwargs.get("reason", "")):
                item.add_marker(pytest.mark.dakota)
                break
    for item in items:
        if not any(item.get_closest_marker(m) for m in NOT_FAST):
            item.add_marker(pytest.mark.fast)
    if not config.getoption("--extended"):
        skip = pytest.mark.skip(reason="extended check: run with pytest --extended")
        for item in items:
            if item.get_closest_marker("extended"):
                item.add_marker(skip)
    heavy = {item.path for item in items
             if item.get_closest_marker("slow") or item.get_closest_marker("mbdyn")}
    items.sort(key=lambda item: item.path not in heavy)  # stable: the order within kept
