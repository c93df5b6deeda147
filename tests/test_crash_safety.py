"""A study killed with SIGKILL part way resumes: same results, no finished evaluation re-run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections import Counter

import numpy as np

from rotoruq.evaluation.store import Store

# Driver: a slow solver that records every evaluation it finishes in a side file.
DRIVER = r'''
import os, sys, time
params, results = sys.argv[1], sys.argv[2]
lines = open(params).read().splitlines()
n = int(lines[0].split()[0])
x = {tag: val for val, tag in (l.split() for l in lines[1 : 1 + n])}
a = float(x["a"])
time.sleep(0.1)
open(results, "w").write(f"{a * a + 1.0!r} f\n{a ** 0.5!r} g\n")
with open(os.environ["SIDE_FILE"], "a") as f:
    f.write(x["a"] + "\n")
'''

# The study: 12 external evaluations through the Evaluator, results saved at the end.
STUDY = r'''
import sys
import numpy as np
from rotoruq.evaluation.evaluator import Evaluator
from rotoruq.evaluation.external import ExternalModel
db, driver, work, out, executor = sys.argv[1:6]
x = np.linspace(1.0, 12.0, 12)[:, None] * np.pi
m = ExternalModel([sys.executable, "-S", driver], ["a"], ["f", "g"], workdir=work)
with Evaluator(m, store=db, study="crash", executor=executor) as ev:
    res = ev.evaluate(x)
np.save(out, res.values)
'''


def run_study(tmp_path, tag, side, executor="processes:2", wait=True):
    env = {**os.environ, "SIDE_FILE": str(side)}
    args = [sys.executable, str(tmp_path / "study.py"), str(tmp_path / f"{tag}.db"),
            str(tmp_path / "driver.py"), str(tmp_path / f"work_{tag}"),
            str(tmp_path / f"{tag}.npy"), executor]
    proc = subprocess.Popen(args, env=env, start_new_session=True, stderr=subprocess.PIPE)
    if wait:
        _, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err.decode()
    return proc


def test_sigkill_then_resume(tmp_path):
    (tmp_path / "driver.py").write_text(DRIVER)
    (tmp_path / "study.py").write_text(STUDY)
    # uninterrupted reference run
    run_study(tmp_path, "ref", tmp_path / "side_ref")
    ref = np.load(tmp_path / "ref.npy")
    a = np.linspace(1.0, 12.0, 12) * np.pi
    np.testing.assert_array_equal(ref, np.c_[a * a + 1.0, np.sqrt(a)])

    # killed run: SIGKILL the study (and its pool workers) once 4 evaluations are committed
    side = tmp_path / "side"
    proc = run_study(tmp_path, "crash", side, wait=False)
    db = tmp_path / "crash.db"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if db.exists() and Store(db).count() >= 4:
            break
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(10)
    assert proc.returncode == -signal.SIGKILL
    time.sleep(0.5)  # orphaned drivers of the killed workers finish (they are not committed)
    committed = [r.inputs[0] for r in Store(db).records()]
    assert 4 <= len(committed) < 12, "the study was not killed part way"
    assert not (tmp_path / "crash.npy").exists()

    # resume: same results as the uninterrupted run
    run_study(tmp_path, "crash", side)
    np.testing.assert_array_equal(np.load(tmp_path / "crash.npy"), ref)
    recs = Store(db).records()
    assert len(recs) == 12 and all(r.status == "ok" for r in recs)
    assert len({r.inputs[0] for r in recs}) == 12  # every point committed exactly once
    runs = Counter(float(s) for s in side.read_text().split())
    for x in committed:
        assert runs[x] == 1, f"finished evaluation a={x} ran {runs[x]} times"
    assert set(runs) == set(a)
    # at most the evaluations in flight at the kill ran twice
    assert sum(runs.values()) - 12 <= 2
    # the store exports what the study computed
    tab = np.loadtxt(Store(db).export_tabular(tmp_path / "crash.dat"), comments="%",
                     usecols=(2, 3, 4))
    np.testing.assert_array_equal(tab[np.argsort(tab[:, 0])], np.c_[a, ref])
