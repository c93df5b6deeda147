"""``rotoruq show RESULTS [STEP] [--csv|--json|--why-rerun]``: print a step's result tables
(all steps without STEP), or export them as CSV or JSON, without opening the HTML report;
``--why-rerun`` says which steps ``rotoruq run`` would run again and which part of their
identity changed.

Names, titles, labels and descriptions come from the study file and the results folder: the
text and CSV output escape their control characters (:func:`rotoruq.report.escape.terminal`),
so a name cannot rewrite the terminal; JSON escapes them itself."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

HELP = "print the result tables of a study's steps (or export them with --csv / --json)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("results", help="a study output folder (the one holding study.json)")
    parser.add_argument("step", nargs="?", help="one step (default: every step)")
    fmt = parser.add_mutually_exclusive_group()
    fmt.add_argument("--csv", action="store_true",
                     help="CSV: each table preceded by a '# step: title' line")
    fmt.add_argument("--json", action="store_true", help="JSON: steps, tables, warnings")
    fmt.add_argument("--why-rerun", action="store_true",
                     help="which steps a new run would run again, and what changed (the "
                          "step's spec, inputs, data, model, code file or an upstream step)")


def show_data(results: str | Path, step: str | None = None) -> dict:
    """``{"study", "description", "steps": {name: {"type", "title", "seconds",
    "n_evaluations", "failed_evaluations", "tables": [StepTable.as_dict()], "warnings":
    [...]}}}``; ``failed_evaluations`` is ``{"count", "reasons": {reason: count}}`` or None
    when the step recorded nothing."""
    from ..errors import InputFileError
    from ..report.diagnostics import step_warnings
    from ..report.escape import terminal
    from ..report.provenance import failed_evaluations
    from ..report.steptables import step_tables
    from ..results import is_study_dir, load_results, load_study_info

    folder = Path(results)
    if not is_study_dir(folder):
        raise InputFileError(folder, None, "a study output folder (with study.json)")
    info = load_study_info(folder)
    with _damaged_steps_named(folder):
        steps = load_results(folder)
    if step is not None and step not in steps:
        raise InputFileError(folder, None, f"a saved step named {step!r}; saved steps: "
                             + (", ".join(map(terminal, steps)) or "none"))
    labels = {k: v.get("label") or k for k, v in info.get("parameters", {}).items()}
    out = {"study": info.get("name"), "description": info.get("description", ""), "steps": {}}
    for name, res in steps.items():
        if step is not None and name != step:
            continue
        fails = failed_evaluations(res)
        out["steps"][name] = {
            "type": res.type, "title": res.meta.get("title", ""),
            "seconds": res.meta.get("seconds"), "n_evaluations": res.meta.get("n_evaluations"),
            "failed_evaluations": None if fails is None else {"count": fails[0],
                                                              "reasons": fails[1]},
            "tables": [t.as_dict() for t in step_tables(res, labels)],
            "warnings": step_warnings(res, labels),
        }
    return out


def why_rerun_text(results: str | Path, step: str | None = None) -> str:
    """One line per step: ``reused`` or ``runs again: <part>: <what> changed; ...``."""
    from ..report.escape import terminal
    from .runner import why_rerun

    lines = []
    with _damaged_steps_named(Path(results)):
        reasons = why_rerun(results)
    for name, why in reasons.items():
        if step is not None and name != step:
            continue
        lines.append(terminal(name) + ": " + ("reused" if not why else "runs again: "
                                              + "; ".join(map(terminal, why))))
    return "\n".join(lines) + "\n"


@contextmanager
def _damaged_steps_named(folder: Path) -> Iterator[None]:
    """A saved step that is incomplete or changed since it was saved stops ``show`` (its
    numbers are never shown) with one line that names its file and says what to do."""
    from ..results import ForeignStepFileError, IncompleteStepError

    try:
        yield
    except ForeignStepFileError:
        raise
    except IncompleteStepError as exc:
        raise IncompleteStepError(f"{exc}: not shown; `rotoruq run` computes the step again "
                                  f"(`rotoruq repair {folder}` moves it aside)") from None


def run(args: argparse.Namespace) -> int:
    from ..report.steptables import StepTable, table_csv, table_text

    w = sys.stdout.write
    if args.why_rerun:
        w(why_rerun_text(args.results, args.step))
        return 0
    data = show_data(args.results, args.step)
    if args.json:  # json.dumps writes every control character as \uXXXX
        w(json.dumps(data, indent=1) + "\n")
        return 0
    data = _for_terminal(data)
    for name, s in data["steps"].items():
        tables = [StepTable(t["title"], tuple(t["columns"]), tuple(map(tuple, t["rows"])),
                            t["note"]) for t in s["tables"]]
        if args.csv:
            for t in tables:
                w(f"# {name}: {t.title}\n{table_csv(t)}\n")
            continue
        w(f"== {name} ({s['type']}) {s['title']}\n")
        for t in tables:
            w(table_text(t) + "\n\n")
        fails = s["failed_evaluations"]
        if fails:
            w(f"failed evaluations: {fails['count']}"
              + "".join(f"\n  {k} x {r}" for r, k in sorted(fails["reasons"].items()))
              + "\n\n")
    return 0


def _for_terminal(obj):
    """``obj`` (show_data's dict) with every string's control characters escaped."""
    from ..report.escape import terminal

    if isinstance(obj, str):
        return terminal(obj)
    if isinstance(obj, dict):
        return {_for_terminal(k): _for_terminal(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_for_terminal(v) for v in obj]
    return obj
