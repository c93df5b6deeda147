"""Cost of the integrity check (``PRAGMA quick_check``) run when an evaluation store is opened.

Prints JSON: for stores of growing size (rows of a 2-input, 2-output model, one in ten a failure
keeping 8 KiB of solver output), the file size and the best-of-3 time to open the store with and
without the check (the check runs once per file and process). Target: well under a second
for 100,000 evaluations.

    python benchmarks/store_open.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from rotoruq.evaluation.store import _CHECKED, NewRecord, Store

KW = dict(study="s", model="m", names_in=("a", "b"), names_out=("f", "g"))


def fill(path: Path, n: int) -> None:
    st = Store(path)
    rng = np.random.default_rng(0)
    x = rng.normal(size=(n, 2))
    recs = [NewRecord(x[i], None, "failed", "solver diverged", "o" * 8192, "")
            if i % 10 == 0 else NewRecord(x[i], x[i] ** 2) for i in range(n)]
    for s in range(0, n, 5000):
        st.add(recs[s : s + 5000], **KW)
    st.close()


def open_time(path: Path, check: bool, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        _CHECKED.clear()  # as in a new process
        Store(path, check=check).close()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    sizes = [1_000, 10_000] if args.quick else [1_000, 10_000, 100_000]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            path = Path(tmp) / f"e{n}.db"
            fill(path, n)
            rows.append({
                "evaluations": n,
                "file_mb": round(path.stat().st_size / 2**20, 2),
                "open_s": round(open_time(path, False), 5),
                "open_checked_s": round(open_time(path, True), 5),
            })
    print(json.dumps({"benchmark": "store_open", "stores": rows}, indent=2))


if __name__ == "__main__":
    main()
