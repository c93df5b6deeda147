"""Every public random function of rotoruq: the same seed gives bitwise the same result.

The functions are found, not listed: every callable in ``rotoruq.__all__`` with a ``seed``
parameter. Each needs a small problem below (``CASES``); a new random function without one
fails :func:`test_every_random_function_has_a_recipe`, so none escapes the check. The result is
walked (dataclass fields, mappings, sequences) and every array and number in it compared byte
for byte. A different seed must change some array, so the comparison is not vacuous.
"""

from __future__ import annotations

import dataclasses
import inspect
import warnings
from collections.abc import Callable, Mapping

import numpy as np
import pytest

import rotoruq as rq
from rotoruq.methods.surrogate import ExtrapolationWarning

# --- small problems -------------------------------------------------------------------------


def _quadratic():
    space = rq.ParameterSpace({"a": rq.Normal(0.5, 0.3), "b": rq.Uniform(-1.0, 1.0)})
    model = rq.FunctionModel(
        lambda x: np.column_stack([x[:, 0] + x[:, 1] ** 2, np.sin(x[:, 0]) * x[:, 1]]),
        ["a", "b"], ["y", "z"])
    return model, space


def _bayes(seed, **kw):
    model, space = _quadratic()
    data = np.array([[0.8, 0.2], [0.7, 0.25], [0.9, 0.15]])
    return rq.calibrate_bayes(model, data, space,
                              chains=rq.ChainOptions(n_samples=300, burn_in=20, n_chains=2),
                              noise=rq.NoiseModel(noise_std=[0.1, 0.05]), seed=seed, **kw)


def _gp(seed):
    x = np.random.default_rng(0).uniform(-1.0, 1.0, size=(12, 2))
    y = np.column_stack([np.sin(3 * x[:, 0]) + x[:, 1], x[:, 0] * x[:, 1]])
    gp = rq.GaussianProcess(n_restarts=2, seed=seed).fit(x, y)
    mean, var = gp.predict(np.linspace(-0.9, 0.9, 14).reshape(7, 2))
    return {"length_scales": gp.length_scales, "process_variance": gp.process_variance,
            "mean": mean, "var": var}


def _cuu(seed, inner="sampling"):
    a = np.array([[2.0, 1.0], [0.5, 3.0]])
    model = rq.FunctionModel(lambda x: x @ a.T, ["x1", "x2"], ["y1", "y2"])
    space = rq.ParameterSpace({"x1": rq.Normal(1.0, 0.1), "x2": rq.Normal(-2.0, 0.5)})
    return model, rq.calibrate_under_uncertainty(
        model, space, calibrate={"x1": "std", "x2": "std"},
        targets={"y1": {"std": 0.7}, "y2": {"std": 0.65}}, inner=inner,
        inner_options={"n_samples": 64} if inner == "sampling" else None, seed=seed)


def _evidence(seed):
    space = rq.ParameterSpace({
        "a": rq.Interval([(0.0, 1.0), (1.0, 3.0)], [0.4, 0.6]),
        "b": rq.Interval([(-1.0, 1.0), (0.5, 2.0)], [0.5, 0.5])})
    model = rq.FunctionModel(lambda x: np.sin(3 * x[:, 0]) * x[:, 1], ["a", "b"], ["g"])
    # EGO's stopping tolerance 1e-2 (default 1e-4): 19 refinements instead of 39, each
    # seeded the same way (0.6 instead of 1.6 CPU-s a call)
    return rq.evidence(model, space, n_samples=20, n_starts=2, response_levels=[[0.0, 0.5]],
                       tolerance=1e-2, seed=seed)


def _sample(seed):
    model, space = _quadratic()
    return rq.sample(model, space, 40, seed=seed)


def _bayes_emulated(seed):
    # the README's example: an unseeded GaussianProcess() handed to calibrate_bayes(seed=)
    return _bayes(seed, emulator=rq.EmulatorOptions(rq.GaussianProcess(), n_emulator_samples=30))


def _sbc(seed):
    model, space = _quadratic()
    return rq.simulation_based_calibration(model, space, noise_std=0.3, n_replications=6,
                                           n_draws=9, n_samples=300, seed=seed)


def _discrepancy(seed):
    h = np.repeat([1.0, 2.0, 3.0], 2)
    model = rq.FunctionModel(lambda x: x[:, 0] * np.exp(-0.3 * x[:, 1]), ["a", "h"], ["y"])
    y = (2.0 * np.exp(-0.3 * h) + 0.1 * np.sin(h))[:, None]
    prior = rq.ParameterSpace({"a": rq.Normal(2.0, 0.5)})
    return rq.calibrate_with_discrepancy(
        model, y, prior, configurations=h, configuration_name="h",
        discrepancy=rq.Discrepancy(amplitude_scale=0.2), noise_std=0.05, n_samples=200,
        n_draws=20, seed=seed)


def _importance(seed):
    space = rq.ParameterSpace({"a": rq.Normal(10, 5), "b": rq.Normal(10, 5)})
    model = rq.FunctionModel(lambda x: x[:, 0] ** 3 + x[:, 1] ** 3 - 18, ["a", "b"], ["g"])
    mpp = rq.mpp_search(model, space, response_levels=[0.0])
    return rq.importance_sampling(model, space, mpp, n_samples=200, n_rounds=1, seed=seed)


def _box(seed):
    return rq.box_extremes(lambda x: np.sin(3 * x[:, :1]) * x[:, 1:], [0.0, 1.0], [1.0, 3.0],
                           max_evaluations=25, seed=seed)


def _ladder():
    return [rq.FunctionModel(lambda x, p=p: x[:, 0] ** p, ["x"], ["y"]) for p in (5, 4, 3)]


def _multifidelity(seed):
    return rq.multifidelity_sample(_ladder(), rq.ParameterSpace({"x": rq.Uniform(0.0, 1.0)}),
                                   50.0, n_pilot=20, costs=[1.0, 0.05, 0.01], seed=seed)


def _multifidelity_sobol(seed):
    models = [rq.FunctionModel(lambda x, p=p: x[:, 0] ** p + 0.5 * x[:, 1], ["a", "b"], ["y"])
              for p in (3, 2)]
    space = rq.ParameterSpace({"a": rq.Uniform(0.0, 1.0), "b": rq.Uniform(0.0, 1.0)})
    return rq.multifidelity_sobol(models, space, 200.0, n_pilot=20, costs=[1.0, 0.05],
                                  seed=seed)


def _cokriging(seed):
    x_lo = np.linspace(0.0, 1.0, 11)[:, None]
    x_hi = x_lo[::3]
    lo, hi = np.sin(8 * x_lo) + x_lo, 2.0 * (np.sin(8 * x_hi) + x_hi) + x_hi ** 2
    ck = rq.CoKriging(seed=seed).fit([x_lo, x_hi], [lo, hi])
    mean, var = ck.predict(np.linspace(0.05, 0.95, 7)[:, None])
    return {"mean": mean, "var": var, "rho": np.asarray(ck.rho, dtype=float)}


#: case -> (public function, small problem calling it with a seed)
CASES: dict[str, tuple[str, Callable[[int], object]]] = {
    "as_generator": ("as_generator", lambda s: rq.as_generator(s).random(16)),
    "sample": ("sample", _sample),
    "refine": ("refine", lambda s: rq.refine(_sample(3), 24, seed=s)),
    "sobol_indices": ("sobol_indices",
                      lambda s: rq.sobol_indices(*_quadratic(), 64, n_bootstrap=20, seed=s)),
    "polynomial_chaos": ("polynomial_chaos", lambda s: rq.polynomial_chaos(
        *_quadratic(), 2, estimator="regression", n_samples=30, seed=s)),
    "evidence": ("evidence", _evidence),
    "importance_sampling": ("importance_sampling", _importance),
    "box_extremes": ("box_extremes", _box),
    "calibrate_bayes": ("calibrate_bayes", _bayes),
    "calibrate_bayes_emulator": ("calibrate_bayes", _bayes_emulated),
    "continue_chain": ("continue_chain", lambda s: rq.continue_chain(_bayes(3), 100, seed=s)),
    "GaussianProcess": ("GaussianProcess", _gp),
    "CoKriging": ("CoKriging", _cokriging),
    "multifidelity_sample": ("multifidelity_sample", _multifidelity),
    "multifidelity_sample_adapted": ("multifidelity_sample", lambda s: rq.multifidelity_sample(
        _ladder(), rq.ParameterSpace({"x": rq.Uniform(0.0, 1.0)}), 50.0, n_pilot=20,
        costs=[1.0, 0.05, 0.01], adapt="linear", seed=s)),
    "multifidelity_sobol": ("multifidelity_sobol", _multifidelity_sobol),
    "simulation_based_calibration": ("simulation_based_calibration", _sbc),
    "calibrate_with_discrepancy": ("calibrate_with_discrepancy", _discrepancy),
    "predict_with_discrepancy": ("predict_with_discrepancy", lambda s: rq.predict_with_discrepancy(
        _discrepancy(3), rq.FunctionModel(lambda x: x[:, 0] * np.exp(-0.3 * x[:, 1]),
                                          ["a", "h"], ["y"]), [0.5], n_draws=30, seed=s)),
    "calibrate_under_uncertainty": ("calibrate_under_uncertainty", lambda s: _cuu(s)[1]),
    "check_cuu": ("check_cuu", lambda s: rq.check_cuu(
        _cuu(3, inner="mean_value")[1], _cuu(3, inner="mean_value")[0], 40, seed=s)),
}

# cases known to differ between two calls with one seed (strict xfail: fixed ones must leave)
KNOWN_NONDETERMINISTIC: set[str] = set()

# random choices a seed may legitimately not change (the answer is the same optimum)
SEED_INSENSITIVE = {"GaussianProcess", "calibrate_under_uncertainty"}

# fields that measure the machine, not the method
TIMING = ("seconds", "elapsed", "wall")


def _random_functions() -> dict[str, Callable]:
    out = {}
    for name in rq.__all__:
        obj = getattr(rq, name)
        if not callable(obj):
            continue
        try:
            params = inspect.signature(obj).parameters
        except (TypeError, ValueError):
            continue
        if "seed" in params:
            out[name] = obj
    return out


def _walk(obj, path: str, out: dict[str, object], depth: int = 0) -> None:
    """Collect every array and number reachable from a result, keyed by its path."""
    if depth > 6:
        return
    if isinstance(obj, np.ndarray):
        out[path] = obj
    elif isinstance(obj, bool | int | float | complex | np.number | np.bool_):
        out[path] = np.asarray(obj)
    elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        for f in dataclasses.fields(obj):
            if f.name.startswith("_") or any(t in f.name for t in TIMING):
                continue
            _walk(getattr(obj, f.name), f"{path}.{f.name}", out, depth + 1)
    elif isinstance(obj, Mapping):
        for k, v in obj.items():
            _walk(v, f"{path}[{k!r}]", out, depth + 1)
    elif isinstance(obj, list | tuple):
        for i, v in enumerate(obj):
            _walk(v, f"{path}[{i}]", out, depth + 1)


def _arrays(name: str, seed: int) -> dict[str, object]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExtrapolationWarning)
        warnings.simplefilter("ignore", RuntimeWarning)
        warnings.simplefilter("ignore", UserWarning)
        result = CASES[name][1](seed)
    out: dict[str, object] = {}
    _walk(result, name, out)
    return out


def _bitwise_equal(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    if a.dtype.hasobject:
        return bool(np.all(a == b))
    return np.ascontiguousarray(a).tobytes() == np.ascontiguousarray(b).tobytes()


def test_every_random_function_has_a_recipe():
    found = set(_random_functions())
    covered = {fn for fn, _ in CASES.values()}
    assert found == covered, (
        f"random functions without a determinism case: {sorted(found - covered)}; "
        f"cases for names no longer public: {sorted(covered - found)}")


@pytest.mark.parametrize("name", [
    pytest.param(c, marks=pytest.mark.xfail(strict=True, reason="issue 21: emulator unseeded"))
    if c in KNOWN_NONDETERMINISTIC else c for c in sorted(CASES)])
def test_same_seed_gives_bitwise_the_same_result(name):
    first, second = _arrays(name, 11), _arrays(name, 11)
    assert first, f"{name}: no array or number found in its result"
    assert first.keys() == second.keys()
    differ = [k for k in first if not _bitwise_equal(first[k], second[k])]
    assert not differ, f"{name}: seed 11 twice gives different {differ}"
    if name not in SEED_INSENSITIVE:
        other = _arrays(name, 12)
        assert any(not _bitwise_equal(first[k], other[k]) for k in first if k in other), (
            f"{name}: seeds 11 and 12 give the same result: the seed is not used")
