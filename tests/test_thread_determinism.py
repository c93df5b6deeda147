"""Same seed, same bits at any thread count (issue 35, item 4): studies run through
``rotoruq run`` in fresh processes with 1, 2 (and 4) threads for numba and BLAS, set before the
process starts, save bit-for-bit equal arrays. The calibration with a 300-point GP emulator and
its variance in the likelihood differed from the first chain row between 1 and 2 threads
before (LAPACK's trtri/potrf/getrf on two OpenBLAS threads). Every bundled study (the MBDyn
ones included) is run at its ``--quick`` size at 1 and at 2 threads by
``test_reproducible_studies.py``, which compares the two runs' arrays and records; the
validation study, where ``posterior_ratio`` moved by 0.4 %, at its own size and the 300-point
GP at 4 threads are ``extended`` checks (``pytest --extended``). The runs and the comparison
are ``benchmarks/thread_determinism.py``'s, which measures the same at 1, 2 and 4 threads."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from thread_determinism import GP_STUDY, differing, run_at  # noqa: E402


def same_bits(study, tmp_path: Path, threads=(1, 2), *, quick: bool = True,
              env: dict | None = None) -> None:
    first = tmp_path / f"t{threads[0]}"
    run_at(study, threads[0], first, quick=quick, env=env)
    for t in threads[1:]:
        run_at(study, t, tmp_path / f"t{t}", quick=quick, env=env)
        n, diffs = differing(first, tmp_path / f"t{t}")
        assert n > 0
        assert not diffs, f"{study}: {threads[0]} vs {t} threads: {diffs}"


# slow: runs in the main lane only; at the minimum versions (.ci/min_constraints.py) the two
# runs still differ (found by that lane, not yet explained: see the issue-35 note)
@pytest.mark.slow
@pytest.mark.parametrize("threads", [(1, 2), pytest.param((1, 4), marks=pytest.mark.extended)])
def test_a_300_point_gp_calibration_is_the_same_at_any_thread_count(threads, tmp_path):
    study = tmp_path / "gp300.toml"
    study.write_text(GP_STUDY)
    same_bits(study, tmp_path, threads, quick=False)
    chain = np.load(tmp_path / "t1" / "steps" / "bayes" / "chain.npy")
    assert chain.shape[0] > 100 and np.ptp(chain[:, 0]) > 0  # a chain that moved


def test_the_comparison_sees_a_last_bit(tmp_path):
    for d in ("a", "b"):
        (tmp_path / d / "steps" / "s").mkdir(parents=True)
        np.save(tmp_path / d / "steps" / "s" / "x.npy", np.array([1.0, 2.0]))
    np.save(tmp_path / "b" / "steps" / "s" / "x.npy", np.array([1.0, np.nextafter(2.0, 3.0)]))
    n, diffs = differing(tmp_path / "a", tmp_path / "b")
    assert n == 1 and diffs == {"steps/s/x.npy": pytest.approx(4.44e-16, rel=1e-3)}


def test_the_quick_study_is_the_same_at_1_and_2_threads(tmp_path):
    same_bits("quick", tmp_path)


@pytest.mark.slow
@pytest.mark.extended  # ~4-6 min
def test_the_validation_study_at_its_own_size_is_the_same_at_1_and_2_threads(tmp_path):
    same_bits("validation", tmp_path, quick=False)
