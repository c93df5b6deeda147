"""Number blocks in the docs that are generated from saved benchmark and script results.

A block in a docs page (Markdown) reads::

    <!-- generated: python benchmarks/gp_fit.py --summary benchmarks/results/gp_fit.json -->
    ...the command's output, verbatim...
    <!-- end generated -->

The command prints text from a saved JSON file (never a new measurement), so it is fast and
deterministic. ``python docs/_ext/generated_blocks.py`` rewrites every block from its command;
``--check`` only reports the blocks that differ (``tests/test_docs.py`` runs the check).
Commands run in this process (``runpy``, with the script's folder on ``sys.path`` as for
``python script.py``) from the repository root, so the imports are paid once.

Each saved JSON records what it measured (``provenance``: the commit and the digests of the
rotoruq modules the benchmark imports; ``benchmarks/_provenance.py``). When the docs are built
(this module is a Sphinx extension), every block whose JSON measured code that has changed
since gets a warning box under it: ``stale: ... measured at <commit> before changes to
<modules>``. The box is computed at build time and never written into the page, so the
check above stays a comparison of the page with the JSON, and CI stays green while the box
stays visible until the benchmark is run again. ``python docs/_ext/generated_blocks.py
--stale`` lists the stale JSONs.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import runpy
import shlex
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
BLOCK = re.compile(
    r"^(?P<indent>[ ]*)(<!-- generated: (?P<cmd>[^\n]+?) -->\n)(?P<body>.*?)"
    r"^(?P=indent)(<!-- end generated -->)$", re.S | re.M)


@dataclass(frozen=True, eq=False)
class Block:
    """One generated block: the page it is in, its command, its current text (without the
    indentation of a block inside a list item) and that indentation."""

    page: Path
    command: str
    text: str
    indent: str = ""


def blocks(docs: Path = DOCS) -> list[Block]:
    """Every generated block of every Markdown page under ``docs`` (build output excluded),
    and of README.md when ``docs`` is the project's."""
    found = []
    pages = sorted(docs.rglob("*.md")) + ([ROOT / "README.md"] if docs == DOCS else [])
    for page in pages:
        if "_build" in page.parts:
            continue
        for m in BLOCK.finditer(page.read_text(encoding="utf-8")):
            found.append(Block(page, m["cmd"], _dedent(m["body"], m["indent"]), m["indent"]))
    return found


def run_command(command: str) -> str:
    """The output of ``python SCRIPT ARGS...`` run in this process from the repository root."""
    argv = shlex.split(command)
    if len(argv) < 2 or argv[0] != "python" or not argv[1].endswith(".py"):
        raise ValueError(f"a generated block's command must be 'python SCRIPT.py ...', "
                         f"got {command!r}")
    script = ROOT / argv[1]
    if not script.is_file():
        raise FileNotFoundError(f"generated block command {command!r}: no script {script}")
    out = io.StringIO()
    old_argv, old_path, old_cwd = sys.argv, list(sys.path), os.getcwd()
    try:
        sys.argv = [str(script), *argv[2:]]
        sys.path.insert(0, str(script.parent))
        os.chdir(ROOT)
        with contextlib.redirect_stdout(out):
            try:
                runpy.run_path(str(script), run_name="__main__")
            except SystemExit as exc:
                if exc.code not in (None, 0):
                    raise RuntimeError(f"{command!r} exited with {exc.code}") from None
    finally:
        sys.argv, sys.path[:] = old_argv, old_path
        os.chdir(old_cwd)
    return out.getvalue().strip("\n") + "\n"


def _dedent(text: str, indent: str) -> str:
    return "".join(ln[len(indent):] if ln.startswith(indent) else ln
                   for ln in text.splitlines(keepends=True))


def _indent(text: str, indent: str) -> str:
    return "".join(indent + ln if ln.strip() else ln for ln in text.splitlines(keepends=True))


def regenerate(page: Path) -> str:
    """The page's text with every block replaced by its command's output (indented like the
    block's markers, so a block can sit inside a list item)."""
    def sub(m: re.Match) -> str:
        ind = m["indent"]
        return ind + m[2] + _indent(run_command(m["cmd"]), ind) + ind + m[5]
    return BLOCK.sub(sub, page.read_text(encoding="utf-8"))


def results_of(command: str) -> list[str]:
    """The saved JSON files a block's command prints from: its ``.json`` arguments, or the
    benchmark's default ``benchmarks/results/<name>.json`` when it names none."""
    argv = shlex.split(command)
    named = [a for a in argv[2:] if a.endswith(".json")]
    default = f"benchmarks/results/{Path(argv[1]).stem}.json"
    return named or ([default] if (ROOT / default).is_file() else [])


def _provenance():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import _provenance
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return _provenance


def stale_notes(command: str) -> list[str]:
    """``stale: ...`` lines for the JSONs ``command`` prints from (none when each measured
    the code as it is now)."""
    prov = _provenance()
    return [n for n in (prov.stale_note(j) for j in results_of(command)) if n]


def with_stale_notes(text: str) -> str:
    """``text`` (a page) with a warning box after every generated block whose JSON is stale."""
    def sub(m: re.Match) -> str:
        notes = stale_notes(m["cmd"])
        if not notes:
            return m[0]
        box = "\n:::{warning}\n" + "\n\n".join(notes) + "\n:::\n"
        return m[0] + "\n" + _indent(box, m["indent"]).rstrip("\n")
    return BLOCK.sub(sub, text)


def _source_read(app, docname: str, source: list[str]) -> None:
    if "<!-- generated:" in source[0]:
        source[0] = with_stale_notes(source[0])


def setup(app) -> dict:
    """Sphinx extension: the stale notes under the generated blocks, at build time."""
    app.connect("source-read", _source_read)
    return {"parallel_read_safe": True}


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if "--stale" in args:
        for b in blocks():
            for note in stale_notes(b.command):
                print(f"{b.page.relative_to(ROOT)}: {note}")
        return 0
    stale = []
    for page in sorted({b.page for b in blocks()}):
        text = regenerate(page)
        if text != page.read_text(encoding="utf-8"):
            stale.append(page)
            if "--check" not in args:
                page.write_text(text, encoding="utf-8")
    for page in stale:
        print(f"{'stale' if '--check' in args else 'rewritten'}: {page.relative_to(ROOT)}")
    return 1 if stale and "--check" in args else 0


if __name__ == "__main__":
    raise SystemExit(main())
