"""Polynomial chaos expansions with Wiener-Askey bases (thesis section 2.3.3, table 2.1).

Each input gets a germ variable xi and a one-dimensional orthonormal basis:

=============== ================================ ===============================
distribution    polynomials                      germ xi
=============== ================================ ===============================
Normal          Hermite (probabilists')          (x - mu) / sigma
Uniform         Legendre                         2 (x - lower) / (upper - lower) - 1
Beta            Jacobi (a = beta-1, b = alpha-1) 2 (x - lower) / (upper - lower) - 1
Exponential     Laguerre                         x / beta
Gamma           generalized Laguerre (alpha-1)   x / beta
other / corr.   Hermite                          u (Nataf / marginal u-space transform)
=============== ================================ ===============================

(In a correlated space every input uses Hermite in the Nataf u-space.) The expansion is
truncated at total order p: N_T = (d + p)! / (d! p!) terms (eq. 2.16), or (Dakota's default
on a tensor quadrature grid) kept as the grid's tensor basis, degree <= p in each input, or by
a hyperbolic (q-norm) truncation. Coefficients by
projection (eq. 2.17) with tensor Gauss quadrature or a Smolyak sparse grid (combination
technique on the projections), or by regression on an LHS sample: least squares on all terms,
or sparse regression by orthogonal matching pursuit or least angle regression (plain or with
the lasso modification), the number of terms and the order chosen by leave-one-out error. Moments
(eqs. 2.18, 2.19) and Sobol' indices follow from the coefficients.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import special

from .._rng import SeedLike, as_generator
from ..errors import ParameterError
from ..model import Model
from ..params import Beta, Exponential, Gamma, Normal, ParameterSpace, Uniform, unit_design
from ._common import eval_space, nan_rows_warning
from .sampling import unit_to_space

__all__ = [
    "PCEResult",
    "PCEModel",
    "polynomial_chaos",
    "total_order_indices",
    "tensor_indices",
    "hyperbolic_indices",
    "Germ",
    "TRUNCATIONS",
    "SOLVERS",
]

ESTIMATORS = ("quadrature", "sparse_grid", "regression", "sampling")
TRUNCATIONS = ("tensor", "total_order", "hyperbolic")
"""Basis truncations of :func:`polynomial_chaos`."""
SOLVERS = ("least_squares", "omp", "lars", "lasso")
"""Regression solvers of :func:`polynomial_chaos`."""
_OMP_PATIENCE = 20


def total_order_indices(d: int, p: int) -> np.ndarray:
    """Multi-indices with total degree <= p, shape (N_T, d), sorted by degree."""
    out = [a for a in itertools.product(range(p + 1), repeat=d) if sum(a) <= p]
    out.sort(key=lambda a: (sum(a), tuple(-v for v in a)))
    return np.array(out, dtype=int).reshape(-1, d)


def tensor_indices(d: int, p: int | Sequence[int]) -> np.ndarray:
    """Multi-indices with every degree <= p (the tensor basis), shape ((p + 1)^d, d), sorted
    by total degree; ``p`` may give each input its own degree.

    Examples
    --------
    >>> tensor_indices(2, 1).tolist()
    [[0, 0], [1, 0], [0, 1], [1, 1]]
    >>> tensor_indices(2, (2, 0)).tolist()
    [[0, 0], [1, 0], [2, 0]]
    """
    degrees = [int(p)] * d if isinstance(p, int | np.integer) else [int(v) for v in p]
    out = list(itertools.product(*[range(k + 1) for k in degrees]))
    out.sort(key=lambda a: (sum(a), tuple(-v for v in a)))
    return np.array(out, dtype=int).reshape(-1, d)


def hyperbolic_indices(d: int, p: int, q_norm: float) -> np.ndarray:
    """Multi-indices with ``(sum_j alpha_j^q)^(1/q) <= p`` (hyperbolic truncation of Blatman
    and Sudret 2011; q = 1 is the total order), shape (N, d), sorted by total degree.

    Parameters
    ----------
    d : number of inputs; p : maximal degree; q_norm : q in (0, 1].

    Examples
    --------
    >>> hyperbolic_indices(2, 2, 0.5).tolist()
    [[0, 0], [1, 0], [0, 1], [2, 0], [0, 2]]
    """
    if not 0.0 < q_norm <= 1.0:
        raise ParameterError(f"q_norm must lie in (0, 1], got {q_norm}")
    alpha = total_order_indices(d, p)
    norm = np.sum(alpha.astype(float) ** q_norm, axis=1) ** (1.0 / q_norm)
    return alpha[norm <= p * (1.0 + 1e-12)]


class Germ:
    """One input's germ: x <-> xi maps, raw polynomials, Gauss rule, and orthonormalization."""

    def __init__(self, dist, family: str):
        self.dist, self.family = dist, family
        self._norms: dict[int, np.ndarray] = {}

    # maps
    def to_x(self, xi):
        d, f = self.dist, self.family
        if f == "hermite":
            return d.mean + d.std * xi if isinstance(d, Normal) else d.from_z(xi)
        if f in ("legendre", "jacobi"):
            lo, hi = d.bounds
            return lo + (xi + 1) * (hi - lo) / 2
        return xi * d.beta  # laguerre, genlaguerre

    def to_xi(self, x):
        d, f = self.dist, self.family
        if f == "hermite":
            if isinstance(d, Normal):
                return (x - d.mean) / d.std
            return d.to_z(x)
        if f in ("legendre", "jacobi"):
            lo, hi = d.bounds
            return 2 * (x - lo) / (hi - lo) - 1
        return x / d.beta

    def gauss(self, n: int):
        """n-point Gauss rule for the germ's probability measure (weights sum to 1)."""
        f, d = self.family, self.dist
        if f == "hermite":
            t, w = np.polynomial.hermite_e.hermegauss(n)
        elif f == "legendre":
            t, w = np.polynomial.legendre.leggauss(n)
        elif f == "jacobi":
            t, w = special.roots_jacobi(n, d.beta - 1, d.alpha - 1)
        elif f == "laguerre":
            t, w = special.roots_laguerre(n)
        else:
            t, w = special.roots_genlaguerre(n, d.alpha - 1)
        return np.asarray(t), np.asarray(w) / np.sum(w)

    def _raw(self, n, xi):
        f, d = self.family, self.dist
        if f == "hermite":
            return special.eval_hermitenorm(n, xi)
        if f == "legendre":
            return special.eval_legendre(n, xi)
        if f == "jacobi":
            return special.eval_jacobi(n, d.beta - 1, d.alpha - 1, xi)
        if f == "laguerre":
            return special.eval_laguerre(n, xi)
        return special.eval_genlaguerre(n, d.alpha - 1, xi)

    def basis(self, p: int, xi) -> np.ndarray:
        """Orthonormal polynomials of degree 0..p at xi: shape (len(xi), p + 1)."""
        if p not in self._norms:
            t, w = self.gauss(p + 2)
            raw = np.column_stack([self._raw(k, t) for k in range(p + 1)])
            self._norms[p] = np.sqrt(w @ raw**2)
        xi = np.asarray(xi, dtype=float)
        raw = np.column_stack([self._raw(k, xi) for k in range(p + 1)])
        return raw / self._norms[p]


def _germs(space: ParameterSpace, basis: str) -> list[Germ]:
    germs = []
    for dist in space.distributions:
        fam = "hermite"
        if basis == "askey" and space.correlation is None:
            if isinstance(dist, Uniform):
                fam = "legendre"
            elif isinstance(dist, Beta):
                fam = "jacobi"
            elif isinstance(dist, Exponential):
                fam = "laguerre"
            elif isinstance(dist, Gamma):
                fam = "genlaguerre"
        germs.append(Germ(dist, fam))
    return germs


def _xi_to_x(space, germs, xi):
    if space.correlation is not None:
        return space.from_u(xi)
    return np.column_stack([g.to_x(xi[:, j]) for j, g in enumerate(germs)])


def _x_to_xi(space, germs, x):
    if space.correlation is not None:
        return space.to_u(x)
    return np.column_stack([g.to_xi(x[:, j]) for j, g in enumerate(germs)])


def _design_matrix(germs, alpha, xi):
    p = int(alpha.max()) if alpha.size else 0
    psi1 = [g.basis(p, xi[:, j]) for j, g in enumerate(germs)]
    out = np.ones((xi.shape[0], alpha.shape[0]))
    for j in range(len(germs)):
        out *= psi1[j][:, alpha[:, j]]
    return out


@dataclass(frozen=True, eq=False)
class PCEResult:
    """A polynomial chaos expansion of m responses.

    Attributes
    ----------
    names_in, names_out : tuple of str
        The d input and m response names.
    order : int
        The polynomial order p.
    multi_indices : ndarray of shape (N_T, d)
        The degree of each input in each of the N_T basis terms.
    coefficients : ndarray of shape (N_T, m)
        The expansion's coefficients, response units (orthonormal basis).
    families : tuple of str
        The polynomial family of each input (``"hermite"``, ``"legendre"``, ...).
    mean : ndarray of shape (m,)
        c_0 (eq. 2.18).
    variance : ndarray of shape (m,)
        sum_{i>0} c_i^2 (eq. 2.19), response units squared.
    std : ndarray of shape (m,)
        The square root of ``variance``.
    main, total : ndarray of shape (m, d)
        Sobol' indices from the coefficients.
    estimator : str
        ``"quadrature"``, ``"sparse_grid"``, ``"regression"`` or ``"sampling"``.
    n_evaluations : int
        Model evaluations (points).
    n_dropped : int
        Failed points left out of a regression fit.
    truncation : str
        ``"tensor"``, ``"total_order"`` or ``"hyperbolic"``.
    loo_error : ndarray of shape (m,) or None
        Relative leave-one-out error of a sparse (``"omp"``, ``"lars"``, ``"lasso"``)
        regression, None otherwise.
    space : ParameterSpace or None
        The inputs' distributions (:meth:`predict` maps points through them).
    germs : list
        The one-dimensional polynomial families of the inputs, with their maps to the
        standard variables.
    """

    names_in: tuple[str, ...]
    names_out: tuple[str, ...]
    order: int
    multi_indices: np.ndarray
    coefficients: np.ndarray
    families: tuple[str, ...]
    mean: np.ndarray
    variance: np.ndarray
    std: np.ndarray
    main: np.ndarray
    total: np.ndarray
    estimator: str
    n_evaluations: int
    n_dropped: int = 0
    truncation: str = "total_order"
    loo_error: np.ndarray | None = None
    space: ParameterSpace | None = field(default=None, repr=False)
    germs: list = field(default_factory=list, repr=False)

    @property
    def n_terms(self) -> int:
        """Number of basis terms N_T."""
        return self.multi_indices.shape[0]

    def interaction(self, *names_in: str) -> np.ndarray:
        """Sobol' index of the interaction of exactly these inputs, shape (m,).

        The share of the variance carried by the terms whose non-zero degrees are exactly on
        ``names_in`` (one name: the main index; two: the pure second-order index S_ij).

        Parameters
        ----------
        *names_in : str
            The inputs of the interaction (at least one).

        Examples
        --------
        >>> import rotoruq as rq
        >>> space = rq.ParameterSpace({"a": rq.Uniform(-1, 1), "b": rq.Uniform(-1, 1)})
        >>> m = rq.FunctionModel(lambda x: x[:, 0] * x[:, 1], ["a", "b"], ["y"])
        >>> float(polynomial_chaos(m, space, 2).interaction("a", "b")[0])
        1.0
        """
        if not names_in:
            raise ParameterError("interaction needs at least one input name")
        idx = []
        for n in names_in:
            if n not in self.names_in:
                raise ParameterError(f"unknown input {n!r}; valid: {list(self.names_in)}")
            idx.append(self.names_in.index(n))
        support = self.multi_indices > 0
        want = np.zeros(len(self.names_in), dtype=bool)
        want[idx] = True
        rows = np.all(support == want, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            return (self.coefficients[rows] ** 2).sum(axis=0) / self.variance

    def predict(self, x: np.ndarray) -> np.ndarray:
        """Expansion at points x (n, d) in ``names_in`` order: (n, m).

        Parameters
        ----------
        x : array_like of shape (n, d) or (d,)
            Points, in the inputs' units.
        """
        if self.space is None:
            raise ParameterError("this PCEResult does not carry its parameter space")
        x = self.space._check(x)
        xi = _x_to_xi(self.space, self.germs, x)
        return _design_matrix(self.germs, self.multi_indices, xi) @ self.coefficients

    def as_model(self) -> PCEModel:
        """The expansion as a :class:`~rotoruq.model.Model` (inputs ``names_in``, outputs
        ``names_out``), e.g. to propagate through it with ``rq.sample(result.as_model(),
        space, n_samples)``."""
        return PCEModel(self)


class PCEModel:
    """A :class:`PCEResult` seen through the Model protocol (``__call__`` = ``predict``)."""

    def __init__(self, result: PCEResult):
        self.result = result
        self.names_in = result.names_in
        self.names_out = result.names_out

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.result.predict(x)

    def __repr__(self) -> str:
        return f"PCEModel(order={self.result.order}, in={self.names_in}, out={self.names_out})"


def _smolyak_terms(d: int, level: int):
    """(multi-index of points per dim, coefficient) of the Smolyak combination technique."""
    q = d + level
    out = []
    for i in itertools.product(range(1, level + 2), repeat=d):
        s = sum(i)
        if q - d + 1 <= s <= q:
            c = (-1) ** (q - s) * math.comb(d - 1, q - s)
            if c:
                out.append((i, c))
    return out


def _tensor_grid(germs, npts):
    rules = [g.gauss(n) for g, n in zip(germs, npts, strict=True)]
    nodes = np.array(list(itertools.product(*[r[0] for r in rules])))
    w = np.prod(np.array(list(itertools.product(*[r[1] for r in rules]))), axis=1)
    return nodes.reshape(-1, len(germs)), w


def _omp(psi: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    """Orthogonal matching pursuit with the sparsity chosen by leave-one-out error.

    Parameters
    ----------
    psi : (n, P) design matrix; y : (n,) responses.

    Returns
    -------
    coef : (P,) coefficients, zero outside the chosen active set (refit by least squares).
    loo : the chosen fit's leave-one-out mean squared error.

    The constant term enters first; each step adds the column most correlated with the
    residual (orthogonalized against the active ones by twice-repeated Gram-Schmidt, so a step
    costs O(n P)), up to n - 2 terms so that the leave-one-out error e_i / (1 - h_ii) stays
    defined; the path stops once that error has not improved for ``_OMP_PATIENCE`` steps.
    The fit with the least leave-one-out error along the path is kept.
    """
    n, p = psi.shape
    norms = np.linalg.norm(psi, axis=0)
    usable = norms > 0
    norms[~usable] = 1.0
    q = np.empty((n, min(p, n)))
    h = np.zeros(n)
    resid = y.astype(float).copy()
    active: list[int] = []
    best_loo, best_k, since = np.inf, 0, 0
    candidate = 0  # the constant first
    while candidate >= 0:
        v = psi[:, candidate].astype(float)
        for _ in range(2):
            v -= q[:, : len(active)] @ (q[:, : len(active)].T @ v)
        nv = np.linalg.norm(v)
        usable[candidate] = False
        if nv > 1e-10 * norms[candidate]:
            k = len(active)
            q[:, k] = v / nv
            active.append(candidate)
            h += q[:, k] ** 2
            resid -= q[:, k] * (q[:, k] @ resid)
            loo = float(np.mean((resid / (1.0 - np.minimum(h, 1.0 - 1e-12))) ** 2))
            if loo < best_loo:
                best_loo, best_k, since = loo, len(active), 0
            else:
                since += 1
            if len(active) >= min(p, n - 2) or since >= _OMP_PATIENCE or not np.any(resid):
                break
        score = np.abs(psi.T @ resid) / norms
        score[~usable] = -1.0
        candidate = int(np.argmax(score)) if np.any(usable) else -1
    chosen = active[:best_k]
    coef = np.zeros(p)
    coef[chosen] = np.linalg.lstsq(psi[:, chosen], y, rcond=None)[0]
    return coef, float(best_loo)


def _orthonormal_add(q: np.ndarray, v: np.ndarray) -> np.ndarray | None:
    """q (n, k) with the column v orthonormalized against it appended (twice-repeated
    Gram-Schmidt), or None when v is (numerically) in the span of q."""
    v = v.astype(float).copy()
    nv0 = float(np.linalg.norm(v))
    for _ in range(2):
        v -= q @ (q.T @ v)
    nv = float(np.linalg.norm(v))
    if nv <= 1e-10 * nv0 or nv == 0.0:
        return None
    return np.column_stack([q, v / nv])


def _loo_from_q(q: np.ndarray, y: np.ndarray) -> float:
    """Leave-one-out mean squared error e_i / (1 - h_ii) of the least-squares fit of y on an
    orthonormal basis q (n, k) of the columns."""
    h = np.sum(q * q, axis=1)
    resid = y - q @ (q.T @ y)
    return float(np.mean((resid / (1.0 - np.minimum(h, 1.0 - 1e-12))) ** 2))


def _lars(psi: np.ndarray, y: np.ndarray, lasso: bool = False) -> tuple[np.ndarray, float]:
    """Hybrid least angle regression with the sparsity chosen by leave-one-out error.

    Parameters
    ----------
    psi : (n, P) design matrix, column 0 the constant term; y : (n,) responses.
    lasso : apply the lasso modification (a term whose coefficient crosses zero leaves the
        active set), which makes the path the lasso's (Efron et al. 2004).

    Returns
    -------
    coef : (P,) coefficients, zero outside the chosen active set (refit by least squares).
    loo : the chosen fit's leave-one-out mean squared error.

    LARS (on centred, unit-norm columns; the constant is the intercept) moves the fit along
    the direction equiangular to the active columns until an inactive column is as correlated
    with the residual; each active set along the path is refit by least squares with the
    constant and scored by its leave-one-out error (the hybrid LARS of Blatman and Sudret
    2011, Dakota's ``least_angle_regression`` / ``lasso`` with cross validation). Up to n - 2
    terms; the path stops once that error has not improved for ``_OMP_PATIENCE`` steps.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> x = rng.uniform(-1, 1, (30, 3))
    >>> psi = np.column_stack([np.ones(30), x, x[:, 0] * x[:, 1]])
    >>> coef, loo = _lars(psi, 2 + 3 * x[:, 1] - x[:, 0] * x[:, 1])
    >>> np.round(coef, 12).tolist(), loo < 1e-25
    ([2.0, 0.0, 3.0, 0.0, -1.0], True)
    """
    n, p = psi.shape
    x = psi[:, 1:] - psi[:, 1:].mean(axis=0)
    norms = np.linalg.norm(x, axis=0)
    usable = norms > 1e-12 * max(1.0, float(norms.max(initial=0.0)))
    x = x / np.where(usable, norms, 1.0)
    yc = y - y.mean()
    fit, beta = np.zeros(n), np.zeros(p - 1)
    q = _orthonormal_add(np.empty((n, 0)), psi[:, 0])
    assert q is not None
    best_loo, best_set, since = _loo_from_q(q, y), [], 0
    c = x.T @ yc
    active = [int(np.argmax(np.where(usable, np.abs(c), -1.0)))] if np.any(usable) else []
    if active:
        q = _orthonormal_add(q, psi[:, active[0] + 1])
    limit = min(p - 1, n - 2)
    for _ in range(4 * limit if active else 0):  # joins, and with the lasso some drops
        c = x.T @ (yc - fit)
        big = float(np.max(np.abs(c[active])))
        if big <= 1e-14 * max(1.0, float(np.linalg.norm(yc))):
            break  # the residual is orthogonal to every column: the fit is exact
        sgn = np.sign(c[active])
        xa = x[:, active] * sgn
        try:
            g1 = np.linalg.solve(xa.T @ xa, np.ones(len(active)))
        except np.linalg.LinAlgError:
            break
        a_a = 1.0 / np.sqrt(max(float(g1.sum()), 1e-300))
        w = a_a * g1
        u = xa @ w
        a = x.T @ u
        free = usable.copy()
        free[active] = False
        with np.errstate(divide="ignore", invalid="ignore"):
            cand = np.concatenate([(big - c) / (a_a - a), (big + c) / (a_a + a)])
        cand = np.where(np.concatenate([free, free]) & (cand > 1e-12), cand, np.inf)
        k = int(np.argmin(cand))
        gamma, join, drop = float(cand[k]), k % (p - 1), -1
        if not np.isfinite(gamma):
            gamma, join = big / a_a, -1  # the last step: least squares on the active set
        if lasso:
            with np.errstate(divide="ignore", invalid="ignore"):
                cross = -beta[active] / (sgn * w)
            cross = np.where(cross > 1e-12, cross, np.inf)
            if cross.min() < gamma:
                gamma, drop, join = float(cross.min()), int(np.argmin(cross)), -1
        fit += gamma * u
        beta[active] += gamma * sgn * w
        if drop >= 0:
            beta[active[drop]] = 0.0
            del active[drop]
            q = _orthonormal_add(np.empty((n, 0)), psi[:, 0])
            for j in active:  # rebuilt without the dropped column (rare)
                q = _orthonormal_add(q, psi[:, j + 1]) if q is not None else None
        elif join >= 0:
            q_new = _orthonormal_add(q, psi[:, join + 1]) if q is not None else None
            if q_new is None:  # in the span of the active columns: it cannot join
                usable[join] = False
                continue
            active.append(join)
            q = q_new
        loo = _loo_from_q(q, y) if q is not None else np.inf  # inf: rank deficient
        if loo < best_loo:
            best_loo, best_set, since = loo, list(active), 0
        else:
            since += 1
        if since >= _OMP_PATIENCE or (join < 0 and drop < 0) or len(active) >= limit:
            break
    cols = [0] + [j + 1 for j in best_set]
    coef = np.zeros(p)
    coef[cols] = np.linalg.lstsq(psi[:, cols], y, rcond=None)[0]
    return coef, float(best_loo)


def _tensor_projection(germs, nq: Sequence[int], alpha: np.ndarray,
                       values: np.ndarray) -> np.ndarray:
    """Projection coefficients (N, m) of ``values`` (prod(nq), m), given on the tensor Gauss
    grid of :func:`_tensor_grid` with ``nq[j]`` points along input j, onto the basis terms
    ``alpha`` (N, d).

    One 1-D projection per axis (O(nq^d d p) work) instead of the (nq^d, N) design matrix,
    which for a tensor basis would be square in the grid size.
    """
    m = values.shape[1]
    pmax = int(alpha.max()) if alpha.size else 0
    t = values.reshape(tuple(nq) + (m,))
    for j, g in enumerate(germs):
        nodes, wj = g.gauss(nq[j])
        proj = (g.basis(pmax, nodes) * wj[:, None]).T  # (pmax + 1, nq)
        t = np.moveaxis(np.tensordot(proj, t, axes=([1], [j])), 0, j)
    return t[tuple(alpha.T)]


def polynomial_chaos(
    model: Model,
    space: ParameterSpace,
    order: int,
    *,
    estimator: str = "quadrature",
    n_samples: int | None = None,
    quadrature_points: int | None = None,
    basis: str = "askey",
    truncation: str | None = None,
    q_norm: float = 0.5,
    solver: str = "least_squares",
    dimension_preference: Sequence[float] | None = None,
    seed: SeedLike = None,
) -> PCEResult:
    """Fit an order-``order`` polynomial chaos expansion of every response.

    All points of a design go to the model in ONE batched call.

    Parameters
    ----------
    model, space : the Model and its uncertain inputs (matched by name).
    order : polynomial order p (>= 1): the total order, or the degree in each input for the
        tensor basis.
    estimator : "quadrature" (tensor Gauss rule, ``quadrature_points`` per input, default p + 1),
        "sparse_grid" (Smolyak level p over Gauss rules of 1..p+1 points), "regression"
        (least squares on ``n_samples`` LHS points, default 2 N_T) or "sampling" (each
        coefficient the sample mean of y times its orthonormal basis term over ``n_samples``
        LHS points, default 2 N_T: Dakota's ``expansion_samples``).
    n_samples : int, optional
        ``"regression"`` and ``"sampling"``: the number of LHS points (default 2 N_T, or N_T
        of the order with a sparse ``solver``).
    quadrature_points : int, optional
        ``"quadrature"``: Gauss points per input (default p + 1; the most preferred input's
        with ``dimension_preference``).
    basis : "askey" (table 2.1 where it applies, Hermite in u-space otherwise) or "hermite"
        (Hermite in u-space for every input).
    truncation : "tensor" (degree <= p in each input, (p + 1)^d terms: Dakota's basis on a
        tensor grid, and the default for ``estimator="quadrature"``; needs
        ``quadrature_points >= p + 1`` there, where the projection is then exact for every
        polynomial in the basis), "total_order" (N_T = (d + p)! / (d! p!) terms, the default
        for the other estimators) or "hyperbolic" (``||alpha||_q <= p`` with ``q_norm``).
    q_norm : q in (0, 1] of the hyperbolic truncation.
    solver : "regression" only: "least_squares" (all terms; needs n_samples >= N), or a sparse
        fit per response whose number of terms, and order up to ``order`` (raised until two
        orders in a row do not improve it), minimize the leave-one-out error: "omp"
        (orthogonal matching pursuit, Dakota's ``omp``), "lars" (least angle regression,
        Dakota's ``least_angle_regression``) or "lasso" (LARS with the lasso modification,
        Dakota's ``lasso``); each active set is refit by least squares (hybrid LARS). Fewer
        samples than terms allowed, default n_samples = N_T of the order. The result's
        ``loo_error`` holds the relative leave-one-out error of each response.
    dimension_preference : (d,) positive, "quadrature" only: an anisotropic tensor grid as
        Dakota's ``dimension_preference`` makes it: the most preferred input gets the
        ``quadrature_points``, input i ``int(quadrature_points * pref_i / max pref)`` (at
        least 1), and the tensor basis its degree ``points - 1`` per input.
    seed : design seed for "regression".

    Examples
    --------
    y = a^2 with a ~ N(0, 1): mean 1 and variance 2, exact for an order-2 Hermite expansion:

    >>> import rotoruq as rq
    >>> space = rq.ParameterSpace({"a": rq.Normal(0.0, 1.0)})
    >>> model = rq.FunctionModel(lambda x: x**2, space.names, ["y"])
    >>> pce = rq.polynomial_chaos(model, space, order=2)
    >>> round(float(pce.mean[0]), 12), round(float(pce.std[0] ** 2), 12)
    (1.0, 2.0)
    """
    order = int(order)
    if order < 1:
        raise ParameterError(f"order must be >= 1, got {order}")
    if basis not in ("askey", "hermite"):
        raise ParameterError(f"basis must be 'askey' or 'hermite', got {basis!r}")
    d = space.dim
    germs = _germs(space, basis)
    m = len(model.names_out)
    n_dropped = 0
    loo: np.ndarray | None = None
    if estimator not in ESTIMATORS:
        raise ParameterError(
            f"unknown PCE estimator {estimator!r}; valid: {', '.join(ESTIMATORS)}")
    if solver not in SOLVERS:
        raise ParameterError(f"unknown solver {solver!r}; valid: {', '.join(SOLVERS)}")
    if solver != "least_squares" and estimator != "regression":
        # (estimator "sampling" projects; it has no solver)
        raise ParameterError(f"solver {solver!r} needs estimator 'regression'")
    if truncation is None:
        truncation = "tensor" if estimator == "quadrature" else "total_order"
    if truncation == "tensor" and estimator == "sparse_grid":
        raise ParameterError("a sparse grid cannot resolve the tensor basis; use truncation "
                             "'total_order' or 'hyperbolic' with estimator 'sparse_grid'")
    points: list[int] | None = None
    if dimension_preference is not None:
        pref = np.asarray(dimension_preference, dtype=float)
        if estimator != "quadrature" or truncation != "tensor":
            raise ParameterError("dimension_preference needs estimator 'quadrature' with the "
                                 "tensor truncation")
        if pref.shape != (d,) or not np.all(np.isfinite(pref)) or np.any(pref <= 0):
            raise ParameterError(f"dimension_preference needs {d} positive numbers (one per "
                                 f"input), got {list(np.atleast_1d(pref))}")
        nq0 = int(quadrature_points or order + 1)
        top = int(np.argmax(pref))  # the first of equal maxima, as Dakota
        points = [nq0 if i == top else max(1, int(nq0 * pref[i] / pref[top]))
                  for i in range(d)]
    if truncation == "tensor":
        alpha = tensor_indices(d, order if points is None else [n - 1 for n in points])
    elif truncation == "total_order":
        alpha = total_order_indices(d, order)
    elif truncation == "hyperbolic":
        alpha = hyperbolic_indices(d, order, q_norm)
    else:
        raise ParameterError(
            f"unknown truncation {truncation!r}; valid: {', '.join(TRUNCATIONS)}")
    if estimator == "quadrature":
        nq = int(quadrature_points or order + 1)
        if truncation == "tensor" and nq < order + 1:
            raise ParameterError(
                f"a tensor basis of degree {order} per input needs quadrature_points >= "
                f"{order + 1}, got {nq}")
        npts = points if points is not None else [nq] * d
        xi, w = _tensor_grid(germs, npts)
        batch = eval_space(model, space, _xi_to_x(space, germs, xi))
        if batch.failures:
            raise ParameterError(
                f"{len(batch.failures)} quadrature evaluations failed; projection needs all "
                "points (use estimator='regression')"
            )
        coef = _tensor_projection(germs, npts, alpha, batch.values)
        n_eval = xi.shape[0]
    elif estimator == "sparse_grid":
        terms = _smolyak_terms(d, order)
        grids = [_tensor_grid(germs, i) for i, _ in terms]
        allxi = np.vstack([g[0] for g in grids])
        uniq, inv = np.unique(np.round(allxi, 13), axis=0, return_inverse=True)
        batch = eval_space(model, space, _xi_to_x(space, germs, uniq))
        if batch.failures:
            raise ParameterError(
                f"{len(batch.failures)} sparse-grid evaluations failed; use estimator='regression'"
            )
        y_all = batch.values[inv.ravel()]
        coef = np.zeros((alpha.shape[0], m))
        start = 0
        for (npts, c), (xi, w) in zip(terms, grids, strict=True):
            y = y_all[start : start + xi.shape[0]]
            start += xi.shape[0]
            inside = np.all(alpha <= np.array(npts) - 1, axis=1)
            coef[inside] += c * (_design_matrix(germs, alpha[inside], xi).T @ (w[:, None] * y))
        n_eval = uniq.shape[0]
    else:  # regression, or projection by sampling
        default_n = 2 * alpha.shape[0] if solver == "least_squares" else alpha.shape[0]
        n = int(n_samples or default_n)
        if solver == "least_squares" and estimator == "regression" and n < alpha.shape[0]:
            raise ParameterError(f"regression needs n_samples >= N_T = {alpha.shape[0]}, got {n}"
                                 " (or a sparse solver: 'omp', 'lars', 'lasso')")
        if n < 4:
            raise ParameterError(f"regression needs n_samples >= 4, got {n}")
        x = unit_to_space(space, unit_design(n, d, design="lhs", seed=as_generator(seed)))
        batch = eval_space(model, space, x)
        ok = batch.ok
        n_dropped = int(np.sum(~ok))
        nan_rows_warning(n_dropped, n, "polynomial_chaos regression")
        psi = _design_matrix(germs, alpha, _x_to_xi(space, germs, x[ok]))
        yv = batch.values[ok]
        if estimator == "sampling":
            # the projection <y, psi_k> of the orthonormal basis by its sample mean
            coef = psi.T @ yv / psi.shape[0]
        elif solver == "least_squares":
            coef = np.linalg.lstsq(psi, yv, rcond=None)[0]
        else:
            coef = np.zeros((alpha.shape[0], m))
            loo = np.full(m, np.nan)
            sparse = {"omp": _omp, "lars": _lars,
                      "lasso": lambda a, b: _lars(a, b, lasso=True)}[solver]
            degree = alpha.sum(axis=1) if truncation != "tensor" else alpha.max(axis=1)
            for k in range(m):
                best = None
                # orders 1, 2, ... on the same sample (adaptive order, as Dakota's
                # cross-validated OMP): stop once two orders in a row have not improved
                worse = 0
                for o in range(1, order + 1):
                    rows = np.flatnonzero(degree <= o)
                    c, e = sparse(psi[:, rows], yv[:, k])
                    if best is None or e < best[0]:
                        best, worse = (e, rows, c), 0
                    else:
                        worse += 1
                        if worse >= 2:
                            break
                assert best is not None
                coef[best[1], k] = best[2]
                var_y = np.var(yv[:, k])
                loo[k] = best[0] / var_y if var_y > 0 else 0.0
        n_eval = n
    c2 = coef[1:] ** 2
    var = c2.sum(axis=0)
    a = alpha[1:]
    only = [(a[:, i] > 0) & (a.sum(axis=1) == a[:, i]) for i in range(d)]
    # zero up to the round-off of the projection
    flat = [name for name, v, c0 in zip(model.names_out, var, coef[0], strict=True)
            if v <= (1e-13 * max(abs(c0), 1e-300)) ** 2]
    if flat:
        import warnings

        warnings.warn(
            f"polynomial_chaos: responses {flat} have zero variance in the expansion (up to "
            "round-off): their Sobol' indices are undefined",
            RuntimeWarning,
            stacklevel=2,
        )
    with np.errstate(invalid="ignore", divide="ignore"):
        main = np.array([c2[o].sum(axis=0) for o in only]).T / var[:, None]
        total = np.array([c2[a[:, i] > 0].sum(axis=0) for i in range(d)]).T / var[:, None]
    for name in flat:
        k = tuple(model.names_out).index(name)
        main[k] = total[k] = np.nan
    return PCEResult(
        names_in=space.names,
        names_out=tuple(model.names_out),
        order=order,
        multi_indices=alpha,
        coefficients=coef,
        families=tuple(g.family for g in germs),
        mean=coef[0].copy(),
        variance=var,
        std=np.sqrt(var),
        main=main,
        total=total,
        estimator=estimator,
        n_evaluations=int(n_eval),
        n_dropped=n_dropped,
        truncation=truncation,
        loo_error=loo,
        space=space,
        germs=germs,
    )
