"""Compiled (numba) pieces of the Markov chains: the DRAM step, the box/normal log prior, the
Gaussian misfit and, for an emulator, the whole log posterior.

The step is split so that one implementation serves two drivers:

* :func:`propose` writes the proposals of ``K`` future steps, all centred on the current
  points (stage 1 ``x + L z1`` and, with delayed rejection, stage 2 ``x + L z2 / dr_scale``);
* the caller evaluates the log posterior of those points (a Python model in one batched
  call, or :func:`run_block_emulator` in compiled code);
* :func:`advance` applies the acceptance rules step by step, records the kept samples, updates
  the adaptive-Metropolis history and covariance, and stops after the first step that moves a
  chain (the later proposals were centred on a point the chain has left).

State arrays (``c`` chains, ``d`` parameters): ``x`` (c, d), ``lp`` (c,), ``L`` (c, d, d)
lower Cholesky factors of the stage-1 proposal covariance, ``mean`` (c, d) and ``m2``
(c, d, d) running mean and sum of squared deviations of each chain's history (Welford),
``st`` int64 counters ``[steps, run_step, kept, prop1, acc1, prop2, acc2]``.

One compiled version per kernel: a compiled caller passes a constant argument typed
(``np.int64(1)``, ``np.bool_(False)``), as a Python caller's ints and bools arrive, so numba does
not compile a second version specialised on the literal (a cold start compiled
:func:`advance` twice, once for each driver).
Settings: ``fpar = [1/dr_scale, AM scale, AM eps]``,
``ipar = [delayed_rejection, adaptive, adapt_start, adapt_interval, pooled, burn_in, thin]``.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ... import _numba_cache  # noqa: F401  (the cache keyed by what the kernels compile in)
from .._gp_mean import gp_mean_into, gp_mean_var_into

_jit = nb.njit(cache=True, nogil=True)
# called only from compiled code: no CPython wrapper, which each compiled function's library
# would optimise and compile to machine code on its own (issue 34: 29.6 -> 24.6 CPU-s of a
# cold compile of the chain kernels, with _gp_mean's). Such a function cannot be called from
# Python (its entry point is null).
_inner = nb.njit(cache=True, nogil=True, no_cpython_wrapper=True)
NEG_INF = -np.inf

# st / ipar / counter indices
STEPS, RUN_STEP, KEPT, PROP1, ACC1, PROP2, ACC2 = range(7)
DR, ADAPTIVE, ADAPT_START, INTERVAL, POOLED, BURN_IN, THIN = range(7)
N_EVALS, N_OUTSIDE, N_NAN, N_EXTRAP, MAX_EXTRAP = range(5)


@_inner
def cholesky_into(a, out) -> bool:
    """Lower Cholesky factor of the symmetric matrix a (d, d) into out; False (out partly
    written) when a is not positive definite."""
    d = a.shape[0]
    for j in range(d):
        s = a[j, j]
        for k in range(j):
            s -= out[j, k] * out[j, k]
        if not s > 0.0:
            return False
        ljj = math.sqrt(s)
        out[j, j] = ljj
        for i in range(j):
            out[i, j] = 0.0
        for i in range(j + 1, d):
            s = a[i, j]
            for k in range(j):
                s -= out[i, k] * out[j, k]
            out[i, j] = s / ljj
    return True


@_inner
def _log1mexp(a: float) -> float:
    """log(1 - exp(a)) for a <= 0 (-inf at a = 0)."""
    if a >= 0.0:
        return NEG_INF
    return math.log(-math.expm1(a))


@_inner
def _propose_node(centre, L, Z1, Z2, tt, inv_s, Y, node, k) -> None:
    """Y[node, 0, k] = centre + L[k] Z1[tt, k]; Y[node, 1, k] = centre + L[k] Z2[tt, k] / s."""
    d = centre.shape[0]
    two = Y.shape[1] == 2
    for a in range(d):
        s1 = 0.0
        s2 = 0.0
        for b in range(a + 1):
            s1 += L[k, a, b] * Z1[tt, k, b]
            if two:
                s2 += L[k, a, b] * Z2[tt, k, b]
        Y[node, 0, k, a] = centre[a] + s1
        if two:
            Y[node, 1, k, a] = centre[a] + s2 * inv_s


@_jit
def propose(x, L, Z1, Z2, t, K, inv_s, Y) -> None:
    """Proposals of steps t .. t+K-1 all centred on the current points: Y[j, 0, k] =
    x[k] + L[k] Z1[t + j, k] and (two stages) Y[j, 1, k] = x[k] + L[k] Z2[t + j, k] / dr_scale.
    Y : (K_max, S, c, d)."""
    for j in range(K):
        for k in range(x.shape[0]):
            _propose_node(x[k], L, Z1, Z2, t + j, inv_s, Y, j, k)


@_jit
def propose_tree(x, L, Z1, Z2, t, inv_s, Y) -> None:
    """Proposals of steps t and t+1 for every outcome of step t (one chain): node 0 from x at
    step t, then step t+1 from x (node 1), from the stage-1 point (node 2) and from the
    stage-2 point (node 3, with delayed rejection)."""
    _propose_node(x[0], L, Z1, Z2, t, inv_s, Y, 0, 0)
    _propose_node(x[0], L, Z1, Z2, t + 1, inv_s, Y, 1, 0)
    for stage in range(Y.shape[1]):
        _propose_node(Y[0, stage, 0], L, Z1, Z2, t + 1, inv_s, Y, 2 + stage, 0)


# Element loops, not ``dst[k] = src``: an array assigned to a slice compiles numba's
# shape-mismatch error message (string formatting), a few CPU-seconds of every cold compile.
@_inner
def _copy1(src, dst) -> None:
    for a in range(src.shape[0]):
        dst[a] = src[a]


@_inner
def _copy2(src, dst) -> None:
    for a in range(src.shape[0]):
        for b in range(src.shape[1]):
            dst[a, b] = src[a, b]


@_inner
def _adapt(L, mean, m2, n, fpar, pooled) -> None:
    """Adaptive Metropolis (eq. A.10): L <- chol(sd (cov + eps I)) of the history covariance,
    pooled over the chains or per chain; a factor that fails keeps the previous one."""
    c, d = mean.shape
    sd, eps = fpar[1], fpar[2]
    cov = np.empty((d, d))
    Lnew = np.empty((d, d))
    if pooled:
        mu = np.zeros(d)
        for k in range(c):
            for a in range(d):
                mu[a] += mean[k, a] / c
        for a in range(d):
            for b in range(d):
                s = 0.0
                for k in range(c):
                    s += m2[k, a, b] + n * (mean[k, a] - mu[a]) * (mean[k, b] - mu[b])
                cov[a, b] = sd * (s / (c * n - 1.0) + (eps if a == b else 0.0))
        if cholesky_into(cov, Lnew):
            for k in range(c):
                _copy2(Lnew, L[k])
        return
    for k in range(c):
        for a in range(d):
            for b in range(d):
                cov[a, b] = sd * (m2[k, a, b] / (n - 1.0) + (eps if a == b else 0.0))
        if cholesky_into(cov, Lnew):
            _copy2(Lnew, L[k])


@_inner
def _after_step(x, lp, L, mean, m2, st, fpar, ipar, out, out_lp, delta) -> None:
    c, d = x.shape
    st[STEPS] += 1
    n = st[STEPS]
    f = (n - 1.0) / n
    for k in range(c):
        for a in range(d):
            delta[a] = x[k, a] - mean[k, a]
            mean[k, a] += delta[a] / n
        for a in range(d):
            for b in range(a + 1):
                m2[k, a, b] += f * delta[a] * delta[b]
                m2[k, b, a] = m2[k, a, b]
    r = st[RUN_STEP]
    st[RUN_STEP] += 1
    if r >= ipar[BURN_IN] and (r - ipar[BURN_IN]) % ipar[THIN] == 0:
        _copy2(x, out[st[KEPT]])
        _copy1(lp, out_lp[st[KEPT]])
        st[KEPT] += 1
    if ipar[ADAPTIVE] and n % ipar[INTERVAL] == 0 and n >= max(ipar[ADAPT_START], 2):
        _adapt(L, mean, m2, n, fpar, ipar[POOLED])


@_inner
def _step(x, lp, Y, LPY, node, Z1, Z2, LU1, LU2, tt, st, inv_s) -> int:
    """One step of every chain from the evaluated proposals Y[node] (S, c, d) with log
    posteriors LPY[node] (S, c). Stage-2 entries are read only for chains whose stage 1 was
    rejected; -inf there rejects. Returns the outcome of the last chain: 0 stayed, 1 moved to
    the stage-1 point, 2 to the stage-2 point."""
    c, d = x.shape
    two = Y.shape[1] == 2
    outcome = 0
    for k in range(c):
        outcome = 0
        st[PROP1] += 1
        lp1 = LPY[node, 0, k]
        if LU1[tt, k] < lp1 - lp[k]:
            _copy1(Y[node, 0, k], x[k])
            lp[k] = lp1
            st[ACC1] += 1
            outcome = 1
            continue
        if not two:
            continue
        st[PROP2] += 1
        lp2 = LPY[node, 1, k]
        if not lp2 > NEG_INF:
            continue
        dz2 = 0.0
        z12 = 0.0
        for a in range(d):
            z1 = Z1[tt, k, a]
            dz = z1 - Z2[tt, k, a] * inv_s
            dz2 += dz * dz
            z12 += z1 * z1
        num = lp2 - 0.5 * dz2 + _log1mexp(min(lp1 - lp2, 0.0))
        den = lp[k] - 0.5 * z12 + _log1mexp(min(lp1 - lp[k], 0.0))
        if LU2[tt, k] < num - den:
            _copy1(Y[node, 1, k], x[k])
            lp[k] = lp2
            st[ACC2] += 1
            outcome = 2
    return outcome


@_jit
def advance(x, lp, L, Y, LPY, Z1, Z2, LU1, LU2, t, K, tree, mean, m2, st, fpar, ipar, out,
            out_lp) -> int:
    """Take up to K steps from the proposals of :func:`propose` (stopping after the first
    step that moves a chain: the later proposals were centred on the point it left) or, with
    ``tree``, K (1 or 2) steps from those of :func:`propose_tree`. Returns the steps taken."""
    delta = np.empty(x.shape[1])
    inv_s = fpar[0]
    if tree:
        o = _step(x, lp, Y, LPY, np.int64(0), Z1, Z2, LU1, LU2, t, st, inv_s)
        _after_step(x, lp, L, mean, m2, st, fpar, ipar, out, out_lp, delta)
        if K == 1:
            return 1
        _step(x, lp, Y, LPY, 1 + o, Z1, Z2, LU1, LU2, t + 1, st, inv_s)
        _after_step(x, lp, L, mean, m2, st, fpar, ipar, out, out_lp, delta)
        return 2
    for j in range(K):
        moved = _step(x, lp, Y, LPY, j, Z1, Z2, LU1, LU2, t + j, st, inv_s)
        _after_step(x, lp, L, mean, m2, st, fpar, ipar, out, out_lp, delta)
        if moved:
            return j + 1
    return K


# --- log prior and likelihood ------------------------------------------------------------------

@_inner
def _piece_index(edges, e0, n, x) -> int:
    """Bin k in 0..n-1 of x among the n + 1 sorted edges ``edges[e0:e0 + n + 1]``: the last
    edge <= x (numpy's ``searchsorted(side="right") - 1``), clipped to the bins."""
    a = 0
    b = n + 1
    while a < b:
        h = (a + b) // 2
        if edges[e0 + h] <= x:
            a = h + 1
        else:
            b = h
    return min(max(a - 1, 0), n - 1)


@_inner
def logprior_point(theta, prior) -> float:
    """Log density of independent uniform / normal / piecewise-constant marginals at theta
    (d,); -inf outside the support [lo, hi] or where it is NaN. prior = (lo, hi, const,
    normal index, mu, sigma, piecewise index (r,), edge offsets (r + 1,), edges, log
    densities): piece q's edges are ``edges[off[q]:off[q + 1]]`` and its bins' log densities
    ``logd[off[q] - q:off[q + 1] - q - 1]`` (:class:`.proposals.LogPrior`). The piecewise
    terms are added after the normal ones, in parameter order."""
    lo, hi, const, idx, mu, sig, pidx, poff, pedges, plogd = prior
    for a in range(theta.shape[0]):
        if not (theta[a] >= lo[a] and theta[a] <= hi[a]):
            return NEG_INF
    out = const
    for q in range(idx.shape[0]):
        u = (theta[idx[q]] - mu[q]) / sig[q]
        out -= 0.5 * u * u
    for q in range(pidx.shape[0]):
        e0 = poff[q]
        out += plogd[e0 - q + _piece_index(pedges, e0, poff[q + 1] - e0 - 1, theta[pidx[q]])]
    return out


@_jit
def logprior_rows(theta, prior, out) -> None:
    for k in range(theta.shape[0]):
        out[k] = logprior_point(theta[k], prior)


@_inner
def misfit_point(q, lik) -> float:
    """``1/2 (q^T P q - 2 q^T b + c0)`` for responses q (m,); lik = (P, b, c0, const, diag,
    P^-1, P^-1 b, c0 - b^T P^-1 b, log det P) (:class:`.likelihood.GaussianLikelihood`)."""
    P, b, c0 = lik[0], lik[1], lik[2]
    diag = lik[4]
    m = q.shape[0]
    quad = 0.0
    lin = 0.0
    for i in range(m):
        lin += q[i] * b[i]
        if diag:
            quad += P[i, i] * q[i] * q[i]
        else:
            s = 0.0
            for j in range(m):
                s += P[i, j] * q[j]
            quad += q[i] * s
    return 0.5 * (quad - 2.0 * lin + c0)


@_inner
def loglik_var_point(q, v, lik) -> float:
    """Log-likelihood of responses q (m,) whose emulator error has variance v (m,), shared by
    every experiment and integrated out (:meth:`.likelihood.GaussianLikelihood.__call__`)."""
    P, const, diag, Pinv, dbar, resid, logdet_p = lik[0], lik[3], lik[4], lik[5], lik[6], \
        lik[7], lik[8]
    m = q.shape[0]
    acc = resid
    if diag:
        for j in range(m):
            a = 1.0 + P[j, j] * v[j]
            r = dbar[j] - q[j]
            acc += math.log(a) + P[j, j] * r * r / a
        return const - 0.5 * acc
    A = Pinv.copy()
    for j in range(m):
        A[j, j] += v[j]
    L = np.empty((m, m))
    if not cholesky_into(A, L):
        return math.nan
    acc += logdet_p
    for j in range(m):  # forward solve L w = r, accumulating |w|^2 and log det A
        t = dbar[j] - q[j]
        for k in range(j):
            t -= L[j, k] * A[k, k]
        w = t / L[j, j]
        A[j, j] = w  # A's diagonal is free now: keep w there
        acc += 2.0 * math.log(L[j, j]) + w * w
    return const - 0.5 * acc


@_jit
def loglik_var_rows(Q, V, lik, out) -> None:
    for k in range(Q.shape[0]):
        out[k] = loglik_var_point(Q[k], V[k], lik)


@_jit
def misfit_rows(Q, lik, out) -> None:
    for k in range(Q.shape[0]):
        out[k] = misfit_point(Q[k], lik)


@_inner
def _with_loglik(lpr, q, lik, cnt) -> float:
    """Log prior lpr plus the log-likelihood of responses q (m,); -inf (counted) when the
    likelihood is not finite."""
    cnt[N_EVALS] += 1.0
    ll = lik[3] - misfit_point(q, lik)
    if not math.isfinite(ll):
        cnt[N_NAN] += 1.0
        return NEG_INF
    return lpr + ll


@_jit
def scaled_logprior_rows(Z, center, scale, prior, theta, lp) -> None:
    """theta = center + scale Z (k, d) and its compiled log prior lp (k,)."""
    for k in range(Z.shape[0]):
        for a in range(Z.shape[1]):
            theta[k, a] = center[a] + scale[a] * Z[k, a]
        lp[k] = logprior_point(theta[k], prior)


@_jit
def add_loglik_rows(Q, lik, lp, cnt) -> None:
    """lp[k] += log-likelihood of the next row of Q for every k with lp[k] > -inf (Q holds the
    responses of those rows, in order); counts the rows outside the support and the
    non-finite likelihoods."""
    r = 0
    for k in range(lp.shape[0]):
        if lp[k] == NEG_INF:
            cnt[N_OUTSIDE] += 1.0
            continue
        lp[k] = _with_loglik(lp[k], Q[r], lik, cnt)
        r += 1


# --- the log posterior on an emulator, and a chain block that never leaves compiled code -----

@_inner
def _emulator_work(Z, post):
    """Scratch for :func:`emulator_logpost`: rows theta, xs, q, variance (d or m wide),
    correlations or squared distances r (n), trend basis g and its residual u (p); row 2
    unused."""
    Xe = post[3][2]  # (m, d, n)
    w = max(Z.shape[1], Xe.shape[0], Xe.shape[2], post[3][6].shape[0], 1)
    return np.empty((8, w))


@_inner
def emulator_logpost(z, post, work, cnt) -> float:
    """Log posterior at scaled point z (d,): theta = center + scale z, uniform / normal prior,
    GP mean (and, with ``use_var``, the GP's Kriging variance added to the noise, shared by
    the experiments), Gaussian likelihood. post = (center, scale, prior, gp mean pack, lik,
    gp variance pack, use_var); work : :func:`_emulator_work`; cnt : float counters
    (evaluations, outside the support, non-finite likelihoods, extrapolations beyond 0.1
    box-widths, largest extrapolation)."""
    center, scale, prior, gp, lik, gpv, use_var = post
    d = z.shape[0]
    m, n = gp[2].shape[0], gp[2].shape[2]
    p = gp[6].shape[0]
    theta = work[0, :d]
    for a in range(d):
        theta[a] = center[a] + scale[a] * z[a]
    lpr = logprior_point(theta, prior)
    if lpr == NEG_INF:
        cnt[N_OUTSIDE] += 1.0
        return NEG_INF
    xs = work[1, :d]
    q = work[3, :m]
    if use_var:
        v = work[4, :m]
        gp_mean_var_into(theta, gp, gpv, xs, work[5, :n], work[6, :p], work[7, :p], q, v)
    else:
        gp_mean_into(theta, gp, xs, work[5, :n], q)
    e2 = 0.0
    for a in range(d):
        e = max(0.0, -xs[a]) + max(0.0, xs[a] - 1.0)
        e2 += e * e
    if e2 > 0.01:
        cnt[N_EXTRAP] += 1.0
        cnt[MAX_EXTRAP] = max(cnt[MAX_EXTRAP], math.sqrt(e2))
    if not use_var:
        return _with_loglik(lpr, q, lik, cnt)
    cnt[N_EVALS] += 1.0
    ll = loglik_var_point(q, work[4, :m], lik)
    if not math.isfinite(ll):
        cnt[N_NAN] += 1.0
        return NEG_INF
    return lpr + ll


@_jit
def emulator_logpost_rows(Z, post, cnt, out) -> None:
    work = _emulator_work(Z, post)
    for k in range(Z.shape[0]):
        out[k] = emulator_logpost(Z[k], post, work, cnt)


@_jit
def add_loglik_var_rows(Q, V, lik, lp, cnt) -> None:
    """:func:`add_loglik_rows` with the emulator's variance V (rows as Q)."""
    r = 0
    for k in range(lp.shape[0]):
        if lp[k] == NEG_INF:
            cnt[N_OUTSIDE] += 1.0
            continue
        cnt[N_EVALS] += 1.0
        ll = loglik_var_point(Q[r], V[r], lik)
        r += 1
        if not math.isfinite(ll):
            cnt[N_NAN] += 1.0
            lp[k] = NEG_INF
        else:
            lp[k] += ll


@_jit
def run_block_emulator(x, lp, L, Z1, Z2, LU1, LU2, nb_steps, Y, LPY, mean, m2, st, fpar, ipar,
                       out, out_lp, post, cnt) -> None:
    """nb_steps steps of every chain on the emulator posterior, evaluating only what the
    chain needs: stage 1, then stage 2 for the chains whose stage 1 was rejected."""
    c, d = x.shape
    two = Y.shape[1] == 2
    work = _emulator_work(x, post)
    for t in range(nb_steps):
        propose(x, L, Z1, Z2, t, np.int64(1), fpar[0], Y)
        for k in range(c):
            LPY[0, 0, k] = emulator_logpost(Y[0, 0, k], post, work, cnt)
            if two:
                LPY[0, 1, k] = NEG_INF
                if not LU1[t, k] < LPY[0, 0, k] - lp[k]:
                    LPY[0, 1, k] = emulator_logpost(Y[0, 1, k], post, work, cnt)
        advance(x, lp, L, Y, LPY, Z1, Z2, LU1, LU2, t, np.int64(1), np.bool_(False), mean, m2,
                st, fpar, ipar, out, out_lp)
