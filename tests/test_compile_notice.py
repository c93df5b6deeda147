"""A first run on a cold numba cache says what it compiles before it compiles (issue 34): the
chain and emulator kernels, as the rotor's (tests/test_cli.py)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import logging, numpy as np
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    import rotoruq as rq
    f = rq.FunctionModel(lambda x: x[:, :1] * 2.0, ["a"], ["y"])
    prior = rq.ParameterSpace({"a": rq.Uniform(0.0, 1.0)})
    rq.calibrate_bayes(f, np.array([[1.0]]), prior, noise=rq.NoiseModel(noise_std=0.1),
                       chains=rq.ChainOptions(n_samples=50, burn_in=0),
                       emulator=rq.EmulatorOptions(rq.GaussianProcess(),
                                                   n_emulator_samples=8))
""")


def test_a_cold_cache_names_the_kernels_before_compiling_them(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT], env=env, cwd=tmp_path,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        said = []
        for line in proc.stderr:  # ended once it has named one family, not left to compile
            if line.startswith("compiling "):
                said.append(line.strip())
                break
        assert said, "no notice before compiling"
        assert said[0] in ("compiling emulator kernels (once per install, ~10-60 s) ...",
                           "compiling chain kernels (once per install, ~10-60 s) ..."), said
    finally:
        proc.kill()
        proc.wait()


ONCE = textwrap.dedent("""
    import numpy as np
    import rotoruq as rq
    from rotoruq.methods.mcmc import _kernels as kn
    f = rq.FunctionModel(lambda x: x[:, :1] * 2.0, ["a"], ["y"])
    prior = rq.ParameterSpace({"a": rq.Uniform(0.0, 1.0)})
    for emulator in (rq.EmulatorOptions(rq.GaussianProcess(), n_emulator_samples=8), None):
        rq.calibrate_bayes(f, np.array([[1.0]]), prior, noise=rq.NoiseModel(noise_std=0.1),
                           chains=rq.ChainOptions(n_samples=50, burn_in=0),
                           emulator=emulator, seed=0)
    print([len(k.signatures) for k in (kn.advance, kn.propose, kn._step, kn._after_step)])
""")


@pytest.mark.slow
@pytest.mark.extended  # a cold numba compile of the chain kernels: minutes on 2 cores
def test_each_step_kernel_is_compiled_once_on_a_cold_cache(tmp_path):
    """Chains on an emulator (the compiled driver) and on a Python model (the Python driver)
    in one process with an empty numba cache compile each step kernel once: the compiled
    driver passes typed constants, not literals that numba would specialise on."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    done = subprocess.run([sys.executable, "-c", ONCE], env=env, cwd=tmp_path,
                          capture_output=True, text=True, timeout=1200)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "[1, 1, 1, 1]", done.stdout
