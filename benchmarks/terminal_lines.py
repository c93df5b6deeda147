"""How many lines ``rotoruq reproduce`` prints, and of which kind (issue 36: 504 lines, 307 of
them one per chain or replication, before the methods' messages were gathered under their
step).

Runs ``python -m rotoruq reproduce [--quick]`` in a fresh folder with stdout and stderr
pipes (no terminal: no bar, the status line every 15 s) from the sources ``--src`` (default
this tree's), counts the lines, and writes ``benchmarks/results/terminal_lines.json``
(one entry per ``--label``, kept across runs)::

    python benchmarks/terminal_lines.py --quick --label after
    git archive <commit> src | tar -x -C /tmp/before
    python benchmarks/terminal_lines.py --quick --label before --src /tmp/before/src
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _provenance import ROOT, provenance  # noqa: E402

OUT = ROOT / "benchmarks" / "results" / "terminal_lines.json"

#: Line kinds counted apart (the first pattern that matches a line names its kind).
KINDS = {
    "step lines": r"^\[[^\]]+\] \d+/\d+ \S+: (running|done|reused|skipped)",
    "status lines": r"^  \S.*: \S+ running, \d+:\d\d elapsed",
    "method messages": r"(calibrate_bayes:|emulator LOO|emulator leave-one-out|self-check "
                       r"reused|refinement round)",
    "warnings": r"^warning: ",
    "compile notices": r"^compiling ",
    "report lines": r"^report: ",
    "summary and verdict": r"^(summary of|  \S|      !|\d+ warning|verdict:|results:)",
}


def count(text: str) -> dict[str, int]:
    """Lines of ``text`` by kind (:data:`KINDS`, else ``"other"``) and in all."""
    out = dict.fromkeys([*KINDS, "other"], 0)
    lines = text.splitlines()
    for line in lines:
        kind = next((k for k, pat in KINDS.items() if re.search(pat, line)), "other")
        out[kind] += 1
    out["total"] = len(lines)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="rotoruq reproduce --quick")
    ap.add_argument("--label", default="after", help="name of this entry in the JSON")
    ap.add_argument("--src", default=str(ROOT / "src"), help="rotoruq sources to run")
    args = ap.parse_args()
    env = {**os.environ, "PYTHONPATH": str(Path(args.src).resolve())}
    env.pop("ROTORUQ_STATUS_INTERVAL", None)
    prov = provenance(modules=["rotoruq.study.cli"])
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "rotoruq", "reproduce",
                               *(["--quick"] if args.quick else []), "--out", "out"],
                              capture_output=True, text=True, cwd=tmp, env=env)
        seconds = time.perf_counter() - t0
    if proc.returncode not in (0, 3):
        sys.exit(f"reproduce exited {proc.returncode}:\n{proc.stderr[-2000:]}")
    result = {"command": "rotoruq reproduce" + (" --quick" if args.quick else ""),
              "src": args.src, "exit_code": proc.returncode, "seconds": round(seconds, 1),
              "stdout": count(proc.stdout), "stderr": count(proc.stderr),
              "total_lines": len(proc.stdout.splitlines()) + len(proc.stderr.splitlines()),
              "provenance": prov}
    doc = json.loads(OUT.read_text()) if OUT.is_file() else {}
    doc.setdefault("quick" if args.quick else "full", {})[args.label] = result
    OUT.write_text(json.dumps(doc, indent=1) + "\n")
    print(json.dumps({k: v for k, v in result.items() if k != "provenance"}, indent=1))


if __name__ == "__main__":
    main()
