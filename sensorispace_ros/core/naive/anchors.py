"""The naive agent's snapshots of past events, and which of their anchors it
tries to compensate after a change.

A snapshot is recorded after every event, in that event's environment: the
sensation at the resting arm (the anchor) and the sensation of one sample of
every POV then known (its sweep). After a change the agent matches each
snapshot's sweep with the new one; a snapshot with a full-rank match is
*confirmed* (no redistribution since), and its anchor, and the unmatched
rows next to its matched ones (the frontier), are worth searching for.
``SnapshotMatching`` (a mixin of ``NaiveAgent``) does the matching, the rank
tests it needs, the equality sets it gives and keeps the pool.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from sensorispace_ros.core.naive.equality_sets import (RANK_DEFICIENT, RANK_FULL, RANK_UNKNOWN,
    check_pose_rank, match_sensations)
from sensorispace_ros.core.naive.points_of_view import jacobian_stencil


@dataclass
class Request:
    """An anchor to search for: row ``row`` of snapshot ``snapshot``'s sweep
    (-1: its resting anchor), recorded at ``anchor_motor_state``; ``start``
    an extra state to search from (None: none)."""

    snapshot: int
    row: int
    target: np.ndarray
    anchor_motor_state: np.ndarray
    start: np.ndarray | None = None


@dataclass
class Snapshot:
    """What the agent sensed at event ``event``: the sweep's ``sensations``
    ``(K_t, S)`` (one per POV known then) and their ``rank`` ``(K_t,)``
    (``RANK_*``), the anchor ``rest_sensation`` at ``rest_motor_state``
    (POV ``rest_pov``, -1 if none) and its rank; ``fails``: events since it
    last matched or was compensated."""

    event: int
    sensations: np.ndarray
    rank: np.ndarray
    rest_sensation: np.ndarray
    rest_motor_state: np.ndarray
    rest_pov: int
    rest_rank: int = RANK_UNKNOWN
    fails: int = 0
    chained: bool = True        # its rest is the start or a compensation of a chained anchor


def anchor_requests(pool: list, matches, rest_hits, rank_now, params, *,
                    pov_samples: np.ndarray, frontier_budget: int):
    """Anchors: matched by a known POV, or searched for. A snapshot none
    of whose POVs matches is from before a redistribution or from before
    a long translation; its anchor is searched only while few POVs were
    known (later a long translation puts the anchor's target out of reach
    too, and the search would be wasted). ``matches`` of full rank only;
    ``rest_hits[k]`` the POV now sensing snapshot ``k``'s anchor (-1: none).
    Returns ``({snapshot index: known POV}, [Request, ...])``."""
    known_comp: dict[int, int] = {}
    requests: list[Request] = []
    unconfirmed_left = params.unconfirmed_attempts
    for k, snap in enumerate(pool):
        hit = rest_hits[k]
        if params.chained_anchors and not snap.chained:
            continue                # its anchor does not relate to the start (chained_anchors)
        if hit >= 0 and rank_now[hit] == RANK_FULL:
            known_comp[k] = int(hit)
        elif snap.rest_rank == RANK_DEFICIENT:
            continue                # a blank anchor would be "compensated" anywhere
        elif len(matches[k][0]) > 0:
            requests.append(Request(k, -1, snap.rest_sensation, snap.rest_motor_state))
        elif unconfirmed_left > 0 and len(snap.sensations) < params.unconfirmed_max_povs:
            requests.append(Request(k, -1, snap.rest_sensation, snap.rest_motor_state))
            unconfirmed_left -= 1
    requests.extend(frontier_requests(pool, matches, pov_samples=pov_samples,
                                      attempts=params.frontier_attempts,
                                      budget=frontier_budget))
    return known_comp, requests


def frontier_requests(pool: list, matches, *, pov_samples: np.ndarray, attempts: int,
                      budget: int) -> list:
    """Anchors beyond the rest: rows of the most recent confirmed snapshot
    that no known POV matches, the ``budget`` nearest (in that snapshot's
    sensations) to a matched row (none if ``attempts`` is 0). Their targets
    are the unknown positions next to the known ones moved by the
    displacement; the matched neighbour's partner is a start a lattice step
    from the target."""
    for k, snap in enumerate(pool):
        before, after = matches[k]
        if len(before) == 0:
            continue
        unmatched = np.setdiff1d(np.flatnonzero(snap.rank != RANK_DEFICIENT), before)
        unmatched = unmatched[unmatched != snap.rest_pov]
        # A lost sensation (non-finite) is no target.
        unmatched = unmatched[np.all(np.isfinite(snap.sensations[unmatched]), axis=1)]
        if len(unmatched) == 0 or attempts == 0:
            return []
        distance, nearest = cKDTree(snap.sensations[before]).query(
            snap.sensations[unmatched], k=1)
        order = np.argsort(distance, kind="stable")[:budget]
        return [Request(k, int(unmatched[i]), snap.sensations[unmatched[i]],
                        pov_samples[unmatched[i], 0], pov_samples[after[nearest[i]], 0])
                for i in order]
    return []


def full_rank_matches(matches, rank_now):
    """``matches`` ``[(before, after), ...]`` kept where ``rank_now[after]`` is full."""
    return [(b[rank_now[a] == RANK_FULL], a[rank_now[a] == RANK_FULL]) for b, a in matches]


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
        rank_now = np.full(len(current), RANK_UNKNOWN)
        match = dict(match_tol=self._tol.match, separation=self._tol.separation, tree=tree,
                     ratio=self._tol.ratio)
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
            with self._body.lookahead(jacobian_stencil(starts, self._fd_step)):
                full, _ = check_pose_rank(self._body, self._store.samples[unknown, 0],
                                          rank=self.structure.pose_rank,
                                          fd_step=self._fd_step,
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
        if p.chained_anchors and not snapshot.chained:
            snapshot = None         # an anchor unrelated to the start is never searched
        self._pool = (([snapshot] if snapshot is not None else []) + kept)[:p.max_snapshots]

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
