"""NaiveAgent.state() / from_state(): a pickled agent restored on a fresh body
continues exactly as the uninterrupted agent (what the agent node's restart
relies on)."""
import pickle

import numpy as np
import pytest

from sensorispace_ros.core import arm, retina
from sensorispace_ros.core.body import SensingOnly, SimulatedBody
from sensorispace_ros.core.paper.exploration import build_world
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams


def _passive(simulator, lights, world):
    return retina.sensation(arm.forward(simulator.motor_state), lights, world.receptors)


def _drive(agent, simulator, world, events):
    reactions = []
    for event in events:
        simulator.set_lights(event.lights)
        reactions.append(agent.react(_passive(simulator, event.lights, world)))
    return reactions


def _same_reactions(first, second):
    assert len(first) == len(second)
    for a, b in zip(first, second):
        np.testing.assert_array_equal(a.new_pov_ids, b.new_pov_ids)
        np.testing.assert_array_equal(a.new_povs, b.new_povs)
        np.testing.assert_array_equal(a.equality_rows, b.equality_rows)
        np.testing.assert_array_equal(a.rest_motor_state, b.rest_motor_state)
        assert (a.queries, a.calls, a.compensated) == (b.queries, b.calls, b.compensated)
        assert len(a.compensations) == len(b.compensations)
        for ra, rb in zip(a.compensations, b.compensations):
            np.testing.assert_array_equal(ra.motor_state, rb.motor_state)
            assert (ra.event, ra.anchor_event, ra.pov) == (rb.event, rb.anchor_event, rb.pov)


def _same_agent(a, b):
    np.testing.assert_array_equal(a.points_of_view, b.points_of_view)
    for got, want in zip(a.equality_sets(), b.equality_sets()):
        np.testing.assert_array_equal(got, want)
    assert a.queries_by_stage == b.queries_by_stage and a.calls_by_stage == b.calls_by_stage
    assert (a.pov_queries, a.pov_events, a.compensation_queries, a.compensated) == \
        (b.pov_queries, b.pov_events, b.compensation_queries, b.compensated)


@pytest.fixture(scope="module")
def world():
    return build_world(4, {"grid_count": 8})


def test_restored_agent_continues_like_the_uninterrupted_one(world):
    cut = len(world.events) // 2
    reference_sim = SimulatedBody(world.receptors, world.initial_lights)
    reference = NaiveAgent(SensingOnly(reference_sim), NaiveParams())
    reference.start(world.m0)
    _drive(reference, reference_sim, world, world.events[:cut])
    reference_rest = _drive(reference, reference_sim, world, world.events[cut:])

    simulator = SimulatedBody(world.receptors, world.initial_lights)
    agent = NaiveAgent(SensingOnly(simulator), NaiveParams())
    agent.start(world.m0)
    _drive(agent, simulator, world, world.events[:cut])
    assert agent.compensated > 0 and len(agent.equality_sets()[1]) > 0, "nothing to restore"
    blob = pickle.dumps(agent.state())
    del agent                               # the process dies; the simulator lives on
    restored = NaiveAgent.from_state(SensingOnly(simulator), pickle.loads(blob))
    _same_reactions(_drive(restored, simulator, world, world.events[cut:]), reference_rest)
    _same_agent(restored, reference)


def test_restored_agent_in_the_equality_pass_continues_identically(world):
    def explored():
        simulator = SimulatedBody(world.receptors, world.initial_lights)
        agent = NaiveAgent(SensingOnly(simulator), NaiveParams())
        agent.start(world.m0)
        _drive(agent, simulator, world, world.events)
        simulator.set_lights(world.initial_lights)
        agent.begin_equality_pass()
        _drive(agent, simulator, world, world.events[:5])
        return agent, simulator

    reference, reference_sim = explored()
    reference_rest = _drive(reference, reference_sim, world, world.events[5:])
    agent, simulator = explored()
    restored = NaiveAgent.from_state(SensingOnly(simulator), pickle.loads(pickle.dumps(
        agent.state())))
    rest = _drive(restored, simulator, world, world.events[5:])
    assert sum(len(r.equality_rows) for r in rest) > 0, "the pass found no set to compare"
    _same_reactions(rest, reference_rest)
    _same_agent(restored, reference)


def test_state_is_refused_inside_a_reaction(world):
    simulator = SimulatedBody(world.receptors, world.initial_lights)

    class Peeking(SensingOnly):
        def sense(self, motor_states):
            with pytest.raises(RuntimeError, match="inside"):
                agent.state()
            return super().sense(motor_states)

    agent = NaiveAgent(Peeking(simulator), NaiveParams())
    agent.start(world.m0)


def test_agent_records_survive_a_round_trip_through_arrays(tmp_path):
    from dataclasses import fields

    from sensorispace_ros.core.naive.records import NaiveAgentRecords
    rng = np.random.default_rng(2)
    records = NaiveAgentRecords(
        povs=rng.normal(size=(3, 5, 4)), pov_events=np.array([0, 4, 9]),
        pov_queries=np.array([10, 20, 30]), compensation_event=np.array([4, 9]),
        compensation_anchor_event=np.array([0, 4]),
        compensation_motor_state=rng.normal(size=(2, 4)),
        compensation_anchor_motor_state=rng.normal(size=(2, 4)),
        compensation_searched=np.array([True, False]), pairs=np.array([[0, 1], [1, 2]]),
        set_ids=np.array([0, 0]), compensated=2, compensation_queries=77, queries_total=900,
        calls_total=40, queries_by_stage={"sweep": 5, "pov": 60},
        calls_by_stage={"sweep": 1, "pov": 3}, ends_between_loops=7, ends_off_manifold=3)
    np.savez(tmp_path / "records.npz", **records.to_arrays())
    with np.load(tmp_path / "records.npz") as stored:
        back = NaiveAgentRecords.from_arrays({key: stored[key] for key in stored.files})
    for item in fields(NaiveAgentRecords):
        got, expected = getattr(back, item.name), getattr(records, item.name)
        if isinstance(expected, np.ndarray):
            assert got.dtype == expected.dtype and np.array_equal(got, expected), item.name
        else:
            assert got == expected and type(got) is type(expected), item.name


def test_the_refused_search_ends_reach_the_stage_counters_and_the_metrics():
    from types import SimpleNamespace

    from sensorispace_ros.core.naive.records import NaiveAgentRecords, search_fields
    from sensorispace_ros.evaluation.naive import _query_numbers
    from sensorispace_ros.graph.agent_outputs import stage_counters
    agent = SimpleNamespace(queries_by_stage={}, calls_by_stage={}, compensation_queries=[],
                            structure=None, ends_between_loops=5, ends_off_manifold=2)
    assert search_fields(agent) == {"ends_between_loops": 5, "ends_off_manifold": 2}
    assert search_fields(SimpleNamespace()) == {"ends_between_loops": 0, "ends_off_manifold": 0}
    counters, _ = stage_counters(agent)
    assert counters["ends_between_loops"] == 5 and counters["ends_off_manifold"] == 2
    records = NaiveAgentRecords(
        povs=np.zeros((0, 5, 4)), pov_events=np.zeros(0, int), pov_queries=np.zeros(0, int),
        compensation_event=np.zeros(0, int), compensation_anchor_event=np.zeros(0, int),
        compensation_motor_state=np.zeros((0, 4)), compensation_anchor_motor_state=np.zeros((0, 4)),
        compensation_searched=np.zeros(0, bool), pairs=np.zeros((0, 2), int),
        set_ids=np.zeros(0, int), compensated=0, compensation_queries=0, queries_total=0,
        calls_total=0, queries_by_stage={}, calls_by_stage={}, ends_between_loops=5,
        ends_off_manifold=2)
    numbers = _query_numbers(records)
    assert numbers["naive.ends_between_loops"] == 5 and numbers["naive.ends_off_manifold"] == 2
