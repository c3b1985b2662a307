"""How the naive agent tells, from its sensory flow alone, that its world
changed.

No one tells the agent when the environment changes. It knows motor states
whose sensation it has just sensed (its resting state, its anchor); sensed
again, such a state gives what it gave, up to the noise the agent measured
(``noise.measure_body``: a per-receptor standard deviation). A receptor
farther than ``Z_BAND`` standard deviations of a difference of two
sensings (sqrt 2 sd) from the remembered value is a change; float64
round-off bounds the band from below, so a noiseless body flags any change
of the bits that is more than round-off. A non-finite output (a lost frame)
is no evidence either way. A flag is confirmed by sensing the state once
more: a single wild output is not a change. ``Tripwire`` applies the test to
the sentinel rows that end every call of a reaction.
"""
from __future__ import annotations

import numpy as np

Z_BAND = 6.0
ROUND_OFF = 64 * np.finfo(float).eps


def tolerance(noise_sd: float, reference: np.ndarray) -> np.ndarray:
    """Per-receptor half-width of the band around ``reference``."""
    reference = np.asarray(reference, dtype=float)
    scale = np.where(np.isfinite(reference), np.abs(reference), 0.0)
    return np.maximum(Z_BAND * np.sqrt(2.0) * float(noise_sd), ROUND_OFF * np.maximum(scale, 1.0))


def band(noise_sd: float, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(low, high)``: what sensing the reference's state again may give
    without a change (a non-finite reference receptor accepts anything)."""
    reference = np.asarray(reference, dtype=float)
    half = tolerance(noise_sd, reference)
    finite = np.isfinite(reference)
    low = np.where(finite, reference - half, -np.inf)
    high = np.where(finite, reference + half, np.inf)
    return low, high


def differs(noise_sd: float, reference: np.ndarray, sensed: np.ndarray) -> bool:
    """Does ``sensed`` (the reference's motor state sensed again) lie outside
    the band? Receptors non-finite in either are left out."""
    reference = np.asarray(reference, dtype=float)
    sensed = np.asarray(sensed, dtype=float)
    both = np.isfinite(reference) & np.isfinite(sensed)
    half = tolerance(noise_sd, reference)
    return bool(np.any(np.abs(sensed - reference)[both] > half[both]))


class ChangeLog:
    """Every test the agent made: the row its reference was sensed at, the
    row of the test, whether it flagged a change, the motor state tested
    (body units) and what kind of test (``hold``: idle watching; ``cut``: a
    check after a reaction). Rows are the clock's (ground truth joins them)."""

    def __init__(self):
        self.reference_row: list[int] = []
        self.test_row: list[int] = []
        self.flagged: list[bool] = []
        self.motor_state: list[np.ndarray] = []
        self.kind: list[str] = []

    def add(self, reference_row: int, test_row: int, flagged: bool, motor_state, kind: str):
        self.reference_row.append(int(reference_row))
        self.test_row.append(int(test_row))
        self.flagged.append(bool(flagged))
        self.motor_state.append(np.asarray(motor_state, dtype=float).copy())
        self.kind.append(kind)

# ------------------------------------------------------------------ sentinels
# A reaction on the row clock is many calls to the body; the world may change
# between any two rows. ``Tripwire`` ends every call with the *sentinels*:
# motor states whose sensation in the world the reaction started in the agent
# holds. When each sensed again gives what it gave (``differs``), every row of
# the call saw that world, as far as the sentinels see. A sentinel sees a
# change only where it senses something that moves; a resting state that
# senses nothing in either world sees none, so a reaction watches, beside its
# resting state, a *lookout*: the known state that sensed most when the
# reaction began (``ClockedAgent.sense_sentinels``).


class WorldChanged(Exception):
    """A sentinel's sensation left its band: the world changed.
    ``args[0]``: the first sentinel's (the resting state's) sensation then,
    ``args[1]``: every sentinel's."""


class Tripwire:
    """The agent's body with the sentinel rows after every call while armed
    (``arm``), or after the call that makes ``every`` rows since they were last
    sensed (``flush`` senses them alone): their sensations are tested against those
    the agent holds (``differs``): when they pass, every row sent before them
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
        self.every = 0                 # rows a call may leave unwatched before the sentinels
        self._unwatched = 0            # rows sent since the sentinels were last sensed

    @property
    def armed(self) -> bool:
        return self._sentinel is not None

    def arm(self, motor_states, references, noise_sd: float) -> None:
        """Watch ``motor_states`` ``(K, M)`` (or one state) against their
        sensations ``references`` ``(K, S)``; the first is the resting state."""
        self._sentinel = np.asarray(motor_states, dtype=float).reshape(-1, self.n_motors)
        self._reference = np.asarray(references, dtype=float).reshape(len(self._sentinel), -1)
        self.noise_sd = float(noise_sd)
        self._unwatched = 0

    def disarm(self) -> None:
        self._sentinel = self._reference = None

    def rearm(self, references) -> None:
        """The same sentinels, held to ``references`` (their sensations in a new world)."""
        self._reference = np.asarray(references, dtype=float).reshape(len(self._sentinel), -1)

    def check(self) -> None:
        """Sense the sentinels alone (raises ``WorldChanged``)."""
        self.sense(np.zeros((0, self.n_motors)))

    def flush(self) -> None:
        """Sense the sentinels alone if rows went unwatched since they were
        last sensed (``every``): then every row sent saw the world held."""
        if self._sentinel is not None and self._unwatched:
            self.check()

    def sense(self, motor_states) -> np.ndarray:
        motor_states = np.asarray(motor_states, dtype=float).reshape(-1, self.n_motors)
        if self._sentinel is None:
            self.sent += len(motor_states)
            return self._body.sense(motor_states)
        if len(motor_states) and self._unwatched + len(motor_states) < self.every:
            self._unwatched += len(motor_states)      # watched by a later call's sentinels
            self.sent += len(motor_states)
            return self._body.sense(motor_states)
        self._unwatched = 0
        k = len(self._sentinel)
        sensed = self._body.sense(np.vstack([motor_states, self._sentinel]))
        self.rows += k
        self.sent += len(motor_states) + k
        watched = sensed[len(motor_states):]
        if any(differs(self.noise_sd, held, now)
               for held, now in zip(self._reference, watched)):
            raise WorldChanged(watched[0], watched)
        self.passed += 1
        self.passed_at = self.sent
        return sensed[:len(motor_states)]

    def move(self, motor_states) -> None:
        self.sense(motor_states)
