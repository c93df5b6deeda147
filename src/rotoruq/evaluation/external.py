"""External solvers as Models, through Dakota's fork contract.

For each input point, :class:`ExternalModel`

1. makes a work directory ``<workdir>/<name>.<pid>.<token>.<eval_id>`` (``pid`` of the
   process running the evaluation, ``token`` random per model, so that evaluations, worker
   processes and concurrent runs over one base folder never share a directory), copies or
   links the listed files into it and fills the templates. The base folder is opened
   without following a link and the evaluation's folder made exclusively and held by a
   descriptor (:class:`~rotoruq.safety.SafeFolder`); every file rotoruq puts there is
   created through it with ``O_EXCL | O_NOFOLLOW``, the driver starts in the folder held
   and the results file is read without following a link: a symlink planted at any of
   these names fails the evaluation, naming it;
2. writes the Dakota parameters file (standard or aprepro format) there;
3. runs the command with the work directory as current directory, **without a shell**
   (argument list), in a session of its own; ``driver`` becomes
   ``driver params.in results.out``, and a list command may place ``{params}``,
   ``{results}``, ``{workdir}`` and ``{eval_id}`` itself;
4. waits at most ``timeout`` seconds; on timeout, on interruption and after the driver exits,
   every process it left behind is killed, grandchildren that left its process group
   included (see :mod:`rotoruq.evaluation.process_tree`). stdout and stderr go to
   ``rotoruq.stdout`` / ``rotoruq.stderr`` in the work directory, capped at ``output_cap``
   bytes plus the last 64 KiB; the last 8 KiB of each are kept with a failed evaluation;
5. reads the results file. A failed evaluation is any of: the driver could not start, ran
   past the timeout, exited with a non-zero status or a signal, wrote no results file, a
   results file that is not UTF-8 or is malformed, a ``fail`` marker, or a non-finite value
   (NaN, inf). Every failure goes through the failure policy.

Values are read **by position**, as Dakota reads them: a results file whose labels are not
the response names (Dakota's own test drivers label every value ``g``) is read in order, with
one warning per model naming the labels that disagree (a permutation of the names is put in
order); a file with the wrong *number* of values is a failed evaluation naming the file and
line.

Analytic gradients (``gradients="analytic"``): the model then has ``gradient(x)`` and
``evaluate_gradient(x)``, each ONE run of the driver per point with active set code 3
(value and gradient) for every response and the derivative variables in the DVV block; the
results file holds the values, then one ``[ g_1 ... g_p ]`` per response (p derivative
variables). A driver that writes no gradients when asked fails the evaluation, naming the
results file and line. Methods reach them through :func:`rotoruq.model.model_gradient`.

Failure policies (``failure_policy``):

- ``"continue"`` (default): the row is NaN and the reason goes to ``EvalBatch.failures``, as for
  any Model; the batch goes on.
- ``"abort"``: stop the study at the first failure (:class:`~rotoruq.errors.EvaluationError`);
  evaluations already finished are kept in the store.
- ``"retry:N"``: run a failed evaluation up to N more times, then continue.
- ``{"recover": [v1, ..., vm]}``: return these values for a failed evaluation (stored with
  status ``recovered`` and the error text).

Names: input and response labels, the model ``name`` and the file names must be
non-empty, without white space, control characters, path separators, ``..``, braces, ``=``
or quotes (:func:`~rotoruq.evaluation.dakota_files.check_label`). rotoruq deletes only work
directories it made: per-evaluation directories it created itself, and with
``WorkDirectory(tag=False)`` a directory holding its ``.rotoruq-workdir`` marker.

Options: where the evaluations run is a :class:`WorkDirectory` (Dakota's ``work_directory``),
the files exchanged with the driver a :class:`FileContract` (``parameters_file``,
``results_file``, ``aprepro``, the active set vector, ``analysis_components``).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import logging
import os
import shlex
import shutil
import signal
import stat
import threading
import time
import uuid
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._docs import fill_doc
from .._options import fields_of, legacy_keywords, legacy_mapping, with_fields
from ..errors import EvaluationError, InputFileError, ParameterError, RotoruqError
from ..model import EVALUATE_BATCH_DOC, EvalBatch, Gradient
from ..safety import ForeignFileError, SafeFolder, UnsafePathError
from .dakota_files import check_label, decode_text, format_parameters, parse_results, read_text
from .identity import file_sha256
from .process_tree import run_process_tree
from .templates import check_template, fill_template

__all__ = ["ExternalModel", "WorkDirectory", "FileContract", "RunResult", "FailurePolicy",
           "parse_failure_policy", "GRADIENTS", "warn_once", "LEGACY_KEYWORDS"]

log = logging.getLogger(__name__)

#: the ``gradients`` an external model takes: finite differences of its values (rotoruq's, in
#: the methods), or the driver's own through the file contract
GRADIENTS = ("finite_difference", "analytic")

_TAIL = 8192  # bytes of stdout/stderr kept with a failed evaluation
STDOUT_FILE, STDERR_FILE = "rotoruq.stdout", "rotoruq.stderr"
MARKER = ".rotoruq-workdir"  # in a tag=False work directory: rotoruq made it, may empty it
MAX_RESULTS_BYTES = 256 * 2**20  # a results file larger than this is a failure, not read


@dataclass(frozen=True, eq=False)
class WorkDirectory:
    """Where each evaluation of an :class:`ExternalModel` runs, what is put there, and what is
    kept (Dakota's ``work_directory`` with ``named``, ``directory_tag``, ``directory_save``,
    ``copy_files`` and ``link_files``; rotoruq fills templates too).

    Parameters
    ----------
    base : str or path-like
        Base directory of the work directories (default ``./rotoruq_work``, relative to the
        current directory when the model is made); created if missing, never deleted.
    name : str
        Name (prefix) of the work directories (Dakota's ``named``): each evaluation gets
        ``<base>/<name>.<pid>.<token>.<eval_id>`` while ``tag`` is True.
    tag : bool
        Dakota's ``directory_tag``, default True: one directory per evaluation. False: one
        directory ``<base>/<name>``, emptied before each run (not for parallel use), which
        rotoruq only empties if it made it (it holds a ``.rotoruq-workdir`` marker).
    keep_workdirs : True, False or "failed"
        Dakota's ``directory_save``: keep every work directory (True), none (False), or the
        failed evaluations' only ("failed", the default).
    template_files : sequence of paths
        Files filled with :func:`~rotoruq.evaluation.templates.fill_template` into the work
        directory (same base name); read, checked and hashed once, when the model is made.
    copy_files, link_files : sequences of paths
        Files or directories copied / symbolically linked into the work directory.

    Examples
    --------
    >>> wd = WorkDirectory("runs", name="case", keep_workdirs=True)
    >>> wd.tag, wd.copy_files
    (True, ())
    >>> m = ExternalModel(["solver"], ["a"], ["f"], workdir=wd)  # nothing runs yet
    >>> m.workdir.name, m.name, m.keep_workdirs
    ('runs', 'case', True)
    """

    base: str | os.PathLike = "rotoruq_work"
    name: str = "eval"
    tag: bool = True
    keep_workdirs: bool | str = "failed"
    template_files: Sequence[str | os.PathLike] = ()
    copy_files: Sequence[str | os.PathLike] = ()
    link_files: Sequence[str | os.PathLike] = ()


@dataclass(frozen=True, eq=False)
class FileContract:
    """The files an :class:`ExternalModel` and its driver exchange: Dakota's
    ``parameters_file``, ``results_file`` and parameters format (``aprepro``), and what the
    parameters file asks for (active set vector, analysis components).

    Parameters
    ----------
    parameters_format : "standard" or "aprepro"
        Format of the parameters file (Dakota's default standard format, or ``aprepro``).
    parameters_file, results_file : str
        File names inside the work directory (default ``params.in`` and ``results.out``).
    asv : int
        Active set code written for every response, 0..7 (1, the default: values only); a
        gradient run (``gradients="analytic"``) writes 3.
    analysis_components : sequence of (component, driver) pairs
        Dakota's ``analysis_components``, written to the parameters file.

    Examples
    --------
    >>> FileContract(parameters_format="aprepro").results_file
    'results.out'
    >>> m = ExternalModel(["solver"], ["a"], ["f"], contract=FileContract(parameters_file="in.txt"))
    >>> m.parameters_file, m.results_file
    ('in.txt', 'results.out')
    """

    parameters_format: str = "standard"
    parameters_file: str = "params.in"
    results_file: str = "results.out"
    asv: int = 1
    analysis_components: Sequence[tuple[str, str]] = ()


#: The flat keyword arguments of ExternalModel before its option records (deprecated, accepted
#: for one release): old name -> (parameter, record class name, field).
LEGACY_KEYWORDS: Mapping[str, tuple[str, str, str]] = {
    **legacy_mapping("workdir", WorkDirectory, fields_of(WorkDirectory)[1:]),
    **legacy_mapping("contract", FileContract),
}


@dataclass(frozen=True)
class FailurePolicy:
    """Parsed failure policy: kind in {"continue", "abort", "retry", "recover"}."""

    kind: str = "continue"
    retries: int = 0
    recover: tuple[float, ...] | None = None


def parse_failure_policy(policy: str | Mapping[str, Any] | FailurePolicy,
                         n_out: int) -> FailurePolicy:
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


@dataclass(frozen=True, eq=False)
class RunResult:
    """Outcome of one external evaluation.

    values : (m,) responses (NaN when failed and not recovered).
    error : failure reason, None on success.
    status : "ok", "failed" or "recovered".
    stdout, stderr : solver output (last 8 KiB), filled on failure only.
    gradient : (m, d) derivatives of the responses by the inputs when the run asked for them
        (columns of inputs outside the derivative variables NaN); None otherwise.
    note : a remark on a successful run worth one warning per model (the results file's
        labels differ from the response names and were read by position), else None.
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
    gradient: np.ndarray | None = None
    note: str | None = None


_WARNED: set[str] = set()  # notes already logged by this process (one warning per model)
_WARNED_LOCK = threading.Lock()


def warn_once(note: str | None) -> None:
    """Log ``note`` (a :class:`RunResult`'s remark, e.g. results read by position) as a
    warning the first time this process sees it: one line per model, not per evaluation."""
    if not note:
        return
    with _WARNED_LOCK:
        if note in _WARNED:
            return
        _WARNED.add(note)
    log.warning("%s", note)


def _tail(b: bytes | None) -> str:
    if not b:
        return ""
    s = b[-_TAIL:].decode(errors="replace")
    return s if len(b) <= _TAIL else "...\n" + s


def _content(path: Path) -> dict:
    """``{"name", "sha256"}`` of a file; of a directory, the digest of its listing (relative
    paths sorted, each with the sha256 of its bytes or its symbolic link's target)."""
    if not path.is_dir():
        return {"name": path.name, "sha256": file_sha256(path)}
    lines = []
    for root, dirs, files in os.walk(path):
        dirs.sort()
        for f in sorted(files + [d for d in dirs if Path(root, d).is_symlink()]):
            q = Path(root, f)
            rel = q.relative_to(path).as_posix()
            if q.is_symlink() and not q.is_file():
                lines.append(f"{rel}\0link\0{os.readlink(q)}")
            else:
                lines.append(f"{rel}\0{file_sha256(q)}")
    digest = hashlib.sha256("\n".join(lines).encode("utf-8", "surrogateescape")).hexdigest()
    return {"name": path.name, "sha256": digest, "files": len(lines)}


def _file_name(name, what: str) -> str:
    check_label(name, what)
    if name in (".", ".."):
        raise ParameterError(f"{what} may not be {name!r}")
    return name


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
    workdir : :class:`WorkDirectory`, or a path: the base directory of the work directories
        (``WorkDirectory(base=path)``; default ``./rotoruq_work``). Where each evaluation
        runs, the files put there (templates, copied and linked files) and which directories
        are kept.
    contract : :class:`FileContract`
        The parameters and results files (names, ``parameters_format``), the active set code
        and the analysis components (default: Dakota's standard ``params.in`` and
        ``results.out``, values only).
    timeout : seconds per run (None: no limit).
    failure_policy : "continue", "abort", "retry:N" or {"recover": values}.
    env : extra environment variables for the command.
    output_cap : bytes of the start of stdout and of stderr kept in the work directory files
        (the last 64 KiB are kept too); default 10 MiB.
    gradients : "finite_difference" (default: the model has no gradient; methods difference
        its values) or "analytic": the driver computes them (Dakota's ``analytic_gradients``);
        ``gradient(x)`` and ``evaluate_gradient(x)`` then run it once per point with ASV 3.
    derivative_variables : the inputs written to the DVV block of a gradient run (default all
        ``names_in``); the gradient columns of the others are NaN.
    **legacy : the flat keyword arguments of rotoruq 0.1, fields of the records
        (:data:`LEGACY_KEYWORDS`): ``name``, ``tag``, ``keep_workdirs``, ``template_files``,
        ``copy_files``, ``link_files`` (of :class:`WorkDirectory`) and ``parameters_format``,
        ``parameters_file``, ``results_file``, ``asv``, ``analysis_components`` (of
        :class:`FileContract`): accepted for one release with a ``DeprecationWarning`` (a flat
        keyword overrides that field of the record given).

    Examples
    --------
    A driver run in ``runs/case.<pid>.<token>.<eval_id>``, reading an aprepro parameters file
    (``driver.py`` is the user's script; making the model runs nothing):

    >>> import rotoruq as rq
    >>> solver = rq.ExternalModel(
    ...     ["python", "driver.py"], ["a", "b"], ["f"],
    ...     workdir=rq.WorkDirectory("runs", name="case", keep_workdirs=True),
    ...     contract=rq.FileContract(parameters_format="aprepro"),
    ...     timeout=600, failure_policy="retry:2")
    >>> solver.workdir.name, solver.parameters_format, solver.policy.retries
    ('runs', 'aprepro', 2)
    """

    def __init__(
        self,
        command: str | Sequence[str],
        names_in: Sequence[str],
        names_out: Sequence[str],
        *,
        workdir: str | os.PathLike | WorkDirectory = "rotoruq_work",
        contract: FileContract | None = None,
        timeout: float | None = None,
        failure_policy: str | Mapping[str, Any] | FailurePolicy = "continue",
        env: Mapping[str, str] | None = None,
        output_cap: int = 10 * 2**20,
        gradients: str = "finite_difference",
        derivative_variables: Sequence[str] | None = None,
        **legacy: Any,
    ):
        flat = legacy_keywords("ExternalModel", legacy, LEGACY_KEYWORDS)
        if not isinstance(workdir, WorkDirectory):
            if not isinstance(workdir, str | os.PathLike):
                raise ParameterError(f"workdir must be a path or a WorkDirectory, got "
                                     f"{workdir!r}")
            workdir = WorkDirectory(workdir)
        wd_opts = with_fields(workdir, WorkDirectory, flat.get("workdir"), "workdir")
        files = with_fields(contract, FileContract, flat.get("contract"), "contract")
        name, tag, keep_workdirs = wd_opts.name, wd_opts.tag, wd_opts.keep_workdirs
        template_files, copy_files, link_files = (
            wd_opts.template_files, wd_opts.copy_files, wd_opts.link_files)
        parameters_format, parameters_file, results_file = (
            files.parameters_format, files.parameters_file, files.results_file)
        asv, analysis_components = files.asv, files.analysis_components
        command = shlex.split(command) if isinstance(command, str) else [str(c) for c in command]
        if not command:
            raise ParameterError("command is empty")
        # the command runs inside the work directory: words naming files that exist relative
        # to the caller's directory (the driver script, say) are made absolute now
        self.command = [str(Path(c).absolute()) if ("{" not in c and not Path(c).is_absolute()
                                                    and Path(c).exists()) else c
                        for c in command]
        self.names_in = tuple(check_label(n, "input name") for n in names_in)
        self.names_out = tuple(check_label(n, "response name") for n in names_out)
        if len(set(self.names_in)) != len(self.names_in):
            raise ParameterError(f"duplicate input names in {self.names_in}")
        if len(set(self.names_out)) != len(self.names_out):
            raise ParameterError(f"duplicate response names in {self.names_out}")
        self.workdir = Path(wd_opts.base).absolute()
        # a link the user made is their choice; one planted later is refused (_make_workdir)
        self._workdir_linked = self.workdir.is_symlink()
        self.name = _file_name(name, "model name")
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
        self.parameters_file = _file_name(parameters_file, "parameters_file")
        self.results_file = _file_name(results_file, "results_file")
        placed = [self.parameters_file, self.results_file, STDOUT_FILE, STDERR_FILE, MARKER]
        placed += [p.name for p in (*self.template_files, *self.copy_files, *self.link_files)]
        clash = sorted({n for n in placed if placed.count(n) > 1})
        if clash:
            raise ParameterError(f"two files would have the same name {clash} in the work "
                                 "directory (templates, copied and linked files, "
                                 f"{self.parameters_file}, {self.results_file}, "
                                 f"{STDOUT_FILE}, {STDERR_FILE})")
        # templates are read once: the text filled is the text hashed in identity()
        self._templates = []
        for p in self.template_files:
            text = read_text(p, "template file")
            check_template(text, self.names_in, p)
            self._templates.append((p, text))
        self.timeout = None if timeout is None else float(timeout)
        if self.timeout is not None and not self.timeout > 0:
            raise ParameterError(f"timeout must be > 0 seconds, got {timeout!r}")
        self.policy = parse_failure_policy(failure_policy, len(self.names_out))
        if keep_workdirs not in (True, False, "failed"):
            raise ParameterError(f"keep_workdirs must be True, False or 'failed', got "
                                 f"{keep_workdirs!r}")
        self.keep_workdirs = keep_workdirs
        self.env = {str(k): str(v) for k, v in (env or {}).items()}
        self.analysis_components = tuple((str(c), str(d)) for c, d in analysis_components)
        for c, d in self.analysis_components:
            check_label(c, "analysis component")
            check_label(d, "analysis driver name")
        self.asv = int(asv)
        if not 0 <= self.asv <= 7:
            raise ParameterError(f"asv must be in 0..7, got {asv!r}")
        self.output_cap = int(output_cap)
        if self.output_cap < 0:
            raise ParameterError(f"output_cap must be >= 0 bytes, got {output_cap!r}")
        if gradients not in GRADIENTS:
            raise ParameterError(f"gradients must be one of {', '.join(map(repr, GRADIENTS))}, "
                                 f"got {gradients!r}")
        self.gradients = gradients
        dvv = self.names_in if derivative_variables is None else tuple(derivative_variables)
        unknown = [n for n in dvv if n not in self.names_in]
        if unknown or len(set(dvv)) != len(dvv) or not dvv:
            raise ParameterError(f"derivative_variables must be distinct inputs among "
                                 f"{list(self.names_in)}, got {list(dvv)}")
        self.derivative_variables = tuple(n for n in self.names_in if n in dvv)
        if gradients == "analytic":
            self.gradient = self._gradient
            self.evaluate_gradient = self._evaluate_gradient
        self._token = uuid.uuid4().hex[:12]
        self._identity: dict | None = None
        self._counter = itertools.count(1)
        self._lock = threading.Lock()

    def identity(self) -> dict:
        """Everything that can change an answer, as a JSON-serializable dict.

        The command (a word naming an existing file, and the program found on ``PATH`` for
        the first word, becomes ``{"path", "sha256"}`` of its bytes, so editing the driver
        script changes the identity), the sha256 of every template, copied and linked file
        (directories: of all files inside, by relative path), the names, parameters format,
        file names, analysis components, ASV, extra environment, failure policy and, for
        ``gradients="analytic"``, the gradients and derivative variables. Not
        included: the timeout, work directories and output cap (they do not change a
        successful answer). Files are hashed on the first call only.
        """
        if self._identity is None:
            command: list[str | dict[str, str]] = []
            for i, word in enumerate(self.command):
                path = Path(word) if "{" not in word else None
                if path is not None and i == 0 and os.sep not in word:
                    found = shutil.which(word, path=self.env.get("PATH", os.environ.get("PATH")))
                    path = Path(found) if found else None
                if path is not None and path.is_file():
                    command.append({"arg": word, "path": str(path.absolute()),
                                    "sha256": file_sha256(path)})
                else:
                    command.append(word)
            p = self.policy
            ident = {
                "class": f"{type(self).__module__}.{type(self).__qualname__}",
                "command": command,
                "names_in": list(self.names_in),
                "names_out": list(self.names_out),
                "templates": [{"name": q.name,
                               "sha256": hashlib.sha256(t.encode("utf-8")).hexdigest()}
                              for q, t in self._templates],
                "copy_files": [_content(q) for q in self.copy_files],
                "link_files": [_content(q) for q in self.link_files],
                "parameters_format": self.parameters_format,
                "parameters_file": self.parameters_file,
                "results_file": self.results_file,
                "analysis_components": [list(c) for c in self.analysis_components],
                "asv": self.asv,
                "env": dict(sorted(self.env.items())),
                "failure_policy": {"kind": p.kind, "retries": p.retries,
                                   "recover": None if p.recover is None else list(p.recover)},
            }
            if self.gradients != "finite_difference":  # absent by default: stored runs stay
                ident["gradients"] = self.gradients
                ident["derivative_variables"] = list(self.derivative_variables)
            json.dumps(ident)  # JSON-serializable by construction; fail here if not
            self._identity = ident
        return self._identity

    @property
    def failure_policy(self) -> FailurePolicy:
        """What a failed run becomes (``continue``, ``abort``, ``retry:N`` or ``recover``),
        parsed from the ``failure_policy`` argument."""
        return self.policy

    def __getstate__(self):
        d = self.__dict__.copy()
        for k in ("_lock", "_counter", "gradient", "evaluate_gradient"):
            d.pop(k, None)
        return d

    def __setstate__(self, d):
        self.__dict__.update(d)
        self._lock = threading.Lock()
        self._counter = itertools.count(1)
        if self.__dict__.get("gradients") == "analytic":
            self.gradient = self._gradient
            self.evaluate_gradient = self._evaluate_gradient

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

    def _make_workdir(self, eval_id: str, previous: Path | None) -> _Place:
        """A fresh, empty work directory made by this call, held by descriptors; ``previous``
        (the directory of the previous attempt of this evaluation, made by this model) is
        removed first. Never removes a directory rotoruq did not make, never makes or
        writes one through a symlink planted at the base or in it after the model was made:
        the base is opened without following a link (unless the user's own link, there when
        the model was made) and everything below it is made through its descriptor."""
        base = SafeFolder(self.workdir, follow=self.__dict__.get("_workdir_linked", True))
        try:
            if previous is not None:
                try:
                    base.remove_tree(previous.name)
                except OSError:
                    pass  # kept: the new attempt has a directory of its own
            if not self.tag:
                return _Place(self.workdir / self.name, base, self._fixed_workdir(base))
            name = f"{self.name}.{os.getpid()}.{self._token}.{eval_id}"
            for _ in range(100):
                try:
                    # exclusive: a name taken (by anything, a planted link included) is
                    # never reused
                    return _Place(self.workdir / name, base, base.folder(name, new=True))
                except FileExistsError:
                    name = f"{self.name}.{os.getpid()}.{self._token}.{eval_id}." \
                           f"{uuid.uuid4().hex[:12]}"
            raise FileExistsError(f"no free work directory name {self.name}.* in "
                                  f"{self.workdir}")
        except BaseException:
            base.close()
            raise

    def _fixed_workdir(self, base: SafeFolder) -> SafeFolder:
        """The one work directory of ``tag=False``, emptied (only if rotoruq made it)."""
        wd = self.workdir / self.name
        st = base.lstat(self.name)
        if st is not None:
            ours = False
            if stat.S_ISDIR(st.st_mode):
                with base.folder(self.name, create=False) as old:
                    mark = old.lstat(MARKER)
                    ours = mark is not None and stat.S_ISREG(mark.st_mode)
            if not ours:
                raise ParameterError(
                    f"work directory {wd} exists and was not made by rotoruq (no {MARKER} "
                    "marker in it): rotoruq will not empty it; remove it or choose another "
                    "name")
            base.remove_tree(self.name)
        folder = base.folder(self.name, new=True)
        try:
            folder.write(MARKER, f"made by rotoruq for ExternalModel {self.name!r}\n".encode())
        except BaseException:
            folder.close()
            raise
        return folder

    def _prepare(self, folder: SafeFolder, values: Mapping[str, float]) -> None:
        for p in self.copy_files:
            _copy_into(folder, p)
        for p in self.link_files:
            folder.symlink(p.name, p)
        for p, text in self._templates:
            folder.write(p.name, fill_template(text, values, path=p).encode("utf-8"))

    def _run_once(self, x: np.ndarray, eval_id: str, place: _Place, gradient: bool = False
                  ) -> _Attempt:
        """One attempt in the (empty) work directory ``place``; with ``gradient``, values and
        gradients (ASV 3, the derivative variables in the DVV)."""
        values = dict(zip(self.names_in, (float(v) for v in x), strict=True))
        asv = 3 if gradient else self.asv
        wd, folder = place.path, place.folder
        streams: list[int] = []
        try:
            self._prepare(folder, values)
            text = format_parameters(values, list(self.names_out), asv=asv,
                                     analysis_components=self.analysis_components,
                                     eval_id=eval_id, format=self.parameters_format,
                                     dvv=list(self.derivative_variables))
            folder.write(self.parameters_file, text.encode("utf-8"))
            streams = [folder.create(STDOUT_FILE), folder.create(STDERR_FILE)]
        except (OSError, RotoruqError) as exc:
            for fd in streams:
                os.close(fd)
            return _Attempt(None, f"could not prepare the work directory: {_why(exc)}")
        argv = self._argv(wd, eval_id)
        env = {**os.environ, **self.env}
        try:
            run = run_process_tree(argv, cwd=folder.fd, env=env, timeout=self.timeout,
                                   stdout_path=streams[0], stderr_path=streams[1],
                                   cap=self.output_cap)
        except OSError as exc:
            return _Attempt(None, f"could not start {argv[0]!r}: {exc}")
        out_s, err_s = _tail(run.stdout), _tail(run.stderr)
        if run.timed_out:
            extra = f" and {run.leftovers} other processes" if run.leftovers else ""
            return _Attempt(None, f"timed out after {self.timeout:g} s (driver{extra} killed)",
                            out_s, err_s)
        if run.returncode != 0:
            rc = run.returncode
            sig = (f" (signal {signal.Signals(-rc).name})"
                   if rc < 0 and -rc in signal.valid_signals() else "")
            last = err_s.strip().splitlines()[-1:] if err_s.strip() else []
            why = f": {last[0][:200]}" if last else ""
            return _Attempt(None, f"driver exited with status {rc}{sig}{why}", out_s, err_s)
        m = len(self.names_out)
        results = wd / self.results_file
        try:
            data = folder.read(self.results_file, MAX_RESULTS_BYTES + 1)
            if len(data) > MAX_RESULTS_BYTES:
                return _Attempt(None, f"bad results file: more than {MAX_RESULTS_BYTES} "
                                "bytes (not read)", out_s, err_s)
            res = parse_results(decode_text(data, results, "Dakota results file"), results,
                                names_out=self.names_out, asv=[asv] * m,
                                n_dvv=len(self.derivative_variables), by_position=True)
        except FileNotFoundError:
            return _Attempt(None, f"bad results file: {InputFileError(results, None, 'a results file written by the driver', 'no file')}", out_s, err_s)  # noqa: E501
        except (UnsafePathError, ForeignFileError, OSError) as exc:
            return _Attempt(None, f"bad results file: {_why(exc)}", out_s, err_s)
        except InputFileError as exc:
            hint = ""
            if gradient:
                hint = (f" (gradients = \"analytic\": the driver is asked for values and "
                        f"gradients, ASV 3, and must write the {m} values, then {m} gradients "
                        f"'[ ... ]' of {len(self.derivative_variables)} entries each, by the "
                        f"derivative variables {', '.join(self.derivative_variables)})")
            return _Attempt(None, f"bad results file: {exc}{hint}", out_s, err_s)
        if res.failed:
            return _Attempt(None, "driver reported failure (fail marker in results file)",
                            out_s, err_s)
        bad = [f"{n}={v!r}" for n, v in zip(self.names_out, res.values.tolist(), strict=True)
               if not np.isfinite(v)]
        if bad:
            return _Attempt(None, f"non-finite response in results file: {', '.join(bad)}",
                            out_s, err_s)
        grad = None
        if gradient:
            assert res.gradients is not None  # read_results checked there are m of them
            grad = np.full((m, len(self.names_in)), np.nan)
            grad[:, [self.names_in.index(n) for n in self.derivative_variables]] = res.gradients
            if not np.all(np.isfinite(res.gradients)):
                return _Attempt(None, "non-finite gradient in results file", out_s, err_s)
        note = None
        if any(lab is not None for lab in res.names_out) and \
                tuple(res.names_out) != self.names_out:
            differ = [f"{lab or '(none)'} for {n}" for lab, n in
                      zip(res.names_out, self.names_out, strict=True) if lab != n]
            note = (f"the results files of {' '.join(self.command)!r} label the values "
                    f"{', '.join(differ)}; rotoruq reads them by position, as Dakota does "
                    "(check that the driver writes the responses in the order "
                    f"{', '.join(self.names_out)})")
        return _Attempt(res.values, None, out_s, err_s, grad, note)

    def next_eval_id(self) -> str:
        """The next evaluation id of this model object (``"1"``, ``"2"``, ...; thread-safe)."""
        with self._lock:
            return str(next(self._counter))

    def run_one(self, x: np.ndarray, eval_id: str | int | None = None, *,
                gradient: bool = False) -> RunResult:
        """Run one evaluation (with retries per the policy) and return its :class:`RunResult`;
        with ``gradient`` (a model with ``gradients="analytic"``), values and gradients.

        Never raises for a solver failure: the failure is described in the result.

        Parameters
        ----------
        x : array_like of shape (d,)
            The point, in ``names_in`` order.
        eval_id : str or int, optional
            The evaluation id written to the parameters file and in the work directory's
            name (default: :meth:`next_eval_id`).
        gradient : bool, optional
            Ask the driver for gradients too (ASV 3); needs ``gradients="analytic"``.
        """
        if gradient and self.gradients != "analytic":
            raise ParameterError(f"model {self.name!r} has gradients = {self.gradients!r}: "
                                 "its driver is not asked for gradients")
        eval_id = self.next_eval_id() if eval_id is None else str(eval_id)
        check_label(eval_id, "eval_id")
        x = np.asarray(x, dtype=float).ravel()
        if x.shape != (len(self.names_in),):
            raise ParameterError(f"expected {len(self.names_in)} inputs {self.names_in}, got "
                                 f"shape {x.shape}")
        started = time.time()
        t0 = time.perf_counter()
        attempts = 0
        tries = 1 + (self.policy.retries if self.policy.kind == "retry" else 0)
        wd = None
        place: _Place | None = None
        error: str | None
        while True:
            attempts += 1
            if place is not None:
                place.close()
            try:
                place = self._make_workdir(eval_id, wd)
            except (OSError, UnsafePathError) as exc:  # disk full, no permission, a link
                # planted at the base: a failure like any other, naming the path
                got = _Attempt(None, f"could not make a work directory: {_why(exc)}")
                wd = place = None
            else:
                wd = place.path
                try:
                    got = self._run_once(x, eval_id, place, gradient)
                except BaseException:
                    place.close()
                    raise
            error, out, err = got.error, got.stdout, got.stderr
            if error is None or attempts >= tries:
                break
        wall = time.perf_counter() - t0
        keep = wd is not None and (self.keep_workdirs is True or
                                   (self.keep_workdirs == "failed" and error is not None))
        if place is not None:
            if not keep:
                try:
                    place.base.remove_tree(place.path.name)
                except OSError:
                    pass  # a link swapped in for it: left as it is, never followed
            place.close()
        m = len(self.names_out)
        if error is None:
            return RunResult(np.asarray(got.values, float), None, "ok", None, None, wall, started,
                             eval_id, attempts, str(wd) if keep else None, got.gradient, got.note)
        if attempts > 1:
            error = f"{error} (after {attempts} attempts)"
        where = f" [work directory {wd}]" if keep else ""
        if self.policy.kind == "recover":
            return RunResult(np.array(self.policy.recover, float), error + where, "recovered",
                             out, err, wall, started, eval_id, attempts, str(wd) if keep else None)
        return RunResult(np.full(m, np.nan), error + where, "failed", out, err, wall, started,
                         eval_id, attempts, str(wd) if keep else None)

    # -- Model protocol ----------------------------------------------------------------------

    @fill_doc(evaluate_batch=EVALUATE_BATCH_DOC)
    def evaluate(self, x: np.ndarray) -> EvalBatch:
        """Run every row in turn (use :class:`~rotoruq.evaluation.evaluator.Evaluator` for
        parallel runs and a store). With the "abort" policy the first failure raises.

        %(evaluate_batch)s
        """
        x = np.atleast_2d(np.asarray(x, dtype=float))
        values = np.full((len(x), len(self.names_out)), np.nan)
        failures: dict[int, str] = {}
        for i, row in enumerate(x):
            r = self.run_one(row)
            warn_once(r.note)
            values[i] = r.values
            if r.status == "failed":
                if self.policy.kind == "abort":
                    raise EvaluationError(_abort_message(r, self.names_in, row))
                failures[i] = r.error or "failed"
        return EvalBatch(values, failures)

    def _evaluate_gradient(self, x: np.ndarray) -> Gradient:
        """Values (n, m) and gradients (n, m, d) from one driver run per point (ASV 3); a failed
        run is a NaN row with its reason in ``failures`` (the "abort" policy raises). Use
        :class:`~rotoruq.evaluation.evaluator.Evaluator` to keep them in a store."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        n, m, d = len(x), len(self.names_out), len(self.names_in)
        values, grads = np.full((n, m), np.nan), np.full((n, m, d), np.nan)
        failures: dict[int, str] = {}
        for i, row in enumerate(x):
            r = self.run_one(row, gradient=True)
            warn_once(r.note)
            values[i] = r.values
            if r.gradient is not None:
                grads[i] = r.gradient
            if r.status != "ok":  # a recovered run has values, not a gradient
                if self.policy.kind == "abort":
                    raise EvaluationError(_abort_message(r, self.names_in, row))
                failures[i] = r.error or "failed"
        return Gradient(values=values, gradient=grads, steps=np.zeros((n, d)), n_evaluations=n,
                        failures=failures)

    def _gradient(self, x: np.ndarray) -> np.ndarray:
        """Gradients (n, m, d) of the responses by the inputs, one driver run per point."""
        return self._evaluate_gradient(x).gradient

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.evaluate(x).values


@dataclass(frozen=True, eq=False)
class _Place:
    """One attempt's work directory: its path (for messages and ``{workdir}``), the base
    folder and the directory itself, both held by descriptors until :meth:`close`."""

    path: Path
    base: SafeFolder
    folder: SafeFolder

    def close(self) -> None:
        self.folder.close()
        self.base.close()


def _why(exc: BaseException) -> str:
    """An exception as one line naming its file (``[Errno 28] No space left on device:
    'path'``), without the class name."""
    return str(exc)


def _copy_into(folder: SafeFolder, src: Path) -> None:
    """Copy the user's file or folder ``src`` into ``folder`` under its name, through the
    folder's descriptor (permission bits kept, links inside a copied folder copied as
    links, as ``shutil.copytree(symlinks=True)`` does)."""
    if src.is_dir():
        with folder.folder(src.name, new=True) as sub:
            for entry in sorted(os.scandir(src), key=lambda e: e.name):
                if entry.is_symlink():
                    sub.symlink(entry.name, os.readlink(entry.path))
                else:
                    _copy_into(sub, Path(entry.path))
        return
    with open(src, "rb") as fh:
        folder.write(src.name, fh, mode=stat.S_IMODE(os.fstat(fh.fileno()).st_mode))


@dataclass(frozen=True, eq=False)
class _Attempt:
    """What one attempt of an evaluation gave (see :meth:`ExternalModel._run_once`)."""

    values: np.ndarray | None
    error: str | None
    stdout: str = ""
    stderr: str = ""
    gradient: np.ndarray | None = None
    note: str | None = None


def _abort_message(r: RunResult, names_in, x) -> str:
    point = ", ".join(f"{n}={float(v)!r}" for n, v in zip(names_in, np.ravel(x), strict=True))
    msg = f"evaluation {r.eval_id} failed at ({point}): {r.error}; failure_policy='abort'"
    if r.stderr:
        msg += "\n--- stderr (tail) ---\n" + r.stderr[-2000:]
    return msg
