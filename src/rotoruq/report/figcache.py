"""Figures of earlier reports, kept so that a report of unchanged results redraws nothing.

A step's figures depend on the step's results, on the other steps of its study the figure
hook read (the hook sees them all; the report notes those it looked at), on what the report
passes to the hook (labels, units, the application's numbers beside the run's, the model's
curves), on the code that draws and renders them and on Matplotlib. The cache key is the
sha256 of the step's fingerprint (it identifies its numbers: inputs, options, seed and the
code that computes them), the hook's name, the context as JSON,
:func:`~rotoruq.evaluation.identity.code_version` (the package's source), a digest of the
report's own modules and Matplotlib's version; the entry also keeps the fingerprints of the
other steps the hook read, and it is used only while they are the same. So a study whose one
step changed redraws that step's figures (and those of steps that read it), not all of them.
A step without a fingerprint (results built by hand, not by the runner), or whose hook read
one, is never cached.

An entry is a folder ``<report>/.figure-cache/<key>/`` holding the rendered files and an
index with their sha256: an entry is only ever read as bytes (never unpickled), and one whose
files do not match its index counts as missing. Entries are written whole into a temporary
folder and renamed; a report removes the entries it did not use. All of it goes through the
descriptor of the cache folder, opened without following a link: a symlink planted there
while a report is written is never followed.
"""

from __future__ import annotations

import hashlib
import json
import os
import secrets
import stat
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from ..safety import SafeFolder, UnsafePathError

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


def _matplotlib_version() -> str:
    # the installed version without importing Matplotlib (about 0.3 CPU-s) when this report
    # draws nothing; the imported module's own when it is loaded (the one that draws)
    module = sys.modules.get("matplotlib")
    if module is not None:
        return str(module.__version__)
    from importlib.metadata import version

    return version("matplotlib")


class FigureCache:
    """The rendered figures of the steps of earlier reports in ``report_dir``.

    Every entry is read, written and removed through the descriptor of the cache folder
    (opened without following a symlink, through the report folder's own descriptor when
    one is given): a link planted at ``.figure-cache``, at an entry or at a file of one,
    at any time, is never followed (a cache that cannot be used is skipped: the report
    draws the figures).

    Parameters
    ----------
    report_dir : path
        The report folder; the cache lives in its ``.figure-cache`` folder.
    folder : SafeFolder, optional
        The report folder, already open (the report writer's): the cache folder is opened
        in it, so a report folder swapped by its name does not redirect the cache.

    Examples
    --------
    >>> import tempfile
    >>> cache = FigureCache(tempfile.mkdtemp())
    >>> cache.key("study", "lhs", "m:f", "", ({}, {}, None, {})) is None
    True
    """

    def __init__(self, report_dir: str | os.PathLike, folder: SafeFolder | None = None
                 ) -> None:
        self.root = Path(report_dir) / CACHE_DIR
        self._report = folder
        self._root: SafeFolder | None = None
        self._code: str | None = None
        self.used: set[str] = set()

    def _open(self, create: bool) -> SafeFolder:
        """The cache folder, opened once (never through a link)."""
        if self._root is None:
            if self._report is not None:
                self._root = self._report.folder(CACHE_DIR, create=create)
            else:
                self._root = SafeFolder(self.root, create=create)
        return self._root

    def close(self) -> None:
        """Close the cache folder's descriptor."""
        if self._root is not None:
            self._root.close()
            self._root = None

    def __enter__(self) -> FigureCache:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _code_digest(self) -> str:
        if self._code is None:
            from ..evaluation.identity import code_version

            self._code = hashlib.sha256(
                f"{code_version()}|{_report_code_digest()}|{_matplotlib_version()}".encode()
            ).hexdigest()
        return self._code

    def key(self, study: str, step: str, hook: str | None, fingerprint: str,
            context: Sequence[Any]) -> str | None:
        """The key of one step's figures; None when they cannot be cached (a hook another
        process cannot name, a step without a fingerprint, a context that is not JSON)."""
        if hook is None or not fingerprint:
            return None
        try:
            ctx = json.dumps(list(context), sort_keys=True, default=_no_json)
        except TypeError:
            return None
        doc = json.dumps({"study": study, "step": step, "hook": hook, "context": ctx,
                          "fingerprint": fingerprint,
                          "code": self._code_digest()}, sort_keys=True)
        return hashlib.sha256(doc.encode()).hexdigest()

    def get(self, key: str | None, make: Callable[..., Any], fingerprints: Mapping[str, str]
            ) -> list[Any] | None:
        """The figures cached under ``key``, each built by ``make(name, caption, png, svg,
        xlabels, ylabels)``; None when there is no whole entry, or when a step its hook read
        has another fingerprint now (``fingerprints``: the study's steps, name -> fingerprint;
        a step gone counts as changed)."""
        if key is None:
            return None
        try:
            with self._open(create=False).folder(key, create=False) as entry:
                index = json.loads(entry.read(_INDEX).decode("utf-8"))
                reads = index["reads"]
                if any(not fp or fingerprints.get(name) != fp for name, fp in reads.items()):
                    return None
                out = []
                for i, f in enumerate(index["figures"]):
                    png, svg = entry.read(f"{i}.png"), entry.read(f"{i}.svg")
                    if (hashlib.sha256(png).hexdigest() != f["png"]
                            or hashlib.sha256(svg).hexdigest() != f["svg"]):
                        return None
                    out.append(make(str(f["name"]), str(f["caption"]), png, svg,
                                    tuple(map(str, f["xlabels"])),
                                    tuple(map(str, f["ylabels"]))))
        except (OSError, ValueError, KeyError, TypeError):  # UnsafePathError: a ValueError
            return None
        self.used.add(key)
        return out

    def put(self, key: str | None, figures: Sequence[Any], reads: Mapping[str, str]) -> None:
        """Keep ``figures`` (records with name, caption, png, svg, xlabels, ylabels) under
        ``key``, valid while the steps the hook read keep the fingerprints ``reads``; a
        cache that cannot be written (a full disk, a planted link) is skipped (the report
        does not need it), and figures whose hook read a step without a fingerprint are not
        kept."""
        if key is None or not all(reads.values()):
            return
        tmp = f".tmp-{secrets.token_hex(6)}"
        try:
            root = self._open(create=True)
        except (OSError, UnsafePathError):
            return
        try:
            with root.folder(tmp, new=True) as entry:
                index = []
                for i, f in enumerate(figures):
                    entry.write(f"{i}.png", f.png)
                    entry.write(f"{i}.svg", f.svg)
                    index.append({"name": f.name, "caption": f.caption,
                                  "png": hashlib.sha256(f.png).hexdigest(),
                                  "svg": hashlib.sha256(f.svg).hexdigest(),
                                  "xlabels": list(f.xlabels), "ylabels": list(f.ylabels)})
                entry.write(_INDEX, json.dumps({"figures": index, "reads": dict(reads)}
                                               ).encode("utf-8"))
            root.remove_tree(key)
            os.replace(tmp, key, src_dir_fd=root.fd, dst_dir_fd=root.fd)
            self.used.add(key)
        except (OSError, UnsafePathError):
            try:
                root.remove_tree(tmp)
            except (OSError, UnsafePathError):
                pass

    def prune(self) -> int:
        """Remove the entries this report did not use; returns how many."""
        try:
            root = self._open(create=False)  # never prunes through a planted link
        except (OSError, UnsafePathError):
            return 0
        gone = 0
        for name in os.listdir(root.fd):
            if name in self.used:
                continue
            st = root.lstat(name)
            try:
                if st is not None and stat.S_ISDIR(st.st_mode):
                    root.remove_tree(name)
                else:
                    os.unlink(name, dir_fd=root.fd)  # a file or a link: the link itself
            except OSError:
                continue
            gone += 1
        return gone


def _no_json(obj: Any) -> Any:
    import numpy as np

    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(type(obj).__name__)
