"""What the terminal shows of a run, through the CLI in a subprocess in a fresh folder: a pool
worker killed the out-of-memory killer's way is said, the methods' messages are gathered under
their step, the progress of long phases (a bar on a terminal, the status line in a pipe), the
chains arviz opens and ``chain.csv``'s chain column."""

from __future__ import annotations

import io
import os
import re
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
@pytest.mark.slow  # the fast counterpart: tests/test_infra_faults.py, in one process
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


BAYES_STUDY = """\
[study]
name = "tb"
seed = 4

[model]
function = "text_book"
responses = ["f"]

[parameters.x1]
distribution = "normal"
mean = 1.5
std = 0.3

[parameters.x2]
distribution = "normal"
mean = 1.5
std = 0.3

[data.obs]
f = [0.52, 0.47, 0.55, 0.49]

[[steps]]
name = "bayes"
type = "bayes_calibration"
data = "obs"
emulator = "gp"
n_emulator_samples = 30
noise_std = { f = 0.05 }
n_samples = 400
burn_in = 100
self_check = 20
"""


def _bayes_study(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "study.toml"
    path.write_text(BAYES_STUDY)
    return path


# a status line every 0.05 s: the pipe's fallback for the bar, with the phase under way
FAST_STATUS = {**os.environ, "ROTORUQ_STATUS_INTERVAL": "0.05"}


@pytest.fixture(scope="module")
def bayes_run(tmp_path_factory):
    """The Bayes study run once through the CLI, stderr a pipe: (folder, process)."""
    d = tmp_path_factory.mktemp("bayes")
    study = _bayes_study(d / "s")
    proc = subprocess.run([*CLI, "run", study, "--out", d / "out", "--no-report"],
                          capture_output=True, text=True, timeout=600, env=FAST_STATUS, cwd=d)
    assert proc.returncode in (0, 3), proc.stderr
    return d, proc


@pytest.mark.slow
def test_method_messages_are_gathered_under_their_step_and_the_status_line_says_the_phase(
        bayes_run):
    d, proc = bayes_run
    lines = proc.stderr.splitlines()
    assert "\r" not in proc.stderr and "\033" not in proc.stderr  # no bar in a pipe
    done = lines.index(next(x for x in lines if x.startswith("[tb] 1/1 bayes: done in")))
    loo = [k for k, x in enumerate(lines) if "emulator leave-one-out: f RMSE" in x]
    cal = [k for k, x in enumerate(lines) if "calibrate_bayes: 4 chains x 400 kept steps" in x]
    # each once, after the step's "done" line, under its name; no raw arrays
    assert len(loo) == 1 and len(cal) == 1 and min(loo + cal) > done, proc.stderr
    assert lines[loo[0]].startswith("  [tb] 1/1 bayes: emulator leave-one-out: f RMSE ")
    assert not any("RMSE [" in x for x in lines)
    status = [x for x in lines if x.startswith("  [tb] 1/1 bayes: bayes_calibration running, ")]
    phases = " ".join(status)
    assert "4 chains " in phases or "self-check replications " in phases, proc.stderr
    # --quiet: none of these lines
    quiet = subprocess.run([*CLI, "run", d / "s" / "study.toml", "--out", d / "q",
                            "--no-report", "-q"], capture_output=True, text=True, timeout=600,
                           env=FAST_STATUS, cwd=d)
    assert "leave-one-out" not in quiet.stderr and "running" not in quiet.stderr


@pytest.mark.slow
def test_a_terminal_gets_a_progress_bar_a_pipe_does_not(tmp_path):
    """stderr on a pseudo-terminal: the phases drawn in place (carriage return, erase to the
    end of the line), no periodic status line for them; the lines of the run still there."""
    import pty
    import select

    study = _bayes_study(tmp_path / "s")
    master, slave = pty.openpty()
    # every phase drawn, however short: a warm run's chains take well under the default 0.5 s
    env = {**os.environ, "ROTORUQ_STATUS_INTERVAL": "0.05", "ROTORUQ_BAR_AFTER": "0",
           "COLUMNS": "200"}
    proc = subprocess.Popen([*CLI, "run", study, "--out", tmp_path / "out", "--no-report"],
                            stdout=subprocess.DEVNULL, stderr=slave, env=env, cwd=tmp_path)
    os.close(slave)
    chunks = []
    try:
        while True:
            ready, _, _ = select.select([master], [], [], 600)
            if not ready:
                break
            try:
                data = os.read(master, 65536)
            except OSError:  # the child closed the terminal
                break
            if not data:
                break
            chunks.append(data)
        assert proc.wait(timeout=60) in (0, 3)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(master)
    text = b"".join(chunks).decode(errors="replace")
    bars = [seg for seg in text.split("\r") if "] " in seg and "ETA" in seg]
    assert any(seg.startswith(("4 chains [", "self-check replications [")) for seg in bars), \
        text[-3000:]
    assert "\033[K" in text
    # the bar is taken off the line (or redrawn) before anything else is written after it
    after = re.findall(r"ETA [^\r\n\x1b]*\x1b\[K(.)", text, flags=re.S)
    assert after and set(after) == {"\r"}, text[-3000:]
    assert "[tb] 1/1 bayes: done in" in text
    # the status line leaves the phases to the bar
    assert not any("(4 chains " in seg or "(self-check replications " in seg
                   for seg in text.splitlines()), text[-3000:]


@pytest.mark.slow
def test_every_bayes_step_writes_chains_arviz_opens_and_a_csv_with_a_chain_column(bayes_run):
    az = pytest.importorskip("arviz")  # the `arviz` extra (installed with the test extras)
    d, _ = bayes_run
    step = d / "out" / "steps" / "bayes"
    chain = np.load(step / "chain.npy")  # (4 chains x 400 draws, 2), chain after chain
    idata = az.from_netcdf(step / "chains.nc")
    post = idata.posterior
    assert dict(post.sizes)["chain"] == 4 and dict(post.sizes)["draw"] == 400
    assert sorted(post.data_vars) == ["x1", "x2"]
    assert np.array_equal(np.stack([post["x1"].values, post["x2"].values], -1).reshape(-1, 2),
                          chain)
    rows = (step / "chain.csv").read_text().splitlines()
    assert rows[0] == "chain,x1,x2"
    table = np.loadtxt(step / "chain.csv", delimiter=",", skiprows=1)
    assert np.array_equal(table[:, 0], np.repeat(np.arange(4), 400))
    assert np.array_equal(table[:, 1:], chain)  # shortest repr: the same bits


VV_STUDY = """\
[study]
name = "vvu"
seed = 3

[model]
preset = "gvpm"
responses = ["thrust", "power"]
fixed = { collective_deg = 5.0 }

[parameters.k_pitch_link]
distribution = "normal"
mean = 15.0
std = 0.75

[data.obs]
height_over_radius = [4.0, 4.0]
thrust = [29.0, 29.6]
power = [280.0, 290.0]

[[steps]]
name = "val"
type = "validation"
data = "obs"
conditions = { height_over_radius = [4.0] }
u_num = 0.05
u_systematic = 0.1
n_samples = 20
"""


def test_vv_tables_carry_units_on_every_column(tmp_path):
    import json

    (tmp_path / "vv.toml").write_text(VV_STUDY)
    proc = subprocess.run([*CLI, "run", "vv.toml", "--out", "out", "--no-report"],
                          capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    shown = subprocess.run([*CLI, "show", "out", "val", "--json"], capture_output=True,
                           text=True, timeout=120, cwd=tmp_path)
    assert shown.returncode == 0, shown.stderr
    tables = json.loads(shown.stdout)["steps"]["val"]["tables"]
    vv = next(t for t in tables if t["title"].startswith("V&V 20 comparison error"))
    numeric = [c for c in vv["columns"][1:] if not c.startswith("D in ")]
    assert all("[unit]" in c or "[-]" in c for c in numeric), vv["columns"]
    assert [r[1] for r in vv["rows"]] == ["thrust [N]", "power [W]"]
    assert "[unit]: the response's unit, beside its name." in vv["note"]


class _Terminal(io.StringIO):
    """A stderr that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def test_phases_draw_one_bar_on_a_terminal_and_nothing_in_a_pipe(monkeypatch):
    """The fast counterpart of the runs above: the CLI's logging, phases reported as the
    methods report them, a terminal and a pipe as stderr."""
    import logging

    from rotoruq._progress import Phase, bar_on_terminal
    from rotoruq.study.console import configure_logging

    for stream, drawn in ((_Terminal(), True), (io.StringIO(), False)):
        monkeypatch.setattr(sys, "stderr", stream)
        configure_logging()
        assert bar_on_terminal() is drawn
        with Phase("4 chains", 1000, interval=0.0) as phase:
            t0 = time.perf_counter()
            while time.perf_counter() - t0 < 0.8:  # a phase under half a second is not drawn
                time.sleep(0.25)
                phase.advance(100)
            logging.getLogger("rotoruq.study").info("a line")
        text = stream.getvalue()
        if drawn:
            assert re.search(r"\r4 chains \[#+\.+\] \d00/1000 ", text), text
            # the bar is taken off before the line, and the line stands alone
            assert "\r\x1b[Ka line\n" in text
        else:
            assert text == "a line\n"
    configure_logging()  # back to the real stderr


def test_a_compile_phase_counts_its_time_on_the_bar_and_the_status_line(monkeypatch):
    """An uncounted phase (a compile) never advances: it still tells its elapsed time while
    it runs. Found in a by-hand run: the status line said `compiling rotor kernels, 0:00`
    for five minutes of a cold compile."""
    import logging

    from rotoruq._progress import Phase
    from rotoruq.steps.base import _Phases
    from rotoruq.study.console import configure_logging

    stream = _Terminal()
    monkeypatch.setattr(sys, "stderr", stream)
    configure_logging()
    phases = _Phases()
    logging.getLogger("rotoruq.progress").addHandler(phases)
    try:
        with Phase("compiling demo kernels", None, tick=0.05):
            time.sleep(1.3)
            under_way = phases.text()
    finally:
        logging.getLogger("rotoruq.progress").removeHandler(phases)
        configure_logging()  # back to the real stderr
    assert re.fullmatch(r"compiling demo kernels, 0:0[1-9]", under_way), under_way
    assert re.search(r"\rcompiling demo kernels, 0:0[1-9]", stream.getvalue()), stream.getvalue()
    assert phases.text() == ""  # closed: off the status line


def test_gathered_messages_pass_warnings_at_once_and_count_the_rest(monkeypatch):
    import logging

    from rotoruq.study.console import configure_logging, gathered_messages

    stream = io.StringIO()
    monkeypatch.setattr(sys, "stderr", stream)
    configure_logging()
    log = logging.getLogger("rotoruq.methods.demo")
    with gathered_messages() as got:
        for k in range(5):
            log.info("calibrate_bayes: 4 chains x %d kept steps", 100 + k)
        log.warning("a warning")
        log.info("emulator leave-one-out: f RMSE 0.01")
    assert stream.getvalue() == "a warning\n"  # at once; the INFO lines wait for the step
    assert got.lines() == ["calibrate_bayes: 4 chains x 100 kept steps (and 4 more like it)",
                           "emulator leave-one-out: f RMSE 0.01"]
    configure_logging(verbose=True)  # --verbose: each as it comes
    with gathered_messages() as got:
        log.info("calibrate_bayes: 4 chains x 7 kept steps")
    assert got.lines() == [] and stream.getvalue().endswith("x 7 kept steps\n")
    configure_logging()
