"""``rotoruq repair RESULTS``: check a results folder's evaluation store and, if it is damaged,
move it aside and rebuild it from the evaluations that can still be read.

The damaged file is renamed ``<name>.damaged-<UTC time>`` beside it, never deleted; the
evaluations that could not be read are simply run again by the next ``rotoruq run``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "check a results folder's evaluation store; move a damaged one aside and rebuild it"


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
    from ..evaluation.store import repair_store

    for path in _stores(args.results):
        rep = repair_store(path)
        if rep.status == "ok":
            print(f"{path}: store intact")
        elif rep.status == "missing":
            print(f"{path}: no store here, nothing to repair (the next run creates one)")
        else:
            print(f"{path}: damaged ({rep.problem}); moved it to {rep.quarantined}; kept "
                  f"{rep.n_salvaged} evaluation(s): run again to evaluate the rest")
    return 0
