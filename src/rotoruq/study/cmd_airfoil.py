"""``rotoruq airfoil``: fit a C81 table (thesis tables 4.3/4.4) or write a perturbed table."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..errors import ParameterError
from ..rotor.airfoil import BUNDLED_AIRFOILS, Airfoil, fit_airfoil, parse_parameter_name
from ..rotor.airfoil import read_bundled as _read_bundled
from ..rotor.c81 import read_c81, write_c81

HELP = "fit CL/CD lines of a C81 airfoil table, or write a table with perturbed fits"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="airfoil_command", metavar="ACTION")
    src_help = (f"C81 file (fixed or free format), or the name of a bundled table "
                f"({', '.join(BUNDLED_AIRFOILS)})")
    p = sub.add_parser("fit", help="print the CL (linear) and CD (quadratic) fits per Mach row")
    p.add_argument("file", help=src_help)
    p.add_argument("--mach", type=float, nargs="+", default=None,
                   help="Mach rows to fit (default: the CL block's Mach rows)")
    p.add_argument("--window", type=float, default=10.0,
                   help="half-width of the alpha window, deg (default 10)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    w = sub.add_parser("write", help="write the table with its window rewritten by the fits")
    w.add_argument("file", help=src_help)
    w.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                   help="perturbed coefficients, e.g. cla_m03=0.11 cd0_m02=0.009")
    w.add_argument("--mach", type=float, nargs="+", default=None,
                   help="fit Mach rows to rewrite (default: those named in --set)")
    w.add_argument("--window", type=float, default=10.0, help="alpha window half-width, deg")
    w.add_argument("--free-format", action="store_true", help="write MBDyn's free format")
    w.add_argument("-o", "--output", required=True, help="output C81 file")


def _load(src):
    if not Path(src).exists() and src.lower().removesuffix(".c81") in BUNDLED_AIRFOILS:
        return _read_bundled(src)
    return read_c81(src)


def _parse_sets(items):
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep:
            raise ParameterError(f"--set expects NAME=VALUE, got {item!r}")
        parse_parameter_name(name.strip())
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ParameterError(f"--set {name}: {value!r} is not a number") from None
    return out


def run(args: argparse.Namespace) -> int:
    action = getattr(args, "airfoil_command", None)
    if action == "fit":
        fit = fit_airfoil(_load(args.file), args.mach, (-args.window, args.window))
        if args.json:
            print(json.dumps({
                "file": args.file,
                "alpha_range_deg": list(fit.alpha_range),
                "mach": fit.machs.tolist(),
                "cla_per_deg": fit.cla.tolist(),
                "cl0": fit.cl0.tolist(),
                "cda2_per_deg2": fit.cda2.tolist(),
                "cda_per_deg": fit.cda.tolist(),
                "cd0": fit.cd0.tolist(),
                "parameters": fit.as_dict(),
            }, indent=2))
        else:
            print(fit.to_text())
        return 0
    if action == "write":
        sets = _parse_sets(args.set)
        machs = args.mach
        if machs is None:
            machs = sorted({parse_parameter_name(n)[1] for n in sets})
            if not machs:
                raise ParameterError("give --set NAME=VALUE or --mach to choose the fit rows")
        airfoil = Airfoil(_load(args.file), fit_machs=machs, alpha_window=args.window)
        table = airfoil.perturbed_table(sets)
        path = write_c81(table, args.output, free_format=args.free_format)
        if not getattr(args, "quiet", False):
            print(f"wrote {path} (fit rows at Mach "
                  f"{', '.join(f'{m:g}' for m in airfoil.fit_machs)}, |alpha| <= "
                  f"{args.window:g} deg)")
        return 0
    print("usage: rotoruq airfoil {fit,write} ... (see rotoruq airfoil --help)")
    return 2
