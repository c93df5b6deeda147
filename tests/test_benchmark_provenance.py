"""A benchmark's saved JSON knows what it measured, and the docs say when that code changed.

- Every JSON the docs quote (through a ``<!-- generated: -->`` block) records a
  ``provenance`` block: the commit and the digests of the rotoruq modules its benchmark
  imports (``benchmarks/_provenance.py``, on ``identity.module_digests``).
- Every script that saves such a JSON adds that block (``provenance(``) to what it saves.
- ``stale`` recomputes the digests and names the modules and files that changed; the docs
  build puts a warning box under every block whose JSON is stale (``generated_blocks``'s
  Sphinx hook). Staleness does not fail CI: the stale JSONs are listed as a warning of this
  run and in a box on the built page until the benchmark runs again.
"""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
sys.path.insert(0, str(ROOT / "benchmarks"))

import _provenance  # noqa: E402
import generated_blocks  # noqa: E402

QUOTED = sorted({j for b in generated_blocks.blocks()
                 for j in generated_blocks.results_of(b.command)})


def _script_of(result: str) -> Path:
    """The script that saved ``result``: the one its provenance names (a benchmark may save
    several results, e.g. ``reproduce_cpu.py --cold``), else ``<stem>.py``."""
    path = ROOT / result
    script = (json.loads(path.read_text(encoding="utf-8")).get("provenance") or {}).get("script")
    if script:
        return ROOT / script
    # a script may save several results named after it (rotor_throughput_loaded.json)
    stem = next((p for p in ("multifidelity_mbdyn", "rotor_throughput")
                 if path.stem.startswith(p)), path.stem)
    return ROOT / path.parts[len(ROOT.parts)] / f"{stem}.py"


def test_the_docs_quote_saved_results():
    assert "benchmarks/results/gp_fit.json" in QUOTED and len(QUOTED) >= 15, QUOTED


@pytest.mark.parametrize("result", QUOTED)
def test_quoted_result_records_its_provenance(result):
    prov = json.loads((ROOT / result).read_text(encoding="utf-8")).get("provenance")
    assert prov, f"{result} records no provenance: run its benchmark again"
    assert {"commit", "date", "script", "modules", "files"} <= set(prov), (result, sorted(prov))
    assert prov["modules"] and all(m.startswith("rotoruq") for m in prov["modules"]), result
    assert (ROOT / prov["script"]).is_file(), (result, prov["script"])


@pytest.mark.parametrize("result", QUOTED)
def test_quoted_result_is_saved_with_provenance(result):
    script = _script_of(result)
    assert script.is_file(), f"no script for {result}"
    text = script.read_text(encoding="utf-8")
    assert 'provenance(' in text and "from _provenance import provenance" in text, (
        f"{script.relative_to(ROOT)} saves {result} without its provenance")


def test_stale_quoted_results_are_listed():
    """Not a failure (a change to measured code must not turn CI red): the stale results are a
    warning of the test run, and a box under their numbers in the built docs."""
    notes = [n for r in QUOTED if (n := _provenance.stale_note(r))]
    if notes:
        warnings.warn(f"{len(notes)} quoted benchmark results measured code that has changed "
                      "since:\n" + "\n".join(notes), stacklevel=1)


def _fresh(tmp_path: Path) -> Path:
    script = tmp_path / "bench.py"
    script.write_text("import rotoruq as rq\nfrom rotoruq.methods.sensitivity import sobol\n"
                      "rq.sample\n", encoding="utf-8")
    result = tmp_path / "bench.json"
    result.write_text(json.dumps({"x": 1, "provenance": _provenance.provenance(script)}),
                      encoding="utf-8")
    return result


def test_provenance_keys_the_imported_modules(tmp_path):
    prov = json.loads(_fresh(tmp_path).read_text())["provenance"]
    assert set(prov["modules"]) == {"rotoruq.methods.sensitivity", "rotoruq.methods.sampling"}
    assert "rotoruq/methods/sensitivity.py" in prov["files"]
    assert len(prov["commit"]) == 40 or prov["commit"] == "unknown"
    assert _provenance.stale(prov) == {}
    assert _provenance.stale_note(_fresh(tmp_path)) == ""


def test_a_changed_module_is_named(tmp_path):
    result = _fresh(tmp_path)
    doc = json.loads(result.read_text())
    doc["provenance"]["modules"]["rotoruq.methods.sampling"] = "0" * 16
    doc["provenance"]["files"]["rotoruq/methods/sampling.py"] = "0" * 16
    result.write_text(json.dumps(doc))
    assert _provenance.stale(doc["provenance"]) == {
        "rotoruq.methods.sampling": ["rotoruq/methods/sampling.py"]}
    note = _provenance.stale_note(result)
    assert note.startswith("stale: ") and "`rotoruq.methods.sampling`" in note, note
    assert "rotoruq.methods.sensitivity" not in note and doc["provenance"]["commit"][:10] in note


def test_no_provenance_is_stale():
    assert _provenance.stale(None) == {"(no provenance)": []}
    assert _provenance.stale({"commit": "abc"}) == {"(no provenance)": []}


def test_docs_build_puts_a_box_under_a_stale_block(tmp_path, monkeypatch):
    result = _fresh(tmp_path)
    page = ("text\n\n<!-- generated: python benchmarks/gp_fit.py --summary RESULT -->\n"
            "numbers\n<!-- end generated -->\n\nmore\n")
    page = page.replace("RESULT", str(result))
    assert generated_blocks.with_stale_notes(page) == page   # fresh: no box
    doc = json.loads(result.read_text())
    doc["provenance"]["modules"]["rotoruq.methods.sampling"] = "0" * 16
    result.write_text(json.dumps(doc))
    built = generated_blocks.with_stale_notes(page)
    assert "<!-- end generated -->\n\n:::{warning}\nstale: " in built, built
    assert built.endswith(":::\n\nmore\n"), built
    # the page itself is never rewritten with the box: the block check compares page and JSON
    assert generated_blocks.BLOCK.search(built)["body"] == "numbers\n"


def test_a_reviewed_change_is_accepted_in_the_json(tmp_path, monkeypatch):
    result = _fresh(tmp_path)
    doc = json.loads(result.read_text())
    measured = doc["provenance"]["commit"]
    doc["provenance"]["modules"]["rotoruq.methods.sampling"] = "0" * 16
    result.write_text(json.dumps(doc, indent=1))
    with pytest.raises(ValueError, match="reason"):
        _provenance.accept(result, " ")
    assert _provenance.accept(result, "a refactoring, bitwise identical") == {
        "rotoruq.methods.sampling": ["(files it no longer imports)"]}
    prov = json.loads(result.read_text())["provenance"]
    assert prov["commit"] == measured and _provenance.stale(prov) == {}
    assert prov["accepted"][0]["reason"] == "a refactoring, bitwise identical"
    assert prov["accepted"][0]["modules"] == ["rotoruq.methods.sampling"]
    assert _provenance.accept(result, "again") == {}
