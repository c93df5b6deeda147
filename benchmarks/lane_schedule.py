"""How long the full suite takes on two pytest-xdist workers under each way of handing out the
tests, from every test's measured CPU seconds (a simulation, JSON).

CI's main lane (``pytest -q -n auto`` on 2 cores) took 24.1 min while its tests' CPU seconds,
spread evenly over 2 workers, would take about 19. xdist's default scheduler (``load``) gives
each worker a fixed first chunk of the collection (a quarter of its share) and later hands
out the rest of the queue, but never takes back tests a worker already holds; and
``tests/conftest.py`` puts the files holding the slow and MBDyn tests first, so one worker's
first chunk held nearly all the minutes-long tests. ``worksteal`` (pyproject.toml's
``addopts``) lets an idle worker take half of the other one's queue. This script replays both
schedulers' rules on the suite's collection order, with each test lasting its CPU seconds
(the tests are CPU-bound; waiting in a test, for a signal or a server, is not counted):

- the collection order: ``pytest --collect-only -q`` (``tests/conftest.py``'s order), run
  here, or the same order alphabetical by file (``alphabetical_*``: without that sort);
- the seconds of each test: JSON-lines files of ``benchmarks/test_lanes.py --per-test``
  (the fast lane's and ``--marker "not fast"``'s); a test found in none counts 0.05 s.

    python benchmarks/lane_schedule.py FAST.jsonl SLOW.jsonl [--json OUT]

Output: ``tests``, ``measured`` (tests with a measured time), ``cpu_s`` (their sum),
``even_s`` (the sum over the workers: no scheduler does better), and the simulated
makespan of each scheduler and order [s] with each worker's busy seconds.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

from _summary import print_and_save  # noqa: E402  (benchmarks/ is on sys.path)

ROOT = Path(__file__).resolve().parents[1]
UNMEASURED_S = 0.05
MIN_PENDING = 2  # xdist's worksteal: a worker with fewer queued tests asks for more


def load(d: list[float], nodes: int = 2) -> list[float]:
    """Busy seconds of each worker under xdist's ``load`` scheduler: a first chunk of
    ``len(d) // nodes // 4`` consecutive tests each; a worker whose queue drops below a
    quarter of its share of what is left (and that did not just finish a test of >= 0.1 s
    with 2 still queued) is topped up to half of it from the front of the queue."""
    pending = list(range(len(d)))
    chunk = max(len(d) // nodes // 4, 2)
    queues = [pending[k * chunk:(k + 1) * chunk] for k in range(nodes)]
    pending = pending[nodes * chunk:]
    busy = [0.0] * nodes
    while any(queues):
        k = min((i for i in range(nodes) if queues[i]), key=lambda i: busy[i] + d[queues[i][0]])
        last = d[queues[k].pop(0)]
        busy[k] += last
        if pending:
            low = max(2, len(pending) // nodes // 4)
            high = max(2, len(pending) // nodes // 2)
            if len(queues[k]) < low and not (last >= 0.1 and len(queues[k]) >= 2):
                n = high - len(queues[k])
                queues[k] += pending[:n]
                pending = pending[n:]
    return busy


def worksteal(d: list[float], nodes: int = 2) -> list[float]:
    """Busy seconds of each worker under xdist's ``worksteal``: the collection split into
    ``nodes`` consecutive parts; a worker with fewer than ``MIN_PENDING`` queued tests takes
    the last half of the longest queue."""
    pending = list(range(len(d)))
    queues = []
    for i in range(nodes):
        n = len(pending) // (nodes - i)
        queues.append(pending[:n])
        pending = pending[n:]
    busy = [0.0] * nodes
    while any(queues):
        k = min((i for i in range(nodes) if queues[i]), key=lambda i: busy[i] + d[queues[i][0]])
        busy[k] += d[queues[k].pop(0)]
        for i in range(nodes):
            if len(queues[i]) < MIN_PENDING:
                j = max(range(nodes), key=lambda j: len(queues[j]))
                n = min(len(queues[j]) // 2, max(0, len(queues[j]) - MIN_PENDING))
                if j != i and n > 0:
                    if not queues[i]:  # idle until now: it starts when the steal arrives
                        busy[i] = max(busy[i], busy[k])
                    queues[i] += queues[j][-n:]
                    del queues[j][-n:]
    return busy


def collection_order() -> list[str]:
    """The full suite's test ids in the order pytest runs them (``tests/conftest.py``'s)."""
    done = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q",
                           "-p", "no:cacheprovider"], cwd=ROOT, capture_output=True, text=True)
    ids = [ln.strip() for ln in done.stdout.splitlines() if "::" in ln]
    if not ids:
        raise SystemExit("pytest --collect-only listed no test:\n" + done.stderr[-3000:])
    return ids


def simulate(order: list[str], seconds: dict[str, float]) -> dict:
    """Both schedulers on ``order`` and on the same tests alphabetical by file."""
    alphabetical = sorted(order, key=lambda t: t.split("::")[0])  # stable: in-file order kept
    d = [seconds.get(t, UNMEASURED_S) for t in order]
    out: dict = {"tests": len(order), "measured": sum(t in seconds for t in order),
                 "cpu_s": round(sum(d), 1), "even_s": round(sum(d) / 2, 1)}
    runs: dict[str, Callable[[list[float]], list[float]]] = {"load": load,
                                                              "worksteal": worksteal}
    for label, ids in (("", order), ("alphabetical_", alphabetical)):
        times = [seconds.get(t, UNMEASURED_S) for t in ids]
        for name, run in runs.items():
            busy = run(times)
            out[f"{label}{name}_s"] = round(max(busy), 1)
            out[f"{label}{name}_workers_s"] = [round(b, 1) for b in busy]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("per_test", nargs="+", help="JSON-lines files of test_lanes.py --per-test")
    ap.add_argument("--json", help="save the result here")
    args = ap.parse_args()
    seconds: dict[str, float] = {}
    for path in args.per_test:
        for line in Path(path).read_text(encoding="utf-8").splitlines():
            if line.strip():
                row = json.loads(line)
                seconds[row["nodeid"]] = row["cpu_s"]
    print_and_save(simulate(collection_order(), seconds), args.json)


if __name__ == "__main__":
    main()
