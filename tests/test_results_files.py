"""The files a saved step leaves for users: every array with named columns as CSV beside the
.npy, values exact (shortest form that reads back to the same float)."""

from __future__ import annotations

import numpy as np
import pytest

from rotoruq.results import StepResult, load_step, save_step


def test_csv_copies_read_back_bitwise(tmp_path):
    rng = np.random.default_rng(3)
    chain = rng.normal(size=(20_000, 3)) * np.array([1e-12, 1.0, 3e7])
    chain[5, 1], chain[6, 2], chain[7, 0] = np.nan, np.inf, -0.0
    counts = np.arange(12).reshape(4, 3)
    res = StepResult("bayes", "bayes_calibration", {"ess/a": 12.5},
                     arrays={"chain": chain, "counts": counts, "flat": np.ones(4)},
                     meta={"columns": {"chain": ["a", "b", "c"], "counts": ["x", "y", "z"]}})
    folder = save_step(res, tmp_path)
    text = (folder / "chain.csv").read_text()
    assert text.splitlines()[0] == "a,b,c"
    back = np.loadtxt(folder / "chain.csv", delimiter=",", skiprows=1)
    assert back.shape == chain.shape
    assert np.array_equal(back, chain, equal_nan=True)
    assert np.array_equal(np.signbit(back), np.signbit(chain))
    assert np.array_equal(np.loadtxt(folder / "counts.csv", delimiter=",", skiprows=1), counts)
    assert not (folder / "flat.csv").exists()  # no column names, no CSV
    loaded = load_step(folder)
    assert np.array_equal(loaded.arrays["chain"], chain, equal_nan=True)
    assert not [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]


def _line_figure(res, ctx):
    from rotoruq.render.figures import Figure, _subplots

    fig, ax = _subplots(figsize=(3, 2))
    ax.plot(res.arrays["y"][:, 0])
    ax.set_xlabel("sample [-]")
    return [Figure(f"{res.name}_line", f"line of {res.name}", fig)]


def _lambda_figure(res, ctx):
    import time

    time.sleep(1.5)  # the report draws these itself first: the worker has time to claim
    return _line_figure(res, ctx)


def test_report_figures_survive_a_worker_that_cannot_import_their_hook(tmp_path, caplog,
                                                                     monkeypatch):
    """A figure hook the worker process cannot import (here: a test module's function) is
    drawn by the report itself after the worker fails; a hook that is no importable function
    at all (a lambda) is never sent. The page is the same as when drawn in one process."""
    import logging
    import re
    from types import MappingProxyType

    import rotoruq.steps
    from rotoruq.report.html import write_report
    from rotoruq.results import save_study_info
    from rotoruq.steps import STEP_TYPES, StepType

    monkeypatch.chdir(tmp_path)  # the worker cannot import this test module from here
    monkeypatch.setattr(rotoruq.steps, "STEP_TYPES", MappingProxyType({
        **STEP_TYPES, "test_line": StepType("test_line", run=None, figures=_line_figure),
        "test_lambda": StepType("test_lambda", run=None,
                                figures=lambda r, c: _lambda_figure(r, c))}))
    for k in range(3):
        for kind in ("test_line", "test_lambda"):
            save_step(StepResult(f"{kind}{k}", kind, {"a": 1.0},
                                 arrays={"y": np.arange(10.0 + k)[:, None]}), tmp_path)
    save_study_info(tmp_path, {"name": "lines", "parameters": {}})
    with caplog.at_level(logging.WARNING, logger="rotoruq.report.html"):
        two = write_report([tmp_path], tmp_path / "r2", workers=2).read_text()
    assert "figure worker failed" in caplog.text
    one = write_report([tmp_path], tmp_path / "r1", workers=1).read_text()

    def strip(page):
        return re.sub(r"Generated \S+ from [^<]*", "", page)

    assert strip(one) == strip(two)
    assert len(re.findall(r"<figure id=", two)) == 6
    assert len(list((tmp_path / "r2" / "figures").glob("*.png"))) == 6


def test_a_misspelled_scalar_raises_with_the_closest_names():
    """``StepResult.get`` of a key the step never saved raises (a typo must not read as NaN)
    and names the closest saved keys; an explicit default is returned as asked."""
    res = StepResult("fwd", "forward_check", {"mean/y1": 1.5, "std/y1": 0.25, "mean/y2": 3.0})
    assert res.get("mean/y1") == 1.5
    with pytest.raises(KeyError, match=r"saved no scalar 'men/y1' \(did you mean 'mean/y1'"):
        res.get("men/y1")
    with pytest.raises(KeyError, match="saved no scalar 'zzz'"):
        res.get("zzz")
    assert np.isnan(res.get("skewness/y1", np.nan))


def test_a_typed_record_round_trips_and_old_or_newer_saves_say_what_they_need(tmp_path):
    """A step's typed record is saved through the generic serializer (arrays with their axis
    names, names and numbers in meta) and read back by attribute; a typo names the field; a
    step saved without the record shows its flat view with the reason; a newer record or
    results schema is refused with the version it needs."""
    import json

    from rotoruq.report.steptables import step_tables
    from rotoruq.results import SCHEMA_VERSION, RecordError
    from rotoruq.steps.sensitivity import SensitivityRecord

    rng = np.random.default_rng(5)
    main, total = rng.random((2, 3)), rng.random((2, 3))
    ci = np.stack([main - 0.1, main + 0.1], axis=-1)
    rec = SensitivityRecord(("a", "b", "c"), ("y1", "y2"), main, total, ci, ci + 0.5,
                            np.array([1.0, 2.0]), np.array([0.25, 4.0]), 0.9)
    arrays, meta = rec.parts()
    assert meta["record"]["axes"]["main_ci"] == ["response", "input", "bound"]
    save_step(StepResult("sobol", "sensitivity", {"x": 1.0}, arrays, meta=meta), tmp_path)
    back = SensitivityRecord.read(load_step(tmp_path / "steps" / "sobol"))
    assert back.names_in == ("a", "b", "c") and back.confidence == 0.9
    assert np.array_equal(back.total_ci, ci + 0.5) and np.array_equal(back.main, main)
    with pytest.raises(AttributeError, match="did you mean 'main_ci'"):
        back.main_cl  # noqa: B018
    tables = step_tables(load_step(tmp_path / "steps" / "sobol"))
    assert tables[0].rows[1][1:4] == (2.0, 4.0, 2.0)  # mean, variance, std of y2
    assert tables[1].rows[2][1] == main[0, 2]
    with pytest.raises(ValueError, match="expected 3 axes"):
        SensitivityRecord(("a",), ("y",), main, total, main, ci, np.ones(2), np.ones(2),
                          0.9).parts()
    old = StepResult("old", "sensitivity", {"S/y1/a": 0.5}, meta={"inputs": ["a"]})
    (t,) = step_tables(old)
    assert t.rows == (("S/y1/a", 0.5),) and "saved without a SensitivityRecord" in t.note
    newer = dict(meta, record=dict(meta["record"], version=SensitivityRecord.VERSION + 1))
    with pytest.raises(RecordError, match="needs a newer rotoruq"):
        SensitivityRecord.read(StepResult("n", "sensitivity", arrays=arrays, meta=newer))
    doc = json.loads((tmp_path / "steps" / "sobol" / "result.json").read_text())
    assert doc["schema"] == SCHEMA_VERSION
    doc["schema"] = SCHEMA_VERSION + 1
    (tmp_path / "steps" / "sobol" / "result.json").write_text(json.dumps(doc))
    with pytest.raises(RecordError, match=f"reads up to schema {SCHEMA_VERSION}"):
        load_step(tmp_path / "steps" / "sobol")
