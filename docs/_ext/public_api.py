"""Write the API reference page (``api.rst``) from the package's public names at build time.

The page lists ``rotoruq.__all__`` grouped by the module that defines each name, then the public
names of each subpackage that has an ``__all__`` and that the top level does not re-export.
Generated, not written by hand, so a name added to ``__all__`` is documented on the next build
and a removed one disappears (``tests/test_docs.py`` checks the page against ``__all__``).
"""

from __future__ import annotations

import importlib
import inspect
from pathlib import Path

#: subpackages whose ``__all__`` is part of the public API
SUBPACKAGES = ("rotoruq.params", "rotoruq.evaluation", "rotoruq.methods.mcmc", "rotoruq.mbdyn",
               "rotoruq.steps")

HEADER = """\
API reference
=============

Generated from ``rotoruq.__all__`` and the subpackages' ``__all__`` (``docs/_ext/public_api.py``).
Every name is importable as written; the top-level names load on first use.
"""


def _section(title: str, char: str, module: str, names: list[str]) -> list[str]:
    lines = ["", title, char * len(title), "", f".. currentmodule:: {module}", "",
             ".. autosummary::", "   :toctree: generated", ""]
    lines += [f"   {name}" for name in names]
    return lines


def api_page() -> str:
    """The reST text of the API page."""
    rq = importlib.import_module("rotoruq")
    by_module: dict[str, list[str]] = {}
    for name, rel in rq._PUBLIC.items():  # defining module of each lazily loaded public name
        if rel.rpartition(".")[2] == name and inspect.ismodule(getattr(rq, name)):
            continue  # a public submodule (named below)
        by_module.setdefault("rotoruq" + rel, []).append(name)
    lines = HEADER.splitlines()
    lines += ["", "Top level: ``import rotoruq as rq``", "-" * 35, "",
              "``rq.errors`` is :mod:`rotoruq.errors`, ``rq.presets`` is "
              ":mod:`rotoruq.rotor.presets`."]
    for module in sorted(by_module):
        lines += _section(f"From ``{module}``", "~", "rotoruq", sorted(by_module[module]))
    top = set(rq.__all__)
    lines += ["", "Subpackages", "-" * 11]
    for sub in SUBPACKAGES:
        mod = importlib.import_module(sub)
        names = sorted(n for n in mod.__all__ if n not in top)
        if names:
            lines += _section(f"``{sub}``", "~", sub, names)
    return "\n".join(lines) + "\n"


def write_api_page(app, config) -> None:  # noqa: ARG001 (Sphinx's config-inited signature)
    path = Path(app.srcdir) / "api.rst"
    text = api_page()
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


def setup(app):
    # config-inited runs before autosummary (builder-inited) scans the sources for its stubs
    app.connect("config-inited", write_api_page)
    return {"parallel_read_safe": True}
