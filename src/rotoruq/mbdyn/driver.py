"""``python -m rotoruq.mbdyn.driver [options] PARAMS RESULTS``: MBDyn as a Dakota analysis driver.

A study's external model calls it (paths of ``[model]`` are relative to the study file)::

    [model]
    command = ["python", "-m", "rotoruq.mbdyn.driver", "--preset", "gvpm",
               "--template", "rigid", "{params}", "{results}"]
    responses = ["thrust", "torque", "power"]

and so does a Dakota deck (``analysis_drivers = 'python -m rotoruq.mbdyn.driver --template
rigid'``). It reads the parameters file (rotor inputs such as ``collective_deg`` and
``height_over_radius``, airfoil coefficients such as ``cla_m03``, deck labels renamed by
``--map``, inputs held by ``--set``), writes the sample's c81 table and the filled MBDyn input
into the current (work) directory, runs MBDyn (``--mbdyn``, else ``$MBDYN``, else ``mbdyn`` on
PATH, else the build tool's install ``$MBDYN_PREFIX/bin/mbdyn``, ``~/.cache/mbdyn`` by
default: :func:`~rotoruq.mbdyn.solver.find_mbdyn` as the benchmarks and scripts call it),
and writes the responses named by the parameters file's functions (``thrust``,
``torque``, ``roll``, ``pitch``, ``power``, ``ct``, ``cq``) as its active set vector asks:
values, gradients by central finite differences (one MBDyn run per stencil point, each in a
folder ``point_<k>``), never Hessians. A batch file (Dakota's ``batch`` interface) runs one
case per block, each in its ``point_<k>`` folder.

MBDyn does not trim. In forward flight (inputs ``advance_ratio``, ``shaft_angle_deg``) with
``--trim wind_tunnel`` the parameters file gives ``thrust_target`` [N] instead of the controls:
for each case the built-in rotor (:class:`~rotoruq.rotor.forward.ForwardRotorModel`, same
preset and inputs, ``--inflow-model``) is trimmed to that thrust and zero first-harmonic
flapping, and MBDyn flies its collective, lateral and longitudinal cyclic; a case the built-in
rotor cannot trim fails with its reason. Rotor inputs the template does not model (the rigid
template's ``k_pitch_link``, ``ei_flap``, ...) then act through the trim only.

When MBDyn fails, stops early or does not reach a periodic state, or the file or the command
line is wrong, the results file says ``FAIL``, the reason goes to stderr and the exit status is
1 (2 for a command line that does not parse), so Dakota's ``failure_capture`` and rotoruq's
failure policy both apply (see :mod:`rotoruq.evaluation.driver`).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import ParameterError, RotoruqError
from ..evaluation import driver as _driver
from ..model import EvalBatch
from .case import TEMPLATES, CaseSettings, run_case
from .extract import RESPONSES
from .solver import find_mbdyn

__all__ = ["main", "build_parser", "MBDynCaseModel"]

PROGRAM = "rotoruq mbdyn driver"


class MBDynCaseModel:
    """One MBDyn hover case per point, as a :class:`~rotoruq.model.Model`.

    names_in : rotor inputs and airfoil coefficients; names_out : hub loads of
    :data:`~rotoruq.mbdyn.extract.RESPONSES`; fixed : inputs held at a value. A call with one
    point runs in ``workdir`` itself, with several in ``workdir/point_<k>``. A point whose run
    fails is a failure of its row (reason kept), never an exception.
    """

    def __init__(self, names_in: Sequence[str], names_out: Sequence[str],
                 fixed: dict[str, float], args: argparse.Namespace,
                 workdir: Path | None = None) -> None:
        bad = [n for n in names_out if n not in RESPONSES]
        if bad:
            raise ParameterError(f"responses {bad} are not MBDyn hub loads; available: "
                                 f"{', '.join(RESPONSES)}")
        from ..rotor.presets import get_preset

        self.names_in, self.names_out = tuple(names_in), tuple(names_out)
        self.fixed = dict(fixed)
        self.preset = get_preset(args.preset)
        self.settings = CaseSettings(args.revolutions, args.steps_per_rev, args.average,
                                     args.tolerance, args.timeout)
        self.args = args
        self.workdir = Path.cwd() if workdir is None else Path(workdir)

    def evaluate(self, x: np.ndarray) -> EvalBatch:
        x = np.atleast_2d(np.asarray(x, dtype=float))
        values = np.full((len(x), len(self.names_out)), np.nan)
        failures: dict[int, str] = {}
        for k, row in enumerate(x):
            wd = self.workdir if len(x) == 1 else self.workdir / f"point_{k}"
            inputs = {**self.fixed, **dict(zip(self.names_in, row.tolist(), strict=True))}
            try:
                mbdyn = find_mbdyn(self.args.mbdyn, build_prefix=True)
                if getattr(self.args, "trim", None):
                    inputs = builtin_trim(self.preset, inputs, self.args.inflow_model)
                    inputs = self._for_template(inputs)
                loads = run_case(wd, self.preset, inputs, template=self.args.template,
                                 settings=self.settings, mbdyn=mbdyn)
                values[k] = [loads.response(n) for n in self.names_out]
            except (RotoruqError, OSError, ValueError) as exc:
                failures[k] = str(exc)
        return EvalBatch(values, failures)

    def _for_template(self, inputs: dict[str, float]) -> dict[str, float]:
        """After the built-in trim: the rotor inputs the template does not model (the rigid
        template's structure, say) have acted through the trim's controls; MBDyn gets the
        others (airfoil coefficients always)."""
        from ..evaluation.templates import template_fields
        from ..rotor.model import ROTOR_INPUTS
        from .case import DERIVED_FROM, template_text

        text, path = template_text(self.args.template)
        used = set(template_fields(text, path))
        used |= {src for f in list(used) for src in DERIVED_FROM.get(f, ())}
        return {k: v for k, v in inputs.items() if k in used or k not in ROTOR_INPUTS}

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.evaluate(x).values


#: The controls the built-in trim gives MBDyn, by the trim's response names.
TRIM_CONTROLS = {"collective_trim_deg": "collective_deg", "lateral_trim_deg": "lateral_deg",
                 "longitudinal_trim_deg": "longitudinal_deg"}


def builtin_trim(preset, inputs: dict[str, float], inflow_model: str = "glauert"
                 ) -> dict[str, float]:
    """``inputs`` with ``thrust_target`` replaced by the controls [deg] of the built-in rotor
    trimmed in the wind tunnel (thrust target, zero first-harmonic flapping) at the same
    inputs; :class:`ParameterError` naming the reason when it cannot trim.

    Parameters
    ----------
    preset : RotorPreset
        The rotor (the driver's ``--preset``).
    inputs : dict of str to float
        Rotor, forward-flight and airfoil-coefficient inputs with ``thrust_target`` [N].
    inflow_model : {"glauert", "drees"}
        The built-in rotor's inflow.
    """
    from ..rotor.forward import ForwardRotorModel

    if "thrust_target" not in inputs:
        raise ParameterError("--trim wind_tunnel needs the input thrust_target [N] in the "
                             "parameters file (or --set thrust_target=...)")
    given = [k for k in TRIM_CONTROLS.values() if k in inputs]
    if given:
        raise ParameterError(f"--trim wind_tunnel solves the controls: {given} cannot be "
                             "inputs too")
    names = list(inputs)
    model = ForwardRotorModel(preset, names_in=names, names_out=list(TRIM_CONTROLS),
                              trim="wind_tunnel", inflow_model=inflow_model)
    batch = model.evaluate(np.array([[inputs[n] for n in names]]))
    if batch.failures:
        raise ParameterError(f"the built-in rotor does not trim: {batch.failures[0]}")
    out = {k: v for k, v in inputs.items() if k != "thrust_target"}
    out.update({TRIM_CONTROLS[n]: float(v) for n, v in zip(TRIM_CONTROLS, batch.values[0],
                                                            strict=True)})
    return out


def _model_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--preset", default="gvpm", help="rotor preset for geometry and the inputs "
                   "the parameters file does not set (default: gvpm)")
    p.add_argument("--template", default="rigid",
                   help=f"bundled template ({', '.join(TEMPLATES)}) or an MBDyn template file")
    p.add_argument("--mbdyn", default=None,
                   help="MBDyn executable (default: $MBDYN, then PATH, then "
                   "$MBDYN_PREFIX/bin/mbdyn, the prefix ~/.cache/mbdyn by default)")
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
    p.add_argument("--trim", choices=["wind_tunnel"], default=None,
                   help="fly the controls of the built-in rotor trimmed to the input "
                   "thrust_target [N] and zero first-harmonic flapping (MBDyn does not trim)")
    p.add_argument("--inflow-model", choices=["glauert", "drees"], default="glauert",
                   help="the built-in rotor's inflow for --trim (default glauert)")


def build_parser() -> argparse.ArgumentParser:
    """The driver's command line (for ``--help`` and documentation)."""
    p = argparse.ArgumentParser(
        prog="python -m rotoruq.mbdyn.driver",
        description="Run one MBDyn rotor case from a Dakota parameters file and write the "
                    "results file.")
    _driver.add_arguments(p)
    _model_arguments(p)
    return p


def _make_model(args: argparse.Namespace, names_in: list[str], names_out: list[str],
                fixed: dict[str, float]) -> MBDynCaseModel:
    return MBDynCaseModel(names_in, names_out, fixed, args)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    return _driver.main(argv, _make_model, program=PROGRAM, prog=parser.prog,
                        description=parser.description or "",
                        add_model_arguments=_model_arguments)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
