"""Time of the fast test lane (``pytest -q -n 2 -m fast``) and the modules it leaves untested.

The fast lane is the suite a developer runs often: every test without the ``slow``,
``extended``, ``browser``, ``mbdyn`` or ``dakota`` marker (``tests/conftest.py`` marks the
rest ``fast``). Its target (issue 34): under 5 minutes on 2 cores, covering every module of
``src/rotoruq``.

The default run measures the lane as a developer runs it: one ``pytest --collect-only``
first (it writes the bytecode caches of the test files, as a developer's earlier run would
have, and measures the collection alone), then the lane; wall seconds, CPU seconds of pytest
and its workers (user + system, every process it waited for), the test counts from pytest's
summary and the load average before and after (timings on a shared machine are inflated by
the load; the CPU seconds much less). The CPU seconds of every test (``_test_cpu.py``, a
pytest plugin: its process's and the subprocesses' it waited for, setup and teardown
included) give the ``slowest`` tests and ``over_10_cpu_s``, the fast tests above the 10 s a
test of this lane may take (README: such a test gets ``@pytest.mark.slow``), and
``files_cpu_s``, the test files whose tests cost the most CPU seconds together. Python's
bytecode cache is on in the children even when ``PYTHONDONTWRITEBYTECODE`` is set here
(without it every run rewrites the assertions of every test file again: ~15 CPU-s per
worker).

The lane is timed as a developer's repeated run: on a warm numba cache. A checkout that
changed a kernel's source leaves numba's cache stale, and the first tests to call each kernel
then compile it (tens of CPU-s each, in whichever test comes first: a lane measured so
charged 35 CPU-s to an example that costs 2). Before the lane the script asks numba's cache
index whether rotoruq's compiled functions are cached for their current source
(``numba_cold_before``); when some are not (``--warm auto``, the default), it runs the lane
once unmeasured first (``warm_up``: its wall and CPU seconds, the first run after such a
checkout). ``compile_cpu_s`` adds up the seconds the tests' own processes spent compiling
during the measured lane (``compile_s`` of each test: ``_test_cpu.py``); a compile in a
subprocess is not counted there.

``--marker EXPR`` times another lane instead: ``--marker "not fast"`` runs the ``slow``,
``mbdyn``, ``browser`` and ``dakota`` tests (the rest of the full suite) with the same plugin,
and ``--slowest N`` lists N tests (``benchmarks/results/test_lanes_slow.json`` lists them all).

``--modules`` runs the lane instead under ``coverage`` (``pip install coverage``), started in
each worker after collection: a module counts when a fast test ran a line of it (its
functions, or its body when a test's code imported it first), not for being imported by a
test file. It lists the modules of ``src/rotoruq`` no fast test ran. Code run only in a
subprocess (a test of the CLI) is not seen; a numba-compiled function counts when it was
compiled or loaded for a call, but one compiled into its caller (loaded from the cache with
it) is not seen, so a module listed may still be tested that way: read the list.

    python benchmarks/test_lanes.py --json benchmarks/results/test_lanes.json
    python benchmarks/test_lanes.py --modules [-- tests/test_params.py]   # pytest arguments
    python benchmarks/test_lanes.py --summary benchmarks/results/test_lanes.json  # README's line
    python benchmarks/test_lanes.py --per-test /tmp/lane.jsonl   # and every test's seconds
    python benchmarks/test_lanes.py --marker "not fast" --slowest 1000 \
        --json benchmarks/results/test_lanes_slow.json              # the full suite's rest
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _provenance import provenance  # noqa: E402  (benchmarks/ is on sys.path)
from _summary import print_and_save, print_saved_summary  # noqa: E402  (benchmarks/ is on sys.path)

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "rotoruq"
MARKER = "fast"
LANE = ["-q", "-n", "2", "-m", MARKER]
SLOWEST = 30  # the tests listed by their CPU seconds (--slowest)
SLOW_CPU_S = 10.0  # README: a test above this gets @pytest.mark.slow
COUNTS = re.compile(r"(\d+) (passed|failed|skipped|deselected|errors?|xfailed|xpassed)")


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(ROOT / "src"), str(ROOT / "benchmarks"), *filter(None, [env.get("PYTHONPATH")])])
    return env


def _pytest(args: list[str]) -> tuple[float, float, str, int]:
    """(wall s, CPU s, output, exit code) of ``python -m pytest ARGS`` from the repository root."""
    c0, t0 = _children_cpu(), time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "pytest", *args], cwd=ROOT, env=_env(),
                          capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - c0
    return wall, cpu, done.stdout + done.stderr, done.returncode


def _counts(output: str) -> dict[str, int]:
    """The counts of pytest's last summary line (``2400 passed, 30 skipped, ... in 250.1s``)."""
    last = [ln for ln in output.splitlines() if re.search(r" in [\d.]+s", ln)]
    if not last:
        raise RuntimeError("pytest printed no summary line:\n" + output[-3000:])
    return {k.rstrip("s") if k.startswith("error") else k: int(n)
            for n, k in COUNTS.findall(last[-1])}


# run in a fresh interpreter (the script imports no rotoruq): the compiled functions called
# from Python or from other compiled functions (not those inlined into their callers) whose
# code numba's cache index does not hold for their current source, and the rotor kernel's
# forward-flight build, cached apart from the hover build
COLD_CHECK = r"""
import importlib, json, pathlib, sys
from numba.core.dispatcher import Dispatcher
from rotoruq._compile import is_cached
from rotoruq.rotor.hover import kernels_cached
src = pathlib.Path(sys.argv[1])
cold = []
for path in sorted(src.rglob("*.py")):
    text = path.read_text(encoding="utf-8")
    if "cache=True" not in text and '"cache": True' not in text:
        continue
    name = ".".join(path.relative_to(src.parent).with_suffix("").parts)
    module = importlib.import_module(name)
    for key, fn in vars(module).items():
        if (isinstance(fn, Dispatcher) and fn.__module__ == name
                and fn.targetoptions.get("inline", "never") != "always"
                and not is_cached(fn)):
            cold.append(name + "." + key)
if not kernels_cached(True):
    cold.append("rotoruq.rotor._kernel.solve_samples (forward-flight build)")
print(json.dumps(cold))
"""


def numba_cold() -> list[str]:
    """rotoruq's compiled functions that numba's on-disk cache does not hold for their
    current source (``COLD_CHECK``): the lane's first calls of them would compile."""
    done = subprocess.run([sys.executable, "-c", COLD_CHECK, str(SRC)], cwd=ROOT, env=_env(),
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError("the numba cache check failed:\n" + done.stderr[-3000:])
    return json.loads(done.stdout)


def failures(output: str) -> list[str]:
    """The tests pytest's short summary (``-ra``, pyproject.toml) names as failed or in
    error."""
    return re.findall(r"^(?:FAILED|ERROR) (.+?)(?: - .*)?$", output, re.M)


def by_file(tests: list[dict]) -> dict[str, float]:
    """CPU seconds of the tests of each test file (their own, subprocesses included), the
    ``SLOWEST`` costliest files, the most first."""
    sums: dict[str, float] = {}
    for t in tests:
        path = t["nodeid"].split("::")[0]
        sums[path] = sums.get(path, 0.0) + t["cpu_s"]
    top = sorted(sums.items(), key=lambda kv: -kv[1])[:SLOWEST]
    return {path: round(cpu, 1) for path, cpu in top}


def measure(extra: list[str], per_test_path: str | None = None, warm: str = "auto",
            slowest: int = SLOWEST) -> dict:
    """Collect once (bytecode caches written, collection timed), warm numba's cache when
    ``warm`` says so (``"auto"``: when it is cold, ``"always"``, ``"never"``), then run the
    lane; with ``per_test_path``, every test's record (``_test_cpu.py``) saved there as JSON
    lines."""
    load0 = [round(v, 2) for v in os.getloadavg()]
    # the commit, date and sources at the start (a commit made while the lane runs is not
    # what it ran); the load average at the end, as before
    prov = provenance(modules=all_modules())
    cwall, ccpu, cout, crc = _pytest(["--collect-only", *LANE, *extra])
    if crc != 0:
        raise RuntimeError(f"pytest --collect-only exited with {crc}:\n{cout[-3000:]}")
    cold = numba_cold()
    warm_up = None
    if warm == "always" or (warm == "auto" and cold):
        wwall, wcpu, wout, wrc = _pytest([*LANE, *extra])
        warm_up = {"wall_s": round(wwall, 1), "cpu_s": round(wcpu, 1), "exit_code": wrc,
                   "numba_cold_after": numba_cold()}
        load0 = [round(v, 2) for v in os.getloadavg()]
    # imported here: importing the plugin in a process watches its imports for numba's
    from _test_cpu import read as read_test_cpu

    per_test = tempfile.mkdtemp(prefix="lane-cpu-")
    try:
        os.environ["ROTORUQ_TEST_CPU"] = per_test
        wall, cpu, out, rc = _pytest([*LANE, "-p", "_test_cpu", *extra])
        tests = read_test_cpu(per_test)
    finally:
        os.environ.pop("ROTORUQ_TEST_CPU", None)
        shutil.rmtree(per_test, ignore_errors=True)
    if per_test_path:
        Path(per_test_path).write_text("".join(json.dumps(t) + "\n" for t in tests),
                                       encoding="utf-8")
    counts = _counts(out)
    failed = counts.get("failed", 0) + counts.get("error", 0)
    return {"command": "pytest " + " ".join(LANE + extra), "exit_code": rc,
            "failed_tests": failures(out),
            "wall_s": round(wall, 1), "cpu_s": round(cpu, 1),
            "collect_wall_s": round(cwall, 1), "collect_cpu_s": round(ccpu, 1),
            "passed": counts.get("passed", 0), "skipped": counts.get("skipped", 0),
            "failed": failed, "deselected": counts.get("deselected", 0),
            "cores": os.cpu_count(), "load_before": load0,
            "load_after": [round(v, 2) for v in os.getloadavg()],
            "tests_cpu_s": round(sum(t["cpu_s"] for t in tests), 1),
            "numba_cold_before": cold, "warm_up": warm_up,
            "compile_cpu_s": round(sum(t.get("compile_s", 0.0) for t in tests), 1),
            "slowest": tests[:slowest], "files_cpu_s": by_file(tests),
            "over_10_cpu_s": [t["nodeid"] for t in tests if t["cpu_s"] > SLOW_CPU_S],
            "provenance": {**prov, "load": [round(v, 2) for v in os.getloadavg()]}}


def all_modules() -> list[str]:
    """Every module of ``src/rotoruq``, by name (``rotoruq.rotor.hover``), from its files."""
    names = []
    for path in sorted(SRC.rglob("*.py")):
        parts = path.relative_to(SRC.parent).with_suffix("").parts
        names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


def untested_modules(extra: list[str]) -> dict:
    """Run the lane under coverage (``_lane_modules.py``, a pytest plugin) and name the
    modules of ``src/rotoruq`` whose functions no test of it ran."""
    try:
        import coverage
    except ImportError:
        raise SystemExit("--modules needs coverage: pip install coverage") from None
    data_dir = Path(tempfile.mkdtemp(prefix="lane-modules-"))
    try:
        os.environ["ROTORUQ_LANE_COVERAGE"] = str(data_dir / ".coverage")
        wall, cpu, out, rc = _pytest([*LANE, "-p", "_lane_modules", *extra])
        counts = _counts(out)
        cov = coverage.Coverage(data_file=str(data_dir / ".coverage"))
        cov.combine(data_paths=[str(data_dir)])
        data = cov.get_data()
        ran = {str(Path(f).resolve()): set(data.lines(f) or ()) for f in data.measured_files()}
        compiled = {ln for f in data_dir.glob("numba-*.txt")
                    for ln in f.read_text(encoding="utf-8").split()}
    finally:
        os.environ.pop("ROTORUQ_LANE_COVERAGE", None)
        shutil.rmtree(data_dir, ignore_errors=True)
    untested = []
    for path, name in zip(sorted(SRC.rglob("*.py")), all_modules(), strict=True):
        if not ran.get(str(path.resolve())) and name not in compiled:
            untested.append(name)
    return {"command": "pytest " + " ".join(LANE + extra) + " (under coverage)",
            "exit_code": rc, "passed": counts.get("passed", 0),
            "modules": len(all_modules()), "untested": untested,
            "wall_s": round(wall, 1), "cpu_s": round(cpu, 1)}


def summary(res: dict) -> str:
    """README's sentence: the lane's command, test count, time and the load it ran at."""
    return (f"`{res['command']}`: {res['passed']:,} tests passed ({res['skipped']} skipped, "
            f"{res['failed']} failed) in {res['wall_s'] / 60:.1f} min wall, "
            f"{res['cpu_s'] / 60:.1f} CPU-min, on {res['cores']} cores at load "
            f"{res['load_before'][0]:g} (1-min average at the start; collecting the tests "
            f"alone takes {res['collect_cpu_s']:.0f} CPU-s); measured "
            f"{res['provenance']['date'][:10]} at {res['provenance']['commit'][:10]}."
            + _slowest_sentence(res) + _compile_sentence(res))


def _compile_sentence(res: dict) -> str:
    """Whether numba compiled during the lane (results saved before it was recorded: an
    empty string)."""
    if "compile_cpu_s" not in res:
        return ""
    if res["compile_cpu_s"] > 0:
        return (f" Numba compiled for {res['compile_cpu_s']:.0f} CPU-s in the tests' processes "
                "(a cold cache).")
    first = res.get("warm_up")
    after = (f"; the first run after the checkout, which compiled, took "
             f"{first['wall_s'] / 60:.1f} min wall)." if first else ").")
    return " Numba compiled nothing in the tests' processes (a warm cache" + after


def _slowest_sentence(res: dict) -> str:
    """The lane's most expensive test and how many take more than ``SLOW_CPU_S`` (results
    saved before the per-test CPU seconds have none: an empty string)."""
    if not res.get("slowest"):
        return ""
    top = res["slowest"][0]
    over = len(res["over_10_cpu_s"])
    return (f" The tests' own CPU seconds add up to {res['tests_cpu_s'] / 60:.1f} CPU-min; the "
            f"most expensive is `{top['nodeid']}` ({top['cpu_s']:.0f} CPU-s), and {over} "
            f"test{'' if over == 1 else 's'} take more than {SLOW_CPU_S:.0f} CPU-s.")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", help="save the result here")
    ap.add_argument("--modules", action="store_true",
                    help="run the lane under coverage and list the modules no fast test runs")
    ap.add_argument("--summary", metavar="JSON", help="print README's line from a saved result")
    ap.add_argument("--per-test", metavar="JSONL",
                    help="also save every test's CPU and wall seconds here, one JSON line each")
    ap.add_argument("--warm", choices=("auto", "always", "never"), default="auto",
                    help="run the lane once unmeasured first: when numba's cache is cold "
                         "(auto), always or never")
    ap.add_argument("--marker", default=MARKER,
                    help='the lane\'s -m expression ("not fast": the rest of the full suite)')
    ap.add_argument("--slowest", type=int, default=SLOWEST,
                    help="how many tests to list by their CPU seconds")
    ap.add_argument("pytest_args", nargs="*", help="more pytest arguments (after --)")
    args = ap.parse_args()
    LANE[-1] = args.marker
    if print_saved_summary(args.summary, summary):
        return
    if args.modules:
        res = untested_modules(args.pytest_args)
        print_and_save(res, args.json)
        raise SystemExit(1 if res["untested"] or res["exit_code"] else 0)
    print_and_save(measure(args.pytest_args, args.per_test, args.warm, args.slowest), args.json)


if __name__ == "__main__":
    main()
