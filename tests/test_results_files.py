"""The files a saved step leaves for users: every array with named columns as CSV beside the
.npy, values exact (shortest form that reads back to the same float)."""

from __future__ import annotations

import numpy as np

from rotoruq.results import StepResult, load_step, save_step


def test_csv_copies_read_back_bitwise(tmp_path):
    rng = np.random.default_rng(3)
    chain = rng.normal(size=(20_000, 3)) * np.array([1e-12, 1.0, 3e7])
    chain[5, 1], chain[6, 2], chain[7, 0] = np.nan, np.inf, -0.0
    counts = np.arange(12).reshape(4, 3)
    res = StepResult("bayes", "bayes_calibration", {"ess/a": 12.5},
                     arrays={"chain": chain, "counts": counts, "flat": np.ones(4)},
                     meta={"columns": {"chain": ["a", "b", "c"], "counts": ["x", "y", "z"]}})
    folder = save_step(res, tmp_path)
    text = (folder / "chain.csv").read_text()
    assert text.splitlines()[0] == "a,b,c"
    back = np.loadtxt(folder / "chain.csv", delimiter=",", skiprows=1)
    assert back.shape == chain.shape
    assert np.array_equal(back, chain, equal_nan=True)
    assert np.array_equal(np.signbit(back), np.signbit(chain))
    assert np.array_equal(np.loadtxt(folder / "counts.csv", delimiter=",", skiprows=1), counts)
    assert not (folder / "flat.csv").exists()  # no column names, no CSV
    loaded = load_step(folder)
    assert np.array_equal(loaded.arrays["chain"], chain, equal_nan=True)
    assert not [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]
