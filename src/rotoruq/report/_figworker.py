"""Draw report figures in a second process (``python -m rotoruq.report._figworker JOBS``).

The report splits its figure jobs (one per step with figures) between itself and this worker:
each side claims a job by creating ``<i>.claim`` in the job folder (``O_EXCL``, so a job is
drawn exactly once), the worker from the front of the list and the report from the back. The
worker writes each job's figures (PNG bytes and axis labels) to ``<i>.pkl`` by an atomic
rename. A job names its figure hook as ``module:qualname`` and its study by the results
folder, so the worker needs nothing from the parent process but this folder: it reads the
saved results itself. A plain subprocess (not multiprocessing) never re-imports the caller's
``__main__``, so scripts without an ``if __name__ == "__main__"`` guard work too.
"""

from __future__ import annotations

import importlib
import json
import os
import pickle
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

JOBS_FILE = "jobs.json"


def claim(job_dir: Path, i: int) -> bool:
    """Claim job ``i``; False when the other side has it already."""
    try:
        os.close(os.open(job_dir / f"{i}.claim", os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return False
    return True


def hook_name(hook: Callable) -> str | None:
    """``module:qualname`` of a hook another process can import, else None (a lambda or a
    function defined inside another)."""
    module, qualname = getattr(hook, "__module__", None), getattr(hook, "__qualname__", "")
    if not module or module == "__main__" or "<" in qualname:
        return None
    return f"{module}:{qualname}"


def load_hook(name: str) -> Callable:
    module, qualname = name.split(":", 1)
    obj: Any = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


def run(job_dir: Path) -> None:
    from ..results import load_results
    from .html import draw_step

    jobs = json.loads((job_dir / JOBS_FILE).read_text(encoding="utf-8"))
    studies: dict[str, Any] = {}
    for i, job in enumerate(jobs):
        if not claim(job_dir, i):
            break  # the report has worked through the list from the back to here
        folder = job["folder"]
        if folder not in studies:
            studies[folder] = load_results(folder)
        drawn = draw_step(load_hook(job["hook"]), studies[folder], job["step"],
                          job["study"], *job["context"])
        tmp = job_dir / f"{i}.pkl.tmp"
        tmp.write_bytes(pickle.dumps(drawn))
        os.replace(tmp, job_dir / f"{i}.pkl")


if __name__ == "__main__":
    run(Path(sys.argv[1]))
