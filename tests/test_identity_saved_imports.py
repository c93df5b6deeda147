"""The code identity's parsed imports kept between processes (issue 34: ``ast.parse`` of every
module a study's code touches cost a few tenths of a CPU second per process)."""

from __future__ import annotations

import json

import pytest

from rotoruq.evaluation import identity


@pytest.fixture
def fresh(tmp_path, monkeypatch):
    """identity with no parsed imports in memory and its saved file in tmp_path."""
    monkeypatch.setattr(identity, "_IMPORTS", {})
    monkeypatch.setattr(identity, "_SAVED", tmp_path / "__pycache__" / "imports.json")
    monkeypatch.setattr(identity, "_SAVED_STATE", {"loaded": False, "save": False})
    identity._closure.cache_clear()
    yield tmp_path
    identity._closure.cache_clear()


def test_saved_imports_give_the_same_parts_without_parsing(fresh, monkeypatch):
    want = identity.code_parts(["rotoruq.steps.bayes_calibration"])
    assert identity._SAVED_STATE["save"] and not identity._SAVED.exists()
    identity._save()  # what the exit hook writes
    rows = json.loads(identity._SAVED.read_text())
    assert len(rows) == len(identity._IMPORTS) > 10

    # a new process: nothing in memory, the file read at the first miss, nothing parsed
    monkeypatch.setattr(identity, "_IMPORTS", {})
    monkeypatch.setattr(identity, "_SAVED_STATE", {"loaded": False, "save": False})
    identity._closure.cache_clear()

    def no_parse(source, package):
        raise AssertionError("parsed although saved")

    monkeypatch.setattr(identity, "_parse_imports", no_parse)
    assert identity.code_parts(["rotoruq.steps.bayes_calibration"]) == want
    assert not identity._SAVED_STATE["save"]  # nothing new: nothing to write back


def test_an_unreadable_or_foreign_saved_file_is_parsed_again(fresh):
    identity._SAVED.parent.mkdir()
    identity._SAVED.write_text("{not json")
    want = identity.code_parts(["rotoruq.methods.mcmc.sbc"])
    assert want and identity._SAVED_STATE["loaded"]
    # an entry of another content (another checkout) is never used: keys carry the sha256
    identity._save()
    rows = json.loads(identity._SAVED.read_text())
    rows = [[n, p, "00" * 32, ["rotoruq.nowhere"]] for n, p, _, _ in rows]
    identity._SAVED.write_text(json.dumps(rows))
    identity._IMPORTS.clear()
    identity._SAVED_STATE.update(loaded=False)
    identity._closure.cache_clear()
    assert identity.code_parts(["rotoruq.methods.mcmc.sbc"]) == want


def test_an_unwritable_folder_keeps_nothing_and_fails_nothing(fresh, monkeypatch):
    blocker = fresh / "file"
    blocker.write_text("")
    monkeypatch.setattr(identity, "_SAVED", blocker / "sub" / "imports.json")
    identity.code_parts(["rotoruq.steps.pce"])
    identity._save()  # mkdir under a file fails: no error, no file
    assert not (blocker / "sub").exists()
