"""The bounded sweep of the agent in a world that does not wait for it
(``ClockedAgent``).

A reaction senses its resting POV and ``sweep_budget`` more known POVs, in
turn (a cursor walks through them): what a reaction costs does not grow
with the POVs known. The others are unknowns this time, as a lost frame is.

Most changes move the object so far that no known POV senses now what a
snapshot's POV sensed then: a sweep then matches nothing, and its rows buy
nothing. With ``naive.clock_sweep_first`` > 0 the sweep is sensed in two
calls: the resting POV and that many first; only if they match a snapshot
row or anchor (``_match_snapshots``, the test the whole sweep passes) the
rest of the budget. Skipped, those POVs come first in the next sweep.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sensorispace_ros.core.naive.clock_witnesses import WITNESSES, lit
from sensorispace_ros.core.naive.equality_sets import finite_rows

__all__ = ["BoundedSweep"]


class BoundedSweep:
    """Mixin of ``ClockedAgent``: needs its ``_store``, ``_body``,
    ``_rest_pov``, ``params``, ``sweep_budget``, ``_sweep_cursor`` and
    ``_match_snapshots``."""

    def _sweep_indices(self) -> np.ndarray:
        """The known POVs this reaction senses: the resting one and the next
        ``sweep_budget`` from the cursor (all when that is every one)."""
        count = self._store.count
        if count <= self.sweep_budget + 1:
            return np.arange(count)
        chosen = self._next_in_turn()
        if self._rest_pov >= 0:
            chosen = np.append(chosen, self._rest_pov)
        return np.unique(chosen)

    def _next_in_turn(self) -> np.ndarray:
        """The next ``sweep_budget`` known POVs from the cursor, in its
        order; the cursor moves past them."""
        start = self._sweep_cursor % self._store.count
        self._sweep_cursor = start + self.sweep_budget
        return (start + np.arange(self.sweep_budget)) % self._store.count

    def _sweep_parts(self) -> list[np.ndarray]:
        """The sweep's POVs in the calls that sense them: one, or with
        ``clock_sweep_first`` the resting POV and that many first, then the
        rest of the budget (``_sweep_indices`` otherwise)."""
        first = self.params.clock_sweep_first
        count = self._store.count
        if first <= 0 or count <= self.sweep_budget + 1 or first >= self.sweep_budget:
            return [self._sweep_indices()]
        rest = [self._rest_pov] if self._rest_pov >= 0 else []
        chosen = self._next_in_turn()
        chosen = chosen[~np.isin(chosen, rest)]
        return [np.unique(np.append(chosen[:first], rest)).astype(int), chosen[first:]]

    def _sweep_known(self) -> tuple[np.ndarray, np.ndarray]:
        n_sensors = self._body.n_sensors
        count = self._store.count
        if count == 0:
            return np.zeros((0, n_sensors)), np.zeros((0, n_sensors))
        parts = self._sweep_parts()
        current = np.full((count, n_sensors), np.nan)
        chosen = parts[0]
        current[chosen] = self._body.sense(self._store.samples[chosen, 0])
        if len(parts) > 1:
            if self._matches_anything(current):
                current[parts[1]] = self._body.sense(self._store.samples[parts[1], 0])
                chosen = np.concatenate(parts)
            else:
                self._sweep_cursor -= len(parts[1])
        sensed = current[chosen]
        top = np.argsort(-lit(sensed), kind="stable")[:WITNESSES]
        self._witnesses = (self._store.samples[chosen[top], 0].copy(), sensed[top].copy())
        self._lookouts = self._witnesses[0]
        return current, np.zeros((0, n_sensors))

    def _matches_anything(self, current: np.ndarray) -> bool:
        """Does a row of the part of the sweep in ``current`` match a
        snapshot's row or anchor (``_match_snapshots``, as the whole sweep)?"""
        matches, rest_hits, _ = self._match_snapshots(current, cKDTree(finite_rows(current, -1.0)))
        return bool(np.any(rest_hits >= 0) or any(len(before) for before, _ in matches))
