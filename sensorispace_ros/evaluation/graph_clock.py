"""Ground truth of time for a graph run on its own clock (``world.clock`` rows
or wall): the agent node's driver (``graph.clocked_exploration``) notes
positions by command number, the body node knows what each command
executed (``graph.nodes.body_clock``: ``rows_after``, ``state_after``);
joined here into the offline driver's ``ClockTruth`` so that a graph run is
evaluated as an offline one (``evaluation.naive``, ``evaluation.clock``).

A driver position ``2n + 1`` is the first row of command ``n + 1``, ``2n``
the last row of command ``n``.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.clocked_run import ClockTruth
from sensorispace_ros.core.naive.run import summarize_naive


def position(value) -> tuple[int, bool]:
    """``(command number, first)`` of a driver position: the first row of that
    command (``first``) or its last."""
    value = int(value)
    return ((value - 1) // 2 + 1, True) if value % 2 else (value // 2, False)


def graph_clocked_run(run, world, events: list, *, clocked_body=None, rows_after=None,
                      state_after=None):
    """The offline ``NaiveRunResult`` (with its ``ClockTruth``) of a graph run:
    ``run`` the agent node's driver, ``events`` the changes the world played
    (``body_clock.clock_events``); ``rows``: the body node's ``clocked_body``
    and ``rows_after``; ``wall``: its ``state_after``. ``run``'s positions are
    turned into rows (rows) or world states (wall) in place."""
    if clocked_body is not None:
        numbers = np.asarray(sorted(rows_after))

        def after(number):
            # A number the body never executed (a killed agent's last, not
            # sent): the clock stood where the command before left it.
            return rows_after[int(numbers[np.searchsorted(numbers, number, side="right") - 1])]

        def row_of(value):
            number, first = position(value)
            return after(number - 1) if first else after(number) - 1

        def state_of(value):
            return clocked_body.state_at(row_of(value))
        run.log.reference_row = [row_of(v) for v in run.log.reference_row]
        run.log.test_row = [row_of(v) for v in run.log.test_row]
        run.event_states = [(int(state_of(a)), int(state_of(b))) for a, b in run.event_states]
        truth_state_of, changes = clocked_body.state_at, clocked_body.change_row.copy()
        rows, held = int(clocked_body.row), int(clocked_body.held_rows)
        rest_jumps = clocked_body.rest_jumps.copy()
    else:
        numbers = np.asarray(sorted(state_after))
        states = np.asarray([state_after[n] for n in numbers])

        def state_of_number(number):
            at = np.searchsorted(numbers, number, side="right") - 1
            return int(states[max(at, 0)])

        def truth_state_of(values):
            return np.asarray([state_of_number(position(v)[0])
                               for v in np.reshape(values, -1)]).reshape(np.shape(values))
        run.event_states = [(int(truth_state_of(a)), int(truth_state_of(b)))
                            for a, b in run.event_states]
        changes = np.arange(1, int(states.max(initial=0)) + 1)
        rows, held = int(numbers.max(initial=0)), 0
        rest_jumps = np.full(len(changes), np.nan)
    lights = [world.initial_lights] + [e.lights for e in events]
    truth = ClockTruth(change_row=changes, rest_jumps=rest_jumps,
                       event_states=np.asarray(run.event_states, dtype=int).reshape(-1, 2),
                       log=run.log, lost_rows=int(run.lost_rows), undone=int(run.undone),
                       salvaged=int(run.salvaged), rows=rows, held_rows=held,
                       lost_by_stage=dict(run.lost_by_stage), cuts_by_stage=dict(run.cut_in),
                       pending_povs=int(run.pending_povs), crossed=int(run.crossed),
                       state_of=truth_state_of, lights=lights, restarts=int(run.restarts),
                       rows_lost_to_restart=int(run.rows_lost_to_restart))
    return summarize_naive(run.exploration(world, events, 0.0), truth)
