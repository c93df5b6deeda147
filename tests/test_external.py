"""External drivers through the full path: work directories, files, templates, failures."""

from __future__ import annotations

import hashlib
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rotoruq._options import fields_of
from rotoruq.errors import EvaluationError, InputFileError, ParameterError
from rotoruq.evaluation.evaluator import Evaluator
from rotoruq.evaluation.external import ExternalModel, FileContract, WorkDirectory
from rotoruq.evaluation.process_tree import is_running as alive
from rotoruq.evaluation.store import Store
from rotoruq.model import evaluate

# A driver using only the standard library (fast start-up). It reads either parameters
# format, misbehaves on demand through the variable "kind", and writes f = 2 a + kind + c,
# where c comes from the filled template "solver.inp" (if present).
DRIVER = r'''
import os, random, re, sys, time
params, results = sys.argv[1], sys.argv[2]
x = {}
text = open(params).read()
if text.lstrip().startswith("{"):
    for tag, val in re.findall(r"\{\s*(\S+)\s*=\s*(\S+)\s*\}", text):
        x[tag] = val
else:
    lines = text.splitlines()
    n = int(lines[0].split()[0])
    for line in lines[1 : 1 + n]:
        val, tag = line.split()
        x[tag] = val
kind, a = int(float(x["kind"])), float(x["a"])
GRANDCHILD = ("import os, sys, time; os.setsid(); t = sys.argv[1]; "
              "open(t + '.tmp', 'w').write(str(os.getpid())); os.rename(t + '.tmp', t + '.gc'); "
              "time.sleep(60)")
side = os.environ.get("SIDE_FILE")
attempt = 0
if side:
    with open(side, "a") as f:
        f.write(f"{x['a']}\n")
    attempt = sum(1 for s in open(side).read().split() if s == x["a"])
c = 0.0
if os.path.exists("solver.inp"):
    c = float(open("solver.inp").read().split("=")[1])
for name in os.environ.get("NEED_FILES", "").split():
    if not os.path.exists(name):
        sys.exit(f"missing {name}")
if kind == 1:
    sys.stderr.write("segmentation fault (simulated)\n")
    sys.exit(3)
if kind == 2:
    sys.stderr.write("hanging...\n"); sys.stderr.flush()
    time.sleep(60)
if kind == 3:
    open(results, "w").write("FAIL\n")
    sys.exit(0)
if kind == 4:
    open(results, "w").write("thrust = lots\n")
    sys.exit(0)
if kind == 6:
    open(results, "w").write("nan f\n")
    sys.exit(0)
if kind == 7:
    open(results, "w").write("1e999 f\n")  # overflows to inf
    sys.exit(0)
if kind == 8:
    open(results, "wb").write(b"1.0 f\xff\xfe\n")  # not UTF-8
    sys.exit(0)
if kind in (9, 10):  # a grandchild that leaves the process group (setsid) and hangs
    import subprocess
    tag = os.path.join(os.environ["PID_DIR"], f"{x['a']}-{attempt}-{os.getpid()}")
    subprocess.Popen([sys.executable, "-S", "-c", GRANDCHILD, tag])
    while not os.path.exists(tag + ".gc"):
        time.sleep(0.005)
    if kind == 9:
        time.sleep(60)  # and the driver hangs too
if kind == 11:  # a daemon: double fork, the middle process exits at once, setsid
    tag = os.path.join(os.environ["PID_DIR"], f"{x['a']}-{attempt}-{os.getpid()}")
    if os.fork() == 0:
        if os.fork() != 0:
            os._exit(0)
        os.setsid()
        open(tag + ".tmp", "w").write(str(os.getpid()))
        os.rename(tag + ".tmp", tag + ".gc")
        time.sleep(60)
        os._exit(0)
    while not os.path.exists(tag + ".gc"):
        time.sleep(0.005)
    time.sleep(60)
if kind == 5 and random.Random(f"{x['a']}-{attempt}").random() < 0.1:
    sys.stderr.write(f"random failure at attempt {attempt}\n")
    sys.exit(1)
open(results, "w").write(f"{2 * a + kind + c!r} f\n")
'''


def random_fails(a_text: str, attempt: int) -> bool:
    return random.Random(f"{a_text}-{attempt}").random() < 0.1


@pytest.fixture
def driver(tmp_path):
    p = tmp_path / "driver.py"
    p.write_text(DRIVER)
    return p


def model(driver, tmp_path, **kw):
    """The test driver as an ExternalModel working in ``tmp_path/work``; the fields of its
    WorkDirectory and FileContract records may be given flat here (``tag=False``)."""
    work = {k: kw.pop(k) for k in fields_of(WorkDirectory)[1:] if k in kw}
    contract = {k: kw.pop(k) for k in fields_of(FileContract) if k in kw}
    return ExternalModel([sys.executable, "-S", str(driver)], ["kind", "a"], ["f"],
                         workdir=WorkDirectory(kw.pop("workdir", tmp_path / "work"), **work),
                         contract=FileContract(**contract), **kw)


@pytest.mark.parametrize("fmt", ["standard", "aprepro"])
def test_full_path_with_templates_copies_links_and_store(driver, tmp_path, monkeypatch, fmt):
    tpl = tmp_path / "solver.inp"
    tpl.write_text("c = {a:.17g}\n")
    cp = tmp_path / "table.c81"
    cp.write_text("table\n")
    ln = tmp_path / "mesh"
    ln.mkdir()
    monkeypatch.setenv("NEED_FILES", "table.c81 mesh solver.inp")
    m = model(driver, tmp_path, template_files=[tpl], copy_files=[cp], link_files=[ln],
              parameters_format=fmt)
    x = np.c_[np.zeros(4), [0.1, -2.5, 1e-7, 3.0]]
    with Evaluator(m, store=tmp_path / "s.db", study="ext") as ev:
        out = ev.evaluate(x)
    assert out.failures == {}
    np.testing.assert_array_equal(out.values[:, 0], 3 * x[:, 1])  # 2a + c with c = a
    recs = Store(tmp_path / "s.db").records(study="ext")
    assert [r.status for r in recs] == ["ok"] * 4
    assert all(r.stderr is None for r in recs)
    assert sorted(float(r.inputs[1]) for r in recs) == sorted(x[:, 1])
    assert list((tmp_path / "work").iterdir()) == []  # successful work dirs removed


def test_model_protocol_direct_call(driver, tmp_path):
    m = model(driver, tmp_path, keep_workdirs=True, name="run")
    b = evaluate(m, np.array([[0.0, 1.0], [0.0, 2.0]]))
    np.testing.assert_array_equal(b.values[:, 0], [2.0, 4.0])
    names = sorted(p.name for p in (tmp_path / "work").iterdir())
    prefix = f"run.{os.getpid()}.{m._token}"  # <name>.<pid>.<run token>.<eval_id>
    assert names == [f"{prefix}.1", f"{prefix}.2"]
    assert (tmp_path / "work" / f"{prefix}.1" / "params.in").read_text().split()[:2] == [
        "2", "variables"]


def test_every_failure_kind_is_recorded_and_good_ones_kept(driver, tmp_path):
    m = model(driver, tmp_path, timeout=1.0)
    x = np.array([[0, 1.0], [1, 2.0], [2, 3.0], [3, 4.0], [4, 5.0], [0, 6.0]])
    t0 = time.perf_counter()
    with Evaluator(m, store=tmp_path / "s.db", executor="processes:2") as ev:
        out = ev.evaluate(x)
    assert time.perf_counter() - t0 < 20  # the hanging driver was killed after 1 s
    np.testing.assert_array_equal(out.values[[0, 5], 0], [2.0, 12.0])
    assert set(out.failures) == {1, 2, 3, 4}
    assert np.isnan(out.values[1:5]).all()
    assert "status 3" in out.failures[1] and "segmentation fault" in out.failures[1]
    assert "timed out after 1 s" in out.failures[2]
    assert "fail marker" in out.failures[3]
    assert "bad results file" in out.failures[4] and "numeric response value" in out.failures[4]
    recs = {float(r.inputs[1]): r for r in Store(tmp_path / "s.db").records()}
    assert recs[2.0].status == "failed" and "segmentation fault" in recs[2.0].stderr
    assert "hanging" in recs[3.0].stderr
    assert recs[1.0].status == recs[6.0].status == "ok"
    # failed work directories are kept for inspection, with their files
    kept = [p for p in (tmp_path / "work").iterdir()]
    assert len(kept) == 4 and all((p / "params.in").exists() for p in kept)


def test_abort_policy_stops_and_keeps_finished(driver, tmp_path):
    m = model(driver, tmp_path, failure_policy="abort")
    x = np.array([[0, 1.0], [0, 2.0], [1, 3.0], [0, 4.0], [0, 5.0]])
    ev = Evaluator(m, store=tmp_path / "s.db")
    with pytest.raises(EvaluationError) as err:
        ev.evaluate(x)
    assert "a=3.0" in str(err.value) and "segmentation fault" in str(err.value)
    recs = Store(tmp_path / "s.db").records()
    assert [(float(r.inputs[1]), r.status) for r in recs] == [(1.0, "ok"), (2.0, "ok"),
                                                              (3.0, "failed")]
    with pytest.raises(EvaluationError):
        m(x[2:3])  # direct call aborts too


def test_recover_policy(driver, tmp_path):
    m = model(driver, tmp_path, failure_policy={"recover": [-1.0]}, keep_workdirs=False)
    ev = Evaluator(m, store=tmp_path / "s.db")
    out = ev.evaluate(np.array([[0, 1.0], [3, 2.0]]))
    np.testing.assert_array_equal(out.values[:, 0], [2.0, -1.0])
    assert out.failures == {}
    rec = Store(tmp_path / "s.db").records()[1]
    assert rec.status == "recovered" and "fail marker" in rec.error
    assert not (tmp_path / "work").exists() or not list((tmp_path / "work").iterdir())


def test_random_ten_percent_failures_with_retry_and_continue(driver, tmp_path, monkeypatch):
    a = [f"{v:.16e}" for v in np.linspace(0.5, 30.5, 30)]
    x = np.c_[np.full(30, 5.0), [float(s) for s in a]]
    # which evaluations fail on their first attempt (deterministic pseudo-random, ~10%)
    first = {i for i, s in enumerate(a) if random_fails(s, 1)}
    assert 0 < len(first) < 10
    # continue: exactly those fail, the others are exact
    monkeypatch.setenv("SIDE_FILE", str(tmp_path / "side1"))
    ev = Evaluator(model(driver, tmp_path), store=tmp_path / "s.db", study="cont",
                   executor="processes:2")
    out = ev.evaluate(x)
    ev.close()
    assert set(out.failures) == first
    ok = sorted(set(range(30)) - first)
    np.testing.assert_array_equal(out.values[ok, 0], 2 * x[ok, 1] + 5)
    recs = Store(tmp_path / "s.db").records(study="cont", status="failed")
    assert len(recs) == len(first)
    assert all("random failure at attempt 1" in r.stderr for r in recs)
    # retry:3: every evaluation succeeds, with the expected number of attempts
    monkeypatch.setenv("SIDE_FILE", str(tmp_path / "side2"))
    ev = Evaluator(model(driver, tmp_path, failure_policy="retry:3"), store=tmp_path / "s.db",
                   study="retry")
    out = ev.evaluate(x)
    assert out.failures == {}
    np.testing.assert_array_equal(out.values[:, 0], 2 * x[:, 1] + 5)
    attempts = {float(r.inputs[1]): r.attempts for r in Store(tmp_path / "s.db").records(
        study="retry")}
    for i, s in enumerate(a):
        k = 1
        while random_fails(s, k):
            k += 1
        assert attempts[x[i, 1]] == k


def test_values_and_arguments_never_pass_through_a_shell(driver, tmp_path):
    marker = tmp_path / "pwned"
    echo = tmp_path / "echo.py"
    echo.write_text("import sys\nopen(sys.argv[2], 'w').write(repr(len(sys.argv[3])) + '\\n')\n")
    evil = f"$(touch {marker}); touch {marker}"
    m = ExternalModel([sys.executable, "-S", str(echo), "{params}", "{results}", evil], ["a"],
                      ["n"], workdir=tmp_path / "w w")  # a space in the directory, too
    out = m(np.array([[1.0]]))
    assert out[0, 0] == len(evil)
    assert not marker.exists()


def test_string_command_and_configuration_errors(driver, tmp_path):
    m = ExternalModel(f"{sys.executable} -S {driver}", ["kind", "a"], ["f"],
                      workdir=WorkDirectory(tmp_path / "w", tag=False))
    np.testing.assert_array_equal(m(np.array([[0.0, 1.5], [0.0, 2.5]]))[:, 0], [3.0, 5.0])
    with pytest.raises(ParameterError, match="retry"):
        model(driver, tmp_path, failure_policy="retry:x")
    with pytest.raises(ParameterError, match="recover needs 1"):
        model(driver, tmp_path, failure_policy={"recover": [1, 2]})
    with pytest.raises(ParameterError, match="unknown failure policy"):
        model(driver, tmp_path, failure_policy="ignore")
    with pytest.raises(ParameterError, match="does not exist"):
        model(driver, tmp_path, copy_files=[tmp_path / "nope"])
    missing = ExternalModel(["/nonexistent/solver"], ["a"], ["f"], workdir=tmp_path / "w2")
    b = missing.evaluate(np.array([[1.0]]))
    assert "could not start" in b.failures[0]


# --- `rotoruq driver`: the rotor (or any model) behind Dakota's file contract -----------------


def _grad_model():
    from rotoruq.model import FunctionModel

    return FunctionModel(lambda x: np.c_[x[:, 0] * x[:, 1], x[:, 0] + 2 * x[:, 1]],
                         ["collective_deg", "k_pitch_link"], ["thrust", "torque"],
                         gradient=lambda x: np.stack([np.c_[x[:, 1], x[:, 0]],
                                                      np.c_[np.ones(len(x)), 2 * np.ones(
                                                          len(x))]], axis=1))


def test_run_driver_values_gradients_and_order(tmp_path):
    from rotoruq.evaluation.dakota_files import read_results, write_parameters
    from rotoruq.study.cmd_driver import run_driver

    # variables in another order than the model's inputs; gradient of torque w.r.t. one DVV
    write_parameters(tmp_path / "p.in", {"k_pitch_link": 15.0, "collective_deg": 5.4},
                     {"torque": 3, "thrust": 1}, dvv=["collective_deg"], format="aprepro")
    assert run_driver(tmp_path / "p.in", tmp_path / "r.out", _grad_model()) == 0
    r = read_results(tmp_path / "r.out", names_out=["torque", "thrust"], asv=[3, 1], n_dvv=1)
    np.testing.assert_array_equal(r.values, [5.4 + 30.0, 5.4 * 15.0])
    np.testing.assert_array_equal(r.gradients, [[1.0]])


def test_run_driver_failure_writes_fail_and_errors(tmp_path, capsys):
    from rotoruq.evaluation.dakota_files import read_results, write_parameters
    from rotoruq.model import FunctionModel
    from rotoruq.study.cmd_driver import run_driver

    nan_model = FunctionModel(lambda x: np.full(len(x), np.nan), ["a"], ["f"])
    write_parameters(tmp_path / "p.in", {"a": 1.0}, ["f"])
    assert run_driver(tmp_path / "p.in", tmp_path / "r.out", nan_model) == 1
    assert read_results(tmp_path / "r.out").failed
    for name, variables, asv, words in [("h", {"a": 1.0}, {"f": 5}, "Hessians"),
                                        ("g", {"a": 1.0}, {"f": 2}, "finite-difference stencil"),
                                        ("v", {"b": 1.0}, ["f"],
                                         "parameters and model inputs differ")]:
        write_parameters(tmp_path / f"{name}.in", variables, asv)
        assert run_driver(tmp_path / f"{name}.in", tmp_path / "r.out", nan_model) == 1
        assert read_results(tmp_path / "r.out").failed and words in capsys.readouterr().err


def test_rotoruq_driver_command_with_the_rotor_model(tmp_path):
    from rotoruq.rotor.model import RotorModel

    rotor = RotorModel("gvpm", names_in=["collective_deg"], names_out=["thrust", "torque"])
    x = np.array([[5.4], [6.0]])
    expected = evaluate(rotor, x)  # in-process answer, failures included
    m = ExternalModel([sys.executable, "-m", "rotoruq.study.cli", "driver", "--preset", "gvpm"],
                      ["collective_deg"], ["thrust", "torque"], workdir=tmp_path / "w",
                      timeout=120)
    out = m.evaluate(x)
    # the driver returns the same numbers, and FAIL (with the reason on stderr) where the
    # rotor model itself fails
    assert set(out.failures) == set(expected.failures)
    ok = [i for i in range(len(x)) if i not in expected.failures]
    np.testing.assert_allclose(out.values[ok], expected.values[ok], rtol=1e-12)
    for i in expected.failures:
        assert "fail marker" in out.failures[i]


# --- failures at the seams: non-finite and undecodable results, escaping process trees --------


def run_pids(pid_dir) -> list[int]:
    """Pids of the drivers (from the file names) and their grandchildren (from the files)."""
    out = []
    for p in pid_dir.iterdir():
        if p.suffix == ".gc":
            out += [int(p.stem.rsplit("-", 1)[1]), int(p.read_text())]
    return out


def runs_of(side, a: float) -> int:
    """How many times the driver ran at ``a`` (it logs its input to the side file)."""
    return [float(v) for v in side.read_text().split()].count(a)


BAD = {6: "non-finite response in results file: f=nan",
       7: "non-finite response in results file: f=inf",
       8: "UTF-8",
       9: "timed out after 0.5 s"}


@pytest.mark.parametrize("kind", sorted(BAD))
@pytest.mark.parametrize("policy", ["continue", "abort", "retry:2", "recover"])
def test_bad_results_and_hangs_go_through_every_policy(driver, tmp_path, monkeypatch, kind,
                                                       policy):
    side, pid_dir = tmp_path / "side", tmp_path / "pids"
    pid_dir.mkdir()
    monkeypatch.setenv("SIDE_FILE", str(side))
    monkeypatch.setenv("PID_DIR", str(pid_dir))
    fp = {"recover": [-7.0]} if policy == "recover" else policy
    m = model(driver, tmp_path, failure_policy=fp, timeout=0.5)
    x = np.array([[0, 1.0], [kind, 2.0], [0, 3.0]])
    ev = Evaluator(m, store=tmp_path / "s.db")
    t0 = time.perf_counter()
    if policy == "abort":
        with pytest.raises(EvaluationError, match=BAD[kind]):
            ev.evaluate(x)
        recs = Store(tmp_path / "s.db").records()
        assert [(float(r.inputs[1]), r.status) for r in recs] == [(1.0, "ok"), (2.0, "failed")]
    else:
        out = ev.evaluate(x)
        np.testing.assert_array_equal(out.values[[0, 2], 0], [2.0, 6.0])
        rec = {float(r.inputs[1]): r for r in Store(tmp_path / "s.db").records()}[2.0]
        assert BAD[kind] in rec.error
        if policy == "recover":
            assert out.failures == {} and out.values[1, 0] == -7.0
            assert rec.status == "recovered"
        else:
            assert BAD[kind] in out.failures[1] and np.isnan(out.values[1, 0])
            assert rec.status == "failed"
        want = 3 if policy == "retry:2" else 1
        assert rec.attempts == want
        assert runs_of(side, 2.0) == want  # the driver really ran again
        if policy == "continue":  # a failed point is run again by the next evaluation
            ev.evaluate(x)
            assert ev.last_stats.n_reused == 2 and ev.last_stats.n_evaluations == 1
    ev.close()
    if kind == 9:  # each attempt was stopped at the timeout, driver and grandchild killed
        pids = run_pids(pid_dir)
        assert len(pids) == 2 * runs_of(side, 2.0) > 0
        assert not [p for p in pids if alive(p)]
        assert time.perf_counter() - t0 < 0.5 * len(pids) + 3


def test_timeout_kills_a_grandchild_that_left_the_group(driver, tmp_path, monkeypatch):
    pid_dir = tmp_path / "pids"
    pid_dir.mkdir()
    monkeypatch.setenv("PID_DIR", str(pid_dir))
    m = model(driver, tmp_path, timeout=1)
    t0 = time.perf_counter()
    r = m.run_one(np.array([9.0, 1.0]))
    elapsed = time.perf_counter() - t0
    assert r.status == "failed" and "timed out after 1 s" in r.error
    assert "1 other processes killed" in r.error
    assert 1.0 <= elapsed < 2.5
    driver_pid, gc_pid = run_pids(pid_dir)
    assert not alive(driver_pid) and not alive(gc_pid)


def test_timeout_kills_a_daemonized_grandchild(driver, tmp_path, monkeypatch):
    """The grandchild's parent exits at once, so it is never seen as a descendant: it is found
    by the run's token in its environment."""
    pid_dir = tmp_path / "pids"
    pid_dir.mkdir()
    monkeypatch.setenv("PID_DIR", str(pid_dir))
    r = model(driver, tmp_path, timeout=0.5).run_one(np.array([11.0, 1.0]))
    assert r.status == "failed" and "timed out" in r.error
    pids = run_pids(pid_dir)
    assert len(pids) == 2 and not [p for p in pids if alive(p)]


def test_grandchild_left_behind_by_a_successful_driver_is_killed(driver, tmp_path,
                                                                 monkeypatch):
    pid_dir = tmp_path / "pids"
    pid_dir.mkdir()
    monkeypatch.setenv("PID_DIR", str(pid_dir))
    r = model(driver, tmp_path).run_one(np.array([10.0, 1.0]))
    assert r.status == "ok" and r.values[0] == 12.0
    assert not [p for p in run_pids(pid_dir) if alive(p)]


INTERRUPTED = r'''
import faulthandler
import signal
import sys
# A terminal's Ctrl-C: a test run started in the background (`cmd &` in a script) inherits
# SIGINT ignored, and Python keeps an ignored SIGINT ignored (CI hung here twice).
signal.signal(signal.SIGINT, signal.default_int_handler)
faulthandler.dump_traceback_later(20, exit=False)  # where it waits, if it ever hangs
import numpy as np
from rotoruq.evaluation.external import ExternalModel
from rotoruq.evaluation.process_tree import is_running as alive
m = ExternalModel([sys.executable, "-S", sys.argv[1]], ["kind", "a"], ["f"], workdir=sys.argv[2])
m.run_one(np.array([9.0, 1.0]))
'''


def test_interrupted_evaluation_kills_the_driver_tree(driver, tmp_path):
    pid_dir = tmp_path / "pids"
    pid_dir.mkdir()
    (tmp_path / "study.py").write_text(INTERRUPTED)
    proc = subprocess.Popen([sys.executable, str(tmp_path / "study.py"), str(driver),
                             str(tmp_path / "work")], env={**os.environ, "PID_DIR": str(pid_dir)},
                            stderr=subprocess.PIPE)
    deadline = time.monotonic() + 30
    while not list(pid_dir.glob("*.gc")) and time.monotonic() < deadline:
        time.sleep(0.02)
    pids = run_pids(pid_dir)
    assert len(pids) == 2 and all(alive(p) for p in pids)
    proc.send_signal(signal.SIGINT)  # Ctrl-C: KeyboardInterrupt in the waiting thread
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired as exc:
        proc.kill()
        try:
            _, err = proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:  # something else holds its stderr open
            err = b"(stderr still held open by another process)"
        raise AssertionError(f"no exit 60 s after Ctrl-C; its stacks:\n{err.decode()}") from exc
    assert proc.returncode != 0 and b"KeyboardInterrupt" in err
    assert not [p for p in pids if alive(p)]


def test_output_goes_to_capped_files_not_memory(tmp_path):
    chatty = tmp_path / "chatty.py"
    chatty.write_text("import sys\nline = b'x' * 1023 + b'\\n'\n"
                      "for _ in range(200 * 1024):\n    sys.stdout.buffer.write(line)\n"
                      "sys.stdout.buffer.write(b'LAST LINE\\n')\nsys.exit(2)\n")

    def hwm_kib() -> int:
        line = next(s for s in open("/proc/self/status") if s.startswith("VmHWM"))
        return int(line.split()[1])

    m = ExternalModel([sys.executable, "-S", str(chatty)], ["a"], ["f"],
                      workdir=tmp_path / "w", output_cap=2**20)
    before = hwm_kib()
    r = m.run_one(np.array([1.0]))
    grown = hwm_kib() - before
    assert r.status == "failed" and "status 2" in r.error
    assert r.stdout.endswith("LAST LINE\n") and len(r.stdout) <= 8200
    assert grown < 50 * 1024, f"peak memory grew by {grown} KiB for 200 MiB of output"
    out = Path(r.workdir) / "rotoruq.stdout"
    assert 2**20 < out.stat().st_size < 2**20 + 70 * 1024
    text = out.read_bytes()
    assert text.startswith(b"x" * 1023 + b"\n") and text.endswith(b"LAST LINE\n")
    omitted = 200 * 2**20 + 10 - 2**20 - 64 * 1024
    assert f"[rotoruq: {omitted} bytes omitted]".encode() in text


# --- names, work directories, identity ------------------------------------------------------


@pytest.mark.parametrize("bad", ["", "..", "a\nb", "a/b", "a\\b", "../x", "a b", "x..y", "{a}",
                                 "a=b", "tab\t"])
def test_names_are_validated(driver, tmp_path, bad):
    for kw in ({"names_in": [bad, "a"]}, {"names_out": [bad]},
               {"workdir": WorkDirectory(tmp_path / "w", name=bad)},
               {"contract": FileContract(parameters_file=bad)},
               {"contract": FileContract(results_file=bad)}):
        args = {"names_in": ["kind", "a"], "names_out": ["f"], "workdir": tmp_path / "w", **kw}
        with pytest.raises(ParameterError):
            ExternalModel([sys.executable, str(driver)], args.pop("names_in"),
                          args.pop("names_out"), **args)
    with pytest.raises(ParameterError):
        model(driver, tmp_path).run_one(np.array([0.0, 1.0]), eval_id=bad or "..")


def test_model_named_dotdot_never_deletes_outside_its_work_directory(driver, tmp_path):
    base = tmp_path / "project"
    (base / "work").mkdir(parents=True)
    precious = base / "thesis.tex"
    precious.write_text("years of work\n")
    with pytest.raises(ParameterError, match="'..'"):
        ExternalModel([sys.executable, str(driver)], ["kind", "a"], ["f"],
                      workdir=WorkDirectory(base / "work", name="..", tag=False))
    assert precious.read_text() == "years of work\n"


def test_untagged_work_directory_is_emptied_only_if_rotoruq_made_it(driver, tmp_path):
    mine = tmp_path / "work" / "solver"
    mine.mkdir(parents=True)
    (mine / "notes.txt").write_text("the user's own folder\n")
    m = model(driver, tmp_path, name="solver", tag=False, keep_workdirs=True,
              failure_policy="retry:1")
    with pytest.raises(ParameterError, match="not made by rotoruq"):
        m.run_one(np.array([0.0, 1.0]))
    assert (mine / "notes.txt").read_text() == "the user's own folder\n"
    (mine / "notes.txt").unlink()
    mine.rmdir()
    r = m.run_one(np.array([3.0, 0.5]))  # fails twice (fail marker): the retry re-made it
    assert r.status == "failed" and r.attempts == 2
    for a in (1.0, 2.0):  # rotoruq's own directory is reused run after run
        r = m.run_one(np.array([0.0, a]))
        assert r.values[0] == 2 * a and r.workdir == str(mine)
        assert (mine / ".rotoruq-workdir").exists()
    assert sorted(p.name for p in (tmp_path / "work").iterdir()) == ["solver"]


def test_parameters_file_cannot_be_forged_through_a_label(tmp_path):
    from rotoruq.evaluation.dakota_files import format_parameters

    with pytest.raises(ParameterError, match="white space"):
        format_parameters({"a\n1 functions": 1.0}, ["f"])
    with pytest.raises(ParameterError):
        format_parameters({"a": 1.0}, ["f\n0 eval_id"])


CONCURRENT = r'''
import os, sys
import numpy as np
from rotoruq.evaluation.external import ExternalModel, WorkDirectory
from rotoruq.evaluation.process_tree import is_running as alive
driver, work, who = sys.argv[1:4]
m = ExternalModel([sys.executable, "-S", driver], ["a"], ["f"],
                  workdir=WorkDirectory(work, keep_workdirs=sys.argv[4] == "keep"))
a = np.arange(8.0) + (100.0 if who == "B" else 0.0)
b = m.evaluate(a[:, None])
assert not b.failures, b.failures
assert np.array_equal(b.values[:, 0], 2 * a), b.values
print(os.getpid())
'''

# The driver checks its work directory stays its own while it runs: the parameters file is
# still there and still holds its input, and no foreign file appeared.
SLOW_DRIVER = r'''
import os, sys, time
params, results = sys.argv[1], sys.argv[2]
text = open(params).read()
mine = set(os.listdir("."))
time.sleep(0.05)
if open(params).read() != text or set(os.listdir(".")) != mine:
    sys.exit("work directory changed under me")
a = float(text.splitlines()[1].split()[0])
open(results, "w").write(f"{2 * a!r} f\n")
'''


@pytest.mark.parametrize("keep", ["keep", "remove"])
def test_two_processes_share_a_base_folder_without_collisions(tmp_path, keep):
    (tmp_path / "driver.py").write_text(SLOW_DRIVER)
    (tmp_path / "run.py").write_text(CONCURRENT)
    work = tmp_path / "work"
    procs = [subprocess.Popen([sys.executable, str(tmp_path / "run.py"),
                               str(tmp_path / "driver.py"), str(work), who, keep],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE)
             for who in "AB"]
    outs = [p.communicate(timeout=120) for p in procs]
    for p, (_, err) in zip(procs, outs, strict=True):
        assert p.returncode == 0, err.decode()
    dirs = sorted(d.name for d in work.iterdir())
    if keep == "keep":
        assert len(dirs) == 16  # one per evaluation, none reused
        pids = {out.decode().strip() for out, _ in outs}
        assert {d.split(".")[1] for d in dirs} == pids
    else:
        assert dirs == []


def test_the_flat_keywords_of_0_1_still_work_for_one_release(driver, tmp_path):
    """ExternalModel takes its work directory and file options as two records; the flat
    keywords of rotoruq 0.1 make the same model (same identity, same runs, bitwise) with a
    DeprecationWarning naming the record field; an unknown keyword is a TypeError with the
    closest name."""
    import inspect

    assert len(inspect.signature(ExternalModel).parameters) <= 12
    tpl = tmp_path / "solver.inp"
    tpl.write_text("c = {a:.17g}\n")
    cmd = [sys.executable, "-S", str(driver)]
    new = ExternalModel(cmd, ["kind", "a"], ["f"],
                        workdir=WorkDirectory(tmp_path / "new", name="run", keep_workdirs=True,
                                              template_files=[tpl]),
                        contract=FileContract(parameters_format="aprepro",
                                              parameters_file="in.txt",
                                              analysis_components=[("solver", "mesh")]))
    with pytest.warns(DeprecationWarning) as caught:
        old = ExternalModel(cmd, ["kind", "a"], ["f"], workdir=tmp_path / "old", name="run",
                            keep_workdirs=True, template_files=[tpl],
                            parameters_format="aprepro", parameters_file="in.txt",
                            analysis_components=[("solver", "mesh")])
    said = {str(w.message) for w in caught}
    assert ("ExternalModel(keep_workdirs=...) is deprecated and will be removed in the next "
            "release: pass workdir=WorkDirectory(keep_workdirs=...)") in said
    assert ("ExternalModel(parameters_format=...) is deprecated and will be removed in the "
            "next release: pass contract=FileContract(parameters_format=...)") in said
    assert len(said) == 6
    assert all(w.filename == __file__ for w in caught)  # the warning points at the caller
    assert old.identity() == new.identity()
    for attr in ("name", "tag", "keep_workdirs", "template_files", "copy_files", "link_files",
                 "parameters_format", "parameters_file", "results_file", "asv",
                 "analysis_components"):
        assert getattr(old, attr) == getattr(new, attr), attr
    x = np.array([0.0, 0.1])
    r_old, r_new = old.run_one(x, eval_id="1"), new.run_one(x, eval_id="1")
    np.testing.assert_array_equal(r_old.values, r_new.values)
    assert r_old.values[0] == 3 * 0.1
    assert (Path(r_old.workdir) / "in.txt").read_bytes() == (
        Path(r_new.workdir) / "in.txt").read_bytes()
    # a flat keyword overrides that field of the record given
    with pytest.warns(DeprecationWarning, match="WorkDirectory"):
        mixed = ExternalModel(cmd, ["kind", "a"], ["f"],
                              workdir=WorkDirectory(tmp_path / "w", name="one"), name="two")
    assert mixed.name == "two" and mixed.workdir == tmp_path / "w"
    with pytest.raises(TypeError, match="'keep_workdir'.*did you mean 'keep_workdirs'"):
        ExternalModel(cmd, ["kind", "a"], ["f"], keep_workdir=True)
    with pytest.raises(ParameterError, match="contract must be a FileContract"):
        ExternalModel(cmd, ["kind", "a"], ["f"], contract={"asv": 1})
    with pytest.raises(ParameterError, match="workdir must be a path or a WorkDirectory"):
        ExternalModel(cmd, ["kind", "a"], ["f"], workdir=3)


def test_identity_covers_what_changes_answers(driver, tmp_path):
    tpl = tmp_path / "solver.inp"
    tpl.write_text("c = {a}\n")
    data = tmp_path / "data"
    data.mkdir()
    (data / "table.c81").write_text("v1\n")

    def make(**kw):
        return model(driver, tmp_path, template_files=[tpl], copy_files=[data], **kw)

    ident = make().identity()
    json.dumps(ident)
    assert make().identity() == ident  # a model made the same way has the same identity
    word = ident["command"][2]
    assert word["path"] == str(driver) and word["sha256"] == hashlib.sha256(
        driver.read_bytes()).hexdigest()
    assert ident["command"][0]["sha256"]  # the interpreter itself
    changed = {
        "names_in": ExternalModel([sys.executable, "-S", str(driver)], ["kind", "b"], ["f"],
                                  workdir=WorkDirectory(tmp_path / "work", copy_files=[data])),
        "failure_policy": make(failure_policy="retry:2"),
        "env": make(env={"OMP_NUM_THREADS": "1"}),
        "parameters_format": make(parameters_format="aprepro"),
        "asv": make(asv=3),
    }
    for key, other in changed.items():
        assert other.identity()[key] != ident[key], key
    # timeouts and work directories do not change an answer
    assert make(timeout=5, workdir=tmp_path / "elsewhere", keep_workdirs=True).identity() == ident
    # edits to files: the driver script, a template, a file inside a copied directory
    m = make()
    m.identity()
    driver.write_text(driver.read_text() + "\n# edited\n")
    assert m.identity() == ident  # hashed once per model, not per evaluation
    assert make().identity()["command"] != ident["command"]
    tpl.write_text("c = {a:.3f}\n")
    assert make().identity()["templates"] != ident["templates"]
    (data / "table.c81").write_text("v2\n")
    assert make().identity()["copy_files"] != ident["copy_files"]


def test_template_fields_are_checked_when_the_model_is_made(driver, tmp_path):
    tpl = tmp_path / "solver.inp"
    tpl.write_text("c = {a}\nd = {unknown}\n")
    with pytest.raises(InputFileError, match="unknown") as err:
        model(driver, tmp_path, template_files=[tpl])
    assert err.value.line == 2
    tpl.write_text("c = {a}\nd = {c0}\ne = {h = 2}\n")
    m = ExternalModel([sys.executable, "-S", str(driver)], ["kind", "a", "c0"], ["f"],
                      workdir=WorkDirectory(tmp_path / "work", template_files=[tpl],
                                            keep_workdirs=True))
    r = m.run_one(np.array([0.0, 1.5, 0.25]))
    assert (Path(r.workdir) / "solver.inp").read_text() == "c = 1.5\nd = 0.25\ne = 2\n"
    tpl.write_bytes(b"c = {a}\n\xff\n")
    with pytest.raises(InputFileError, match="UTF-8"):
        model(driver, tmp_path, template_files=[tpl])
