"""Random-walk Metropolis samplers: MH, delayed rejection (DR), adaptive Metropolis (AM), DRAM.

Appendix eqs. A.9-A.11 of the reference study, after Haario, Laine, Mira and Saksman (2006).
Several chains advance together: each step proposes one point per chain and evaluates the log
posterior of all of them in ONE batched call; the delayed-rejection stage does the same for the
chains whose first proposal was rejected.

Defaults follow Dakota's DRAM: one DR stage whose proposal covariance is the first stage's
divided by ``dr_scale**2 = 25``, adaptation from sample 100 and every 100 samples, scale
``2.38**2 / d`` and ``eps = 1e-8`` (eq. A.10). The second stage is centred on the current point,
so its own density cancels in the acceptance ratio and only the first stage's density appears.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ...errors import ParameterError

__all__ = ["SamplerConfig", "SamplerState", "run_chains", "METHODS"]

METHODS = ("mh", "dr", "am", "dram")


@dataclass(frozen=True)
class SamplerConfig:
    """method : "mh", "dr", "am" or "dram". Other fields as in Dakota (see module doc)."""

    method: str = "dram"
    dr_scale: float = 5.0
    adapt_start: int = 100
    adapt_interval: int = 100
    scale: float | None = None
    eps: float = 1e-8
    pooled: bool = True

    def __post_init__(self):
        if self.method not in METHODS:
            raise ParameterError(f"unknown MCMC method {self.method!r}; valid: {METHODS}")
        if self.dr_scale <= 0 or self.adapt_interval < 1 or self.adapt_start < 0:
            raise ParameterError("dr_scale must be > 0, adapt_interval >= 1, adapt_start >= 0")

    @property
    def delayed_rejection(self) -> bool:
        return self.method in ("dr", "dram")

    @property
    def adaptive(self) -> bool:
        return self.method in ("am", "dram")


@dataclass
class SamplerState:
    """Everything needed to continue chains exactly where they stopped (scaled coordinates).

    x : (c, d) current points; lp : (c,) their log posterior; chol : (c, d, d) Cholesky factors
    of the stage-1 proposal covariance; s1, s2, n_seen : running sums of the history for AM.
    """

    x: np.ndarray
    lp: np.ndarray
    chol: np.ndarray
    rng: np.random.Generator
    s1: np.ndarray = None  # type: ignore[assignment]
    s2: np.ndarray = None  # type: ignore[assignment]
    n_seen: int = 0
    steps: int = 0
    buf: np.ndarray = None  # type: ignore[assignment]
    counts: dict = field(default_factory=lambda: {"prop1": 0, "acc1": 0, "prop2": 0, "acc2": 0})

    def __post_init__(self):
        c, d = self.x.shape
        if self.s1 is None:
            self.s1 = np.zeros((c, d))
            self.s2 = np.zeros((c, d, d))

    def copy(self) -> SamplerState:
        new = SamplerState(self.x.copy(), self.lp.copy(), self.chol.copy(),
                           np.random.Generator(type(self.rng.bit_generator)()), self.s1.copy(),
                           self.s2.copy(), self.n_seen, self.steps,
                           None if self.buf is None else self.buf.copy(), dict(self.counts))
        new.rng.bit_generator.state = self.rng.bit_generator.state
        return new


def _log1mexp(a: np.ndarray) -> np.ndarray:
    """log(1 - exp(a)) for a <= 0 (-inf at a = 0, 0 at a = -inf)."""
    return np.log(-np.expm1(a))


def _adapt(state: SamplerState, cfg: SamplerConfig, d: int) -> None:
    sd = cfg.scale if cfg.scale is not None else 2.38**2 / d
    if cfg.pooled:
        n = state.n_seen * state.x.shape[0]
        mu = state.s1.sum(0) / n
        cov = (state.s2.sum(0) - n * np.outer(mu, mu)) / (n - 1.0)
        covs = cov[None]
    else:
        n = state.n_seen
        mu = state.s1 / n
        covs = (state.s2 - n * np.einsum("ci,cj->cij", mu, mu)) / (n - 1.0)
    for k, cov in enumerate(covs):
        try:
            L = np.linalg.cholesky(sd * (cov + cfg.eps * np.eye(d)))
        except np.linalg.LinAlgError:
            continue
        if cfg.pooled:
            state.chol[:] = L
        else:
            state.chol[k] = L


def run_chains(logpost: Callable[[np.ndarray], np.ndarray], state: SamplerState,
               cfg: SamplerConfig, n_steps: int, burn_in: int = 0, thin: int = 1,
               block: int = 512) -> tuple[np.ndarray, np.ndarray]:
    """Advance all chains ``n_steps`` steps in place.

    logpost : batched log posterior, (k, d) -> (k,), -inf (never NaN) where impossible.
    Returns the kept samples (n_kept, c, d) and their log posterior (n_kept, c): steps
    ``burn_in, burn_in + thin, ...`` counted from the start of this call.
    """
    c, d = state.x.shape
    thin = max(int(thin), 1)
    n_keep = max(0, (n_steps - burn_in + thin - 1) // thin) if n_steps > burn_in else 0
    out = np.empty((n_keep, c, d))
    out_lp = np.empty((n_keep, c))
    if state.buf is None or state.buf.shape[0] != cfg.adapt_interval:
        state.buf = np.empty((cfg.adapt_interval, c, d))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _loop(logpost, state, cfg, n_steps, burn_in, thin, block, out, out_lp)


def _loop(logpost, state, cfg, n_steps, burn_in, thin, block, out, out_lp):
    c, d = state.x.shape
    dr, am = cfg.delayed_rejection, cfg.adaptive
    inv_s = 1.0 / cfg.dr_scale
    interval = cfg.adapt_interval
    rng, counts = state.rng, state.counts
    x, lp, L = state.x, state.lp, state.chol
    kept = 0
    for t0 in range(0, n_steps, block):
        nb = min(block, n_steps - t0)
        Z1 = rng.standard_normal((nb, c, d))
        LU1 = np.log(rng.random((nb, c)))
        if dr:
            Z2 = rng.standard_normal((nb, c, d))
            LU2 = np.log(rng.random((nb, c)))
        for i in range(nb):
            z1 = Z1[i]
            y1 = x + np.einsum("cij,cj->ci", L, z1)
            lp1 = logpost(y1)
            acc = LU1[i] < lp1 - lp
            counts["prop1"] += c
            na = int(acc.sum())
            counts["acc1"] += na
            if na:
                x[acc] = y1[acc]
                lp[acc] = lp1[acc]
            if dr and na < c:
                r = np.flatnonzero(~acc)
                z2 = Z2[i, r]
                y2 = x[r] + np.einsum("cij,cj->ci", L[r], z2) * inv_s
                lp2 = logpost(y2)
                lpy1, lpx = lp1[r], lp[r]
                dz = z1[r] - z2 * inv_s
                num = lp2 - 0.5 * (dz * dz).sum(1) + _log1mexp(np.minimum(lpy1 - lp2, 0.0))
                den = lpx - 0.5 * (z1[r] ** 2).sum(1) + _log1mexp(np.minimum(lpy1 - lpx, 0.0))
                acc2 = (LU2[i, r] < num - den) & (lp2 > -np.inf)
                counts["prop2"] += r.size
                if acc2.any():
                    rr = r[acc2]
                    x[rr] = y2[acc2]
                    lp[rr] = lp2[acc2]
                    counts["acc2"] += int(acc2.sum())
            t = t0 + i
            state.buf[state.steps % interval] = x
            state.steps += 1
            if state.steps % interval == 0:
                state.s1 += state.buf.sum(0)
                state.s2 += np.einsum("tci,tcj->cij", state.buf, state.buf)
                state.n_seen += interval
                if am and state.n_seen >= max(cfg.adapt_start, 2):
                    _adapt(state, cfg, d)
            if t >= burn_in and (t - burn_in) % thin == 0:
                out[kept] = x
                out_lp[kept] = lp
                kept += 1
    return out[:kept], out_lp[:kept]
