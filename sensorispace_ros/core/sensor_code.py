"""Sensor codes: a fixed invertible transform of the receptor outputs.

The retina's outputs ``s`` (shape ``(..., R)``, entries >= 0) pass through a
code before the agent sees them; the naive agent should not depend on it.
Kinds (``world.retina.code``, parameter ``v = world.retina.code_value > 0``):

- ``identity``  ``s`` unchanged (same values, bit for bit; ``v`` unused)
- ``scale``     ``v * s``
- ``log``       ``log(v + s)``, finite because ``s >= 0`` and ``v > 0``
- ``power``     ``s ** v``
- ``mix``       ``M @ s`` per row, ``M`` a fixed ``R x R`` matrix with
  singular values ``geomspace(1, 1/v, R)`` between two random orthogonal
  matrices: largest singular value 1, condition number ``v`` (``v >= 1``).
  For ``R = 1`` the matrix is ``[[1]]`` and its condition number 1.

Every code is injective on ``s >= 0``, so distinct sensations stay distinct.
"""
from __future__ import annotations

import numpy as np

CODES = ("identity", "scale", "log", "power", "mix")


def _random_orthogonal(rng: np.random.Generator, size: int) -> np.ndarray:
    """Haar-distributed orthogonal matrix (QR of a Gaussian, signs fixed)."""
    q, r = np.linalg.qr(rng.standard_normal((size, size)))
    return q * np.where(np.diag(r) < 0, -1.0, 1.0)


def mixing_matrix(rng: np.random.Generator, size: int, condition: float) -> np.ndarray:
    """``size x size`` matrix, largest singular value 1, condition number ``condition``."""
    if size == 1:
        return np.ones((1, 1))
    singular = np.geomspace(1.0, 1.0 / condition, size)
    return (_random_orthogonal(rng, size) * singular) @ _random_orthogonal(rng, size)


def _check_kind(kind: str) -> str:
    if kind not in CODES:
        raise ValueError(f"world.retina.code: must be one of {', '.join(CODES)}, got {kind!r}")
    return kind


def _check_value(kind: str, value: float) -> float:
    value = float(value)
    if not np.isfinite(value) or value <= 0:
        raise ValueError(f"world.retina.code_value: must be > 0 and finite, got {value}")
    if kind == "mix" and value < 1:
        raise ValueError(f"world.retina.code_value: must be >= 1 for mix "
                         f"(a condition number), got {value}")
    return value


def _check_receptors(receptors: int) -> int:
    if int(receptors) != receptors or receptors < 1:
        raise ValueError(f"world.retina.receptors: must be an integer >= 1, got {receptors}")
    return int(receptors)


class SensorCode:
    """One code of the receptor outputs, fixed at construction."""

    def __init__(self, kind: str, value: float, receptors: int,
                 rng: np.random.Generator | None = None):
        self.kind = _check_kind(kind)
        self.value = _check_value(kind, value)
        self.receptors = _check_receptors(receptors)
        self.matrix = None
        if kind == "mix":
            if rng is None:
                raise ValueError("world.retina.code: mix needs a numpy Generator (rng)")
            self.matrix = mixing_matrix(rng, self.receptors, self.value)

    @property
    def is_identity(self) -> bool:
        return self.kind == "identity"

    def apply(self, sensations: np.ndarray) -> np.ndarray:
        """Coded sensations, ``(..., R) -> (..., R)``."""
        s = np.asarray(sensations, dtype=float)
        if s.ndim == 0 or s.shape[-1] != self.receptors:
            raise ValueError(f"sensations: last axis must have world.retina.receptors = "
                             f"{self.receptors} entries, got shape {s.shape}")
        if self.kind == "identity":
            return s
        if self.kind == "scale":
            return self.value * s
        if self.kind == "log":
            return np.log(self.value + s)
        if self.kind == "power":
            return s ** self.value
        return s @ self.matrix.T
