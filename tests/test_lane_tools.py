"""The tools that time the test lanes (``benchmarks/test_lanes.py``, ``benchmarks/_test_cpu.py``):
the per-test record of the CPU seconds numba spent compiling, and the check of numba's cache
that decides whether the lane is run once unmeasured first."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))

import lane_schedule  # noqa: E402
import test_lanes  # noqa: E402


def _env(**extra: str) -> dict[str, str]:
    env = {**os.environ, **extra}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), str(BENCHMARKS)])
    return env


@pytest.mark.slow  # two pytest processes importing numba and compiling (~5 CPU-s)
def test_the_plugin_charges_a_compile_to_the_test_that_compiled(tmp_path):
    """A test that compiles a new numba function has ``compile_s`` > 0 (the listener is
    registered when the first test imports numba); one that calls it again compiled nothing."""
    (tmp_path / "test_k.py").write_text(textwrap.dedent("""\
        import numba

        def test_before_numba():
            assert 1 + 1 == 2

        @numba.njit
        def twice(x):
            return 2.0 * x

        def test_compiles():
            assert twice(1.5) == 3.0

        def test_compiled_already():
            assert twice(2.5) == 5.0
        """))
    # numba imported at collection: the listener is registered on the import's way out
    (tmp_path / "test_lazy.py").write_text(textwrap.dedent("""\
        def test_imports_and_compiles():
            import numba

            assert numba.njit(lambda x: x + 1)(1) == 2
        """))
    records = tmp_path / "cpu"
    records.mkdir()
    for name in ("test_k.py", "test_lazy.py"):
        done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                               "-p", "_test_cpu", name], cwd=tmp_path, capture_output=True,
                              text=True, timeout=300, env=_env(ROTORUQ_TEST_CPU=str(records)))
        assert done.returncode == 0, done.stdout + done.stderr
    rows = {r["nodeid"].split("::")[1]: r for f in records.iterdir()
            for r in map(json.loads, f.read_text().splitlines())}
    assert rows["test_compiles"]["compile_s"] > 0
    assert rows["test_compiled_already"]["compile_s"] == 0
    assert rows["test_before_numba"]["compile_s"] == 0
    assert rows["test_imports_and_compiles"]["compile_s"] > 0
    assert rows["test_compiles"]["cpu_s"] >= rows["test_compiles"]["compile_s"] * 0.5


@pytest.mark.slow  # imports every module of rotoruq with compiled functions (~4 CPU-s)
def test_the_cold_check_names_the_functions_of_a_changed_source(tmp_path):
    """A kernel's source changed (a comment appended: numba keys its cache by the source's
    hash) leaves its compiled functions cold, whatever the cache held; functions inlined into
    their callers are never cached on their own and are not named."""
    src = tmp_path / "src"
    shutil.copytree(ROOT / "src" / "rotoruq", src / "rotoruq",
                    ignore=shutil.ignore_patterns("*.pyc"))
    gp = src / "rotoruq" / "methods" / "_gp_mean.py"
    gp.write_text(gp.read_text() + "\n# changed\n")
    done = subprocess.run([sys.executable, "-c", test_lanes.COLD_CHECK, str(src / "rotoruq")],
                          capture_output=True, text=True, timeout=300,
                          env={**os.environ, "PYTHONPATH": str(src)})
    assert done.returncode == 0, done.stderr
    cold = json.loads(done.stdout)
    assert {"rotoruq.methods._gp_mean._mean_rows", "rotoruq.methods._gp_mean._mean_var_rows",
            "rotoruq.methods._gp_mean.gp_mean_into"} <= set(cold)
    assert "rotoruq.methods._gp_mean._sq_distances" not in cold  # inline="always"


def test_worksteal_shares_the_long_tests_that_load_leaves_on_one_worker():
    """Eight 10 s tests first, then 64 of 0.1 s: ``load``'s first chunks (9 tests each) put
    all eight long tests on the first worker, which runs them alone (80 s); with
    ``worksteal`` the second worker takes half of the first one's queue when it runs dry.
    Each scheduler runs every test once."""
    d = [10.0] * 8 + [0.1] * 64
    loaded, stolen = lane_schedule.load(d), lane_schedule.worksteal(d)
    assert sum(loaded) == pytest.approx(sum(d)) and sum(stolen) == pytest.approx(sum(d))
    assert max(loaded) >= 80.0
    assert max(stolen) <= sum(d) / 2 + 10.0
