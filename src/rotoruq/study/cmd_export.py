"""``rotoruq export RESULTS --dakota-tabular FILE``: a study's evaluations as a Dakota tabular file.

RESULTS is a study output folder (its evaluation store and ``study.json``, whose ``[model]
fixed`` inputs become constant columns) or an evaluation store file. The columns are named and
ordered as ``--columns`` says (the order of the deck's variables: Dakota reads points by
position), by default the model's input order then the responses.
"""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "export a study's evaluations (e.g. as a Dakota tabular file)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("results", type=Path, help="study output folder or evaluation store")
    parser.add_argument("--dakota-tabular", type=Path, required=True, metavar="FILE",
                        help="the tabular file to write")
    parser.add_argument("--columns", metavar="NAME[,NAME...]",
                        help="columns in this order (inputs, optionally responses); default: "
                             "the model's inputs, fixed inputs, then the responses")
    parser.add_argument("--inputs-only", action="store_true",
                        help="no response columns (a points file for import_points_file)")
    parser.add_argument("--interface", default="NO_ID", metavar="ID",
                        help="interface id of the rows (default NO_ID, Dakota's)")
    parser.add_argument("--layout", default="annotated",
                        choices=("annotated", "custom_annotated", "freeform"),
                        help="Dakota's tabular layout (default annotated)")
    parser.add_argument("--inputs", metavar="NAME[,NAME...]",
                        help="the evaluations of the model with these inputs, when the store "
                             "holds several")
    parser.add_argument("--outputs", metavar="NAME[,NAME...]",
                        help="the evaluations of the model with these responses, when the "
                             "store holds several (e.g. two steps asking one model for "
                             "different responses)")
    parser.add_argument("--include-failed", action="store_true",
                        help="failed evaluations as rows of nan responses")


def _store_of(results: Path) -> tuple[Path, dict[str, float]]:
    from ..errors import InputFileError
    from ..results import is_study_dir, load_study_info

    if results.is_file():
        return results, {}
    if not results.is_dir():
        raise InputFileError(results, None, "a study output folder or an evaluation store",
                             "no such file or folder")
    fixed = {}
    if is_study_dir(results):
        fixed = dict(load_study_info(results).get("model", {}).get("fixed", {}))
    stores = sorted(results.glob("*.sqlite")) + sorted(results.glob("*.db"))
    if len(stores) != 1:
        raise InputFileError(results, None, "one evaluation store (*.sqlite) in the folder",
                             f"{len(stores)}: {[p.name for p in stores]}")
    return stores[0], fixed


def _names(text: str | None) -> list[str] | None:
    return None if text is None else [w.strip() for w in text.split(",") if w.strip()]


def run(args: argparse.Namespace) -> int:
    from ..evaluation.tabular import export_store

    store, fixed = _store_of(args.results)
    path = export_store(store, args.dakota_tabular, columns=_names(args.columns), fixed=fixed,
                        inputs_only=args.inputs_only, interface=args.interface or None,
                        layout=args.layout, inputs=_names(args.inputs),
                        outputs=_names(args.outputs),
                        include_failed=args.include_failed)
    print(path)
    return 0
