"""The order ``rotoruq reproduce`` starts its chapters in when it runs several at once: the
longest first, as the saved timing benchmark measured them on a quiet machine (issue 34)."""

import json
from pathlib import Path

from rotoruq.reference.studies import CHAPTERS, START_ORDER
from rotoruq.study.cmd_reproduce import start_order

RESULTS = Path(__file__).resolve().parents[1] / "benchmarks" / "results"


def test_every_chapter_has_its_place_and_the_order_keeps_every_name():
    assert sorted(START_ORDER) == sorted(CHAPTERS)
    assert start_order(list(CHAPTERS)) == list(START_ORDER)
    assert start_order(["validation", "heldout"]) == ["heldout", "validation"]
    assert start_order(["validation"]) == ["validation"]


def test_the_longest_chapter_starts_first_by_the_saved_timing_benchmark():
    saved = json.loads((RESULTS / "reproduce_time.json").read_text())
    assert not saved["quick"]
    took = {n: saved["seconds"][n] for n in CHAPTERS}
    assert sorted(took, key=took.get, reverse=True) == list(START_ORDER)
