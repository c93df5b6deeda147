"""Every script in examples/ runs with --quick, from an empty folder, in a fresh interpreter.

The scripts check their own answers (thrust rising with collective, a figure of merit in (0, 1),
the calibrated inputs within 4 posterior standard deviations of the truth, the study's report
written) and exit non-zero when a check fails; here they must exit 0 and print their tables.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples").glob("*.py"))
# what each example must print (its table's header or result line)
EXPECT = {
    "rotor_model.py": "figure of merit",
    "forward_uq.py": "Sobol' indices, N = 32",
    "bayes_calibration.py": "posterior mean",
    "study_cli.py": "Sobol indices of thrust",
}
# over 20 s of wall time on a loaded 2-core machine: the calibration (it compiles the
# sampler's kernels on first use in a fresh environment) and the study (three interpreters)
SLOW = {"bayes_calibration.py", "study_cli.py"}


def test_every_example_is_listed():
    assert sorted(p.name for p in EXAMPLES) == sorted(EXPECT)


@pytest.mark.parametrize(
    "script", [pytest.param(p, marks=pytest.mark.slow) if p.name in SLOW else p
               for p in EXAMPLES], ids=lambda p: p.name)
def test_example_runs(script, tmp_path):
    done = subprocess.run([sys.executable, str(script), "--quick"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-4000:]
    assert EXPECT[script.name] in done.stdout, done.stdout
    assert not any(tmp_path.iterdir()), "an example left files in the working folder"
