"""Random-number generator helpers: every random method takes ``seed`` as an int, None or a
:class:`numpy.random.Generator` and turns it into a Generator with :func:`as_generator`."""

from __future__ import annotations

import numpy as np

SeedLike = int | np.random.Generator | np.random.SeedSequence | None

__all__ = ["SeedLike", "as_generator", "spawn"]


def as_generator(seed: SeedLike = None) -> np.random.Generator:
    """Return a Generator: ``seed`` itself if it is one, else ``numpy.random.default_rng(seed)``."""
    if isinstance(seed, np.random.Generator):
        return seed
    return np.random.default_rng(seed)


def spawn(seed: SeedLike, n: int) -> list[np.random.Generator]:
    """Return ``n`` independent generators derived from ``seed`` (for parallel chains/workers)."""
    if isinstance(seed, np.random.Generator):
        seqs = seed.bit_generator.seed_seq.spawn(n)  # type: ignore[attr-defined]
    elif isinstance(seed, np.random.SeedSequence):
        seqs = seed.spawn(n)
    else:
        seqs = np.random.SeedSequence(seed).spawn(n)
    return [np.random.default_rng(s) for s in seqs]
