"""Chains to files other tools read: a documented ``.npz`` and an arviz-compatible netCDF.

The netCDF file has the layout of arviz's ``InferenceData.to_netcdf`` (one netCDF4/HDF5 group
per InferenceData group), so ``arviz.from_netcdf(path)`` opens it without rotoruq:

* group ``posterior``: one variable per parameter, dims ``(chain, draw)``, coordinates
  ``chain = 0..n_chains-1`` and ``draw = 0..n_draws-1``;
* group ``sample_stats``: ``lp`` (log posterior, natural log, dims ``(chain, draw)``), when
  given.

The ``.npz`` archive (NumPy, no other dependency) holds

``format``
    the string ``"rotoruq-chains-1"``;
``names`` (d,)
    parameter names (unicode);
``chains`` (n_chains, n_draws, d)
    the draws, in the parameters' own units;
``log_posterior`` (n_chains, n_draws)
    when given.

For arviz: ``az.from_dict(posterior={n: f["chains"][..., i] for i, n in enumerate(names)},
sample_stats={"lp": f["log_posterior"]})`` or, equivalently, ``az.from_dict(**to_arviz_dict(
*read_chains(path)))``.

The functions take plain arrays, not a :class:`~rotoruq.methods.mcmc.BayesResult`, so any
sampler's output can be written.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...errors import ParameterError

__all__ = ["FORMAT", "ExportedChains", "write_chains", "read_chains", "to_arviz_dict"]

#: value of the ``format`` entry of an exported ``.npz`` (and netCDF attribute)
FORMAT = "rotoruq-chains-1"

Attr = str | int | float


@dataclass(frozen=True, eq=False)
class ExportedChains:
    """Chains read back from a file.

    names : parameter names (d,). chains : draws (n_chains, n_draws, d), parameter units.
    log_posterior : (n_chains, n_draws) natural-log posterior density, or None.
    attrs : provenance stored with the chains (sampler, seed, ...).
    """

    names: tuple[str, ...]
    chains: np.ndarray
    log_posterior: np.ndarray | None
    attrs: dict[str, Attr]


def _check(chains, names, log_posterior) -> tuple[np.ndarray, tuple[str, ...], np.ndarray | None]:
    x = np.asarray(chains, dtype=float)
    if x.ndim != 3 or 0 in x.shape:
        raise ParameterError(
            f"chains must be a non-empty array (n_chains, n_draws, n_parameters); got shape "
            f"{x.shape}")
    nm = tuple(str(n) for n in names)
    if len(nm) != x.shape[2]:
        raise ParameterError(
            f"names must give one name per parameter: chains have {x.shape[2]}, got {len(nm)} "
            f"names {nm}")
    if len(set(nm)) != len(nm) or any(not n or "/" in n for n in nm):
        raise ParameterError(
            f"names must be distinct, non-empty and without '/' (netCDF variable names); got "
            f"{nm}")
    lp = None
    if log_posterior is not None:
        lp = np.asarray(log_posterior, dtype=float)
        if lp.shape != x.shape[:2]:
            raise ParameterError(
                f"log_posterior must have shape (n_chains, n_draws) = {x.shape[:2]}; got "
                f"{lp.shape}")
    return x, nm, lp


def _check_attrs(attrs: Mapping[str, Attr] | None) -> dict[str, Attr]:
    out: dict[str, Attr] = {}
    for k, v in (attrs or {}).items():
        if isinstance(v, bool) or not isinstance(v, str | int | float | np.integer | np.floating):
            raise ParameterError(
                f"attrs values must be strings or numbers; {k!r} is {type(v).__name__}")
        out[str(k)] = v.item() if isinstance(v, np.generic) else v
    return out


def write_chains(
    path: str | Path,
    chains: np.ndarray,
    names: Sequence[str],
    log_posterior: np.ndarray | None = None,
    *,
    attrs: Mapping[str, Attr] | None = None,
) -> Path:
    """Write MCMC chains as netCDF (``*.nc``, arviz ``InferenceData`` layout) or ``.npz``.

    Parameters
    ----------
    path : str or Path
        Target file. A ``.nc`` suffix writes netCDF (needs ``xarray`` and ``h5netcdf``, both
        installed with arviz); any other suffix is replaced by ``.npz``.
    chains : ndarray, shape (n_chains, n_draws, d)
        Draws in the parameters' own units.
    names : sequence of str, length d
        Parameter names: distinct, non-empty, without ``/``.
    log_posterior : ndarray, shape (n_chains, n_draws), optional
        Natural-log posterior density of each draw (``sample_stats/lp`` in netCDF).
    attrs : mapping of str to str or number, optional
        Provenance (sampler, seed, study, ...) stored as file attributes.

    Returns
    -------
    Path
        The file written (the suffix may have been changed to ``.npz``).

    Raises
    ------
    ParameterError
        Shapes or names that do not fit; a ``.nc`` path without xarray/h5netcdf installed.

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> x = np.random.default_rng(0).normal(size=(2, 50, 2))
    >>> p = write_chains(pathlib.Path(tempfile.mkdtemp()) / "post", x, ["a", "b"])
    >>> p.suffix, read_chains(p).chains.shape
    ('.npz', (2, 50, 2))
    """
    x, nm, lp = _check(chains, names, log_posterior)
    meta = _check_attrs(attrs)
    path = Path(path)
    if path.suffix.lower() == ".nc":
        _write_netcdf(path, x, nm, lp, meta)
        return path
    if path.suffix.lower() != ".npz":
        path = path.with_suffix(".npz")
    arrays: dict[str, np.ndarray] = {"format": np.array(FORMAT), "names": np.array(nm),
                                     "chains": x}
    if lp is not None:
        arrays["log_posterior"] = lp
    for k, v in meta.items():
        arrays[f"attr.{k}"] = np.array(v)
    np.savez(path, **arrays)  # type: ignore[arg-type]
    return path


def _missing_netcdf(modules: Sequence[str]) -> None:
    import importlib.util

    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        raise ParameterError(
            f"writing or reading netCDF (.nc) needs xarray and h5netcdf (pip install arviz "
            f"brings both; missing: {', '.join(missing)}); use a .npz path instead")


def _xarray():
    _missing_netcdf(("xarray", "h5netcdf", "h5py"))
    import xarray as xr

    return xr


def _write_netcdf(path: Path, x, names, lp, meta) -> None:
    """The groups xarray's ``to_netcdf(engine="h5netcdf")`` writes, through h5netcdf
    alone: importing xarray (and pandas) cost a study's process more than a second, writing
    the file a tenth of that."""
    _missing_netcdf(("xarray", "h5netcdf", "h5py"))
    import h5netcdf

    c, n, _ = x.shape
    attrs = {"created_by": "rotoruq", "format": FORMAT, **meta}
    groups = {"posterior": {nm: x[:, :, i] for i, nm in enumerate(names)}}
    if lp is not None:
        groups["sample_stats"] = {"lp": lp}
    with h5netcdf.File(path, "w") as f:
        for group, variables in groups.items():
            g = f.create_group(group)
            g.dimensions = {"chain": c, "draw": n}
            g.create_variable("chain", ("chain",), data=np.arange(c, dtype=np.int64))
            g.create_variable("draw", ("draw",), data=np.arange(n, dtype=np.int64))
            for nm, values in variables.items():
                v = g.create_variable(nm, ("chain", "draw"), dtype=np.float64,
                                      fillvalue=np.nan)
                v[...] = np.ascontiguousarray(values, dtype=np.float64)
            for k, val in attrs.items():
                g.attrs[k] = val


def read_chains(path: str | Path) -> ExportedChains:
    """Read chains written by :func:`write_chains` (``.npz`` or ``.nc``).

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    ExportedChains
        Names, chains (n_chains, n_draws, d), log posterior (or None) and attributes.

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> x = np.arange(24.0).reshape(2, 4, 3)
    >>> p = write_chains(pathlib.Path(tempfile.mkdtemp()) / "c.npz", x, "uvw", attrs={"seed": 1})
    >>> r = read_chains(p)
    >>> r.names, bool(np.array_equal(r.chains, x)), r.attrs
    (('u', 'v', 'w'), True, {'seed': 1})
    """
    path = Path(path)
    if path.suffix.lower() == ".nc":
        xr = _xarray()
        with xr.open_dataset(path, group="posterior", engine="h5netcdf") as post:
            names = tuple(str(v) for v in post.data_vars)
            x = np.stack([post[v].transpose("chain", "draw").values for v in names], axis=-1)
            attrs = {k: (v.item() if isinstance(v, np.generic) else v)
                     for k, v in post.attrs.items() if k not in ("created_by", "format")}
        lp = None
        try:
            with xr.open_dataset(path, group="sample_stats", engine="h5netcdf") as st:
                lp = st["lp"].transpose("chain", "draw").values
        except OSError:
            pass  # no sample_stats group: written without a log posterior
        return ExportedChains(names=names, chains=x, log_posterior=lp, attrs=attrs)
    with np.load(path, allow_pickle=False) as f:
        if "format" not in f.files or str(f["format"]) != FORMAT:
            raise ParameterError(
                f"{path}: expected an archive written by rotoruq's write_chains (format "
                f"{FORMAT!r}); found entries {f.files}")
        attrs = {k[5:]: f[k].item() for k in f.files if k.startswith("attr.")}
        return ExportedChains(
            names=tuple(str(s) for s in f["names"]), chains=f["chains"],
            log_posterior=f["log_posterior"] if "log_posterior" in f.files else None,
            attrs=attrs)


def to_arviz_dict(chains: ExportedChains) -> dict[str, dict[str, np.ndarray]]:
    """Keyword arguments for ``arviz.from_dict``: ``posterior`` and, with lp, ``sample_stats``.

    Parameters
    ----------
    chains : ExportedChains
        As returned by :func:`read_chains`.

    Returns
    -------
    dict
        ``{"posterior": {name: (n_chains, n_draws)}, "sample_stats": {"lp": ...}}``.

    Examples
    --------
    >>> import numpy as np
    >>> e = ExportedChains(("a",), np.zeros((2, 3, 1)), None, {})
    >>> {k: {n: a.shape for n, a in v.items()} for k, v in to_arviz_dict(e).items()}
    {'posterior': {'a': (2, 3)}}
    """
    out = {"posterior": {n: chains.chains[:, :, i] for i, n in enumerate(chains.names)}}
    if chains.log_posterior is not None:
        out["sample_stats"] = {"lp": chains.log_posterior}
    return out
