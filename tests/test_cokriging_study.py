"""A ``bayes_calibration`` step with ``emulator = "cokriging"``: the study's rotor learnt from
a few of its runs and many of a coarse-grid copy (``[models.coarse]``), through the CLI, its
posterior against the exact one (quadrature on the rotor itself); each bad co-kriging option
names its line."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from _inproc import rotoruq
from rotoruq.errors import InputFileError
from rotoruq.results import load_step
from rotoruq.rotor.model import RotorModel
from rotoruq.study.schema import load_study

FIXED = {"height_over_radius": 4.0}
TRUTH, NOISE, N_OBS = 5.6, 0.4, 4


def study_text(step: str) -> str:
    fine = RotorModel("gvpm", names_in=["collective_deg"], names_out=["thrust"], fixed=FIXED)
    y = fine(np.array([[TRUTH]]))[0, 0]
    obs = (y + NOISE * np.random.default_rng(3).standard_normal(N_OBS)).round(4)
    return textwrap.dedent(f"""\
        [study]
        name = "ck"
        seed = 7

        [model]
        preset = "gvpm"
        responses = ["thrust"]
        fixed = {{ height_over_radius = 4.0 }}

        [models.coarse]
        preset = "gvpm"
        discretization = {{ n_stations = 3, n_azimuth = 6 }}

        [parameters.collective_deg]
        distribution = "uniform"
        lower = 4.5
        upper = 6.5

        [data.obs]
        thrust = {obs.tolist()}
        """) + textwrap.dedent(step)


STEP = """
[[steps]]
name = "bayes"
type = "bayes_calibration"
emulator = "cokriging"
models = ["coarse"]
n_emulator_samples = 5
n_low = 30
noise_std = { thrust = 0.4 }
n_samples = 3000
burn_in = 300
"""


def exact_posterior(obs: np.ndarray) -> tuple[float, float]:
    """Mean and std of the collective given the data, on a 2001-point grid of the fine rotor
    (uniform prior, Gaussian noise)."""
    grid = np.linspace(4.5, 6.5, 2001)
    fine = RotorModel("gvpm", names_in=["collective_deg"], names_out=["thrust"], fixed=FIXED)
    y = fine(grid[:, None])[:, 0]
    logp = -0.5 * np.sum((obs[None, :] - y[:, None]) ** 2, axis=1) / NOISE**2
    w = np.exp(logp - logp.max())
    w /= w.sum()
    mean = float(w @ grid)
    return mean, float(np.sqrt(w @ (grid - mean) ** 2))


def test_cokriging_calibration_step_through_the_cli(tmp_path):
    study = tmp_path / "ck.toml"
    study.write_text(study_text(STEP))
    out = tmp_path / "out"
    # through the CLI's entry point in this process (tests/_inproc.py: a fresh interpreter
    # adds ~2 CPU-s per command and nothing checked here)
    done = rotoruq("run", study, "--out", out, "--no-report", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    res = load_step(out / "steps" / "bayes")
    obs = np.asarray(load_study(study).data["obs"].columns["thrust"], dtype=float)
    mean, std = exact_posterior(obs)
    assert abs(res.scalars["mean/collective_deg"] - mean) < 0.3 * std
    assert res.scalars["std/collective_deg"] == pytest.approx(std, rel=0.25)
    assert res.scalars["low_fidelity_runs/coarse"] == 30
    assert np.isfinite(res.scalars["cokriging_rho/model/thrust"])
    show = rotoruq("show", out, "bayes", cwd=tmp_path)
    assert "co-kriging: runs of the low-fidelity model coarse" in show.stdout, show.stdout


@pytest.mark.parametrize("old, new, expected", [
    ('models = ["coarse"]\n', "", 'models = ["NAME", ...] with emulator = "cokriging"'),
    ('emulator = "cokriging"', 'emulator = "gp"', 'emulator = "cokriging" with models'),
    ("n_low = 30", "n_low = 3", "at least n_emulator_samples (5)"),
    ('models = ["coarse"]', 'models = ["cosre"]', "names of [models.NAME] tables"),
])
def test_bad_cokriging_options_name_the_line(tmp_path, old, new, expected):
    text = study_text(STEP)
    assert old in text
    bad = text.replace(old, new, 1)
    study = tmp_path / "bad.toml"
    study.write_text(bad)
    with pytest.raises(InputFileError, match=r"bad\.toml, line \d+") as err:
        load_study(study)
    assert expected in str(err.value), str(err.value)
