"""Markov chain Monte Carlo Bayesian calibration: Gaussian likelihood, MH / DR / AM / DRAM
samplers advancing several chains in one batched step, diagnostics (ESS, split R-hat, KL)."""

from .adequacy import EmulatorAdequacy, RefineConfig
from .bayes import BayesResult, calibrate_bayes, continue_chain
from .diagnostics import effective_sample_size, split_rhat
from .likelihood import GaussianLikelihood
from .options import ChainOptions, EmulatorOptions, NoiseModel
from .samplers import SAMPLERS, SamplerConfig, SamplerState, run_chains

__all__ = [
    "BayesResult",
    "calibrate_bayes",
    "continue_chain",
    "ChainOptions",
    "EmulatorOptions",
    "NoiseModel",
    "EmulatorAdequacy",
    "RefineConfig",
    "effective_sample_size",
    "split_rhat",
    "GaussianLikelihood",
    "SAMPLERS",
    "SamplerConfig",
    "SamplerState",
    "run_chains",
]
