"""``rotoruq dakota import DECK -o STUDY.toml`` and ``rotoruq dakota export STUDY -o DECK``:
Dakota input decks translated into study files and a study's steps written as Dakota decks
(see :mod:`rotoruq.study.deck`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = "translate a Dakota input deck into a study file, or a study's steps into Dakota decks"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    imp = sub.add_parser("import", help="a Dakota deck -> a study file (TOML)")
    imp.add_argument("deck", type=Path, help="the Dakota input deck")
    imp.add_argument("-o", "--output", type=Path, required=True, metavar="STUDY.toml",
                     help="the study file to write")
    imp.add_argument("--name", help="the study's name (default: the deck's file stem)")
    exp = sub.add_parser("export", help="a study's steps -> Dakota decks")
    exp.add_argument("study", type=Path, help="the study file")
    exp.add_argument("-o", "--output", type=Path, required=True, metavar="DECK.in|FOLDER",
                     help="the deck to write, with several steps DECK.<step>.in each; or a "
                          "folder (an existing one, or a name without a suffix): "
                          "FOLDER/<step>.in")
    exp.add_argument("--step", action="append", default=None, metavar="NAME",
                     help="export this step (repeatable; default: every step the export "
                          "supports)")
    exp.add_argument("--quick", action="store_true", help="the steps' --quick sizes")


def run(args: argparse.Namespace) -> int:
    from ..atomic import write_text
    from .deck import EXPORTABLE, read_deck, study_to_decks, translate_deck

    if args.action == "import":
        tr = translate_deck(read_deck(args.deck), name=args.name)
        write_text(args.output, tr.text)
        if tr.ignored:
            print(f"note: {args.deck.name}: kept out of the study (nothing the study "
                  f"computes depends on them): {tr.ignored}", file=sys.stderr)
        for note in tr.notes:
            print(f"note: {args.deck.name}: {note}", file=sys.stderr)
        print(args.output)
        return 0
    from ..errors import InputFileError
    from .schema import load_study

    study = load_study(args.study)
    out: Path = args.output
    folder = out.is_dir() or not out.suffix
    (out if folder else out.parent).mkdir(parents=True, exist_ok=True)
    decks = study_to_decks(study, steps=args.step, quick=args.quick,
                           data_dir=out if folder else out.parent)
    if not decks:
        raise InputFileError(args.study, None, "a step of a type the export writes ("
                             + ", ".join(EXPORTABLE) + ")", "none")
    skipped = [s.name for s in study.steps if s.name not in decks and args.step is None]
    for name, text in decks.items():
        path = (out / f"{name}.in" if folder else out if len(decks) == 1
                else out.with_name(f"{out.stem}.{name}{out.suffix}"))
        write_text(path, _driver_note(text) + text)
        print(path)
    if skipped:
        print(f"not exported (a type without a Dakota deck, or distributions from an "
              f"earlier step's results): {', '.join(skipped)}", file=sys.stderr)
    return 0


def _driver_note(text: str) -> str:
    """A comment saying how the deck's ``analysis_drivers`` line calls rotoruq (see
    :func:`~rotoruq.study.deck.rotoruq_command`); empty for a deck without the driver."""
    from .deck import rotoruq_command

    cmd = rotoruq_command()
    if f"'{cmd} driver" not in text:
        return ""
    if cmd == "rotoruq":
        return ("# driver: 'rotoruq' as found on PATH (here this installation); on another "
                "machine or venv, rotoruq must be on PATH\n")
    return (f"# driver: this installation's rotoruq by absolute path ({cmd}): the 'rotoruq' "
            "on PATH is another installation or none; put it on PATH and export again to get "
            "a portable deck\n")
