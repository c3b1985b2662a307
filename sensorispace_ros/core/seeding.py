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


class CounterStream:
    """A counter-based stream: ``at(a, b)`` is the generator of draw ``(a, b)``
    of ``(seed, stream)``, the same whenever and however often it is asked
    for, whatever was drawn before (Philox: key ``(seed, crc32(stream))``,
    counter ``(0, 0, a, b)``; the draws of one ``at`` advance the low words).
    For choices that two processes must make alike without sharing their
    call order, keyed by something both know (a command's number)."""

    def __init__(self, seed: int, stream: str):
        if int(seed) < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed}")
        key = np.array([int(seed), zlib.crc32(stream.encode("utf-8"))], dtype=np.uint64)
        self._bits = np.random.Philox(key=key)
        self._generator = np.random.Generator(self._bits)
        # Setting a whole state is ~10x cheaper than building a Philox per draw.
        self._state = {"bit_generator": "Philox",
                       "state": {"counter": np.zeros(4, dtype=np.uint64), "key": key},
                       "buffer": np.zeros(4, dtype=np.uint64), "buffer_pos": 4,
                       "has_uint32": 0, "uinteger": 0}

    def at(self, a: int, b: int = 0) -> np.random.Generator:
        """The generator at counter ``(a, b)``; the previous one handed out is reset."""
        counter = self._state["state"]["counter"]
        counter[:2] = 0
        counter[2], counter[3] = int(a), int(b)
        self._bits.state = self._state
        return self._generator
