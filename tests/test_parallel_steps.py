"""Independent steps of one study run at once in worker processes (``rotoruq run --jobs N``,
issue 34): the same bits as one after the other, the workers forked by a fork server that
imported their modules once (rotoruq.study.workers), and the studies whose steps cannot leave
the run's process say why."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from _inproc import rotoruq
from rotoruq.study import workers
from rotoruq.study.runner import _why_serial
from rotoruq.study.schema import load_study

CLI = [sys.executable, "-m", "rotoruq.study.cli"]

STUDY = """\
[study]
name = "parallel"
seed = 8

[model]
function = "text_book"
responses = ["f", "c1", "c2"]

[parameters.a]
distribution = "uniform"
lower = 0.0
upper = 1.0

[parameters.b]
distribution = "normal"
mean = 0.5
std = 0.1

[[steps]]
name = "lhs"
type = "sampling"
n_samples = 64

[[steps]]
name = "mv"
type = "mean_value"

[[steps]]
name = "random"
type = "sampling"
design = "random"
n_samples = 64
"""


def _run(folder, *extra, fresh=True):
    """``rotoruq run`` of the study in ``folder``: a fresh process, or this one
    (tests/_inproc.py) for a serial run, whose process is not what is checked."""
    args = ["run", str(folder / "parallel.toml"), "--no-report",
            "--out", str(folder / f"out{''.join(extra)}"), *extra]
    if not fresh:
        return rotoruq(*args)
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=600)


def test_independent_steps_in_two_processes_give_the_bits_of_one(tmp_path):
    (tmp_path / "parallel.toml").write_text(STUDY)
    one, two = _run(tmp_path, fresh=False), _run(tmp_path, "--jobs", "2")
    assert one.returncode == 0 and two.returncode == 0, two.stderr[-3000:]
    for step in ("lhs", "mv", "random"):
        assert f"{step}: done" in two.stderr  # each step's lines, from its worker
        a, b = tmp_path / "out" / "steps" / step, tmp_path / "out--jobs2" / "steps" / step
        arrays = sorted(p.name for p in a.glob("*.npy"))
        assert arrays == sorted(p.name for p in b.glob("*.npy")) and arrays
        for name in arrays:
            assert np.load(a / name).tobytes() == np.load(b / name).tobytes(), (step, name)
    # the summary lists the steps in the study's order, whatever order they ended in
    assert one.stdout.index("lhs") < one.stdout.index("random")
    assert two.stdout.index("lhs") < two.stdout.index("random")


#: What a worker reports: its parent and whether it holds the module the fork server preloaded.
PROBE = "__import__('os').getppid(), 'rotoruq.study.spec' in __import__('sys').modules"


@pytest.mark.skipif(workers.start_method() != "forkserver",
                    reason="no fork server here: the workers are spawned")
def test_workers_come_from_a_fork_server_that_imported_their_modules_and_stops():
    with workers.worker_context(["rotoruq.study.spec"]) as ctx, ProcessPoolExecutor(
            2, mp_context=ctx) as pool:
        got = [pool.submit(eval, PROBE).result() for _ in range(2)]
    assert ctx.get_start_method() == "forkserver"
    (server, preloaded), *_ = got
    assert preloaded and server != os.getpid()  # forked by the server, which imported it
    with pytest.raises(ProcessLookupError):  # the block stopped the server it started
        os.kill(server, 0)


def test_the_steps_workers_come_from_a_server_that_imported_the_runner(tmp_path, monkeypatch):
    started = []
    real = workers.worker_context

    @contextlib.contextmanager
    def recorded(preload):
        with real(preload) as ctx:
            started.append((ctx.get_start_method(), tuple(preload)))
            yield ctx

    monkeypatch.setattr(workers, "worker_context", recorded)
    (tmp_path / "parallel.toml").write_text(STUDY)
    assert _run(tmp_path, "--jobs", "2", fresh=False).returncode == 0
    assert started == [(workers.start_method(), ("rotoruq.study.runner",))]


def test_a_bad_job_count_is_a_usage_error(tmp_path):
    (tmp_path / "parallel.toml").write_text(STUDY)
    bad = _run(tmp_path, "--jobs", "0", fresh=False)
    assert bad.returncode == 2 and "--jobs: an integer >= 1, got '0'" in bad.stderr


def test_steps_that_cannot_leave_the_process_say_why(tmp_path):
    (tmp_path / "parallel.toml").write_text(STUDY)
    study = load_study(tmp_path / "parallel.toml")
    assert _why_serial(study, None) is None
    assert "model_factory" in _why_serial(study, lambda *a, **k: None)
    ext = STUDY.replace('function = "text_book"', 'command = ["python", "driver.py"]')
    (tmp_path / "ext.toml").write_text(ext)
    assert "external model" in _why_serial(load_study(tmp_path / "ext.toml"), None)
    pooled = STUDY + '\n[executor]\nkind = "processes"\n'
    (tmp_path / "pool.toml").write_text(pooled)
    assert "[executor]" in _why_serial(load_study(tmp_path / "pool.toml"), None)


@pytest.mark.parametrize("jobs", [0, 1.5, True])
def test_run_study_refuses_a_bad_job_count(tmp_path, jobs):
    from rotoruq.study.runner import run_study

    (tmp_path / "parallel.toml").write_text(STUDY)
    with pytest.raises(ValueError, match="jobs must be an integer >= 1"):
        run_study(tmp_path / "parallel.toml", out=tmp_path / "o", jobs=jobs)
