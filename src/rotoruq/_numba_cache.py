"""numba's on-disk cache of rotoruq's kernels, keyed by every source a kernel compiles in.

numba keys a cached kernel by its own source file only. A kernel that calls (and so compiles
in) a function of another module kept the code of that function as it was when the kernel was
cached: after an edit of ``methods/_gp_mean.py`` or ``methods/_vexp.py``, the chain kernels
of ``methods/mcmc/_kernels.py`` loaded from the cache still computed the old emulator mean,
while the emulator's own batch kernel computed the new one (an editable install after a
``git pull`` would silently run the old code). Importing this module (every kernel module
does, before its first ``njit``) puts cache locators in front of numba's own that, for a file
of this package, add to numba's stamp of the file the digests of the package's kernel modules
it imports, directly or through another one (:func:`kernel_dependencies`): a change to any of
them makes the kernel's cache stale, and numba compiles it again. Files outside the package
keep numba's locators and stamps.
"""

from __future__ import annotations

import hashlib
import os
import re
from functools import cache
from pathlib import Path

from numba.core import caching

__all__ = ["kernel_dependencies", "source_stamp"]

PACKAGE = Path(__file__).resolve().parent
# ``from .x import``, ``from ..x.y import``: the relative imports of a kernel module
_RELATIVE_IMPORT = re.compile(r"^\s*from\s+(\.+)([\w.]*)\s+import", re.MULTILINE)


def _module_file(importer: Path, dots: str, name: str) -> Path | None:
    base = importer.parent
    for _ in range(len(dots) - 1):
        base = base.parent
    target = base.joinpath(*name.split(".")) if name else base
    for candidate in (target.with_suffix(".py"), target / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


# a compiled function's decorator or a decorator bound to a name (``_jit = nb.njit(...)``)
_KERNEL = re.compile(r"^\s*(@|\w+\s*=\s*)(nb|numba)\.njit\b", re.MULTILINE)


def _has_kernels(path: Path) -> bool:
    return _KERNEL.search(path.read_text(encoding="utf-8")) is not None


@cache
def kernel_dependencies(py_file: str | Path) -> tuple[Path, ...]:
    """The package's kernel modules (files with ``njit``) that ``py_file`` imports, directly
    or through another kernel module, sorted; ``py_file`` itself is not among them.

    Examples
    --------
    >>> [p.name for p in kernel_dependencies(PACKAGE / "methods" / "mcmc" / "_kernels.py")]
    ['_gp_mean.py', '_vexp.py']
    """
    start = Path(py_file).resolve()
    seen: set[Path] = set()
    todo = [start]
    while todo:
        path = todo.pop()
        for dots, name in _RELATIVE_IMPORT.findall(path.read_text(encoding="utf-8")):
            dep = _module_file(path, dots, name)
            if dep is not None and dep not in seen and dep != start and _has_kernels(dep):
                seen.add(dep)
                todo.append(dep)
    return tuple(sorted(seen))


def source_stamp(py_file: str | Path) -> tuple[tuple[str, str], ...]:
    """(file name relative to ``py_file``'s folder, SHA-1 of its bytes) of each of
    :func:`kernel_dependencies`: what this module adds to numba's stamp of ``py_file``."""
    here = Path(py_file).resolve().parent
    return tuple((os.path.relpath(p, here), hashlib.sha1(p.read_bytes()).hexdigest())
                 for p in kernel_dependencies(py_file))


def _ours(py_file: str) -> bool:
    try:
        Path(py_file).resolve().relative_to(PACKAGE)
    except ValueError:
        return False
    return True


def _with_dependencies(base: type) -> type:
    """``base`` (a numba cache locator) for the files of this package, its stamp with
    :func:`source_stamp` added."""

    class Locator(base):  # type: ignore[misc, valid-type]
        @classmethod
        def from_function(cls, py_func, py_file):
            if not _ours(py_file):
                return None
            return super().from_function(py_func, py_file)

        def get_source_stamp(self):
            return (super().get_source_stamp(), source_stamp(self._py_file))

    Locator.__name__ = Locator.__qualname__ = f"Rotoruq{base.__name__}"
    return Locator


def _install() -> None:
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    classes = getattr(impl, "_locator_classes", None)
    if classes is None or any(c.__name__.startswith("Rotoruq") for c in classes):
        return
    ours = [_with_dependencies(c) for c in classes
            if isinstance(c, type) and c.__name__ in ("UserProvidedCacheLocator",
                                                      "_UserProvidedCacheLocator",
                                                      "InTreeCacheLocator",
                                                      "_InTreeCacheLocator",
                                                      "UserWideCacheLocator",
                                                      "_UserWideCacheLocator")]
    classes[:0] = ours


_install()
