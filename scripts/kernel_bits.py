"""Bit-for-bit check of the compiled kernels across a change of how they are compiled.

Saves (``save``) or compares (``check``) the outputs of the rotor kernel (hover: every preset
and solver path, random points with failing rows; forward flight: given controls, Drees
inflow, both trims), the chain kernels (the draws of a calibration on an emulator, with and
without its variance, and on a model, for fixed seeds) and the emulator kernels (GP mean and
variance). ``check`` exits 1 and names every array that is not ``np.array_equal`` (NaN equal
to NaN) to the saved one. A change meant to leave the numbers alone (inlining, compile
options, signatures; issue 34) is run as::

    git stash; python scripts/kernel_bits.py save /tmp/bits.npz; git stash pop
    python scripts/kernel_bits.py check /tmp/bits.npz

The bits depend on the machine (CPU, libm): compare files made on the same one.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from dataclasses import fields

import numpy as np

from rotoruq.methods._gp_mean import gp_mean_batch, gp_mean_var_batch
from rotoruq.methods.mcmc import ChainOptions, EmulatorOptions, NoiseModel, calibrate_bayes
from rotoruq.methods.surrogate import GaussianProcess
from rotoruq.model import FunctionModel
from rotoruq.params import ParameterSpace, Uniform
from rotoruq.rotor.aero import LinearAirfoil
from rotoruq.rotor.forward import ForwardRotorModel
from rotoruq.rotor.model import RotorModel
from rotoruq.rotor.presets import bo105, gvpm

GVPM_IN = ["collective_deg", "lateral_deg", "longitudinal_deg", "k_pitch_link", "c_pitch_link",
           "ei_flap", "height_over_radius", "omega", "cm0", "aero_center_offset",
           "cla_m02", "cl0_m03", "cda2_m02", "cda_m03", "cd0_m04"]
GVPM_MEAN = [5.4, 0.0, 0.0, 15.0, 0.05, 8.5, 2.0, 224.5, 0.0, -0.001,
             0.1055, 0.0, 1.2e-5, 0.0, 0.0077]
GVPM_STD = [1.5, 1.5, 1.5, 6.0, 0.02, 2.0, 1.0, 15.0, 0.004, 0.001,
            0.006, 0.01, 2e-6, 1e-4, 0.0006]
BO_IN = ["collective_deg", "lateral_deg", "longitudinal_deg", "k_flap", "k_lag",
         "k_pitch_link", "height_over_radius", "cla_m03", "cla_m05", "cl0_m06"]
BO_MEAN = [6.0, 0.0, -2.0, 15035.0, 70698.0, 1e9, 2.5, 0.1075, 0.1172, 0.0]
BO_STD = [2.0, 1.5, 1.5, 3000.0, 10000.0, 0.0, 1.0, 0.006, 0.006, 0.02]
COMMANDS = ["collective_deg", "lateral_deg", "longitudinal_deg", "height_over_radius"]


def _draw(mean, std, n, seed):
    rng = np.random.default_rng(seed)
    return np.asarray(mean) + np.asarray(std) * rng.standard_normal((n, len(mean))), rng


def _solution(prefix: str, sol) -> Iterator[tuple[str, np.ndarray]]:
    for f in fields(sol):
        value = np.asarray(getattr(sol, f.name))
        yield f"{prefix}.{f.name}", value.astype(str) if value.dtype.kind in "OU" else value


def _solve(model, x):
    """Every row's solution (rows refused before the solve or failing in it included)."""
    model.evaluate(x)
    return model.last_solution


def hover() -> Iterator[tuple[str, np.ndarray]]:
    """Every preset and solver path, random points (failing rows among them)."""
    x, rng = _draw(GVPM_MEAN, GVPM_STD, 400, 1)
    h = GVPM_IN.index("height_over_radius")
    x[:, h] = np.where(rng.random(len(x)) < 0.2, np.inf, np.clip(x[:, h], 0.7, None))
    x[:, 3] = np.abs(x[:, 3]) + 1.0
    x[7, 0] = 60.0
    yield from _solution("hover.gvpm", _solve(RotorModel("gvpm", names_in=GVPM_IN), x))
    x, rng = _draw(BO_MEAN, BO_STD, 300, 2)
    h = BO_IN.index("height_over_radius")
    x[:, h] = np.where(rng.random(len(x)) < 0.3, np.inf, np.clip(x[:, h], 0.7, None))
    yield from _solution("hover.bo105", _solve(RotorModel("bo105", names_in=BO_IN), x))
    paths = {"bemt": gvpm(inflow="bemt", harmonic_inflow=True),
             "harmonic": gvpm(harmonic_inflow=True, tip_loss=False),
             "bo105_delta3": bo105(pitching_moment=False, delta3_deg=20.0, k_pitch_link=2e5),
             "bo105_bemt": bo105(inflow="bemt")}
    for name, preset in paths.items():
        x, _ = _draw([6.0, 0.0, 0.0, 2.0], [2.0, 1.5, 1.5, 0.8], 100, 3)
        x[:, 3] = np.clip(x[:, 3], 0.7, None)
        yield from _solution(f"hover.{name}", _solve(RotorModel(preset, names_in=COMMANDS), x))
    names = ["collective_deg", "lateral_deg", "cla", "cl0", "cd0"]
    x, _ = _draw([6.0, 0.0, 0.1, 0.0, 0.01], [2.0, 1.0, 0.01, 0.05, 0.002], 100, 4)
    model = RotorModel(gvpm(k_pitch_link=1e9), airfoil=LinearAirfoil(cda2=1e-4),
                       names_in=names)
    yield from _solution("hover.linear", _solve(model, x))


def forward() -> Iterator[tuple[str, np.ndarray]]:
    """Given controls (Glauert and Drees, mu = 0 rows among them) and both trims."""
    names = ["collective_deg", "lateral_deg", "longitudinal_deg", "advance_ratio",
             "shaft_angle_deg"]
    x, rng = _draw([6.0, 0.0, -1.0, 0.15, 3.0], [1.5, 1.0, 1.0, 0.08, 3.0], 120, 5)
    x[:, 3] = np.clip(x[:, 3], 0.0, 0.35)
    x[::10, 3] = 0.0
    for preset in ("gvpm", "bo105"):
        for inflow in ("glauert", "drees"):
            model = ForwardRotorModel(preset, names_in=names, inflow_model=inflow)
            yield from _solution(f"forward.{preset}.{inflow}", _solve(model, x))
    for trim in ("wind_tunnel", "hub_moments"):
        x, _ = _draw([0.15, 2.0, 12.0], [0.08, 2.0, 1.0], 60, 6)
        x[:, 0] = np.clip(x[:, 0], 0.0, 0.35)
        model = ForwardRotorModel("gvpm", names_in=["advance_ratio", "shaft_angle_deg",
                                                    "thrust_target"], trim=trim)
        yield from _solution(f"forward.{trim}", _solve(model, x))


def chains() -> Iterator[tuple[str, np.ndarray]]:
    """Draws of the chain kernels for fixed seeds: on an emulator (its mean; mean and
    variance) and on a model; and the emulator kernels' mean and variance."""
    def f(x):
        return np.column_stack([x[:, 0] ** 2 + 0.5 * x[:, 1], np.sin(3 * x[:, 0]) * x[:, 1]])

    model = FunctionModel(f, ["a", "b"], ["y1", "y2"])
    prior = ParameterSpace({"a": Uniform(0.0, 1.0), "b": Uniform(-1.0, 1.0)})
    data = f(np.array([[0.4, 0.3]])) + np.array([[0.01, -0.02]])
    noise = NoiseModel(noise_std=0.05)
    for name, emulator in (("gp_mean", EmulatorOptions(GaussianProcess(), 30,
                                                         emulator_variance=False)),
                           ("gp_var", EmulatorOptions(GaussianProcess(), 30)),
                           ("model", None)):
        res = calibrate_bayes(model, data, prior, noise=noise, emulator=emulator, seed=11,
                              chains=ChainOptions(n_samples=600, burn_in=100, n_chains=3))
        yield f"chains.{name}.draws", res.chains
        yield f"chains.{name}.log_posterior", res.log_posterior
    x = np.random.default_rng(7).random((40, 2))
    gp = GaussianProcess(seed=0).fit(x, f(x))
    z = np.random.default_rng(8).random((25, 2))
    yield "gp.mean", gp_mean_batch(z, gp.compiled().mean_pack)
    mean, var = gp_mean_var_batch(z, gp.compiled(variance=True))
    yield "gp.mean_var.mean", mean
    yield "gp.mean_var.var", var


PARTS = {"hover": hover, "forward": forward, "chains": chains}


def collect(parts) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for part in parts:
        out.update(PARTS[part]())
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("action", choices=("save", "check"))
    ap.add_argument("path", help="the .npz file of the outputs")
    ap.add_argument("--parts", nargs="+", default=list(PARTS), choices=list(PARTS))
    args = ap.parse_args(argv)
    got = collect(args.parts)
    if args.action == "save":
        np.savez(args.path, **got)
        print(f"saved {len(got)} arrays to {args.path}")
        return 0
    with np.load(args.path) as ref:
        differ = [k for k in got if k not in ref
                  or got[k].shape != ref[k].shape
                  or not np.array_equal(got[k], ref[k],
                                        equal_nan=got[k].dtype.kind in "fc")]
        missing = [k for k in ref.files if k.split(".")[0] in args.parts and k not in got]
    n_values = sum(v.size for v in got.values())
    if differ or missing:
        print(f"DIFFERENT: {differ}; missing: {missing}")
        return 1
    print(f"bitwise equal: {len(got)} arrays, {n_values} values")
    return 0


if __name__ == "__main__":
    sys.exit(main())
