"""The report: thesis tables beside ours, claims, a self-contained page with figures, CSV."""

from __future__ import annotations

import base64
import re

import numpy as np
import pytest

from rotoruq.report.compare import claims, compare_tables, resolve
from rotoruq.report.html import write_report
from rotoruq.report.reference import TABLES, table
from rotoruq.study.cli import main
from rotoruq.study.results import StepResult
from rotoruq.study.runner import run_study
from test_runner import STUDY, linear_factory


def test_reference_tables_complete():
    numbers = [t.number for t in TABLES]
    assert numbers == [f"3.{i}" for i in range(1, 14)] + [f"4.{i}" for i in range(1, 20)]
    for t in TABLES:
        for _, cells in t.rows:
            assert len(cells) == len(t.columns)
    # spot checks against the thesis text
    assert table("3.6").rows[0][1][0][0] == 5.424e-1
    assert table("4.12").rows[3][1][0][0] == 353.4290
    assert table("4.18").rows[3][1][3][0] == 2.2985


def test_resolve_sources():
    steps = {"fwd": StepResult("fwd", "forward_check", {"mean/thrust@4": 26.0})}
    assert resolve("fwd:mean/thrust@4", steps) == 26.0
    assert resolve("fwd:mean/power@4", steps) is None
    assert resolve("other:mean/x", steps) is None
    assert resolve("data:thrust@1", steps) == pytest.approx(35.8256)
    assert resolve(None, steps) is None


def test_claims_count_within_one_std():
    nstd = {"thrust": 0.4, "roll": 0.2, "pitch": 1.3, "power": 0.9}
    scalars = {f"nstd/{k}@4": v for k, v in nstd.items()}
    results = {"experiment": {"forward_4r": StepResult("forward_4r", "forward_check", scalars)}}
    tables = compare_tables(results)
    t412 = next(t for t in tables if t.ref.number == "4.12")
    assert [cells[3].ours for _, cells in t412.rows] == [0.4, 0.2, 1.3, 0.9]
    assert t412.rows[0][1][3].diff == pytest.approx(0.4 - 0.12)
    c = next(c for c in claims(tables) if "at 4R" in c.text)
    assert c.ours == (3, 4) and c.thesis == (4, 4) and c.holds is False
    not_run = next(c for c in claims(tables) if "at 1R" in c.text)
    assert not_run.ours is None and not_run.holds is None and not_run.thesis == (3, 4)


def _run(tmp_path):
    p = tmp_path / "lin.toml"
    p.write_text(STUDY)
    return run_study(p, model_factory=linear_factory(), log=None)


def test_report_is_self_contained(tmp_path):
    run = _run(tmp_path)
    index = write_report([run.out], tmp_path / "report")
    page = index.read_text()
    imgs = re.findall(r"<img [^>]*src='data:image/png;base64,([^']+)'", page)
    assert len(imgs) >= 3  # truth loads, forward loads at two sweep points
    for b64 in imgs:
        assert base64.b64decode(b64)[:8] == b"\x89PNG\r\n\x1a\n"
    assert "Summary: claims of the reference study" in page
    assert "src='http" not in page and 'src="http' not in page
    pngs = sorted((tmp_path / "report" / "figures").glob("*.png"))
    svgs = sorted((tmp_path / "report" / "figures").glob("*.svg"))
    assert len(pngs) == len(imgs) == len(svgs)


def test_report_tables_as_csv(tmp_path):
    # a fake "experiment" output folder: saved results of one forward step
    from rotoruq.study.results import save_step

    out = tmp_path / "experiment"
    out.mkdir()
    (out / "study.json").write_text('{"name": "experiment", "steps": ["forward_4r"]}')
    scalars = {"mean/thrust@4": 26.0, "std/thrust@4": 3.0, "data/thrust@4": 25.6849,
               "nstd/thrust@4": abs(25.6849 - 26.0) / 3.0}
    arr = np.random.default_rng(0).normal(26.0, 3.0, (50, 1))
    save_step(StepResult("forward_4r", "forward_check", scalars, {"outputs@4": arr},
                         meta={"columns": {"outputs@4": ["thrust"]}, "labels": ["@4"]}), out)
    assert main(["report", str(out), "--out", str(tmp_path / "rep")]) == 0
    csv = (tmp_path / "rep" / "tables" / "table_4_12.csv").read_text().splitlines()
    assert csv[0] == "row,column,thesis,ours,ours_minus_thesis,relative,source"
    first = csv[1].split(",")
    assert first[:4] == ["Thrust T [N]", "Mean", "26.1148", "26.0"]
    page = (tmp_path / "rep" / "index.html").read_text()
    assert "Table 4.12" in page and "Table 3.4" not in page


def test_report_cli_rejects_empty_folder(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 1
    assert "a study output folder (with study.json)" in capsys.readouterr().err


@pytest.mark.slow
def test_reproduce_quick(tmp_path):
    """The bundled reference study, reduced (`rotoruq reproduce --quick`), end to end."""
    assert main(["reproduce", "all", "--quick", "--out", str(tmp_path)]) == 0
    page = (tmp_path / "report" / "index.html").read_text()
    for number in ("3.4", "3.9", "3.13", "4.9", "4.12", "4.14", "4.17", "4.19"):
        assert f"Table {number}:" in page
    assert "does not hold" in page or "holds" in page
    assert (tmp_path / "experiment" / "steps" / "bayes" / "chain.npy").is_file()
    assert (tmp_path / "report" / "figures" / "ground_effect_ct_vs_height.png").is_file()
