"""The bundled ``forward_flight`` study's multi-fidelity steps (issue 38, item 6): the expensive
model is MBDyn's elastic rotor flying the built-in rotor's trim, and the pitch-link stiffness's
lower bound keeps every sample clear of the torsional divergence."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rotoruq.evaluation.dakota_files import read_results, write_parameters
from rotoruq.rotor.forward import ForwardRotorModel
from rotoruq.study.schema import load_study
from test_mbdyn import env_with_mbdyn, needs_mbdyn

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "src" / "rotoruq" / "studies" / "forward_flight.toml"
MF_STEPS = ("multifidelity_mu01", "multifidelity_mu02")


def _study():
    study = load_study(STUDY)
    params = {p.name: p for p in study.parameters}
    steps = {s.name: s for s in study.steps}
    return study, params, steps


def _advance_ratios(study, steps) -> list[float]:
    """Every advance ratio a step of the study flies at (its own or the study's)."""
    base = dict(study.model.fixed)
    return sorted({float({**base, **dict(s.fixed)}["advance_ratio"]) for s in steps.values()})


def test_multifidelity_steps_fly_the_elastic_rotor_at_two_advance_ratios():
    study, params, steps = _study()
    assert [float(steps[n].fixed["advance_ratio"]) for n in MF_STEPS] == [0.1, 0.2]
    for n in MF_STEPS:
        o = steps[n].options
        assert (o["high_fidelity"], list(o["models"])) == ("mbdyn", ["builtin"])
        assert (o["n_pilot"], o["budget"], o["budget_unit"]) == (13, 4, "hf_runs")
        assert dict(steps[n].quick) == {"n_pilot": 5, "budget": 3}
    cmd = list(study.model_spec("mbdyn").external.command)
    assert cmd[cmd.index("--template") + 1] == "elastic"
    assert cmd[cmd.index("--trim") + 1] == "wind_tunnel"
    assert cmd[cmd.index("--revolutions") + 1] == "12"
    # every input is one the elastic template models: none acts through the trim alone
    assert set(params) == {"cla_m03", "cd0_m03", "k_pitch_link", "ei_flap"}


def _divergence_stiffness(mu: float, worst: dict[str, float], lower: float) -> float:
    """The largest K_p [N] on a 0.05 N grid from lower / 2 to lower at which the built-in
    rotor, trimmed as the study trims it, fails for torsional divergence (NaN: none fails)."""
    names = ["k_pitch_link", *worst]
    model = ForwardRotorModel("gvpm", names_in=names, names_out=["power"], trim="wind_tunnel",
                              inflow_model="drees",
                              fixed={"omega": 224.6375, "thrust_target": 20.0,
                                     "shaft_angle_deg": 3.0, "advance_ratio": mu,
                                     "height_over_radius": math.inf})
    kp = np.arange(0.5 * lower, lower + 1e-9, 0.05)
    batch = model.evaluate(np.column_stack([kp, np.tile(list(worst.values()), (len(kp), 1))]))
    diverged = [k for k, why in batch.failures.items() if "torsional divergence" in why]
    assert sorted(diverged) == sorted(batch.failures), batch.failures   # no other failure
    return float(kp[max(diverged)]) if diverged else math.nan


def test_pitch_link_bound_clears_the_torsional_divergence():
    """The built-in GVPM blade (aerodynamic centre 1 mm ahead of the feathering axis) has no
    stable pitch below a K_p that grows with the lift slope and the advance ratio; the
    driver trims it for every MBDyn sample, so a sample there fails both models. At the
    study's lower bound it trims at every advance ratio the study flies, with the lift slope
    4 std above its mean (and the flap EI 4 std below), and the divergence lies below it."""
    study, params, steps = _study()
    kp = params["k_pitch_link"]
    assert kp.kind == "truncated_normal"
    lower = float(kp.distribution.lower)
    cla, ei = params["cla_m03"].distribution, params["ei_flap"].distribution
    worst = {"cla_m03": cla.mean + 4 * cla.std, "cd0_m03": params["cd0_m03"].distribution.upper,
             "ei_flap": ei.mean - 4 * ei.std}
    mus = _advance_ratios(study, steps)
    assert mus == [0.1, 0.2, 0.3]
    k_div = {mu: _divergence_stiffness(mu, worst, lower) for mu in mus}
    # the divergence exists in the range searched (so the bound is what keeps samples out) and
    # lies below the bound, by at least one grid step
    assert all(lower / 2 < k < lower - 0.05 for k in k_div.values()), k_div
    # and grows with the advance ratio: the margin is smallest at the study's largest
    assert k_div[0.1] < k_div[0.2] < k_div[0.3], k_div
    # the bound truncates less than 1 % of the normal's mass
    assert kp.distribution.cdf(lower) == 0.0
    assert 0.005 < 0.5 * math.erfc((kp.distribution.mean - lower) / kp.distribution.std
                                   / math.sqrt(2)) < 0.01


@needs_mbdyn
def test_study_expensive_model_is_the_elastic_rotor_flying_the_builtin_trim(tmp_path):
    """The study's [models.mbdyn] command, run as the study runs it (a parameters file with a
    sample at step multifidelity_mu02's operating point): MBDyn's elastic template with the
    sample's K_p and EI_y, flying the controls of the built-in rotor trimmed at the same
    inputs; its power close to the cheap model's (the pitch link's compliance under the
    blade's pitching moment lowers MBDyn's blade pitch: a few % of power)."""
    from rotoruq.mbdyn.case import OGE_DISTANCE
    from rotoruq.mbdyn.driver import builtin_trim
    from rotoruq.rotor.presets import get_preset
    from rotoruq.study.runner import build_model

    study, params, steps = _study()
    fixed = {**dict(study.model.fixed), **dict(steps["multifidelity_mu02"].fixed)}
    sample = {"cla_m03": 0.112, "cd0_m03": 0.010, "k_pitch_link": 12.5, "ei_flap": 6.6}
    write_parameters(tmp_path / "params.in", {**sample, **fixed}, ["power"])
    cmd = [sys.executable if w == "python" else w.format(params="params.in",
                                                          results="results.out")
           for w in study.model_spec("mbdyn").external.command]
    done = subprocess.run(cmd, cwd=tmp_path, env=env_with_mbdyn(), capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    mbd = (tmp_path / "rotor.mbd").read_text()
    assert mbd.startswith("# rotoruq template: elastic GVPM rotor")

    def field(name: str) -> float:
        m = re.search(rf"^set: real {name} = ([-+0-9.e]+)", mbd, re.M)
        assert m, name
        return float(m.group(1))

    assert (field("KP"), field("EI_Y"), field("MU")) == (12.5, 6.6, 0.2)
    assert field("H_GROUND") == OGE_DISTANCE * get_preset("gvpm").radius   # out of ground effect
    trim = builtin_trim(get_preset("gvpm"), {**sample, **fixed,
                                             "height_over_radius": math.inf}, "drees")
    for name, key in (("TH0", "collective_deg"), ("LAT", "lateral_deg"),
                      ("LON", "longitudinal_deg")):
        m = re.search(rf"^set: real {name} = ([-+0-9.e]+) \* pi / 180\.;", mbd, re.M)
        assert m and float(m.group(1)) == pytest.approx(trim[key], rel=1e-12, abs=1e-12), name
    res = read_results(tmp_path / "results.out")
    assert res.names_out == ("power",) and not res.failed
    power = float(res.values[0])
    cheap = build_model(study, list(sample), ["power"], fixed, tmp_path, model="builtin")
    ref = float(cheap([list(sample.values())])[0, 0])
    assert 100.0 < power < 400.0 and abs(power / ref - 1.0) < 0.10, (power, ref)


def test_the_saved_study_benchmark_measured_the_elastic_steps():
    """benchmarks/results/forward_flight_study.json (quoted in docs/tutorials/forward_flight.md):
    the full study with MBDyn, each multi-fidelity step cheaper than MBDyn alone for the same
    standard error, on the study file as it is now."""
    import json

    d = json.loads((ROOT / "benchmarks/results/forward_flight_study.json").read_text())
    study, _, steps = _study()
    assert not d["quick"] and set(d["steps_cpu_s"]) == set(steps)
    assert d["study_cpu_s"] == pytest.approx(sum(d["steps_cpu_s"].values()))
    for name in MF_STEPS:
        r = d["multifidelity"][name]
        assert r["models"] == ["mbdyn", "builtin"] and r["n_pilot"] == 13
        assert r["costs_given"] == list(steps[name].options["costs"])
        assert r["saving"] == pytest.approx(r["mbdyn_alone_cpu_s"] / r["cpu_s"])
        assert r["saving"] > 1.0 and r["correlation"] > 0.9, r
        assert 100.0 < r["mean_power_W"] < 400.0 and r["mean_se_W"] > 0.0
    assert "commit" in d["provenance"]
