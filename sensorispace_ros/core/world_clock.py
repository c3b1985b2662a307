"""A world on its own clock: the environment changes whatever the agent does.

Time is the motor states the body executes (``rows``). ``change_rows`` draws
when the world changes: after a seeded, exponentially distributed number of
rows (mean ``interval``) from the previous change. ``ClockedBody`` wraps a
simulated body and applies each change before the row it falls on, in the
middle of a batch too (the rows after it see the new world): the agent gets
no notice, no call per change.

An idle agent's time passes too: ``hold`` keeps the arm at one motor state
for as long as its sensation stays within a band the caller gives (or the
world ends) and returns the first sensation outside it, in one call. The
band is the caller's (the agent's test of its own noise); the body only
watches its sensor, as a robot's threshold does. Held rows are time, not
probing: they are counted apart (``held_rows``).

Ground truth for the evaluator (never the agent's): the row of every change,
the world state of any row (``state_at``), and for each change how far it
moved the sensation at the resting arm (``rest_jumps``).
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.seeding import rng_for

CLOCK_STREAM = "world.clock"
HOLD_CHUNK = 4096          # held rows simulated per batch on a noisy body


def change_rows(n_changes: int, interval: float, seed: int) -> np.ndarray:
    """``(n_changes,)`` nondecreasing rows before which change ``k`` (1-based
    world state ``k + 1``) takes effect: cumulative exponential gaps of mean
    ``interval`` rows (stream ``world.clock``), at least one row each."""
    if interval <= 0:
        raise ValueError(f"interval: must be > 0, got {interval!r}")
    gaps = rng_for(seed, CLOCK_STREAM).exponential(float(interval), size=int(n_changes))
    return np.cumsum(np.maximum(1, np.ceil(gaps))).astype(np.int64)


def clock_events(world, cfg: dict) -> list:
    """The changes a world on its own clock plays: the schedule, twice when the
    agent has an equality pass (``naive.clock_equality_changes``), as
    ``core.clocked_run.explore_clocked`` plays it."""
    return list(world.events) * _plays(cfg)


def clock_change_rows(cfg: dict, n_events: int) -> np.ndarray:
    """``change_rows`` of the changes ``clock_events`` plays for a schedule of
    ``n_events`` changes (``world.change_interval``, ``seed``)."""
    return change_rows(n_events * _plays(cfg), cfg["world"]["change_interval"], cfg["seed"])


def clock_plays(equality_changes: int) -> int:
    """How often the world plays its schedule: twice when the agent has an
    equality pass (``equality_changes`` > 0), for simulation 2."""
    return 2 if equality_changes > 0 else 1


def _plays(cfg: dict) -> int:
    return clock_plays(cfg["naive"]["clock_equality_changes"])


def world_on_clock(body, world, events: list, *, interval: float) -> "ClockedBody":
    """``body`` in ``world`` on a row clock: the changes ``events`` (the
    schedule as played), a change every ``interval`` rows on average
    (``change_rows`` of the world's seed)."""
    return ClockedBody(body, [world.initial_lights] + [e.lights for e in events],
                       change_rows(len(events), interval, world.seed))


def clock_body(body, world, cfg: dict) -> "ClockedBody":
    """``world_on_clock`` as configuration ``cfg`` has it (``clock_events``,
    ``world.change_interval``)."""
    return world_on_clock(body, world, clock_events(world, cfg),
                          interval=cfg["world"]["change_interval"])


class ClockedBody:
    """``body`` (a ``SimulatedBody``) in a world that changes on a row clock.

    ``lights[k]`` are the lights of world state ``k`` (0: the initial one),
    ``rows[k - 1]`` the row before which state ``k`` begins. ``sense``,
    ``move`` and ``hold`` execute rows in order; a batch that a change falls
    into is split there."""

    def __init__(self, body, lights: list, rows: np.ndarray):
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        if len(lights) != len(rows) + 1:
            raise ValueError(f"lights: need {len(rows) + 1} states for {len(rows)} changes")
        if len(rows) and (rows[0] < 1 or np.any(np.diff(rows) < 0)):
            raise ValueError("rows: must be nondecreasing and >= 1")
        self._body = body
        self._lights = [np.asarray(x, dtype=float) for x in lights]
        self.change_row = rows
        self.n_motors = int(body.n_motors)
        self.n_sensors = int(body.n_sensors)
        self.description = getattr(body, "description", None)
        self.row = 0                 # rows executed (probes and holds)
        self.held_rows = 0           # of which held
        self.state = 0               # world state of the next row
        self.rest_jumps = np.full(len(rows), np.nan)
        body.set_lights(self._lights[0], change=0)

    # ------------------------------------------------------------- clock

    @property
    def lights(self) -> list:
        """The lights of every world state (ground truth)."""
        return list(self._lights)

    @property
    def ended(self) -> bool:
        """Every change has happened."""
        return self.state >= len(self.change_row)

    def state_at(self, row) -> np.ndarray:
        """World state of row(s) ``row`` (ground truth)."""
        return np.searchsorted(self.change_row, np.asarray(row), side="right")

    def _advance_to(self, row: int) -> None:
        """Apply every change due before ``row``."""
        while self.state < len(self.change_row) and self.change_row[self.state] <= row:
            self._change()

    def _change(self) -> None:
        before = self._resting_truth()
        self.state += 1
        self._body.set_lights(self._lights[self.state], change=self.state)
        after = self._resting_truth()
        if before is not None:
            self.rest_jumps[self.state - 1] = float(np.max(np.abs(after - before)))

    def _resting_truth(self):
        """The body's noiseless sensation at its resting arm (None: a body
        that cannot say, or an arm not yet moved)."""
        truth = getattr(self._body, "resting_truth", None)
        return None if truth is None else truth()

    def position(self) -> np.ndarray:
        """Where the clock and the arm stand: ``[row, held_rows, calls,
        motor state..., physics...]`` (``calls``: the body's commands, which
        number its noise draws; the motor state NaN before the first command;
        ``physics``: the body's ``physics_state``, what its next settle steps
        from, none for a body whose answers depend on the command alone).
        What a restarted body node goes on from (``resume``)."""
        motor = getattr(self._body, "motor_state", None)
        motor = np.full(self.n_motors, np.nan) if motor is None else np.asarray(motor, float)
        calls = getattr(self._body, "calls", 0)
        return np.concatenate([[self.row, self.held_rows, calls], motor.reshape(-1),
                               self._physics()])

    @property
    def position_size(self) -> int:
        """The length of ``position()``'s vector."""
        return 3 + self.n_motors + len(self._physics())

    def _physics(self) -> np.ndarray:
        state = getattr(self._body, "physics_state", None)
        return np.zeros(0) if state is None else np.asarray(state(), dtype=float)

    def resume(self, position) -> None:
        """Stand where ``position`` (``position()``'s vector) says: the world in
        the state of that row, the body's command count, arm and physics as
        they were. The same commands from there are answered bit for bit as
        the first time. The changes skipped over are not seen again: their
        ``rest_jumps`` stay unknown (NaN)."""
        position = np.asarray(position, dtype=float).reshape(-1)
        if len(position) != self.position_size or not np.all(np.isfinite(position[:3])):
            raise ValueError(f"position: need row, held rows, calls, {self.n_motors} joints and "
                             f"{self.position_size - 3 - self.n_motors} physics values, "
                             f"got {len(position)} values")
        row, held, calls = (int(x) for x in position[:3])
        if not 0 <= held <= row:
            raise ValueError(f"position: held rows {held} outside [0, row {row}]")
        self.row, self.held_rows = row, held
        self.state = int(self.state_at(row))
        self._body.set_lights(self._lights[self.state], change=self.state)
        if hasattr(self._body, "calls"):
            self._body.calls = calls
        motor, physics = np.split(position[3:], [self.n_motors])
        if hasattr(self._body, "motor_state"):
            self._body.motor_state = motor.copy() if np.all(np.isfinite(motor)) else None
        if len(physics):
            self._body.set_physics_state(physics)

    # ------------------------------------------------------------- body

    def _segments(self, n: int):
        """``(start, stop)`` slices of the next ``n`` rows, split at changes."""
        start = 0
        while start < n:
            self._advance_to(self.row + start)
            stop = n
            if self.state < len(self.change_row):
                stop = min(n, int(self.change_row[self.state]) - self.row)
            yield start, stop
            start = stop

    def sense(self, motor_states: np.ndarray) -> np.ndarray:
        motor_states = np.asarray(motor_states, dtype=float)
        out = np.empty((len(motor_states), self.n_sensors))
        for start, stop in self._segments(len(motor_states)):
            out[start:stop] = self._body.sense(motor_states[start:stop])
        self.row += len(motor_states)
        self._advance_to(self.row)
        return out

    def move(self, motor_states: np.ndarray) -> None:
        self.sense(motor_states)

    def hold(self, motor_state: np.ndarray, low: np.ndarray, high: np.ndarray):
        """Hold the arm at ``motor_state`` until its sensation leaves
        ``[low, high]`` (per receptor; a non-finite output is no evidence).
        Returns that sensation, or None when the world has no change left
        (the run is over). One call."""
        row = np.asarray(motor_state, dtype=float).reshape(1, -1)
        while True:
            if self.ended:
                return None
            n = int(self.change_row[self.state]) - self.row
            outside = self._watch(row, max(n, 0), low, high)
            if outside is not None:
                return outside
            # The next row is the first of a new world state.
            self._advance_to(self.row)
            outside = self._watch(row, 1, low, high)
            if outside is not None:
                return outside

    def _watch(self, row: np.ndarray, n: int, low, high):
        """Hold ``n`` rows in the current state; the first sensation outside
        the band (its row counted) or None after all ``n``."""
        noisy = getattr(self._body, "noise", None) is not None
        done = 0
        while done < n:
            batch = min(n - done, HOLD_CHUNK) if noisy else 1
            sensed = self._body.sense(np.repeat(row, batch, axis=0))
            out = np.any((sensed < low) | (sensed > high), axis=1) & np.all(
                np.isfinite(sensed), axis=1)
            if out.any():
                first = int(np.argmax(out)) + 1
                self._count_hold(first)
                return sensed[first - 1]
            if not noisy:
                # A perfect body senses the same bits until the world changes.
                batch = n - done
            self._count_hold(batch)
            done += batch
        return None

    def _count_hold(self, n: int) -> None:
        self.row += n
        self.held_rows += n
