"""The naive agent's snapshots of past events, and which of their anchors it
tries to compensate after a change.

A snapshot is recorded after every event, in that event's environment: the
sensation at the resting arm (the anchor) and the sensation of one sample of
every POV then known (its sweep). After a change the agent matches each
snapshot's sweep with the new one; a snapshot with a full-rank match is
*confirmed* (no redistribution since), and its anchor, and the unmatched
rows next to its matched ones (the frontier), are worth searching for.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from sensorispace_ros.core.naive.equality_sets import RANK_DEFICIENT, RANK_FULL, RANK_UNKNOWN


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
