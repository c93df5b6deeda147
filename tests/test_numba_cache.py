"""numba's cache of a kernel goes stale when a kernel module it compiles in changes
(``rotoruq/_numba_cache.py``): numba alone keys a kernel by its own file."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

from rotoruq._numba_cache import PACKAGE, kernel_dependencies, source_stamp


def test_a_kernel_depends_on_the_kernel_modules_it_imports_and_on_no_other():
    def rel(f: str) -> list[str]:
        return [p.relative_to(PACKAGE).as_posix() for p in kernel_dependencies(PACKAGE / f)]

    assert rel("methods/mcmc/_kernels.py") == ["methods/_gp_mean.py", "methods/_vexp.py"]
    assert rel("methods/_gp_mean.py") == ["methods/_vexp.py"]
    # _compile.py names numba.njit in its text but holds no kernel
    assert rel("rotor/_kernel.py") == rel("methods/_vexp.py") == []


def test_the_stamp_changes_with_a_dependency_and_only_with_one(tmp_path):
    src = tmp_path / "rotoruq"
    shutil.copytree(PACKAGE, src, ignore=shutil.ignore_patterns("__pycache__"))
    kernels = src / "methods" / "mcmc" / "_kernels.py"
    before = source_stamp(kernels)
    assert [name for name, _ in before] == ["../_gp_mean.py", "../_vexp.py"]
    with open(src / "rotor" / "_kernel.py", "a", encoding="utf-8") as fh:
        fh.write("\n# another kernel module changed\n")
    kernel_dependencies.cache_clear()
    assert source_stamp(kernels) == before
    with open(src / "methods" / "_vexp.py", "a", encoding="utf-8") as fh:
        fh.write("\n# changed\n")
    kernel_dependencies.cache_clear()
    after = source_stamp(kernels)
    assert after[0] == before[0] and after[1] != before[1]


_WARM = """
import numpy as np
from rotoruq.methods._gp_mean import gp_mean_batch, gp_pack, _mean_rows
from rotoruq._compile import is_cached
print(is_cached(_mean_rows))
pack = gp_pack(np.zeros(1), np.ones(1), np.array([[0.2], [0.7]]), np.ones((1, 1)),
               np.ones((1, 2)), np.zeros((1, 1)), "constant", "sqexp", np.zeros(1), np.ones(1))
gp_mean_batch(np.array([[0.5]]), pack)
"""


def test_a_cached_kernel_is_compiled_again_after_an_edit_of_a_module_it_compiles_in(tmp_path):
    """End to end, in a copy of the package with its own cache: the emulator's batch kernel
    is cached after a first run, and cold again once ``_vexp.py`` (which it inlines)
    changes, although its own file did not (numba alone would load the stale code)."""
    shutil.copytree(PACKAGE, tmp_path / "rotoruq", ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    env.pop("NUMBA_CACHE_DIR", None)

    def cached() -> str:
        done = subprocess.run([sys.executable, "-c", _WARM], capture_output=True, text=True,
                              env=env, timeout=600, cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        return done.stdout.strip()

    assert cached() == "False"  # a fresh copy: nothing cached
    assert cached() == "True"
    with open(tmp_path / "rotoruq" / "methods" / "_vexp.py", "a", encoding="utf-8") as fh:
        fh.write("\n# an edit of a function the kernel inlines\n")
    assert cached() == "False"
    assert cached() == "True"
