"""`--summary JSON`: print README's paragraph for a saved benchmark result instead of running;
:func:`print_and_save`: print a result as JSON and save it where ``--json`` asked."""

from __future__ import annotations

import json
from collections.abc import Callable


def print_saved_summary(path: str | None, summary: Callable[[dict], str]) -> bool:
    """Print ``summary`` of the JSON saved at ``path``; False (nothing printed) without a path."""
    if not path:
        return False
    with open(path, encoding="utf-8") as fh:
        print(summary(json.load(fh)))
    return True


def print_and_save(result: dict, path: str | None) -> None:
    """Print ``result`` as indented JSON and, with a ``path``, write the same text there."""
    text = json.dumps(result, indent=1)
    print(text)
    if path:
        with open(path, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")
