"""The last faults of issue 36, each through ``rotoruq`` in a subprocess with real processes,
real symlinks and a real file-size limit: a driver's whole process tree (setsid'd grandchildren
included) ends with the run, paths created after the start never follow a planted symlink,
storage errors are one line naming the file, long driver arguments are a usage error."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from _inproc import rotoruq

SRC = str(Path(__file__).resolve().parents[1] / "src")
CLI = [sys.executable, "-m", "rotoruq.study.cli"]
ENV = {**os.environ, "PYTHONPATH": SRC}


def run_cli(*args, cwd=None, timeout=300, env=None, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env={**ENV, **(env or {})}, cwd=cwd, **kw)


PARAMS = "1 variables\n5.0 collective_deg\n1 functions\n1 ASV_1:thrust\n" \
         "1 derivative_variables\n1 DVV_1:collective_deg\n0 analysis_components\n"


@pytest.mark.parametrize("where", ["params", "results", "results-deep", "path"])
def test_driver_with_an_overlong_argument_is_a_usage_error(tmp_path, where):
    """A parameters or results name over NAME_MAX (255 bytes) or a path over PATH_MAX:
    exit 2, the usage line, no traceback; a results file that can be named says FAIL (for
    Dakota's failure capture)."""
    (tmp_path / "p.in").write_text(PARAMS)
    long = "a" * 300
    args = {"params": [long, "r.out"], "results": ["p.in", long],
            "results-deep": ["p.in", f"d/{long}/r.out"],
            "path": ["p.in", "a/" * 3000 + "r.out"]}[where]
    proc = run_cli("driver", *args, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and "usage: rotoruq driver" in proc.stderr
    expected = "a path of 6005 bytes" if where == "path" else "a file name of 300 bytes"
    what = "params" if where == "params" else "results"
    assert f"argument {what}: {expected}" in proc.stderr
    written = sorted(p.name for p in tmp_path.iterdir())
    if where == "params":
        assert written == ["p.in", "r.out"] and (tmp_path / "r.out").read_text() == "FAIL\n"
    else:
        assert written == ["p.in"]


def test_driver_whose_results_folder_is_missing_says_so_in_one_line(tmp_path):
    (tmp_path / "p.in").write_text(PARAMS)
    proc = run_cli("driver", "p.in", "no/r.out", cwd=tmp_path)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert proc.stderr.splitlines()[-1] == ("rotoruq driver: cannot write the results file "
                                            "no/r.out: No such file or directory")


# A driver that leaves a tree behind: two children, and a grandchild that calls setsid(),
# execs a program with an empty environment (no token, no session or group of the run's)
# that ignores SIGTERM and starts a child of its own, while its parent exits at once.
TREE_DRIVER = r'''
import os, sys, time
marks = os.environ["MARKS"]
def mark(role):
    open(os.path.join(marks, f"{role}-{os.getpid()}"), "w").close()
GRAND = """
import os, signal, sys, time
signal.signal(signal.SIGTERM, signal.SIG_IGN)
role = "great" if os.fork() == 0 else "grandchild"
open(os.path.join(sys.argv[1], f"{role}-{os.getpid()}"), "w").close()
time.sleep(120)
"""
mark("driver")
for i in range(2):
    if os.fork() == 0:
        mark("child")
        if i == 0:
            if os.fork() == 0:
                os.setsid()
                os.execve(sys.executable, [sys.executable, "-S", "-c", GRAND, marks], {})
            os._exit(0)
        time.sleep(120)
        os._exit(0)
def complete():  # every driver started so far has its five processes marked
    names = os.listdir(marks)
    return len(names) >= 5 * sum(n.startswith("driver-") for n in names)
while not complete():
    time.sleep(0.01)
time.sleep(float(os.environ.get("DRIVER_SLEEP", "0")))
open(sys.argv[2], "w").write("1.0 y1\n2.0 y2\n")
'''

def _tree_study(tmp_path: Path, executor: str, n: int) -> tuple[Path, Path]:
    """test_trust's external study (``n`` points on ``executor``) with the tree driver."""
    from test_trust import external_study

    marks = tmp_path / "marks"
    marks.mkdir()
    study = external_study(tmp_path, n=n, executor=executor)
    (tmp_path / "driver.py").write_text(TREE_DRIVER)
    return study, marks


def _marked(marks: Path) -> dict[str, int]:
    return {f.name: int(f.name.split("-")[1]) for f in marks.iterdir()}


def _alive_after(marks: Path, seconds: float) -> list[str]:
    from rotoruq.evaluation.process_tree import is_running

    time.sleep(seconds)
    return sorted(name for name, pid in _marked(marks).items() if is_running(pid))


def test_a_drivers_whole_tree_ends_with_each_evaluation(tmp_path):
    """After a normal run no process of any driver's tree is alive (2 s later), the setsid'd
    grandchild that ignores SIGTERM and its orphaned child included."""
    study, marks = _tree_study(tmp_path, "serial", 3)
    proc = run_cli("run", study, "--out", tmp_path / "out", "--no-report", cwd=tmp_path,
                   env={"MARKS": str(marks)})
    assert proc.returncode == 0, proc.stderr
    assert len(_marked(marks)) == 15  # 3 evaluations x (driver, 2 children, 2 setsid'd)
    assert _alive_after(marks, 2.0) == []


@pytest.mark.parametrize("executor,whole_group", [("serial", False), ("processes", True)],
                         ids=["serial-kill-cli", "processes-kill-group"])
def test_sigkill_of_the_run_ends_every_drivers_tree(tmp_path, executor, whole_group):
    """kill -9 of `rotoruq run` (or of its process group, pool workers included) while its
    drivers and their trees run: 2 s later none of their processes is alive."""
    n_trees = 2 if executor == "processes" else 1
    study, marks = _tree_study(tmp_path, executor, 4)
    proc = subprocess.Popen([*CLI, "run", str(study), "--out", str(tmp_path / "out"),
                             "--no-report"], cwd=tmp_path, start_new_session=True,
                            env={**ENV, "DRIVER_SLEEP": "120", "MARKS": str(marks)},
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        end = time.monotonic() + 120
        while len(_marked(marks)) < 5 * n_trees:
            assert time.monotonic() < end and proc.poll() is None, "the drivers' trees"
            time.sleep(0.05)
        if whole_group:
            os.killpg(proc.pid, signal.SIGKILL)
        else:
            proc.kill()
        proc.wait(10)
        assert _alive_after(marks, 2.0) == []
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


# A driver that, in its first evaluation, plants a symlink in the results folder ($OUT) the
# run is writing: at `report` (to a folder outside), or at `work` (the real one moved aside
# and linked to, so that this evaluation's own files still read back).
PLANTER = r'''
import os, sys
out, where = os.environ["OUT"], os.environ["PLANT"]
link = os.path.join(out, where)
if not os.path.islink(link):
    if where == "work":
        os.rename(link, link + "-moved")
        os.symlink(link + "-moved", link)
    else:
        os.symlink(os.environ["TARGET"], link)
open(sys.argv[2], "w").write("1.0 y1\n2.0 y2\n")
'''


@pytest.mark.parametrize("where", ["report", "work"])
def test_a_symlink_planted_during_the_steps_is_refused_naming_it(tmp_path, where):
    """A link planted at out/report or out/work while the run is in its steps (after the
    start's checks): the run stops with one line naming the link, writes nothing through it,
    and shows no traceback (before: the report was written into the link's target; a
    swapped work folder failed blaming the driver's interpreter)."""
    study, _ = _tree_study(tmp_path, "serial", 3)
    (tmp_path / "driver.py").write_text(PLANTER)
    out, target = tmp_path / "out", tmp_path / "elsewhere"
    target.mkdir()
    proc = run_cli("run", study, "--out", out, cwd=tmp_path,
                   env={"OUT": str(out), "PLANT": where, "TARGET": str(target)})
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr
    (line,) = [ln for ln in proc.stderr.splitlines() if "error" in ln]
    assert f"symlink planted at {out / where}" in line or f"symlink in a results folder: " \
        f"{out / where} ->" in line, line
    assert (out / where).is_symlink()
    if where == "report":
        assert list(target.iterdir()) == []
        assert (out / "steps" / "lhs" / "result.json").is_file()  # the steps were saved
    else:  # the first evaluation's folder is gone; no other was made through the link
        assert list((out / "work-moved").iterdir()) == []


def _file_size_limit(limit: int):
    """A preexec for a subprocess: files cannot grow past ``limit`` bytes (EFBIG, as on a
    full disk; SIGXFSZ ignored so the write fails instead of killing the process)."""
    import resource

    def pre() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return pre


def _tiny(executor: str, n: int) -> str:
    """test_cli's one-step rotor study, ``n`` points on ``executor``."""
    from test_cli import TINY

    assert "n_samples = 40\n" in TINY
    return (TINY.replace("n_samples = 40\n", f"n_samples = {n}\n")
            + f'\n[executor]\nkind = "{executor}"\n')


def test_a_report_that_cannot_be_written_keeps_the_previous_one_whole(tmp_path):
    """`rotoruq report` under a file-size limit below the size of index.html: one line
    naming the file, no traceback, the previous index.html byte for byte, no temporary
    file left (before: a truncated index.html)."""
    study = tmp_path / "s.toml"
    study.write_text(_tiny("serial", 60))
    out = tmp_path / "out"
    # the run that writes the first report in this process (tests/_inproc.py): the report
    # under the limit below is the fresh process
    first = rotoruq("run", study, "--out", out, cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    index = out / "report" / "index.html"
    before = index.read_bytes()
    assert len(before) > 60_000
    proc = run_cli("report", out, cwd=tmp_path, preexec_fn=_file_size_limit(60_000))
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    (line,) = [ln for ln in proc.stderr.splitlines() if "error" in ln]
    assert line.startswith("rotoruq report: error: ") and "File too large" in line
    assert str(out / "report") in line  # the file that could not be written
    assert index.read_bytes() == before
    left = [p.name for p in (out / "report").rglob("*.tmp")]
    assert left == []


def test_a_full_store_in_a_pool_run_is_one_line_naming_the_file(tmp_path):
    """`rotoruq run` on process workers whose store cannot grow past a file-size limit:
    exit 1, one line naming evaluations.sqlite and what to do, nothing else on stderr."""
    study = tmp_path / "s.toml"
    study.write_text(_tiny("processes", 3000))
    out = tmp_path / "out"
    proc = run_cli("run", study, "--out", out, "--no-report", cwd=tmp_path,
                   preexec_fn=_file_size_limit(100_000))
    assert proc.returncode == 1
    lines = [ln for ln in proc.stderr.splitlines() if not ln.startswith("[tiny]")]
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"rotoruq run: error: {out / 'evaluations.sqlite'}: ")
    assert "free disk space" in lines[0]
