"""The public API follows docs/vocabulary.md: one name per concept.

Every public function, constructor and method reachable from ``rotoruq.__all__`` is checked for
the names the vocabulary retired, every result dataclass for its fields and ``eq=False``, and the
bundled study files for their keys.
"""

from __future__ import annotations

import dataclasses
import inspect
import tomllib
from importlib import resources

import numpy as np
import pytest

import rotoruq as rq

# Retired name -> the one name that replaces it (docs/vocabulary.md).
RETIRED_PARAMETERS = {
    "n": "n_samples",
    "chain_samples": "n_samples",
    "n_more": "n_samples",
    "n_steps": "n_samples",
    "build_samples": "n_emulator_samples",
    "method": "design / estimator / sampler / optimizer",
    "jacobian": "gradient",
    "data_variance": "noise_std",
    "data_covariance": "noise_std / noise_covariance",
    "weights": "noise_std",
    "start": "x0",
    "names": "names_in / names_out",
    "labels": "names_in / names_out",
    "tol": "tolerance",
    "max_iter": "max_iterations",
    "convergence_tolerance": "tolerance",
    "mu": "mean",
    "sigma": "std",
}
RETIRED_FIELDS = {
    "names": "names_in / names_out",
    "labels": "names_in / names_out",
    "n_model_evals": "n_evaluations",
    "n_model_evaluations": "n_evaluations",
    "n_likelihood_evals": "n_likelihood_evaluations",
    "success": "converged",
    "method": "design / estimator / sampler / optimizer",
    "chain_samples": "n_samples",
}
RETIRED_STUDY_KEYS = {
    "n": "n_samples",
    "method": "design / estimator / sampler / optimizer",
    "chain_samples": "n_samples",
    "build_samples": "n_emulator_samples",
    "start": "x0",
}
# Model constructors name their inputs and outputs like the Model protocol does.
MODEL_CLASSES = ("RotorModel", "FunctionModel", "ExternalModel")


def _public_objects():
    for name in sorted(rq.__all__):
        yield name, getattr(rq, name)


def _callables():
    """(qualified name, callable) for every public function, constructor and public method."""
    for name, obj in _public_objects():
        if inspect.isfunction(obj):
            yield name, obj
        elif inspect.isclass(obj):
            if not issubclass(obj, BaseException) and not dataclasses.is_dataclass(obj):
                yield f"{name}.__init__", obj.__init__
            for attr, member in vars(obj).items():
                if attr.startswith("_"):
                    continue
                if isinstance(member, (staticmethod, classmethod)):
                    member = member.__func__
                if inspect.isfunction(member):
                    yield f"{name}.{attr}", member


def _signatures():
    """(qualified name, parameters) of every public callable whose signature can be read."""
    for qualname, func in _callables():
        try:
            yield qualname, inspect.signature(func).parameters
        except (TypeError, ValueError):
            continue


def _result_classes():
    for name, obj in _public_objects():
        if inspect.isclass(obj) and dataclasses.is_dataclass(obj) and name.endswith(
                ("Result", "Statistics", "Check", "LeaveOneOut", "Run")):
            yield name, obj


def test_public_signatures_use_the_vocabulary():
    bad = []
    for qualname, params in _signatures():
        for p in params:
            if p in RETIRED_PARAMETERS:
                bad.append(f"{qualname}({p}=) -> {RETIRED_PARAMETERS[p]}")
        if qualname.split(".")[0] in MODEL_CLASSES:
            for p in ("inputs", "responses"):
                if p in params:
                    bad.append(f"{qualname}({p}=) -> names_in / names_out")
    assert not bad, "retired names in public signatures:\n" + "\n".join(bad)


def test_seed_is_keyword_only_and_only_where_random():
    bad = []
    for qualname, params in _signatures():
        if qualname == "as_generator":  # the seed normalizer: the seed is its one argument
            continue
        if "seed" in params and params["seed"].kind is not inspect.Parameter.KEYWORD_ONLY:
            bad.append(f"{qualname}: seed is not keyword-only")
    assert not bad, "\n".join(bad)
    for deterministic in (rq.mean_value, rq.mpp_search):
        assert "seed" not in inspect.signature(deterministic).parameters, deterministic.__name__


@pytest.mark.parametrize("seed", [True, False, 1.5, "7", np.float64(2.0)])
def test_seed_rejects_non_integers(seed):
    with pytest.raises(rq.ParameterError, match="seed"):
        rq.as_generator(seed)


def test_result_fields_and_equality():
    bad = []
    classes = list(_result_classes())
    assert len(classes) >= 10, [c for c, _ in classes]
    for name, cls in classes:
        params = cls.__dataclass_params__
        if not params.frozen:
            bad.append(f"{name}: not frozen")
        if params.eq:
            bad.append(f"{name}: eq=True (arrays cannot compare with ==); use eq=False")
        for f in dataclasses.fields(cls):
            if f.name in RETIRED_FIELDS:
                bad.append(f"{name}.{f.name} -> {RETIRED_FIELDS[f.name]}")
    assert not bad, "\n".join(bad)


def _walk_keys(table, path=()):
    if isinstance(table, dict):
        for k, v in table.items():
            yield path + (k,)
            yield from _walk_keys(v, path + (k,))
    elif isinstance(table, list):
        for i, v in enumerate(table):
            yield from _walk_keys(v, path + (str(i),))


def test_bundled_study_files_use_the_vocabulary():
    bad = []
    studies = resources.files("rotoruq") / "studies"
    files = [f for f in studies.iterdir() if f.name.endswith(".toml")]
    assert files
    for f in files:
        doc = tomllib.loads(f.read_text())
        for key in _walk_keys(doc.get("steps", [])):
            if key[-1] in RETIRED_STUDY_KEYS:
                bad.append(f"{f.name}: steps.{'.'.join(key)} -> {RETIRED_STUDY_KEYS[key[-1]]}")
    assert not bad, "\n".join(bad)
