"""The SQLite store: exact and tolerant reuse, records, concurrency, tabular export."""

from __future__ import annotations

import multiprocessing as mp
import pickle
import sqlite3

import numpy as np
import pytest

from rotoruq.evaluation.evaluator import Evaluator
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
