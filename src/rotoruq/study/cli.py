"""The ``rotoruq`` command line.

Each subcommand lives in its own module ``rotoruq.study.cmd_<name>`` that defines
``HELP`` (one line), ``add_arguments(parser)`` and ``run(args) -> int``. Modules that are not
present are simply not offered.

Exit codes (every subcommand):

    0  done
    1  an error in the input (a study file, a data file, a results folder) or the system
    2  a usage error (argparse) or an internal error (a bug: please report it)
    3  ``run``/``reproduce``: the results are written, but a step had no successful
       evaluation or more failed evaluations than ``[study] max_failed_share`` allows
    130, 143  interrupted (Ctrl-C), terminated (SIGTERM)

``--quiet``, ``--verbose`` and ``--debug`` are accepted before or after the subcommand.
"""

from __future__ import annotations

import os
import sys

from .. import __version__

# Everything else is imported when used: a ``rotoruq driver`` call answered by the driver
# server loads nothing beyond this module, the package root and ``driver_client``.
TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing
if TYPE_CHECKING:
    import argparse

# Order in which subcommands are listed by --help.
COMMANDS = ("reproduce", "run", "report", "show", "evaluate", "airfoil", "driver", "export",
            "serve", "dakota", "repair")

#: The exit code of a run whose results are written but whose evaluations failed (a step
#: without a successful evaluation, or a failure share above the study's threshold).
EXIT_FAILED_EVALUATIONS = 3

#: Flags accepted before or after the subcommand (the driver's lean path skips them too).
GLOBAL_FLAGS = ("--quiet", "-q", "--verbose", "-v", "--debug")


def _add_global_flags(parser: argparse.ArgumentParser, default: object) -> None:
    """--quiet, --verbose and --debug on the main parser (``default`` False) and on each
    subcommand (``default`` SUPPRESS: a flag given before the subcommand is kept)."""
    parser.add_argument("-q", "--quiet", action="store_true", default=default,
                        help="warnings, errors and failed evaluations only: no progress "
                             "lines or summary")
    parser.add_argument("-v", "--verbose", action="store_true", default=default,
                        help="also the library's debug messages")
    parser.add_argument("--debug", action="store_true", default=default,
                        help="--verbose, and the full traceback of an error")


def build_parser() -> argparse.ArgumentParser:
    import argparse
    import importlib

    from .console import pipe_safe  # not on the driver's lean path

    parser = argparse.ArgumentParser(
        prog="rotoruq",
        description="Verification, validation and calibration under uncertainty of rotor models.",
    )
    _add_global_flags(parser, False)
    parser.add_argument("--version", action="version", version=f"rotoruq {__version__}")
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
        _add_global_flags(p, argparse.SUPPRESS)
        p.set_defaults(_run=pipe_safe(mod.run))
    return parser


class _Terminated(KeyboardInterrupt):
    """SIGTERM, handled like Ctrl-C: running drivers' process trees are ended on the way out."""


def _on_sigterm(signum, frame):
    raise _Terminated()


def main(argv: list[str] | None = None) -> int:
    words = _driver_argv(list(sys.argv[1:] if argv is None else argv))
    if (words is not None and not {"-h", "--help"} & set(words)
            and os.environ.get("ROTORUQ_DRIVER_SERVER", "1") != "0"):
        # the warm path: a running driver server answers (None: run the driver here)
        from .driver_client import call

        status = call(words)
        if status is not None:
            return status
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return _main(argv)
    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        return _main(argv)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _driver_argv(argv: list[str]) -> list[str] | None:
    """The driver's own words when the command is ``driver`` (after any global flags)."""
    k = 0
    while k < len(argv) and argv[k] in GLOBAL_FLAGS:
        k += 1
    return argv[k + 1 :] if argv[k : k + 1] == ["driver"] else None


def _main(argv: list[str] | None) -> int:
    words = _driver_argv(list(sys.argv[1:] if argv is None else argv))
    if words is not None and not {"-h", "--help"} & set(words):
        # Dakota runs the driver once per evaluation: skip the other subcommands' imports, and
        # let the driver answer every error with a FAIL results file
        from .cmd_driver import main as driver_main

        return driver_main(words)
    from ..errors import RotoruqError
    from ..safety import terminal_text
    from .console import configure_logging

    parser = build_parser()
    args = parser.parse_args(argv)
    if args.quiet and (args.verbose or args.debug):
        parser.error("--quiet and --verbose/--debug: choose one")
    configure_logging(quiet=args.quiet, debug=args.debug, verbose=args.verbose)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    try:
        return int(args._run(args) or 0)
    except KeyboardInterrupt as exc:
        how = "terminated" if isinstance(exc, _Terminated) else "interrupted"
        print(f"rotoruq {args.command}: {how} (finished evaluations and steps are saved; "
              "run the same command again to resume)", file=sys.stderr)
        return 143 if isinstance(exc, _Terminated) else 130
    except (RotoruqError, OSError) as exc:
        if args.debug:
            raise
        # messages quote study-supplied names and paths: no escape code reaches the terminal
        print(f"rotoruq {args.command}: error: {terminal_text(exc, lines=True)}",
              file=sys.stderr)
        return 1
    except Exception as exc:  # a bug, not bad input: say so, keep the terminal readable
        if args.debug:
            raise
        print(f"rotoruq {args.command}: internal error: {type(exc).__name__}: "
              f"{terminal_text(exc, lines=True)}\n"
              f"(run 'rotoruq --debug {args.command} ...' for the traceback, and please report "
              "it)", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
