"""A clocked run saved at a reaction's end goes on as if never stopped
(``clocked_run.drive(..., resume=True)``): the agent node's snapshot on the
row clock is this pickle (graph.nodes.agent_restart). Offline the body, its
clock included, is saved with the run, so the resumed run must be the
uninterrupted one bit for bit."""
import pickle

import numpy as np

from sensorispace_ros import config
from sensorispace_ros.core.clocked_run import begin_run, drive
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.run_world import run_world
from sensorispace_ros.core.world_clock import ClockedBody, change_rows

SAVE_AT = 60          # reactions


def test_a_run_saved_at_a_reaction_end_resumes_bit_for_bit():
    cfg = config.load_config("config/smoke.yaml", {"world.clock": "rows",
                                                   "world.change_interval": 2000.0})
    world = run_world(cfg)
    params = NaiveParams(**cfg["naive"])
    events = list(world.events)
    body = ClockedBody(world.body(lights=world.initial_lights),
                       [world.initial_lights] + [e.lights for e in events],
                       change_rows(len(events), 2000.0, world.seed))
    run = begin_run(body, world.m0, world.seed, params, params.clock_sweep_budget)
    saved, seen = [], [0]

    def after_reaction():
        seen[0] += 1
        if seen[0] == SAVE_AT:
            saved.append(pickle.dumps(run))
    drive(run, equality_changes=0, second_round=lambda: False, after_reaction=after_reaction)
    assert saved and seen[0] > SAVE_AT          # saved mid-run

    resumed = pickle.loads(saved[0])
    assert len(resumed.event_states) - 1 == SAVE_AT
    drive(resumed, equality_changes=0, second_round=lambda: False, resume=True)
    np.testing.assert_array_equal(resumed.agent.points_of_view, run.agent.points_of_view)
    assert resumed.event_states == run.event_states
    assert resumed.log.flagged == run.log.flagged
    assert resumed.log.reference_row == run.log.reference_row
    assert (resumed.agent.queries_total, resumed.lost_rows, resumed.undone) == \
        (run.agent.queries_total, run.lost_rows, run.undone)
    assert resumed.body.row == run.body.row and len(run.agent.points_of_view) > 3
