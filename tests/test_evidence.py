import numpy as np
import pytest

import rotoruq as rq
from rotoruq.errors import ParameterError
from rotoruq.methods.evidence import evidence


def space():
    return rq.ParameterSpace(
        {
            "a": rq.Interval([(0.0, 1.0), (1.0, 3.0)], [0.4, 0.6]),
            "b": rq.Interval([(-1.0, 1.0), (0.5, 2.0)], [0.5, 0.5]),
        }
    )


def test_monotone_model_belief_and_plausibility_are_exact():
    # g = a + b is monotone: cell ranges are [lo_a + lo_b, hi_a + hi_b], found at corners
    model = rq.FunctionModel(lambda x: x[:, 0] + x[:, 1], ["a", "b"], ["g"])
    res = evidence(model, space(), response_levels=[0.0, 1.5, 2.5, 5.0], optimizer="sampling",
                   n_samples=20, seed=1)
    np.testing.assert_allclose(np.sort(res.cell_min[:, 0]), [-1.0, 0.0, 0.5, 1.5])
    np.testing.assert_allclose(np.sort(res.cell_max[:, 0]), [2.0, 3.0, 4.0, 5.0])
    # cells: (a1,b1) [-1,2] .2, (a1,b2) [.5,3] .2, (a2,b1) [0,4] .3, (a2,b2) [1.5,5] .3
    np.testing.assert_allclose(res.cpf["g"], [0.5, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(res.cbf["g"], [0.0, 0.0, 0.2, 1.0])
    assert np.all(res.cbf["g"] <= res.cpf["g"])
    np.testing.assert_allclose(res.ccbf["g"] + res.cpf["g"], 1.0)
    assert res.cell_bpa.sum() == pytest.approx(1.0)


def test_interior_extremum_found_by_optimization():
    # minimum of (a - 0.37)^2 inside the first a-interval; sampling alone misses exact 0
    model = rq.FunctionModel(lambda x: (x[:, 0] - 0.37) ** 2 + 0 * x[:, 1], ["a", "b"], ["g"])
    res = evidence(model, space(), optimizer="sampling", n_samples=5, optimize=True, seed=2)
    assert res.cell_min[:, 0].min() == pytest.approx(0.0, abs=1e-8)
    assert res.cell_max[:, 0].max() == pytest.approx((3 - 0.37) ** 2)


def test_bad_input():
    model = rq.FunctionModel(lambda x: x[:, 0], ["a"], ["g"])
    with pytest.raises(ParameterError, match="Interval inputs"):
        evidence(model, rq.ParameterSpace({"a": rq.Normal(0, 1)}))
    with pytest.raises(ParameterError, match="sum to 1"):
        rq.Interval([(0, 1), (1, 2)], [0.5, 0.6])
    with pytest.raises(ParameterError, match="lower < upper"):
        rq.Interval([(1, 0)])


def test_non_monotone_default_matches_brute_force_grid_per_cell():
    # interior extrema in most cells; the default (optimize=True) must find every cell's range
    def f(x):
        return np.sin(3.0 * x[:, 0]) * np.cos(2.0 * x[:, 1]) + 0.3 * x[:, 0] * x[:, 1]

    model = rq.FunctionModel(f, ["a", "b"], ["g"])
    sp = space()
    res = evidence(model, sp, response_levels=[-0.5, 0.0, 0.5], optimizer="sampling", seed=3)
    for c in range(res.cell_bpa.size):
        a = np.linspace(res.cells_lower[c, 0], res.cells_upper[c, 0], 801)
        b = np.linspace(res.cells_lower[c, 1], res.cells_upper[c, 1], 801)
        g = f(np.array(np.meshgrid(a, b)).reshape(2, -1).T)
        # the grid is itself an inner approximation (spacing <= 2.5e-3: error <= 1e-4 here)
        assert res.cell_min[c, 0] <= g.min() + 1e-9
        assert res.cell_max[c, 0] >= g.max() - 1e-9
        assert res.cell_min[c, 0] == pytest.approx(g.min(), abs=1e-4)
        assert res.cell_max[c, 0] == pytest.approx(g.max(), abs=1e-4)
    bel, pl = res.belief_plausibility("g", [-0.5, 0.0, 0.5])
    np.testing.assert_allclose(res.cbf["g"], bel)
    np.testing.assert_allclose(res.cpf["g"], pl)
    # sampling alone (no optimization) misses interior extrema on this function
    coarse = evidence(model, sp, optimizer="sampling", n_samples=5, optimize=False, seed=3)
    assert np.any(coarse.cell_min[:, 0] > res.cell_min[:, 0] + 1e-3)


def _sin_extremes(lo, hi, w, ph):
    """Closed-form min and max of sin(w t + ph) on [lo, hi]: the ends and the interior
    stationary points w t + ph = pi/2 + k pi."""
    ks = np.arange(np.floor((w * lo + ph) / np.pi) - 1, np.ceil((w * hi + ph) / np.pi) + 2)
    t = (np.pi / 2 + ks * np.pi - ph) / w
    v = np.sin(w * np.r_[lo, hi, t[(t > lo) & (t < hi)]] + ph)
    return v.min(), v.max()


def _separable():
    def f(x):
        return np.column_stack([np.sin(3.0 * x[:, 0]) + 0.5 * np.cos(2.0 * x[:, 1]),
                                np.sin(2.0 * x[:, 0] + 1.0) * 0.0 + np.cos(4.0 * x[:, 1])])

    def exact(lo, hi):
        a, b = _sin_extremes(lo[0], hi[0], 3.0, 0.0), _sin_extremes(lo[1], hi[1], 2.0, np.pi / 2)
        c = _sin_extremes(lo[1], hi[1], 4.0, np.pi / 2)
        return np.array([[a[0] + 0.5 * b[0], c[0]], [a[1] + 0.5 * b[1], c[1]]])

    return rq.FunctionModel(f, ["a", "b"], ["g", "h"]), exact


def test_ego_finds_closed_form_cell_extremes_of_non_monotone_responses():
    seed = 0
    # interior maxima and minima in most of the 4 cells, two responses sharing evaluations;
    # tolerance 1e-4 of the response range: the extremes must be exact to 1e-4 absolute
    model, exact = _separable()
    res = evidence(model, space(), response_levels=[0.0], tolerance=1e-4, seed=seed)
    assert res.optimizer == "ego" and res.converged
    for c in range(4):
        ex = exact(res.cells_lower[c], res.cells_upper[c])
        np.testing.assert_allclose(res.cell_min[c], ex[0], atol=1e-4)
        np.testing.assert_allclose(res.cell_max[c], ex[1], atol=1e-4)
        assert np.all(res.cell_min[c] >= ex[0] - 1e-12)  # model values: never beyond the truth
    # bound: 4 cells x 2 responses x (min, max) = 16 extremes; the sampling method spends
    # thousands of evaluations on this, EGO well under 15 per response extreme pair per cell
    assert res.n_evaluations <= 120


def test_ego_monotone_corners_exact_and_seeded():
    model = rq.FunctionModel(lambda x: x[:, 0] + x[:, 1], ["a", "b"], ["g"])
    res = evidence(model, space(), response_levels=[0.0, 1.5, 2.5, 5.0], seed=1)
    np.testing.assert_allclose(np.sort(res.cell_min[:, 0]), [-1.0, 0.0, 0.5, 1.5], atol=1e-9)
    np.testing.assert_allclose(np.sort(res.cell_max[:, 0]), [2.0, 3.0, 4.0, 5.0], atol=1e-9)
    np.testing.assert_allclose(res.cpf["g"], [0.5, 1.0, 1.0, 1.0])
    np.testing.assert_allclose(res.cbf["g"], [0.0, 0.0, 0.2, 1.0])
    again = evidence(model, space(), response_levels=[0.0, 1.5, 2.5, 5.0], seed=1)
    assert again.n_evaluations == res.n_evaluations
    assert np.array_equal(again.cell_min, res.cell_min)


def test_ego_budget_warns_and_bad_method():
    model, _ = _separable()
    with pytest.warns(RuntimeWarning, match="max_evaluations"):
        res = evidence(model, space(), max_evaluations=10, seed=0)
    assert not res.converged and res.n_evaluations <= 10
    with pytest.raises(ParameterError, match="'ego' or 'sampling'"):
        evidence(model, space(), optimizer="lhs")


def test_ego_within_twice_dakotas_evaluations_on_one_response():
    # g = sin(3a) + 0.5 cos(2b) on the 4 cells: Dakota 6.24's global_evidence ego (seed 1)
    # found the cell extremes to 3e-5 with 53 evaluations; issue 24 asks for <= 2x that
    model = rq.FunctionModel(lambda x: np.sin(3.0 * x[:, 0]) + 0.5 * np.cos(2.0 * x[:, 1]),
                             ["a", "b"], ["g"])
    res = evidence(model, space(), seed=5)
    assert res.converged and res.n_evaluations <= 2 * 53
    for c in range(4):
        lo, hi = res.cells_lower[c], res.cells_upper[c]
        a, b = _sin_extremes(lo[0], hi[0], 3.0, 0.0), _sin_extremes(lo[1], hi[1], 2.0, np.pi / 2)
        assert res.cell_min[c, 0] == pytest.approx(a[0] + 0.5 * b[0], abs=1e-4)
        assert res.cell_max[c, 0] == pytest.approx(a[1] + 0.5 * b[1], abs=1e-4)
