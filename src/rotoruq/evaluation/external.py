"""External solvers as Models, through Dakota's fork contract.

For each input point, :class:`ExternalModel`

1. makes a work directory ``<workdir>/<name>.<eval_id>`` (tagged per evaluation, so runs
   can go in parallel), copies or links the listed files into it and fills the templates;
2. writes the Dakota parameters file (standard or aprepro format) there;
3. runs the command with the work directory as current directory, **without a shell**
   (``subprocess`` with an argument list), so parameter values can never be interpreted by
   one; ``driver`` becomes ``driver params.in results.out``, and a list command may place
   ``{params}``, ``{results}``, ``{workdir}`` and ``{eval_id}`` itself;
4. waits at most ``timeout`` seconds (then kills the whole process group);
5. reads the results file; a missing file, a non-zero exit status, a ``fail`` marker or a
   malformed file is a failed evaluation, whose stdout/stderr are kept.

Failure policies (``failure_policy``):

- ``"continue"`` (default): the row is NaN and the reason goes to ``EvalBatch.failures``, as for
  any Model; the batch goes on.
- ``"abort"``: stop the study at the first failure (:class:`~rotoruq.errors.EvaluationError`);
  evaluations already finished are kept in the store.
- ``"retry:N"``: run a failed evaluation up to N more times, then continue.
- ``{"recover": [v1, ..., vm]}``: return these values for a failed evaluation (stored with
  status ``recovered`` and the error text).
"""

from __future__ import annotations

import itertools
import os
import shlex
import shutil
import signal
import subprocess
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import EvaluationError, InputFileError, ParameterError
from .dakota_files import read_results, write_parameters
from .model import EvalBatch
from .templates import fill_template_file

__all__ = ["ExternalModel", "RunResult", "FailurePolicy", "parse_failure_policy"]

_TAIL = 20_000  # characters of stdout/stderr kept per failed evaluation


@dataclass(frozen=True)
class FailurePolicy:
    """Parsed failure policy: kind in {"continue", "abort", "retry", "recover"}."""

    kind: str = "continue"
    retries: int = 0
    recover: tuple[float, ...] | None = None


def parse_failure_policy(policy, n_out: int) -> FailurePolicy:
    """Turn ``"abort"``, ``"continue"``, ``"retry:N"`` or ``{"recover": values}`` into a
    :class:`FailurePolicy`."""
    if isinstance(policy, FailurePolicy):
        return policy
    if isinstance(policy, Mapping):
        if set(policy) != {"recover"}:
            raise ParameterError(f"a failure policy mapping must be {{'recover': values}}, "
                                 f"got keys {sorted(policy)}")
        vals = tuple(float(v) for v in np.ravel(policy["recover"]))
        if len(vals) != n_out:
            raise ParameterError(f"recover needs {n_out} values (one per response), "
                                 f"got {len(vals)}")
        return FailurePolicy("recover", 0, vals)
    if policy in ("abort", "continue"):
        return FailurePolicy(policy)
    if isinstance(policy, str) and policy.startswith("retry:"):
        try:
            n = int(policy.split(":", 1)[1])
        except ValueError:
            n = -1
        if n < 1:
            raise ParameterError(f"retry policy must be 'retry:N' with N >= 1, got {policy!r}")
        return FailurePolicy("retry", n)
    raise ParameterError(f"unknown failure policy {policy!r}; use 'continue', 'abort', "
                         "'retry:N' or {'recover': values}")


@dataclass(frozen=True)
class RunResult:
    """Outcome of one external evaluation.

    values : (m,) responses (NaN when failed and not recovered).
    error : failure reason, None on success.
    status : "ok", "failed" or "recovered".
    stdout, stderr : solver output (tails), filled on failure only.
    """

    values: np.ndarray
    error: str | None
    status: str
    stdout: str | None
    stderr: str | None
    wall_time: float
    started: float
    eval_id: str
    attempts: int
    workdir: str | None


def _tail(b: bytes | str | None) -> str:
    if b is None:
        return ""
    s = b.decode(errors="replace") if isinstance(b, bytes) else b
    return s if len(s) <= _TAIL else "...\n" + s[-_TAIL:]


class ExternalModel:
    """A Model that runs an external command once per input point.

    Parameters
    ----------
    command : str or list of str
        The driver. A string is split like a shell would (``shlex``) but never run by one.
        Without ``{params}`` in it, the parameters and results file names are appended.
        The command runs in the work directory; words that name existing files relative to
        the current directory (a driver script) are made absolute when the model is made.
    names_in, names_out : variable and response labels (the labels of the Dakota files).
    workdir : base directory of the work directories (default ``./rotoruq_work``).
    name : work directory name; each evaluation gets ``<name>.<eval_id>`` (tag) unless
        ``tag=False`` (then one directory, emptied before each run: not for parallel use).
    template_files : files filled with :func:`~rotoruq.evaluation.templates.fill_template`
        into the work directory (same base name).
    copy_files, link_files : files or directories copied / symlinked into the work directory.
    parameters_format : "standard" or "aprepro".
    parameters_file, results_file : file names inside the work directory.
    timeout : seconds per run (None: no limit).
    failure_policy : "continue", "abort", "retry:N" or {"recover": values}.
    keep_workdirs : True (keep all), False (remove all) or "failed" (keep failed ones only).
    env : extra environment variables for the command.
    analysis_components : (component, driver) pairs written to the parameters file.
    asv : active set code written for every response (1: values only).
    """

    def __init__(
        self,
        command: str | Sequence[str],
        names_in: Sequence[str],
        names_out: Sequence[str],
        *,
        workdir: str | os.PathLike = "rotoruq_work",
        name: str = "eval",
        tag: bool = True,
        template_files: Sequence[str | os.PathLike] = (),
        copy_files: Sequence[str | os.PathLike] = (),
        link_files: Sequence[str | os.PathLike] = (),
        parameters_format: str = "standard",
        parameters_file: str = "params.in",
        results_file: str = "results.out",
        timeout: float | None = None,
        failure_policy="continue",
        keep_workdirs: bool | str = "failed",
        env: Mapping[str, str] | None = None,
        analysis_components: Sequence[tuple[str, str]] = (),
        asv: int = 1,
    ):
        command = shlex.split(command) if isinstance(command, str) else [str(c) for c in command]
        if not command:
            raise ParameterError("command is empty")
        # the command runs inside the work directory: words naming files that exist relative
        # to the caller's directory (the driver script, say) are made absolute now
        self.command = [str(Path(c).absolute()) if ("{" not in c and not Path(c).is_absolute()
                                                    and Path(c).exists()) else c
                        for c in command]
        self.names_in = tuple(names_in)
        self.names_out = tuple(names_out)
        if len(set(self.names_in)) != len(self.names_in):
            raise ParameterError(f"duplicate input names in {self.names_in}")
        self.workdir = Path(workdir).absolute()
        self.name = name
        self.tag = bool(tag)
        self.template_files = [Path(p).absolute() for p in template_files]
        self.copy_files = [Path(p).absolute() for p in copy_files]
        self.link_files = [Path(p).absolute() for p in link_files]
        for p in (*self.template_files, *self.copy_files, *self.link_files):
            if not p.exists():
                raise ParameterError(f"file {str(p)!r} listed for the work directory does "
                                     "not exist")
        if parameters_format not in ("standard", "aprepro"):
            raise ParameterError(f"parameters_format must be 'standard' or 'aprepro', got "
                                 f"{parameters_format!r}")
        self.parameters_format = parameters_format
        self.parameters_file = parameters_file
        self.results_file = results_file
        self.timeout = None if timeout is None else float(timeout)
        self.policy = parse_failure_policy(failure_policy, len(self.names_out))
        if keep_workdirs not in (True, False, "failed"):
            raise ParameterError(f"keep_workdirs must be True, False or 'failed', got "
                                 f"{keep_workdirs!r}")
        self.keep_workdirs = keep_workdirs
        self.env = dict(env or {})
        self.analysis_components = tuple(analysis_components)
        self.asv = int(asv)
        self._counter = itertools.count(1)
        self._lock = threading.Lock()

    # identity used by the store to tell models apart
    @property
    def identity(self) -> str:
        return "external:" + " ".join(self.command)

    @property
    def failure_policy(self) -> FailurePolicy:
        return self.policy

    def __getstate__(self):
        d = self.__dict__.copy()
        d.pop("_lock", None)
        d.pop("_counter", None)
        return d

    def __setstate__(self, d):
        self.__dict__.update(d)
        self._lock = threading.Lock()
        self._counter = itertools.count(1)

    def __repr__(self) -> str:
        return f"ExternalModel({' '.join(self.command)!r}, in={self.names_in})"

    # -- one evaluation ------------------------------------------------------------------------

    def _argv(self, wd: Path, eval_id: str) -> list[str]:
        subs = {"{params}": self.parameters_file, "{results}": self.results_file,
                "{workdir}": str(wd), "{eval_id}": eval_id}
        argv = []
        for arg in self.command:
            for k, v in subs.items():
                arg = arg.replace(k, v)
            argv.append(arg)
        if not any("{params}" in a for a in self.command):
            argv += [self.parameters_file, self.results_file]
        return argv

    def _prepare(self, wd: Path, values: Mapping[str, float]) -> None:
        if wd.exists():
            shutil.rmtree(wd)
        wd.mkdir(parents=True)
        for p in self.copy_files:
            if p.is_dir():
                shutil.copytree(p, wd / p.name, symlinks=True)
            else:
                shutil.copy2(p, wd / p.name)
        for p in self.link_files:
            (wd / p.name).symlink_to(p)
        for p in self.template_files:
            fill_template_file(p, wd / p.name, values)

    def _run_once(self, x: np.ndarray, eval_id: str) -> tuple[np.ndarray | None, str | None,
                                                            str, str, Path]:
        wd = self.workdir / (f"{self.name}.{eval_id}" if self.tag else self.name)
        values = dict(zip(self.names_in, (float(v) for v in x), strict=True))
        self._prepare(wd, values)
        write_parameters(wd / self.parameters_file, values, list(self.names_out), asv=self.asv,
                         analysis_components=self.analysis_components, eval_id=eval_id,
                         format=self.parameters_format)
        argv = self._argv(wd, eval_id)
        env = {**os.environ, **self.env} if self.env else None
        try:
            proc = subprocess.Popen(argv, cwd=wd, stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, env=env,
                                    shell=False, start_new_session=True)
        except OSError as exc:
            return None, f"could not start {argv[0]!r}: {exc}", "", "", wd
        try:
            out, err = proc.communicate(timeout=self.timeout)
        except subprocess.TimeoutExpired:
            _kill_group(proc)
            out, err = proc.communicate()
            return (None, f"timed out after {self.timeout:g} s (process group killed)",
                    _tail(out), _tail(err), wd)
        except BaseException:
            _kill_group(proc)
            raise
        out_s, err_s = _tail(out), _tail(err)
        if proc.returncode != 0:
            sig = (f" (signal {signal.Signals(-proc.returncode).name})"
                   if proc.returncode < 0 and -proc.returncode in signal.valid_signals() else "")
            last = err_s.strip().splitlines()[-1:] if err_s.strip() else []
            why = f": {last[0][:200]}" if last else ""
            return (None, f"driver exited with status {proc.returncode}{sig}{why}", out_s, err_s,
                    wd)
        try:
            res = read_results(wd / self.results_file, names=self.names_out,
                               asv=[1] * len(self.names_out))
        except InputFileError as exc:
            return None, f"bad results file: {exc}", out_s, err_s, wd
        if res.failed:
            return None, "driver reported failure (fail marker in results file)", out_s, err_s, wd
        return res.values, None, out_s, err_s, wd

    def next_eval_id(self) -> str:
        with self._lock:
            return str(next(self._counter))

    def run_one(self, x: np.ndarray, eval_id: str | int | None = None) -> RunResult:
        """Run one evaluation (with retries per the policy) and return its :class:`RunResult`.

        Never raises for a solver failure: the failure is described in the result.
        """
        eval_id = self.next_eval_id() if eval_id is None else str(eval_id)
        x = np.asarray(x, dtype=float).ravel()
        if x.shape != (len(self.names_in),):
            raise ParameterError(f"expected {len(self.names_in)} inputs {self.names_in}, got "
                                 f"shape {x.shape}")
        started = time.time()
        t0 = time.perf_counter()
        attempts = 0
        tries = 1 + (self.policy.retries if self.policy.kind == "retry" else 0)
        while True:
            attempts += 1
            vals, error, out, err, wd = self._run_once(x, eval_id)
            if error is None or attempts >= tries:
                break
        wall = time.perf_counter() - t0
        keep = self.keep_workdirs is True or (self.keep_workdirs == "failed" and error)
        if not keep and wd.exists():
            shutil.rmtree(wd, ignore_errors=True)
        m = len(self.names_out)
        if error is None:
            return RunResult(np.asarray(vals, float), None, "ok", None, None, wall, started,
                             eval_id, attempts, str(wd) if keep else None)
        if attempts > 1:
            error = f"{error} (after {attempts} attempts)"
        where = f" [work directory {wd}]" if keep else ""
        if self.policy.kind == "recover":
            return RunResult(np.array(self.policy.recover, float), error + where, "recovered",
                             out, err, wall, started, eval_id, attempts, str(wd) if keep else None)
        return RunResult(np.full(m, np.nan), error + where, "failed", out, err, wall, started,
                         eval_id, attempts, str(wd) if keep else None)

    # -- Model protocol ----------------------------------------------------------------------

    def evaluate(self, x: np.ndarray) -> EvalBatch:
        """Run every row in turn (use :class:`~rotoruq.evaluation.evaluator.Evaluator` for
        parallel runs and a store). With the "abort" policy the first failure raises."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        values = np.full((len(x), len(self.names_out)), np.nan)
        failures: dict[int, str] = {}
        for i, row in enumerate(x):
            r = self.run_one(row)
            values[i] = r.values
            if r.status == "failed":
                if self.policy.kind == "abort":
                    raise EvaluationError(_abort_message(r, self.names_in, row))
                failures[i] = r.error or "failed"
        return EvalBatch(values, failures)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.evaluate(x).values


def _abort_message(r: RunResult, names_in, x) -> str:
    point = ", ".join(f"{n}={float(v)!r}" for n, v in zip(names_in, np.ravel(x), strict=True))
    msg = f"evaluation {r.eval_id} failed at ({point}): {r.error}; failure_policy='abort'"
    if r.stderr:
        msg += "\n--- stderr (tail) ---\n" + r.stderr[-2000:]
    return msg


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    try:
        proc.kill()
    except ProcessLookupError:
        pass
