"""pytest plugin of ``benchmarks/test_lanes.py``: the CPU seconds of every test (setup, call
and teardown), in each process that runs tests (an xdist worker, or pytest alone).

CPU seconds are this process's (``time.process_time``: user + system, every thread) plus its
children's that it waited for (``RUSAGE_CHILDREN``: the ``rotoruq`` subprocesses of a CLI
test). A process's first test that calls a numba-compiled function also pays for loading (or
compiling) it. One JSON line a test goes to ``$ROTORUQ_TEST_CPU/cpu-<pid>.jsonl``:
``{"nodeid": ..., "cpu_s": ..., "wall_s": ...}``.

    python -m pytest -p _test_cpu tests/test_params.py   # with benchmarks/ on PYTHONPATH
"""

from __future__ import annotations

import json
import os
import resource
import time

import pytest


def _cpu() -> float:
    """CPU seconds of this process and of the children it waited for."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + ru.ru_utime + ru.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    c0, t0 = _cpu(), time.perf_counter()
    yield
    cpu, wall = _cpu() - c0, time.perf_counter() - t0
    folder = os.environ.get("ROTORUQ_TEST_CPU")
    if not folder:
        return
    with open(os.path.join(folder, f"cpu-{os.getpid()}.jsonl"), "a", encoding="utf-8") as fh:
        fh.write(json.dumps({"nodeid": item.nodeid, "cpu_s": round(cpu, 3),
                             "wall_s": round(wall, 3)}) + "\n")


def read(folder: str) -> list[dict]:
    """Every test's record written under ``folder``, the most CPU first."""
    rows = []
    for name in sorted(os.listdir(folder)):
        if name.startswith("cpu-") and name.endswith(".jsonl"):
            with open(os.path.join(folder, name), encoding="utf-8") as fh:
                rows.extend(json.loads(line) for line in fh if line.strip())
    return sorted(rows, key=lambda r: -r["cpu_s"])
