"""The import layers of rotoruq (docs/architecture: who may import whom).

Every module under ``src/rotoruq`` is parsed (not imported) and each ``import`` - at module level
or inside a function, since a deferred import is still a dependency - is resolved to the rotoruq
subpackage it reaches. A lower layer must never import a higher one:

    errors, _rng, atomic            the bottom: import nothing of rotoruq but each other
    model, params                   + the bottom
    rotor                           + model, params           (never methods, evaluation, ...)
    methods                         + model, params           (never rotor, evaluation, ...)
    evaluation                      + model, params, atomic   (never methods, rotor, study, ...)
    mbdyn                           + rotor, evaluation (an external solver of the rotor)
    results                         + evaluation (the results format, below study and report)
    report                          everything but study
    study                           everything

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

BOTTOM = {"errors", "_rng", "atomic"}
UNITS = {"model", "params"}
ALLOWED: dict[str, set[str]] = {
    "errors": set(),
    "_rng": {"errors"},
    "atomic": set(),
    "model": BOTTOM,
    "params": BOTTOM,
    "rotor": BOTTOM | UNITS,
    "methods": BOTTOM | UNITS,
    "evaluation": BOTTOM | UNITS,
    "mbdyn": BOTTOM | UNITS | {"rotor", "evaluation"},
    "results": BOTTOM | UNITS | {"evaluation"},
    "report": BOTTOM | UNITS | {"rotor", "methods", "evaluation", "mbdyn", "results"},
    "study": BOTTOM | UNITS | {"rotor", "methods", "evaluation", "mbdyn", "results", "report"},
}

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


def test_no_lower_layer_imports_a_higher_one():
    found = layer_violations()
    new = {k: v for k, v in found.items() if k not in KNOWN_VIOLATIONS}
    assert not new, "layer violations:\n" + "\n".join(s for v in new.values() for s in v)
    fixed = KNOWN_VIOLATIONS - set(found)
    assert not fixed, f"fixed: remove from KNOWN_VIOLATIONS: {sorted(fixed)}"


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
    assert units <= {"", "errors", "_rng", "model", "params", "rotor"}, units
    # a name loads its own module (and what that imports), nothing else
    units = {_unit(m) for m in _loaded_after("import rotoruq; rotoruq.ParameterSpace")}
    assert units == {"", "errors", "_rng", "params"}, units


def test_every_public_name_resolves_lazily():
    import rotoruq

    for name in rotoruq.__all__:
        assert getattr(rotoruq, name) is not None, name
    assert set(rotoruq.__all__) <= set(dir(rotoruq))
    assert rotoruq.Normal is __import__("rotoruq.params", fromlist=["Normal"]).Normal
    with pytest.raises(AttributeError, match="has no attribute 'sampel'"):
        rotoruq.sampel  # noqa: B018
