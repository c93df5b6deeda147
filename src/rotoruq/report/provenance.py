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
    ``meta["failures"]``); None when the step recorded nothing."""
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
    """The commit of rotoruq's source checkout (None when it is not one, or git is absent)."""
    src = Path(__file__).resolve().parents[1]
    try:
        out = subprocess.run(["git", "-C", str(src), "rev-parse", "--short=12", "HEAD"],
                             capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    if out.returncode != 0:
        return None
    return out.stdout.strip() or None
