"""scripts/kernel_bits.py, the bit-for-bit check of the compiled kernels across a change of
how they are compiled (issue 34): it passes on unchanged code and names an array whose last
bit moved."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "kernel_bits.py"


def _script():
    spec = importlib.util.spec_from_file_location("kernel_bits", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_the_bits_check_passes_on_the_same_code_and_sees_a_last_bit(tmp_path, capsys):
    bits = _script()
    path = tmp_path / "bits.npz"
    assert bits.main(["save", str(path), "--parts", "chains"]) == 0
    assert bits.main(["check", str(path), "--parts", "chains"]) == 0
    assert "bitwise equal" in capsys.readouterr().out
    with np.load(path) as saved:
        arrays = dict(saved)
    draws = arrays["chains.gp_var.draws"]
    draws.flat[17] = np.nextafter(draws.flat[17], np.inf)
    np.savez(path, **arrays)
    assert bits.main(["check", str(path), "--parts", "chains"]) == 1
    out = capsys.readouterr().out
    assert "chains.gp_var.draws" in out and "chains.model.draws" not in out
