"""The report's figures drawn with fewer artists and one layout (issue 34: figure CPU): the
same histograms, the SVG laid out as the PNG, the pair plot's lower triangle only."""

from __future__ import annotations

import io

import numpy as np

from rotoruq.params import Normal, Uniform
from rotoruq.render.figures import load_distributions, pair_plot, prior_posterior
from rotoruq.report.html import _render
from rotoruq.results import StepResult

NAMES = ["k_flap", "c_flap", "cla_1"]


def _bayes(seed: int = 3) -> StepResult:
    rng = np.random.default_rng(seed)
    chain = rng.multivariate_normal([1.0, 2.0, 0.1], [[1.0, 0.8, 0.0], [0.8, 1.0, 0.1],
                                                      [0.0, 0.1, 0.04]], size=3000)
    prior = {"k_flap": Normal(1.0, 2.0).describe(), "c_flap": Uniform(-2.0, 6.0).describe()}
    return StepResult("bayes", "bayes_calibration", {}, {"chain": chain},
                      meta={"columns": {"chain": NAMES}, "prior": prior})


def _stairs(ax):
    from matplotlib.patches import Rectangle, StepPatch

    assert not [p for p in ax.patches if isinstance(p, Rectangle)]  # no bar per bin
    return [p for p in ax.patches if isinstance(p, StepPatch)]


def test_histograms_are_one_outline_with_the_histogram_heights():
    res = _bayes()
    (fig,) = prior_posterior(res, {}, None)
    chain = res.arrays["chain"]
    for j, ax in enumerate(fig.figure.axes[:len(NAMES)]):
        (patch,) = _stairs(ax)
        values, edges, _ = patch.get_data()
        want, want_edges = np.histogram(chain[:, j], bins=40, density=True)
        np.testing.assert_array_equal(values, want)
        np.testing.assert_array_equal(edges, want_edges)
        assert abs(np.sum(values * np.diff(edges)) - 1.0) < 1e-12
        assert patch.get_fill() and patch.get_rasterized()
    # the legend still names the posterior's histogram
    legend = fig.figure.legends[0]
    assert "posterior (chain)" in [t.get_text() for t in legend.get_texts()]
    rng = np.random.default_rng(4)
    outputs = [rng.normal(size=(200, 2))]
    pp = [rng.normal(size=(300, 2)) * 1.5]
    (loads,) = load_distributions("cal", ["thrust", "power"], [""], outputs, pp)
    for k in range(2):
        ax = loads.figure.axes[k]  # the PDF row
        patches = _stairs(ax)
        assert len(patches) == 2  # independent normals and the joint predictive
        for patch, v in zip(patches, (outputs[0][:, k], pp[0][:, k]), strict=True):
            np.testing.assert_array_equal(patch.get_data()[0],
                                          np.histogram(v, bins=30, density=True)[0])
            assert patch.get_alpha() == 0.3


def test_the_svg_is_laid_out_as_the_png():
    """The SVG keeps the layout the PNG's drawing computed: the axes sit where a figure laid
    out for the SVG alone puts them (to 0.2 % of the figure), and the file is whole."""
    res = _bayes()
    (drawn,) = _render(prior_posterior(res, {}, None))
    assert drawn.png[:8] == b"\x89PNG\r\n\x1a\n" and drawn.svg.rstrip().endswith(b"</svg>")
    (alone,) = prior_posterior(res, {}, None)
    alone.figure.savefig(io.BytesIO(), format="svg")  # its own constrained layout
    (again,) = prior_posterior(res, {}, None)
    _render([again])
    for a, b in zip(alone.figure.axes, again.figure.axes, strict=True):
        np.testing.assert_allclose(a.get_position().bounds, b.get_position().bounds,
                                   atol=2e-3)
    # laid out: the axes were moved from matplotlib's default subplot grid
    (raw,) = prior_posterior(res, {}, None)
    assert not np.allclose(raw.figure.axes[0].get_position().bounds,
                           again.figure.axes[0].get_position().bounds, atol=1e-3)
    assert drawn.xlabels == tuple(sorted(f"{n} [" + u for n, u in (
        ("c_flap", "N m s/rad]"), ("cla_1", "1/deg]"), ("k_flap", "N m/rad]"))))


def test_the_pair_plot_makes_only_the_lower_triangle():
    res = _bayes()
    (fig,) = pair_plot(res, {}, None)
    d = len(NAMES)
    axes = fig.figure.axes
    assert len(axes) == d * (d + 1) // 2 and all(ax.get_visible() for ax in axes)
    chain = res.arrays["chain"]
    corr = np.corrcoef(chain, rowvar=False)
    k = 0
    for i in range(d):
        for j in range(i + 1):
            ax = axes[k]
            k += 1
            spec = ax.get_subplotspec()
            assert (spec.rowspan.start, spec.colspan.start) == (i, j)
            if i == j:
                (patch,) = _stairs(ax)
                np.testing.assert_array_equal(patch.get_data()[0],
                                              np.histogram(chain[:, i], bins=30)[0])
            else:
                (text,) = ax.texts
                assert text.get_text() == f"{corr[i, j]:+.2f}"
                assert text.get_color() == ("C3" if abs(corr[i, j]) > 0.7 else "k")
            if i == d - 1:
                assert ax.get_xlabel().startswith(NAMES[j])
            if j == 0 and i > 0:
                assert ax.get_ylabel().startswith(NAMES[i])
    assert axes[0].get_ylabel() == "count [-]"
    (drawn,) = _render([fig])
    assert drawn.png[:8] == b"\x89PNG\r\n\x1a\n"
