"""The Dakota analysis-driver loop shared by ``rotoruq driver`` and the MBDyn driver.

Dakota runs an analysis driver as ``<driver string> params.in results.out``: the two file names
come last, after whatever options the deck's driver string holds. Every option here therefore
takes exactly one value (``--set k=v`` once per pair, ``--outputs a,b``), so the appended names
are never swallowed. Dakota 6.24's parser refuses its block keywords (``environment``,
``method``, ``model``, ``variables``, ``interface``, ``responses``) anywhere in a driver string,
so the response option is spelled ``--outputs`` (``--responses`` and ``--resp`` are kept for
commands outside Dakota).

What a call does, for one parameters block or several (Dakota's ``batch`` interface writes one
block per evaluation into one file and reads one results block per evaluation, separated by
``#`` lines):

- variable and response labels of the deck are renamed by ``--map deck_name=model_name``;
- the active set vector is honoured: bit 1 values, bit 2 gradients with respect to the
  derivative variables (from :func:`rotoruq.model.model_gradient`: the model's analytic
  gradient, else central finite differences, every stencil point of every block in one batched
  call), bit 4 (Hessians) is refused;
- the metadata label ``seconds`` is answered with the wall time of the evaluation;
- every failure (unreadable parameters file, unknown name, bad option, failed or non-finite
  evaluation, Hessians) writes ``FAIL`` for the block (the whole file when nothing could be
  evaluated), prints the reason on stderr and exits with status 1. Dakota ignores the status and
  applies its ``failure_capture`` policy to the ``FAIL``; rotoruq's external model reports the
  status and the reason.

The module imports only the evaluation layer's file formats and :mod:`rotoruq.model`: the model
a driver runs is made by the caller's ``make_model``, so a driver's start-up costs what its
model costs.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ParameterError, RotoruqError
from ..model import EvalBatch, Model, align_inputs, evaluate, has_gradient, model_gradient
from ..safety import UnsafePathError, path_length_problem, terminal_text, write_file
from .dakota_files import FAIL_TEXT, ParametersFile, format_results, read_parameters_batch

__all__ = ["add_arguments", "main", "named_pairs", "run", "run_model", "ArgumentError",
           "METADATA"]

#: metadata labels a driver answers (Dakota's ``responses ... metadata 'seconds'``).
METADATA = ("seconds",)

#: make_model(args, names_in, names_out, fixed) -> Model
MakeModel = Callable[[argparse.Namespace, list[str], list[str], dict[str, float]], Model]


class ArgumentError(ParameterError):
    """A driver's command line is not valid."""


class _Parser(argparse.ArgumentParser):
    """Raises instead of exiting, so a results file can still say FAIL."""

    def error(self, message: str):  # type: ignore[override]
        raise ArgumentError(f"{message}\n{self.format_usage().strip()}")


def add_arguments(parser: argparse.ArgumentParser, outputs_help: str = "") -> None:
    """Add the options every driver has: the two files, ``--outputs``, ``--set``, ``--map``."""
    parser.add_argument("params", type=Path, help="Dakota parameters file (standard or aprepro; "
                        "one block, or several from Dakota's batch interface)")
    parser.add_argument("results", type=Path, help="results file to write")
    parser.add_argument("--outputs", "--responses", "--resp", dest="outputs", action="append",
                        default=[], metavar="NAME[,NAME...]",
                        help="outputs to write, in the order of the deck's responses (default: "
                             "the response labels of the parameters file, renamed by --map). "
                             "Repeatable. " + outputs_help)
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        dest="fixed", help="an input held fixed at VALUE (once per input; an "
                        "input of the parameters file cannot be set)")
    parser.add_argument("--map", action="append", default=[], metavar="DECK_NAME=NAME",
                        dest="mapping", help="a deck label (variable or response) that is "
                        "named NAME in the model (once per label)")


def named_pairs(items: Sequence[str], option: str, number: bool = False) -> dict:
    """``["a=1", "b=2"]`` -> ``{"a": "1", "b": "2"}`` (values as floats with ``number``).

    The name is split at the last ``=``: a deck label may hold ``=`` (``--map P=W=power`` maps
    ``P=W``), a model's names and numbers never do.

    Examples
    --------
    >>> named_pairs(["omega=230", "rho=1.2"], "--set", number=True)
    {'omega': 230.0, 'rho': 1.2}
    >>> named_pairs(["P=W=power"], "--map")
    {'P=W': 'power'}
    """
    out: dict = {}
    for item in items:
        name, eq, value = item.rpartition("=")
        name, value = name.strip(), value.strip()
        if not eq or not name or not value:
            raise ArgumentError(f"{option} expects NAME=VALUE, got {item!r}")
        if number:
            try:
                out_value: object = float(value)
            except ValueError:
                raise ArgumentError(f"{option} {item!r}: {value!r} is not a number") from None
        else:
            out_value = value
        if name in out:
            raise ArgumentError(f"{option} names {name!r} twice")
        out[name] = out_value
    return out


def _outputs(items: Sequence[str]) -> list[str]:
    return [w.strip() for item in items for w in item.split(",") if w.strip()]


def _results_path(argv: Sequence[str]) -> Path | None:
    """The results file of a command line that did not parse: the last word, when the word
    before it names an existing file (Dakota appends ``params results``)."""
    if (len(argv) >= 2 and not argv[-1].startswith("-")
            and not any(map(path_length_problem, argv[-2:])) and Path(argv[-2]).is_file()):
        return Path(argv[-1])
    return None


def _write(path: Path, text: str, program: str) -> bool:
    """Write the results file (via a new temporary one, never through a symlink planted
    at its name); a failure is one line on stderr."""
    try:
        write_file(path, text.encode("utf-8"))
    except UnsafePathError as exc:
        print(f"{program}: cannot write the results file: {exc}", file=sys.stderr)
        return False
    except OSError as exc:
        print(f"{program}: cannot write the results file {terminal_text(path)}: "
              f"{exc.strerror or exc}", file=sys.stderr)
        return False
    return True


def _check_paths(args: argparse.Namespace, parser: argparse.ArgumentParser) -> None:
    """A parameters or results file that no file system can name is a usage error."""
    for what in ("params", "results"):
        problem = path_length_problem(getattr(args, what))
        if problem is not None:
            raise ArgumentError(f"argument {what}: {problem}\n"
                                f"{parser.format_usage().strip()}")


class _Plan:
    """What the blocks of one parameters file ask, checked against the options."""

    def __init__(self, blocks: list[ParametersFile], outputs: list[str],
                 fixed: dict[str, float], mapping: dict[str, str]) -> None:
        first = blocks[0]
        for b in blocks[1:]:
            if b.names_in != first.names_in or b.names_out != first.names_out:
                raise ParameterError(f"evaluation {b.eval_id} of the batch has variables "
                                     f"{list(b.names_in)} and responses {list(b.names_out)}; "
                                     f"the first has {list(first.names_in)} and "
                                     f"{list(first.names_out)}")
        labels = set(first.names_in) | set(first.names_out)
        stray = [k for k in mapping if k not in labels]
        if stray:
            raise ParameterError(f"--map names {stray}, which are neither variables "
                                 f"{list(first.names_in)} nor responses "
                                 f"{list(first.names_out)} of the parameters file")
        self.names_in = [mapping.get(k, k) for k in first.names_in]
        if len(set(self.names_in)) < len(self.names_in):
            raise ParameterError(f"--map gives two variables the same name: {self.names_in}")
        clash = [k for k in fixed if k in self.names_in]
        if clash:
            raise ParameterError(f"--set {clash}: the parameters file sets "
                                 f"{'it' if len(clash) == 1 else 'them'} already (remove the "
                                 "--set, or the variable from the deck)")
        deck_out = list(first.names_out)
        if outputs:
            if len(outputs) != len(deck_out):
                raise ParameterError(f"--outputs names {len(outputs)} outputs {outputs}; the "
                                     f"parameters file has {len(deck_out)} responses {deck_out}")
            self.names_out = list(outputs)
        else:
            self.names_out = [mapping.get(k, k) for k in deck_out]
        self.deck_out = deck_out
        self.position = {k: i for i, k in enumerate(first.names_in)}
        for b in blocks:
            hess = [k for k, a in b.asv.items() if a & 4]
            if hess:
                raise ParameterError(f"evaluation {b.eval_id} asks for Hessians of {hess} "
                                     "(ASV bit 4), which rotoruq's drivers do not compute; use "
                                     "numerical_hessians or no_hessians in the deck")
            bad = [m for m in b.metadata if m not in METADATA]
            if bad:
                raise ParameterError(f"metadata {bad} are not known; a driver writes "
                                     f"{list(METADATA)}")
        self.blocks = blocks

    def points(self) -> np.ndarray:
        rows = []
        for b in self.blocks:
            strings = [k for k, v in b.variables.items() if isinstance(v, str)]
            if strings:
                raise ParameterError(f"string variables {strings} cannot be model inputs")
            rows.append([float(v) for v in b.variables.values()])
        return np.array(rows, dtype=float).reshape(len(self.blocks), len(self.names_in))


def _evaluate(model: Model, plan: _Plan) -> tuple[np.ndarray, np.ndarray | None,
                                                   dict[int, str], np.ndarray]:
    """Values (n, m), gradients (n, m, d) or None, failures, seconds per block (n,)."""
    x = plan.points()
    n = len(x)
    want_grad = np.array([any(a & 2 for a in b.asv.values()) for b in plan.blocks])
    want_val = np.array([any(a & 1 for a in b.asv.values()) for b in plan.blocks])
    values = np.full((n, len(model.names_out)), np.nan)
    grads = None
    failures: dict[int, str] = {}
    seconds = np.zeros(n)
    g_rows = np.flatnonzero(want_grad)
    v_rows = np.flatnonzero(want_val & ~want_grad)
    if g_rows.size:
        t0 = time.perf_counter()
        g = model_gradient(model, x[g_rows])
        seconds[g_rows] = (time.perf_counter() - t0) / g_rows.size
        grads = np.full((n, len(model.names_out), x.shape[1]), np.nan)
        values[g_rows], grads[g_rows] = g.values, g.gradient
        failures.update({int(g_rows[i]): r for i, r in g.failures.items()})
    if v_rows.size:
        t0 = time.perf_counter()
        batch: EvalBatch = evaluate(model, x[v_rows])
        seconds[v_rows] = (time.perf_counter() - t0) / v_rows.size
        values[v_rows] = batch.values
        failures.update({int(v_rows[i]): r for i, r in batch.failures.items()})
    return values, grads, failures, seconds


def _block_text(plan: _Plan, k: int, model: Model, values, grads, seconds) -> str:
    b = plan.blocks[k]
    cols = [list(model.names_out).index(n) for n in plan.names_out]
    asv = [b.asv[n] for n in plan.deck_out]
    keep = [i for i, a in enumerate(asv) if a & 1]
    g = None
    if any(a & 2 for a in asv):
        assert grads is not None
        dcols = [plan.position[v] for v in b.dvv]
        g = np.array([grads[k, cols[i]][dcols] for i, a in enumerate(asv) if a & 2])
        if not np.all(np.isfinite(g)):
            raise ParameterError("non-finite gradient")
    y = values[k, cols]
    meta = {m: float(seconds[k]) for m in b.metadata}
    return format_results(y[keep], [plan.deck_out[i] for i in keep], gradients=g,
                          metadata=meta)


def run(params: Path, results: Path, make_model: MakeModel, args: argparse.Namespace, *,
        program: str) -> int:
    """Answer one parameters file (one block or a batch) with ``make_model``'s model.

    Parameters
    ----------
    params, results : the files Dakota names.
    make_model : ``make_model(args, names_in, names_out, fixed) -> Model`` with inputs in the
        order of the parameters file's variables (renamed by ``--map``) and outputs in the order
        of its responses.
    args : the parsed command line (``outputs``, ``fixed``, ``mapping`` and the caller's own).
    program : name used in messages on stderr.

    Returns
    -------
    int
        0 when every block was answered, 1 when any block (or the file) says ``FAIL``.

    Examples
    --------
    >>> import argparse, tempfile
    >>> from pathlib import Path
    >>> from rotoruq.model import FunctionModel
    >>> from rotoruq.evaluation.dakota_files import write_parameters, read_results
    >>> d = Path(tempfile.mkdtemp())
    >>> _ = write_parameters(d / "p.in", {"a": 2.0}, {"f": 3})
    >>> make = lambda args, i, o, fixed: FunctionModel(lambda x: x**2, i, o)
    >>> ns = argparse.Namespace(outputs=[], fixed=[], mapping=[])
    >>> run(d / "p.in", d / "r.out", make, ns, program="demo")
    0
    >>> r = read_results(d / "r.out", names_out=["f"], asv=[3], n_dvv=1)
    >>> float(r.values[0]), round(float(r.gradients[0, 0]), 6)
    (4.0, 4.0)
    """
    try:
        blocks = read_parameters_batch(params)
        plan = _Plan(blocks, _outputs(args.outputs), named_pairs(args.fixed, "--set", True),
                     named_pairs(args.mapping, "--map"))
        model = make_model(args, plan.names_in, plan.names_out,
                           named_pairs(args.fixed, "--set", True))
        values, grads, failures, seconds = _evaluate(model, plan)
    except (RotoruqError, OSError, ValueError) as exc:
        print(f"{program}: {exc}", file=sys.stderr)
        _write(results, FAIL_TEXT, program)
        return 1
    texts = []
    status = 0
    for k, b in enumerate(blocks):
        reason = failures.get(k)
        if reason is None:
            try:
                texts.append(_block_text(plan, k, model, values, grads, seconds))
                continue
            except (RotoruqError, ValueError) as exc:
                reason = str(exc)
        print(f"{program}: evaluation {b.eval_id} failed: {reason}", file=sys.stderr)
        texts.append(FAIL_TEXT)
        status = 1
    if not _write(results, "#\n".join(texts), program):
        return 1
    return status


class _Ordered:
    """``model`` with its inputs taken in another order (the deck's)."""

    def __init__(self, model: Model, names_in: Sequence[str], names_out: Sequence[str]):
        missing = [n for n in names_out if n not in model.names_out]
        if missing:
            raise ParameterError(f"responses {missing} are not outputs of {model!r}; outputs: "
                                 f"{list(model.names_out)}")
        self.model, self.names_in = model, tuple(names_in)
        self.names_out = tuple(model.names_out)
        self.perm = align_inputs(model, names_in)
        if has_gradient(model):
            self.gradient = self._gradient

    def _x(self, x: np.ndarray) -> np.ndarray:
        x = np.atleast_2d(np.asarray(x, dtype=float))
        return x if self.perm is None else x[:, self.perm]

    def evaluate(self, x: np.ndarray) -> EvalBatch:
        return evaluate(self.model, self._x(x))

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.evaluate(x).values

    def _gradient(self, x: np.ndarray) -> np.ndarray:
        inner: Any = self.model  # gradient: an optional member of the Model protocol
        g = np.asarray(inner.gradient(self._x(x)), dtype=float)
        return g if self.perm is None else g[..., np.argsort(self.perm)]


def run_model(params: str | Path, results: str | Path, model: Model,
              outputs: Sequence[str] | None = None, *, program: str = "rotoruq driver") -> int:
    """Answer a parameters file with a Python model (inputs: the file's variables, any order).

    The :func:`run` loop without a command line: ``outputs`` as ``--outputs``. Returns 0, or 1
    when the results file says ``FAIL`` (the reason on stderr).

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> from rotoruq.model import FunctionModel
    >>> from rotoruq.evaluation.dakota_files import write_parameters, read_results
    >>> d = Path(tempfile.mkdtemp())
    >>> _ = write_parameters(d / "p.in", {"b": 3.0, "a": 2.0}, ["f"])
    >>> m = FunctionModel(lambda x: x[:, 0] - x[:, 1], ["a", "b"], ["f"])
    >>> run_model(d / "p.in", d / "r.out", m), float(read_results(d / "r.out").values[0])
    (0, -1.0)
    """
    args = argparse.Namespace(outputs=list(outputs or []), fixed=[], mapping=[])

    def make(args, names_in, names_out, fixed):
        return _Ordered(model, names_in, names_out)

    return run(Path(params), Path(results), make, args, program=program)


def main(argv: Sequence[str] | None, make_model: MakeModel, *, program: str,
         description: str, add_model_arguments: Callable[[argparse.ArgumentParser], None]
         | None = None, prog: str | None = None) -> int:
    """Parse a driver's command line and :func:`run` it; a command line that does not parse
    still writes ``FAIL`` when the results file can be told (the last word, after an existing
    parameters file), and returns 2. ``program`` prefixes messages, ``prog`` (default
    ``program``) is the command shown in the usage line."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = _Parser(prog=prog or program, description=description)
    add_arguments(parser)
    if add_model_arguments is not None:
        add_model_arguments(parser)
    try:
        args = parser.parse_args(argv)
        named_pairs(args.fixed, "--set", True)
        named_pairs(args.mapping, "--map")
        _check_paths(args, parser)
    except ArgumentError as exc:
        print(f"{program}: error: {exc}", file=sys.stderr)
        path = getattr(locals().get("args"), "results", None) or _results_path(argv)
        if path is not None and path_length_problem(path) is None:
            _write(Path(path), FAIL_TEXT, program)
        return 2
    return run(args.params, args.results, make_model, args, program=program)
