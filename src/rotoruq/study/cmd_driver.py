"""``rotoruq driver [options] PARAMS RESULTS``: the rotor model as a Dakota analysis driver.

An existing Dakota study calls rotoruq in place of its MBDyn driver script::

    interface
      fork
        analysis_drivers = 'rotoruq driver --set omega=230 --map theta_0=collective_deg'
        parameters_file = 'params.in'
        results_file = 'results.out'

The variables of the parameters file (standard or aprepro format, one block or a ``batch`` of
them) are rotor inputs (``collective_deg``, ``k_pitch_link``, ``cla_m03``, ...) or deck labels
renamed by ``--map``; the response labels (``thrust``, ``torque``, ``power``, ...) are the
outputs unless ``--outputs`` says otherwise. Values, gradients (ASV 2: central finite
differences of the rotor, in one batched call) and the ``seconds`` metadata are written; every
failure writes ``FAIL`` (see :mod:`rotoruq.evaluation.driver`).

This module is the lean path: it loads the evaluation layer's driver loop and the rotor model,
nothing of the study, report or methods.
"""

from __future__ import annotations

import argparse

from ..evaluation import driver as _driver
from ..evaluation.driver import run_model as run_driver
from ..model import Model

__all__ = ["HELP", "add_arguments", "main", "make_model", "run", "run_driver"]

HELP = "act as a Dakota analysis driver: read a parameters file, write a results file"
PROGRAM = "rotoruq driver"


def _model_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--preset", default="gvpm", help="rotor preset (default: gvpm)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    _driver.add_arguments(parser)
    _model_arguments(parser)


def make_model(args: argparse.Namespace, names_in: list[str], names_out: list[str],
               fixed: dict[str, float]) -> Model:
    """The rotor model of ``args.preset`` with the deck's inputs and outputs."""
    from ..rotor.model import RotorModel  # the physics is only imported when used

    return RotorModel(args.preset, names_in=names_in, names_out=names_out, fixed=fixed)


def main(argv: list[str] | None = None, make_model: _driver.MakeModel = make_model) -> int:
    """Run the driver on a command line (without the ``driver`` word); see the module.
    ``make_model`` is the driver server's hook (it keeps the models it makes)."""
    return _driver.main(argv, make_model, program=PROGRAM, description=HELP,
                        add_model_arguments=_model_arguments)


def run(args: argparse.Namespace) -> int:
    return _driver.run(args.params, args.results, make_model, args, program=PROGRAM)
