"""pytest plugin of ``benchmarks/test_lanes.py``: the CPU seconds of every test (setup, call
and teardown), in each process that runs tests (an xdist worker, or pytest alone).

CPU seconds are this process's (``time.process_time``: user + system, every thread) plus its
children's that it waited for (``RUSAGE_CHILDREN``: the ``rotoruq`` subprocesses of a CLI
test). A process's first test that calls a numba-compiled function also pays for loading (or
compiling) it: ``compile_s`` is the CPU seconds of this process while numba compiled during
the test (its ``numba:compile`` events, outermost only: a kernel its on-disk cache did not
hold, on a new checkout or after its source changed; a compile in a subprocess is not seen).
One JSON line a test goes to ``$ROTORUQ_TEST_CPU/cpu-<pid>.jsonl``: ``{"nodeid": ...,
"cpu_s": ..., "wall_s": ..., "compile_s": ...}``.

    python -m pytest -p _test_cpu tests/test_params.py   # with benchmarks/ on PYTHONPATH
"""

from __future__ import annotations

import importlib.abc
import importlib.util
import json
import os
import resource
import sys
import threading
import time

import pytest

_compile = {"s": 0.0}  # numba's compile seconds in this process so far
_depth = threading.local()


def _listen_to_numba() -> None:
    """Count the seconds of numba's outermost ``numba:compile`` events (a kernel's compile
    compiles the functions it calls inside the same event)."""
    from numba.core import event

    class Timer(event.Listener):
        def on_start(self, ev):
            level = getattr(_depth, "n", 0)
            if level == 0:
                _depth.t0 = time.process_time()
            _depth.n = level + 1

        def on_end(self, ev):
            _depth.n = getattr(_depth, "n", 1) - 1
            if _depth.n == 0:
                _compile["s"] += time.process_time() - _depth.t0

    event.register("numba:compile", Timer())


class _AfterNumba(importlib.abc.MetaPathFinder):
    """Registers the listener once numba is imported, by whichever test imports it first
    (importing numba here would cost every worker its import and change what the tests
    see)."""

    def find_spec(self, fullname, path, target=None):
        if fullname != "numba":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(fullname)
        if spec is None or spec.loader is None:
            return spec
        run = spec.loader.exec_module

        def exec_module(module):
            run(module)
            _listen_to_numba()

        spec.loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


if "numba" in sys.modules:
    _listen_to_numba()
else:
    sys.meta_path.insert(0, _AfterNumba())


def _cpu() -> float:
    """CPU seconds of this process and of the children it waited for."""
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + ru.ru_utime + ru.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    c0, t0, k0 = _cpu(), time.perf_counter(), _compile["s"]
    yield
    cpu, wall = _cpu() - c0, time.perf_counter() - t0
    folder = os.environ.get("ROTORUQ_TEST_CPU")
    if not folder:
        return
    with open(os.path.join(folder, f"cpu-{os.getpid()}.jsonl"), "a", encoding="utf-8") as fh:
        fh.write(json.dumps({"nodeid": item.nodeid, "cpu_s": round(cpu, 3),
                             "wall_s": round(wall, 3),
                             "compile_s": round(_compile["s"] - k0, 3)}) + "\n")


def read(folder: str) -> list[dict]:
    """Every test's record written under ``folder``, the most CPU first."""
    rows = []
    for name in sorted(os.listdir(folder)):
        if name.startswith("cpu-") and name.endswith(".jsonl"):
            with open(os.path.join(folder, name), encoding="utf-8") as fh:
                rows.extend(json.loads(line) for line in fh if line.strip())
    return sorted(rows, key=lambda r: -r["cpu_s"])
