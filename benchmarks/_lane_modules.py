"""pytest plugin of ``benchmarks/test_lanes.py --modules``: measure, in each process that runs
tests (an xdist worker, or pytest alone), the lines of rotoruq the tests run, from the end of
the collection on (a module imported by a test file counts only for what its tests ran). The
data goes to ``$ROTORUQ_LANE_COVERAGE`` with a suffix per process; the modules whose
numba-compiled functions were called (compiled or loaded from the cache: coverage does not
see their lines) to ``numba-<pid>.txt`` beside it, one name a line."""

from __future__ import annotations

import os
import sys

import coverage

_COV: list[coverage.Coverage] = []


def pytest_collection_finish(session) -> None:
    if session.config.getoption("numprocesses", None) and "PYTEST_XDIST_WORKER" not in os.environ:
        return  # the xdist controller runs no test
    cov = coverage.Coverage(data_file=os.environ["ROTORUQ_LANE_COVERAGE"], data_suffix=True,
                            source_pkgs=["rotoruq"])
    cov.start()
    _COV.append(cov)


def _compiled_modules() -> set[str]:
    """The rotoruq modules holding a numba dispatcher that has a compiled signature."""
    found = set()
    for name, module in list(sys.modules.items()):
        if not name.startswith("rotoruq") or module is None:
            continue
        for obj in list(vars(module).values()):
            py_func = getattr(obj, "py_func", None)
            if py_func is not None and getattr(obj, "signatures", None):
                found.add(py_func.__module__)
    return found


def pytest_sessionfinish(session) -> None:
    for cov in _COV:
        cov.stop()
        cov.save()
        folder = os.path.dirname(os.environ["ROTORUQ_LANE_COVERAGE"])
        with open(os.path.join(folder, f"numba-{os.getpid()}.txt"), "w", encoding="utf-8") as fh:
            fh.write("".join(f"{m}\n" for m in sorted(_compiled_modules())))
