"""Markov chain Monte Carlo Bayesian calibration: Gaussian likelihood, MH / DR / AM / DRAM
samplers advancing several chains in one batched step, diagnostics (ESS, split R-hat, KL, the
MSER-5 warm-up)."""

from .adequacy import EmulatorAdequacy, RefineConfig
from .bayes import BayesResult, calibrate_bayes, continue_chain
from .diagnostics import effective_sample_size, split_rhat
from .likelihood import GaussianLikelihood
from .options import ChainOptions, EmulatorOptions, NoiseModel
from .samplers import SAMPLERS, SamplerConfig, SamplerState, run_chains
from .warmup import WarmUp, mser_warm_up

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
    "mser_warm_up",
    "WarmUp",
    "GaussianLikelihood",
    "SAMPLERS",
    "SamplerConfig",
    "SamplerState",
    "run_chains",
]
