"""One list of public names: ``rotoruq._PUBLIC`` (name -> defining module).

``__all__`` is its keys, every name loads lazily from it in a fresh interpreter, and the
``if TYPE_CHECKING:`` imports at the end of ``rotoruq/__init__.py`` (what type checkers and IDEs
read) name exactly the same set, each from the same module. After editing ``_PUBLIC``, rewrite
that block with ``python tests/test_public_api.py`` (it runs ruff's import sorting on it).
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import rotoruq

INIT = Path(rotoruq.__file__)
MARKER = "if TYPE_CHECKING:  # the same names, eagerly, for type checkers and IDEs\n"


def _type_checking_imports(source: str) -> dict[str, str]:
    """name -> module (relative, as in ``_PUBLIC``) of every import under ``if TYPE_CHECKING``
    that re-exports a name (``import x as x``); a re-export under another name is an error."""
    out: dict[str, str] = {}
    for node in ast.parse(source).body:
        if not (isinstance(node, ast.If) and isinstance(node.test, ast.Name)
                and node.test.id == "TYPE_CHECKING"):
            continue
        for imp in node.body:
            if not isinstance(imp, ast.ImportFrom) or not imp.level:
                continue  # `from typing import Any` and the like are not public names
            module = "." * imp.level + (imp.module or "")
            for alias in imp.names:
                assert alias.asname == alias.name, f"{alias.name} re-exported as {alias.asname}"
                assert alias.name not in out, f"{alias.name} imported twice"
                out[alias.name] = module
    return out


def _defines(module: str, name: str) -> str:
    """``_PUBLIC``'s form of ``from module import name``: a submodule names itself."""
    sub = module + ("" if module.endswith(".") else ".") + name
    return sub if Path(rotoruq.__file__).parent.joinpath(*sub.strip(".").split(".")).with_suffix(
        ".py").is_file() else module


def test_all_is_the_one_list():
    assert rotoruq.__all__ == ["__version__", *rotoruq._PUBLIC]
    assert len(set(rotoruq.__all__)) == len(rotoruq.__all__)


def test_the_type_checking_block_names_the_same_set_from_the_same_modules():
    imports = _type_checking_imports(INIT.read_text(encoding="utf-8"))
    found = {name: _defines(module, name) for name, module in imports.items()}
    missing = sorted(set(rotoruq._PUBLIC) - set(found))
    extra = sorted(set(found) - set(rotoruq._PUBLIC))
    moved = sorted(n for n in set(found) & set(rotoruq._PUBLIC) if found[n] != rotoruq._PUBLIC[n])
    assert not (missing or extra or moved), (
        f"TYPE_CHECKING block out of step with _PUBLIC: missing {missing}, extra {extra}, "
        f"from another module {moved}; run `python tests/test_public_api.py`")


def test_every_name_resolves_lazily_in_a_fresh_interpreter():
    """``import rotoruq`` defines none of the names; each then loads from its module."""
    probe = """
import importlib, inspect, json, sys
import rotoruq as rq
eager = sorted(n for n in rq._PUBLIC if n in vars(rq))
bad = []
for name, rel in rq._PUBLIC.items():
    value = getattr(rq, name)
    module = importlib.import_module(rel, "rotoruq")
    if inspect.ismodule(value):
        ok = value is module
    else:
        ok = value is getattr(module, name)
    if not ok:
        bad.append(name)
print(json.dumps({"eager": eager, "bad": bad, "typing": "typing" in sys.modules}))
"""
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, timeout=300)
    got = json.loads(out.stdout)
    assert got["eager"] == [] and got["bad"] == [], got
    assert rotoruq.presets.__name__ == "rotoruq.rotor.presets"
    assert rotoruq.errors.__name__ == "rotoruq.errors"


def test_import_rotoruq_imports_no_typing():
    """The driver client imports rotoruq: the package root stays free of ``typing``."""
    out = subprocess.run([sys.executable, "-c", "import sys, rotoruq; "
                          "print('typing' in sys.modules)"], capture_output=True, text=True,
                         check=True, timeout=60)
    assert out.stdout.strip() == "False"


def type_checking_block() -> str:
    """The ``if TYPE_CHECKING`` block that ``_PUBLIC`` implies (before ruff sorts it)."""
    lines = [MARKER]
    for name, module in rotoruq._PUBLIC.items():
        parent, _, last = module.rpartition(".")
        if last == name and not hasattr(__import__("importlib").import_module(
                module, "rotoruq"), name):
            lines.append(f"    from {parent or '.'} import {name} as {name}\n")
        else:
            lines.append(f"    from {module} import {name} as {name}\n")
    return "".join(lines)


def main() -> None:
    """Rewrite the TYPE_CHECKING block of ``rotoruq/__init__.py`` from ``_PUBLIC``."""
    text = INIT.read_text(encoding="utf-8")
    head = text[: text.index(MARKER)]
    INIT.write_text(head + type_checking_block(), encoding="utf-8")
    subprocess.run([sys.executable, "-m", "ruff", "check", "--fix", "--select", "I", "-q",
                    str(INIT)], check=False)
    print(f"rewrote the TYPE_CHECKING block of {INIT}")


if __name__ == "__main__":
    main()
