"""``python -m rotoruq.mbdyn.driver PARAMS RESULTS``: MBDyn as a Dakota-style analysis driver.

A study's external model calls it (paths of ``[model]`` are relative to the study file)::

    [model]
    command = ["python", "-m", "rotoruq.mbdyn.driver", "--preset", "gvpm",
               "--template", "rigid", "{params}", "{results}"]
    responses = ["thrust", "torque", "power"]

It reads the parameters file (rotor inputs such as ``collective_deg`` and
``height_over_radius``, and airfoil coefficients such as ``cla_m03``), writes the sample's c81
table and the filled MBDyn input into the current (work) directory, runs MBDyn (``--mbdyn``,
else ``$MBDYN``, else ``mbdyn`` on PATH), and writes the responses named by the parameters
file's functions (``thrust``, ``torque``, ``roll``, ``pitch``, ``power``, ``ct``, ``cq``).
When MBDyn fails, stops early or does not reach a periodic state, the results file says
``FAIL``, the reason goes to stderr and the exit status is 1, so rotoruq's failure policy
reports the reason.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from ..errors import RotoruqError
from ..evaluation.dakota_files import read_parameters, write_results
from .case import TEMPLATES, CaseSettings, run_case
from .extract import RESPONSES

log = logging.getLogger(__name__)

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m rotoruq.mbdyn.driver",
        description="Run one MBDyn hover case from a Dakota parameters file and write the "
                    "results file.")
    p.add_argument("params", type=Path, help="Dakota parameters file (standard or aprepro)")
    p.add_argument("results", type=Path, help="results file to write")
    p.add_argument("--preset", default="gvpm", help="rotor preset for geometry and the inputs "
                   "the parameters file does not set (default: gvpm)")
    p.add_argument("--template", default="rigid",
                   help=f"bundled template ({', '.join(TEMPLATES)}) or an MBDyn template file")
    p.add_argument("--mbdyn", default=None, help="MBDyn executable (default: $MBDYN, then PATH)")
    d = CaseSettings()
    p.add_argument("--revolutions", type=int, default=d.revolutions,
                   help=f"simulated revolutions (default {d.revolutions})")
    p.add_argument("--steps-per-rev", type=int, default=d.steps_per_rev,
                   help=f"time steps per revolution (default {d.steps_per_rev})")
    p.add_argument("--average", type=int, default=d.average,
                   help=f"revolutions averaged at the end (default {d.average})")
    p.add_argument("--tolerance", type=float, default=d.tolerance,
                   help=f"periodicity tolerance, relative (default {d.tolerance:g})")
    p.add_argument("--timeout", type=float, default=d.timeout,
                   help=f"seconds MBDyn may run (default {d.timeout:g})")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        from ..rotor.presets import get_preset

        p = read_parameters(args.params)
        names = list(p.names_out)
        bad = [n for n in names if n not in RESPONSES]
        if bad:
            raise RotoruqError(f"{args.params}: responses {bad} are not MBDyn hub loads; "
                               f"available: {', '.join(RESPONSES)}")
        settings = CaseSettings(args.revolutions, args.steps_per_rev, args.average, args.tolerance,
                                args.timeout)
        loads = run_case(Path.cwd(), get_preset(args.preset),
                         {k: float(v) for k, v in p.variables.items()},
                         template=args.template, settings=settings, mbdyn=args.mbdyn)
    except (RotoruqError, OSError, ValueError) as exc:
        log.error("%s", exc)
        write_results(args.results, failed=True)
        return 1
    write_results(args.results, [loads.response(n) for n in names], names)
    return 0


if __name__ == "__main__":  # pragma: no cover
    logging.basicConfig(format="rotoruq mbdyn driver: %(message)s", stream=sys.stderr)
    sys.exit(main())
