"""A crash-safe record of every evaluation, in SQLite.

One row per evaluation: inputs, outputs, status (``ok``, ``failed``, ``recovered``), error
text, the solver's stdout/stderr (kept on failure), wall time, host/pid, timestamps, and the
study and run it belongs to. Each evaluation is committed in its own transaction the moment it
finishes, so a study killed at any point loses at most the evaluations that were running.

Re-running a study looks up stored evaluations by a canonical key of the input point (the
bytes of each float64, with -0.0 folded into 0.0), so identical inputs are never evaluated
twice; :meth:`Store.lookup` also accepts a tolerance for near matches.

The database runs in WAL mode with a busy timeout, and writes retry on "database is locked",
so several processes (parallel studies, Dask workers on a shared file system that honours
locks) may write to one file. Export to Dakota's annotated tabular format with
:meth:`Store.export_tabular`.
"""

from __future__ import annotations

import json
import math
import os
import socket
import sqlite3
import threading
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

from ..errors import ParameterError

__all__ = ["Store", "EvalRecord", "NewRecord", "canonical_key", "open_store"]

_SCHEMA = """
CREATE TABLE IF NOT EXISTS evaluations (
    id        INTEGER PRIMARY KEY AUTOINCREMENT,
    study     TEXT NOT NULL,
    run_id    TEXT NOT NULL,
    model     TEXT NOT NULL,
    key       TEXT NOT NULL,
    names_in  TEXT NOT NULL,
    names_out TEXT NOT NULL,
    inputs    TEXT NOT NULL,
    outputs   TEXT,
    status    TEXT NOT NULL,
    error     TEXT,
    stdout    TEXT,
    stderr    TEXT,
    wall_time REAL,
    started   REAL,
    finished  REAL NOT NULL,
    host      TEXT,
    pid       INTEGER,
    eval_id   TEXT,
    attempts  INTEGER
);
CREATE INDEX IF NOT EXISTS evaluations_lookup ON evaluations (study, model, key);
"""

_COLUMNS = ("study", "run_id", "model", "key", "names_in", "names_out", "inputs", "outputs",
            "status", "error", "stdout", "stderr", "wall_time", "started", "finished", "host",
            "pid", "eval_id", "attempts")

STATUSES = ("ok", "failed", "recovered")


def canonical_key(x: np.ndarray) -> str:
    """Exact key of one input point: hex of its little-endian float64 bytes (-0.0 -> 0.0)."""
    x = np.asarray(x, dtype="<f8") + 0.0  # +0.0 turns -0.0 into 0.0
    return x.tobytes().hex()


def canonical_keys(x: np.ndarray) -> list[str]:
    """Keys of every row of ``x`` (n, d)."""
    x = np.ascontiguousarray(np.atleast_2d(np.asarray(x, dtype="<f8")) + 0.0)
    d = x.shape[1]
    raw = x.tobytes().hex()
    w = 16 * d
    return [raw[i * w : (i + 1) * w] for i in range(x.shape[0])]


def _dumps(a) -> str | None:
    if a is None:
        return None
    # json writes floats with repr (exact round trip); NaN/inf as bare words Python reads back
    return json.dumps([float(v) for v in np.ravel(a)])


@dataclass(frozen=True, eq=False)
class NewRecord:
    """One finished evaluation to commit (what an evaluator hands to :meth:`Store.add`)."""

    inputs: np.ndarray
    outputs: np.ndarray | None
    status: str = "ok"
    error: str | None = None
    stdout: str | None = None
    stderr: str | None = None
    wall_time: float | None = None
    started: float | None = None
    eval_id: str | None = None
    attempts: int = 1


@dataclass(frozen=True, eq=False)
class EvalRecord:
    """One stored evaluation. ``outputs`` is None for failures without recovered values."""

    id: int
    study: str
    run_id: str
    model: str
    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    inputs: np.ndarray
    outputs: np.ndarray | None
    status: str
    error: str | None
    stdout: str | None
    stderr: str | None
    wall_time: float | None
    started: float | None
    finished: float
    host: str | None
    pid: int | None
    eval_id: str | None
    attempts: int | None


class Store:
    """SQLite evaluation store.

    Parameters
    ----------
    path : database file (created with its directory when missing).
    timeout : seconds a writer waits for a lock before retrying (busy_timeout).
    retries : how many times a locked write is retried (with growing back-off) before raising.

    The store opens one connection per process and thread and reopens after a fork, so one
    Store object may be shared with worker processes.
    """

    def __init__(self, path: str | os.PathLike, *, timeout: float = 30.0, retries: int = 20):
        self.path = Path(path)
        self.timeout = float(timeout)
        self.retries = int(retries)
        self._local = threading.local()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        def schema(con):
            for stmt in _SCHEMA.split(";"):
                if stmt.strip():
                    con.execute(stmt)

        self._write(schema)

    # -- connections ---------------------------------------------------------------------------

    def _con(self) -> sqlite3.Connection:
        con = getattr(self._local, "con", None)
        if con is None or self._local.pid != os.getpid():
            con = sqlite3.connect(self.path, timeout=self.timeout, isolation_level=None,
                                  check_same_thread=True)
            con.execute(f"PRAGMA busy_timeout = {int(self.timeout * 1000)}")
            for _ in range(self.retries):
                try:
                    con.execute("PRAGMA journal_mode = WAL")
                    break
                except sqlite3.OperationalError:
                    time.sleep(0.05)
            # WAL + NORMAL: a committed transaction survives the death of the process
            # (SIGKILL); only an OS crash or power cut can lose the last commits.
            con.execute("PRAGMA synchronous = NORMAL")
            self._local.con = con
            self._local.pid = os.getpid()
        return con

    def close(self) -> None:
        """Close this thread's connection (a later call reopens it)."""
        con = getattr(self._local, "con", None)
        if con is not None and self._local.pid == os.getpid():
            con.close()
        self._local.con = None

    def __getstate__(self):
        return {"path": self.path, "timeout": self.timeout, "retries": self.retries}

    def __setstate__(self, state):
        self.path, self.timeout, self.retries = state["path"], state["timeout"], state["retries"]
        self._local = threading.local()

    def __repr__(self) -> str:
        return f"Store({str(self.path)!r})"

    def _write(self, fn):
        """Run ``fn(con)`` in an immediate transaction, retrying while the file is locked."""
        delay = 0.01
        for attempt in range(self.retries + 1):
            con = self._con()
            try:
                con.execute("BEGIN IMMEDIATE")
                try:
                    out = fn(con)
                    con.execute("COMMIT")
                    return out
                except BaseException:
                    if con.in_transaction:
                        con.execute("ROLLBACK")
                    raise
            except sqlite3.OperationalError as exc:
                msg = str(exc).lower()
                if ("locked" not in msg and "busy" not in msg) or attempt == self.retries:
                    raise
                time.sleep(delay)
                delay = min(delay * 2, 1.0)
        raise AssertionError("unreachable")  # pragma: no cover

    # -- writing ---------------------------------------------------------------------------

    def add(
        self,
        records: Iterable[NewRecord],
        *,
        study: str,
        model: str,
        names_in: Sequence[str],
        names_out: Sequence[str],
        run_id: str = "",
    ) -> list[int]:
        """Commit finished evaluations in one transaction; returns their ids."""
        host, pid, now = socket.gethostname(), os.getpid(), time.time()
        nin, nout = json.dumps(list(names_in)), json.dumps(list(names_out))
        rows = []
        for r in records:
            if r.status not in STATUSES:
                raise ParameterError(f"status must be one of {STATUSES}, got {r.status!r}")
            x = np.asarray(r.inputs, dtype=float)
            rows.append((study, run_id, model, canonical_key(x), nin, nout, _dumps(x),
                         _dumps(r.outputs), r.status, r.error, r.stdout, r.stderr, r.wall_time,
                         r.started, now, host, pid, r.eval_id, r.attempts))
        if not rows:
            return []
        sql = (f"INSERT INTO evaluations ({', '.join(_COLUMNS)}) "
               f"VALUES ({', '.join('?' * len(_COLUMNS))})")

        def ins(con):
            ids = []
            for row in rows:
                ids.append(con.execute(sql, row).lastrowid)
            return ids

        return self._write(ins)

    # -- reading ---------------------------------------------------------------------------

    def lookup(
        self,
        x: np.ndarray,
        *,
        study: str,
        model: str,
        tolerance: float | None = None,
        statuses: Sequence[str] = ("ok", "recovered"),
    ) -> list[EvalRecord | None]:
        """Stored evaluation for each row of ``x`` (n, d), or None where there is none.

        Exact matching compares canonical keys. With ``tolerance``, a stored point x_s matches
        x when ``|x - x_s| <= tolerance * max(1, |x_s|)`` componentwise; the closest (max-norm)
        match wins. When several stored rows match exactly, the latest wins.
        """
        x = np.atleast_2d(np.asarray(x, dtype=float))
        keys = canonical_keys(x)
        st = tuple(statuses)
        marks = ",".join("?" * len(st))
        con = self._con()
        if tolerance is None:
            found: dict[str, EvalRecord] = {}
            uniq = list(dict.fromkeys(keys))
            for i in range(0, len(uniq), 500):
                part = uniq[i : i + 500]
                q = (f"SELECT * FROM evaluations WHERE study = ? AND model = ? AND status IN "
                     f"({marks}) AND key IN ({','.join('?' * len(part))}) ORDER BY id")
                for row in con.execute(q, (study, model, *st, *part)):
                    rec = _record(row)
                    found[row[4]] = rec
            return [found.get(k) for k in keys]
        q = (f"SELECT * FROM evaluations WHERE study = ? AND model = ? AND status IN ({marks})"
             " ORDER BY id")
        recs = [_record(row) for row in con.execute(q, (study, model, *st))]
        recs = [r for r in recs if r.inputs.shape == (x.shape[1],)]
        if not recs:
            return [None] * len(x)
        xs = np.array([r.inputs for r in recs])
        scale = np.maximum(1.0, np.abs(xs))
        out: list[EvalRecord | None] = []
        for row in x:
            dev = np.abs(row[None, :] - xs) / scale
            worst = dev.max(axis=1)
            j = int(np.argmin(worst[::-1]))
            j = len(recs) - 1 - j  # latest among equally close
            out.append(recs[j] if worst[j] <= tolerance else None)
        return out

    def records(
        self, *, study: str | None = None, model: str | None = None, status: str | None = None,
        run_id: str | None = None,
    ) -> list[EvalRecord]:
        """Stored evaluations, oldest first, filtered by the given fields."""
        where, args = [], []
        for col, val in (("study", study), ("model", model), ("status", status),
                         ("run_id", run_id)):
            if val is not None:
                where.append(f"{col} = ?")
                args.append(val)
        q = "SELECT * FROM evaluations"
        if where:
            q += " WHERE " + " AND ".join(where)
        q += " ORDER BY id"
        return [_record(r) for r in self._con().execute(q, args)]

    def count(self, *, study: str | None = None, status: str | None = None) -> int:
        """Number of stored evaluations (optionally of one study / status)."""
        where, args = [], []
        if study is not None:
            where.append("study = ?")
            args.append(study)
        if status is not None:
            where.append("status = ?")
            args.append(status)
        q = "SELECT COUNT(*) FROM evaluations" + (" WHERE " + " AND ".join(where) if where
                                                   else "")
        return int(self._con().execute(q, args).fetchone()[0])

    def max_id(self) -> int:
        """Largest evaluation id so far (0 for an empty store)."""
        row = self._con().execute("SELECT MAX(id) FROM evaluations").fetchone()
        return int(row[0] or 0)

    def export_tabular(
        self, path: str | os.PathLike, *, study: str | None = None, model: str | None = None,
        interface: str = "NO_ID", include_failed: bool = False,
    ) -> Path:
        """Write Dakota's annotated tabular format: ``%eval_id interface <vars> <responses>``.

        One row per stored evaluation (in commit order) of a single model's variables and
        responses; failed evaluations are left out unless ``include_failed`` (then written as
        ``nan``). Values are written with 17 significant digits. Returns the path.
        """
        recs = self.records(study=study, model=model)
        if not include_failed:
            recs = [r for r in recs if r.outputs is not None and r.status != "failed"]
        path = Path(path)
        if not recs:
            raise ParameterError("no evaluations to export" + (f" for study {study!r}" if study
                                                             else ""))
        heads = {(r.names_in, r.names_out) for r in recs}
        if len(heads) > 1:
            raise ParameterError("the selected evaluations come from models with different "
                             "variables/responses; pass study= or model= to pick one")
        names_in, names_out = heads.pop()
        cols = ["%eval_id", "interface", *names_in, *names_out]
        lines = [" ".join(f"{c:>24}" if i > 1 else c for i, c in enumerate(cols))]
        for k, r in enumerate(recs, 1):
            out = r.outputs if r.outputs is not None else np.full(len(names_out), np.nan)
            vals = " ".join(f"{v:24.16e}" for v in (*r.inputs, *out))
            lines.append(f"{k:<8} {interface:<9} {vals}")
        path.write_text("\n".join(lines) + "\n")
        return path


def _floats(text: str | None) -> np.ndarray | None:
    if text is None:
        return None
    return np.array([float(v) if v is not None else math.nan for v in json.loads(text)],
                    dtype=float)


def _record(row) -> EvalRecord:
    (id_, study, run_id, model, _key, nin, nout, inputs, outputs, status, error, stdout, stderr,
     wall, started, finished, host, pid, eval_id, attempts) = row
    return EvalRecord(id_, study, run_id, model, tuple(json.loads(nin)), tuple(json.loads(nout)),
                      cast(np.ndarray, _floats(inputs)),  # the inputs column is NOT NULL
                      _floats(outputs), status, error, stdout, stderr, wall,
                      started, finished, host, pid, eval_id, attempts)


def open_store(store: Store | str | os.PathLike | None) -> Store | None:
    """A Store from a path, an existing Store, or None."""
    if store is None or isinstance(store, Store):
        return store
    return Store(store)
