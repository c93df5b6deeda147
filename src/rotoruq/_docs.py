"""Docstring entries shared by several public names (scipy's ``doccer`` idea).

An entry that several functions take the same way (the fit settings of an airfoil's
constructors, the ``x``/``EvalBatch`` contract of every ``evaluate``) is written once, next to
the concept it describes, and filled into each docstring with :func:`fill_doc`, so the
rendered docs and numpydoc's validation see a complete docstring everywhere.
"""

from __future__ import annotations

import re
import textwrap
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")

_PLACEHOLDER = re.compile(r"^([ \t]*)%\((\w+)\)s[ \t]*$", re.MULTILINE)


def fill_doc(**parts: str) -> Callable[[T], T]:
    """Decorator: each line ``%(name)s`` of the docstring becomes ``parts[name]``, indented
    as the placeholder line is.

    Parameters
    ----------
    **parts : str
        Name -> the text of the entry (any common indentation is removed first).

    Returns
    -------
    callable
        The decorator; it sets ``__doc__`` and returns the object itself. A placeholder
        without a part raises ``KeyError`` at import, so a typo cannot ship.

    Examples
    --------
    >>> @fill_doc(x="x : float\\n    A number.")
    ... def f(x):
    ...     '''Twice x.
    ...
    ...     Parameters
    ...     ----------
    ...     %(x)s
    ...     '''
    >>> print(f.__doc__.splitlines()[4].strip(), f.__doc__.splitlines()[5].strip())
    x : float A number.
    """

    def fill(match: re.Match) -> str:
        return textwrap.indent(textwrap.dedent(parts[match.group(2)]).strip("\n"),
                               match.group(1))

    def apply(obj: T) -> T:
        obj.__doc__ = _PLACEHOLDER.sub(fill, obj.__doc__ or "")
        return obj

    return apply
