"""Which studies the reference covers and what ``rotoruq reproduce`` runs.

A study is one of the reference's only when its file declares ``[study] reference =
"thesis"`` (saved as ``reference`` in ``study.json``); its name then says which chapter it
is and its model preset must be the chapter's. A study that is merely called ``validation``
is a user's study like any other.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = ["NAME", "STUDIES", "CHAPTERS", "START_ORDER", "is_reference", "declaration_error"]

#: The reference's name, as a study file declares it.
NAME = "thesis"

#: The reference studies and the rotor preset each runs.
STUDIES = {"validation": "bo105", "experiment": "gvpm", "heldout": "gvpm"}

#: The chapters ``rotoruq reproduce`` runs (the bundled study files): the thesis's chapters 3
#: and 4, then the held-out validation of the GVPM ground effect with a model discrepancy
#: (beyond the thesis).
CHAPTERS = {"validation": "validation.toml", "experiment": "experiment.toml",
            "heldout": "heldout.toml"}

#: The order ``rotoruq reproduce`` starts the chapters in when it runs several at once: the
#: longest first (seconds per chapter on a quiet machine,
#: ``benchmarks/results/reproduce_time.json``; ``tests/test_reproduce_schedule.py`` checks
#: the order against it), so on two processes the two shorter ones share the second while
#: the longest runs (the chapters are independent: the order changes no number, only when
#: each ends).
START_ORDER = ("experiment", "heldout", "validation")


def is_reference(info: Mapping[str, Any]) -> bool:
    """Whether a saved study (its ``study.json``) is one of the reference's: it declares
    ``reference = "thesis"``, and its name and model preset are a chapter's."""
    if info.get("reference") != NAME:
        return False
    preset = (info.get("model") or {}).get("preset")
    name = info.get("name")
    return name in STUDIES and (preset is None or STUDIES[name] == preset)


def declaration_error(name: str, preset: str | None) -> tuple[str, str] | None:
    """What is wrong with a study file declaring ``reference = "thesis"`` with this study name
    and model preset, as (expected, found); None: nothing."""
    if name not in STUDIES:
        return (f"reference = \"{NAME}\" only on the reference's studies ("
                + ", ".join(f"{n} on the {p} preset" for n, p in STUDIES.items())
                + "); leave reference out for a study of your own",
                f"a study named {name!r}")
    if preset != STUDIES[name]:
        return (f"reference = \"{NAME}\" on study {name!r} only with preset = "
                f"\"{STUDIES[name]}\"", f"preset = {preset!r}" if preset else "an external model")
    return None
