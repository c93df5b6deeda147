"""The minimum-versions CI job pins every dependency to its lower bound in pyproject.toml."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / ".ci" / "min_constraints.py"


def _pins(*extras: str) -> dict[str, str]:
    out = subprocess.run([sys.executable, str(SCRIPT), *extras], capture_output=True, text=True,
                         check=True, timeout=60).stdout
    return dict(line.split("==") for line in out.split())


def test_every_requirement_is_pinned_to_its_lower_bound():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    pins = _pins("test")
    reqs = project["dependencies"] + project["optional-dependencies"]["test"]
    for req in reqs:
        name = re.match(r"[A-Za-z0-9._-]+", req).group(0).lower()
        low = re.search(r">=\s*([0-9][^,\s]*)", req).group(1)
        assert pins[name] == low, req
    assert len(pins) == len({re.match(r"[A-Za-z0-9._-]+", r).group(0).lower() for r in reqs})
    # NumPy 2.3: below it the rotor kernel and its numpy oracle are not bitwise equal
    assert pins["numpy"] == "2.3"


def test_an_unknown_extra_is_an_error():
    proc = subprocess.run([sys.executable, str(SCRIPT), "tset"], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode != 0 and "no extra 'tset'" in proc.stderr
