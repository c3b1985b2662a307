"""The naive agent's snapshots of past events and the anchors it compensates.

A snapshot is recorded after every event, in that event's environment: the
sensation at the resting arm (the anchor) and the sensation of one sample of
every POV then known (its sweep). After a change the agent matches each
snapshot's sweep with the new one; a snapshot with a full-rank match is
*confirmed* (no redistribution since), and its anchor, and the unmatched
rows next to its matched ones (the frontier), are worth searching for.
``SnapshotMatching`` (a mixin of ``NaiveAgent``) does the matching, the rank
tests it needs, the equality sets it gives and keeps the pool. Where noise
sized the tolerances, every match passes an averaged test (``confirm``),
matched rows pool their chains' sensings (``pooled_sweep``), some rows are
averaged (``targets``), and a row is searched only where it stands out.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.stats import chi2

from sensorispace_ros.core.naive.confirm import Provisional, settle_provisional, verify_matches
from sensorispace_ros.core.naive.equality_sets import (RANK_DEFICIENT, RANK_FULL, RANK_UNKNOWN,
    check_pose_rank, match_counted, match_noise)
from sensorispace_ros.core.naive.match_discrepancy import sweep_discrepancy
from sensorispace_ros.core.naive.neighbours import (Neighbours, held_by_neighbours,
    matched_neighbours)
from sensorispace_ros.core.naive.points_of_view import jacobian_stencil
from sensorispace_ros.core.naive.targets import averaged_targets


@dataclass
class Request:
    """An anchor to search for: row ``row`` of snapshot ``snapshot``'s sweep
    (-1: its resting anchor), recorded at ``anchor_motor_state``; ``start``
    an extra state to search from (None: none); ``count`` the sensings
    averaged in ``target``; ``neighbours`` (``anchor_requests(by_motor=True)``,
    else None): the matched rows nearest ``anchor_motor_state`` in motor
    space, the known POVs now sensing what they sensed, and their motor
    distances (``Neighbours``)."""

    snapshot: int
    row: int
    target: np.ndarray
    anchor_motor_state: np.ndarray
    start: np.ndarray | None = None
    count: int = 1
    neighbours: "Neighbours | None" = None


@dataclass
class Snapshot:
    """What the agent sensed at event ``event``: the sweep's ``sensations``
    ``(K_t, S)`` (one per POV known then) and their ``rank`` ``(K_t,)``
    (``RANK_*``), the anchor ``rest_sensation`` at ``rest_motor_state``
    (POV ``rest_pov``, -1 if none) and its rank; ``fails``: events since it
    last matched or was compensated; ``counts`` ``(K_t,)`` the sensings
    pooled in each row of ``sensations`` (None: one each; ``pooled_sweep``),
    ``rest_count`` in ``rest_sensation``."""

    event: int
    sensations: np.ndarray
    rank: np.ndarray
    rest_sensation: np.ndarray
    rest_motor_state: np.ndarray
    rest_pov: int
    rest_rank: int = RANK_UNKNOWN
    fails: int = 0
    counts: np.ndarray | None = None
    rest_count: int = 1
    chained: bool = True        # its rest is the start or a compensation of a chained anchor

    def count(self, row: int) -> int:
        """Sensings pooled in row ``row`` (-1: the anchor)."""
        if row < 0:
            return int(self.rest_count)
        return 1 if self.counts is None else int(self.counts[row])


def anchor_requests(pool: list, matches, rest_hits, rank_now, params, *,
                    pov_samples: np.ndarray, frontier_budget: int, by_motor: bool = False,
                    order=None):
    """Anchors: matched by a known POV, or searched for. A snapshot none
    of whose POVs matches is from before a redistribution or from before
    a long translation; its anchor is searched only while few POVs were
    known (later a long translation puts the anchor's target out of reach
    too, and the search would be wasted). ``matches`` of full rank only;
    ``rest_hits[k]`` the POV now sensing snapshot ``k``'s anchor (-1: none);
    ``by_motor``: the requests of a snapshot with matches carry their
    ``Neighbours`` (frontier rows as ``frontier_requests``'s, in ``order``).
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
            requests.append(Request(k, -1, snap.rest_sensation, snap.rest_motor_state,
                                    count=snap.rest_count))
            if by_motor:
                requests[-1].neighbours = matched_neighbours(pov_samples, *matches[k],
                                                             snap.rest_motor_state)
        elif unconfirmed_left > 0 and len(snap.sensations) < params.unconfirmed_max_povs:
            requests.append(Request(k, -1, snap.rest_sensation, snap.rest_motor_state,
                                    count=snap.rest_count))
            unconfirmed_left -= 1
    requests.extend(frontier_requests(pool, matches, pov_samples=pov_samples,
                                      attempts=params.frontier_attempts,
                                      budget=frontier_budget, by_motor=by_motor,
                                      order=order))
    return known_comp, requests


def frontier_requests(pool: list, matches, *, pov_samples: np.ndarray, attempts: int,
                      budget: int, by_motor: bool = False, order=None) -> list:
    """Anchors beyond the rest: rows of the most recent confirmed snapshot
    that no known POV matches, the ``budget`` nearest (in that snapshot's
    sensations) to a matched row (none if ``attempts`` is 0). Their targets
    are the unknown positions next to the known ones moved by the
    displacement; the matched neighbour's partner is a start a lattice step
    from the target. ``by_motor``: the neighbour is the matched row whose
    POV lies nearest the row's in motor space (a sensation alike may be a
    far pose's), and the request carries its ``Neighbours``. ``order(distance,
    rows, snapshot, (before, after))``: the rows' indices in the order asked
    (default nearest first), given the snapshot's matches."""
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
        chosen = np.argsort(distance, kind="stable") if order is None else \
            order(distance, unmatched, snap, (before, after))
        requests = [Request(k, int(unmatched[i]), snap.sensations[unmatched[i]],
                            pov_samples[unmatched[i], 0], pov_samples[after[nearest[i]], 0],
                            snap.count(int(unmatched[i])))
                    for i in chosen[:budget]]
        if by_motor:
            for r in requests:
                r.neighbours = matched_neighbours(pov_samples, before, after,
                                                  r.anchor_motor_state)
                r.start = pov_samples[r.neighbours.after[0], 0]
        return requests
    return []


def pooled_sweep(pool: list, matches, current: np.ndarray, cap: int):
    """This sweep's sensations ``current`` ``(K, S)`` pooled with what its
    matches sensed before: a row matched to a snapshot's row senses the same
    pose relative to the object in the same light layout, so the two are
    sensings of one thing. Each matched row becomes the mean of its sensing
    and the snapshot row's pooled ones (the most recent snapshot that
    matched it; ``cap`` sensings at most, so an old mistake fades). Returns
    ``(pooled (K, S), counts (K,))``."""
    pooled = np.array(current, dtype=float, copy=True)
    counts = np.ones(len(current), dtype=int)
    done = np.zeros(len(current), dtype=bool)
    for snap, (before, after) in zip(pool, matches):
        if snap.counts is None or not len(after):
            continue
        fresh = ~done[after]
        before, after = before[fresh], after[fresh]
        previous = np.minimum(snap.counts[before], cap - 1)
        finite = np.all(np.isfinite(current[after]), axis=1)
        before, after, previous = before[finite], after[finite], previous[finite]
        pooled[after] = (current[after] + previous[:, None] * snap.sensations[before]) \
            / (previous + 1)[:, None]
        counts[after] = previous + 1
        done[after] = True
    return pooled, counts


def full_rank_matches(matches, rank_now):
    """``matches`` ``[(before, after), ...]`` kept where ``rank_now[after]`` is full."""
    return [(b[rank_now[a] == RANK_FULL], a[rank_now[a] == RANK_FULL]) for b, a in matches]


def _within_noise(rows, counts, target, count, sd2, quantile) -> bool:
    """Whether a finite row of ``rows`` (each the mean of ``counts``
    sensings) lies from ``target`` (``count`` sensings) within the
    chi-square ``quantile`` of two such means' difference."""
    limit = quantile * sd2 * (1.0 / np.asarray(counts, dtype=float) + 1.0 / count)
    return bool(len(rows)) and bool(np.any(np.sum((rows - target) ** 2, axis=1) <= limit))


def _far_from_matched(request, agent) -> bool:
    """Whether a frontier row's POV lies farther than ``_FRONTIER_REACH``
    separations of the agent's POVs (motor space) from every matched row's:
    its target is no neighbour of a pose the match located, and nothing
    holds a far pose sensing it alike (``SnapshotMatching._held_by_neighbours``)."""
    if request.neighbours is None or agent._store.count < agent.params.pose_precision_povs:
        return False
    return bool(request.neighbours.reach[0] > _FRONTIER_REACH * agent._store.separation())


_HIT_SHARE = 4.0    # predicted pose errors (_max_pose_error) a known POV may lie from an anchor
# A frontier compensation's motor distance to a neighbour's partner may be
# this many times its row's distance to the neighbour, plus this many
# separations of the POVs (``SnapshotMatching._held_by_neighbours``).
_NEIGHBOUR_RATIO = 3.0
_NEIGHBOUR_SLACK = 1.0
# A frontier row is searched only within this many separations of the POVs
# from a matched row's POV (``_far_from_matched``).
_FRONTIER_REACH = 4.0


class SnapshotMatching:
    """Mixin of ``NaiveAgent``: needs its ``params``, ``structure``, ``_tol``,
    ``_body``, ``_store``, ``_pool``, ``_provisional``, ``_sets``, ``_rest_pov`` and
    ``_repeats``, ``_noisy``, ``_search_plan`` and ``_confirm`` (``searching``),
    ``_frontier_order`` and ``_frontier_budget`` (``frontier``)."""

    _discrepancy = 0.0      # this sweep's, set by _match_snapshots (match_discrepancy)

    def _match_snapshots(self, current, tree):
        """Match every snapshot's sweep, and its anchor, with this sweep
        ``current``. Returns ``(matches [(before, after), ...], rest_hits
        (the POV now sensing each snapshot's anchor, -1: none), rank_now)``;
        ``rank_now`` ``(K,)`` holds the ranks the matches carry over (a
        match senses the same relative pose in the same light layout)."""
        rank_now = np.full(len(current), RANK_UNKNOWN)
        noise_sd = match_noise(self.structure.noise, self.structure.repeat_noise,
                               self.structure.quantum) if self._noisy else 0.0
        # Only where repeats spread: outputs rounded alike sense alike, and the
        # spread between rounded rows lets in neighbours, not partners.
        self._discrepancy = sweep_discrepancy(self._pool, current, noise_sd, tree) \
            if noise_sd > 0 and self._repeats > 1 and self.params.match_discrepancy else 0.0
        match = dict(match_tol=self._tol.match, separation=self._tol.separation, tree=tree,
                     ratio=self._tol.ratio, confidence=self.params.noise_confidence,
                     noise_sd=noise_sd, discrepancy=self._discrepancy)
        matches = []
        for snap in self._pool:
            before, after = match_counted(snap.sensations, current, counts=snap.counts, **match)
            known = snap.rank[before]
            rank_now[after[known != RANK_UNKNOWN]] = known[known != RANK_UNKNOWN]
            matches.append((before, after))
        rest_hits = np.full(len(self._pool), -1)
        for k, snap in enumerate(self._pool):
            _, hit = match_counted(snap.rest_sensation[None], current,
                                   counts=[snap.rest_count], **match)
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
            # Which anchors are searched depends on these tests. The call also carries
            # what the search's first call senses (``_search_lookahead``) if every tested
            # state has full rank (the usual outcome): that call is answered from memory.
            guess = rank_now.copy()
            guess[unknown] = RANK_FULL
            _, guessed = self._anchor_requests(full_rank_matches(matches, guess), rest_hits,
                                               guess)
            starts = self._search_plan(guessed, current)[-1] if guessed else np.zeros(
                (0, self.n_motors))
            self._body.stage = "rank"
            with self._body.lookahead(self._search_lookahead(starts)):
                full, _ = check_pose_rank(self._body, self._store.samples[unknown, 0],
                                          rank=self.structure.pose_rank,
                                          fd_step=self._fd_step,
                                          rank_ratio=p.rank_ratio,
                                          min_singular=self._tol.min_singular,
                                          pattern_ratio=p.pattern_ratio)
            rank_now[unknown] = np.where(full, RANK_FULL, RANK_DEFICIENT)
        return full_rank_matches(matches, rank_now)

    def _search_lookahead(self, starts: np.ndarray) -> np.ndarray:
        """The rows a search from ``starts`` senses first: their stencils."""
        return jacobian_stencil(starts, self._first_search_step())

    def _pooled_counts(self, rows: int) -> np.ndarray | None:
        """Sensings pooled per row of a snapshot taken now (None: not pooled)."""
        return np.ones(rows, dtype=int) if self._repeats > 1 else None

    def _pool_sweep(self, matches, current):
        """``pooled_sweep`` of this sweep, some rows averaged (``targets``), where
        the agent pools sensings, else ``(current, None)``."""
        return (current, None) if self._repeats <= 1 else averaged_targets(
            self, *pooled_sweep(self._pool, matches, current, self.params.pool_sensings))

    def _verify_rest_hits(self, rest_hits):
        """Where noise sized the tolerances, a known POV that matched an
        anchor is a compensation found without a search: it passes the same
        averaged test as a search's end (``searching._confirm``) or the
        anchor is searched for instead; its pose is not refined, so its
        Gauss-Newton step toward the anchor must be within ``_HIT_SHARE``
        times the largest predicted pose error a compensation may keep.
        Returns the hits kept (-1: none)."""
        hits = np.flatnonzero(rest_hits >= 0)
        if not self._noisy or not len(hits):
            return rest_hits
        solution = {int(k): self._store.samples[rest_hits[k], 0] for k in hits}
        targets = np.stack([self._pool[k].rest_sensation for k in range(len(self._pool))])
        counts = {int(k): self._pool[k].rest_count for k in hits}
        self._body.stage = "compensation"
        kept = self._confirm(solution, targets, counts, rounds=1,
                             max_step=_HIT_SHARE * self._max_pose_error())
        return np.where(np.isin(np.arange(len(rest_hits)), list(kept)), rest_hits, -1)

    def _verify_matches(self, matches):
        """Where noise sized the tolerances, a match of a sweep row to a
        snapshot's row is a compensation too (the POV now senses what the
        other sensed then): it passes the averaged test of a known POV
        against an anchor (``_verify_rest_hits``), or, where repeats spread,
        is located (``confirm.verify_matches``: a row sensed once cannot pin
        the pose, yet the fresh averages of the snapshot's POVs reproduce its
        rows), or it confirms nothing and adds no equality. Returns those kept."""
        if not self._noisy:
            return matches
        kept = []
        for snap, (before, after) in zip(self._pool, matches):
            counts = np.array([snap.count(int(b)) for b in before])
            if not len(before):
                kept.append((before, after))
                continue
            self._body.stage, error = "compensation", self._max_pose_error()
            # Averaging pays until the average's noise is a quarter of the target's.
            repeats, sensed = min(self._repeats, 4 * int(counts.max())), []
            precise, located = verify_matches(
                self._body, self._store.samples[after, 0], snap.sensations[before],
                self.structure.noise ** 2 / counts, noise_sd=self.structure.noise,
                repeats=repeats, rank=self.structure.pose_rank,
                fd_step=self._fd_step, confidence=self.params.noise_confidence, max_error=error,
                max_step=_HIT_SHARE * error, min_singular=self._pinning_floor(),
                discrepancy=self._discrepancy, sensed=sensed)
            good = precise | (located & (self._repeats > 1))
            self._note_verified(snap, before, after, sensed[0], repeats, good)
            kept.append((before[good], after[good]))
        return kept

    def _distinct_targets(self, requests, current):
        """Where noise sized the tolerances: ``requests`` without the frontier
        rows whose target does not stand out, beyond what two sensings of
        one pose differ by (their averaged noise), from every other row of
        its snapshot and from every known POV's sensation now (``current``;
        no match singled one out): a search toward it would end on whichever
        of the poses sensing it. The budget is not filled again from rows
        farther from the matched ones: those are poorer targets still."""
        if not self._noisy:
            return requests
        sd2 = self.structure.noise ** 2
        quantile = chi2.ppf(self.params.noise_confidence, self._body.n_sensors)
        current = np.asarray(current, dtype=float).reshape(-1, self._body.n_sensors)
        kept = []
        for r in requests:
            if r.row < 0:
                kept.append(r)
                continue
            snap = self._pool[r.snapshot]
            counts = snap.counts if snap.counts is not None else np.ones(len(snap.sensations))
            others = np.arange(len(snap.sensations)) != r.row
            if _within_noise(snap.sensations[others], counts[others], r.target, r.count,
                             sd2, quantile) or \
                    _within_noise(current, np.ones(len(current)), r.target, r.count, sd2,
                                  quantile) or _far_from_matched(r, self):
                continue
            kept.append(r)
        return kept

    def _held_by_neighbours(self, solution, requests, group):
        """Where noise sized the tolerances: ``solution`` ``{group: state}``
        without the compensations (of a frontier row, or of the anchor of a
        snapshot some POVs matched) that do not lie among the matched
        neighbours' partners of the pose they were asked for
        (``held_by_neighbours``, within ``_NEIGHBOUR_RATIO`` times plus
        ``_NEIGHBOUR_SLACK`` separations of the POVs): a far pose sensing
        the target alike is not the one asked for."""
        if not self._noisy or not solution:
            return solution
        slack = _NEIGHBOUR_SLACK * self._store.separation()
        kept = {}
        for g, state in solution.items():
            if all(held_by_neighbours(self._store.samples, r.neighbours, state,
                                      ratio=_NEIGHBOUR_RATIO, slack=slack)
                   for r, h in zip(requests, group) if h == g and r.neighbours is not None):
                kept[g] = state
        return kept

    def _may_rest(self, snapshot: int, requests) -> bool:
        """Whether the arm may rest on the searched compensation of snapshot
        ``snapshot``'s anchor. Every later anchor is sensed from the rest, so
        a rest off the start's lattice of relative poses (a far pose sensing
        the anchor alike, across a redistribution no match revealed) puts
        every POV found after it on a lattice of its own. Where noise sized
        the tolerances only a compensation held to matched neighbours
        (``_held_by_neighbours``) whose nearest one lies within
        ``_FRONTIER_REACH`` separations of the POVs of the anchor is rested
        on; elsewhere the arm stays where it is: any rest on the lattice
        keeps every later compensation on it."""
        if not self._noisy:
            return True
        request = next((r for r in requests if r.snapshot == snapshot and r.row < 0), None)
        return request is not None and request.neighbours is not None and \
            len(request.neighbours.reach) > 0 and not _far_from_matched(request, self)

    def _hold_unconfirmed(self, records, matches, known_comp, found_rest):
        """Where noise sized the tolerances: a searched compensation with no
        POV walked whole (``_whole_on_level_set``) is not recorded (nothing
        vouches for its pose); that of the anchor of a snapshot no sweep row
        matched is provisional: its POV is kept, its record waits for a
        later sweep to confirm it (``confirm.settle_provisional``).
        ``records``: this event's, anchors first in pool order
        (``_compensation_records``). Returns those kept and the earlier
        ones confirmed now."""
        if not self._noisy:
            return records
        confirmed, pending = settle_provisional(self._provisional, self._pool, matches,
                                                known_comp)
        anchors = [k for k in range(len(self._pool)) if k in known_comp or k in found_rest]
        kept = []
        for i, record in enumerate(records):
            k = anchors[i] if i < len(anchors) else -1
            if record.pov < 0:
                continue
            if k < 0 or len(matches[k][0]):
                kept.append(record)
            elif self._pool[k].rest_pov >= 0:
                pending.append(Provisional(record, self._pool[k].rest_pov))
        self._provisional = pending
        return confirmed + kept

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

    def _anchor_requests(self, matches, rest_hits, rank_now, current=None):
        """``anchors.anchor_requests`` on the pool, with this event's frontier
        budget; given this sweep's sensations ``current``, only the targets
        that stand out (``_distinct_targets``)."""
        known_comp, requests = anchor_requests(self._pool, matches, rest_hits, rank_now,
                                               self._anchor_params(),
                                               pov_samples=self._store.samples,
                                               frontier_budget=self._frontier_budget(),
                                               by_motor=self._noisy,
                                               order=self._frontier_order)
        if current is not None:
            requests = self._distinct_targets(requests, current)
        return known_comp, requests

    def _anchor_params(self):
        """The parameters ``anchor_requests`` works with: the agent's own."""
        return self.params
