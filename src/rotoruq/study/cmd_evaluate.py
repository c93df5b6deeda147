"""``rotoruq evaluate``: print the hub loads of one or a few rotor points."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from ..errors import ParameterError

HELP = "evaluate the rotor model at one or a few points and print the loads"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--preset", default="gvpm", help="rotor preset (bo105, gvpm)")
    p.add_argument(
        "--set",
        nargs="*",
        default=[],
        metavar="NAME=VALUE[,VALUE...]",
        help="inputs, e.g. collective_deg=5.4 k_pitch_link=15; comma lists give several points",
    )
    p.add_argument(
        "--responses",
        nargs="+",
        metavar="NAME",
        default=["thrust", "torque", "roll", "pitch", "power", "ct", "cq"],
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")


def parse_assignments(items: list[str]) -> tuple[list[str], np.ndarray]:
    """``["a=1,2", "b=3"]`` -> names, points (n, d) with scalars broadcast."""
    names, cols = [], []
    for item in items:
        if "=" not in item:
            raise ParameterError(f"--set expects NAME=VALUE, got {item!r}")
        name, _, value = item.partition("=")
        try:
            vals = [float(v) for v in value.split(",")]
        except ValueError:
            raise ParameterError(f"--set {name}: expected numbers, got {value!r}") from None
        names.append(name.strip())
        cols.append(vals)
    n = max((len(c) for c in cols), default=1)
    for name, c in zip(names, cols, strict=True):
        if len(c) not in (1, n):
            raise ParameterError(f"--set {name}: {len(c)} values but other inputs have {n}")
    x = np.array([c * n if len(c) == 1 else c for c in cols], dtype=float).T.reshape(n, -1)
    return names, x


def fixed_inputs_line(model) -> str:
    """The inputs the preset supplies (every rotor input not given with ``--set``), one line:
    ``fixed inputs (preset gvpm): lateral_deg=-1 longitudinal_deg=-1 ...``."""
    given = set(model.names_in)
    fixed = " ".join(f"{k}={v:.6g}" for k, v in model.defaults().items() if k not in given)
    return f"fixed inputs (preset {model.preset.name}): {fixed}"


def run(args: argparse.Namespace) -> int:
    from ..render.tables import with_unit
    from ..rotor.model import RotorModel

    quiet = getattr(args, "quiet", False)
    names, x = parse_assignments(args.set)
    model = RotorModel(args.preset, names_in=names, names_out=args.responses)
    out = model.evaluate(x)
    rows = []
    for i in range(x.shape[0]):
        row: dict[str, float | str | None] = {
            k: float(v) for k, v in zip(names, x[i], strict=True)}
        # JSON has no NaN: a failed point's responses are null
        row.update({k: float(v) if np.isfinite(v) else None
                    for k, v in zip(model.names_out, out.values[i], strict=True)})
        if i in out.failures:
            row["failure"] = out.failures[i]
        rows.append(row)
    if args.json:
        if not quiet:
            print(fixed_inputs_line(model), file=sys.stderr)
        print(json.dumps(rows, indent=2))
    else:
        if not quiet:
            print(fixed_inputs_line(model))
        header = list(names) + list(model.names_out)
        titles = [with_unit(h) for h in header]
        widths = [max(14, len(t)) for t in titles]
        print("  ".join(f"{t:>{w}s}" for t, w in zip(titles, widths, strict=True)))
        for i, row in enumerate(rows):
            print("  ".join(f"{_num(row[h]):{w}.6g}" for h, w in zip(header, widths,
                                                                       strict=True)))
            if "failure" in row:
                print(f"    point {i} failed: {row['failure']}")
    if out.failures:
        n = x.shape[0]
        what = ("the evaluation failed" if n == 1 else f"all {n} evaluations failed"
                if len(out.failures) == n
                else f"{len(out.failures)} of {n} evaluations failed")
        reasons = sorted(set(out.failures.values()))
        everything = len(out.failures) == n
        # a failed point is an answer (the model's own), not an error of the command; only
        # a command that produced no answer at all exits non-zero
        print(f"rotoruq evaluate: {'error' if everything else 'warning'}: {what} "
              f"({'; '.join(reasons[:3])})", file=sys.stderr)
        return 1 if everything else 0
    return 0


def _num(v) -> float:
    return float("nan") if v is None else float(v)
