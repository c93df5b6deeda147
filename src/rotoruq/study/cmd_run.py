"""``rotoruq run STUDY``: run a study file and write its results and report."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "run a study file (TOML) and write its results and HTML report"

#: The exit code of a run whose results are written but whose evaluations failed (a step
#: without a successful evaluation, or more failed than ``max_failed_share`` allows).
EXIT_FAILED_EVALUATIONS = 3


def bundled_studies() -> list[str]:
    """The names of the study files shipped with rotoruq (``rotoruq/studies/*.toml``)."""
    return sorted(p.stem for p in (Path(__file__).resolve().parents[1] / "studies")
                  .glob("*.toml"))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("study", help="study file (TOML), or the name of a study shipped "
                        f"with rotoruq ({', '.join(bundled_studies())})")
    parser.add_argument("--out", help="output directory (default: [study] output)")
    parser.add_argument("--quick", action="store_true", help="small samples (a fast check)")
    parser.add_argument("--only", nargs="+", metavar="STEP",
                        help="run only these steps; the others are reused where saved, else "
                             "skipped (a step one of them takes from must be saved or named)")
    parser.add_argument("--max-failed-share", type=_share, metavar="SHARE",
                        help="exit with code 3 when a step has more failed evaluations than "
                             "this share, 0 to 1 (default: [study] max_failed_share, else "
                             "0.5); a step without a successful evaluation always does")
    parser.add_argument("--no-report", action="store_true", help="do not write the report")
    parser.add_argument("--jobs", type=_jobs, default=1, metavar="N",
                        help="steps run at once, each in its own process, as soon as the "
                             "steps they take from are done (default 1); the numbers are the "
                             "same at any count")
    parser.add_argument("--allow-outside-store", action="store_true",
                        help="allow a [store] path outside the results folder (absolute or "
                             "with '..'), e.g. a store shared between studies")


def _jobs(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"an integer >= 1, got {text!r}")
    return n


def _share(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not 0.0 <= v <= 1.0:
        raise argparse.ArgumentTypeError(f"a share from 0 to 1 (0.5: half), not {text!r}")
    return v


def resolve_study(name: str) -> tuple[Path, bool]:
    """A study file path, or a bundled study's name (``quick``); returns (path, bundled).
    A name that is neither is an error listing the bundled studies (with the closest)."""
    path = Path(name)
    if path.exists() or path.suffix or "/" in name:
        return path, False
    from .cmd_reproduce import studies_dir

    cand = studies_dir() / f"{name}.toml"
    if cand.is_file():
        return cand, True
    from ..errors import InputFileError
    from .options import close_hint

    names = bundled_studies()
    raise InputFileError(path, None, "an existing study file or the name of a bundled study ("
                         + ", ".join(names) + ")" + close_hint(name, names))


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
        result = run_study(study, out=out, quick=args.quick, only=args.only,
                           jobs=args.jobs)
        say = (lambda line: None) if getattr(args, "quiet", False) else print
        index = None
        if not args.no_report and result.results:
            from .cmd_report import write

            index = write([result.out], Path(result.out) / "report")
    say(summary(result))
    say(verdict(result))
    say(f"results: {result.out}")
    if index is not None:
        say(f"report: {index}")  # last: what the user opens next
    return exit_status(result, "run", args.max_failed_share)


def verdict(*results) -> str:
    """The run's own verdict (:func:`rotoruq.report.verdict.verdict_text`) over the studies
    of ``results`` (:class:`~rotoruq.study.runner.StudyRun` each), for the terminal."""
    from ..report.verdict import verdict_text

    labels = {r.study.info.name: {p.name: p.label or p.name for p in r.study.parameters}
              for r in results}
    return verdict_text({r.study.info.name: r.results for r in results}, labels)


def exit_status(result, command: str, share: float | None = None) -> int:
    """0, or :data:`EXIT_FAILED_EVALUATIONS` after printing on stderr (also with --quiet) each
    step whose evaluations failed beyond the threshold (:func:`failed_steps`)."""
    import sys

    bad = failed_steps(result, share)
    for line in bad:
        print(f"rotoruq {command}: error: {line}", file=sys.stderr)
    if bad:
        print(f"rotoruq {command}: results written to {result.out}; exit code "
              f"{EXIT_FAILED_EVALUATIONS} (failed evaluations)", file=sys.stderr)
        return EXIT_FAILED_EVALUATIONS
    return 0


def _failures(res) -> tuple[int, int | None, str | None]:
    """(failed evaluations, evaluations or None when the step does not say, first reason)."""
    fe = res.meta.get("failed_evaluations") or {}
    failed = int(fe.get("count") or 0)
    n = res.meta.get("n_evaluations")
    n = int(n) if isinstance(n, int | float) and not isinstance(n, bool) else None
    first = fe.get("first") or next(iter(fe.get("reasons") or {}), None)
    return failed, n, None if first is None else str(first)


def failed_steps(result, share: float | None = None) -> list[str]:
    """One line per step of ``result`` (a :class:`~rotoruq.study.runner.StudyRun`) without a
    successful evaluation, or with a share of failed evaluations above ``share`` (default:
    the study's ``[study] max_failed_share``), with the first failure's own message."""
    from ..report.escape import terminal

    limit = result.study.info.max_failed_share if share is None else share
    lines = []
    for name, res in result.results.items():
        failed, n, first = _failures(res)
        if not failed:
            continue
        why = f"; first failure: {terminal(_short(first))}" if first else ""
        if n is not None and failed >= n:
            lines.append(f"step {terminal(name)!r}: none of its {n} evaluations succeeded{why}")
        elif n and failed / n > limit:
            lines.append(f"step {terminal(name)!r}: {failed} of {n} evaluations failed "
                         f"({failed / n:.0%}, above the {limit:.0%} allowed by "
                         f"max_failed_share){why}")
    return lines


def _short(text: str, limit: int = 300) -> str:
    line = " ".join(text.split())
    return line if len(line) <= limit else line[: limit - 3] + "..."


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
        _, _, first = _failures(res)
        if failed and first:
            lines.append(f"      x first failed evaluation: {terminal(_short(first))}")
        lines += [f"      ! {terminal(w)}" for w in warns[:3]]
        if len(warns) > 3:
            lines.append(f"      ! ... and {len(warns) - 3} more")
    reasons = getattr(result, "skip_reasons", {})
    for name in getattr(result, "skipped", ()):
        why = reasons.get(name, "not in --only, no saved result")
        lines.append(f"  {terminal(name):<20} skipped ({terminal(why)})")
    lines.append(f"{n_warn} warning(s), {n_failed} failed evaluation(s). Tables: rotoruq show "
                 f"{terminal(result.out)} [STEP] [--csv|--json]")
    return "\n".join(lines)
