"""`--summary JSON`: print README's paragraph for a saved benchmark result instead of running."""

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
