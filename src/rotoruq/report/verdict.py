"""A run's own verdict, computed from its saved steps: the first thing the report shows and the
last thing ``rotoruq run`` prints.

Four lines, each with the counts it rests on: validation comparisons within k u_val (ASME
V&V 20, as each ``validation`` step records them; comparisons on a calibration's own data
are consistency checks, counted apart and never as validation), self-checks (simulation-based
calibration) that failed, failed model evaluations, steps with diagnostic warnings. A failed
self-check is named next to what rests on it (issue 35): the validation verdict says which of
its steps take their predictions from a calibration whose self-check failed (through their
chain of ``from``), and the self-check line names those steps and the reason.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..results import RecordError, StepResult
from ..steps.bayes_calibration import posterior_record
from .diagnostics import step_warnings
from .provenance import failed_evaluations

__all__ = ["VerdictLine", "verdict_lines", "verdict_text", "failed_self_checks", "resting_on"]

Studies = Mapping[str, Mapping[str, StepResult]]


@dataclass(frozen=True)
class VerdictLine:
    """One line of a run's verdict.

    check : what it judges (``"validation"``, ``"self-check"``, ``"failed-evaluations"``,
        ``"warnings"``). title : its name for a reader. text : the finding in words, with
        the steps it concerns. counts : the numbers it rests on (e.g. ``within``,
        ``comparisons``).
    """

    check: str
    title: str
    text: str
    counts: dict[str, int] = field(default_factory=dict)


def _validation_counts(res: StepResult) -> tuple[int, int, float, int, list[str]] | None:
    """(comparisons with |E| <= k u_val, comparisons, k, consistency checks left out, the
    extrapolated conditions in words) of a ``validation`` step's record: every prediction,
    condition and response with a finite ratio whose data the calibration did not use;
    None when unreadable."""
    from ..steps.validation import ValidationRecord

    try:
        rec = ValidationRecord.read(res)
    except (RecordError, KeyError, ValueError):
        return None
    ratio = np.asarray(rec.error_ratio, dtype=float)
    cal = np.broadcast_to(rec.calibrated()[None], ratio.shape)
    finite = np.isfinite(ratio)
    ratio = ratio[finite & ~cal]
    k = float(rec.coverage_factor)
    far = [f"{rec.configuration} = {rec.conditions[j]:g} an extrapolation "
           f"{rec.beyond(j):g} beyond the calibrated range"
           for j in range(rec.conditions.size) if rec.beyond(j) > 0]
    return int(np.sum(ratio <= k)), int(ratio.size), k, int(np.sum(cal)), far


def failed_self_checks(steps: Mapping[str, StepResult]) -> dict[str, str]:
    """The calibrations of one study whose self-check (simulation-based calibration) failed.

    Parameters
    ----------
    steps : mapping
        Step name -> saved result, of one study.

    Returns
    -------
    dict of str to str
        Step name -> the self-check's reason (its coverages), in the steps' order.

    Examples
    --------
    >>> failed_self_checks({})
    {}
    """
    out = {}
    for name, s in steps.items():
        rec = posterior_record(s) if s.type == "bayes_calibration" else None
        if rec is not None and rec.self_check_passed is False:
            out[name] = rec.self_check_reason
    return out


def resting_on(steps: Mapping[str, StepResult], name: str) -> list[str]:
    """The steps a saved step rests on through its chain of ``from`` (``meta["source"]``,
    ``"STEP.posterior"``), nearest first, the step itself excluded.

    Parameters
    ----------
    steps : mapping
        Step name -> saved result, of one study.
    name : str
        The step whose sources are followed.

    Returns
    -------
    list of str
        The names of its sources, its source's source, and so on (those saved in ``steps``).

    Examples
    --------
    >>> resting_on({}, "val")
    []
    """
    out: list[str] = []
    at = steps.get(name)
    while at is not None:
        source = at.meta.get("source")
        up = source.split(".")[0] if isinstance(source, str) and source else None
        if up is None or up in out or up == name:
            break
        out.append(up)
        at = steps.get(up)
    return out


def verdict_lines(studies: Studies, labels: Mapping[str, Mapping[str, str]] | None = None
                  ) -> list[VerdictLine]:
    """The verdict of the saved steps of ``studies`` (study -> step name -> result).

    Parameters
    ----------
    studies : mapping
        Study name -> its saved steps by name.
    labels : mapping, optional
        Study name -> parameter name -> label (for the steps' warnings).

    Returns
    -------
    list of VerdictLine
        Validation, self-checks, failed evaluations and diagnostic warnings, in that order.

    Examples
    --------
    >>> [line.text for line in verdict_lines({})][0]
    'no validation step, so no comparison with data is judged.'
    """
    labels = labels or {}
    lines = []
    within = total = consistency = extrapolations = on_failed = 0
    per_step = []
    failed_checks = {study: failed_self_checks(steps) for study, steps in studies.items()}
    for study, steps in studies.items():
        for s in steps.values():
            if s.type != "validation":
                continue
            got = _validation_counts(s)
            if got is None:
                per_step.append(f"{study} / {s.name}: record not readable")
                continue
            w, n, k, c, far = got
            within, total, consistency = within + w, total + n, consistency + c
            extrapolations += len(far)
            bad = [u for u in resting_on(steps, s.name) if u in failed_checks[study]]
            on_failed += n if bad else 0
            per_step.append(f"{study} / {s.name}: {w} of {n} within {k:g} u_val"
                            + (f" ({c} on calibration data left out)" if c else "")
                            + (f" ({'; '.join(far)})" if far else "")
                            + (f", resting on {', '.join(bad)}, whose self-check FAILED"
                               if bad else ""))
    counts = {"within": within, "comparisons": total, "calibration_data": consistency,
              "extrapolations": extrapolations, "on_failed_self_check": on_failed}
    if per_step:
        lines.append(VerdictLine("validation", "Validation", (
            f"{within} of {total} comparisons with data lie within their validation "
            f"uncertainty (|E| <= k u_val, E = S - D): {'; '.join(per_step)}."
            + (f" {consistency} comparisons on the calibrations' own data are consistency "
               "checks of the fits, not validation, and are not counted." if consistency
               else "")), counts))
    else:
        lines.append(VerdictLine("validation", "Validation", "no validation step, so no "
                                 "comparison with data is judged.", counts))
    checked, failed = [], []
    for study, steps in studies.items():
        for s in steps.values():
            rec = posterior_record(s) if s.type == "bayes_calibration" else None
            if rec is not None and rec.self_check_passed is not None:
                checked.append(f"{study} / {s.name}")
            if s.name in failed_checks[study]:
                users = [u for u in steps if s.name in resting_on(steps, u)]
                failed.append(f"{study} / {s.name} ({failed_checks[study][s.name]}"
                              + (f"; resting on it: {', '.join(users)}" if users else "")
                              + ")")
    what = ((f"{len(failed)} of {len(checked)} failed: {'; '.join(failed)}; a failed "
             "self-check means the posterior is not calibrated" if failed
             else f"all {len(checked)} passed") if checked else "none ran")
    lines.append(VerdictLine("self-check", "Self-checks (simulation-based calibration)",
                             f"{what}.", {"failed": len(failed), "checked": len(checked)}))
    n_failed, recorded, unrecorded, where = 0, 0, 0, []
    for study, steps in studies.items():
        for s in steps.values():
            fails = failed_evaluations(s)
            if fails is None:
                unrecorded += 1
                continue
            recorded += 1
            n_failed += fails[0]
            if fails[0]:
                where.append(f"{study} / {s.name} {fails[0]}")
    lines.append(VerdictLine(
        "failed-evaluations", "Failed evaluations",
        f"{n_failed} in the {recorded} steps that record them"
        + (f" ({', '.join(where)})" if where else "")
        + (f"; {unrecorded} steps do not record them" if unrecorded else "") + ".",
        {"failed": n_failed}))
    warned = [f"{study} / {s.name}" for study, steps in studies.items()
              for s in steps.values() if step_warnings(s, labels.get(study))]
    n_steps = sum(len(steps) for steps in studies.values())
    lines.append(VerdictLine(
        "warnings", "Diagnostic warnings", f"{len(warned)} of {n_steps} steps"
        + (f" ({', '.join(warned)}; see each step's table)" if warned else "") + ".",
        {"steps": len(warned)}))
    return lines


def verdict_text(studies: Studies, labels: Mapping[str, Mapping[str, str]] | None = None
                 ) -> str:
    """The verdict as plain lines for a terminal (``title: text`` each).

    Examples
    --------
    >>> print(verdict_text({}).splitlines()[1])
    verdict: Self-checks (simulation-based calibration): none ran.
    """
    return "\n".join(f"verdict: {line.title}: {line.text}"
                     for line in verdict_lines(studies, labels))
