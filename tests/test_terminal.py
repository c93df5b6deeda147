"""What the terminal shows of a run, through the CLI in a subprocess in a fresh folder: a pool
worker killed the out-of-memory killer's way is said, the methods' messages are gathered under
their step, the progress of long phases (a bar on a terminal, the status line in a pipe), the
chains arviz opens and ``chain.csv``'s chain column."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from test_trust import external_study  # one external-driver study for both

CLI = [sys.executable, "-m", "rotoruq.study.cli"]


def _children(pid: int) -> list[int]:
    """Process ids whose parent is ``pid`` (read from /proc)."""
    out = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
            out.append(int(entry.name))
    return out


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads the process tree from /proc")
def test_a_killed_pool_worker_is_logged_and_the_run_completes(tmp_path):
    study = external_study(tmp_path / "s", n=16, executor="processes")
    err = (tmp_path / "err.txt").open("w")
    env = {**os.environ, "DRIVER_SLEEP": "0.4"}
    proc = subprocess.Popen([*CLI, "run", study, "--out", tmp_path / "out", "--no-report"],
                            cwd=tmp_path / "s", stdout=subprocess.DEVNULL, stderr=err,
                            env=env)
    killed = None
    try:
        deadline = time.monotonic() + 120
        while killed is None and time.monotonic() < deadline and proc.poll() is None:
            # a worker busy with a driver: a child of the run with a child of its own
            busy = [w for w in _children(proc.pid) if _children(w)]
            if busy:
                killed = busy[0]
                os.kill(killed, signal.SIGKILL)
            time.sleep(0.05)
        assert killed is not None, "no pool worker seen running a driver"
        assert proc.wait(timeout=180) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        err.close()
    text = (tmp_path / "err.txt").read_text()
    assert f"a process-pool worker died (PID {killed}, killed by signal 9 (SIGKILL)" in text, text
    assert "the pool is replaced and its" in text and "(replacement 1 of at most 2)" in text
    outputs = np.load(tmp_path / "out" / "steps" / "lhs" / "outputs.npy")
    assert outputs.shape == (16, 2) and np.isfinite(outputs).all()
