"""A first run on a cold numba cache says what it compiles before it compiles (issue 34): the
chain and emulator kernels, as the rotor's (tests/test_cli.py)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import logging, numpy as np
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    import rotoruq as rq
    f = rq.FunctionModel(lambda x: x[:, :1] * 2.0, ["a"], ["y"])
    prior = rq.ParameterSpace({"a": rq.Uniform(0.0, 1.0)})
    rq.calibrate_bayes(f, np.array([[1.0]]), prior, noise=rq.NoiseModel(noise_std=0.1),
                       chains=rq.ChainOptions(n_samples=50, burn_in=0),
                       emulator=rq.EmulatorOptions(rq.GaussianProcess(),
                                                   n_emulator_samples=8))
""")


@pytest.mark.slow  # ~12 CPU-s, a cold compile; the next test and test_cli's stay fast
def test_a_cold_cache_names_the_kernels_before_compiling_them(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT], env=env, cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        said = []
        for line in proc.stderr:  # ended once it has named one family, not left to compile
            if line.startswith("compiling "):
                said.append(line.strip())
                break
        assert said, "no notice before compiling"
        assert said[0] in ("compiling emulator kernels (once per install, ~10-60 s) ...",
                           "compiling chain kernels (once per install, ~10-60 s) ..."), said
    finally:
        proc.kill()
        proc.wait()


ONCE = textwrap.dedent("""
    import numpy as np
    import rotoruq as rq
    from rotoruq.methods.mcmc import _kernels as kn
    f = rq.FunctionModel(lambda x: x[:, :1] * 2.0, ["a"], ["y"])
    prior = rq.ParameterSpace({"a": rq.Uniform(0.0, 1.0)})
    for emulator in (rq.EmulatorOptions(rq.GaussianProcess(), n_emulator_samples=8), None):
        rq.calibrate_bayes(f, np.array([[1.0]]), prior, noise=rq.NoiseModel(noise_std=0.1),
                           chains=rq.ChainOptions(n_samples=50, burn_in=0),
                           emulator=emulator, seed=0)
    print([len(k.signatures) for k in (kn.advance, kn.propose, kn._step, kn._after_step)])
""")


@pytest.mark.slow
@pytest.mark.extended  # a cold numba compile of the chain kernels: minutes on 2 cores
def test_each_step_kernel_is_compiled_once_on_a_cold_cache(tmp_path):
    """Chains on an emulator (the compiled driver) and on a Python model (the Python driver)
    in one process with an empty numba cache compile each step kernel once: the compiled
    driver passes typed constants, not literals that numba would specialise on."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    done = subprocess.run([sys.executable, "-c", ONCE], env=env, cwd=tmp_path,
                          capture_output=True, text=True, timeout=1200)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "[1, 1, 1, 1]", done.stdout


# Two kernels in a module of their own: the process calls `used` only, as a chain on an
# emulator calls one of the emulator's kernels and never the other (issue 36).
KERNELS = textwrap.dedent("""
    import logging, sys
    import numba as nb
    from rotoruq._compile import compiling

    @nb.njit(cache=True)
    def used(x):
        return x + 1.0

    @nb.njit(cache=True)
    def never(x):
        return x - 1.0

    class Phases(logging.Handler):
        def emit(self, record):
            p = record.progress
            print(f"phase {p.name!r} total={p.total} closed={p.closed}")

    logging.basicConfig(level=logging.INFO, format="%(message)s", stream=sys.stdout)
    progress = logging.getLogger("rotoruq.progress")
    progress.addHandler(Phases())
    progress.propagate = False
    with compiling("demo kernels", [used], logging.getLogger("demo")):
        used(1.0)
""")


def test_the_notice_names_only_kernels_about_to_be_called(tmp_path):
    """The notice is given where a kernel is called, for that kernel: a second run on the same
    numba cache says nothing although the module's other kernel was never compiled (before,
    a family was checked as a whole, and a kernel no run calls was 'compiled' every run).
    While the compile runs, a progress phase names it."""
    (tmp_path / "kernels.py").write_text(KERNELS)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
           "PYTHONPATH": os.pathsep.join([str(tmp_path), *sys.path])}
    said = [subprocess.run([sys.executable, "-c", "import kernels"], capture_output=True,
                           text=True, env=env, cwd=tmp_path, timeout=300).stdout
            for _ in range(2)]
    assert said[0].startswith("compiling demo kernels"), said
    # while it compiles, an uncounted phase is open (the status line names it; a record
    # every few seconds on a slow machine), then closed
    lines = said[0].splitlines()[1:]
    assert lines[0] == "phase 'compiling demo kernels' total=None closed=False"
    assert set(lines[1:-1]) <= {lines[0]}
    assert lines[-1] == "phase 'compiling demo kernels' total=None closed=True"
    assert said[1] == "", said


STUDY = textwrap.dedent("""
    [study]
    name = "warm"
    seed = 1

    [model]
    function = "text_book"
    responses = ["y1", "y2"]

    [parameters.a]
    distribution = "uniform"
    lower = -1.0
    upper = 1.0

    [parameters.b]
    distribution = "uniform"
    lower = -1.0
    upper = 1.0

    [data.obs]
    file = "obs.csv"

    [[steps]]
    name = "bayes"
    type = "bayes_calibration"
    data = "obs"
    noise_std = { y1 = 0.2, y2 = 0.2 }
    n_emulator_samples = 12
    n_samples = 200
    """)


@pytest.mark.slow
@pytest.mark.extended  # the first run compiles the emulator and chain kernels: minutes
def test_a_second_run_on_a_warm_cache_prints_no_compile_notice(tmp_path):
    """`rotoruq run` twice with one NUMBA_CACHE_DIR: the first (cold) names what it
    compiles, the second compiles nothing and says nothing of compiling."""
    (tmp_path / "obs.csv").write_text("y1,y2\n0.9,0.1\n1.1,-0.1\n")
    (tmp_path / "study.toml").write_text(STUDY)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
           "PYTHONPATH": os.pathsep.join(sys.path)}
    runs = [subprocess.run([sys.executable, "-m", "rotoruq.study.cli", "run", "study.toml",
                            "--out", f"out{k}", "--no-report"], capture_output=True,
                           text=True, env=env, cwd=tmp_path, timeout=1800) for k in range(2)]
    for r in runs:
        assert r.returncode == 0, r.stderr
    assert "compiling " in runs[0].stderr, runs[0].stderr
    assert "compiling " not in runs[1].stderr, runs[1].stderr


LOCKED = textwrap.dedent("""
    import json, logging, sys
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    from numba.core import event
    sys.path.insert(0, sys.argv[1])
    import demo_kernel
    from rotoruq._compile import compiling
    compiled = []

    class Count(event.Listener):
        def on_start(self, ev):
            compiled.append(ev.data["dispatcher"].py_func.__name__)

        def on_end(self, ev):
            pass

    with event.install_listener("numba:compile", Count()):
        with compiling("demo kernels", [demo_kernel.twice], logging.getLogger("demo")):
            value = demo_kernel.twice(2.0)
    print(json.dumps({"value": value, "compiled": compiled}))
""")


HOLD = textwrap.dedent("""
    import logging, sys
    sys.path.insert(0, sys.argv[1])
    import demo_kernel
    from rotoruq._compile import compile_lock
    with compile_lock("demo kernels", [demo_kernel.twice], logging.getLogger("demo")) as held:
        print(held, flush=True)
        sys.stdin.readline()  # until the test says
""")


def test_processes_on_a_cold_cache_compile_a_family_once(tmp_path):
    """Two processes that reach the same cold kernels at once: one compiles them (holding the
    family's lock in numba's cache folder), the other waits, then loads them from the cache
    (issue 34: `rotoruq reproduce`'s chapters each compiled the rotor kernels)."""
    import json
    import time

    (tmp_path / "demo_kernel.py").write_text(textwrap.dedent("""
        import numba

        @numba.njit(cache=True)
        def twice(x):
            return 2.0 * x
    """))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    # a third process holds the lock while both start: each must find it taken and wait
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(tmp_path)], env=env,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    procs: list[subprocess.Popen] = []
    try:
        assert holder.stdout is not None and holder.stdin is not None
        assert holder.stdout.readline().strip() == "True"
        errs = [tmp_path / f"err{k}" for k in range(2)]
        procs = [subprocess.Popen([sys.executable, "-c", LOCKED, str(tmp_path)], env=env,
                                  stdout=subprocess.PIPE, stderr=e.open("w"), text=True)
                 for e in errs]
        t0 = time.monotonic()
        while not all("another process is compiling the demo kernels" in e.read_text()
                      for e in errs):
            assert time.monotonic() - t0 < 120 and all(p.poll() is None for p in procs), \
                [e.read_text() for e in errs]
            time.sleep(0.1)
        holder.stdin.write("go\n")
        holder.stdin.close()
        assert holder.wait(timeout=60) == 0
        outs = []
        for p, e in zip(procs, errs, strict=True):
            out, _ = p.communicate(timeout=120)
            assert p.returncode == 0, e.read_text()
            outs.append(json.loads(out.strip().splitlines()[-1]))
    finally:
        for p in [holder, *procs]:
            if p.poll() is None:
                p.kill()
                p.wait()
    assert [o["value"] for o in outs] == [4.0, 4.0]
    # one process compiled `twice`; the other loaded the first one's code from the cache
    assert sorted(len(o["compiled"]) for o in outs) == [0, 1], outs


def test_an_open_compile_phase_reports_its_elapsed_time(monkeypatch):
    """Nothing advances an uncounted phase: while a compile runs, its phase gets a record
    every ``tick`` seconds, each with a later elapsed time (the status line showed
    'compiling rotor kernels, 0:00' for the whole compile)."""
    import logging
    import time

    from rotoruq._progress import Phase

    states = []

    class Keep(logging.Handler):
        def emit(self, record):
            states.append(record.progress)

    log = logging.getLogger("rotoruq.progress")
    keep = Keep()
    log.addHandler(keep)
    level = log.level
    log.setLevel(logging.INFO)  # (setLevel: a level set as an attribute keeps a stale cache)
    try:
        with Phase("compiling demo kernels", None, tick=0.05):
            time.sleep(1.0)
    finally:
        log.removeHandler(keep)
        log.setLevel(level)
    assert len(states) >= 3, states
    elapsed = [s.elapsed for s in states]
    assert elapsed == sorted(elapsed) and elapsed[-2] > 0.2, elapsed
    assert [s.closed for s in states] == [False] * (len(states) - 1) + [True]


VARIANT_SCRIPT = textwrap.dedent("""
    import logging, sys
    sys.path.insert(0, sys.argv[1])
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    from rotoruq._compile import compiling, is_cached
    import tiny_kernel as tk
    log = logging.getLogger("t")
    floats = lambda types: types[-1] == "float64"
    ints = lambda types: types[-1] == "int64"
    print("before", is_cached(tk.twice), is_cached(tk.twice, floats), is_cached(tk.twice, ints))
    with compiling("float kernels", [tk.twice], log, variant=floats, lock="tiny") as cold:
        tk.twice(1.5)
    print("float announced", cold)
    print("after", is_cached(tk.twice), is_cached(tk.twice, floats), is_cached(tk.twice, ints))
    with compiling("int kernels", [tk.twice], log, variant=ints, lock="tiny") as cold:
        tk.twice(3)
    print("int announced", cold)
""")


def test_a_specialisation_not_cached_is_announced_although_another_is(tmp_path):
    """The rotor kernel has a hover and a forward-flight build (one dispatcher, two
    signatures); with only the first cached the second compiles for tens of seconds, so it
    is announced and locked on its own (found in CI: it compiled unannounced, twice)."""
    (tmp_path / "tiny_kernel.py").write_text(
        "import numba\n\n@numba.njit(cache=True)\ndef twice(x):\n    return 2 * x\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    run = subprocess.run([sys.executable, "-c", VARIANT_SCRIPT, str(tmp_path)], env=env,
                         cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert run.stdout.splitlines() == [
        "before False False False", "float announced True", "after True True False",
        "int announced True"]
    assert "compiling float kernels" in run.stderr and "compiling int kernels" in run.stderr
    again = subprocess.run([sys.executable, "-c", VARIANT_SCRIPT, str(tmp_path)], env=env,
                           cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert again.stdout.splitlines() == [
        "before True True True", "float announced False", "after True True True",
        "int announced False"]
    assert "compiling" not in again.stderr


def test_the_rotors_hover_and_forward_flight_builds_are_told_apart():
    from rotoruq.rotor.hover import _is_build

    hover = ("array(float64, 2d, C)", "none")
    flight = ("array(float64, 2d, C)", "bool")
    assert _is_build(False)(hover) and not _is_build(False)(flight)
    assert _is_build(True)(flight) and not _is_build(True)(hover)
