"""The aerodynamic-centre offset as an uncertain input and its calibration
(scripts/aero_center_calibration.py): the input against the preset's fixed value, the airfoil
prior against the verification script, the evidence measures against closed forms, and the
script in quick mode from a fresh folder."""

from __future__ import annotations

import importlib.util
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import rotoruq as rq
from rotoruq.rotor.presets import gvpm

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "aero_center_calibration.py"
_spec = importlib.util.spec_from_file_location("aero_center_calibration", SCRIPT)
assert _spec and _spec.loader
A = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(A)

OP = {"omega": 224.6375, "height_over_radius": 4.0, "k_pitch_link": 15.0}
COMMANDS = ["collective_deg", "lateral_deg", "longitudinal_deg"]
OUT = ["thrust", "torque", "roll", "pitch", "power"]


@pytest.mark.slow  # ~15 CPU-s: five rotor builds (the rotor's other tests stay fast)
def test_uncertain_offset_gives_the_fixed_presets_loads_bitwise():
    offsets = [-0.001, -0.00019, 0.0, -0.0005]
    cmd = [5.0, -1.0, -1.0]
    uncertain = rq.RotorModel("gvpm", names_in=[*COMMANDS, "aero_center_offset"],
                              names_out=OUT, fixed=OP)
    # one batch with a different offset per row: each row is that offset's fixed preset
    y = uncertain([[*cmd, a] for a in offsets])
    for row, a in zip(y, offsets, strict=True):
        fixed = rq.RotorModel(gvpm(aero_center_offset=a), names_in=COMMANDS, names_out=OUT,
                              fixed=OP)([cmd])[0]
        assert np.array_equal(row, fixed), (a, row, fixed)
    # the preset's own value (-1 mm) needs no input at all
    assert np.array_equal(y[0], rq.RotorModel("gvpm", names_in=COMMANDS, names_out=OUT,
                                              fixed=OP)([cmd])[0])
    # and the offset matters: 1 mm ahead of the axis pitches the soft-linked blade up
    assert y[0, 0] > 1.2 * y[2, 0]


def test_prior_is_the_verification_scripts_airfoil_value():
    prior = A.offset_prior()
    saved = json.loads((ROOT / "scripts" / "results" / "mbdyn_verification.json").read_text())
    af = saved["aero_center_offset"]["airfoil"]
    assert prior["mean_m"] == pytest.approx(af["x_ac_m"], rel=1e-9)
    assert prior["std_m"] == pytest.approx(af["spread_m"], rel=1e-9)
    # the airfoil's a.c. lies ahead of the quarter chord by well under the preset's 1 mm
    assert -1e-3 < prior["mean_m"] < 0


def test_savage_dickey_ratio_and_tail_match_the_normal_closed_form():
    # posterior N(m, s) drawn, prior N(m0, s0): p(x | y) / p(x) and P(x <= -1 mm) in closed form
    from scipy.stats import norm

    m, s = -0.4e-3, 0.25e-3
    prior = {"mean_m": -0.19e-3, "std_m": 0.44e-3}
    draws = np.random.default_rng(3).normal(m, s, 200_000)
    got = A.offset_posterior(draws, prior)
    for key, x in (("preset_-1mm", -1e-3), ("airfoil", prior["mean_m"])):
        exact = norm.pdf(x, m, s) / norm.pdf(x, prior["mean_m"], prior["std_m"])
        assert got["savage_dickey"][key] == pytest.approx(exact, rel=0.03), key
    assert got["p_below_-1mm"] == pytest.approx(norm.cdf(-1e-3, m, s), abs=2e-3)
    assert got["prior_p_below_-1mm"] == pytest.approx(norm.cdf(-1e-3, -0.19e-3, 0.44e-3))
    assert got["interval_90_m"] == pytest.approx([m - 1.6449 * s, m + 1.6449 * s], abs=0.02 * s)
    # a point beyond the draws has no density estimate, and no Bayes factor from it
    far = A.offset_posterior(np.random.default_rng(4).normal(0.0, 1e-5, 10_000), prior)
    assert far["savage_dickey"]["preset_-1mm"] is None
    assert far["bayes_factor_-1mm_vs_airfoil"] is None


def test_predictive_fit_standardises_with_model_and_noise_spread():
    pred = np.column_stack([np.full(4, 10.0) + [-1, 1, -1, 1], np.full(4, 3.0)])
    fit = A.predictive_fit(pred, np.array([12.0, 3.0]), np.array([1.0, 0.5]))
    sd = np.std([-1, 1, -1, 1], ddof=1)
    assert fit["z"] == pytest.approx([2.0 / math.sqrt(sd**2 + 1.0), 0.0])


def _check_mbdyn_calibration(a: dict, prior: dict) -> None:
    """The MBDyn calibration rejects the tuned -1 mm: the prior's mean inside its 90 %
    interval, -1 mm outside, the prior narrowed, the likelihood ratio decisive; without the
    prior the answer stands (MBDyn's loads alone put the offset inside the posterior's
    interval, and -1 mm far outside their own)."""
    lo, hi = a["offset"]["interval_90_m"]
    assert lo <= prior["mean_m"] <= hi and not lo <= -1e-3 <= hi
    assert a["offset"]["std_over_prior_std"] < 0.6
    assert a["log10_likelihood_ratio_-1mm_vs_airfoil"] < -5
    lk = a["likelihood_only"]
    assert lo <= lk["max_m"] <= hi and lk["interval_m"][0] > -1e-3


@pytest.mark.slow  # ~20 CPU-s: the script's quick run, and its MBDyn calibration again here
def test_quick_run_from_a_fresh_folder(tmp_path):
    """The script's ``--quick`` run from an empty folder; its MBDyn calibration computed again
    in this process gives the same numbers bitwise (the same seed; it was computed twice in
    one process before, a calibration more) and rejects the tuned value."""
    done = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--out", "a.json"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    res = json.loads((tmp_path / "a.json").read_text())
    prior = A.offset_prior()
    again = json.loads(json.dumps(A.mbdyn_elastic(prior, quick=True)))
    for r in (again, res["mbdyn_elastic"]):
        del r["posterior"]["sampling_seconds"]      # wall time, the one number that may differ
    assert again == res["mbdyn_elastic"]
    _check_mbdyn_calibration(again, prior)
    assert res["quick"] and res["prior"]["mean_m"] == pytest.approx(A.offset_prior()["mean_m"])
    m4 = res["measured_4r"]
    assert set(m4) >= {"calibrated", "fixed_-1mm", "fixed_airfoil"}
    assert m4["calibrated"]["posterior"]["names"][-1] == "aero_center_offset"
    assert "aero_center_offset" not in m4["fixed_-1mm"]["posterior"]["names"]
    for case in ("calibrated", "fixed_-1mm", "fixed_airfoil"):
        assert len(m4[case]["predictive"]["z"]) == 4
    # the four 4R means with free commands cannot pin the offset down: the prior's width stays
    assert m4["calibrated"]["offset"]["std_over_prior_std"] > 0.7
    share = res["table_4_6"]["lateral_share_of_roll"]
    assert np.all(np.diff(share) < 0)        # more offset ahead of the axis: more roll from lat
    summary = subprocess.run([sys.executable, str(SCRIPT), "--summary", "a.json"], cwd=tmp_path,
                             capture_output=True, text=True, timeout=60)
    assert summary.returncode == 0 and "MBDyn elastic" in summary.stdout
