"""Imperfect sensors and motors of the simulated body (docs/bodies.md).

``Imperfections`` holds what the body does wrong: joints that land off the
command (``arm.motor_noise``), receptor noise (``world.retina.noise``),
outputs rounded to a step (``world.retina.quantum``) and published in a
narrower type (``world.retina.dtype``), and lost frames
(``world.retina.dropout``). ``BodyNoise`` applies them, in this order on
each call:

    reached = commanded + N(0, motor_noise)          (B, J), motor unit
    raw     = receptors at reached                   (the simulator)
    raw    += N(0, noise)                            (B, R), before the code
    out     = quantum * round(code(raw) / quantum)   (quantum > 0)
    out     = out.astype(dtype)
    out[row] = NaN with probability dropout          (B,)

Every draw of a call comes from one generator of the named counter stream
``"body_noise"`` (``core.seeding.CounterStream``) at counter ``(call, 0)``
for the body's ``call``-th command, ``(change, 1)`` for the passive
sensation after change ``change``, motor draws first: the same seed gives the
same imperfections to the offline driver and to the body node, which number
their commands and changes alike, and a command answered twice is answered
alike. ``reached(commanded, call)`` replays the joints a call reached.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensorispace_ros.core.seeding import CounterStream

DTYPES = ("float64", "float32")
STREAM = "body_noise"
COMMAND, PASSIVE = 0, 1


@dataclass(frozen=True)
class Imperfections:
    """What the body does wrong; the defaults are a perfect body. Errors name
    the parameter."""

    noise: float = 0.0          # world.retina.noise
    quantum: float = 0.0        # world.retina.quantum
    dtype: str = "float64"      # world.retina.dtype
    dropout: float = 0.0        # world.retina.dropout
    motor_noise: float = 0.0    # arm.motor_noise

    def __post_init__(self):
        for name, value in (("world.retina.noise", self.noise),
                            ("world.retina.quantum", self.quantum),
                            ("arm.motor_noise", self.motor_noise)):
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name}: must be a finite number >= 0, got {value!r}")
        if not (np.isfinite(self.dropout) and 0.0 <= self.dropout < 1.0):
            raise ValueError(f"world.retina.dropout: must be >= 0 and < 1 (1 loses every "
                             f"frame), got {self.dropout!r}")
        if self.dtype not in DTYPES:
            raise ValueError(f"world.retina.dtype: must be one of {', '.join(DTYPES)}, "
                             f"got {self.dtype!r}")

    @property
    def perfect(self) -> bool:
        """True when the body is today's: exact joints, float64 sensations as computed."""
        return self == Imperfections()


class BodyNoise:
    """``Imperfections`` drawn from ``seed``'s counter stream ``"body_noise"``."""

    def __init__(self, imperfections: Imperfections, seed: int):
        self.imperfections = imperfections
        self.seed = int(seed)
        self._stream = CounterStream(self.seed, STREAM)
        self._dtype = np.dtype(imperfections.dtype)
        # Only a quantum or a type: nothing to draw, no generator to position.
        self._draws = (imperfections.noise, imperfections.dropout,
                       imperfections.motor_noise) != (0.0, 0.0, 0.0)

    def command(self, call: int) -> np.random.Generator | None:
        """The generator of the body's ``call``-th command (0 = the first)."""
        return self._stream.at(call, COMMAND) if self._draws else None

    def passive(self, change: int) -> np.random.Generator | None:
        """The generator of the passive sensation after change ``change``."""
        return self._stream.at(change, PASSIVE) if self._draws else None

    def reach(self, commanded: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
        """The joint values reached for ``commanded`` (B, J): the call's first draws."""
        sd = self.imperfections.motor_noise
        if sd == 0.0:
            return commanded
        return commanded + sd * rng.standard_normal(commanded.shape)

    def reached(self, commanded: np.ndarray, call: int) -> np.ndarray:
        """The joint values the body's ``call``-th command ``commanded`` reached
        (a replay: for an evaluator that has the commands, not the body)."""
        return self.reach(np.asarray(commanded, dtype=float), self.command(call))

    def perceive(self, raw: np.ndarray, code, rng: np.random.Generator | None) -> np.ndarray:
        """What reaches the agent of the receptors' ``raw`` outputs (B, R):
        noise, ``code`` (a ``SensorCode`` or None), quantum, type, lost rows."""
        imperfect = self.imperfections
        if imperfect.noise > 0.0:
            raw = raw + imperfect.noise * rng.standard_normal(raw.shape)
        out = raw if code is None else code.apply(raw)
        if imperfect.quantum > 0.0:
            out = imperfect.quantum * np.round(out / imperfect.quantum)
        out = out.astype(self._dtype, copy=False)
        if imperfect.dropout > 0.0:
            lost = rng.random(len(out)) < imperfect.dropout
            out[lost] = np.nan          # ``out`` is this call's own array
        return out
