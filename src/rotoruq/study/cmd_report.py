"""``rotoruq report RESULTS``: rebuild the HTML report from saved results."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "rebuild the HTML report from saved study results"


def write(results_dirs, out, **kwargs) -> Path:
    """The report of saved study results; a study that declares a reference
    (``[study] reference = "thesis"``) gets that reference's claims, tables and figures
    (:mod:`rotoruq.reference`)."""
    from ..reference import application_for
    from ..report.html import write_report

    return write_report(results_dirs, out, application=application_for(results_dirs), **kwargs)


def prerender(results_dir, out, part: tuple[int, int] = (0, 1)) -> int:
    """Draw the figures of the study saved in ``results_dir`` (its ``part``, ``(k, n)``: every
    n-th figure job from the k-th) into the figure cache of the report folder ``out``, ahead
    of :func:`write` (same application as it gives); returns the figure jobs drawn
    (:func:`rotoruq.report.html.prerender_figures`)."""
    from ..reference import application_for
    from ..report.html import prerender_figures

    return prerender_figures(results_dir, out, application=application_for([results_dir]),
                             part=part)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("results", nargs="+",
                        help="study output folder(s), or a folder holding several")
    parser.add_argument("--out", help="report folder (default: <first RESULTS>/report)")


def run(args: argparse.Namespace) -> int:
    from ..errors import InputFileError
    from ..report.html import find_study_dirs

    if not any(find_study_dirs(r) for r in args.results):
        raise InputFileError(args.results[0], None,
                             "a study output folder (with study.json) or a folder of them")
    out = Path(args.out) if args.out else Path(args.results[0]) / "report"
    index = write(args.results, out)
    if not getattr(args, "quiet", False):
        print(f"report: {index}")
    return 0
