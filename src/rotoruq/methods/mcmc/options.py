"""The option records of :func:`~rotoruq.methods.mcmc.bayes.calibrate_bayes`.

Three small frozen records group its options by what they set: the chains
(:class:`ChainOptions`), the emulator (:class:`EmulatorOptions`) and the data noise
(:class:`NoiseModel`). Their fields keep the names (and defaults) of the flat keyword arguments
they replace, which are the keys of a study file's ``bayes_calibration`` step.

Examples
--------
>>> from rotoruq.methods.mcmc.options import ChainOptions, NoiseModel
>>> ChainOptions(n_samples=2000, n_chains=4).burn_in is None  # default: n_samples // 19
True
>>> NoiseModel(noise_std=[0.5, 2.0]).noise_multiplier_prior
(1.0, 1.0)
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from numpy.typing import ArrayLike

from ..._options import fields_of, legacy_keywords, legacy_mapping, with_fields

if TYPE_CHECKING:
    from ..cokriging import CoKriging
    from ..surrogate import GaussianProcess
    from .adequacy import RefineConfig
    from .samplers import SamplerConfig

__all__ = ["ChainOptions", "EmulatorOptions", "NoiseModel", "LEGACY_KEYWORDS",
           "legacy_keywords", "with_fields"]


@dataclass(frozen=True, eq=False)
class ChainOptions:
    """The Markov chains: algorithm, length, start and initial proposal.

    Parameters
    ----------
    sampler : "dram" (default), "am", "dr", "mh", or a
        :class:`~rotoruq.methods.mcmc.samplers.SamplerConfig` with its tuning.
    n_samples : kept steps per chain (after burn-in and thinning).
    burn_in : steps dropped at the start of each chain (default None: ``n_samples // 19``,
        5 % of the steps).
    thin : keep every ``thin``-th step after the burn-in.
    n_chains : chains advanced together (one batched likelihood call per step).
    proposal_covariance : "hessian", "prior" or a (d, d) array in parameter units.
    map_start : start the chains at the maximum a posteriori point.
    x0 : (d,) start point (parameter units), or None.

    Examples
    --------
    >>> ChainOptions(sampler="am", n_samples=500, burn_in=0).thin
    1
    """

    sampler: str | SamplerConfig = "dram"
    n_samples: int = 95_000
    burn_in: int | None = None
    thin: int = 1
    n_chains: int = 1
    proposal_covariance: str | ArrayLike = "hessian"
    map_start: bool = True
    x0: ArrayLike | None = None


@dataclass(frozen=True, eq=False)
class EmulatorOptions:
    """An emulator in place of the model in the likelihood, and how it is built and refined.

    Parameters
    ----------
    emulator : a GaussianProcess or a CoKriging, unfitted (built here on
        ``n_emulator_samples`` LHS points of the prior) or fitted (used as given).
    n_emulator_samples : build points of an unfitted emulator.
    emulator_variance : add the emulator's Kriging variance to the noise variance (Higdon et
        al. 2004); False: its mean only (the reference thesis).
    refine : a :class:`~rotoruq.methods.mcmc.adequacy.RefineConfig` to refine the emulator over
        the posterior, or None.

    Examples
    --------
    >>> from rotoruq.methods.surrogate import GaussianProcess
    >>> EmulatorOptions(GaussianProcess(), n_emulator_samples=60).emulator_variance
    True
    """

    emulator: GaussianProcess | CoKriging
    n_emulator_samples: int = 500
    emulator_variance: bool = True
    refine: RefineConfig | None = None


@dataclass(frozen=True, eq=False)
class NoiseModel:
    """The data noise: its stated size and the multipliers calibrated with the parameters.

    Parameters
    ----------
    noise_std : standard deviation (data units): scalar, (m,) per response or (n_exp, m) per
        observation. noise_covariance : instead, a full (m, m) or (n_exp, m, m) covariance.
        Neither: unit variance (Dakota's default).
    noise_multipliers : "one", "per_response", "per_experiment" or a list of observed
        responses: calibrated multipliers of the stated variance (needs ``noise_std``).
    noise_multiplier_prior : (alpha, beta) of each multiplier's inverse-gamma prior.

    Examples
    --------
    >>> NoiseModel(noise_std=0.5, noise_multipliers="one").noise_covariance is None
    True
    """

    noise_std: ArrayLike | None = None
    noise_covariance: ArrayLike | None = None
    noise_multipliers: str | Sequence[str] | None = None
    noise_multiplier_prior: tuple[float, float] = (1.0, 1.0)


#: The flat keyword arguments of calibrate_bayes before its option records (deprecated,
#: accepted for one release): old name -> (parameter, record class name, field).
LEGACY_KEYWORDS: Mapping[str, tuple[str, str, str]] = {
    **legacy_mapping("chains", ChainOptions),
    **legacy_mapping("emulator", EmulatorOptions, fields_of(EmulatorOptions)[1:]),
    **legacy_mapping("noise", NoiseModel),
}

