"""Frontier targets of many sensings, averaged while their environment lasts.

A frontier row is a snapshot's sensation of one POV, searched for after
the environment changed: it can never be sensed again. Sensed once, its
noise leaves the pose it asks for uncertain by the noise over the eye's
weakest pose direction; where that exceeds the precision a compensation is
held to (``SearchAndSample._max_pose_error``) no search toward it can be
accepted, however well its end is averaged. Which rows will be frontier
rows depends on the next displacement, which the agent cannot know; every
row is as likely. So, only where one sensing cannot pin a pose, each
snapshot senses up to ``averaged_targets`` of its rows again before the
environment changes (the rows pooled least so far, in turn over the POVs),
as often as lets a target pass where the weakest pose direction is
``target_singular`` times the start's: a few sensings on many rows, for
only where that direction is strong can any target pass. Their means and
counts go into the snapshot (``Snapshot.counts``), so matches, the test of
a target standing out and the averaged check of a search's end all see
the target's own variance, and frontier requests take the rows of most
sensings first (``anchors.frontier_requests``).
"""
from __future__ import annotations

import numpy as np


def rows_to_average(counts: np.ndarray, wanted: int, event: int) -> np.ndarray:
    """The ``wanted`` rows of fewest pooled sensings ``counts`` ``(K,)``,
    ties taken in turn from row ``event * wanted`` (modulo ``K``) on, so
    that successive events average other rows."""
    counts = np.asarray(counts)
    n_rows = len(counts)
    if n_rows == 0 or wanted <= 0:
        return np.zeros(0, dtype=int)
    turn = (np.arange(n_rows) - event * wanted) % n_rows
    return np.lexsort((turn, counts))[:min(wanted, n_rows)]


def average_rows(body, motor_states: np.ndarray, sensations: np.ndarray, counts: np.ndarray,
                 rows: np.ndarray, repeats: int):
    """Sense ``motor_states[rows]`` ``repeats`` more times each (one call,
    never answered from memory) and pool the finite sensings with the
    ``counts`` already averaged in ``sensations``. Returns the new
    ``(sensations (K, S), counts (K,))`` (copies)."""
    sensations = np.array(sensations, dtype=float, copy=True)
    counts = np.array(counts, dtype=int, copy=True)
    rows = np.asarray(rows, dtype=int)
    if not len(rows) or repeats <= 0:
        return sensations, counts
    asked = np.repeat(np.asarray(motor_states, dtype=float)[rows], repeats, axis=0)
    with body.fresh():
        sensed = np.asarray(body.sense(asked), dtype=float).reshape(len(rows), repeats, -1)
    finite = np.all(np.isfinite(sensed), axis=2)
    added = finite.sum(axis=1)
    total = np.where(finite[:, :, None], sensed, 0.0).sum(axis=1)
    before = np.where(np.all(np.isfinite(sensations[rows]), axis=1), counts[rows], 0)
    previous = np.where(before[:, None] > 0, sensations[rows], 0.0) * before[:, None]
    pooled = before + added
    ok = pooled > 0
    sensations[rows[ok]] = (previous[ok] + total[ok]) / pooled[ok, None]
    counts[rows[ok]] = pooled[ok]
    return sensations, counts


def averages_targets(agent) -> bool:
    """Whether the agent averages sweep rows as targets: where noise that
    spreads sized the tolerances, frontier rows are searched, and a target
    sensed once leaves its pose, at the weakest pose singular value measured
    at the start, more uncertain than ``_max_pose_error`` and, at
    ``target_singular`` times it, too (``_target_repeats`` above one)."""
    if not agent._noisy or agent._repeats <= 1 or agent.params.frontier_attempts == 0 or \
            agent.structure.weakest <= 0:
        return False
    limit = agent._max_pose_error()
    return bool(np.isfinite(limit)) and agent.structure.noise / agent.structure.weakest > limit \
        and _target_repeats(agent) > 1


def _target_repeats(agent) -> int:
    structure = agent.structure
    return target_repeats(structure.noise, agent.params.target_singular * structure.weakest,
                          agent._max_pose_error(), agent._repeats)


def averaged_targets(agent, pooled: np.ndarray, counts: np.ndarray):
    """``pooled``, ``counts`` (this event's snapshot rows, ``anchors.pooled_sweep``)
    with some rows averaged more where the agent ``averages_targets``, else
    unchanged: ``averaged_targets`` rows while the frontier searches find
    new POVs, fewer as their budget falls (``_frontier_budget``): averaging
    pays only where a frontier target may be searched. Each row pooled from
    fewer sensings than lets a target where the weakest pose singular value
    is ``target_singular`` times the start's pass the test with its end
    averaged ``_repeats`` times (``target_repeats``) is sensed that many
    times more but one."""
    if not averages_targets(agent):
        return pooled, counts
    p, wanted = agent.params, _target_repeats(agent)
    share = int(np.ceil(p.averaged_targets * agent._frontier_budget() / p.frontier_attempts))
    rows = rows_to_average(counts, share, agent._event)
    agent._body.stage = "sweep"
    return average_rows(agent._body, agent._store.samples[:len(pooled), 0], pooled, counts,
                        rows[counts[rows] < wanted], wanted - 1)


def target_repeats(noise: float, singular: float, limit: float, end_repeats: int) -> int:
    """Sensings of a target that keep the predicted pose error of its
    compensation, with the end averaged ``end_repeats`` times, within
    ``limit`` where the weakest pose singular value is ``singular``:
    ``noise^2 (1/k + 1/end_repeats) / singular^2 <= limit^2``; ``end_repeats``
    where even an exact target would not pass."""
    room = (limit * singular / noise) ** 2 - 1.0 / end_repeats
    if room <= 0:
        return int(end_repeats)
    return int(np.clip(np.ceil(1.0 / room), 1, end_repeats))
