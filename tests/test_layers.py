"""The import layers of rotoruq (docs/architecture: who may import whom).

Every module under ``src/rotoruq`` is parsed (not imported) and each ``import`` - at module level
or inside a function, since a deferred import is still a dependency - is resolved to the rotoruq
subpackage it reaches. A lower layer must never import a higher one:

    errors, _rng, _options, _compile, _docs, _progress, _lazy, atomic, safety
                                    the bottom: import nothing of rotoruq but each other
                                    (_options: the option records' deprecation helpers;
                                    _compile: the notice before numba compiles;
                                    _docs: docstring entries shared by several names;
                                    _progress: a long phase's progress as log records;
                                    _lazy: a third-party module imported on first use;
                                    _numba_cache: numba's cache keyed by what a kernel
                                    compiles in)
    model, params                   + the bottom
    rotor                           + model, params           (never methods, evaluation, ...)
    methods                         + model, params           (never rotor, evaluation, ...)
    evaluation                      + model, params, atomic   (never methods, rotor, study, ...)
    mbdyn                           + rotor, evaluation (an external solver of the rotor)
    results                         + evaluation (the results format, below study and report)
    render                          + results (table and figure primitives)
    steps                           + methods, evaluation, results, render (one module per
                                    step type: options, adapter, tables, figures, warnings)
    report                          + results, render, steps, evaluation (never rotor, study)
    reference                       + report, steps, render, results (the reference study as an
                                    application: its claims, thesis tables, reference figures,
                                    studies; never rotor, methods, study)
    study                           everything
    __main__                        + study (``python -m rotoruq``: the CLI's ``main``)

No generic layer (render, steps, report, results, methods, ...) imports ``reference``: the
report takes an application object from its caller (``report/application.py``), so a user's
report never depends on the reference study's code.

No module may, at import, write into another layer's globals (assign or delete an attribute or
an item of a name imported from another layer, or call something of another layer for its
effect, directly or through a function of its own): a registry filled that way differs
between interpreters that imported different modules.

The package ``rotoruq/__init__.py`` re-exports the public API lazily and is exempt. Imports under
``if TYPE_CHECKING:`` are annotations only and are exempt too.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "rotoruq"

BOTTOM = {"errors", "_rng", "_options", "_compile", "_docs", "_progress", "_lazy", "atomic",
          "safety", "_numba_cache"}
UNITS = {"model", "params", "testfunctions"}
ALLOWED: dict[str, set[str]] = {
    "errors": set(),
    "_rng": {"errors"},
    "_options": {"errors"},
    "_compile": {"_progress"},
    "_docs": set(),
    "_progress": set(),
    "_lazy": set(),
    "_numba_cache": set(),
    "atomic": set(),
    "safety": {"errors"},
    "model": BOTTOM,
    "params": BOTTOM,
    "testfunctions": BOTTOM,
    "rotor": BOTTOM | UNITS,
    "methods": BOTTOM | UNITS,
    "evaluation": BOTTOM | UNITS,
    "mbdyn": BOTTOM | UNITS | {"rotor", "evaluation"},
    "results": BOTTOM | UNITS | {"evaluation"},
    "render": BOTTOM | UNITS | {"evaluation", "results"},
    "steps": BOTTOM | UNITS | {"methods", "evaluation", "results", "render"},
    "report": BOTTOM | UNITS | {"evaluation", "results", "render", "steps"},
    "reference": BOTTOM | UNITS | {"evaluation", "results", "render", "steps", "report"},
    "study": BOTTOM | UNITS | {"rotor", "methods", "evaluation", "mbdyn", "results", "render",
                               "steps", "report", "reference"},
    "__main__": {"study"},
}
# The application on top of the toolkit: only the study layer (and the CLI in it) imports it.
APPLICATIONS = {"reference"}

# Violations that other branches of issue 14 remove in parallel: (importing module, imported
# unit). The lead empties this list when merging them; an entry that no longer occurs fails.
KNOWN_VIOLATIONS: set[tuple[str, str]] = set()


def _unit(module: str) -> str:
    """The layer unit of a dotted module name under rotoruq ("rotoruq.methods.pce" -> "methods");
    "" for the package itself and its ``__version__`` (the package root loads nothing)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] != "__version__" else ""


def _module_name(path: Path) -> str:
    rel = path.relative_to(SRC.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _type_checking_lines(tree: ast.AST) -> set[int]:
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If):
            test = node.test
            name = test.id if isinstance(test, ast.Name) else getattr(test, "attr", None)
            if name == "TYPE_CHECKING":
                for child in node.body:
                    for sub in ast.walk(child):
                        if hasattr(sub, "lineno"):
                            lines.add(sub.lineno)
    return lines


def rotoruq_imports(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module) of every rotoruq import in one source file."""
    module = _module_name(path)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    tree = ast.parse(path.read_text(), filename=str(path))
    skip = _type_checking_lines(tree)
    out = []
    for node in ast.walk(tree):
        if getattr(node, "lineno", None) in skip:
            continue
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.split(".")[0] == "rotoruq"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "rotoruq":
                continue
            if target == "rotoruq" or not node.module:  # from . import x / from .. import y
                out += [(node.lineno, f"{target}.{a.name}") for a in node.names]
            else:
                out.append((node.lineno, target))
    return out


def _sources() -> list[Path]:
    return sorted(p for p in SRC.rglob("*.py") if p != SRC / "__init__.py")


def layer_violations() -> dict[tuple[str, str], list[str]]:
    found: dict[tuple[str, str], list[str]] = {}
    for path in _sources():
        module = _module_name(path)
        unit = _unit(module)
        for line, target in rotoruq_imports(path):
            to = _unit(target)
            if to in ("", unit) or to in ALLOWED[unit]:
                continue
            found.setdefault((module, to), []).append(
                f"{path.relative_to(SRC.parent)}:{line} imports {target}")
    return found


def test_every_module_belongs_to_a_layer():
    units = {_unit(_module_name(p)) for p in _sources()}
    assert units <= set(ALLOWED), f"modules outside every layer: {units - set(ALLOWED)}"


def test_generic_layers_never_import_the_reference_application():
    """render, steps, report, results, methods, ... import nothing of ``rotoruq.reference``
    (not even inside a function): the report gets an application object from its caller."""
    for unit, allowed in ALLOWED.items():
        if unit != "study":
            assert not allowed & APPLICATIONS or unit in APPLICATIONS, unit
    found = [f"{path.relative_to(SRC.parent)}:{line} imports {target}"
             for path in _sources() if _unit(_module_name(path)) not in APPLICATIONS | {"study"}
             for line, target in rotoruq_imports(path) if _unit(target) in APPLICATIONS]
    assert not found, "generic code imports the reference application:\n" + "\n".join(found)


def test_no_lower_layer_imports_a_higher_one():
    found = layer_violations()
    new = {k: v for k, v in found.items() if k not in KNOWN_VIOLATIONS}
    assert not new, "layer violations:\n" + "\n".join(s for v in new.values() for s in v)
    fixed = KNOWN_VIOLATIONS - set(found)
    assert not fixed, f"fixed: remove from KNOWN_VIOLATIONS: {sorted(fixed)}"


def _foreign_names(tree: ast.AST, module: str, unit: str) -> set[str]:
    """Names a module binds by importing from another layer's unit of rotoruq."""
    package = module.rpartition(".")[0]
    names: set[str] = set()
    for node in tree.body if isinstance(tree, ast.Module) else []:
        for sub in ast.walk(node):
            if isinstance(sub, ast.Import):
                for a in sub.names:
                    if a.name.split(".")[0] == "rotoruq" and _unit(a.name) not in ("", unit):
                        names.add((a.asname or a.name).split(".")[0])
            elif isinstance(sub, ast.ImportFrom):
                if sub.level:
                    base = package.split(".")[: len(package.split(".")) - (sub.level - 1)]
                    target = ".".join(base + ([sub.module] if sub.module else []))
                else:
                    target = sub.module or ""
                for a in sub.names:
                    full = target if sub.module else f"{target}.{a.name}"
                    if full.split(".")[0] == "rotoruq" and _unit(full) not in ("", unit):
                        names.add(a.asname or a.name)
    return names


def _root(node: ast.AST) -> str | None:
    while isinstance(node, (ast.Attribute, ast.Subscript, ast.Call)):
        node = node.func if isinstance(node, ast.Call) else node.value
    return node.id if isinstance(node, ast.Name) else None


def _writes(stmts: list[ast.stmt], foreign: set[str], local_writers: set[str]) -> list[int]:
    """Lines of ``stmts`` (not descending into function bodies) that write into a foreign
    name: assignment/deletion of its attribute or item, a call of it as a statement, or a call
    of a local function that does so."""
    lines = []
    for stmt in stmts:
        todo: list[ast.AST] = [stmt]
        while todo:
            node = todo.pop()
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                continue
            targets: list[ast.AST] = []
            if isinstance(node, (ast.Assign, ast.Delete)):
                targets = list(node.targets)
            elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
                targets = [node.target]
            if any(isinstance(x, (ast.Attribute, ast.Subscript)) and _root(x) in foreign
                   for x in targets):
                lines.append(node.lineno)
            if isinstance(node, ast.Expr) and isinstance(node.value, ast.Call) and (
                    _root(node.value.func) in foreign):
                lines.append(node.lineno)
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and (
                    node.func.id in local_writers):
                lines.append(node.lineno)
            todo.extend(ast.iter_child_nodes(node))
    return lines


def _is_main_guard(node: ast.stmt) -> bool:
    """``if __name__ == "__main__":`` (runs as a script, not at import)."""
    return (isinstance(node, ast.If) and isinstance(node.test, ast.Compare)
            and isinstance(node.test.left, ast.Name) and node.test.left.id == "__name__")


def foreign_writes(path: Path) -> list[str]:
    """Where a module writes into another layer's globals when it is imported."""
    module = _module_name(path)
    tree = ast.parse(path.read_text(), filename=str(path))
    foreign = _foreign_names(tree, module, _unit(module))
    funcs = {n.name: n for n in tree.body if isinstance(n, (ast.FunctionDef,
                                                             ast.AsyncFunctionDef))}
    writers: set[str] = set()
    changed = True
    while changed:  # a local function that calls a writer is a writer
        changed = False
        for name, fn in funcs.items():
            if name not in writers and _writes(fn.body, foreign, writers):
                writers.add(name)
                changed = True
    body = [n for n in tree.body if not isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
            and not _is_main_guard(n)]
    return [f"{path.relative_to(SRC.parent)}:{line}" for line in _writes(body, foreign, writers)]


def test_no_module_writes_into_another_layer_at_import():
    found = [w for p in _sources() for w in foreign_writes(p)]
    assert not found, "module-level writes into another layer:\n" + "\n".join(found)


@pytest.mark.parametrize("source, bad", [
    # the old registry: a local function, called at import, fills the report's table
    ("from ...report.hooks import register_rendering\n"
     "def register(st):\n    register_rendering(st.name, st)\n    return st\n"
     "register(object())\n", True),
    ("from ...report.hooks import RENDERINGS\nRENDERINGS['x'] = 1\n", True),
    ("from ...report import hooks\nhooks.RENDERINGS.update(x=1)\n", True),
    ("import rotoruq.report.hooks\nrotoruq.report.hooks.RENDERINGS = {}\n", True),
    ("from ...report import hooks\nif True:\n    del hooks.RENDERINGS['x']\n", True),
    # reading another layer, building one's own table, writing inside a function: fine
    ("from ...report.hooks import RENDERINGS\nMINE = dict(RENDERINGS)\nMINE['x'] = 1\n"
     "def later():\n    RENDERINGS['x'] = 1\n", False),
    ("from ..mcmc import helper\nhelper.CACHE['x'] = 1\n", False),  # its own layer
])
def test_the_checker_sees_foreign_writes(tmp_path, monkeypatch, source, bad):
    root = tmp_path / "rotoruq"
    (root / "methods" / "mcmc").mkdir(parents=True)
    path = root / "methods" / "mcmc" / "x.py"
    path.write_text(source)
    monkeypatch.setattr(sys.modules[__name__], "SRC", root)
    assert bool(foreign_writes(path)) is bad, foreign_writes(path)


@pytest.mark.parametrize(
    "source, expected",
    [
        ("from ...evaluation.store import Store\n", "rotoruq.evaluation.store"),
        ("from ... import study\n", "rotoruq.study"),
        ("import rotoruq.report.html\n", "rotoruq.report.html"),
        ("def f():\n    from ...study import runner\n", "rotoruq.study"),
    ],
)
def test_the_checker_sees_imports(tmp_path, monkeypatch, source, expected):
    # a module rotoruq/methods/mcmc/x.py: ".." is rotoruq.methods, "..." is rotoruq
    root = tmp_path / "rotoruq"
    (root / "methods" / "mcmc").mkdir(parents=True)
    path = root / "methods" / "mcmc" / "x.py"
    path.write_text(source)
    monkeypatch.setattr(sys.modules[__name__], "SRC", root)
    got = [t for _, t in rotoruq_imports(path)]
    assert any(t == expected or t.startswith(expected + ".") for t in got), got


def test_type_checking_imports_are_exempt(tmp_path, monkeypatch):
    root = tmp_path / "rotoruq"
    (root / "rotor").mkdir(parents=True)
    path = root / "rotor" / "x.py"
    path.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                    "    from ..study.schema import Study\nfrom ..methods import pce\n")
    monkeypatch.setattr(sys.modules[__name__], "SRC", root)
    assert [t for _, t in rotoruq_imports(path)] == ["rotoruq.methods"]


def _loaded_after(code: str) -> list[str]:
    """rotoruq modules loaded by ``code`` in a fresh interpreter."""
    probe = (f"{code}\nimport sys\n"
             "print(' '.join(sorted(m for m in sys.modules if m.split('.')[0] == 'rotoruq')))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, timeout=120)
    return out.stdout.split()


def test_import_rotoruq_loads_nothing_until_a_name_is_used():
    assert _loaded_after("import rotoruq") == ["rotoruq"]
    # one layer alone: the rotor does not bring methods, evaluation, study or report
    units = {_unit(m) for m in _loaded_after("import rotoruq.rotor.hover")}
    assert units <= {"", "errors", "_rng", "_docs", "_lazy", "model", "params", "rotor",
                     "safety", "_numba_cache"}  # c81 tables through safety.write_file;
    # _numba_cache: the rotor kernel's cache locators
    # a name loads its own module (and what that imports), nothing else
    units = {_unit(m) for m in _loaded_after("import rotoruq; rotoruq.ParameterSpace")}
    assert units == {"", "errors", "_rng", "_docs", "_lazy", "params"}, units


def test_python_m_rotoruq_is_as_light_as_the_console_script():
    # ``python -m rotoruq driver ...`` reaches the driver client before any heavy import
    assert _loaded_after("import rotoruq.__main__") == [
        "rotoruq", "rotoruq.__main__", "rotoruq.study", "rotoruq.study.cli"]


def test_every_public_name_resolves_lazily():
    import rotoruq

    for name in rotoruq.__all__:
        assert getattr(rotoruq, name) is not None, name
    assert set(rotoruq.__all__) <= set(dir(rotoruq))
    assert rotoruq.Normal is __import__("rotoruq.params", fromlist=["Normal"]).Normal
    with pytest.raises(AttributeError, match="has no attribute 'sampel'"):
        rotoruq.sampel  # noqa: B018
