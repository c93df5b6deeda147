"""Random-walk Metropolis samplers: MH, delayed rejection (DR), adaptive Metropolis (AM), DRAM.

Appendix eqs. A.9-A.11 of the reference study, after Haario, Laine, Mira and Saksman (2006).
Defaults follow Dakota's DRAM: one DR stage whose proposal covariance is the first stage's
divided by ``dr_scale**2 = 25``, adaptation from sample 100 and every 100 samples, scale
``2.38**2 / d`` and ``eps = 1e-8`` (eq. A.10). The second stage is centred on the current point,
so its own density cancels in the acceptance ratio and only the first stage's density appears.

The step itself is compiled (:mod:`._kernels`); what this module decides is *which points are
evaluated together*. The chain is a function of the seed alone, whatever the schedule:

* ``evaluations="speculative"`` (default): each call of the log posterior evaluates, for every
  chain, the stage-1 and stage-2 proposals of the next ``K`` steps, all centred on the current
  point. The steps are then taken one by one up to the first one that moves a chain; the
  proposals after it are discarded. Stage 2 is centred on the current point, not on the
  rejected stage-1 point, which is what makes it computable before stage 1 is decided. With
  one chain ``K`` follows the observed move rate (about the expected number of steps to the
  next move, at most ``max_lookahead``); with several chains ``K = 1``. This trades extra
  evaluations for far fewer calls: right for cheap models and for models whose cost per call
  hardly grows with the batch (the rotor model, a parallel executor, an emulator).
* ``evaluations="minimal"``: stage 1 of every chain, then stage 2 of the chains whose stage 1
  was rejected: the fewest model runs, for expensive models evaluated one point at a time.
* A log posterior that carries a ``compiled`` attribute (the emulator posterior of
  :func:`~rotoruq.methods.mcmc.calibrate_bayes`) runs whole blocks of steps in compiled code
  with the minimal schedule.

Random numbers come from four streams (stage-1 normals, stage-1 uniforms, stage-2 normals,
stage-2 uniforms) drawn in blocks; the numbers of a step do not depend on the block size nor
on how the run is split into calls.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..._compile import compiling
from ..._progress import Phase
from ...errors import ParameterError
from . import _kernels as kn

log = logging.getLogger(__name__)

__all__ = ["SamplerConfig", "SamplerState", "run_chains", "SAMPLERS", "EVALUATIONS"]

#: MCMC algorithms by name: Metropolis-Hastings, delayed rejection, adaptive Metropolis and
#: both (DRAM, the default), as Dakota's ``mcmc_type``.
SAMPLERS = ("mh", "dr", "am", "dram")
EVALUATIONS = ("speculative", "minimal")


@dataclass(frozen=True)
class SamplerConfig:
    """An MCMC sampler and its tuning (``calibrate_bayes(chains=ChainOptions(sampler=...))``).

    Defaults are Dakota's DRAM.

    Parameters
    ----------
    sampler : str, optional
        ``"mh"``, ``"dr"``, ``"am"`` or ``"dram"`` (default).
    dr_scale : float, optional
        Divisor of the stage-2 proposal's scale (default 5).
    adapt_start, adapt_interval : int, optional
        Adaptive Metropolis: adapt from this step on, every so many steps (default 100 and
        100).
    scale : float, optional
        Proposal scale (default ``2.38**2 / d``).
    eps : float, optional
        Regularization of the adapted covariance (default 1e-8).
    pooled : bool, optional
        Adapt the covariance from the pooled history of all chains (inter-chain adaptation,
        default) instead of each chain's own.
    evaluations : str, optional
        ``"speculative"`` (default) or ``"minimal"``: which points go into one model call
        (module doc).
    max_lookahead : int, optional
        The most steps evaluated ahead in one call (speculative, one chain; default 8).
    """

    sampler: str = "dram"
    dr_scale: float = 5.0
    adapt_start: int = 100
    adapt_interval: int = 100
    scale: float | None = None
    eps: float = 1e-8
    pooled: bool = True
    evaluations: str = "speculative"
    max_lookahead: int = 8

    def __post_init__(self):
        if self.sampler not in SAMPLERS:
            raise ParameterError(f"unknown MCMC sampler {self.sampler!r}; valid: {SAMPLERS}")
        if self.dr_scale <= 0 or self.adapt_interval < 1 or self.adapt_start < 0:
            raise ParameterError("dr_scale must be > 0, adapt_interval >= 1, adapt_start >= 0")
        if self.evaluations not in EVALUATIONS:
            raise ParameterError(f"unknown evaluations schedule {self.evaluations!r}; valid: "
                                 f"{EVALUATIONS}")
        if int(self.max_lookahead) < 1:
            raise ParameterError(f"max_lookahead must be >= 1, got {self.max_lookahead}")

    @property
    def delayed_rejection(self) -> bool:
        """Whether a rejected proposal gets a second, smaller one (``"dr"``, ``"dram"``)."""
        return self.sampler in ("dr", "dram")

    @property
    def adaptive(self) -> bool:
        """Whether the proposal covariance adapts to the history (``"am"``, ``"dram"``)."""
        return self.sampler in ("am", "dram")


_COUNTS = ("prop1", "acc1", "prop2", "acc2")


@dataclass
class SamplerState:
    """Everything needed to continue chains exactly where they stopped (scaled coordinates).

    Parameters
    ----------
    x : ndarray of shape (c, d)
        The c chains' current points.
    lp : ndarray of shape (c,)
        Their log posterior.
    chol : ndarray of shape (c, d, d)
        Cholesky factors of the stage-1 proposal covariance.
    rng : Generator
        Seeds the four random streams of the chains.
    mean, m2 : ndarray of shape (c, d) and (c, d, d), optional
        Running mean and sum of squared deviations of each chain's history (for AM);
        default zero.
    streams : list of Generator, optional
        The four random streams (stage-1 and stage-2 normals and uniforms); default drawn
        from ``rng``.
    st : ndarray of shape (7,), optional
        The kernels' counters: steps, steps of this run, kept steps, stage-1 and stage-2
        proposals and acceptances.
    """

    x: np.ndarray
    lp: np.ndarray
    chol: np.ndarray
    rng: np.random.Generator
    mean: np.ndarray = None  # type: ignore[assignment]
    m2: np.ndarray = None  # type: ignore[assignment]
    streams: list = None  # type: ignore[assignment]
    st: np.ndarray = field(default_factory=lambda: np.zeros(7, np.int64))

    def __post_init__(self):
        self.x = np.array(self.x, dtype=float, order="C")
        self.lp = np.array(self.lp, dtype=float)
        self.chol = np.array(self.chol, dtype=float, order="C")
        c, d = self.x.shape
        if self.lp.shape != (c,) or self.chol.shape != (c, d, d):
            raise ParameterError(f"state of {c} chains in {d}-D needs lp ({c},) and chol "
                                 f"({c}, {d}, {d}); got {self.lp.shape} and {self.chol.shape}")
        if self.mean is None:
            self.mean = np.zeros((c, d))
            self.m2 = np.zeros((c, d, d))
        if self.streams is None:
            self.reseed(self.rng)

    def reseed(self, rng: np.random.Generator) -> None:
        """Draw the four random streams of the following steps from ``rng``.

        Parameters
        ----------
        rng : Generator
            The new seed source; it is kept as :attr:`rng`.
        """
        self.rng = rng
        self.streams = [np.random.default_rng(int(s)) for s in rng.integers(2**63, size=4)]

    @property
    def steps(self) -> int:
        """Steps taken so far."""
        return int(self.st[kn.STEPS])

    @property
    def counts(self) -> dict:
        """Stage-1 and stage-2 proposals and acceptances summed over chains."""
        return {k: int(self.st[kn.PROP1 + i]) for i, k in enumerate(_COUNTS)}

    def copy(self) -> SamplerState:
        """An independent copy (arrays and generators cloned: the copy continues the chains
        exactly as the original would)."""

        def clone(g):
            new = np.random.Generator(type(g.bit_generator)())
            new.bit_generator.state = g.bit_generator.state
            return new

        return SamplerState(self.x.copy(), self.lp.copy(), self.chol.copy(), clone(self.rng),
                            self.mean.copy(), self.m2.copy(), [clone(g) for g in self.streams],
                            self.st.copy())


def run_chains(logpost: Callable[[np.ndarray], np.ndarray], state: SamplerState,
               cfg: SamplerConfig, n_samples: int, burn_in: int = 0, thin: int = 1,
               block: int = 4096, progress: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Advance all chains in place until each has ``n_samples`` kept steps.

    Takes ``burn_in + (n_samples - 1) * thin + 1`` steps (none for ``n_samples = 0``) and
    returns the kept samples (n_samples, c, d) and their log posterior (n_samples, c): steps
    ``burn_in, burn_in + thin, ...`` counted from the start of this call.

    Parameters
    ----------
    logpost : callable
        Batched log posterior, (k, d) -> (k,), -inf (never NaN) where impossible; its value
        at a point must not depend on the other points of the batch.
    state : SamplerState
        The c chains' state (points, log posteriors, adaptation, random streams), advanced
        in place.
    cfg : SamplerConfig
        The sampler and its tuning.
    n_samples : int
        Kept steps per chain.
    burn_in : int, optional
        Steps dropped first (default 0).
    thin : int, optional
        Keep every ``thin``-th step after the burn-in (default 1).
    block : int, optional
        Steps per compiled block between returns to Python (default 4096); the chains do
        not depend on it.
    progress : bool, optional
        Report the steps done as the ``"chains"`` phase (:mod:`rotoruq._progress`) after
        each block (default True; False for chains inside another reported phase).

    Returns
    -------
    tuple of ndarray
        The kept samples (n_samples, c, d) and their log posterior (n_samples, c).
    """
    c, d = state.x.shape
    thin = max(int(thin), 1)
    n_keep = max(int(n_samples), 0)
    n_steps = burn_in + (n_keep - 1) * thin + 1 if n_keep else 0
    out = np.empty((n_keep, c, d))
    out_lp = np.empty((n_keep, c))
    dr = cfg.delayed_rejection
    sd = cfg.scale if cfg.scale is not None else 2.38**2 / d
    fpar = np.array([1.0 / cfg.dr_scale, sd, cfg.eps])
    ipar = np.array([dr, cfg.adaptive, cfg.adapt_start, cfg.adapt_interval, cfg.pooled,
                     burn_in, thin], dtype=np.int64)
    state.st[kn.RUN_STEP] = 0
    state.st[kn.KEPT] = 0
    compiled = getattr(logpost, "compiled", None)
    # open until the first block is done: the kernels compile in its call
    compile_phase = contextlib.ExitStack()
    compile_phase.enter_context(compiling("chain kernels", [kn.advance], log))
    speculative = cfg.evaluations == "speculative" and compiled is None
    if compiled is None and progress:
        # a step of a Python model costs a model call: blocks small enough for the progress
        # to move (the chains do not depend on the block size)
        block = min(block, 128)
    k_max = int(cfg.max_lookahead) if speculative and c == 1 else 1
    Y = np.empty((max(k_max, 4 if k_max > 1 else 1), 2 if dr else 1, c, d))
    LPY = np.full(Y.shape[:3], -np.inf)
    g1, u1, g2, u2 = state.streams
    no_z2 = np.zeros((1, 1, 1))
    no_u2 = np.zeros((1, 1))
    done = 0
    phase = Phase(f"{c} chain{'s' if c > 1 else ''}", n_steps) if progress else None
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"), \
            phase or contextlib.nullcontext(), compile_phase:
        while done < n_steps:
            nb = min(block, n_steps - done)
            Z1 = g1.standard_normal((nb, c, d))
            LU1 = np.log(u1.random((nb, c)))
            Z2 = g2.standard_normal((nb, c, d)) if dr else no_z2
            LU2 = np.log(u2.random((nb, c))) if dr else no_u2
            args = (Z1, Z2, LU1, LU2)
            if compiled is not None:
                post, cnt = compiled
                kn.run_block_emulator(state.x, state.lp, state.chol, *args, nb, Y, LPY,
                                      state.mean, state.m2, state.st, fpar, ipar, out, out_lp,
                                      post, cnt)
            elif speculative:
                _block_speculative(logpost, state, cfg, args, nb, k_max, Y, LPY, fpar, ipar,
                                   out, out_lp)
            else:
                _block_minimal(logpost, state, args, nb, Y, LPY, fpar, ipar, out, out_lp)
            done += nb
            compile_phase.close()
            if phase is not None:
                phase.advance(nb)
    kept = int(state.st[kn.KEPT])
    return out[:kept], out_lp[:kept]


def _plan(state: SamplerState, k_max: int) -> tuple[bool, int]:
    """Speculative schedule of one chain from its move rate p: the two-step tree (every
    outcome of the next step, 2 steps per call) when p >= 0.4, else the next K steps from the
    current point with K about 1/p, the expected number of steps to the next move."""
    prop = state.st[kn.PROP1]
    rate = (state.st[kn.ACC1] + state.st[kn.ACC2]) / prop if prop >= 50 else 0.5
    if k_max >= 2 and rate >= 0.4:
        return True, 2
    return False, int(min(k_max, max(1.0, np.ceil(1.0 / max(rate, 1e-3)))))


def _block_speculative(logpost, state, cfg, args, nb, k_max, Y, LPY, fpar, ipar, out, out_lp):
    x, lp, L, st = state.x, state.lp, state.chol, state.st
    d = x.shape[1]
    n_nodes = 4 if Y.shape[1] == 2 else 3
    interval = cfg.adapt_interval if cfg.adaptive else nb
    Z1, Z2 = args[0], args[1]
    t = 0
    tree, K = _plan(state, k_max) if x.shape[0] == 1 else (False, 1)
    while t < nb:
        # proposals after an adaptation would use the new covariance: stop at the boundary
        k = min(K, nb - t, interval - int(st[kn.STEPS]) % interval)
        if tree and k == 2:
            kn.propose_tree(x, L, Z1, Z2, t, fpar[0], Y)
            rows = n_nodes
        else:
            kn.propose(x, L, Z1, Z2, t, k, fpar[0], Y)
            rows = k
        LPY[:rows] = logpost(Y[:rows].reshape(-1, d)).reshape(LPY[:rows].shape)
        t += kn.advance(x, lp, L, Y, LPY, *args, t, k, tree and k == 2, state.mean, state.m2,
                        st, fpar, ipar, out, out_lp)
        if k_max > 1 and st[kn.PROP1] % 64 < k:
            tree, K = _plan(state, k_max)


def _block_minimal(logpost, state, args, nb, Y, LPY, fpar, ipar, out, out_lp):
    x, lp, L, st = state.x, state.lp, state.chol, state.st
    Z1, Z2, LU1 = args[0], args[1], args[2]
    two = Y.shape[1] == 2
    for t in range(nb):
        kn.propose(x, L, Z1, Z2, t, 1, fpar[0], Y)
        LPY[0, 0] = logpost(Y[0, 0])
        if two:
            rej = ~(LU1[t] < LPY[0, 0] - lp)
            LPY[0, 1] = -np.inf
            if rej.any():
                LPY[0, 1, rej] = logpost(Y[0, 1, rej])
        kn.advance(x, lp, L, Y, LPY, *args, t, 1, False, state.mean, state.m2, st, fpar, ipar,
                   out, out_lp)
