"""Exceptions raised by rotoruq.

Every error about a file names the file, the line and what was expected, so that a user can fix
the input without reading the source.
"""

from __future__ import annotations

from os import PathLike

__all__ = [
    "RotoruqError",
    "InputFileError",
    "ParameterError",
    "EvaluationError",
    "ModelShapeError",
    "InfrastructureError",
    "StoreError",
    "StoreCorruptError",
]


class RotoruqError(Exception):
    """Base class of every rotoruq error."""


class InputFileError(RotoruqError, ValueError):
    """A malformed input file (c81 table, study file, Dakota parameters/results file).

    Parameters
    ----------
    path : str or PathLike
        The file.
    line : int or None
        1-based line number where the problem was found (None when it concerns the whole file).
    expected : str
        What was expected at that place, in words.
    found : str, optional
        What was found instead (shortened in the message).
    """

    def __init__(
        self,
        path: str | PathLike | None,
        line: int | None,
        expected: str,
        found: str | None = None,
    ):
        self.path = str(path) if path is not None else "<string>"
        self.line = line
        self.expected = expected
        self.found = found
        where = self.path if line is None else f"{self.path}, line {line}"
        msg = f"{where}: expected {expected}"
        if found is not None:
            shown = found if len(found) <= 80 else found[:77] + "..."
            msg += f", found {shown!r}"
        super().__init__(msg)


class ParameterError(RotoruqError, ValueError):
    """An invalid parameter definition or value (unknown name, std <= 0, inverted bounds...)."""


class EvaluationError(RotoruqError, RuntimeError):
    """An evaluation failed and the failure policy says to stop."""


class ModelShapeError(RotoruqError, ValueError):
    """A model returned an array of the wrong shape."""


class InfrastructureError(RotoruqError, RuntimeError):
    """The machinery running the evaluations failed (a lost Dask worker, a killed process-pool
    worker, a broken connection), not the model: nothing about the points it was running is
    stored, and running the same command again evaluates only the missing points."""


class StoreError(RotoruqError, OSError):
    """The evaluation store cannot be read or written (disk full, read-only folder, ...); the
    message names the file and what to do.

    Parameters
    ----------
    path : str or PathLike
        The store's file.
    problem : str
        What went wrong, in words.
    remedy : str
        What to do about it, in words.
    """

    def __init__(self, path: str | PathLike, problem: str, remedy: str):
        self.path = str(path)
        self.problem = problem
        self.remedy = remedy
        super().__init__(f"{self.path}: {problem}; {remedy}")

    def __str__(self) -> str:  # OSError would format (errno, strerror) otherwise
        return f"{self.path}: {self.problem}; {self.remedy}"


class StoreCorruptError(StoreError):
    """The evaluation store file is damaged (truncated, overwritten, not a database).

    Parameters
    ----------
    path : str or PathLike
        The store's file.
    problem : str
        What is damaged, in words.
    remedy : str
        What to do about it, in words.
    """
