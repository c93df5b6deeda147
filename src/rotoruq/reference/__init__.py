"""The reference study as an application on top of the toolkit: the thesis's printed tables
(:mod:`~rotoruq.reference.tables`), our values beside them (:mod:`~rotoruq.reference.compare`),
its claims (:mod:`~rotoruq.reference.claims`) and their causes
(:mod:`~rotoruq.reference.causes`), the studies it covers and what ``rotoruq reproduce`` runs
(:mod:`~rotoruq.reference.studies`), and what it adds to a report: the claims, the thesis
tables and the thesis's numbers drawn beside ours (:mod:`~rotoruq.reference.report`).

It sits above :mod:`rotoruq.report`, :mod:`rotoruq.steps` and :mod:`rotoruq.render` and
below the study layer and the CLI; none of the generic layers imports it. A study is a
reference study only when its file says so (``[study] reference = "thesis"``); the CLI then
hands the report this package's application object (``rotoruq.report.application``).
"""

from __future__ import annotations

__all__ = ["NAMES", "application", "application_for"]

#: The reference names a study file may declare (``[study] reference = ...``).
NAMES = ("thesis",)


def application(name: str):
    """The report application of reference ``name`` (one of :data:`NAMES`)."""
    if name not in NAMES:
        raise KeyError(f"unknown reference {name!r}: one of {', '.join(NAMES)}")
    from .report import APPLICATION

    return APPLICATION


def application_for(results_dirs):
    """The report application of the reference the saved studies under ``results_dirs``
    declare (``study.json`` ``reference``), or None when none declares one. A reference name
    this version does not know is logged and left out (the report is then the run's own)."""
    import logging

    from ..report.html import find_study_dirs
    from ..results import study_infos

    found = study_infos([f for d in results_dirs for f in find_study_dirs(d)])
    declared = {info.get("reference") for _, info in found.values()} - {None}
    for name in sorted(declared - set(NAMES), key=str):
        logging.getLogger(__name__).warning(
            "report: reference %r is not one this version knows (%s): its studies get the "
            "plain report", name, ", ".join(NAMES))
    known = [n for n in NAMES if n in declared]
    return application(known[0]) if known else None
