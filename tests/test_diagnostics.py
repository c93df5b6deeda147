"""Chain diagnostics against arviz (Vehtari et al. 2021) and closed forms.

arviz computes the same estimators (rank-normalised split R-hat with folding, bulk/tail ESS,
MCSE of mean and quantiles); the issue's acceptance tolerance is 1 % on R-hat and 10 % on ESS,
which the tests use, although the hand-written code agrees with arviz to rounding.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from rotoruq.errors import ParameterError
from rotoruq.methods.mcmc.diagnostics import (
    diagnose,
    effective_sample_size,
    mcse_mean,
    mcse_quantile,
    split_rhat,
)
from rotoruq.methods.mcmc.export import FORMAT, read_chains, to_arviz_dict, write_chains


class _Arviz:
    """arviz, imported by the first test that uses it (~4 CPU-s: every pytest worker collects
    this file, one runs these tests)."""

    def __getattr__(self, name):
        if name.startswith("_"):
            # pytest's collection asks every module attribute for its own markers
            # (``__test__``, ``_pytestfixturefunction``...): not arviz's to answer (importing it
            # here made every worker pay for it)
            raise AttributeError(name)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)  # arviz announces its refactor
            return getattr(pytest.importorskip("arviz"), name)


az = _Arviz()


def _ar1(rng, shape, phi, innovations):
    e = innovations(shape)
    x = np.empty(shape)
    x[:, 0] = e[:, 0]
    for i in range(1, shape[1]):
        x[:, i] = phi * x[:, i - 1] + e[:, i]
    return x


def _families():
    rng = np.random.default_rng(20210)
    gauss = _ar1(rng, (4, 1000, 3), 0.8, lambda s: rng.normal(size=s))
    heavy = _ar1(rng, (4, 1000, 3), 0.5, lambda s: rng.standard_t(1.5, size=s))
    scale = rng.normal(size=(4, 1000, 2))
    scale[0] *= 3.0  # one chain three times wider, same centre
    return {"gaussian_ar1": gauss, "student_t_1.5": heavy, "scale_mismatch": scale}


FAMILIES = _families()


def _arviz(x, **kw):
    ds = az.convert_to_dataset(x)
    return kw.pop("fn")(ds, **kw)["x"].values


@pytest.mark.parametrize("name", list(FAMILIES))
def test_rhat_and_ess_agree_with_arviz(name):
    x = FAMILIES[name]
    d = diagnose(x)
    np.testing.assert_allclose(d.rhat, _arviz(x, fn=az.rhat), rtol=0.01)
    np.testing.assert_allclose(d.rhat_bulk, _arviz(x, fn=az.rhat, method="z_scale"), rtol=0.01)
    np.testing.assert_allclose(d.rhat_folded, _arviz(x, fn=az.rhat, method="folded"),
                               rtol=0.01)
    np.testing.assert_allclose(d.ess_bulk, _arviz(x, fn=az.ess, method="bulk"), rtol=0.1)
    np.testing.assert_allclose(d.ess_tail, _arviz(x, fn=az.ess, method="tail"), rtol=0.1)
    np.testing.assert_allclose(effective_sample_size(x, kind="mean"),
                               _arviz(x, fn=az.ess, method="mean"), rtol=0.1)
    np.testing.assert_allclose(effective_sample_size(x, kind="quantile", prob=0.3),
                               _arviz(x, fn=az.ess, method="quantile", prob=0.3), rtol=0.1)


@pytest.mark.parametrize("name", list(FAMILIES))
def test_mcse_agrees_with_arviz(name):
    x = FAMILIES[name]
    d = diagnose(x)
    np.testing.assert_allclose(d.mcse_mean, _arviz(x, fn=az.mcse), rtol=0.05)
    for prob, got in ((0.05, d.mcse_q05), (0.95, d.mcse_q95)):
        np.testing.assert_allclose(got, _arviz(x, fn=az.mcse, method="quantile", prob=prob),
                                   rtol=0.05)


def test_scale_mismatch_is_flagged_where_classic_rhat_is_blind():
    x = FAMILIES["scale_mismatch"]
    assert np.all(split_rhat(x) > 1.01)
    assert np.all(split_rhat(x, kind="folded") > 1.1)
    assert np.all(split_rhat(x, kind="classic") < 1.01)  # why the folded version exists


def test_heavy_tails_do_not_inflate_ess():
    x = FAMILIES["student_t_1.5"]
    bulk = effective_sample_size(x)
    raw = effective_sample_size(x, kind="mean")
    # AR(1) with phi = 0.5 has tau = (1 + phi) / (1 - phi) = 3 for any finite-variance
    # innovation; rank-normalised ESS recovers it, 4000 / 3 = 1333, within Monte Carlo error.
    assert np.all(np.abs(bulk / (4000 / 3.0) - 1.0) < 0.35)
    assert raw.shape == bulk.shape


def test_ar1_ess_and_mcse_closed_forms():
    rng = np.random.default_rng(7)
    phi = 0.9
    x = _ar1(rng, (4, 20000, 1), phi, lambda s: rng.normal(size=s) * np.sqrt(1 - phi**2))
    expected = 80000 * (1 - phi) / (1 + phi)
    assert abs(effective_sample_size(x)[0] / expected - 1.0) < 0.15
    assert abs(mcse_mean(x)[0] / np.sqrt(1.0 / expected) - 1.0) < 0.1
    iid = rng.normal(size=(4, 2500, 1))
    # the median of n iid normals has standard error sqrt(pi / 2) / sqrt(n)
    assert abs(mcse_quantile(iid, 0.5)[0] / (np.sqrt(np.pi / 2) / 100.0) - 1.0) < 0.25


def test_single_chain_is_split_and_short_chains_are_nan():
    rng = np.random.default_rng(3)
    one = rng.normal(size=(1, 2000, 2))
    assert np.all(np.abs(split_rhat(one) - 1.0) < 0.01)
    drift = one + np.linspace(0.0, 3.0, 2000)[None, :, None]
    assert np.all(split_rhat(drift) > 1.1)
    assert np.all(np.isnan(split_rhat(one[:, :3])))
    np.testing.assert_array_equal(effective_sample_size(one[:, :3]), [3.0, 3.0])


def test_constant_parameter_has_full_ess():
    x = np.ones((2, 100, 1))
    np.testing.assert_array_equal(effective_sample_size(x), [200.0])


@pytest.mark.parametrize("bad, match", [
    (np.zeros((10, 2)), "n_chains, n_draws, n_parameters"),
    (np.zeros((0, 10, 2)), "n_chains, n_draws, n_parameters"),
])
def test_bad_shapes_raise(bad, match):
    with pytest.raises(ParameterError, match=match):
        split_rhat(bad)


def test_bad_options_raise():
    x = np.zeros((2, 10, 1))
    with pytest.raises(ParameterError, match="kind must be one of"):
        effective_sample_size(x, kind="bogus")
    with pytest.raises(ParameterError, match="kind must be one of"):
        split_rhat(x, kind="bogus")
    with pytest.raises(ParameterError, match=r"prob must be a quantile level in \(0, 1\)"):
        effective_sample_size(x, kind="quantile")
    with pytest.raises(ParameterError, match=r"prob must be a quantile level in \(0, 1\)"):
        mcse_quantile(x, 1.5)


# --- export -------------------------------------------------------------------------------


def _posterior(seed=5):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(3, 60, 2)) * [2.0, 0.5] + [14.0, 0.1]
    lp = -0.5 * (((x - [14.0, 0.1]) / [2.0, 0.5]) ** 2).sum(-1)
    return x, ("K_p", "theta_0"), lp


def test_netcdf_round_trips_through_arviz(tmp_path):
    pytest.importorskip("h5netcdf")
    pytest.importorskip("h5py")  # the netCDF backend (the minimum-versions venv lacks it)
    x, names, lp = _posterior()
    path = write_chains(tmp_path / "post.nc", x, names, lp, attrs={"sampler": "dram", "seed": 4})
    idata = az.from_netcdf(path)
    assert set(idata.groups()) == {"posterior", "sample_stats"}
    assert list(idata.posterior.data_vars) == list(names)
    for i, name in enumerate(names):
        assert idata.posterior[name].dims == ("chain", "draw")
        np.testing.assert_array_equal(idata.posterior[name].values, x[:, :, i])
    np.testing.assert_array_equal(idata.sample_stats["lp"].values, lp)
    assert idata.posterior.attrs["sampler"] == "dram"
    # arviz's own diagnostics on the file are ours on the array
    np.testing.assert_allclose([az.rhat(idata)[n].item() for n in names], split_rhat(x),
                               rtol=1e-12)
    back = read_chains(path)
    assert back.names == names and back.attrs == {"sampler": "dram", "seed": 4}
    np.testing.assert_array_equal(back.chains, x)
    np.testing.assert_array_equal(back.log_posterior, lp)


def test_netcdf_without_log_posterior(tmp_path):
    pytest.importorskip("h5netcdf")
    pytest.importorskip("h5py")  # the netCDF backend (the minimum-versions venv lacks it)
    x, names, _ = _posterior()
    path = write_chains(tmp_path / "post.nc", x, names)
    assert set(az.from_netcdf(path).groups()) == {"posterior"}
    assert read_chains(path).log_posterior is None


def test_npz_round_trips_into_arviz(tmp_path):
    x, names, lp = _posterior()
    path = write_chains(tmp_path / "post", x, names, lp, attrs={"seed": 7})
    assert path.suffix == ".npz"
    with np.load(path) as f:  # the documented layout, readable without rotoruq
        assert str(f["format"]) == FORMAT
        assert tuple(f["names"]) == names
        np.testing.assert_array_equal(f["chains"], x)
        np.testing.assert_array_equal(f["log_posterior"], lp)
    back = read_chains(path)
    idata = az.from_dict(**to_arviz_dict(back))
    np.testing.assert_array_equal(idata.posterior["theta_0"].values, x[:, :, 1])
    np.testing.assert_array_equal(idata.sample_stats["lp"].values, lp)
    np.testing.assert_allclose([az.ess(idata)[n].item() for n in names],
                               effective_sample_size(x), rtol=1e-12)
    assert back.attrs == {"seed": 7}


@pytest.mark.parametrize("kw, match", [
    (dict(chains=np.zeros((3, 2))), "n_chains, n_draws, n_parameters"),
    (dict(names=("a",)), "one name per parameter"),
    (dict(names=("a", "a")), "distinct"),
    (dict(names=("a", "b/c")), "without '/'"),
    (dict(log_posterior=np.zeros((3, 59))), r"log_posterior must have shape \(n_chains"),
    (dict(attrs={"x": [1, 2]}), "attrs values must be strings or numbers"),
])
def test_export_rejects_bad_input(tmp_path, kw, match):
    x, names, lp = _posterior()
    args = dict(chains=x, names=names, log_posterior=lp) | kw
    attrs = args.pop("attrs", None)
    with pytest.raises(ParameterError, match=match):
        write_chains(tmp_path / "p.npz", attrs=attrs, **args)


def test_reading_a_foreign_npz_names_the_format(tmp_path):
    np.savez(tmp_path / "other.npz", chains=np.zeros((1, 4, 1)))
    with pytest.raises(ParameterError, match="rotoruq-chains-1"):
        read_chains(tmp_path / "other.npz")


@pytest.mark.parametrize("shape,round_to", [((1, 1), None), ((7, 3), 0), ((4000, 9), 1),
                                             ((2500, 2), None)])
def test_average_ranks_are_scipys(shape, round_to):
    """The quicksort ranks are scipy's rankdata(method="average", axis=0), ties, infinities
    and a NaN column included."""
    from scipy import stats

    from rotoruq.methods.mcmc.diagnostics import _average_ranks

    a = np.random.default_rng(3).normal(size=shape) * 3.0
    if round_to is not None:  # ties, as a chain's rejected moves make them
        a = np.round(a, round_to)
    if a.size > 4:
        a[0, 0], a[1, 0] = np.inf, -np.inf
        a[2, -1] = np.nan
    got = _average_ranks(a)
    want = stats.rankdata(a, method="average", axis=0)
    assert np.array_equal(got, want, equal_nan=True)


@pytest.mark.parametrize("shape", [(4, 600, 3), (1, 999, 2), (2, 3, 2)])
def test_diagnose_and_ess_and_rhat_give_the_public_functions_numbers(shape):
    """diagnose and ess_and_rhat share their intermediate results: the same bits as each
    estimator on its own (chains with repeated draws, as a Metropolis chain's)."""
    from rotoruq.methods.mcmc.diagnostics import diagnose, ess_and_rhat

    x = np.random.default_rng(5).standard_normal(shape).cumsum(1)
    x[:, 1::4] = x[:, 0:-1:4][:, :x[:, 1::4].shape[1]]  # rejected moves: repeats
    dg = diagnose(x)
    one = {"rhat": split_rhat(x), "rhat_bulk": split_rhat(x, kind="bulk"),
           "rhat_folded": split_rhat(x, kind="folded"), "ess_bulk": effective_sample_size(x),
           "ess_tail": effective_sample_size(x, kind="tail"), "mcse_mean": mcse_mean(x),
           "mcse_q05": mcse_quantile(x, 0.05), "mcse_q95": mcse_quantile(x, 0.95)}
    for name, want in one.items():
        assert np.array_equal(getattr(dg, name), want, equal_nan=True), name
    ess, rhat = ess_and_rhat(x)
    assert np.array_equal(ess, one["ess_bulk"]) and np.array_equal(rhat, one["rhat"],
                                                                   equal_nan=True)
