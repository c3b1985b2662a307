"""Sentinel rows: the naive agent's watch on its world while it works.

A reaction on the row clock is many calls to the body; the world may change
between any two rows. ``Tripwire`` ends every call with the *sentinels*:
motor states whose sensation in the world the reaction started in the agent
holds. When each sensed again gives what it gave (``change_detection.
differs``), every row of the call saw that world, as far as the sentinels
see. A sentinel sees a change only where it senses something that moves; a
resting state that senses nothing in either world sees none, so a reaction
watches, beside its resting state, a *lookout*: the known state that sensed
most when the reaction began (``ClockedAgent.sense_sentinels``).
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.naive import change_detection


class WorldChanged(Exception):
    """A sentinel's sensation left its band: the world changed.
    ``args[0]``: the first sentinel's (the resting state's) sensation then,
    ``args[1]``: every sentinel's."""


class Tripwire:
    """The agent's body with the sentinel rows after every call while armed
    (``arm``): their sensations are tested against those the agent holds
    (``change_detection.differs``): when they pass, every row of the call
    saw the world the agent holds. Rows are the body's units."""

    def __init__(self, body):
        self._body = body
        self.n_motors = int(body.n_motors)
        self.n_sensors = int(body.n_sensors)
        self.description = getattr(body, "description", None)
        self._sentinel = None
        self._reference = None
        self.noise_sd = 0.0
        self.rows = 0                  # sentinel rows sensed
        self.passed = 0                # calls whose sentinels passed
        self.sent = 0                  # rows sent to the body, sentinels included
        self.passed_at = 0             # ``sent`` after the last call whose sentinels passed

    @property
    def armed(self) -> bool:
        return self._sentinel is not None

    def arm(self, motor_states, references, noise_sd: float) -> None:
        """Watch ``motor_states`` ``(K, M)`` (or one state) against their
        sensations ``references`` ``(K, S)``; the first is the resting state."""
        self._sentinel = np.asarray(motor_states, dtype=float).reshape(-1, self.n_motors)
        self._reference = np.asarray(references, dtype=float).reshape(len(self._sentinel), -1)
        self.noise_sd = float(noise_sd)

    def disarm(self) -> None:
        self._sentinel = self._reference = None

    def rearm(self, references) -> None:
        """The same sentinels, held to ``references`` (their sensations in a new world)."""
        self._reference = np.asarray(references, dtype=float).reshape(len(self._sentinel), -1)

    def check(self) -> None:
        """Sense the sentinels alone (raises ``WorldChanged``)."""
        self.sense(np.zeros((0, self.n_motors)))

    def sense(self, motor_states) -> np.ndarray:
        motor_states = np.asarray(motor_states, dtype=float).reshape(-1, self.n_motors)
        if self._sentinel is None:
            self.sent += len(motor_states)
            return self._body.sense(motor_states)
        k = len(self._sentinel)
        sensed = self._body.sense(np.vstack([motor_states, self._sentinel]))
        self.rows += k
        self.sent += len(motor_states) + k
        watched = sensed[len(motor_states):]
        if any(change_detection.differs(self.noise_sd, held, now)
               for held, now in zip(self._reference, watched)):
            raise WorldChanged(watched[0], watched)
        self.passed += 1
        self.passed_at = self.sent
        return sensed[:len(motor_states)]

    def move(self, motor_states) -> None:
        self.sense(motor_states)
