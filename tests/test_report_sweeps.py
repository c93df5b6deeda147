"""Steps of one type that differ in one fixed input get figures against it (issue 38)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from rotoruq.report.sweeps import Sweep, find_sweeps

ROOT = Path(__file__).resolve().parents[1]


def test_sweeps_need_one_type_and_exactly_one_differing_fixed_input():
    types = {"a": "sensitivity", "b": "sensitivity", "c": "sensitivity", "d": "sampling",
             "e": "sampling", "f": "pce", "g": "pce"}
    fixed = {"a": {"mu": 0.3, "h": 1.0}, "b": {"mu": 0.1, "h": 1.0}, "c": {"mu": 0.2, "h": 1.0},
             # two inputs differ: no sweep
             "d": {"mu": 0.1, "h": 1.0}, "e": {"mu": 0.2, "h": 2.0},
             # the same value twice: no sweep
             "f": {"mu": 0.1}, "g": {"mu": 0.1}}
    assert find_sweeps(types, fixed) == [Sweep("sensitivity", "mu", ("b", "c", "a"),
                                               (0.1, 0.2, 0.3))]
    # a step without fixed inputs of its own is in no sweep; text values are not swept
    assert find_sweeps({"a": "sensitivity", "b": "sensitivity"}, {"a": {"mu": 0.1}}) == []
    assert find_sweeps({"a": "sensitivity", "b": "sensitivity"},
                       {"a": {"m": "x"}, "b": {"m": "y"}}) == []


@pytest.mark.slow
def test_forward_flight_report_draws_the_indices_against_the_advance_ratio(tmp_path):
    # where MBDyn is not found (MBDYN unset, no build under MBDYN_PREFIX, no mbdyn on PATH):
    # the multi-fidelity step is skipped, and the report says so in its place
    env = {k: v for k, v in os.environ.items() if k != "MBDYN"}
    env.update(PYTHONPATH=str(ROOT / "src"), MBDYN_PREFIX=str(tmp_path / "no-mbdyn"),
               PATH=os.pathsep.join([str(Path(sys.executable).parent), "/usr/bin", "/bin"]))
    done = subprocess.run([sys.executable, "-m", "rotoruq", "run", "forward_flight", "--quick",
                           "--out", "res"], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    html = next(tmp_path.rglob("index.html")).read_text()
    figures = {p.name for p in tmp_path.rglob("figures/*.png")}
    for response in ("power", "collective_trim_deg", "lateral_trim_deg"):
        name = f"sweep_advance_ratio_{response}"
        assert f"Sobol indices and {response} against advance_ratio" in html
        assert any(name in f for f in figures), sorted(figures)
    # the three Sobol steps at mu 0.1, 0.2, 0.3, and not the LHS (no fixed input of its own)
    assert "(steps sobol_mu01, sobol_mu02, sobol_mu03)" in html
    # the step MBDyn was missing for: its own section in the report, saying why
    for step, mu in (("multifidelity_mu01", "0.1"), ("multifidelity_mu02", "0.2")):
        assert f"{step}: skipped</h4>" in html
        assert ("<b>Skipped by the run</b> (multifidelity, Multi-fidelity Monte Carlo of the "
                f"elastic MBDyn rotor&#x27;s power at mu = {mu}): needs MBDyn, not found here: "
                "MBDyn executable not found") in html, html[html.find(step):][:2000]
