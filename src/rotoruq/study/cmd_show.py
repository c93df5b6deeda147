"""``rotoruq show RESULTS [STEP] [--csv|--json|--why-rerun]``: print a step's result tables
(all steps without STEP), or export them as CSV or JSON, without opening the HTML report;
``--why-rerun`` says which steps ``rotoruq run`` would run again and which part of their
identity changed."""

from __future__ import annotations

import argparse
import json
import sys
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
    "n_evaluations", "tables": [StepTable.as_dict()], "warnings": [...]}}}``."""
    from ..errors import InputFileError
    from ..report.diagnostics import step_warnings
    from ..report.steptables import step_tables
    from ..results import is_study_dir, load_results, load_study_info

    folder = Path(results)
    if not is_study_dir(folder):
        raise InputFileError(folder, None, "a study output folder (with study.json)")
    info = load_study_info(folder)
    steps = load_results(folder)
    if step is not None and step not in steps:
        raise InputFileError(folder, None, f"a saved step named {step!r}; saved steps: "
                             + (", ".join(steps) or "none"))
    labels = {k: v.get("label") or k for k, v in info.get("parameters", {}).items()}
    out = {"study": info.get("name"), "description": info.get("description", ""), "steps": {}}
    for name, res in steps.items():
        if step is not None and name != step:
            continue
        out["steps"][name] = {
            "type": res.type, "title": res.meta.get("title", ""),
            "seconds": res.meta.get("seconds"), "n_evaluations": res.meta.get("n_evaluations"),
            "tables": [t.as_dict() for t in step_tables(res, labels)],
            "warnings": step_warnings(res, labels),
        }
    return out


def why_rerun_text(results: str | Path, step: str | None = None) -> str:
    """One line per step: ``reused`` or ``runs again: <part>: <what> changed; ...``."""
    from .runner import why_rerun

    lines = []
    for name, why in why_rerun(results).items():
        if step is not None and name != step:
            continue
        lines.append(f"{name}: " + ("reused" if not why else "runs again: " + "; ".join(why)))
    return "\n".join(lines) + "\n"


def run(args: argparse.Namespace) -> int:
    from ..report.steptables import StepTable, table_csv, table_text

    w = sys.stdout.write
    if args.why_rerun:
        w(why_rerun_text(args.results, args.step))
        return 0
    data = show_data(args.results, args.step)
    if args.json:
        w(json.dumps(data, indent=1) + "\n")
        return 0
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
    return 0
