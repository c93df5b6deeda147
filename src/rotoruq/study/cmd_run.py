"""``rotoruq run STUDY``: run a study file and write its results and report."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "run a study file (TOML) and write its results and HTML report"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("study", help="study file (TOML), or the name of a study shipped "
                        "with rotoruq (quick, validation, experiment)")
    parser.add_argument("--out", help="output directory (default: [study] output)")
    parser.add_argument("--quick", action="store_true", help="small samples (a fast check)")
    parser.add_argument("--only", nargs="+", metavar="STEP",
                        help="run only these steps (earlier results are reused)")
    parser.add_argument("--no-report", action="store_true", help="do not write the report")
    parser.add_argument("--allow-outside-store", action="store_true",
                        help="allow a [store] path outside the results folder (absolute or "
                             "with '..'), e.g. a store shared between studies")


def resolve_study(name: str) -> tuple[Path, bool]:
    """A study file path, or a bundled study's name (``quick``); returns (path, bundled)."""
    path = Path(name)
    if path.exists() or path.suffix or "/" in name:
        return path, False
    from .cmd_reproduce import studies_dir

    cand = studies_dir() / f"{name}.toml"
    return (cand, True) if cand.is_file() else (path, False)


def run(args: argparse.Namespace) -> int:
    from .lock import results_lock
    from .paths import check_study_paths
    from .runner import run_study
    from .schema import load_study

    path, bundled = resolve_study(args.study)
    study = load_study(path)
    out = Path(args.out) if args.out else (
        Path("rotoruq-results") / study.info.name if bundled else study.info.output)
    check_study_paths(study, out, out_given=bool(args.out) or bundled,
                      outside_store=args.allow_outside_store)
    with results_lock(out, "run"):  # the run and its report, one at a time per folder
        result = run_study(study, out=out, quick=args.quick, only=args.only)
        say = (lambda line: None) if getattr(args, "quiet", False) else print
        say(f"results: {result.out}")
        if not args.no_report:
            from .cmd_report import write

            index = write([result.out], Path(result.out) / "report")
            say(f"report: {index}")
    say(summary(result))
    return 0


def summary(result) -> str:
    """A short terminal summary of a finished run: each step's time (or that it was reused),
    evaluations and warnings; ``rotoruq show`` prints the tables."""
    from ..report.diagnostics import step_warnings
    from ..report.escape import terminal

    labels = {p.name: p.label or p.name for p in result.study.parameters}
    lines = [f"summary of {terminal(result.study.info.name)} ({len(result.results)} steps):"]
    n_warn = n_failed = 0
    for name, res in result.results.items():
        when = ("reused" if name in result.reused else
                f"{result.seconds.get(name, res.meta.get('seconds', 0.0)):.1f} s")
        warns = step_warnings(res, labels)
        n_warn += len(warns)
        failed = (res.meta.get("failed_evaluations") or {}).get("count", 0)
        n_failed += failed
        lines.append(f"  {terminal(name):<20} {res.type:<18} {when:>9}  "
                     f"{res.meta.get('n_evaluations', '-')!s:>7} evaluations"
                     + (f", {failed} failed" if failed else "")
                     + (f"  {len(warns)} warning(s)" if warns else ""))
        lines += [f"      ! {terminal(w)}" for w in warns[:3]]
        if len(warns) > 3:
            lines.append(f"      ! ... and {len(warns) - 3} more")
    lines.append(f"{n_warn} warning(s), {n_failed} failed evaluation(s). Tables: rotoruq show "
                 f"{terminal(result.out)} [STEP] [--csv|--json]")
    return "\n".join(lines)
