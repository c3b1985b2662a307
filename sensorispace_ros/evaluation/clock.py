"""Ground-truth numbers of time for a naive run in a world on its own clock
(``world.clock: rows``; ``core.clocked_run.ClockTruth``): what the
agent detected, what the changes cost it, and whether any accepted
compensation spans two world states. Every key is ``naive.clock.*`` or
``naive.accepted_across_change``.

A *test* is one comparison the agent made of a motor state's sensation
with what it held (a hold that ended, a reaction's checks). Ground truth
knows the world state of every row: a test whose two rows lie in different
world states that give, at the tested motor state and without noise,
sensations farther apart than ``DETECTABLE_SDS`` standard deviations of a
difference of two noisy sensings (at least ``DETECTABLE_FLOOR``) should
flag; recall is the share of those that did, false detections the share of
flags with no change between the two rows.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.body import simulate

DETECTABLE_SDS = 3.0
DETECTABLE_FLOOR = 1e-9


def clock_metrics(run, world) -> dict:
    """``naive.clock.*`` of an offline clocked run (``clocked_run.run_on_clock``, clock ``rows``)."""
    truth = run.clock
    if truth is None:
        return {}
    records_events = np.asarray([c.event for c in run.agent.compensations], dtype=int)
    records_anchors = np.asarray([c.anchor_event for c in run.agent.compensations], dtype=int)
    spans = truth.event_states[:, 0] != truth.event_states[:, 1]
    across = spans[records_events] | spans[records_anchors] if len(records_events) else \
        np.zeros(0, dtype=bool)
    detection = _detection_numbers(truth, world)
    n_povs = len(run.povs)
    # Every motor state probed: the starts a change cut were moves too.
    probed = run.agent.queries_total + int(truth.start_lost_rows)
    per_pov = probed / max(n_povs, 1)
    return {
        "naive.queries_total": int(probed),
        "naive.queries_total_per_pov": per_pov,
        "naive.accepted_across_change": int(np.sum(across)),
        "naive.clock.changes": int(len(truth.change_row)),
        "naive.clock.rows": int(truth.rows),
        "naive.clock.held_rows": int(truth.held_rows),
        "naive.clock.lost_rows": int(truth.lost_rows),
        "naive.clock.undone_reactions": int(truth.undone),
        "naive.clock.salvaged_povs": int(truth.salvaged),
        "naive.clock.reactions": int(len(truth.event_states) - 1),
        "naive.clock.queries_per_pov": per_pov,
        "naive.clock.start_lost_rows": int(truth.start_lost_rows),
        # Motor states probed when the agent found exploring no longer paid (0: it never did).
        "naive.clock.explored_at": int(run.agent.explored_at),
        "naive.clock.pending_povs": int(truth.pending_povs),
        "naive.clock.crossed_reactions": int(truth.crossed),
        "naive.clock.walks_restarted": int(getattr(run.agent, "crossings", 0)),
        "naive.clock.restarts": int(truth.restarts),
        "naive.clock.rows_lost_to_restart": int(truth.rows_lost_to_restart),
        **{f"naive.clock.lost_rows_by_stage.{stage}": int(rows)
           for stage, rows in sorted(truth.lost_by_stage.items())},
        **{f"naive.clock.cuts_by_stage.{stage}": int(n)
           for stage, n in sorted(truth.cuts_by_stage.items())},
        **detection,
    }


def _detection_numbers(truth, world) -> dict:
    log = truth.log
    if not log.flagged:
        return {"naive.clock.tests": 0}
    ref_state = truth.state_of(np.asarray(log.reference_row))
    test_state = truth.state_of(np.asarray(log.test_row))
    flagged = np.asarray(log.flagged, dtype=bool)
    changed = ref_state != test_state
    lights = truth.lights
    threshold = max(DETECTABLE_SDS * np.sqrt(2.0) * float(world.imperfections.noise),
                    DETECTABLE_FLOOR)
    detectable = np.zeros(len(flagged), dtype=bool)
    for i in np.flatnonzero(changed):
        a = _sensation(world, lights[ref_state[i]], log.motor_state[i])
        b = _sensation(world, lights[test_state[i]], log.motor_state[i])
        detectable[i] = np.max(np.abs(a - b)) > threshold
    n_detectable = int(np.sum(detectable))
    n_flagged = int(np.sum(flagged))
    return {
        "naive.clock.tests": int(len(flagged)),
        "naive.clock.detections": n_flagged,
        "naive.clock.detectable": n_detectable,
        "naive.clock.recall": float(np.sum(flagged & detectable) / n_detectable)
        if n_detectable else 1.0,
        "naive.clock.missed": int(np.sum(~flagged & detectable)),
        "naive.clock.false_detections": int(np.sum(flagged & ~changed)),
        "naive.clock.false_detection_rate": float(np.sum(flagged & ~changed) / n_flagged)
        if n_flagged else 0.0,
        "naive.clock.undetectable_changes": int(np.sum(changed & ~detectable)),
    }


def _sensation(world, lights, motor_state) -> np.ndarray:
    """The noiseless sensation at ``motor_state`` among ``lights`` (ground truth)."""
    raw, _ = simulate(np.asarray(motor_state, dtype=float)[None], np.asarray(lights, float),
                      world.receptors, "numpy", world.arm)
    code = world.code
    return (raw if code is None or code.is_identity else code.apply(raw))[0]
