"""Ground truth of time for a graph run on its own clock (``world.clock`` rows
or wall): the agent node's driver (``graph.clocked_exploration``) notes
positions by command number, the body node knows what each command
executed (``graph.nodes.body_clock``: ``rows_after``, ``state_after``);
joined here into the offline driver's ``ClockTruth`` so that a graph run is
evaluated as an offline one (``evaluation.naive``, ``evaluation.clock``).

A driver position ``2n + 1`` is the first row of command ``n + 1``, ``2n``
the last row of command ``n``. A launched run (``clocked_numbers``) is read
from its checkpoint directory: the agent's snapshot of the run over and the
body's record (``state.clock_truth``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from sensorispace_ros.core.clocked_run import ClockTruth
from sensorispace_ros.core.naive.run import summarize_naive
from sensorispace_ros.core.run_world import run_world
from sensorispace_ros.core.world_clock import clock_body, clock_events
from sensorispace_ros.protocol import BODY_TRUTH_FILE, BODY_TRUTH_LOG_FILE, SNAPSHOT_FILE
from sensorispace_ros.state.agent_journal import read_snapshot
from sensorispace_ros.state.clock_truth import read_clock_truth


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
                       rows_lost_to_restart=int(run.rows_lost_to_restart),
                       start_lost_rows=int(getattr(run, "start_lost_rows", 0)))
    return summarize_naive(run.exploration(world, events, 0.0), truth)


def clocked_numbers(cfg: dict, checkpoint_dir: Path) -> dict:
    """``naive.*`` (``naive.clock.*`` too) of a launched run on its own clock, as
    an offline run's: the agent's run from its snapshot of the run over
    (``agent.snapshot``) joined with the body's record (``body.truth.npz``);
    else only ``analysis.naive_records`` saying what is missing."""
    from sensorispace_ros.evaluation.clock import clock_metrics
    from sensorispace_ros.evaluation.naive import evaluate_naive_run

    checkpoint_dir = Path(checkpoint_dir)
    truth = read_clock_truth(checkpoint_dir / BODY_TRUTH_FILE)
    snapshot_path = checkpoint_dir / SNAPSHOT_FILE
    snapshot = read_snapshot(snapshot_path) if snapshot_path.is_file() else None
    if truth is None or snapshot is None or not snapshot.get("over"):
        return {"analysis.naive_records": (
            f"world.clock {cfg['world']['clock']}: naive.* not evaluated (no "
            f"{BODY_TRUTH_FILE} or no {SNAPSHOT_FILE} of the run over in {checkpoint_dir})")}
    if not truth["whole"]:
        return {"analysis.naive_records": (
            f"world.clock {cfg['world']['clock']}: naive.* not evaluated (the body restarted "
            f"without its {BODY_TRUTH_LOG_FILE}: its {BODY_TRUTH_FILE} holds only the commands "
            "since)")}
    world = run_world(cfg)
    events = clock_events(world, cfg)
    if cfg["world"]["clock"] == "rows":
        body = clock_body(world.body(lights=world.initial_lights), world, cfg)
        body.row, body.held_rows, body.rest_jumps = (truth["rows"], truth["held_rows"],
                                                     truth["rest_jumps"])
        result = graph_clocked_run(snapshot["run"], world, events, clocked_body=body,
                                   rows_after=truth["rows_after"])
    else:
        result = graph_clocked_run(snapshot["run"], world, events,
                                   state_after=truth["state_after"])
    metrics = {**evaluate_naive_run(result, world).metrics, **clock_metrics(result, world)}
    numbers = {key: value for key, value in metrics.items() if key.startswith("naive.")}
    numbers["analysis.naive_records"] = ("world.clock: the agent's snapshot of the run over "
                                         "joined with the body's record (evaluation.graph_clock)")
    return numbers
