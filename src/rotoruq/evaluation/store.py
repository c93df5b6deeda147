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

Storage faults are never raw ``sqlite3`` errors: a full disk, a read-only file or folder and a
damaged file raise :class:`~rotoruq.errors.StoreError` (:class:`~rotoruq.errors.StoreCorruptError`
for damage) with a one-line message naming the file and what to do. Opening a store runs
SQLite's ``PRAGMA quick_check``; :func:`repair_store` moves a damaged store aside and keeps
the evaluations that can still be read.
"""

from __future__ import annotations

import functools
import json
import math
import os
import shutil
import socket
import sqlite3
import threading
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

from ..errors import ParameterError, StoreCorruptError, StoreError

__all__ = ["Store", "EvalRecord", "NewRecord", "StoreRepair", "canonical_key", "open_store",
           "repair_store", "store_error"]

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
CREATE TABLE IF NOT EXISTS computed (
    kind      TEXT NOT NULL,
    key       TEXT NOT NULL,
    value     BLOB NOT NULL,
    finished  REAL NOT NULL,
    PRIMARY KEY (kind, key)
);
"""

_COLUMNS = ("study", "run_id", "model", "key", "names_in", "names_out", "inputs", "outputs",
            "status", "error", "stdout", "stderr", "wall_time", "started", "finished", "host",
            "pid", "eval_id", "attempts")

STATUSES = ("ok", "failed", "recovered")


_RESUME = "run the same command again (finished evaluations are saved)"
_SIDE_FILES = ("-wal", "-shm", "-journal")


def store_error(path: str | os.PathLike, exc: BaseException) -> StoreError:
    """The :class:`~rotoruq.errors.StoreError` saying what ``exc`` (an ``sqlite3`` error or an
    ``OSError`` met while using the store at ``path``) means and what to do.

    Examples
    --------
    >>> import sqlite3
    >>> err = store_error("e.db", sqlite3.DatabaseError("file is not a database"))
    >>> str(err).startswith("e.db: the evaluation store is damaged (file is not a database)")
    True
    """
    if isinstance(exc, StoreError):
        return exc
    name = getattr(exc, "sqlite_errorname", "") or ""
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    low = text.lower()
    errno = getattr(exc, "errno", None)
    if name.startswith(("SQLITE_CORRUPT", "SQLITE_NOTADB")) or "malformed" in low \
            or "not a database" in low:
        return StoreCorruptError(
            path, f"the evaluation store is damaged ({text})",
            "move it aside with `rotoruq repair RESULTS` (or rename the file) and run again: "
            "the evaluations it held are kept where they can be read, the others are run "
            "again")
    if name == "SQLITE_FULL" or errno in (28, 27) or "disk is full" in low \
            or "no space" in low or "too large" in low:
        return StoreError(path, f"no room to write the evaluation store ({text})",
                          f"free disk space (or raise the file-size limit), then {_RESUME}")
    if name.startswith(("SQLITE_READONLY", "SQLITE_CANTOPEN", "SQLITE_PERM", "SQLITE_AUTH")) \
            or errno in (1, 13, 30) or "readonly" in low or "read-only" in low \
            or "unable to open" in low or "permission" in low:
        return StoreError(path, f"cannot write the evaluation store ({text}: a read-only "
                                "file, folder or file system?)",
                          "make the folder writable or choose another results folder "
                          "(--out), then run again")
    if name.startswith("SQLITE_IOERR") or "i/o error" in low or isinstance(exc, OSError):
        return StoreError(path, f"cannot read or write the evaluation store ({text}: a full "
                                "disk, a file-size limit or a failing disk?)",
                          f"free disk space or check the disk, then {_RESUME}")
    return StoreError(path, f"the evaluation store failed ({type(exc).__name__}: {text})",
                      f"check the file and the disk, then {_RESUME}")


_CHECKED: set[tuple] = set()  # store files found intact by this process: (path, dev, inode)


def _guarded(method):
    """Turn ``sqlite3`` and ``OSError`` failures of a Store method into a StoreError."""

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        try:
            return method(self, *args, **kwargs)
        except StoreError:
            raise
        except (sqlite3.Error, OSError) as exc:
            raise store_error(self.path, exc) from exc

    return wrapper


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
    return json.dumps(np.ravel(np.asarray(a, dtype=float)).tolist())


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
    """One stored evaluation.

    Attributes
    ----------
    id : int
        The row's id (commit order).
    study : str
        The study it belongs to.
    run_id : str
        Label of the run that made it.
    model : str
        The text identifying the model.
    names_in, names_out : tuple of str
        The model's input and response names.
    inputs : ndarray of shape (d,)
        The point.
    outputs : ndarray of shape (m,) or None
        The responses; None for a failure without recovered values.
    status : str
        ``"ok"``, ``"failed"`` or ``"recovered"``.
    error : str or None
        Why it failed.
    stdout, stderr : str or None
        What an external solver printed (the start and the end, capped).
    wall_time : float or None
        Seconds the evaluation took.
    started : float or None
        When it started (Unix time).
    finished : float
        When it was committed (Unix time).
    host : str or None
        The machine that ran it.
    pid : int or None
        The process that committed it.
    eval_id : str or None
        An external solver's evaluation id.
    attempts : int or None
        Runs it took (retries included).
    """

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

    The store opens one connection per process and thread and reopens after a fork, so one
    Store object may be shared with worker processes.

    Parameters
    ----------
    path : database file (created with its directory when missing).
    timeout : seconds a writer waits for a lock before retrying (busy_timeout).
    retries : how many times a locked write is retried (with growing back-off) before raising.
    check : run SQLite's ``PRAGMA quick_check`` on an existing file (once per file and
        process; about 0.3 s for 100,000 evaluations) and raise
        :class:`~rotoruq.errors.StoreCorruptError` when it finds damage.

    Raises
    ------
    StoreError
        For any storage fault (disk full, read-only, damaged file), on opening or later, with
        a one-line message naming the file and what to do; never a raw ``sqlite3`` error.
    """

    def __init__(self, path: str | os.PathLike, *, timeout: float = 30.0, retries: int = 20,
                 check: bool = True):
        self.path = Path(path)
        self.timeout = float(timeout)
        self.retries = int(retries)
        self._local = threading.local()
        try:
            self._open(check)
        except BaseException:
            self.close()
            raise

    @_guarded
    def _open(self, check: bool) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        info = self.path.stat() if self.path.is_file() else None
        # once per file and process: a study opens its store for every step
        key = (str(self.path.resolve()), info.st_dev, info.st_ino) if info else None
        if check and info is not None and info.st_size and key not in _CHECKED:
            problems = [r[0] for r in self._con().execute("PRAGMA quick_check").fetchall()]
            if problems == ["ok"]:
                _CHECKED.add(cast(tuple, key))
            else:
                raise StoreCorruptError(
                    self.path, "the evaluation store is damaged (integrity check: "
                    f"{'; '.join(str(p) for p in problems[:2])})",
                    "move it aside with `rotoruq repair RESULTS` (or rename the file) and run "
                    "again")

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
            try:
                con.execute(f"PRAGMA busy_timeout = {int(self.timeout * 1000)}")
                for attempt in range(self.retries + 1):
                    try:
                        con.execute("PRAGMA journal_mode = WAL")
                        break
                    except sqlite3.OperationalError as exc:
                        msg = str(exc).lower()
                        if ("locked" not in msg and "busy" not in msg) or attempt == self.retries:
                            raise
                        time.sleep(0.05)
                # WAL + NORMAL: a committed transaction survives the death of the process
                # (SIGKILL); only an OS crash or power cut can lose the last commits.
                con.execute("PRAGMA synchronous = NORMAL")
            except BaseException:
                con.close()
                raise
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

    @_guarded
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
        """Commit finished evaluations in one transaction; returns their ids.

        Parameters
        ----------
        records : iterable of NewRecord
            The evaluations: inputs, outputs, status, error text, captured output, timing.
        study : str
            The study the evaluations belong to (reuse happens within a study).
        model : str
            The text identifying the model (its identity digest).
        names_in, names_out : sequence of str
            The model's input and response names (the columns of the records).
        run_id : str, optional
            Label of the run that made them.

        Returns
        -------
        list of int
            The new rows' ids, in the order of ``records``.
        """
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
            # one statement for the batch; inside the transaction the ids are consecutive
            con.executemany(sql, rows)
            last = int(con.execute("SELECT last_insert_rowid()").fetchone()[0])
            return list(range(last - len(rows) + 1, last + 1))

        return self._write(ins)

    # -- reading ---------------------------------------------------------------------------

    @_guarded
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

        Parameters
        ----------
        x : array_like of shape (n, d) or (d,)
            The points, in the model's input order.
        study : str
            The study to look in.
        model : str
            The model's identity text.
        tolerance : float, optional
            Relative tolerance of a match (default None: exact matches only).
        statuses : sequence of str, optional
            The statuses that count (default ``("ok", "recovered")``: failures are run
            again).
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

    @_guarded
    def records(
        self, *, study: str | None = None, model: str | None = None, status: str | None = None,
        run_id: str | None = None,
    ) -> list[EvalRecord]:
        """Stored evaluations, oldest first, filtered by the given fields.

        Parameters
        ----------
        study, model, status, run_id : str, optional
            Keep only the evaluations with this study, model identity, status (``"ok"``,
            ``"failed"``, ...) or run id (default: any).
        """
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

    @_guarded
    def count(self, *, study: str | None = None, status: str | None = None) -> int:
        """Number of stored evaluations (optionally of one study / status).

        Parameters
        ----------
        study, status : str, optional
            Count only the evaluations of this study, with this status (default: any).
        """
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

    @_guarded
    def put_computed(self, kind: str, key: str, value: bytes) -> None:
        """Keep ``value``, a piece computed once and reused by the identity of its setup
        (``kind``, e.g. "self_check", and ``key``, a digest of everything its answer depends
        on); an earlier value under the same key is replaced.

        Parameters
        ----------
        kind : str
            What the value is (``"self_check"``, ...).
        key : str
            The digest of the setup it belongs to.
        value : bytes
            The value, serialised by the caller.
        """
        def ins(con):
            con.execute("INSERT OR REPLACE INTO computed (kind, key, value, finished) "
                        "VALUES (?, ?, ?, ?)", (kind, key, sqlite3.Binary(value), time.time()))

        self._write(ins)

    @_guarded
    def get_computed(self, kind: str, key: str) -> bytes | None:
        """The value :meth:`put_computed` kept under (``kind``, ``key``), or None.

        Parameters
        ----------
        kind : str
            What the value is.
        key : str
            The digest of its setup.
        """
        row = self._con().execute("SELECT value FROM computed WHERE kind = ? AND key = ?",
                                  (kind, key)).fetchone()
        return None if row is None else bytes(row[0])

    @_guarded
    def max_id(self) -> int:
        """Largest evaluation id so far (0 for an empty store)."""
        row = self._con().execute("SELECT MAX(id) FROM evaluations").fetchone()
        return int(row[0] or 0)

    @_guarded
    def export_tabular(
        self, path: str | os.PathLike, *, study: str | None = None, model: str | None = None,
        interface: str = "NO_ID", include_failed: bool = False,
    ) -> Path:
        """Write Dakota's annotated tabular format: ``%eval_id interface <vars> <responses>``.

        One row per stored evaluation (in commit order) of a single model's variables and
        responses; failed evaluations are left out unless ``include_failed`` (then written as
        ``nan``). Values are written with 17 significant digits. Returns the path.

        Parameters
        ----------
        path : str or PathLike
            The file to write.
        study, model : str, optional
            Export only this study's / model's evaluations (needed when the store holds
            models with different variables or responses).
        interface : str, optional
            The interface column's text (default ``"NO_ID"``, Dakota's).
        include_failed : bool, optional
            Also write failed evaluations, as ``nan`` (default False).
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


@dataclass(frozen=True, eq=False)
class StoreRepair:
    """What :func:`repair_store` did.

    path : the store file.
    status : "ok" (intact, left alone), "missing" (no file) or "rebuilt" (damaged: moved
        aside, a new store holds the evaluations that could be read).
    problem : why the store was found damaged (None unless rebuilt).
    quarantined : where the damaged file went (None unless rebuilt).
    n_salvaged : evaluations copied into the new store.
    """

    path: Path
    status: str
    problem: str | None = None
    quarantined: Path | None = None
    n_salvaged: int = 0


def _salvage(path: Path) -> list[tuple]:
    """The rows of ``evaluations`` that can still be read from a damaged store (rowid ranges
    around unreadable pages are skipped). Works on a copy whose header is made to agree with
    the file's length (a truncated file is otherwise unreadable as a whole)."""
    import struct
    import tempfile

    try:
        data = bytearray(path.read_bytes())
    except OSError:
        return []
    if len(data) < 100 or not data.startswith(b"SQLite format 3\0"):
        return []
    size = struct.unpack(">H", data[16:18])[0]
    size = 65536 if size == 1 else size
    if size < 512 or size & (size - 1):
        return []
    del data[len(data) // size * size :]
    data[28:32] = struct.pack(">I", len(data) // size)
    data[18:20] = b"\x01\x01"  # rollback-journal format: no -wal/-shm needed to read it
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / "salvage.db"
        copy.write_bytes(bytes(data))
        return _salvage_rows(copy)


def _salvage_rows(path: Path) -> list[tuple]:
    try:
        con = sqlite3.connect(f"file:{path}?mode=ro", uri=True, isolation_level=None)
    except sqlite3.Error:
        return []
    rows: list[tuple] = []
    q = (f"SELECT {', '.join(_COLUMNS)} FROM evaluations WHERE id > ? AND id <= ? "
         "ORDER BY id")
    try:
        top = None
        for probe in ("SELECT MAX(id) FROM evaluations",
                      "SELECT seq FROM sqlite_sequence WHERE name = 'evaluations'"):
            try:
                top = int(con.execute(probe).fetchone()[0] or 0)
                break
            except (sqlite3.Error, TypeError):
                continue
        for lo in range(0, top or 0, 256):
            try:
                rows += con.execute(q, (lo, lo + 256)).fetchall()
            except sqlite3.Error:  # a damaged page: read the block row by row
                for i in range(lo, lo + 256):
                    try:
                        rows += con.execute(q, (i, i + 1)).fetchall()
                    except sqlite3.Error:
                        continue
    finally:
        con.close()
    good = []
    for r in rows:  # keep rows whose values parse: a damaged page may still read as text
        try:
            if r[8] not in STATUSES:
                continue
            json.loads(r[4]), json.loads(r[5]), _floats(r[6]), _floats(r[7])
        except (TypeError, ValueError):
            continue
        good.append(r)
    return good


def repair_store(path: str | os.PathLike) -> StoreRepair:
    """Check the store at ``path``; if it is damaged, move it aside and rebuild it from the
    evaluations that can still be read.

    The damaged file (with its ``-wal``/``-shm`` companions) is renamed to
    ``<name>.damaged-<UTC time>`` in the same folder, never deleted; evaluations that are lost
    are simply run again by the next run. An intact store is left alone.

    Parameters
    ----------
    path : the store file (``<results>/evaluations.db`` for a study).

    Returns
    -------
    StoreRepair

    Raises
    ------
    StoreError
        When the folder cannot be written (the damaged file cannot be moved aside).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "e.db"
    >>> _ = p.write_bytes(b"not a database" * 100)
    >>> r = repair_store(p)
    >>> r.status, r.n_salvaged, r.quarantined.name.startswith("e.db.damaged-")
    ('rebuilt', 0, True)
    >>> repair_store(p).status
    'ok'
    """
    path = Path(path)
    if not path.exists():
        return StoreRepair(path, "missing")
    try:
        Store(path).close()
        return StoreRepair(path, "ok")
    except StoreCorruptError as exc:
        problem = exc.problem
    rows = _salvage(path)
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    aside = path.with_name(f"{path.name}.damaged-{stamp}")
    k = 1
    while aside.exists():
        k += 1
        aside = path.with_name(f"{path.name}.damaged-{stamp}-{k}")
    try:
        shutil.move(path, aside)
        for side in _SIDE_FILES:
            extra = path.with_name(path.name + side)
            if extra.exists():
                shutil.move(extra, aside.with_name(aside.name + side))
    except OSError as exc:
        raise store_error(path, exc) from exc
    st = Store(path)
    sql = (f"INSERT INTO evaluations ({', '.join(_COLUMNS)}) "
           f"VALUES ({', '.join('?' * len(_COLUMNS))})")
    st._write(lambda con: [con.execute(sql, r) for r in rows])
    st.close()
    return StoreRepair(path, "rebuilt", problem, aside, len(rows))


def open_store(store: Store | str | os.PathLike | None) -> Store | None:
    """A Store from a path, an existing Store, or None."""
    if store is None or isinstance(store, Store):
        return store
    return Store(store)
