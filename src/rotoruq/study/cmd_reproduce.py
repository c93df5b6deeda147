"""``rotoruq reproduce [validation|experiment|heldout|all]``: run the bundled reference study
(the thesis's chapters 3 and 4, then the held-out ground-effect validation) and write
``<out>/report/index.html``."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from ..errors import InputFileError
from ..reference.studies import CHAPTERS

HELP = ("reproduce the reference study (thesis chapters 3 and 4, and a held-out validation of "
        "the ground effect) and write the report")

__all__ = ["CHAPTERS", "reproduce", "studies_dir"]


def studies_dir() -> Path:
    """The study files shipped with the package (``rotoruq/studies/``)."""
    path = Path(__file__).resolve().parents[1] / "studies"
    if not (path / "validation.toml").is_file():
        raise InputFileError(path, None, "the bundled study files (validation.toml, ...)",
                             "an incomplete installation of rotoruq")
    return path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("which", nargs="?", default="all",
                        choices=[*CHAPTERS, "all"],
                        help="chapter 3 (validation), chapter 4 (experiment), the held-out "
                        "ground-effect validation beyond the thesis (heldout) or all three")
    parser.add_argument("--quick", action="store_true",
                        help="small samples: a check that runs in about a minute")
    parser.add_argument("--out", default="rotoruq-results", help="output folder")
    parser.add_argument("--json", action="store_true",
                        help="print the report's path and the seconds per chapter as JSON "
                        "instead of the summary")


def reproduce(which: str = "all", out: str | Path = "rotoruq-results",
              quick: bool = False) -> dict:
    """Run the chapters, write the report; returns ``{"report": path, "seconds": {...},
    "runs": {chapter: StudyRun}}``. Holds ``out`` (and so each chapter's folder in it) for the
    whole run."""
    from .lock import results_lock

    out = Path(out)
    with results_lock(out, "reproduce"):
        return _reproduce(which, out, quick)


def _reproduce(which: str, out: Path, quick: bool) -> dict:
    from ..results import is_study_dir
    from .cmd_report import write
    from .runner import run_study

    names = list(CHAPTERS) if which == "all" else [which]
    seconds, runs = {}, {}
    for name in names:
        t0 = time.perf_counter()
        runs[name] = run_study(studies_dir() / CHAPTERS[name], out=out / name, quick=quick)
        seconds[name] = time.perf_counter() - t0
    t0 = time.perf_counter()
    index = write([out / n for n in CHAPTERS if is_study_dir(out / n)], out / "report")
    seconds["report"] = time.perf_counter() - t0
    return {"report": str(index), "seconds": seconds, "runs": runs}


def run(args: argparse.Namespace) -> int:
    from .cmd_run import EXIT_FAILED_EVALUATIONS, exit_status, summary

    result = reproduce(args.which, args.out, args.quick)
    if args.json:
        print(json.dumps({"report": result["report"], "seconds": result["seconds"]}, indent=1))
    elif not getattr(args, "quiet", False):
        for res in result["runs"].values():
            print(f"results: {res.out}")
        print(f"report: {result['report']}")
        for res in result["runs"].values():
            print(summary(res))
    codes = [exit_status(res, "reproduce") for res in result["runs"].values()]
    return EXIT_FAILED_EVALUATIONS if any(codes) else 0
