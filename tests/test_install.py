"""The package as a user installs it: a wheel in a fresh virtual environment (not editable),
then ``rotoruq reproduce --quick`` from an empty folder."""

from __future__ import annotations

import os
import subprocess
import sys
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_wheel_installs_and_reproduces_from_an_empty_folder(tmp_path):
    # nothing of this source tree may leak into the fresh environment
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    dist = tmp_path / "dist"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist),
                    str(ROOT)], check=True, timeout=600, env=env)
    wheels = list(dist.glob("rotoruq-*.whl"))
    assert len(wheels) == 1
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    py = env_dir / "bin" / "python"
    subprocess.run([str(py), "-m", "pip", "install", "-q", str(wheels[0])], check=True,
                   timeout=900, env=env, cwd=tmp_path)
    empty = tmp_path / "empty"
    empty.mkdir()
    env["PATH"] = f"{env_dir / 'bin'}{os.pathsep}{env['PATH']}"
    # the package imports from site-packages, not from this source tree
    where = subprocess.run([str(py), "-c", "import rotoruq; print(rotoruq.__file__)"],
                           cwd=empty, env=env, capture_output=True, text=True)
    assert where.returncode == 0, where.stderr
    assert str(env_dir) in where.stdout
    proc = subprocess.run([str(env_dir / "bin" / "rotoruq"), "reproduce", "--quick"], cwd=empty,
                          env=env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (empty / "rotoruq-results" / "report" / "index.html").is_file()
    assert (empty / "rotoruq-results" / "validation" / "steps").is_dir()
    # a bundled study by name, results in the current folder (never inside the package)
    proc = subprocess.run([str(env_dir / "bin" / "rotoruq"), "run", "quick", "--quick",
                           "--no-report"], cwd=empty, env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (empty / "rotoruq-results" / "quick" / "steps").is_dir()
    # bad input through the installed command: a message, no traceback
    proc = subprocess.run([str(env_dir / "bin" / "rotoruq"), "run", "missing.toml"], cwd=empty,
                          env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert "missing.toml" in proc.stderr
