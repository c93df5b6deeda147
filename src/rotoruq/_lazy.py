"""Modules imported on their first use.

``rotoruq report`` of unchanged results reads saved numbers and copies figures from the
cache: it never evaluates a distribution, but :mod:`scipy.stats` (about 1 CPU-s to import)
was imported by every module that names it at the top. Such a module names it through
:func:`lazy_module` instead, so the import happens when a function first reaches into it::

    from typing import TYPE_CHECKING
    if TYPE_CHECKING:            # the type checker sees the real module
        from scipy import stats
    else:
        stats = lazy_module("scipy.stats")
"""

from __future__ import annotations

import importlib
import threading
import types
from typing import Any

__all__ = ["lazy_module", "LazyModule"]

_LOCK = threading.Lock()


class LazyModule(types.ModuleType):
    """A stand-in for the module ``name`` that imports it on the first attribute read.

    After the import the module's attributes are copied into the stand-in, so later reads
    are plain attribute lookups (no call through ``__getattr__``). The stand-in is not put in
    :data:`sys.modules`: ``"scipy.stats" in sys.modules`` stays a test of the real import.

    Parameters
    ----------
    name : str
        The dotted name of the module, as for :func:`importlib.import_module`.

    Examples
    --------
    >>> m = LazyModule("json")
    >>> m.dumps([1, 2])
    '[1, 2]'
    """

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.__dict__["_lazy_module"] = None

    def _load(self) -> types.ModuleType:
        module = self.__dict__["_lazy_module"]
        if module is None:
            with _LOCK:  # one import and one copy even when two threads start together
                module = self.__dict__["_lazy_module"]
                if module is None:
                    module = importlib.import_module(self.__name__)
                    for k, v in module.__dict__.items():
                        if not k.startswith("__"):
                            self.__dict__.setdefault(k, v)
                    self.__dict__["_lazy_module"] = module
        return module

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("__"):
            raise AttributeError(attr)
        return getattr(self._load(), attr)

    def __dir__(self) -> list[str]:
        return dir(self._load())

    def __repr__(self) -> str:
        state = "imported" if self.__dict__["_lazy_module"] is not None else "not imported"
        return f"<lazy module {self.__name__!r} ({state})>"


def lazy_module(name: str) -> Any:
    """The module ``name``, imported when one of its attributes is first read.

    Parameters
    ----------
    name : str
        Dotted module name (``"scipy.stats"``).

    Returns
    -------
    LazyModule
        A stand-in; typed ``Any`` (import the real module under ``TYPE_CHECKING`` for the
        type checker).

    Examples
    --------
    >>> colorsys = lazy_module("colorsys")
    >>> colorsys
    <lazy module 'colorsys' (not imported)>
    >>> colorsys.rgb_to_hsv(1.0, 0.0, 0.0)
    (0.0, 1.0, 1.0)
    >>> colorsys
    <lazy module 'colorsys' (imported)>
    """
    return LazyModule(name)
