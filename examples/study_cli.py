"""Write a study file and run it through the command line: ``rotoruq run``, then ``show``.

    python examples/study_cli.py [--quick] [--out FOLDER]

The study (a TOML file, written next to its results) declares the GVPM rotor at 4R, two
uncertain inputs and two steps: Sobol' indices and the mean value method. ``rotoruq run``
writes each step's results and a self-contained HTML report; ``rotoruq show`` prints a step's
tables. The same commands run any study file of your own. ``--quick`` shrinks the samples.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

STUDY = """\
[study]
name = "example"
seed = 1
output = "results"

[model]
preset = "gvpm"
responses = ["thrust", "power"]
fixed = {{ omega = 224.6375, height_over_radius = 4.0, collective_deg = 5.4 }}

[parameters.cla_m03]
distribution = "normal"
mean = 0.1080
std = 5.4e-3

[parameters.k_pitch_link]
distribution = "normal"
mean = 15.0
std = 2.0

[[steps]]
name = "sensitivity"
type = "sensitivity"
n_samples = {n_samples}

[[steps]]
name = "mean_value"
type = "mean_value"
"""


def rotoruq(*args: str) -> str:
    """Run the ``rotoruq`` command line (in this interpreter) and return what it printed."""
    done = subprocess.run([sys.executable, "-m", "rotoruq.study.cli", *args],
                          capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"rotoruq {' '.join(args)} failed:\n{done.stderr}")
    return done.stdout


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="32 Sobol' base samples, not 256")
    ap.add_argument("--out", help="folder for the study file and its results (default: a "
                                  "temporary folder, removed afterwards)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(args.out or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        study = folder / "example.toml"
        study.write_text(STUDY.format(n_samples=32 if args.quick else 256), encoding="utf-8")
        rotoruq("--quiet", "run", str(study))
        results = folder / "results"
        print(rotoruq("show", str(results), "sensitivity"))
        report = results / "report" / "index.html"
        if not report.is_file():
            raise SystemExit(f"no report at {report}")
        print(f"report: {report if args.out else 'index.html (in the temporary folder)'}")


if __name__ == "__main__":
    main()
