"""The naive agent in a world that does not wait for it.

``ClockedAgent`` is a ``NaiveAgent`` that is told nothing about time: its
driver (``clocked_run``) calls ``react`` when the agent's own test
(``change_detection``) flags a change. Two things differ from the agent of
a waiting world:

* a reaction senses a bounded part of what it knows (``_sweep_known``):
  its resting POV and ``sweep_budget`` more, in turn (a cursor walks
  through the known POVs, so every POV is swept again after
  ``P / sweep_budget`` reactions); the others are unknowns this time, as a
  lost frame is. What a reaction costs no longer grows with the POVs known.
* a reaction can be undone (``checkpoint``/``restore``): when the world
  changed while the agent was working, what it found spans two worlds and
  is dropped, its probing still counted.
"""
from __future__ import annotations

import copy

import numpy as np

from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams


class ClockedAgent(NaiveAgent):
    """``NaiveAgent`` with a bounded sweep and undoable reactions (module docstring)."""

    def __init__(self, body, params: NaiveParams | None = None, sweep_budget: int = 64):
        super().__init__(body, params)
        if isinstance(sweep_budget, bool) or not isinstance(sweep_budget, (int, np.integer)) \
                or sweep_budget < 0:
            raise ValueError(f"sweep_budget: must be an integer >= 0, got {sweep_budget!r}")
        self.sweep_budget = int(sweep_budget)
        self._sweep_cursor = 0

    @property
    def noise_sd(self) -> float:
        """The per-receptor noise the agent measured (0 before ``start``)."""
        return 0.0 if self.structure is None else float(self.structure.noise)

    @property
    def anchor_sensation(self) -> np.ndarray | None:
        """The sensation the agent recorded at its resting state, in the
        world of its last reaction."""
        return None if not self._pool else self._pool[0].rest_sensation.copy()

    def sense_again(self, motor_states) -> np.ndarray:
        """Sense ``motor_states`` (body units) afresh, not from memory:
        counted as resting rows."""
        rows = self._phase.to_phase(np.atleast_2d(np.asarray(motor_states, dtype=float)))
        self._body.stage = "rest"
        with self._body.fresh():
            sensed = self._body.sense(np.ascontiguousarray(rows))
        self._body.pause()
        return sensed

    def checkpoint(self) -> dict:
        """What the agent knows (its counters excluded), to undo a reaction."""
        return copy.deepcopy({name: value for name, value in vars(self).items()
                              if name != "_body"})

    def restore(self, saved: dict) -> None:
        """Back to ``saved``; the rows spent since stay counted."""
        vars(self).update(copy.deepcopy(saved))
        self._body.phase = self._phase

    def _sweep_indices(self) -> np.ndarray:
        """The known POVs this reaction senses: the resting one and the next
        ``sweep_budget`` from the cursor (all when that is every one)."""
        count = self._store.count
        if count <= self.sweep_budget + 1:
            return np.arange(count)
        start = self._sweep_cursor % count
        chosen = (start + np.arange(self.sweep_budget)) % count
        self._sweep_cursor = start + self.sweep_budget
        if self._rest_pov >= 0:
            chosen = np.append(chosen, self._rest_pov)
        return np.unique(chosen)

    def _sweep_known(self) -> tuple[np.ndarray, np.ndarray]:
        n_sensors = self._body.n_sensors
        count = self._store.count
        if count == 0:
            return np.zeros((0, n_sensors)), np.zeros((0, n_sensors))
        chosen = self._sweep_indices()
        current = np.full((count, n_sensors), np.nan)
        current[chosen] = self._body.sense(self._store.samples[chosen, 0])
        return current, np.zeros((0, n_sensors))
