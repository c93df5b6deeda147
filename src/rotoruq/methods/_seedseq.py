"""A seed as a :class:`numpy.random.SeedSequence`, for methods that spawn independent streams."""

from __future__ import annotations

import numpy as np

from .._rng import SeedLike
from ..errors import ParameterError

__all__ = ["seed_sequence"]


def seed_sequence(seed: SeedLike) -> np.random.SeedSequence:
    """``seed`` (int >= 0, None, SeedSequence or Generator) as a SeedSequence; a Generator
    gives one drawn from it (so it advances). Other types raise :class:`ParameterError`."""
    if isinstance(seed, np.random.SeedSequence):
        return seed
    if isinstance(seed, np.random.Generator):
        return np.random.SeedSequence(int(seed.integers(2**63)))
    if seed is None:
        return np.random.SeedSequence()
    if isinstance(seed, bool | np.bool_) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ParameterError(f"seed must be a non-negative integer, None, a numpy SeedSequence "
                             f"or Generator; got {seed!r} ({type(seed).__name__})")
    return np.random.SeedSequence(int(seed))
