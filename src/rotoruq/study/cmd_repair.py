"""``rotoruq repair RESULTS``: check a results folder's evaluation store and saved steps.

A damaged store is moved aside and rebuilt from the evaluations that can still be read; a
saved step that does not load (a file missing or changed since it was saved, ``result.json``
edited by hand, a file rotoruq did not write) is moved aside. The damaged store is renamed
``<name>.damaged-<UTC time>`` beside it, a damaged step ``steps/.damaged-<step>.<UTC time>``:
never deleted. What was lost (evaluations that could not be read, the steps moved aside) is
simply computed again by the next ``rotoruq run``. A folder is repaired under its lock: never
while a run uses it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = ("check a results folder's evaluation store and saved steps; move damaged ones aside "
        "(and rebuild the store)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("results", type=Path, help="a study output folder or a store file")


def _stores(results: Path) -> list[Path]:
    from ..errors import InputFileError

    if results.is_file():
        return [results]
    if not results.is_dir():
        raise InputFileError(results, None, "a study output folder or an evaluation store",
                             "no such file or folder")
    found = sorted(p for p in results.glob("*.sqlite") if p.is_file())
    return found or [results / "evaluations.sqlite"]


def run(args: argparse.Namespace) -> int:
    from .lock import results_lock

    if args.results.is_file():
        _repair_stores([args.results])
        return 0
    stores = _stores(args.results)
    with results_lock(args.results, "repair"):
        _repair_stores(stores)
        _repair_steps(args.results)
    return 0


def _repair_stores(paths: list[Path]) -> None:
    from ..evaluation.store import repair_store

    for path in paths:
        rep = repair_store(path)
        if rep.status == "ok":
            print(f"{path}: store intact")
        elif rep.status == "missing":
            print(f"{path}: no store here, nothing to repair (the next run creates one)")
        else:
            print(f"{path}: damaged ({rep.problem}); moved it to {rep.quarantined}; kept "
                  f"{rep.n_salvaged} evaluation(s): run again to evaluate the rest")


def _repair_steps(folder: Path) -> None:
    from ..report.escape import terminal
    from ..results import load_results, set_aside_damaged_steps

    for d in set_aside_damaged_steps(folder):
        print(f"{terminal(folder / 'steps' / d.name)}: damaged ({terminal(d.problem)}); moved "
              f"it to {terminal(d.moved_to)}: run again to compute the step")
    n = len(load_results(folder))
    if n:
        print(f"{folder / 'steps'}: {n} saved step(s) intact")
