"""What the naive agent sensed since the environment last changed, and the
body proxy that answers from it.

Between two changes the environment is static and the body answers every
motor state on its own, so a motor state sensed again senses the same bits.
``CountingBody`` wraps the agent's body: it counts rows, calls and time per
stage of the agent, answers a call whose states were all sensed since the
last change from ``SensedSinceChange`` (no round trip), and can carry the
rows the agent expects to ask for next with the call it sends now
(``lookahead``). None of this changes a result: only fewer calls are sent.

The agent's motor coordinates are *phases*: each joint's value scaled so that
its period (as the body's description states it) is 2 pi. ``MotorPhase``
converts; ``CountingBody`` sends the body its own units. With periods of 2 pi
(radians) both conversions return their input unchanged.
"""
from __future__ import annotations

import contextlib
import itertools
import time

import numpy as np


class SensedSinceChange:
    """The motor states sensed since the environment last changed, with their
    sensations. The environment is static between two changes and the body
    answers each row on its own, so a state sensed again would sense the same
    bits: ``recall`` gives them without a ``sense`` call, ``lookup`` row by
    row. Whole calls so answered: the resting state after every change, rank
    tests and walk starts at states the search just probed; rows of a call:
    the centre of a rank test the sweep just sensed (docs/benchmarks.md). Rows are
    matched bit for bit: a key mixes a row's uint64 views (integer
    arithmetic, so a row has the same key in any batch; a float dot product
    does not), candidates must then have the same bits (-0.0 is not 0.0 here)."""

    # Odd 64-bit constants (splitmix64's); rows whose keys collide are caught
    # by the bitwise check.
    _MIX = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9,
                     0xD6E8FEB86659FD93], dtype=np.uint64)

    def __init__(self, n_motors: int, n_sensors: int):
        self._mix = np.resize(self._MIX, n_motors)
        self._index: dict[int, int] = {}         # key -> the first stored row with it
        self._motor_states = np.empty((1024, n_motors))
        self._sensations = np.empty((1024, n_sensors))
        self.count = 0

    def clear(self) -> None:
        self.count = 0
        self._index.clear()

    def recall(self, motor_states: np.ndarray) -> np.ndarray | None:
        """Sensations of ``motor_states`` if every row was sensed, else None."""
        if self.count == 0 or len(motor_states) == 0:
            return None
        if self._keys(motor_states[:1])[0] not in self._index:
            return None                          # the usual case: a new state
        sensations, found = self.lookup(motor_states)
        return sensations if found.all() else None

    def lookup(self, motor_states: np.ndarray):
        """Row by row: ``(sensations (K, S), found (K,) bool)``, the stored
        bits of each row sensed since the last change (NaN where not)."""
        sensations = np.full((len(motor_states), self._sensations.shape[1]), np.nan)
        if self.count == 0 or len(motor_states) == 0:
            return sensations, np.zeros(len(motor_states), dtype=bool)
        keys = self._keys(motor_states)
        where = np.array(list(map(self._index.get, keys, itertools.repeat(-1, len(keys)))),
                         dtype=np.int64)
        found = where >= 0
        found[found] = np.all(self._motor_states[where[found]].view(np.uint64) ==
                              motor_states[found].view(np.uint64), axis=1)
        sensations[found] = self._sensations[where[found]]
        return sensations, found

    def _keys(self, motor_states: np.ndarray) -> list[int]:
        """Each row's key: its uint64 views mixed (the same in any batch)."""
        return (motor_states.view(np.uint64) @ self._mix).tolist()

    def store(self, motor_states: np.ndarray, sensations: np.ndarray) -> None:
        end = self.count + len(motor_states)
        if end > len(self._motor_states):
            size = max(2 * len(self._motor_states), end)
            for name in ("_motor_states", "_sensations"):
                old = getattr(self, name)
                grown = np.empty((size,) + old.shape[1:], dtype=old.dtype)
                grown[:self.count] = old[:self.count]
                setattr(self, name, grown)
        keys = self._keys(motor_states)
        # Each key's first row: within the batch (reversed, so the first
        # overwrites), then against what was stored before.
        first = dict(zip(reversed(keys), range(end - 1, self.count - 1, -1)))
        for key in first.keys() & self._index.keys():
            del first[key]
        self._index.update(first)
        self._motor_states[self.count:end] = motor_states
        self._sensations[self.count:end] = sensations
        self.count = end


class MotorPhase:
    """Body units <-> phases (a joint's period maps to 2 pi), per joint."""

    def __init__(self, periods):
        periods = np.asarray(periods, dtype=float).reshape(-1)
        if not np.all(np.isfinite(periods)) or np.any(periods <= 0):
            raise ValueError(f"periods: must be finite and > 0, got {periods}")
        self.periods = periods
        self.identity = bool(np.all(periods == 2.0 * np.pi))
        self._to_phase = 2.0 * np.pi / periods
        self._to_body = periods / (2.0 * np.pi)

    def to_phase(self, motor: np.ndarray) -> np.ndarray:
        motor = np.asarray(motor, dtype=float)
        return motor if self.identity else motor * self._to_phase

    def to_body(self, phase: np.ndarray) -> np.ndarray:
        phase = np.asarray(phase, dtype=float)
        return phase if self.identity else phase * self._to_body


class CountingBody:
    """Counts rows, calls and wall time per stage of the agent; exposes only
    what the body exposes. A stage lasts from its ``stage = name`` to the
    next one (or to ``pause()``). With ``remember``, a call whose motor
    states were all sensed since the last ``forget()`` is answered from
    ``SensedSinceChange`` (counted in ``remembered``, not in ``calls``);
    with ``partial`` too, a call sends only its rows not sensed since then
    (the others counted in ``recalled``, not in ``rows``).
    Rows in and out are phases (``phase``, identity by default); the body is
    sent its own units. A row that comes back non-finite (a lost frame) is
    sensed again, ``retries`` times at most (each a call of the lost rows);
    one still lost is returned as it came (its users leave it out)."""

    def __init__(self, body, remember: bool = True, phase: MotorPhase | None = None,
                 retries: int = 0, partial: bool = False):
        self._body = body
        self.n_motors = int(body.n_motors)
        self.n_sensors = int(body.n_sensors)
        self._move = getattr(body, "move", None)
        self._stage = None
        self._since = 0.0
        self.rows: dict[str, int] = {}
        self.calls: dict[str, int] = {}
        self.seconds: dict[str, float] = {}
        self.remembered: dict[str, int] = {}
        self.recalled: dict[str, int] = {}
        self.partial = bool(partial)
        self._sensed = SensedSinceChange(self.n_motors, self.n_sensors) if remember else None
        self._lookahead: np.ndarray | None = None
        self.phase = phase if phase is not None else MotorPhase([2.0 * np.pi] * self.n_motors)
        self.retries = int(retries)
        self._fresh = False

    @property
    def stage(self) -> str | None:
        return self._stage

    @stage.setter
    def stage(self, name: str | None) -> None:
        now = time.perf_counter()
        if self._stage is not None:
            self.seconds[self._stage] = self.seconds.get(self._stage, 0.0) + now - self._since
        self._stage, self._since = name, now

    def pause(self) -> None:
        self.stage = None

    def forget(self) -> None:
        """The environment changed: what was sensed before says nothing now."""
        if self._sensed is not None:
            self._sensed.clear()

    @contextlib.contextmanager
    def lookahead(self, motor_states: np.ndarray):
        """Inside the block, the first call that goes to the body also carries
        ``motor_states`` (rows the agent expects to ask for next); their
        sensations are remembered, so a later call asking only for remembered
        states costs no round trip. Results are unchanged: every row is sensed
        on its own. Without ``remember`` it does nothing."""
        rows = np.ascontiguousarray(motor_states, dtype=float).reshape(-1, self.n_motors)
        self._lookahead = rows if self._sensed is not None and len(rows) else None
        try:
            yield
        finally:
            self._lookahead = None

    @contextlib.contextmanager
    def fresh(self):
        """Inside the block every call goes to the body, remembered or not:
        sensing a state again to average its noise."""
        self._fresh = True
        try:
            yield
        finally:
            self._fresh = False

    def _recall(self, motor_states: np.ndarray) -> np.ndarray | None:
        if self._sensed is None or self._fresh:
            return None
        return self._sensed.recall(motor_states)

    def _count(self, n_rows: int) -> None:
        self.rows[self.stage] = self.rows.get(self.stage, 0) + n_rows
        self.calls[self.stage] = self.calls.get(self.stage, 0) + 1

    def sense(self, motor_states):
        motor_states = np.ascontiguousarray(motor_states, dtype=float)
        if self.partial and self._sensed is not None and not self._fresh:
            return self._sense_new_rows(motor_states)
        known = self._recall(motor_states)
        if known is not None:
            self.remembered[self.stage] = self.remembered.get(self.stage, 0) + 1
            return known
        return self._command(motor_states)

    def _sense_new_rows(self, motor_states: np.ndarray) -> np.ndarray:
        """``sense`` with ``partial``: the rows sensed since the last change
        from memory, the others from the body (one call)."""
        known, found = self._sensed.lookup(motor_states)
        if found.all() and len(found):
            self.remembered[self.stage] = self.remembered.get(self.stage, 0) + 1
            return known
        if found.any():
            self.recalled[self.stage] = self.recalled.get(self.stage, 0) + int(found.sum())
            known[~found] = self._command(np.ascontiguousarray(motor_states[~found]))
            return known
        return self._command(motor_states)

    def rest(self, motor_state: np.ndarray) -> np.ndarray:
        """Move the arm to ``motor_state`` and return its sensation: always a
        command (the arm must end there). When the state was sensed since the
        last change and the body can ``move`` (the ROS agent collects that
        answer before it settles), the agent goes on without waiting."""
        row = np.ascontiguousarray(motor_state, dtype=float).reshape(1, -1)
        known = self._recall(row) if self._move is not None else None
        if known is None:
            return self._command(row)[0]
        self._count(1)
        self._move(self.phase.to_body(row))
        return known[0].copy()

    def _command(self, motor_states: np.ndarray) -> np.ndarray:
        asked = len(motor_states)
        if self._lookahead is not None:
            motor_states = np.concatenate([motor_states, self._lookahead])
            self._lookahead = None
        answer = self._ask(motor_states)
        lost = ~np.all(np.isfinite(answer), axis=1)
        for _ in range(self.retries):
            if not lost.any():
                break
            answer[lost] = self._ask(motor_states[lost])
            lost = ~np.all(np.isfinite(answer), axis=1)
        if self._sensed is not None:
            # A row still lost is not remembered: asked again, it is sensed again.
            self._sensed.store(motor_states[~lost], answer[~lost])
        return answer[:asked]

    def _ask(self, motor_states: np.ndarray) -> np.ndarray:
        self._count(len(motor_states))
        answer = np.array(self._body.sense(self.phase.to_body(motor_states)), dtype=float)
        if answer.shape != (len(motor_states), self.n_sensors):
            raise ValueError(f"body.sense returned shape {answer.shape}, expected "
                             f"({len(motor_states)}, {self.n_sensors})")
        return answer

    @property
    def total_rows(self) -> int:
        return sum(self.rows.values())

    @property
    def total_calls(self) -> int:
        return sum(self.calls.values())
