"""The ``rotoruq`` command line.

Each subcommand lives in its own module ``rotoruq.study.cmd_<name>`` that defines
``HELP`` (one line), ``add_arguments(parser)`` and ``run(args) -> int``. Modules that are not
present are simply not offered.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from ..errors import RotoruqError

# Order in which subcommands are listed by --help.
COMMANDS = ("reproduce", "run", "report", "evaluate", "airfoil", "driver")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rotoruq",
        description="Verification, validation and calibration under uncertainty of rotor models.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            mod = importlib.import_module(f"rotoruq.study.cmd_{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"rotoruq.study.cmd_{name}":
                continue
            raise
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    try:
        return int(args._run(args) or 0)
    except RotoruqError as exc:
        print(f"rotoruq {args.command}: error: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
