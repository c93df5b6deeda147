"""Figures of earlier reports, kept so that a report of unchanged results redraws nothing.

A step's figures depend on the results of its study (the figure hook sees them all), on what
the report passes to the hook (labels, units, the application's numbers beside the run's,
the model's curves), on the code that draws and renders them and on Matplotlib. The cache
key is the sha256 of all of these: the fingerprint of every step of the study (a step's
fingerprint identifies its numbers: inputs, options, seed and the code that computes them),
the hook's name, the context as JSON, :func:`~rotoruq.evaluation.identity.code_version`
(the package's source), a digest of the report's own modules and Matplotlib's version. A
study with a step that has no fingerprint (results built by hand, not by the runner) is
never cached.

An entry is a folder ``<report>/.figure-cache/<key>/`` holding the rendered files and an
index with their sha256: an entry is only ever read as bytes (never unpickled), and one whose
files do not match its index counts as missing. Entries are written whole into a temporary
folder and renamed; a report removes the entries it did not use.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from ..safety import real_dir

__all__ = ["FigureCache", "CACHE_DIR"]

#: The cache folder inside a report folder.
CACHE_DIR = ".figure-cache"
_INDEX = "figures.json"


def _report_code_digest() -> str:
    here = Path(__file__).parent
    h = hashlib.sha256()
    for p in sorted(here.glob("*.py")):
        h.update(p.name.encode() + b"\0" + p.read_bytes() + b"\0")
    return h.hexdigest()


class FigureCache:
    """The rendered figures of the steps of earlier reports in ``report_dir``.

    Parameters
    ----------
    report_dir : path
        The report folder; the cache lives in its ``.figure-cache`` folder.

    Examples
    --------
    >>> import tempfile
    >>> cache = FigureCache(tempfile.mkdtemp())
    >>> cache.key("study", "lhs", "m:f", {"lhs": ""}, ({}, {}, None, {})) is None
    True
    """

    def __init__(self, report_dir: str | os.PathLike) -> None:
        self.root = Path(report_dir) / CACHE_DIR
        self._code: str | None = None
        self.used: set[str] = set()

    def _code_digest(self) -> str:
        if self._code is None:
            import matplotlib

            from ..evaluation.identity import code_version

            self._code = hashlib.sha256(
                f"{code_version()}|{_report_code_digest()}|{matplotlib.__version__}".encode()
            ).hexdigest()
        return self._code

    def key(self, study: str, step: str, hook: str | None, fingerprints: Mapping[str, str],
            context: Sequence[Any]) -> str | None:
        """The key of one step's figures; None when they cannot be cached (a hook another
        process cannot name, a step without a fingerprint, a context that is not JSON)."""
        if hook is None or not fingerprints or not all(fingerprints.values()):
            return None
        try:
            ctx = json.dumps(list(context), sort_keys=True, default=_no_json)
        except TypeError:
            return None
        doc = json.dumps({"study": study, "step": step, "hook": hook, "context": ctx,
                          "steps": dict(sorted(fingerprints.items())),
                          "code": self._code_digest()}, sort_keys=True)
        return hashlib.sha256(doc.encode()).hexdigest()

    def get(self, key: str | None, make: Callable[..., Any]) -> list[Any] | None:
        """The figures cached under ``key``, each built by ``make(name, caption, png, svg,
        xlabels, ylabels)``; None when there is no whole entry."""
        if key is None:
            return None
        folder = self.root / key
        try:
            index = json.loads((folder / _INDEX).read_text(encoding="utf-8"))
            out = []
            for i, f in enumerate(index):
                png, svg = (folder / f"{i}.png").read_bytes(), (folder / f"{i}.svg").read_bytes()
                if (hashlib.sha256(png).hexdigest() != f["png"]
                        or hashlib.sha256(svg).hexdigest() != f["svg"]):
                    return None
                out.append(make(str(f["name"]), str(f["caption"]), png, svg,
                                tuple(map(str, f["xlabels"])), tuple(map(str, f["ylabels"]))))
        except (OSError, ValueError, KeyError, TypeError):
            return None
        self.used.add(key)
        return out

    def put(self, key: str | None, figures: Sequence[Any]) -> None:
        """Keep ``figures`` (records with name, caption, png, svg, xlabels, ylabels) under
        ``key``; a cache that cannot be written is skipped (the report does not need it)."""
        if key is None:
            return
        try:
            real_dir(self.root, create=True)  # a planted link is refused, never followed
            tmp = Path(tempfile.mkdtemp(prefix=".tmp-", dir=self.root))
            index = []
            for i, f in enumerate(figures):
                (tmp / f"{i}.png").write_bytes(f.png)
                (tmp / f"{i}.svg").write_bytes(f.svg)
                index.append({"name": f.name, "caption": f.caption,
                              "png": hashlib.sha256(f.png).hexdigest(),
                              "svg": hashlib.sha256(f.svg).hexdigest(),
                              "xlabels": list(f.xlabels), "ylabels": list(f.ylabels)})
            (tmp / _INDEX).write_text(json.dumps(index), encoding="utf-8")
            dest = self.root / key
            if dest.exists():
                shutil.rmtree(dest, ignore_errors=True)
            os.replace(tmp, dest)
            self.used.add(key)
        except OSError:
            shutil.rmtree(locals().get("tmp", self.root / ".none"), ignore_errors=True)

    def prune(self) -> int:
        """Remove the entries this report did not use; returns how many."""
        try:
            real_dir(self.root)  # never prunes through a planted link
        except FileNotFoundError:
            return 0
        gone = 0
        for p in self.root.iterdir():
            if p.name not in self.used:
                shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)
                gone += 1
        return gone


def _no_json(obj: Any) -> Any:
    import numpy as np

    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(type(obj).__name__)
