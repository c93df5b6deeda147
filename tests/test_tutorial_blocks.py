"""Every Python code block of the tutorials (docs/tutorials/*.md) and of docs/index.md runs.

A page's ```` ```python ```` blocks run in order in one fresh interpreter, in an empty temporary
folder, sharing one namespace (like a notebook's cells): a later block may use what an earlier
one defined. A block that is not Python (shell, TOML, a solver's input, printed output) is not
tagged ``python`` and is not run. A Python block that cannot run here says so on the line
before its fence::

    <!-- skip: needs MBDyn -->
    ```python
    ...
    ```

and is reported as skipped with that reason (the comment is invisible on the site). The
convention is described in docs/architecture.md ("Tutorials that run").
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

import rotoruq

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted((ROOT / "docs" / "tutorials").glob("*.md")) + [ROOT / "docs" / "index.md"]
FENCE = re.compile(r"^(?P<indent>[ ]*)(?P<ticks>`{3,})(?P<info>[^`\n]*)$")
SKIP = re.compile(r"^\s*<!--\s*skip:\s*(?P<reason>.*?)\s*-->\s*$")
#: the width a code line fits in full on the site (docs/conf.py, docs/_static/rotoruq.css)
MAX_COLUMNS = 100


@dataclass(frozen=True)
class Block:
    page: Path
    line: int  # 1-based line of the block's first code line
    code: str
    skip: str | None  # the reason, for a block marked <!-- skip: ... -->

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def python_blocks(page: Path) -> list[Block]:
    """The ```` ```python ```` blocks of a Markdown page, dedented (a block may sit in a list
    item), with their skip reasons."""
    lines = page.read_text(encoding="utf-8").splitlines()
    found, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, ticks = m["indent"], m["ticks"]
        end = i + 1
        while end < len(lines) and lines[end].rstrip() != indent + ticks:
            end += 1
        if end == len(lines):
            raise AssertionError(f"{page.name}:{i + 1}: code block without its closing fence")
        info = m["info"].strip().split()
        if info and info[0] == "python":
            before = next((ln for ln in reversed(lines[:i]) if ln.strip()), "")
            skip = SKIP.match(before)
            body = [ln[len(indent):] if ln.startswith(indent) else ln for ln in lines[i + 1:end]]
            found.append(Block(page, i + 2, "\n".join(body) + "\n",
                               skip["reason"] if skip else None))
        i = end + 1
    return found


BLOCKS = {page: python_blocks(page) for page in PAGES}
RUN = [p for p in PAGES if any(b.skip is None for b in BLOCKS[p])]
SKIPPED = [b for p in PAGES for b in BLOCKS[p] if b.skip is not None]

# Runs the blocks of one page (a JSON list of {where, line, code}) in one namespace; a
# traceback names the page and its line.
RUNNER = textwrap.dedent("""\
    import json, sys
    namespace = {"__name__": "__main__"}
    for block in json.load(open(sys.argv[1], encoding="utf-8")):
        code = "\\n" * (block["line"] - 1) + block["code"]
        exec(compile(code, block["page"], "exec"), namespace)
        print("ran", block["where"], flush=True)
    """)


def test_the_tutorials_have_python_blocks():
    assert len([b for bs in BLOCKS.values() for b in bs]) >= 18
    for block in SKIPPED:
        assert block.skip, f"{block.where}: say why the block is skipped (<!-- skip: why -->)"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_code_lines_fit_the_page(page):
    long = [f"{b.where}+{k}: {len(ln)} columns" for b in BLOCKS[page]
            for k, ln in enumerate(b.code.splitlines()) if len(ln) > MAX_COLUMNS]
    assert not long, f"lines longer than {MAX_COLUMNS} columns scroll on the site: {long}"


# slow: about 45 s for all pages once numba's kernels are cached, minutes in a fresh environment
# (the chains' and the rotor's kernels compile on first use)
@pytest.mark.slow
@pytest.mark.parametrize("page", RUN, ids=lambda p: p.name)
def test_tutorial_page_runs(page, tmp_path):
    blocks = [{"where": b.where, "page": str(b.page), "line": b.line, "code": b.code}
              for b in BLOCKS[page] if b.skip is None]
    (tmp_path / "blocks.json").write_text(json.dumps(blocks), encoding="utf-8")
    (tmp_path / "run_blocks.py").write_text(RUNNER, encoding="utf-8")
    # the rotoruq under test, whatever the folder (PYTHONPATH=src is relative to the checkout)
    path = [str(Path(rotoruq.__file__).resolve().parents[1])]
    path += [str(Path(p).resolve()) for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
             if p]
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": os.pathsep.join(path)}
    done = subprocess.run([sys.executable, "run_blocks.py", "blocks.json"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=600, env=env)
    assert done.returncode == 0, (f"{page.relative_to(ROOT)}: a block failed\n"
                                  + done.stdout[-2000:] + done.stderr[-5000:])
    assert done.stdout.count("ran ") == len(blocks), done.stdout


@pytest.mark.parametrize("block", SKIPPED, ids=lambda b: b.where)
def test_tutorial_block_marked_skip(block):
    pytest.skip(f"{block.where}: {block.skip}")
