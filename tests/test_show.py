"""A user's own study through the command line: every step type gets a table in its report and
in ``rotoruq show`` (text, CSV, JSON); the terminal summary of ``rotoruq run``; the README's
study example gives a sensible calibration."""

from __future__ import annotations

import csv
import html
import io
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

CLI = [sys.executable, "-m", "rotoruq.study.cli"]
ROOT = Path(__file__).resolve().parents[1]

USER_STUDY = """\
[study]
name = "my_rotor"
seed = 11
description = "a user's GVPM study"

[model]
preset = "gvpm"
responses = ["thrust", "power"]
fixed = { omega = 224.6375, height_over_radius = 4.0, collective_deg = 5.4 }

[parameters.cla_m03]
distribution = "normal"
mean = 0.1080
std = 5.4e-3
label = "C_La(0.3)"

[parameters.k_pitch_link]
distribution = "normal"
mean = 15.0
std = 0.75
label = "K_p"

[data.measured]
file = "gvpm_measurements.csv"
select = { height_over_radius = 4.0 }

[[steps]]
name = "lhs"
type = "sampling"
n_samples = 20

[[steps]]
name = "mv"
type = "mean_value"

[[steps]]
name = "form"
type = "reliability"
responses = ["thrust"]
response_levels = { thrust = [24.0] }

[[steps]]
name = "chaos"
type = "pce"
order = 2

[[steps]]
name = "ds"
type = "evidence"
responses = ["thrust"]
intervals = { k_pitch_link = [[14.0, 15.0, 0.5], [15.0, 16.0, 0.5]] }
response_levels = { thrust = [26.0] }
n_samples = 10

[[steps]]
name = "sobol"
type = "sensitivity"
n_samples = 16

[[steps]]
name = "bayes"
type = "bayes_calibration"
parameters = ["cla_m03"]
data = "measured"
noise_std = { thrust = 0.86, power = 11.66 }
n_emulator_samples = 20
n_samples = 1500
burn_in = 200

[[steps]]
name = "cuu"
type = "cuu"
from = "bayes.posterior"
parameters = ["cla_m03"]
responses = ["thrust"]
targets = { thrust = [25.68, 0.86] }
verify_samples = 20

[[steps]]
name = "check"
type = "forward_check"
from = "bayes.posterior"
data = "measured"
n_samples = 20
sweep = { height_over_radius = [4.0], omega = [224.6375] }
"""

TYPES = {"lhs": "sampling", "mv": "mean_value", "form": "reliability", "chaos": "pce",
         "ds": "evidence", "sobol": "sensitivity", "bayes": "bayes_calibration", "cuu": "cuu",
         "check": "forward_check"}


def cli(*args, timeout=600):
    proc = subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc


@pytest.fixture(scope="module")
def user_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("user")
    study = d / "my_rotor.toml"
    study.write_text(USER_STUDY)
    proc = cli("run", study, "--out", d / "out")
    return d / "out", proc


@pytest.mark.slow
def test_user_study_every_step_type_in_report_and_show(user_run):
    out, proc = user_run
    page = (out / "report" / "index.html").read_text()
    assert "<title>rotoruq: my_rotor (a user&#x27;s GVPM study)</title>" in page
    assert "reproduction of the reference study" not in page
    assert "Thesis tables beside ours" not in page and "id='claims'" not in page
    assert not re.search(r"Table [34]\.\d+:", page)
    data = json.loads(cli("show", out, "--json").stdout)
    assert data["study"] == "my_rotor" and list(data["steps"]) == list(TYPES)
    for step, typ in TYPES.items():
        s = data["steps"][step]
        assert s["type"] == typ and s["tables"], step
        # the step's table in the report, its numbers as show prints them
        assert f"id='study-my_rotor-step-{step}'" in page
        for t in s["tables"]:
            assert f"<b>{html.escape(t['title'])}</b>" in page, (step, t["title"])
            assert all(len(r) == len(t["columns"]) for r in t["rows"])
    # numbers in the tables are the saved scalars
    mv = data["steps"]["mv"]["tables"][0]
    from rotoruq.results import load_step

    saved = load_step(out / "steps" / "mv")
    assert mv["rows"][0][:3] == ["thrust", saved.get("mean/thrust"), saved.get("std/thrust")]
    check = next(t for t in data["steps"]["check"]["tables"] if t["title"].startswith("Prop"))
    assert "joint mean" in check["columns"]
    # the terminal summary of the run
    assert "summary of my_rotor (9 steps):" in proc.stdout
    for step in TYPES:
        assert re.search(rf"^\s+{step}\s+{TYPES[step]}\s", proc.stdout, re.M), step
    assert "rotoruq show" in proc.stdout


@pytest.mark.slow
def test_show_text_csv_and_errors(user_run):
    out, _ = user_run
    text = cli("show", out, "sobol").stdout
    assert text.startswith("== sobol (sensitivity)")
    assert "Output spread" in text and "Sobol indices of thrust" in text
    csv_text = cli("show", out, "bayes", "--csv").stdout
    blocks = [b for b in csv_text.split("# bayes: ")[1:]]
    assert blocks and blocks[0].startswith("Prior and posterior")
    rows = list(csv.reader(io.StringIO(blocks[0].split("\n", 1)[1])))
    assert rows[0][:4] == ["parameter", "prior mean", "prior std", "posterior mean"]
    assert rows[1][0] == "C_La(0.3)" and float(rows[1][3]) > 0
    bad = subprocess.run([*CLI, "show", str(out), "nope"], capture_output=True, text=True)
    assert bad.returncode == 1
    assert "a saved step named 'nope'" in bad.stderr and "sobol" in bad.stderr
    empty = subprocess.run([*CLI, "show", str(out / "steps")], capture_output=True, text=True)
    assert empty.returncode == 1 and "study.json" in empty.stderr


def _readme_study() -> str:
    text = (ROOT / "docs" / "tutorials" / "studies.md").read_text()  # the README's, moved
    block = re.search(r"1\. \*A study file\*.*?```toml\n(.*?)```", text, re.S).group(1)
    return "\n".join(line[3:] if line.startswith("   ") else line
                     for line in block.splitlines())


@pytest.mark.slow
def test_readme_study_example_is_sensible(tmp_path):
    """The studies tutorial's example: the lift slope stays in its prior's bulk and the measured 4R
    thrust lies within 3 predictive std devs under the joint posterior predictive (the
    example once ended at 4x the nominal lift slope, 357 std devs from the thrust)."""
    from rotoruq.results import load_step

    study = tmp_path / "quick.toml"
    study.write_text(_readme_study())
    cli("run", study, "--out", tmp_path / "out", "--quick", "--no-report")
    bayes = load_step(tmp_path / "out" / "steps" / "bayes")
    assert abs(bayes.get("prior_z/cla_m03")) < 3.0
    assert bayes.get("noise_std/thrust") == 0.86
    fwd = load_step(tmp_path / "out" / "steps" / "forward")
    assert fwd.meta["joint_predictive"]
    assert fwd.get("pp_nstd/thrust@4") < 3.0
    assert np.isfinite(fwd.get("pp_nstd/power@4")) and np.isfinite(fwd.get("nstd/power@4"))
