"""Reasons of the reference claims computed from the run's numbers (issue 35, item 6): the
K_f miss from the data's information on each input, a V&V 20 miss (roll) from u_num, u_input
and the shift one calibrated input would need, and the Bo105 ranking from the section loads
the run records. Each is checked against a closed form computed here."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import rotoruq
from rotoruq.params import Normal, Uniform
from rotoruq.reference.causes import comparison_miss, data_information, lift_slope_sections
from rotoruq.results import StepResult, dist_to_dict
from rotoruq.steps.bayes_calibration import BayesRecord


def _plane_step(x, y, names_in, names_out):
    return StepResult("lhs", "sampling", arrays={"inputs": x, "outputs": y},
                      meta={"columns": {"inputs": list(names_in), "outputs": list(names_out)}})


def _bayes(names_in, names_out, *, data, prior, **fields):
    arrays, meta = BayesRecord.partial(tuple(names_in), tuple(names_out),
                                       **{k: np.asarray(v, dtype=float)
                                          for k, v in fields.items()}).parts()
    meta["input_distributions"] = {k: dist_to_dict(d) for k, d in prior.items()}
    return StepResult("bayes", "bayes_calibration", {}, {"data": data, **arrays}, meta=meta)


def test_data_information_is_the_linear_gaussian_posterior_of_the_runs_effects():
    # y = 2 a + 2 b (exactly a plane), prior U(0, 2 sqrt 3) (std 1) for both: +1 prior std
    # changes y by 2; n = 4 rows, noise 0.5: in prior-std units the posterior precision is
    # I + (4 / 0.25) [2 2]^T [2 2], whose inverse has diagonal 1 - 64 / (1 + 128)
    rng = np.random.default_rng(1)
    x = rng.uniform(0, 2 * np.sqrt(3), size=(40, 2))
    lhs = _plane_step(x, 2 * x[:, :1] + 2 * x[:, 1:], "ab", ["y"])
    prior = {p: Uniform(0.0, 2 * np.sqrt(3)) for p in "ab"}
    bayes = _bayes("ab", ["y"], data=np.zeros((4, 1)), prior=prior, noise_std=[0.5],
                   std_ratio=[0.8, 0.8], correlation=[[1.0, -0.97], [-0.97, 1.0]])
    (text,) = data_information(bayes, {"lhs": lhs}, ["a"], {"a": "A"})
    want = np.sqrt(1 - 64 / 129)
    assert f"keeps {want:.2f} of A's prior std (the run's posterior: 0.80)" in text
    assert "measure 1 response (y) for 2 calibrated inputs" in text
    assert "leave 1 to the prior" in text and "y +2 " in text
    assert "moves with b (posterior corr -0.97)" in text
    # a second response that sees a - b: both directions are fixed, nothing left to the prior
    lhs2 = _plane_step(x, np.column_stack([2 * x[:, 0] + 2 * x[:, 1], x[:, 0] - x[:, 1]]),
                       "ab", ["y", "z"])
    bayes2 = _bayes("ab", ["y", "z"], data=np.zeros((4, 2)), prior=prior,
                    noise_std=[0.5, 0.5], std_ratio=[0.1, 0.1],
                    correlation=np.eye(2))
    (text2,) = data_information(bayes2, {"lhs": lhs2}, ["a"], {})
    h = np.array([[2.0, 2.0], [1.0, -1.0]]) / 0.5
    cov = np.linalg.inv(np.eye(2) + 4 * h.T @ h)
    assert f"keeps {np.sqrt(cov[0, 0]):.2f} of a's prior std" in text2
    assert "leave" not in text2 and "the data could resolve it" in text2
    assert "moves with" not in text2  # no correlation worth naming


def test_a_miss_the_calibrated_inputs_cannot_close_says_how_far_each_would_have_to_move():
    # roll = 0.02 a - 0.5 b (a plane); posterior std 1 for a, 0.1 for b; E = -0.25:
    # a would need 0.25 / 0.02 / 1 = 12.5 posterior std devs, b 0.25 / 0.5 / 0.1 = 5
    rng = np.random.default_rng(2)
    x = rng.normal(size=(30, 2))
    lhs = _plane_step(x, 0.02 * x[:, :1] - 0.5 * x[:, 1:], "ab", ["roll"])
    bayes = _bayes("ab", ["thrust"], data=np.zeros((1, 1)),
                   prior={p: Normal(0.0, 1.0) for p in "ab"}, std=[1.0, 0.1])
    text = comparison_miss({"lhs": lhs, "bayes": bayes}, bayes, "roll", -0.25, 2e-3, 0.01,
                           {"b": "K_p"})
    assert text.startswith("u_num 0.002 is 0.8 % of |E| = 0.25 and u_input 0.01 is 4.0 %")
    m = re.search(r"would take ([\d.]+) posterior std devs of K_p \(droll/dK_p = ([-\d.e]+)",
                  text)
    assert m and float(m.group(1)) == pytest.approx(5.0, rel=1e-6)
    assert float(m.group(2)) == pytest.approx(-0.5, rel=1e-9)
    assert text.endswith("beyond 3 of them: the calibrated inputs cannot produce this roll at "
                         "their posterior")
    near = comparison_miss({"lhs": lhs}, bayes, "roll", -0.1, 2e-3, 0.01, {})
    assert "would take 2 posterior std devs of b" in near and near.endswith("within 3 of them")
    assert comparison_miss({}, None, "roll", 0.0, 1e-3, 1e-3, {}) == ""


def test_the_lift_slope_ranking_comes_from_the_recorded_section_loads():
    rec = {"r": [1.0, 2.0, 3.0], "w": [1.0, 1.0, 1.0], "mach": [0.2, 0.4, 0.6],
           "alpha_deg": [2.0, 0.5, -1.5], "inputs": {"collective_deg": 6.0},
           "thrust_derivative": {"lo": 300.0, "hi": -900.0},
           "station_derivative": {"lo": [300.0, 0.0, 0.0], "hi": [0.0, 0.0, -900.0]},
           "no_negative_pitch": {"twist_deg": -6.0, "thrust_derivative": {"lo": 200.0,
                                                                          "hi": -500.0}}}
    first, second = lift_slope_sections(rec, {"lo": 0.01, "hi": 0.02}, {"hi": "C(0.6)"})
    # effects 3 and -18: shares 9 / 333 and 324 / 333
    assert "-18 (C(0.6)), +3 (lo) N, squared shares C(0.6) 0.97, lo 0.03" in first
    assert "acts on the sections at r = 3 to 3 m (Mach 0.60 to 0.60)" in first
    assert "angle of attack is -1.5 to -1.5 deg" in first
    # at -6 deg: effects 2 and -10: shares 4 / 104 and 100 / 104
    assert "at -6 deg of twist" in second and "C(0.6) still has the largest share" in second
    assert "C(0.6) 0.96, lo 0.04" in second
    assert lift_slope_sections(None, {"lo": 0.01}, {}) == []


def test_the_rotor_returns_its_section_loads_and_the_run_records_them():
    model = rotoruq.RotorModel("bo105", names_in=["collective_deg", "cla_m06"],
                               names_out=["thrust"], fixed={"longitudinal_deg": -2.0})
    x = [[6.0, 0.1135]]
    out = model.section_loads(x, derivatives=["cla_m06"])
    thrust = float(model(x)[0, 0])
    assert float(np.sum(out["thrust_per_span"][0] * out["w"])) == pytest.approx(thrust,
                                                                               rel=1e-6)
    # the direct derivative is the section's own: nonzero only where Mach 0.6 weighs in
    d = out["d_thrust_per_span/cla_m06"][0]
    assert np.all(d[out["mach"][0] < 0.5 - 1e-6] == 0) and np.any(d != 0)
    from rotoruq.study.runner import model_record
    from rotoruq.study.schema import load_study

    study = load_study(Path(rotoruq.__file__).parent / "studies" / "validation.toml")
    rec = model_record(study)["spanwise"]
    assert rec["failure"] == "" and rec["twist_deg"] == -8.0
    assert rec["no_negative_pitch"]["twist_deg"] == -6.0  # collective 6: tip pitch 0
    assert set(rec["thrust_derivative"]) == {f"cla_m0{k}" for k in range(1, 7)}
    top = max(rec["thrust_derivative"], key=lambda p: abs(rec["thrust_derivative"][p]))
    assert top == "cla_m06"
