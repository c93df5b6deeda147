"""What an evaluation's answer depends on, as one digest.

An evaluation is reused from the store (and a study step from its saved results) only when
everything that can change its answer is the same: the model's class, its full configuration
(``model.identity()``: preset contents, airfoil table, fixed inputs, solver options, or for an
external model its command, templates and files by content) and the code that computes it.

That code is scoped to what computes the answer (:func:`code_parts`): the source files the
model's module imports, transitively, within rotoruq (a rotor model: ``rotor/`` and what it
uses, plus the airfoil data; an external model: the evaluation layer's file-contract modules),
never the methods, the steps or the report. A step's fingerprint digests its own module and
the method modules it imports the same way. :data:`EPOCHS` holds one integer per layer:
raising one invalidates everything computed with that layer's code, on purpose.

>>> from rotoruq.evaluation.identity import model_identity
>>> model_identity(model)                                    # doctest: +SKIP
'rotoruq.rotor.model.RotorModel|collective_deg->thrust|3f9a0c...'

The digest is computed once per model object (hashing costs a few milliseconds for a rotor
preset); per evaluation, the store key is only the bytes of the input vector.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import json
import math
from collections.abc import Iterable, Iterator, Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["code_version", "code_parts", "code_digest", "model_code_parts", "EPOCHS",
           "digest", "file_sha256", "model_identity", "script_modules", "module_digests"]

_PACKAGE = Path(__file__).resolve().parent.parent
# Folders whose code cannot change a model's answer or a step's numbers.
_NOT_ANSWER = ("report",)
# Layers a code closure never follows: they present numbers or run studies, they do not
# compute a model's answer or a step's numbers.
_NOT_COMPUTING = frozenset({"report", "render", "study"})

#: One epoch per layer: raise a layer's number to invalidate, on purpose, every stored
#: evaluation and saved step computed with that layer's code (e.g. after a fix whose effect
#: the source digest cannot see, such as a changed data file outside the package).
EPOCHS: Mapping[str, int] = {
    "model": 1, "params": 1, "rotor": 1, "mbdyn": 1, "evaluation": 1, "methods": 1,
    "steps": 1, "results": 1,
}


@lru_cache(maxsize=1)
def code_version() -> str:
    """rotoruq's version and a digest of the package's source and data files (the report
    left out): recorded with each saved step, for the record. Identities and fingerprints use
    the scoped :func:`code_parts` instead, so an edit invalidates only what it can change.
    """
    from .. import __version__

    h = hashlib.sha256()
    for p in sorted(_PACKAGE.rglob("*")):
        rel = p.relative_to(_PACKAGE)
        if (not p.is_file() or rel.parts[0] in _NOT_ANSWER or "__pycache__" in rel.parts
                or p.suffix in (".pyc", ".pyo")):
            continue
        h.update(rel.as_posix().encode())
        h.update(b"\0")
        h.update(p.read_bytes())
        h.update(b"\0")
    return f"{__version__}+{h.hexdigest()[:16]}"


def _module_file(name: str) -> Path | None:
    """Source file of module ``name``: inside rotoruq found by path (no import), else by
    ``importlib.util.find_spec`` (a plugin's module); None when there is none."""
    parts = name.split(".")
    if parts[0] == "rotoruq":
        base = _PACKAGE.joinpath(*parts[1:])
        for cand in (base / "__init__.py", base.with_suffix(".py")):
            if cand.is_file():
                return cand
        return None
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError):
        return None
    origin = getattr(spec, "origin", None)
    return Path(origin) if origin and origin.endswith(".py") else None


def _package_of(path: Path, name: str) -> str:
    return name if path.name == "__init__.py" else name.rpartition(".")[0]


def _imports(path: Path, name: str) -> set[str]:
    """rotoruq modules ``path`` (module ``name``) imports, anywhere in the file (parsed once
    per content: keyed by the module and the sha256 of the file's bytes, never by its
    time stamp, whose granularity may hide an edit)."""
    text = path.read_bytes()
    return set(_parsed_imports(name, _package_of(path, name), hashlib.sha256(text).digest(),
                               text))


def _parsed_imports(name: str, package: str, sha: bytes, text: bytes) -> frozenset[str]:
    key = (name, package, sha)
    hit = _IMPORTS.get(key)
    if hit is None and _load_saved():
        hit = _IMPORTS.get(key)
    if hit is None:
        hit = _IMPORTS[key] = frozenset(_parse_imports(text.decode("utf-8"), package))
        _save_at_exit()
    return hit


#: _parse_imports by (module, package, sha256 of the source)
_IMPORTS: dict[tuple[str, str, bytes], frozenset[str]] = {}
#: :data:`_IMPORTS` kept between processes (parsing every module a study's code touches
#: costs a few tenths of a CPU second per process): a file beside this module's bytecode,
#: named by the digest of this file (an edit of the parser starts a new one), read at the
#: first lookup that misses, written back atomically at exit when a parse added to it.
#: Entries are keyed by content, so a file left by another checkout or version is never
#: wrong, only unused; where the folder is not writable nothing is kept.
_SAVED = Path(__file__).resolve().parent / "__pycache__" / (
    "rotoruq-imports-" + hashlib.sha256(Path(__file__).read_bytes()).hexdigest()[:16]
    + ".json")
_SAVED_STATE = {"loaded": False, "save": False}


def _load_saved() -> bool:
    """Merge the saved imports into :data:`_IMPORTS` (once per process): whether it read
    any."""
    if _SAVED_STATE["loaded"]:
        return False
    _SAVED_STATE["loaded"] = True
    try:
        rows = json.loads(_SAVED.read_text(encoding="utf-8"))
        for name, package, sha, imports in rows:
            _IMPORTS.setdefault((name, package, bytes.fromhex(sha)), frozenset(imports))
    except (OSError, ValueError, TypeError):  # none yet, or unreadable: parse again
        return False
    return True


def _save_at_exit() -> None:
    if not _SAVED_STATE["save"]:
        _SAVED_STATE["save"] = True
        import atexit

        atexit.register(_save)


def _save() -> None:
    """Write :data:`_IMPORTS` to :data:`_SAVED` (atomically; nothing when it cannot)."""
    from ..atomic import write_bytes

    rows = sorted([name, package, sha.hex(), sorted(imports)]
                  for (name, package, sha), imports in _IMPORTS.items())
    try:
        _SAVED.parent.mkdir(exist_ok=True)
        write_bytes(_SAVED, json.dumps(rows).encode())
    except OSError:
        pass


def _statements(body: list) -> Iterator[ast.stmt]:
    """Every statement of ``body`` and of the blocks nested in it (an import is a statement:
    the expressions, most of a module's nodes, are not walked)."""
    for node in body:
        yield node
        for name in ("body", "orelse", "finalbody"):
            sub = getattr(node, name, None)
            if isinstance(sub, list):
                yield from _statements(sub)
        for block in (*getattr(node, "handlers", ()), *getattr(node, "cases", ())):
            yield from _statements(block.body)


def _parse_imports(source: str, package: str) -> set[str]:
    out = set()
    for node in _statements(ast.parse(source).body):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.split(".")[0] == "rotoruq"}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "rotoruq":
                continue
            out.add(target)
            out |= {f"{target}.{a.name}" for a in node.names}  # names may be submodules
    return out


def _unit(name: str) -> str:
    parts = name.split(".")
    return parts[1] if parts[0] == "rotoruq" and len(parts) > 1 else ""


@lru_cache(maxsize=256)
def _closure(roots: tuple[str, ...],
             skip: frozenset[str] = _NOT_COMPUTING) -> tuple[tuple[str, Path], ...]:
    seen: dict[str, Path] = {}
    todo = list(roots)
    while todo:
        name = todo.pop()
        # the package root only re-exports names lazily: it computes nothing
        if name in seen or name == "rotoruq" or _unit(name) in skip:
            continue
        path = _module_file(name)
        if path is None:
            continue
        seen[name] = path
        todo.extend(_imports(path, name))
    return tuple(sorted(seen.items()))


def _label(path: Path) -> str:
    try:
        return "rotoruq/" + path.relative_to(_PACKAGE).as_posix()
    except ValueError:
        return path.as_posix()


def code_parts(modules: Iterable[str], *, every_layer: bool = False) -> dict[str, str]:
    """What of rotoruq's code computes the answer of ``modules``, part by part.

    The source files ``modules`` import, transitively, within rotoruq (the report, the
    drawing primitives and the study layer excepted, unless ``every_layer``: what a benchmark
    of the CLI or the report exercises), each as ``"rotoruq/<path>": sha256``;
    the airfoil data files when the rotor is among them; and ``"epoch:<layer>"`` for every
    layer they touch (:data:`EPOCHS`). A plugin's module outside rotoruq enters by its file.

    Examples
    --------
    >>> from rotoruq.evaluation.identity import code_parts
    >>> parts = code_parts(["rotoruq.steps.pce"])
    >>> "rotoruq/methods/pce.py" in parts, "rotoruq/methods/cuu.py" in parts
    (True, False)
    >>> parts["epoch:methods"]
    '1'
    """
    skip = frozenset() if every_layer else _NOT_COMPUTING
    files = _closure(tuple(sorted(set(modules))), skip)
    out = {_label(p): file_sha256(p)[:16] for _, p in files}
    units = {_unit(n) for n, _ in files} - {""}
    if "rotor" in units:
        for p in sorted((_PACKAGE / "data" / "airfoils").glob("*")):
            if p.is_file():
                out[_label(p)] = file_sha256(p)[:16]
    out.update({f"epoch:{u}": str(EPOCHS[u]) for u in sorted(units) if u in EPOCHS})
    return dict(sorted(out.items()))


def code_digest(parts: Mapping[str, str]) -> str:
    """One digest of :func:`code_parts`."""
    return digest(dict(parts))[:16]


def _lazy_names() -> dict[str, str]:
    """The package root's one list of public names (``_PUBLIC``: name -> module relative to
    the package), read from its source like every import here, never imported."""
    for node in ast.parse((_PACKAGE / "__init__.py").read_text(encoding="utf-8")).body:
        target: ast.expr
        value: ast.expr | None
        if isinstance(node, ast.AnnAssign):
            target, value = node.target, node.value
        elif isinstance(node, ast.Assign):
            target, value = node.targets[0], node.value
        else:
            continue
        if isinstance(target, ast.Name) and target.id == "_PUBLIC" and value is not None:
            return dict(ast.literal_eval(value))
    return {}


def script_modules(path: str | Path) -> list[str]:
    """The rotoruq modules a script outside the package imports: its import statements, and
    the public names it reads from the package root (``import rotoruq as rq; rq.sample``:
    ``rotoruq.methods.sampling``, through the root's table of lazily loaded names).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "bench.py"
    >>> _ = p.write_text("import rotoruq as rq\\n"
    ...                  "from rotoruq.methods.pce import polynomial_chaos\\n"
    ...                  "rq.sample(None, None)\\n")
    >>> script_modules(p)
    ['rotoruq.methods.pce', 'rotoruq.methods.sampling']
    """
    lazy = _lazy_names()
    path = Path(path)
    tree = ast.parse(path.read_text(encoding="utf-8"))
    roots = {a.asname or a.name for node in ast.walk(tree) if isinstance(node, ast.Import)
             for a in node.names if a.name == "rotoruq"}
    names = _imports(path, "__main__")
    names |= {f"rotoruq.{node.attr}" for node in ast.walk(tree)
              if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
              and node.value.id in roots}
    out = set()
    for name in names:
        head, _, last = name.rpartition(".")
        if head == "rotoruq" and last in lazy:
            name = "rotoruq" + lazy[last]
        if name != "rotoruq" and _module_file(name) is not None:
            out.add(name)
    return sorted(out)


def module_digests(modules: Iterable[str], *, every_layer: bool = True) -> dict[str, str]:
    """One :func:`code_digest` per module: of the code it imports, transitively
    (:func:`code_parts`, by default through every layer), keyed by the module's name.

    Examples
    --------
    >>> d = module_digests(["rotoruq.methods.pce"])
    >>> list(d), len(d["rotoruq.methods.pce"])
    (['rotoruq.methods.pce'], 16)
    """
    return {m: code_digest(code_parts([m], every_layer=every_layer)) for m in sorted(set(modules))}


def model_code_parts(model: Any) -> dict[str, str]:
    """:func:`code_parts` of the module defining ``model``'s class (an Evaluator: of the model
    it wraps)."""
    inner = getattr(model, "model", None)
    if inner is not None and hasattr(model, "store"):
        model = inner
    return code_parts([type(model).__module__])


def file_sha256(path: str | Path) -> str:
    """sha256 hex digest of a file's bytes, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(1 << 20):
            h.update(block)
    return h.hexdigest()


def _plain(o):
    """JSON-able form of configuration values (arrays by their bytes' digest)."""
    if isinstance(o, Mapping):
        return {str(k): _plain(v) for k, v in sorted(o.items(), key=lambda kv: str(kv[0]))}
    if isinstance(o, (list, tuple)):
        return [_plain(v) for v in o]
    if isinstance(o, np.ndarray):
        a = np.ascontiguousarray(o)
        return {"array": list(a.shape), "dtype": str(a.dtype),
                "sha256": hashlib.sha256(a.tobytes()).hexdigest()}
    if isinstance(o, (np.floating, float)):
        o = float(o)
        return o if math.isfinite(o) else repr(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.bool_,)):
        return bool(o)
    if isinstance(o, Path):
        return str(o)
    if o is None or isinstance(o, (str, int, bool)):
        return o
    ident = getattr(o, "identity", None)
    if callable(ident):
        return {"class": _qualname(o), "identity": _plain(ident())}
    return repr(o)


def digest(obj: Any) -> str:
    """sha256 hex digest of a configuration (nested mappings, sequences, numbers, arrays)."""
    text = json.dumps(_plain(obj), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _qualname(o) -> str:
    t = type(o)
    return f"{t.__module__}.{t.__qualname__}"


def model_identity(model: Any) -> str:
    """Text that tells models apart in the store and in step fingerprints.

    ``class|inputs->responses|digest``, where the digest covers the class, the model's
    ``identity()`` (its full configuration) and the code that computes its answers
    (:func:`model_code_parts`: the model's own module and what it imports, not the methods
    that sample it). A model without an
    ``identity()`` method is identified by its class and ``repr`` only: give your own models
    one if their configuration can change between runs. An Evaluator is identified by the model
    it wraps.
    """
    inner = getattr(model, "model_id", None)
    if isinstance(inner, str) and hasattr(model, "store"):
        return inner
    ident = getattr(model, "identity", None)
    if callable(ident):
        config = ident()
    elif isinstance(ident, str):
        config = ident
    else:
        config = repr(model)
    doc = {"class": _qualname(model), "config": config,
           "code": code_digest(model_code_parts(model)),
           "in": list(model.names_in), "out": list(model.names_out)}
    return (f"{_qualname(model)}|{','.join(model.names_in)}->{','.join(model.names_out)}"
            f"|{digest(doc)[:24]}")
