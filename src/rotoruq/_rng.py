"""Random-number generator helper: every random method takes a keyword-only ``seed`` (an int,
None, a :class:`numpy.random.SeedSequence` or a :class:`numpy.random.Generator`) and turns it into
a Generator with :func:`as_generator`. The same seed gives the same numbers, bitwise."""

from __future__ import annotations

import numbers

import numpy as np

from .errors import ParameterError

SeedLike = int | np.random.Generator | np.random.SeedSequence | None

__all__ = ["SeedLike", "as_generator", "as_seed_sequence"]


def as_generator(seed: SeedLike = None) -> np.random.Generator:
    """Return a Generator: ``seed`` itself if it is one, else ``numpy.random.default_rng(seed)``.

    Raises :class:`~rotoruq.errors.ParameterError` for anything but a non-negative integer,
    None, a SeedSequence or a Generator: ``True``/``False`` (a bool is an int to Python, so
    ``seed=True`` would silently mean seed 1), floats (``1.5`` is not a seed, and ``1.0`` hides a
    computed value), strings and arrays.

    Parameters
    ----------
    seed : int, SeedSequence, Generator or None
        The random source: a Generator is used as it is (and advances), an int >= 0 or a
        SeedSequence seeds a new one, None seeds one from fresh OS entropy.
    """
    if seed is None or isinstance(seed, np.random.Generator | np.random.SeedSequence):
        return seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    if isinstance(seed, bool | np.bool_) or not isinstance(seed, numbers.Integral):
        raise ParameterError(
            f"seed must be a non-negative integer, None, a numpy SeedSequence or Generator; "
            f"got {seed!r} ({type(seed).__name__})"
        )
    if int(seed) < 0:
        raise ParameterError(f"seed must be a non-negative integer, got {int(seed)}")
    return np.random.default_rng(int(seed))


def as_seed_sequence(seed: SeedLike = None) -> np.random.SeedSequence:
    """``seed`` as a :class:`numpy.random.SeedSequence`, for methods that spawn independent
    streams (one child per stage or replication): a SeedSequence itself, a Generator gives one
    drawn from it (so it advances), an int or None its own. Other types raise
    :class:`~rotoruq.errors.ParameterError`, as :func:`as_generator` does.

    Examples
    --------
    >>> as_seed_sequence(3).entropy
    3
    """
    if isinstance(seed, np.random.SeedSequence):
        return seed
    if isinstance(seed, np.random.Generator):
        return np.random.SeedSequence(int(seed.integers(2**63)))
    as_generator(seed)  # the same checks
    return np.random.SeedSequence(None if seed is None else int(seed))
