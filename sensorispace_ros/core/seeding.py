"""Named random streams derived from one seed.

Every random choice in the project draws from ``rng_for(seed, "<stream>")``.
Streams are keyed by name, not by the order in which they are created, so
adding a new random choice somewhere never shifts the numbers of another.
"""
from __future__ import annotations

import zlib

import numpy as np


def rng_for(seed: int, stream: str) -> np.random.Generator:
    """A generator for ``stream`` that depends only on (seed, stream)."""
    if int(seed) < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed}")
    key = zlib.crc32(stream.encode("utf-8"))
    return np.random.default_rng(np.random.SeedSequence([int(seed), key]))
