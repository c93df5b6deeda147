"""Print a pip constraints file that pins every dependency to the lowest version pyproject.toml
allows: ``name>=X`` becomes ``name==X`` (dependencies and the extras named on the command line).

    python .ci/min_constraints.py test > min.txt
    pip install -c min.txt -e ".[test]"

A requirement without a lower bound is an error: the minimum-versions job could not test it.
"""

from __future__ import annotations

import re
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REQ = re.compile(r"^\s*([A-Za-z0-9][A-Za-z0-9._-]*)\s*(\[[^\]]*\])?\s*(.*)$")


def lower_bounds(extras: list[str]) -> dict[str, str]:
    """Distribution name -> lowest allowed version, from pyproject's dependencies and extras."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = list(project.get("dependencies", []))
    optional = project.get("optional-dependencies", {})
    for extra in extras:
        if extra not in optional:
            sys.exit(f"min_constraints: no extra {extra!r} in pyproject.toml; "
                     f"have {', '.join(optional)}")
        reqs += optional[extra]
    out: dict[str, str] = {}
    for req in reqs:
        m = REQ.match(req.split(";")[0])
        if not m:
            sys.exit(f"min_constraints: cannot read requirement {req!r}")
        name, spec = m.group(1).lower().replace("_", "-"), m.group(3)
        low = re.search(r">=\s*([0-9][^,\s]*)", spec)
        if not low:
            sys.exit(f"min_constraints: {req!r} has no lower bound (>=)")
        if name in out and out[name] != low.group(1):
            sys.exit(f"min_constraints: {name} has two lower bounds, {out[name]} and "
                     f"{low.group(1)}: make them agree")
        out[name] = low.group(1)
    return out


if __name__ == "__main__":
    for name, version in sorted(lower_bounds(sys.argv[1:]).items()):
        print(f"{name}=={version}")
