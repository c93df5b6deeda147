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

As the emulator of :func:`~rotoruq.methods.mcmc.calibrate_bayes`, a CoKriging names its
cheaper models (``low_fidelity``) and their design sizes (``n_low``); the calibration builds
the nested design and fits it (:func:`rotoruq.methods.mcmc._emulator.fit_on_prior`).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from scipy import optimize

from .._rng import SeedLike, as_seed_sequence
from ..errors import ModelShapeError, ParameterError
from ._common import names_or_default
from .surrogate import ExtrapolationWarning, GaussianProcess, LeaveOneOut

__all__ = ["CoKriging", "CoKrigingModel"]


class CoKriging:
    """Recursive autoregressive co-kriging emulator (module doc).

    Parameters
    ----------
    gp_options : keyword arguments of every level's
        :class:`~rotoruq.methods.surrogate.GaussianProcess` (trend, kernel, nugget,
        n_restarts...); ``seed`` is set here.
    low_fidelity : a Model or a sequence of Models, the cheapest first, for
        :func:`~rotoruq.methods.mcmc.calibrate_bayes` to build this emulator from (their
        inputs those of the calibrated model, their responses including the observed ones,
        by name). Not needed for :meth:`fit` on your own runs.
    n_low : runs of each low-fidelity model in the calibration's nested design: an int for
        all, or one per model (cheapest first, non-increasing). Each must be at least the
        high-fidelity design (``n_emulator_samples``), whose points every cheaper design
        holds. None: four times the high-fidelity design.
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
                 low_fidelity: Any = None, n_low: int | Sequence[int] | None = None,
                 seed: SeedLike = None) -> None:
        self.gp_options = dict(gp_options or {})
        if "seed" in self.gp_options:
            raise ParameterError("give the seed to CoKriging(seed=...), not in gp_options")
        GaussianProcess(**self.gp_options)  # checks the options now, not at fit
        self.low_fidelity = _as_models(low_fidelity)
        self.n_low = _as_n_low(n_low, len(self.low_fidelity))
        self.seed = seed
        self._levels: list[list[GaussianProcess]] = []
        self._rho: np.ndarray | None = None
        self._data: list[tuple[np.ndarray, np.ndarray]] = []

    def design_sizes(self, n_high: int) -> tuple[int, ...]:
        """Runs of each low-fidelity model (cheapest first) in a nested design around
        ``n_high`` high-fidelity points: ``n_low``, or four times ``n_high``.

        Parameters
        ----------
        n_high : int
            Runs of the high-fidelity model (``n_emulator_samples``).

        Examples
        --------
        >>> from rotoruq.model import FunctionModel
        >>> lf = FunctionModel(lambda x: 0.5 * x, ["a"], ["y"])
        >>> CoKriging(low_fidelity=[lf, lf], n_low=[60, 20]).design_sizes(10)
        (60, 20)
        >>> CoKriging(low_fidelity=lf).design_sizes(10)
        (40,)
        """
        if not self.low_fidelity:
            raise ParameterError("CoKriging has no low-fidelity model: give "
                                 "CoKriging(low_fidelity=model_lf, n_low=...)")
        sizes = self.n_low or (4 * int(n_high),) * len(self.low_fidelity)
        if min(sizes) < n_high:
            raise ParameterError(f"n_low={list(sizes)} is smaller than the high-fidelity "
                                 f"design ({n_high} runs, n_emulator_samples): the co-kriging "
                                 "design is nested, every cheaper design holds the "
                                 "high-fidelity points")
        return sizes

    # --- fitting ---------------------------------------------------------------------------
    def fit(self, X: Sequence[Any], Y: Sequence[Any]) -> CoKriging:
        """Fit on the points of each level, the cheapest first and the truth last.

        Nested designs (every level's points among the previous level's) make the recursive
        model exact; each level needs at least 3 points.

        Parameters
        ----------
        X : sequence of array_like of shape (n_t, d)
            The L >= 2 levels' input points, cheapest first, input units.
        Y : sequence of array_like of shape (n_t,) or (n_t, m)
            Each level's responses at its points, response units.

        Returns
        -------
        CoKriging
            This emulator, fitted.
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
        self._data = list(zip(Xs, Ys, strict=True))
        return self

    @property
    def training_data(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Each level's (X (n_t, d), Y (n_t, m)) as fitted, the cheapest first (copies)."""
        self._check_fitted()
        return [(x.copy(), y.copy()) for x, y in self._data]

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
        """Number of inputs d."""
        self._check_fitted()
        return self._d

    @property
    def n_outputs(self) -> int:
        """Number of responses m."""
        self._check_fitted()
        return self._m

    def _check_fitted(self) -> None:
        if not self._levels:
            raise ParameterError("CoKriging is not fitted: call fit([X_lf, X_hf], [Y_lf, Y_hf])")

    @staticmethod
    def _predict_levels(levels, rho, X, return_var: bool, return_grad: bool = False):
        mean = var = grad = None
        for t, gps in enumerate(levels):
            out = [gp.predict(X, return_var=return_var, return_grad=return_grad,
                              warn_distance=None) for gp in gps]
            if not (return_var or return_grad):
                out = [(o,) for o in out]
            mu = np.column_stack([o[0] for o in out])
            v = np.column_stack([o[1] for o in out]) if return_var else None
            g = np.concatenate([o[-1] for o in out], axis=1) if return_grad else None
            if t == 0:
                mean, var, grad = mu, v, g
            else:
                mean = rho[t - 1] * mean + mu
                if return_var:
                    var = rho[t - 1] ** 2 * var + v
                if return_grad:
                    grad = rho[t - 1][None, :, None] * grad + g
        return mean, var, grad

    def predict(self, X, return_var: bool = True, return_grad: bool = False,
                warn_distance: float | None = None):
        """Predict the highest-fidelity response at points X (n, d).

        Returns ``mean`` (n, m), then ``var`` (n, m) (the recursive posterior variance,
        without the uncertainty of rho) when ``return_var``, then ``grad`` (n, m, d) (d mean /
        d x) when ``return_grad``, like
        :meth:`~rotoruq.methods.surrogate.GaussianProcess.predict`; warns
        :class:`~rotoruq.methods.surrogate.ExtrapolationWarning` for points farther than
        ``warn_distance`` box-widths outside the high-fidelity runs' box (None: no check).

        Parameters
        ----------
        X : array_like of shape (n, d) or (d,)
            Points, in input units.
        return_var : bool, optional
            Also return the variance (default True).
        return_grad : bool, optional
            Also return the gradient of the mean (default False).
        warn_distance : float or None, optional
            Distance in box-widths beyond which to warn (default None: no check).
        """
        self._check_fitted()
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if X.shape[1] != self._d:
            raise ModelShapeError(f"CoKriging trained on {self._d} inputs, got points of "
                                  f"shape {X.shape}")
        if warn_distance is not None:
            dist = self.extrapolation_distance(X)
            if dist.size and dist.max() > warn_distance:
                warnings.warn(f"CoKriging asked to extrapolate: {int((dist > warn_distance).sum())}"
                              f" point(s) outside the high-fidelity runs' box, the farthest at "
                              f"{dist.max():.3g} box-widths", ExtrapolationWarning, stacklevel=2)
        mean, var, grad = self._predict_levels(self._levels, self._rho, X, return_var,
                                               return_grad)
        out = [mean] + ([var] if return_var else []) + ([grad] if return_grad else [])
        return out[0] if len(out) == 1 else tuple(out)

    # the emulator interface of calibrate_bayes: compiled per-level GPs, no checks
    def _mean_fast(self, X: np.ndarray) -> np.ndarray:
        """Mean, X (k, d) -> (k, m), through each level's compiled GP means."""
        mean = None
        for t, gps in enumerate(self._levels):
            mu = np.hstack([gp._mean_fast(X) for gp in gps])
            mean = mu if t == 0 else cast(np.ndarray, self._rho)[t - 1] * mean + mu
        return cast(np.ndarray, mean)

    def _mean_var_fast(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean and recursive variance, X (k, d) -> (k, m), (k, m), compiled per level."""
        mean = var = None
        rho = cast(np.ndarray, self._rho)
        for t, gps in enumerate(self._levels):
            mv = [gp._mean_var_fast(X) for gp in gps]
            mu, v = np.hstack([a for a, _ in mv]), np.hstack([b for _, b in mv])
            if t == 0:
                mean, var = mu, v
            else:
                mean, var = rho[t - 1] * mean + mu, rho[t - 1] ** 2 * var + v
        return cast(np.ndarray, mean), cast(np.ndarray, var)

    @property
    def bounds(self) -> np.ndarray:
        """Box of the high-fidelity runs (the level known least widely), shape (d, 2)."""
        self._check_fitted()
        return self._levels[-1][0].bounds

    def extrapolation_distance(self, X) -> np.ndarray:
        """Euclidean distance (n,) of points outside :attr:`bounds`, in box-widths: the
        high-fidelity level's :meth:`GaussianProcess.extrapolation_distance
        <rotoruq.methods.surrogate.GaussianProcess.extrapolation_distance>` (0 inside).

        Parameters
        ----------
        X : array_like of shape (n, d) or (d,)
            Points, in input units.
        """
        self._check_fitted()
        return self._levels[-1][0].extrapolation_distance(X)

    def loo(self) -> LeaveOneOut:
        """Leave-one-out errors at the high-fidelity runs, the levels below held fixed: the
        top level's discrepancy GP's closed-form LOO (Dubrule 1983). With nested designs
        the levels below interpolate their runs at these points, so this is the error of
        predicting a high-fidelity run from the others and all cheaper runs."""
        self._check_fitted()
        y = self._data[-1][1]
        errs = np.column_stack([gp.loo().errors[:, 0] for gp in self._levels[-1]])
        rmse = np.sqrt((errs**2).mean(0))
        ystd = y.std(0)
        q2 = 1.0 - (errs**2).sum(0) / ((y - y.mean(0)) ** 2).sum(0).clip(1e-300)
        return LeaveOneOut(errors=errs, rmse=rmse, nrmse=rmse / np.where(ystd > 0, ystd, 1.0),
                           q2=q2)

    def as_model(self, names_in: Sequence[str], names_out: Sequence[str] | None = None
                 ) -> CoKrigingModel:
        """This emulator's mean as a :class:`~rotoruq.model.Model`.

        Parameters
        ----------
        names_in, names_out : sequence of str
            As in :meth:`GaussianProcess.as_model
            <rotoruq.methods.surrogate.GaussianProcess.as_model>`.

        See Also
        --------
        rotoruq.methods.surrogate.GaussianProcess.as_model
        """
        self._check_fitted()
        names_in = tuple(names_in)
        names_out = names_or_default(names_out, self._m, "y")
        if len(names_in) != self._d or len(names_out) != self._m:
            raise ModelShapeError(f"CoKriging has {self._d} inputs and {self._m} outputs; got "
                                  f"names {names_in} and {names_out}")
        return CoKrigingModel(self, names_in, names_out)

    def __repr__(self) -> str:
        if not self._levels:
            return f"CoKriging({self.gp_options}, unfitted)"
        return f"CoKriging({len(self._levels)} levels, rho={np.round(self.rho, 4).tolist()})"


def _as_models(low_fidelity: Any) -> tuple[Any, ...]:
    if low_fidelity is None:
        return ()
    models = (low_fidelity,) if hasattr(low_fidelity, "names_in") else tuple(low_fidelity)
    for i, mdl in enumerate(models):
        if not (hasattr(mdl, "names_in") and hasattr(mdl, "names_out") and callable(mdl)):
            raise ParameterError(f"low_fidelity[{i}] is not a Model (names_in, names_out, "
                                 f"batched __call__): {mdl!r}")
    if not models:
        raise ParameterError("low_fidelity is an empty sequence: give one or more Models")
    return models


def _as_n_low(n_low: int | Sequence[int] | None, n_models: int) -> tuple[int, ...] | None:
    if n_low is None:
        return None
    if not n_models:
        raise ParameterError("n_low is the design size of the low-fidelity models: give "
                             "low_fidelity= too")
    sizes = (int(n_low),) * n_models if isinstance(n_low, (int, np.integer)) else tuple(
        int(n) for n in n_low)
    if len(sizes) != n_models:
        raise ParameterError(f"n_low has {len(sizes)} sizes for {n_models} low-fidelity "
                             "models: give one per model (cheapest first) or one int")
    if min(sizes) < 3 or any(a < b for a, b in zip(sizes[:-1], sizes[1:], strict=True)):
        raise ParameterError(f"n_low={list(sizes)}: each at least 3, and non-increasing from "
                             "the cheapest model (nested designs)")
    return sizes


@dataclass(frozen=True, eq=False)
class CoKrigingModel:
    """A fitted :class:`CoKriging` as a Model: ``names_in``, ``names_out``, ``__call__``.

    Attributes
    ----------
    emulator : CoKriging
        The fitted emulator; the model is its mean.
    names_in, names_out : tuple of str
        The d input and m response names.
    """

    emulator: CoKriging
    names_in: tuple[str, ...]
    names_out: tuple[str, ...]

    def __call__(self, x) -> np.ndarray:
        return self.emulator.predict(x, return_var=False)
