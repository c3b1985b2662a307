"""Simulation 2 of an agent on a clock (``ClockedAgent.begin_equality_pass``).

The world replays its schedule; the agent is told nothing of when it
changes and sweeps known POVs after each change it detects. A sweep is
matched with every earlier one, not only the previous: a world the agent
met before is a displacement it can still tell, however many changes it
missed in between. A sweep senses a bounded, seeded sample of the known
POVs, not every one (no stage senses every known POV at every change).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sensorispace_ros.core.naive.equality_sets import (RANK_DEFICIENT, RANK_FULL, RANK_UNKNOWN,
    EqualitySetSweep, check_pose_rank, finite_rows, match_sensations)


class AllPairsSweep(EqualitySetSweep):
    """Simulation 2 that matches each sweep with every earlier one, not
    only the previous: a world the agent met before is a displacement it can
    still tell, however many changes it missed in between (``history``:
    each sweep's POV indices, sensations and ranks). With a ``budget`` a
    sweep senses that many known POVs, a seeded sample drawn afresh each
    change (``stream``: ``CounterStream``, keyed by the sweep's number), not
    every one: its cost does not grow with the POVs known, and the pairs of
    sweeps still share POVs the matches and equality sets need."""

    budget = 0
    stream = None

    def _chosen(self) -> np.ndarray:
        count = len(self.probe_states)
        if self.budget <= 0 or count <= self.budget or self.stream is None:
            return np.arange(count)
        draw = self.stream.at(len(self.history))
        return np.sort(draw.choice(count, size=self.budget, replace=False))

    def observe(self) -> np.ndarray:
        chosen = self._chosen()
        current = np.asarray(self.body.sense(self.probe_states[chosen]), dtype=float)
        self.rows += len(current)
        self.calls += 1
        rank = np.full(len(current), RANK_UNKNOWN)
        tree = cKDTree(finite_rows(current, -1.0))
        for ids, previous, previous_rank in self.history:
            before, after = match_sensations(previous, current, match_tol=self.match_tol,
                                             separation=self.separation, tree=tree,
                                             ratio=self.ratio)
            known = np.where(rank[after] != RANK_UNKNOWN, rank[after], previous_rank[before])
            rank[after] = known
            unknown = after[known == RANK_UNKNOWN]
            if len(unknown):
                full, rows = check_pose_rank(self.body, self.probe_states[chosen[unknown]],
                                             rank=self.rank, fd_step=self.fd_step,
                                             rank_ratio=self.rank_ratio,
                                             min_singular=self.min_singular,
                                             pattern_ratio=self.pattern_ratio)
                self.rows += rows
                self.calls += 1
                rank[unknown] = np.where(full, RANK_FULL, RANK_DEFICIENT)
            previous_rank[before] = rank[after]
            good = rank[after] == RANK_FULL
            self.sets.add(ids[before[good]], chosen[after[good]])
        self.history.append((chosen, current, rank))
        return np.zeros((0, 2), dtype=int)
