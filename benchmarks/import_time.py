"""Cost of ``import rotoruq`` (lazy, PEP 562) against loading every public name at once.

Each case runs in a fresh interpreter ``--repeat`` times; the minimum wall time is kept. Prints
JSON: seconds and rotoruq modules loaded per case, and the ratio eager / lazy (how much a user
who needs one layer saves). Cases:

- ``lazy``: ``import rotoruq``
- ``params``: ``import rotoruq`` then ``rotoruq.ParameterSpace`` (scipy.stats comes in)
- ``hover``: ``import rotoruq.rotor.hover`` (the rotor layer alone)
- ``eager``: ``import rotoruq`` then every name of ``rotoruq.__all__`` (what 0.1 did on import)
- ``chapter_workers``: the modules of ``rotoruq reproduce``'s chapter workers
  (``rotoruq.study.cmd_reproduce.CHAPTER_MODULES``): what each spawned worker imported before
  it ran a chapter, and what the workers' fork server now imports once per run (issue 34)

    python benchmarks/import_time.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

CASES = {
    "lazy": "import rotoruq",
    "params": "import rotoruq; rotoruq.ParameterSpace",
    "hover": "import rotoruq.rotor.hover",
    "eager": "import rotoruq; [getattr(rotoruq, n) for n in rotoruq.__all__]",
    "chapter_workers": "import importlib; from rotoruq.study.cmd_reproduce import CHAPTER_MODULES;"
                       " [importlib.import_module(m) for m in CHAPTER_MODULES]",
}

PROBE = """
import sys, time
t = time.perf_counter()
{code}
dt = time.perf_counter() - t
print(dt, sum(1 for m in sys.modules if m == "rotoruq" or m.startswith("rotoruq.")))
"""


def measure(code: str, repeat: int) -> tuple[float, int]:
    """(minimum seconds, rotoruq modules loaded) over ``repeat`` fresh interpreters."""
    best, modules = float("inf"), 0
    for _ in range(repeat):
        out = subprocess.run([sys.executable, "-c", PROBE.format(code=code)], check=True,
                             capture_output=True, text=True).stdout.split()
        best, modules = min(best, float(out[0])), int(out[1])
    return best, modules


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    res = {name: measure(code, args.repeat) for name, code in CASES.items()}
    out = {f"{name}_s": round(t, 4) for name, (t, _) in res.items()}
    out.update({f"{name}_modules": m for name, (_, m) in res.items()})
    out["eager_over_lazy"] = round(res["eager"][0] / res["lazy"][0], 1)
    out["eager_over_hover"] = round(res["eager"][0] / res["hover"][0], 1)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
