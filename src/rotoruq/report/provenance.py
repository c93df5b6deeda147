"""What a saved step records about how it was computed: its failed model evaluations, and
the source checkout rotoruq runs from. The report's provenance block and ``rotoruq show``
read them here."""

from __future__ import annotations

import subprocess
from collections.abc import Mapping
from pathlib import Path

from ..results import StepResult

__all__ = ["failed_evaluations", "git_commit"]


def failed_evaluations(res: StepResult) -> tuple[int, dict[str, int]] | None:
    """(count, reason -> count) of a step's failed model evaluations, as its run recorded
    them (``meta["failed_evaluations"]``: ``{"count", "reasons"}``; older steps: a count in
    ``meta["failures"]``); None when the step recorded nothing.

    Examples
    --------
    >>> failed_evaluations(StepResult("s", "sampling", meta={"failed_evaluations": {
    ...     "count": 3, "reasons": {"solver diverged": 2, "timeout": 1}}}))
    (3, {'solver diverged': 2, 'timeout': 1})
    >>> failed_evaluations(StepResult("s", "sampling")) is None
    True
    """
    rec = res.meta.get("failed_evaluations")
    if isinstance(rec, Mapping):
        reasons = rec.get("reasons") or {}
        reasons = {str(k): int(v) for k, v in reasons.items()} if isinstance(
            reasons, Mapping) else {}
        try:
            return int(rec.get("count", sum(reasons.values()))), reasons
        except (TypeError, ValueError):
            return None
    n = res.meta.get("failures")
    if isinstance(n, int | float) and not isinstance(n, bool):
        return int(n), {}
    return None


def git_commit() -> str | None:
    """The commit of rotoruq's source checkout: only when rotoruq runs from its own source
    tree (``src/rotoruq`` under a ``pyproject.toml`` naming rotoruq at the top of a git work
    tree), never the commit of a repository an installed copy happens to sit in. None
    otherwise, or without git."""
    root = Path(__file__).resolve().parents[3]
    try:
        if 'name = "rotoruq"' not in (root / "pyproject.toml").read_text(encoding="utf-8"):
            return None
        out = subprocess.run(["git", "-C", str(root), "rev-parse", "--show-toplevel",
                              "--short=12", "HEAD"], capture_output=True, text=True, timeout=10)
    except (OSError, UnicodeDecodeError, subprocess.SubprocessError):
        return None
    lines = out.stdout.split()
    if out.returncode != 0 or len(lines) != 2 or Path(lines[0]).resolve() != root:
        return None
    return lines[1]
