"""Each observation calibrates once, by content (issue 35, item 3): the same rows under another
data-set name (an alias of the same CSV) or in a copy of the CSV are refused when a step
conditions on an earlier one that calibrated them, naming both data sets and the rows;
``reuse_data = true`` still allows it; other rows of the same file are new observations. Each
case goes through ``rotoruq run`` on a study file in a fresh folder: the runs in a subprocess,
the refusals (the study is read, no step runs) in this process (``rotoruq_main``)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

CLI = [sys.executable, "-m", "rotoruq.study.cli"]

CSV = "height,y1,y2\n1.0,0.9,0.1\n2.0,1.1,-0.1\n3.0,1.0,0.05\n4.0,1.3,0.2\n"

HEAD = """\
[study]
name = "reuse"
seed = 1

[model]
function = "text_book"
responses = ["y1", "y2"]

[parameters.a]
distribution = "normal"
mean = 0.0
std = 1.0

[parameters.b]
distribution = "normal"
mean = 0.0
std = 1.0

"""


def _step(name: str, data: str, extra: str = "") -> str:
    return textwrap.dedent(f"""
        [[steps]]
        name = "{name}"
        type = "bayes_calibration"
        emulator = "none"
        data = "{data}"
        noise_std = {{ y1 = 0.2, y2 = 0.2 }}
        n_samples = 100
        """) + extra


def _write(folder: Path, data: str, second: str, extra: str = "") -> None:
    (folder / "obs.csv").write_text(CSV)
    text = (HEAD + data + _step("first", "obs")
            + _step("second", second, 'from = "first.posterior"\n' + extra))
    (folder / "study.toml").write_text(text)


def show(folder: Path, data: str, second: str, extra: str = "") -> subprocess.CompletedProcess:
    _write(folder, data, second, extra)
    return subprocess.run([*CLI, "run", str(folder / "study.toml"), "--out",
                           str(folder / "out"), "--no-report", "-q"], capture_output=True,
                          text=True, timeout=300, cwd=folder)


OBS = '[data.obs]\nfile = "obs.csv"\n\n'


@pytest.fixture
def refused(rotoruq_main, tmp_path, monkeypatch):
    """The refusal of ``rotoruq run`` (in this process, from the study's folder) of the study
    ``_write`` makes of its arguments, its stderr on one line."""
    monkeypatch.chdir(tmp_path)

    def run(data: str, second: str, extra: str = "") -> str:
        _write(tmp_path, data, second, extra)
        code, _, err = rotoruq_main("run", tmp_path / "study.toml", "--out", tmp_path / "out",
                                    "--no-report", "-q")
        assert code != 0
        return " ".join(err.split())

    return run


def test_an_alias_of_the_same_file_is_refused_naming_both_data_sets_and_rows(refused):
    err = refused(OBS + '[data.again]\nfile = "obs.csv"\n\n', "again")
    assert "study.toml" in err and "already calibrates y1, y2 of data set 'obs'" in err
    assert "data set 'again' (obs.csv) holds the same values (rows 1-4)" in err
    assert "reuse_data = true" in err


def test_a_copy_of_the_csv_is_refused(tmp_path, refused):
    (tmp_path / "copy.csv").write_text(CSV)
    err = refused(OBS + '[data.copy]\nfile = "copy.csv"\n\n', "copy")
    assert "data set 'copy' (copy.csv) holds the same values (rows 1-4)" in err
    assert "as data set 'obs' (obs.csv)" in err


def test_inline_columns_repeating_some_rows_name_those_rows(refused):
    data = OBS + "[data.some]\nheight = [5.0, 2.0, 4.0]\ny1 = [2.0, 1.1, 1.3]\n\n"
    err = refused(data, "some", 'responses = ["y1"]\n')
    assert "already calibrates y1 of data set 'obs'" in err
    assert "data set 'some' holds the same values (rows 2-3)" in err


@pytest.mark.slow  # two calibrations run; the refusals above stop when the study is read
def test_reuse_data_true_allows_it_and_new_rows_are_not_reuse(tmp_path):
    alias = OBS + '[data.again]\nfile = "obs.csv"\n\n'
    proc = show(tmp_path, alias, "again", "reuse_data = true\n")
    assert proc.returncode == 0, proc.stderr[-2000:]
    # the same file's other rows (a select) are new observations
    split = ('[data.obs]\nfile = "obs.csv"\nselect = { height = 1.0 }\n\n'
             '[data.later]\nfile = "obs.csv"\nselect = { height = 4.0 }\n\n')
    proc = show(tmp_path, split, "later")
    assert proc.returncode == 0, proc.stderr[-2000:]
