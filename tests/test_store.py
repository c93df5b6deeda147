"""The SQLite store: exact and tolerant reuse, records, concurrency, tabular export."""

from __future__ import annotations

import multiprocessing as mp
import pickle
import sqlite3
import sys

import numpy as np
import pytest

from rotoruq.evaluation.evaluator import Evaluator
from rotoruq.evaluation.external import ExternalModel
from rotoruq.evaluation.store import NewRecord, Store, canonical_key, canonical_keys
from rotoruq.model import FunctionModel

KW = dict(study="s", model="m", names_in=("a", "b"), names_out=("f", "g"))


def test_wal_mode_and_round_trip(tmp_path):
    st = Store(tmp_path / "sub" / "e.db")
    mode = sqlite3.connect(tmp_path / "sub" / "e.db").execute("PRAGMA journal_mode").fetchone()
    assert mode[0] == "wal"
    x = np.array([0.1 + 0.2, -1e-300])
    ids = st.add([NewRecord(x, np.array([np.pi, np.nan]), wall_time=0.5, eval_id="3"),
                  NewRecord(x * 2, None, "failed", "boom", "out", "err")], run_id="r1", **KW)
    assert ids == [1, 2]
    r1, r2 = st.records(study="s")
    np.testing.assert_array_equal(r1.inputs, x)  # exact float round trip
    assert r1.outputs[0] == np.pi and np.isnan(r1.outputs[1])
    assert (r1.status, r1.run_id, r1.eval_id, r1.wall_time) == ("ok", "r1", "3", 0.5)
    assert r1.names_in == ("a", "b") and r1.names_out == ("f", "g")
    assert (r2.status, r2.error, r2.stdout, r2.stderr, r2.outputs) == ("failed", "boom", "out",
                                                                        "err", None)
    assert st.count() == 2 and st.count(status="failed") == 1 and st.max_id() == 2
    with pytest.raises(ValueError, match="status"):
        st.add([NewRecord(x, None, "odd")], **KW)


def test_canonical_keys():
    assert canonical_key(np.array([0.0])) == canonical_key(np.array([-0.0]))
    assert canonical_key(np.array([0.1 + 0.2])) != canonical_key(np.array([0.3]))
    x = np.random.default_rng(0).normal(size=(5, 3))
    assert canonical_keys(x) == [canonical_key(r) for r in x]


def test_lookup_exact_tolerance_and_status(tmp_path):
    st = Store(tmp_path / "e.db")
    st.add([NewRecord(np.array([1.0, 2.0]), np.array([1.0, 1.0])),
            NewRecord(np.array([1.0, 2.0]), np.array([2.0, 2.0])),  # latest wins
            NewRecord(np.array([5.0, 5.0]), None, "failed", "x")], **KW)
    q = np.array([[1.0, 2.0], [1.0, 2.0 + 1e-12], [5.0, 5.0], [-0.0 + 1.0, 2.0]])
    found = st.lookup(q, study="s", model="m")
    assert found[0].outputs.tolist() == [2.0, 2.0]
    assert found[1] is None and found[2] is None and found[3] is not None
    near = st.lookup(q, study="s", model="m", tolerance=1e-9)
    assert near[1].outputs.tolist() == [2.0, 2.0]
    assert st.lookup(np.array([[1.0, 2.1]]), study="s", model="m", tolerance=1e-3) == [None]
    assert st.lookup(q[2:3], study="s", model="m", statuses=("failed",))[0].error == "x"
    assert st.lookup(q[:1], study="other", model="m") == [None]
    assert st.lookup(q[:1], study="s", model="other") == [None]


def test_export_annotated_tabular(tmp_path):
    st = Store(tmp_path / "e.db")
    st.add([NewRecord(np.array([1.5, -2.0]), np.array([3.25, 1e-20])),
            NewRecord(np.array([0.0, 1.0]), None, "failed", "x"),
            NewRecord(np.array([2.0, 3.0]), np.array([4.0, 5.0]))], **KW)
    path = st.export_tabular(tmp_path / "t.dat", study="s")
    lines = path.read_text().splitlines()
    assert lines[0].split() == ["%eval_id", "interface", "a", "b", "f", "g"]
    assert [ln.split()[:2] for ln in lines[1:]] == [["1", "NO_ID"], ["2", "NO_ID"]]
    data = np.loadtxt(path, comments="%", usecols=range(2, 6))
    np.testing.assert_array_equal(data, [[1.5, -2.0, 3.25, 1e-20], [2.0, 3.0, 4.0, 5.0]])
    with_failed = st.export_tabular(tmp_path / "t2.dat", include_failed=True)
    assert "nan" in with_failed.read_text().splitlines()[2]
    with pytest.raises(ValueError, match="no evaluations"):
        st.export_tabular(tmp_path / "t3.dat", study="none")


def _writer(path, worker, n):
    st = Store(path, timeout=10.0)
    for i in range(n):
        st.add([NewRecord(np.array([worker, i], float), np.array([worker * 1000.0 + i, 0.0]))],
               run_id=f"w{worker}", **KW)


def test_concurrent_writers_from_several_processes(tmp_path):
    path = tmp_path / "e.db"
    Store(path)
    ctx = mp.get_context("spawn")
    procs = [ctx.Process(target=_writer, args=(path, w, 60)) for w in range(4)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    assert [p.exitcode for p in procs] == [0, 0, 0, 0]
    recs = Store(path).records()
    assert len(recs) == 240 and len({r.id for r in recs}) == 240
    got = sorted((int(r.inputs[0]), int(r.inputs[1]), r.outputs[0]) for r in recs)
    assert got == sorted((w, i, w * 1000.0 + i) for w in range(4) for i in range(60))


def test_store_pickles_and_reopens(tmp_path):
    st = Store(tmp_path / "e.db")
    st.add([NewRecord(np.array([1.0, 2.0]), np.array([3.0, 4.0]))], **KW)
    st2 = pickle.loads(pickle.dumps(st))
    assert st2.count() == 1


def test_add_returns_consecutive_ids_and_computed_values_round_trip(tmp_path):
    st = Store(tmp_path / "e.db")
    recs = [NewRecord(np.array([float(i)]), np.array([i * 2.0])) for i in range(5)]
    assert st.add(recs[:2], **KW) == [1, 2]
    assert st.add(recs[2:], **KW) == [3, 4, 5]
    assert [r.outputs[0] for r in st.records()] == [0.0, 2.0, 4.0, 6.0, 8.0]
    assert st.get_computed("self_check", "k") is None
    st.put_computed("self_check", "k", b"\x00one")
    st.put_computed("self_check", "k", b"two")  # replaced
    assert Store(tmp_path / "e.db").get_computed("self_check", "k") == b"two"
    assert st.get_computed("other", "k") is None


def test_deferred_writes_commit_on_leaving_the_block_also_on_error(tmp_path):
    m = FunctionModel(lambda x: x * 2.0, ["a"], ["y"])
    ev = Evaluator(m, store=tmp_path / "e.db", study="st")
    with ev.deferred_writes(seconds=3600.0):
        for i in range(3):
            ev.evaluate(np.array([[float(i)], [i + 0.5]]))
        assert ev.store.count() == 0  # nothing committed yet
    assert ev.store.count() == 6
    with pytest.raises(RuntimeError), ev.deferred_writes(seconds=3600.0):
        ev.evaluate(np.array([[7.0]]))
        raise RuntimeError("the chain failed")
    assert ev.store.count() == 7
    with ev.deferred_writes(seconds=0.0):  # every batch committed at once
        ev.evaluate(np.array([[8.0]]))
        assert ev.store.count() == 8
    ev.evaluate(np.array([[9.0]]))  # outside the block: committed at once, as always
    assert ev.store.count() == 9
    assert Evaluator(m, store=tmp_path / "e.db", study="st").evaluate(
        np.array([[0.5], [7.0]])).values.tolist() == [[1.0], [14.0]]


def test_unstored_evaluates_an_in_process_model_directly_and_an_external_one_as_always(
        tmp_path):
    calls = []

    def f(x):
        calls.append(len(x))
        return np.c_[x[:, 0] * 2.0, np.where(x[:, 0] > 5.0, np.nan, 1.0)]

    ev = Evaluator(FunctionModel(f, ["a"], ["y", "z"]), store=tmp_path / "e.db", study="st")
    stored = ev.evaluate(np.array([[1.0]])).values
    with ev.unstored():
        got = ev.evaluate(np.array([[1.0], [2.0], [2.0], [6.0]]))
        assert ev.store.count() == 1  # nothing written, the stored point not looked up
    assert calls == [1, 4]
    np.testing.assert_array_equal(got.values[0], stored[0])  # the model's own bits
    assert list(got.failures) == [3] and ev.last_stats.n_evaluations == 4
    ev.evaluate(np.array([[2.0]]))  # outside the block: stored again
    assert ev.store.count() == 2
    # an external solver keeps the store inside the block too (its runs cost seconds)
    driver = tmp_path / "driver.py"
    driver.write_text("import sys\nline = open(sys.argv[1]).read().splitlines()[1]\n"
                      "a = float(line.split()[0])\n"
                      "open(sys.argv[2], 'w').write(f'{2 * a!r} y\\n')\n")
    ext = Evaluator(ExternalModel([sys.executable, "-S", str(driver)], ["a"], ["y"],
                                  workdir=tmp_path / "work"), store=tmp_path / "x.db")
    with ext.unstored():
        assert ext.evaluate(np.array([[3.0]])).values.tolist() == [[6.0]]
    assert ext.store.count() == 1


def test_evaluator_reuses_identical_inputs_across_runs(tmp_path):
    calls = []

    def f(x):
        calls.append(len(x))
        return np.c_[x.sum(axis=1), x.prod(axis=1)]

    m = FunctionModel(f, ["a", "b"], ["s", "p"])
    x = np.random.default_rng(1).normal(size=(10, 2))
    ev = Evaluator(m, store=tmp_path / "e.db", study="st", chunk_size=4)
    a = ev.evaluate(x)
    assert sum(calls) == 10 and ev.last_stats.n_reused == 0
    ev2 = Evaluator(m, store=tmp_path / "e.db", study="st")
    y = np.vstack([x[3:7], [[9.0, 9.0]], x[3:4]])
    b = ev2.evaluate(y)
    assert sum(calls) == 11  # only the new point was run, once
    assert ev2.last_stats.n_reused == 5 and ev2.last_stats.n_evaluations == 1
    np.testing.assert_array_equal(b.values[:4], a.values[3:7])
    np.testing.assert_array_equal(b.values[4], [18.0, 81.0])
    # another study does not see these evaluations; a tolerance finds near points
    ev3 = Evaluator(m, store=tmp_path / "e.db", study="other")
    ev3.evaluate(x[:2])
    assert sum(calls) == 13
    ev4 = Evaluator(m, store=tmp_path / "e.db", study="st", tolerance=1e-8)
    ev4.evaluate(x * (1 + 1e-12))
    assert ev4.last_stats.n_reused == 10 and sum(calls) == 13


# -- storage faults: a one-line StoreError naming the file, never a raw sqlite3 error ----------

KW1 = dict(study="s", model="m", names_in=("a",), names_out=("f",))
SRC = str(__import__("pathlib").Path(__file__).resolve().parents[1] / "src")


def _filled(path, n=600):
    st = Store(path)
    for i in range(n):
        st.add([NewRecord(np.array([float(i)]), np.array([2.0 * i + 0.5]))], **KW1)
    st.close()
    return path


def _one_line(exc, path):
    msg = str(exc)
    assert "\n" not in msg and msg.startswith(f"{path}: ")
    return msg


@pytest.mark.parametrize("damage", ["truncated", "zeroed", "garbage"])
def test_damaged_store_is_a_clear_error_and_repair_keeps_what_is_readable(tmp_path, damage):
    from rotoruq.errors import StoreCorruptError
    from rotoruq.evaluation.store import repair_store

    path = _filled(tmp_path / "e.db")
    data = path.read_bytes()
    if damage == "truncated":
        bad = data[: len(data) // 2]
    elif damage == "zeroed":  # pages in the middle overwritten with zeros
        bad = data[:16384] + bytes(16384) + data[32768:]
    else:
        bad = np.random.default_rng(0).bytes(len(data))
    path.write_bytes(bad)
    with pytest.raises(StoreCorruptError) as info:
        Store(path)
    msg = _one_line(info.value, path)
    assert "damaged" in msg and "rotoruq repair RESULTS" in msg
    assert not isinstance(info.value, sqlite3.Error)

    rep = repair_store(path)
    assert rep.status == "rebuilt" and rep.quarantined.read_bytes() == bad
    assert rep.quarantined.name.startswith("e.db.damaged-")
    st = Store(path)
    recs = st.records()
    assert len(recs) == rep.n_salvaged < 600
    if damage != "garbage":
        assert rep.n_salvaged > 0
    for r in recs:  # what was kept is what was written
        assert r.outputs[0] == 2.0 * r.inputs[0] + 0.5
    assert repair_store(path).status == "ok"

    # resume: only the lost points are evaluated again
    m = FunctionModel(lambda x: 2.0 * x + 0.5, ["a"], ["f"])
    x = np.arange(600.0)[:, None]
    with Evaluator(m, store=path, study="s", model_id="m") as ev:
        out = ev.evaluate(x)
        assert ev.last_stats.n_reused == rep.n_salvaged
        assert ev.last_stats.n_evaluations == 600 - rep.n_salvaged
    np.testing.assert_array_equal(out.values[:, 0], 2.0 * x[:, 0] + 0.5)


CHILD = """
import resource, signal, sys
import numpy as np
from rotoruq.errors import StoreError
from rotoruq.evaluation.store import NewRecord, Store
path, limit = sys.argv[1], int(sys.argv[2])
kw = dict(study="s", model="m", names_in=("a",), names_out=("f",))
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # writes past the limit fail with EFBIG
if limit:
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
n = 0
try:
    st = Store(path)
    for i in range(100000):
        st.add([NewRecord(np.array([float(i)]), np.array([2.0 * i + 0.5]), stdout="o" * 4000)],
               **kw)
        n += 1
        if not limit and n == 3:
            break
except StoreError as exc:
    print(n)
    print(exc)
    sys.exit(3)
print(n)
"""


def _child(args, prefix=()):
    import subprocess
    import sys

    env = {**__import__("os").environ, "PYTHONPATH": SRC}
    return subprocess.run([*prefix, sys.executable, "-c", CHILD, *map(str, args)],
                          capture_output=True, text=True, timeout=120, env=env)


def _resume_after_fault(path, n_committed):
    st = Store(path)  # passes the integrity check
    assert st.count() == n_committed
    m = FunctionModel(lambda x: 2.0 * x + 0.5, ["a"], ["f"])
    with Evaluator(m, store=st, study="s", model_id="m") as ev:
        out = ev.evaluate(np.arange(n_committed + 5.0)[:, None])
        assert ev.last_stats.n_reused == n_committed and ev.last_stats.n_evaluations == 5
    np.testing.assert_array_equal(out.values[:, 0], 2.0 * np.arange(n_committed + 5.0) + 0.5)


def test_file_size_limit_is_a_clear_error_and_the_store_resumes(tmp_path):
    path = tmp_path / "e.db"
    proc = _child([path, 150_000])
    assert proc.returncode == 3, proc.stderr
    n, msg = proc.stdout.splitlines()
    assert msg.startswith(f"{path}: ") and "free disk space" in msg, msg
    assert "Traceback" not in proc.stderr
    assert int(n) > 0
    _resume_after_fault(path, int(n))


def test_full_disk_is_a_clear_error_and_the_store_resumes(tmp_path):
    import os
    import subprocess

    mnt = tmp_path / "small"
    mnt.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mnt)],
                      capture_output=True).returncode:
        pytest.skip("cannot mount a small tmpfs here (not root); the file-size limit test "
                    "covers the write error")
    try:
        path = mnt / "e.db"
        _filled(path, n=3)
        with open(mnt / "filler", "wb") as f:  # fill the file system but for ~40 KiB
            while os.statvfs(mnt).f_bavail * os.statvfs(mnt).f_frsize > 40_000:
                f.write(bytes(4096))
        proc = _child([path, 10**9])  # the limit is never reached: the disk fills up first
        assert proc.returncode == 3, proc.stdout + proc.stderr
        msg = proc.stdout.splitlines()[1]
        assert msg.startswith(f"{path}: ") and "free disk space" in msg, msg
        assert "Traceback" not in proc.stderr
        assert "no room" in msg  # ENOSPC: SQLite's "database or disk is full"
        (mnt / "filler").unlink()
        _resume_after_fault(path, 3 + int(proc.stdout.splitlines()[0]))
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def test_read_only_folder_is_a_clear_error(tmp_path):
    import os
    import shutil

    folder = tmp_path / "ro"
    path = _filled(folder / "e.db", n=3)
    prefix: tuple[str, ...] = ()
    if os.geteuid() == 0:  # root writes anywhere: run the child without that privilege
        if shutil.which("setpriv") is None:
            pytest.skip("running as root without setpriv")
        prefix = ("setpriv", "--bounding-set=-dac_override,-dac_read_search,-fowner")
    folder.chmod(0o555)
    path.chmod(0o444)
    try:
        proc = _child([path, 0], prefix)
        assert proc.returncode == 3, proc.stdout + proc.stderr
        msg = proc.stdout.splitlines()[1]
        assert msg.startswith(f"{path}: ") and "read-only" in msg, msg
        new = folder / "new" / "e.db"
        proc = _child([new, 0], prefix)
        assert proc.returncode == 3 and str(new) in proc.stdout, proc.stdout + proc.stderr
    finally:
        folder.chmod(0o755)
        path.chmod(0o644)
    _resume_after_fault(path, 3)


def test_rotoruq_repair_command_moves_a_damaged_store_aside(tmp_path):
    """The one-line error names `rotoruq repair RESULTS`; the command does what it says."""
    import subprocess
    import sys

    path = _filled(tmp_path / "evaluations.sqlite")
    data = path.read_bytes()
    path.write_bytes(data[:16384] + bytes(16384) + data[32768:])
    cmd = [sys.executable, "-m", "rotoruq.study.cli", "repair", str(tmp_path)]
    first = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert first.returncode == 0, first.stderr
    assert "damaged" in first.stdout and "moved it to" in first.stdout
    assert len(list(tmp_path.glob("evaluations.sqlite.damaged-*"))) == 1
    assert 0 < len(Store(path).records()) < 600
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert again.returncode == 0 and "store intact" in again.stdout
