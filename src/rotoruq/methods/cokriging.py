"""Multi-fidelity Gaussian-process emulator: recursive autoregressive co-kriging.

Kennedy and O'Hagan (2000, Biometrika 87(1)) link the fidelity levels t = 0 (cheapest) .. L-1
(the truth) by ``y_t(x) = rho_t y_{t-1}(x) + delta_t(x)`` with independent Gaussian processes
delta_t. Le Gratiet and Garnier (2014, IJUQ 4(5)) showed that with nested designs
(X_t a subset of X_{t-1}) the joint model splits into one GP per level, each fitted on its
own points with the previous level's posterior mean as a regressor:

    mean_t(x) = rho_t mean_{t-1}(x) + mean_delta_t(x)
    var_t(x)  = rho_t^2 var_{t-1}(x) + var_delta_t(x).

Here every delta_t is a :class:`~rotoruq.methods.surrogate.GaussianProcess` (its options are
``gp_options``) fitted on ``y_t - rho_t mean_{t-1}`` at the level-t points, and rho_t (one per
response) minimises the delta GP's leave-one-out error (closed form, Dubrule 1983) over
``|rho| <= 3 max(std(y_t) / std(mean_{t-1}), |least-squares slope|)`` (a grid, then Brent).
On points of level t that are not level-(t-1) points the previous level enters by its
posterior mean (exact for nested designs, where that mean interpolates the data).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy import optimize

from .._rng import SeedLike, as_seed_sequence
from ..errors import ModelShapeError, ParameterError
from .surrogate import GaussianProcess

__all__ = ["CoKriging", "CoKrigingModel"]


class CoKriging:
    """Recursive autoregressive co-kriging emulator (module doc).

    Parameters
    ----------
    gp_options : keyword arguments of every level's
        :class:`~rotoruq.methods.surrogate.GaussianProcess` (trend, kernel, nugget,
        n_restarts...); ``seed`` is set here.
    seed : int or Generator for the GPs' random starts (one stream per level and response).

    Examples
    --------
    >>> import numpy as np
    >>> from rotoruq.methods.cokriging import CoKriging
    >>> hf = lambda x: (6 * x - 2) ** 2 * np.sin(12 * x - 4)      # Forrester et al. (2007)
    >>> lf = lambda x: 0.5 * hf(x) + 10 * (x - 0.5) - 5
    >>> x_lf = np.linspace(0, 1, 11)[:, None]
    >>> x_hf = x_lf[[0, 4, 6, 10]]
    >>> ck = CoKriging(seed=0).fit([x_lf, x_hf], [lf(x_lf), hf(x_hf)])
    >>> round(float(ck.rho[0, 0]), 1)
    2.0
    >>> mean, var = ck.predict(np.array([[0.3]]))
    >>> bool(abs(mean[0, 0] - hf(0.3)) < 0.1)
    True
    """

    def __init__(self, gp_options: Mapping[str, Any] | None = None, *,
                 seed: SeedLike = None) -> None:
        self.gp_options = dict(gp_options or {})
        if "seed" in self.gp_options:
            raise ParameterError("give the seed to CoKriging(seed=...), not in gp_options")
        GaussianProcess(**self.gp_options)  # checks the options now, not at fit
        self.seed = seed
        self._levels: list[list[GaussianProcess]] = []
        self._rho: np.ndarray | None = None

    # --- fitting ---------------------------------------------------------------------------
    def fit(self, X: Sequence[Any], Y: Sequence[Any]) -> CoKriging:
        """Fit on the points of each level, the cheapest first and the truth last.

        X : sequence of L arrays (n_t, d); Y : sequence of L arrays (n_t,) or (n_t, m).
        Nested designs (every level's points among the previous level's) make the recursive
        model exact; each level needs at least 3 points. Returns self.
        """
        if isinstance(X, np.ndarray) or isinstance(Y, np.ndarray) or len(X) != len(Y) \
                or len(X) < 2:
            raise ParameterError("CoKriging.fit takes sequences of L >= 2 arrays, one per "
                                 "fidelity level (cheapest first): X=[X_0, ..., X_hf], "
                                 "Y=[Y_0, ..., Y_hf]")
        Xs = [np.atleast_2d(np.asarray(x, dtype=float)) for x in X]
        Ys = [np.asarray(y, dtype=float) for y in Y]
        Ys = [y[:, None] if y.ndim == 1 else y for y in Ys]
        d, m = Xs[0].shape[1], Ys[0].shape[1]
        for t, (x, y) in enumerate(zip(Xs, Ys, strict=True)):
            if x.ndim != 2 or x.shape[1] != d or y.ndim != 2 or y.shape != (x.shape[0], m):
                raise ModelShapeError(f"level {t}: X {x.shape} and Y {y.shape} do not match "
                                      f"(n, {d}) and (n, {m}) of level 0")
            if x.shape[0] < 3:
                raise ParameterError(f"level {t} has {x.shape[0]} points; at least 3 are needed")
            if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
                raise ParameterError(f"level {t}: X and Y must be finite")
        ss = as_seed_sequence(self.seed).spawn(len(Xs) * m)
        levels: list[list[GaussianProcess]] = []
        rho = np.ones((len(Xs) - 1, m))
        for t, (x, y) in enumerate(zip(Xs, Ys, strict=True)):
            gps = []
            prev = self._predict_levels(levels, rho, x, return_var=False)[0] if t else None
            for j in range(m):
                seed = np.random.default_rng(ss[t * m + j])
                if prev is None:
                    gps.append(self._gp(seed).fit(x, y[:, j]))
                    continue
                r, gp = self._fit_delta(x, y[:, j], prev[:, j], seed)
                rho[t - 1, j] = r
                gps.append(gp)
            levels.append(gps)
        self._levels, self._rho = levels, rho
        self._d, self._m = d, m
        return self

    def _gp(self, seed) -> GaussianProcess:
        return GaussianProcess(**self.gp_options, seed=seed)

    def _fit_delta(self, x, y, prev, rng) -> tuple[float, GaussianProcess]:
        """rho minimising the delta GP's leave-one-out RMSE, and that GP.

        With delta independent of the level below, Var[y] = rho^2 Var[prev] + Var[delta], so
        |rho| <= std(y) / std(prev) in expectation; on few points delta can correlate with
        the level below (a linear discrepancy does), so the grid spans three times that (or
        the least-squares slope), then Brent's bounded search refines between the best grid
        point's neighbours."""
        seed_int = int(rng.integers(2**63))
        sd_prev = float(np.std(prev))
        slope = float(np.polyfit(prev, y, 1)[0]) if sd_prev > 0 else 0.0
        s = 3.0 * max(float(np.std(y)) / sd_prev if sd_prev > 0 else 1.0, abs(slope))
        cache: dict[float, float] = {}

        def loo(r: float) -> float:
            if r not in cache:
                with warnings.catch_warnings():  # candidates only: the final fit warns
                    warnings.simplefilter("ignore", RuntimeWarning)
                    gp = self._gp(seed_int).fit(x, y - r * prev)
                cache[r] = float(gp.loo().rmse[0])
            return cache[r]

        grid = np.linspace(-s, s, 31)
        k = int(np.argmin([loo(float(r)) for r in grid]))
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
        res = optimize.minimize_scalar(loo, bounds=(lo, hi), method="bounded",
                                       options={"xatol": 1e-4 * s})
        r = float(res.x) if res.fun <= loo(float(grid[k])) else float(grid[k])
        return r, self._gp(seed_int).fit(x, y - r * prev)

    # --- prediction ------------------------------------------------------------------------
    @property
    def rho(self) -> np.ndarray:
        """(L - 1, m) scale factors rho_t of each level on the one below."""
        self._check_fitted()
        assert self._rho is not None
        return self._rho.copy()

    @property
    def n_inputs(self) -> int:
        self._check_fitted()
        return self._d

    @property
    def n_outputs(self) -> int:
        self._check_fitted()
        return self._m

    def _check_fitted(self) -> None:
        if not self._levels:
            raise ParameterError("CoKriging is not fitted: call fit([X_lf, X_hf], [Y_lf, Y_hf])")

    @staticmethod
    def _predict_levels(levels, rho, X, return_var: bool):
        mean = var = None
        for t, gps in enumerate(levels):
            out = [gp.predict(X, return_var=return_var, warn_distance=None) for gp in gps]
            mu = np.column_stack([o[0] if return_var else o for o in out])
            v = np.column_stack([o[1] for o in out]) if return_var else None
            if t == 0:
                mean, var = mu, v
            else:
                mean = rho[t - 1] * mean + mu
                if return_var:
                    var = rho[t - 1] ** 2 * var + v
        return mean, var

    def predict(self, X, return_var: bool = True):
        """Predict the highest-fidelity response at points X (n, d).

        Returns ``mean`` (n, m), and ``var`` (n, m) (the recursive posterior variance, without
        the uncertainty of rho) when ``return_var``, like
        :meth:`~rotoruq.methods.surrogate.GaussianProcess.predict`.
        """
        self._check_fitted()
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if X.shape[1] != self._d:
            raise ModelShapeError(f"CoKriging trained on {self._d} inputs, got points of "
                                  f"shape {X.shape}")
        mean, var = self._predict_levels(self._levels, self._rho, X, return_var)
        return (mean, var) if return_var else mean

    def as_model(self, names_in: Sequence[str], names_out: Sequence[str] | None = None
                 ) -> CoKrigingModel:
        """This emulator's mean as a :class:`~rotoruq.model.Model`."""
        self._check_fitted()
        names_in = tuple(names_in)
        names_out = tuple(names_out) if names_out is not None else tuple(
            f"y{j}" for j in range(self._m))
        if len(names_in) != self._d or len(names_out) != self._m:
            raise ModelShapeError(f"CoKriging has {self._d} inputs and {self._m} outputs; got "
                                  f"names {names_in} and {names_out}")
        return CoKrigingModel(self, names_in, names_out)

    def __repr__(self) -> str:
        if not self._levels:
            return f"CoKriging({self.gp_options}, unfitted)"
        return f"CoKriging({len(self._levels)} levels, rho={np.round(self.rho, 4).tolist()})"


class CoKrigingModel:
    """A fitted :class:`CoKriging` as a Model: ``names_in``, ``names_out``, ``__call__``."""

    def __init__(self, ck: CoKriging, names_in: tuple[str, ...], names_out: tuple[str, ...]):
        self.emulator = ck
        self.names_in = names_in
        self.names_out = names_out

    def __call__(self, x) -> np.ndarray:
        return self.emulator.predict(x, return_var=False)
