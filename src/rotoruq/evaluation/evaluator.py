"""The Evaluator: one gate through which every method evaluates a model.

``Evaluator(model, store=..., executor=...)`` is itself a Model (``names_in``, ``names_out``,
``__call__``, ``evaluate`` -> :class:`~rotoruq.model.EvalBatch`), so any method can
be handed an Evaluator instead of the raw model. For a batch it

1. looks every row up in the store (exact match on the float64 bytes of the point, or within
   ``tolerance``) and reuses what is there;
2. evaluates only the missing rows (each distinct point once) through the executor:
   vectorized internal models in chunks (several per worker, so progress and crash safety
   have a fine grain), external models (:class:`~rotoruq.evaluation.external.ExternalModel`)
   one task per evaluation;
3. commits each result to the store as soon as its task finishes (inside
   :meth:`Evaluator.deferred_writes`, at most every ``seconds``: a Markov chain's thousands of
   small batches then cost one transaction a second, not one each);
4. returns the whole batch, in order, with failures reported per row.

A study killed at any point and run again therefore resumes: finished evaluations are read
back, never repeated (inside ``deferred_writes``, those of its last ``seconds`` are run again).

A model whose evaluations also give gradients (``evaluate_gradient``: an external driver with
``gradients="analytic"``) has them stored the same way, one row per point and run under the
model's identity with ``#gradient`` appended (outputs: the m values, then the m x d gradient,
row by row), so a resumed gradient-based method (NL2SOL, mean value, FORM) does not ask the
driver again either.
"""

from __future__ import annotations

import math
import os
import time
import uuid
import weakref
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._docs import fill_doc
from .._progress import Phase, bar_on_terminal
from ..errors import EvaluationError, ModelShapeError, ParameterError
from ..model import EVALUATE_BATCH_DOC, EvalBatch, Gradient, Model, evaluate, has_gradient
from .executors import Executor, make_executor
from .external import RunResult, _abort_message
from .identity import model_identity
from .progress import Progress
from .store import NewRecord, Store, canonical_keys, open_store

__all__ = ["Evaluator", "EvalStats", "model_identity"]


#: fewest points of a chunk of a vectorized model on one process (the model's per-call cost
#: is paid once for a small batch; larger batches still commit in four chunks)
MIN_CHUNK = 16


@dataclass(frozen=True, eq=False)
class EvalStats:
    """What the last :meth:`Evaluator.evaluate` call did.

    Attributes
    ----------
    n_samples : int
        Rows asked for.
    n_reused : int
        Rows found in the store.
    n_evaluations : int
        Distinct points run (model evaluations spent).
    n_duplicates : int
        Rows that repeated another row of the batch.
    n_failed : int
        Rows that failed.
    wall_time : float
        Seconds the call took.
    stored_wall_time : float
        Seconds the reused rows took when they were first run (as the store recorded them),
        so a cost measured on a batch served from the store is still the model's cost.
    """

    n_samples: int
    n_reused: int
    n_evaluations: int
    n_duplicates: int
    n_failed: int
    wall_time: float
    stored_wall_time: float = 0.0


class _ChunkTask:
    """Evaluate a chunk of rows of a vectorized model (runs in a worker)."""

    def __init__(self, model):
        self.model = model

    def __call__(self, x: np.ndarray) -> EvalBatch:
        return evaluate(self.model, x)


class _ExternalTask:
    """Run one external evaluation (runs in a worker)."""

    def __init__(self, model):
        self.model = model

    def __call__(self, task) -> RunResult:
        x, eval_id = task
        return self.model.run_one(x, eval_id)


class Evaluator:
    """Store-backed, parallel evaluation of a model; itself a Model.

    Only the model's own failures become failed rows. A fault of the infrastructure (a killed
    pool worker, a lost Dask worker) that the executor cannot recover from raises
    :class:`~rotoruq.errors.InfrastructureError`, and a storage fault
    :class:`~rotoruq.errors.StoreError`; in both cases the evaluations finished before it stay
    in the store, so running again evaluates only the missing points.

    Parameters
    ----------
    model : any Model (``names_in``, ``names_out``, ``__call__``); an object with
        ``run_one(x, eval_id)`` (an ExternalModel) is run one evaluation per task.
    store : a :class:`~rotoruq.evaluation.store.Store`, a path to its SQLite file, or None.
    executor : "serial", "processes" (all cores), "processes:N", "dask", "dask:ADDRESS", or an
        :class:`~rotoruq.evaluation.executors.Executor`.
    study : name that groups the evaluations in the store (reuse happens within a study).
    run_id : label of this run in the store (default: a random id).
    tolerance : reuse stored points within ``|x - x_s| <= tolerance * max(1, |x_s|)``;
        None reuses exact matches only.
    chunk_size : rows per task for vectorized models (default: about four chunks per worker).
    progress : None (a bar on a terminal for runs longer than 2 s), True or False.
    model_id : override the text identifying the model in the store.
    reuse_failed : also reuse stored failures (default: failed points are run again).
    """

    def __init__(
        self,
        model: Model,
        *,
        store: Store | str | os.PathLike | None = None,
        executor: str | Executor = "serial",
        study: str = "default",
        run_id: str | None = None,
        tolerance: float | None = None,
        chunk_size: int | None = None,
        progress: bool | None = None,
        model_id: str | None = None,
        reuse_failed: bool = False,
    ):
        self.model = model
        self.names_in = tuple(model.names_in)
        self.names_out = tuple(model.names_out)
        self.store = open_store(store)
        self._owns_executor = not isinstance(executor, Executor)
        self.executor = make_executor(executor)
        if self._owns_executor:
            self._finalizer = weakref.finalize(self, self.executor.close)
        self.study = str(study)
        self.run_id = run_id or uuid.uuid4().hex[:12]
        if tolerance is not None and not tolerance >= 0:
            raise ParameterError(f"tolerance must be >= 0, got {tolerance}")
        self.tolerance = tolerance
        if chunk_size is not None and chunk_size < 1:
            raise ParameterError(f"chunk_size must be >= 1, got {chunk_size}")
        self.chunk_size = chunk_size
        self.progress = progress
        self.model_id = model_id or model_identity(model)
        self.reuse_failed = bool(reuse_failed)
        self.external = callable(getattr(model, "run_one", None))
        self.last_stats: EvalStats | None = None
        self._next_eval = 1
        self._defer: float | None = None  # deferred_writes: seconds between commits
        self._unstored = False  # unstored: an in-process model evaluated directly
        self._pending: list[NewRecord] = []
        self._committed = 0.0

    def __repr__(self) -> str:
        return (f"Evaluator({self.model!r}, store={self.store!r}, executor={self.executor!r}, "
                f"study={self.study!r})")

    def __getattr__(self, name):
        # forward an analytic gradient so has_gradient(evaluator) is truthful: stored when it
        # comes with the values of one run (evaluate_gradient), else the model's own
        model = self.__dict__.get("model")
        if name in ("gradient", "evaluate_gradient") and model is not None \
                and has_gradient(model):
            if callable(getattr(model, "evaluate_gradient", None)):
                if name == "evaluate_gradient":
                    return self._evaluate_gradient
                return lambda x: self._evaluate_gradient(x).gradient
            if name == "gradient":
                return model.gradient
        raise AttributeError(name)

    def _evaluate_gradient(self, x: np.ndarray) -> Gradient:
        """Values and gradients at ``x`` (n, d): stored ones reused, the others from the
        model's ``evaluate_gradient`` one point at a time, each committed as it finishes."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        n, d, m = x.shape[0], len(self.names_in), len(self.names_out)
        values, grads = np.full((n, m), np.nan), np.full((n, m, d), np.nan)
        failures: dict[int, str] = {}
        key = self.model_id + "#gradient"
        names = self.names_out + tuple(f"d{r}/d{p}" for r in self.names_out
                                       for p in self.names_in)
        done = np.zeros(n, dtype=bool)
        if self.store is not None and n:
            found = self.store.lookup(x, study=self.study, model=key, tolerance=self.tolerance,
                                      statuses=("ok",))
            for i, rec in enumerate(found):
                if rec is not None and rec.outputs is not None \
                        and rec.outputs.shape == (m + m * d,):
                    values[i], grads[i] = rec.outputs[:m], rec.outputs[m:].reshape(m, d)
                    done[i] = True
        keys = canonical_keys(x) if n else []
        groups: dict[str, list[int]] = {}
        for i in np.flatnonzero(~done).tolist():
            groups.setdefault(keys[i], []).append(i)
        model: Any = self.model  # evaluate_gradient: an optional member
        for rows in groups.values():
            started, t0 = time.time(), time.perf_counter()
            got = model.evaluate_gradient(x[rows[0]][None, :])
            wall = time.perf_counter() - t0
            v, g = np.asarray(got.values, dtype=float)[0], np.asarray(got.gradient, dtype=float)[0]
            reason = got.failures.get(0)
            if reason is None and not (np.all(np.isfinite(v)) and np.all(np.isfinite(g))):
                reason = "non-finite value or gradient"
            if self.store is not None:
                out = None if reason is not None else np.concatenate([v, g.ravel()])
                self.store.add([NewRecord(x[rows[0]], out, "failed" if reason else "ok", reason,
                                          wall_time=wall, started=started)],
                               study=self.study, model=key, names_in=self.names_in,
                               names_out=names, run_id=self.run_id)
            for i in rows:
                values[i], grads[i] = v, g
                if reason is not None:
                    failures[i] = reason
        return Gradient(values=values, gradient=grads, steps=np.zeros((n, d)),
                        n_evaluations=len(groups), failures=failures)

    def close(self) -> None:
        """Shut down the executor if this Evaluator created it, and close the store."""
        if self._owns_executor:
            self.executor.close()
        if self.store is not None:
            self.store.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.evaluate(x).values

    # -------------------------------------------------------------------------------------------

    def _eval_ids(self, k: int) -> list[str]:
        start = self._next_eval
        if self.store is not None:
            start = max(start, self.store.max_id() + 1)
        self._next_eval = start + k
        return [str(start + j) for j in range(k)]

    @fill_doc(evaluate_batch=EVALUATE_BATCH_DOC)
    def evaluate(self, x: np.ndarray) -> EvalBatch:
        """Evaluate a batch ``x`` (n, d); returns values (n, m) and per-row failures.

        Stored evaluations of the same model and study are reused; the others run on the
        executor and are stored as they finish.

        %(evaluate_batch)s
        """
        t0 = time.perf_counter()
        x = np.atleast_2d(np.asarray(x, dtype=float))
        d, m = len(self.names_in), len(self.names_out)
        if x.ndim != 2 or x.shape[1] != d:
            raise ModelShapeError(f"expected points of shape (n, {d}) for inputs "
                                  f"{self.names_in}, got {x.shape}")
        n = x.shape[0]
        if self._unstored and not self.external:
            batch = evaluate(self.model, x)
            self.last_stats = EvalStats(n, 0, n, 0, len(batch.failures),
                                        time.perf_counter() - t0)
            return batch
        values = np.full((n, m), np.nan)
        failures: dict[int, str] = {}
        done = np.zeros(n, dtype=bool)
        reused, stored_wall = 0, 0.0
        if self.store is not None and n:
            statuses = ("ok", "recovered", "failed") if self.reuse_failed else ("ok", "recovered")
            found = self.store.lookup(x, study=self.study, model=self.model_id,
                                      tolerance=self.tolerance, statuses=statuses)
            for i, rec in enumerate(found):
                if rec is None:
                    continue
                if rec.outputs is not None and rec.outputs.shape == (m,):
                    values[i] = rec.outputs
                if rec.status == "failed":
                    failures[i] = f"(stored) {rec.error}"
                done[i] = True
                reused += 1
                stored_wall += float(rec.wall_time or 0.0)
        # distinct missing points, each with the rows that share it
        keys = canonical_keys(x) if n else []
        groups: dict[str, list[int]] = {}
        for i in np.flatnonzero(~done).tolist():
            groups.setdefault(keys[i], []).append(i)
        firsts = [rows[0] for rows in groups.values()]
        row_groups = list(groups.values())
        if firsts:
            self._run(x, firsts, row_groups, values, failures)
        for i in range(n):  # non-finite values without a reason (stored NaN outputs)
            if i not in failures and not np.all(np.isfinite(values[i])):
                failures[i] = "non-finite response"
        self.last_stats = EvalStats(n, reused, len(firsts), int((~done).sum()) - len(firsts),
                                    len(failures), time.perf_counter() - t0, stored_wall)
        return EvalBatch(values, failures)

    def _run(self, x, firsts, row_groups, values, failures) -> int:
        pts = x[firsts]
        if self.external:
            ids = self._eval_ids(len(firsts))
            tasks = [(pts[j], ids[j]) for j in range(len(firsts))]
            spans = [[j] for j in range(len(firsts))]
            fn: _ExternalTask | _ChunkTask = _ExternalTask(self.model)
            policy = getattr(self.model, "failure_policy", None)
            abort = getattr(policy, "kind", policy) == "abort"
        else:
            workers = max(1, self.executor.n_workers)
            # one process: no chunk below MIN_CHUNK points (a chain's batch of a few points
            # in one call of the model, not one per point or two)
            size = self.chunk_size or max(1 if workers > 1 else MIN_CHUNK,
                                          math.ceil(len(firsts) / (4 * workers)))
            spans = [list(range(s, min(s + size, len(firsts))))
                     for s in range(0, len(firsts), size)]
            tasks = [pts[s[0] : s[-1] + 1] for s in spans]
            fn = _ChunkTask(self.model)
            abort = False
        # the CLI draws the "evaluations" phase itself on a terminal (one bar for every phase)
        own = self.progress if self.progress is not None else (
            False if bar_on_terminal() else None)
        bar = Progress(len(firsts), enabled=own)
        # not a chain's step of a few points: thousands of those make no phase of their own
        phase = Phase("evaluations", len(firsts)) if (
            self.external or len(firsts) > MIN_CHUNK) else None
        n_failed = 0
        outcomes = self.executor.run(fn, tasks)
        try:
            for out in outcomes:
                span = spans[out.index]
                recs, fails = self._records(out, pts, span)
                self._commit(recs)
                for j, rec in zip(span, recs, strict=True):
                    for i in row_groups[j]:
                        if rec.outputs is not None:
                            values[i] = rec.outputs
                        if j in fails:
                            failures[i] = fails[j]
                n_failed += len(fails)
                bar.update(len(span))
                if phase is not None:
                    phase.advance(len(span))
                if abort and fails:
                    j = next(iter(fails))
                    r = out.value if isinstance(out.value, RunResult) else None
                    if r is None:
                        raise EvaluationError(f"evaluation failed: {fails[j]}; "
                                              "failure_policy='abort'")
                    raise EvaluationError(_abort_message(r, self.names_in, pts[j]))
        finally:
            outcomes.close()  # cancels tasks not yet started
            bar.close()
            if phase is not None:
                phase.close()
        return n_failed

    @contextmanager
    def deferred_writes(self, seconds: float = 1.0) -> Iterator[Evaluator]:
        """Within the block, commit finished evaluations to the store at most every
        ``seconds`` (wall time) instead of after every task, and everything left on leaving
        it (also on an error). For callers that evaluate a few points at a time thousands
        of times (a Markov chain on the model itself): the store stays the record of what
        was computed, a process killed inside the block loses at most its last ``seconds``
        of evaluations. Points evaluated but not yet committed are not found by lookups
        (they are evaluated again, to the same values).

        Parameters
        ----------
        seconds : float, optional
            Longest time between two commits, wall seconds (default 1).
        """
        outer = self._defer
        self._defer = float(seconds)
        self._committed = time.monotonic()
        try:
            yield self
        finally:
            self._defer = outer
            self._commit_pending()

    @contextmanager
    def unstored(self) -> Iterator[Evaluator]:
        """Within the block, an in-process model is evaluated directly, in this process:
        no point is looked up in the store, none is written to it (an external solver
        keeps both: its evaluations cost seconds each, and a killed run resumes them).

        For a Markov chain on the model itself: its thousands of proposals of a few points
        each are not worth keeping. A point of the built-in rotor costs less CPU than its
        lookup and its row in the store, a proposal is never asked for again (the chains are
        a function of the seed alone, so a run killed inside the block runs them again to
        the same numbers), and the values are the model's own, bit for bit, with or
        without the store. What a chain's step needs is kept elsewhere: the emulator's
        design, the start and the predictive runs go through the store outside the block.

        Examples
        --------
        >>> import pathlib, tempfile
        >>> import numpy as np
        >>> from rotoruq.model import FunctionModel
        >>> ev = Evaluator(FunctionModel(lambda x: x**2, ["a"], ["y"]),
        ...                store=pathlib.Path(tempfile.mkdtemp()) / "store.sqlite")
        >>> with ev.unstored():
        ...     ev(np.array([[2.0]])).tolist()
        [[4.0]]
        >>> ev.store.count()
        0
        """
        outer = self._unstored
        self._unstored = True
        try:
            yield self
        finally:
            self._unstored = outer

    def _commit(self, recs: list[NewRecord]) -> None:
        if self.store is None:
            return
        if self._defer is None:
            self.store.add(recs, study=self.study, model=self.model_id,
                           names_in=self.names_in, names_out=self.names_out,
                           run_id=self.run_id)
            return
        self._pending.extend(recs)
        if time.monotonic() - self._committed >= self._defer:
            self._commit_pending()

    def _commit_pending(self) -> None:
        recs, self._pending = self._pending, []
        self._committed = time.monotonic()
        if recs and self.store is not None:
            self.store.add(recs, study=self.study, model=self.model_id,
                           names_in=self.names_in, names_out=self.names_out,
                           run_id=self.run_id)

    def _records(self, out, pts, span) -> tuple[list[NewRecord], dict[int, str]]:
        """Store records and failure reasons (by position in ``pts``) of one task outcome."""
        m = len(self.names_out)
        fails: dict[int, str] = {}
        recs: list[NewRecord] = []
        if self.external:
            j = span[0]
            r = out.value
            if out.error is not None or not isinstance(r, RunResult):
                fails[j] = f"task error: {out.error}"
                recs.append(NewRecord(pts[j], None, "failed", fails[j], wall_time=out.wall_time))
                return recs, fails
            if r.status == "failed":
                fails[j] = r.error or "failed"
            ok = r.status == "ok"
            recs.append(NewRecord(pts[j], None if r.status == "failed" else r.values, r.status,
                                  r.error, None if ok else r.stdout, None if ok else r.stderr,
                                  r.wall_time, r.started, r.eval_id, r.attempts))
            return recs, fails
        started = time.time() - out.wall_time
        per_row = out.wall_time / max(1, len(span))
        if out.error is not None:
            for j in span:
                fails[j] = f"model raised: {out.error.splitlines()[0]}"
                recs.append(NewRecord(pts[j], None, "failed", out.error, wall_time=per_row,
                                      started=started))
            return recs, fails
        batch: EvalBatch = out.value
        vals = np.asarray(batch.values, dtype=float).reshape(len(span), m)
        for k, j in enumerate(span):
            reason = batch.failures.get(k)
            if reason is None and not np.all(np.isfinite(vals[k])):
                reason = "non-finite response"
            if reason is not None:
                fails[j] = reason
                recs.append(NewRecord(pts[j], vals[k], "failed", reason, wall_time=per_row,
                                      started=started))
            else:
                recs.append(NewRecord(pts[j], vals[k], "ok", wall_time=per_row,
                                      started=started))
        return recs, fails


def as_evaluator(model: Model, **kwargs: Any) -> Evaluator:
    """``model`` itself if it is already an Evaluator, else ``Evaluator(model, **kwargs)``.

    Parameters
    ----------
    model : Model
        Any model, or an Evaluator (returned as it is, ``kwargs`` ignored).
    **kwargs
        Keyword arguments of :class:`Evaluator` (``store``, ``executor``, ``study``, ...).
    """
    return model if isinstance(model, Evaluator) else Evaluator(model, **kwargs)


__all__.append("as_evaluator")

