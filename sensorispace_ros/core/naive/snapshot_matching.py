"""How the naive agent relates this event's sweep to its snapshots.

``NaiveAgent`` inherits it: matching every snapshot's sweep (and anchor)
with the sensations of the known POVs now, the rank tests those matches
need, the anchor and frontier requests they lead to, the equality sets they
give, and the pool of snapshots kept for the next event (see
``agent``'s docstring for the policy).
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.naive.anchors import anchor_requests, full_rank_matches
from sensorispace_ros.core.naive.equality_sets import (RANK_DEFICIENT, RANK_FULL, RANK_UNKNOWN,
    check_pose_rank, match_sensations)
from sensorispace_ros.core.naive.points_of_view import jacobian_stencil


class SnapshotMatching:
    """Mixin of ``NaiveAgent``: needs its ``params``, ``structure``, ``_tol``,
    ``_body``, ``_store``, ``_pool``, ``_sets``, ``_rest_pov`` and
    ``_frontier_success``, and ``_search_plan`` (``searching``)."""

    def _match_snapshots(self, current, tree):
        """Match every snapshot's sweep, and its anchor, with this sweep
        ``current``. Returns ``(matches [(before, after), ...], rest_hits
        (the POV now sensing each snapshot's anchor, -1: none), rank_now)``;
        ``rank_now`` ``(K,)`` holds the ranks the matches carry over (a
        match senses the same relative pose in the same light layout)."""
        p = self.params
        rank_now = np.full(len(current), RANK_UNKNOWN)
        match = dict(match_tol=self._tol.match, separation=self._tol.separation, tree=tree)
        matches = []
        for snap in self._pool:
            before, after = match_sensations(snap.sensations, current, **match)
            known = snap.rank[before]
            rank_now[after[known != RANK_UNKNOWN]] = known[known != RANK_UNKNOWN]
            matches.append((before, after))
        rest_hits = np.full(len(self._pool), -1)
        for k, snap in enumerate(self._pool):
            _, hit = match_sensations(snap.rest_sensation[None], current, **match)
            if len(hit):
                rest_hits[k] = hit[0]
                if snap.rest_rank != RANK_UNKNOWN:
                    rank_now[hit[0]] = snap.rest_rank
        return matches, rest_hits, rank_now

    def _test_ranks(self, matches, rest_hits, rank_now, current):
        """Rank tests (M + 1 rows each) only where a decision needs them:
        every match of the snapshots that feed equality sets, a few matches
        of the others (one full-rank match confirms a snapshot), anchor
        hits. Fills ``rank_now`` in place; returns the full-rank matches."""
        p = self.params
        needed = [rest_hits[rest_hits >= 0]]
        for k, (_, after) in enumerate(matches):
            if k < p.equality_snapshots:
                needed.append(after)
            elif not np.any(rank_now[after] == RANK_FULL):
                needed.append(after[rank_now[after] == RANK_UNKNOWN][:p.confirm_checks])
        unknown = np.unique(np.concatenate(needed).astype(int))
        unknown = unknown[rank_now[unknown] == RANK_UNKNOWN]
        if len(unknown):
            # Which anchors are searched depends on these tests. The call also
            # carries the stencils the search starts from if every tested state
            # has full rank (the usual outcome): the search's first call is
            # then answered from memory.
            guess = rank_now.copy()
            guess[unknown] = RANK_FULL
            _, guessed = self._anchor_requests(full_rank_matches(matches, guess), rest_hits,
                                               guess)
            starts = self._search_plan(guessed, current)[-1] if guessed else np.zeros(
                (0, self.n_motors))
            self._body.stage = "rank"
            with self._body.lookahead(jacobian_stencil(starts, p.fd_step)):
                full, _ = check_pose_rank(self._body, self._store.samples[unknown, 0],
                                          rank=self.structure.pose_rank, fd_step=p.fd_step,
                                          rank_ratio=p.rank_ratio,
                                          min_singular=self._tol.min_singular,
                                          pattern_ratio=p.pattern_ratio)
            rank_now[unknown] = np.where(full, RANK_FULL, RANK_DEFICIENT)
        return full_rank_matches(matches, rank_now)

    def _track_frontier(self, requests, found, new_povs) -> None:
        """Moving average of the frontier searches that found a new POV."""
        frontier = [i for i, r in enumerate(requests) if r.row >= 0]
        if frontier:
            hits = sum(1 for i in frontier if i in found and found[i][0] >= 0
                       and found[i][0] in new_povs)
            self._frontier_success = 0.9 * self._frontier_success + 0.1 * hits / len(frontier)

    def _add_equality_sets(self, matches, requests, found) -> None:
        """Equality sets: the changes matched for one snapshot (and the
        compensations of its anchors) all compensate one displacement."""
        for k, snap in enumerate(self._pool):
            before, after = matches[k]
            extra_before, extra_after = [], []
            for i, r in enumerate(requests):
                if r.snapshot != k or i not in found or found[i][0] < 0:
                    continue
                source = r.row if r.row >= 0 else snap.rest_pov
                if source >= 0 and source not in before:
                    extra_before.append(source)
                    extra_after.append(found[i][0])
            self._sets.add(np.concatenate([before, extra_before]).astype(int),
                           np.concatenate([after, extra_after]).astype(int))

    def _renew_pool(self, matches, known_comp, found_rest, snapshot) -> None:
        """Put this event's ``snapshot`` first; forget superseded and
        long-failing ones, keep at most ``max_snapshots``."""
        p = self.params
        kept = []
        for k, snap in enumerate(self._pool):
            alive = len(matches[k][0]) > 0 or k in known_comp or k in found_rest
            snap.fails = 0 if alive else snap.fails + 1
            comp_pov = known_comp[k] if k in known_comp else found_rest.get(k, (None,))[0]
            # Compensated by where the arm now rests: the new snapshot has the
            # same anchor pose relative to the object, in a later environment.
            superseded = comp_pov is not None and comp_pov == self._rest_pov
            if not superseded and snap.fails < p.snapshot_patience:
                kept.append(snap)
        self._pool = ([snapshot] + kept)[:p.max_snapshots]

    def _anchor_requests(self, matches, rest_hits, rank_now):
        """``anchors.anchor_requests`` on the pool, with this event's frontier budget."""
        return anchor_requests(self._pool, matches, rest_hits, rank_now, self.params,
                               pov_samples=self._store.samples,
                               frontier_budget=self._frontier_budget())

    def _frontier_budget(self) -> int:
        """Frontier searches this event: ``frontier_attempts`` while they
        find new POVs, down to one when they keep failing (the known POVs
        already fill the reachable region; later translations may still
        uncover a corner, so the agent keeps trying once per event)."""
        share = min(1.0, self._frontier_success / 0.2)
        return max(1, int(np.ceil(self.params.frontier_attempts * share)))
