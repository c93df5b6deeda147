"""Steps a run skipped: the report shows each in its place with the run's reason.

A step whose ``needs`` (outside software such as MBDyn) were not found is skipped by the run
(:attr:`rotoruq.study.runner.StudyRun.skip_reasons`), which records the reason in
``study.json`` (``"skipped"``: step name -> reason). A step with a saved result is shown by
its result instead: the record only speaks for steps the report has no result of.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .escape import text as e

__all__ = ["skipped_steps", "skipped_note"]


def skipped_steps(info: Mapping[str, Any], results: Mapping[str, Any]) -> list[tuple[str, str]]:
    """``(step, reason)`` of the steps ``study.json`` records as skipped and that have no
    result, in the study's step order.

    Parameters
    ----------
    info : mapping
        The study's ``study.json``.
    results : mapping of str to StepResult
        The steps' results, by step name.

    Examples
    --------
    >>> info = {"steps": ["a", "mf"], "skipped": {"mf": "needs MBDyn, not found here"}}
    >>> skipped_steps(info, {"a": object()})
    [('mf', 'needs MBDyn, not found here')]
    """
    recorded = info.get("skipped") or {}
    if not isinstance(recorded, Mapping):
        return []
    order = [s for s in info.get("steps") or [] if s in recorded]
    order += sorted(s for s in recorded if s not in order)
    return [(str(s), str(recorded[s])) for s in order if s not in results]


def skipped_note(info: Mapping[str, Any], step: str, reason: str) -> str:
    """The HTML paragraph in a skipped step's section: its type and title, and why the run
    skipped it.

    Examples
    --------
    >>> print(skipped_note({"step_types": {"mf": "multifidelity"}}, "mf", "needs MBDyn"))
    <p class=note><b>Skipped by the run</b> (multifidelity): needs MBDyn.</p>
    """
    kind = (info.get("step_types") or {}).get(step)
    title = (info.get("titles") or {}).get(step)
    what = ", ".join(str(x) for x in (kind, title) if x)
    return (f"<p class=note><b>Skipped by the run</b>{f' ({e(what)})' if what else ''}: "
            f"{e(reason.rstrip('.'))}.</p>")
