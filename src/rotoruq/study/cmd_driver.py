"""``rotoruq driver PARAMS RESULTS``: the rotor model as a Dakota analysis driver.

An existing Dakota study calls rotoruq in place of its MBDyn driver script::

    interface
      fork
        analysis_drivers = 'rotoruq driver --preset gvpm'
        parameters_file = 'params.in'
        results_file = 'results.out'

The variables of the parameters file (standard or aprepro format) are the rotor inputs
(``collective_deg``, ``k_pitch_link``, ``cla_m03``, ...); the response labels of its functions
block (``thrust``, ``torque``, ``power``, ...) are the responses, unless ``--responses`` says
otherwise. A failed rotor evaluation writes ``FAIL`` so Dakota's failure policy applies.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ..errors import EvaluationError, ParameterError
from ..evaluation.dakota_files import read_parameters, write_results
from ..model import evaluate, has_gradient

HELP = "act as a Dakota analysis driver: read a parameters file, write a results file"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("params", type=Path, help="Dakota parameters file (standard or aprepro)")
    parser.add_argument("results", type=Path, help="results file to write")
    parser.add_argument("--preset", default="gvpm", help="rotor preset (default: gvpm)")
    parser.add_argument("--responses", nargs="+", metavar="NAME",
                        help="responses to write, in order (default: the labels of the "
                             "functions in the parameters file)")
    parser.add_argument("--set", nargs="+", default=[], metavar="NAME=VALUE", dest="fixed",
                        help="rotor inputs held fixed at these values")


def _fixed(items: list[str]) -> dict[str, float]:
    out = {}
    for item in items:
        name, eq, value = item.partition("=")
        try:
            if not eq:
                raise ValueError
            out[name.strip()] = float(value)
        except ValueError:
            raise ParameterError(f"--set expects NAME=VALUE with a number, got {item!r}") from None
    return out


def run_driver(params_path, results_path, model, responses=None) -> int:
    """Evaluate ``model`` at the point of a parameters file and write the results file.

    ``model`` must take the file's variables as inputs (any order). Responses default to the
    function labels of the file. Gradients (ASV bit 2) are written when the model has an
    analytic gradient, with respect to the file's derivative variables; Hessians (bit 4) are
    not available. Returns 0; a failed evaluation writes ``FAIL`` and returns 0 as well, as
    Dakota expects.
    """
    p = read_parameters(params_path)
    names = list(responses) if responses else list(p.names_out)
    asv = [p.asv.get(n, 1) for n in names]
    missing = [n for n in names if n not in model.names_out]
    if missing:
        raise ParameterError(f"responses {missing} are not outputs of {model!r}; "
                             f"outputs: {list(model.names_out)}")
    if any(a & 4 for a in asv):
        raise EvaluationError("Hessians were requested (ASV bit 4) but the rotor model has "
                              "none; use numerical_hessians or no_hessians in Dakota")
    if any(a & 2 for a in asv) and not has_gradient(model):
        raise EvaluationError("gradients were requested (ASV bit 2) but the model has no "
                              "analytic gradient; use numerical_gradients in Dakota")
    unknown = [k for k in p.variables if k not in model.names_in]
    absent = [k for k in model.names_in if k not in p.variables]
    if unknown or absent:
        raise ParameterError(f"parameters file variables {list(p.variables)} do not match the "
                             f"model inputs {list(model.names_in)}")
    try:
        x = np.array([[float(p.variables[k]) for k in model.names_in]])
    except (TypeError, ValueError):
        raise ParameterError("string variables cannot be rotor inputs") from None
    batch = evaluate(model, x)
    cols = [list(model.names_out).index(n) for n in names]
    y = batch.values[0, cols]
    if batch.failures or not np.all(np.isfinite(y[[a & 1 == 1 for a in asv]])):
        reason = batch.failures.get(0, "non-finite response")
        print(f"rotoruq driver: evaluation {p.eval_id} failed: {reason}", file=sys.stderr)
        write_results(results_path, failed=True)
        return 0
    grads = None
    if any(a & 2 for a in asv):
        g = np.asarray(model.gradient(x))[0]  # (m, d)
        dcols = [list(model.names_in).index(k) for k in p.dvv]
        grads = np.array([g[c, dcols] for c, a in zip(cols, asv, strict=True) if a & 2])
    keep = [i for i, a in enumerate(asv) if a & 1]
    write_results(results_path, y[keep], [names[i] for i in keep], gradients=grads)
    return 0


def run(args: argparse.Namespace) -> int:
    p = read_parameters(args.params)
    responses = args.responses or list(p.names_out)
    from ..rotor.model import RotorModel  # the physics is only imported when used

    model = RotorModel(args.preset, names_in=list(p.variables), names_out=responses,
                       fixed=_fixed(args.fixed))
    return run_driver(args.params, args.results, model, responses)
