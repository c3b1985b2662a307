"""The naive agent in a world on its own clock (world.clock: rows): it is
told nothing, detects the changes from its sensory flow, drops what a change
cut through and accepts nothing that spans two world states."""
import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.clocked_run import run_on_clock
from sensorispace_ros.core.run_world import run_world
from sensorispace_ros.evaluation.clock import clock_metrics
from sensorispace_ros.evaluation.naive import evaluate_naive_run

SMOKE = "config/smoke.yaml"


@pytest.fixture(scope="module")
def clocked_smoke():
    cfg = config.load_config(SMOKE, {"world.clock": "rows", "world.change_interval": 1000.0})
    world = run_world(cfg)
    run = run_on_clock(world, NaiveParams(**cfg["naive"]), "rows", interval=1000.0)
    metrics = {**evaluate_naive_run(run, world).metrics, **clock_metrics(run, world)}
    return world, run, metrics


def test_no_react_per_change_and_no_notice(clocked_smoke):
    world, run, metrics = clocked_smoke
    truth = run.clock
    # Changes came faster than the agent finished its work: it reacted to
    # fewer than there were (the schedule, then simulation 2 through it
    # again) and some of its reactions were cut.
    assert metrics["naive.clock.changes"] == 2 * len(world.events)
    assert metrics["naive.clock.reactions"] < metrics["naive.clock.changes"]
    assert truth.undone > 0 and truth.lost_rows > 0
    assert truth.held_rows > 0 and truth.rows > truth.held_rows


def test_nothing_accepted_spans_two_worlds(clocked_smoke):
    _, run, metrics = clocked_smoke
    assert metrics["naive.accepted_across_change"] == 0
    assert metrics["naive.wrong_poses"] == 0
    assert metrics["naive.state_changes_accepted"] == 0
    assert metrics["naive.accepted_across_redistribution"] == 0
    assert run.agent.compensated > 0


def test_changes_are_detected_from_the_flow(clocked_smoke):
    _, _, metrics = clocked_smoke
    assert metrics["naive.clock.detectable"] > 50
    assert metrics["naive.clock.recall"] >= 0.99
    assert metrics["naive.clock.false_detection_rate"] <= 0.01


def test_simulation_2_on_the_clock_gives_equality_sets(clocked_smoke):
    _, run, _ = clocked_smoke
    pairs, set_ids = run.agent.equality_sets()
    assert run.agent.queries_by_stage.get("equality_pass", 0) > 0
    assert len(np.unique(set_ids)) > 50 and len(pairs) > 2 * len(np.unique(set_ids))


def test_the_same_seed_gives_the_same_run(clocked_smoke):
    world, run, _ = clocked_smoke
    cfg = config.load_config(SMOKE)
    again = run_on_clock(world, NaiveParams(**cfg["naive"]), "rows", interval=1000.0)
    assert np.array_equal(again.povs, run.povs)
    assert again.agent.queries_total == run.agent.queries_total


def test_wall_clock_is_refused_offline():
    cfg = config.load_config(SMOKE, {"world.clock": "wall"})
    with pytest.raises(config.ConfigError, match=r"world\.clock"):
        run_on_clock(run_world(cfg), NaiveParams(**cfg["naive"]), "wall", interval=1000.0)


def _agent_in_two_worlds(world, params, change_after: int, shift=(0.4, -0.3)):
    """A started ``ClockedAgent`` whose world (the smoke world, then the same
    lights shifted by ``shift``) changes ``change_after`` rows after its start."""
    from sensorispace_ros.core.body import SensingOnly
    from sensorispace_ros.core.naive.clocked_agent import ClockedAgent
    from sensorispace_ros.core.world_clock import ClockedBody

    lights = np.asarray(world.initial_lights, dtype=float)
    shifted = lights + np.asarray(shift, dtype=float)
    body = ClockedBody(world.body(lights=lights), [lights, shifted], np.array([10 ** 9]))
    agent = ClockedAgent(SensingOnly(body), params)
    agent.start(world.m0, seed=world.seed)
    body.change_row = np.array([body.row + change_after])
    return agent, body


def _noisy_smoke_in_two_worlds():
    """The smoke world with receptor noise 1e-6, its params, and its lights
    before and after a shift (a start of thousands of rows)."""
    cfg = config.load_config(SMOKE, {"world.retina.noise": 1e-6})
    world = run_world(cfg)
    lights = np.asarray(world.initial_lights, dtype=float)
    return world, NaiveParams(**cfg["naive"]), [lights, lights + np.array([0.4, -0.3])]


def test_a_change_stops_the_start_at_its_next_call_and_the_start_is_made_again():
    # The start watches its start state once its noise is measured: a change
    # stops it within a call, not after all its rows, and the start made
    # again in the new world is whole. Noisy receptors: a start of thousands of rows.
    from sensorispace_ros.core.body import SensingOnly
    from sensorispace_ros.core.clocked_run import start_clocked
    from sensorispace_ros.core.naive.clocked_agent import ClockedAgent, WorldChanged
    from sensorispace_ros.core.world_clock import ClockedBody

    world, params, worlds = _noisy_smoke_in_two_worlds()
    lights = worlds[0]
    calm = ClockedBody(world.body(lights=lights), worlds, np.array([10 ** 9]))
    ClockedAgent(SensingOnly(calm), params).start(world.m0, seed=world.seed)
    whole = calm.row                               # the start's rows in one world
    change = 600
    assert whole > 3 * change
    cut = ClockedBody(world.body(lights=lights), worlds, np.array([change]))
    with pytest.raises(WorldChanged):
        ClockedAgent(SensingOnly(cut), params).start(world.m0, seed=world.seed)
    assert change < cut.row < 2 * change
    again = ClockedBody(world.body(lights=lights), worlds, np.array([change]))
    agent, first_row, lost = start_clocked(again, world.m0, world.seed, params, 64)
    assert first_row == lost < 2 * change
    assert again.state_at(first_row) == again.state_at(again.row - 1) == 1
    assert agent.structure.pose_rank == 3 and agent.points_of_view.shape[0] == 1


def test_a_change_among_the_start_states_repeats_is_not_taken_for_noise():
    # The start senses its start state 16 times in its first call (rows 1-16
    # after start_clocked's own look at it); a change after the eighth puts
    # the repeats in two worlds, half and half. The noise measured is the receptors' (the
    # last world's repeats), so start_clocked sees that the start state
    # changed and makes the start again; a noise the size of the change
    # would have hidden it and been kept.
    from sensorispace_ros.core.body import SensingOnly
    from sensorispace_ros.core.clocked_run import start_clocked
    from sensorispace_ros.core.naive.clocked_agent import ClockedAgent
    from sensorispace_ros.core.world_clock import ClockedBody

    world, params, worlds = _noisy_smoke_in_two_worlds()
    lights = worlds[0]
    calm = ClockedAgent(SensingOnly(ClockedBody(world.body(lights=lights), worlds,
                                                np.array([10 ** 9]))), params)
    calm.start(world.m0, seed=world.seed)
    body = ClockedBody(world.body(lights=lights), worlds, np.array([9]))
    agent, first_row, lost = start_clocked(body, world.m0, world.seed, params, 64)
    assert lost > 0 and body.state_at(first_row) == 1
    assert agent.noise_sd < 1.5 * calm.noise_sd
    assert agent.structure.pose_rank == 3


def test_a_start_made_again_where_the_start_state_sees_less_is_not_kept():
    # The paper world after its first change shows the start state too
    # little for three pose directions: every probe of a start made there
    # measures pose rank 2. A change cut the start in world 0 after it had
    # measured rank 3, so the starts made in world 1 are made again until a
    # world shows the start state as well (2, world 0's lights again).
    from sensorispace_ros.core.clocked_run import start_clocked
    from sensorispace_ros.core.world_clock import ClockedBody

    cfg = config.load_config("config/paper.yaml")
    world = run_world(cfg)
    params = NaiveParams(**cfg["naive"])
    lights = np.asarray(world.initial_lights, dtype=float)
    worlds = [lights, np.asarray(world.events[1].lights, dtype=float), lights]
    body = ClockedBody(world.body(lights=lights), worlds, np.array([500, 5000]))
    agent, first_row, lost = start_clocked(body, world.m0, world.seed, params, 64)
    assert lost > 4500 and body.state_at(first_row) == 2
    assert agent.structure.pose_rank == 3 and agent.points_of_view.shape[0] == 1


def test_every_motor_state_the_body_executed_is_counted_cut_starts_included(clocked_smoke):
    # The body's clock counts every row it executed; all but the holds were
    # the agent's probes, those of the starts a change cut too.
    cfg = config.load_config(SMOKE, {"seed": 1, "world.clock": "rows",
                                     "world.change_interval": 2000.0,
                                     "world.retina.noise": 1e-6})
    world = run_world(cfg)
    run = run_on_clock(world, NaiveParams(**cfg["naive"]), "rows", interval=2000.0)
    noisy = clock_metrics(run, world)
    assert noisy["naive.clock.start_lost_rows"] > 0
    for metrics in (noisy, clocked_smoke[2]):
        moved = metrics["naive.clock.rows"] - metrics["naive.clock.held_rows"]
        assert metrics["naive.queries_total"] == moved


def test_a_walk_goes_on_through_a_change_to_the_same_pov():
    # The states of one eye pose sense alike in any world: a walk a change
    # cuts is walked again in the new world and gives the POV it would have
    # given in the old one; every row of the walk kept saw one world.
    cfg = config.load_config(SMOKE)
    world = run_world(cfg)
    params = NaiveParams(**{**cfg["naive"], "clock_walk_attempts": 4})
    calm, _ = _agent_in_two_worlds(world, params, change_after=10 ** 8)
    cut, body = _agent_in_two_worlds(world, params, change_after=120)
    state = calm.points_of_view[0, len(calm.points_of_view[0]) // 3][None]
    results = []
    for agent in (calm, cut):
        rest = agent.rest_motor_state
        agent._tripwire.arm(rest, agent.sense_again(rest)[0], agent.noise_sd)
        agent._body.stage = "pov"
        walked = agent._sample_povs(agent._phase.to_phase(state))
        agent._tripwire.disarm()
        results.append(agent._store.samples[walked[0][0]])
    assert calm.crossings == 0 and cut.crossings == 1
    assert body.state == 1 and cut.crossing["passed"] < cut.crossing["fired"]
    gap = (results[0][:, None, :] - results[1][None, :, :] + np.pi) % (2 * np.pi) - np.pi
    distance = np.linalg.norm(gap, axis=2)
    assert max(distance.min(axis=0).max(), distance.min(axis=1).max()) < 0.05
    # The walk kept began after the sentinel flagged: every row of it saw the new world.
    offset = body.row - cut.rows_sent
    assert body.state_at(offset + cut.crossing["passed"] - 1) == 0
    assert body.state_at(offset + cut.crossing["latest"]) == 1


@pytest.fixture(scope="module")
def walking_through():
    overrides = {"world.clock": "rows", "world.change_interval": 1000.0,
                 "naive.clock_walk_attempts": 4}
    cfg = config.load_config(SMOKE, overrides)
    world = run_world(cfg)
    run = run_on_clock(world, NaiveParams(**cfg["naive"]), "rows", interval=1000.0)
    return {**evaluate_naive_run(run, world).metrics, **clock_metrics(run, world)}


def test_walks_through_changes_keep_their_reactions(clocked_smoke, walking_through):
    metrics = walking_through
    assert metrics["naive.clock.crossed_reactions"] > 0
    assert metrics["naive.clock.walks_restarted"] >= metrics["naive.clock.crossed_reactions"]
    assert metrics["naive.accepted_across_change"] == 0
    assert metrics["naive.wrong_poses"] == 0 and metrics["naive.state_changes_accepted"] == 0
    assert metrics["naive.clock.recall"] >= 0.99
    assert metrics["naive.clock.false_detection_rate"] <= 0.01
    # Walks kept through a cut lose fewer rows than a cut that undoes the reaction.
    assert clocked_smoke[2]["naive.clock.crossed_reactions"] == 0
    # (a stage that lost no rows has no entry)
    assert metrics.get("naive.clock.lost_rows_by_stage.pov", 0) < \
        clocked_smoke[2]["naive.clock.lost_rows_by_stage.pov"]


def test_clock_walk_attempts_is_checked_at_start_up():
    with pytest.raises(config.ConfigError, match=r"clock_walk_attempts"):
        config.load_config(SMOKE, {"naive.clock_walk_attempts": 0})


def test_lost_rows_are_counted_by_stage(clocked_smoke):
    _, _, metrics = clocked_smoke
    by_stage = {k: v for k, v in metrics.items() if k.startswith("naive.clock.lost_rows_by_")}
    cuts = {k: v for k, v in metrics.items() if k.startswith("naive.clock.cuts_by_stage.")}
    assert sum(by_stage.values()) > 0 and sum(cuts.values()) >= metrics[
        "naive.clock.undone_reactions"]
    # Undone reactions and dropped pending walks lose rows; the start's retries too.
    assert sum(by_stage.values()) <= metrics["naive.clock.lost_rows"]


@pytest.fixture(scope="module")
def clocked_noisy_smoke():
    """The smoke world on the row clock, its receptors noisy by 1e-12 (far
    below what a brief walk's unchecked samples lie off the level set)."""
    cfg = config.load_config(SMOKE, {"seed": 1, "world.clock": "rows",
                                     "world.change_interval": 10000.0,
                                     "world.retina.noise": 1e-12})
    world = run_world(cfg)
    return world, run_on_clock(world, NaiveParams(**cfg["naive"]), "rows", interval=10000.0)


def test_simulation_2_matches_with_the_ratio_test_where_the_agent_measured_noise(
        clocked_noisy_smoke):
    # Where the agent measured a noise its matches must stand out by the
    # ratio, as the lockstep sweep's do; a match by separation alone is
    # refused (ValueError) and the run stops.
    _, run = clocked_noisy_smoke
    sweep = run.agent._sweep
    assert sweep is not None and sweep.ratio > 0 and sweep.separation < sweep.match_tol
    assert len(sweep.history) > 1            # simulation 2 matched sweeps to its end


def test_brief_walks_are_kept_where_the_measured_noise_is_below_their_own_error(
        clocked_noisy_smoke):
    # Every sample of a walk is held to its start's sensation where noise
    # sized the tolerances; a brief walk's unchecked samples lie ~1e-5 off,
    # which noise 1e-12 does not cover: without the walk's own allowance no
    # POV is kept and the run finds nothing.
    world, run = clocked_noisy_smoke
    metrics = {**evaluate_naive_run(run, world).metrics, **clock_metrics(run, world)}
    assert 1e-13 < run.agent.structure.noise < 1e-11
    assert metrics["naive.distinct_positions"] >= 20
    assert metrics["naive.wrong_poses"] == 0 and metrics["naive.accepted_across_change"] == 0


def test_a_pending_solution_on_a_known_pov_is_not_walked_again():
    # A solution whose walk a change cut waits in ``pending``; the reaction
    # made again may walk its POV meanwhile. Walked then, it would be a
    # second POV of one position; a state of another pose is walked.
    cfg = config.load_config(SMOKE)
    world = run_world(cfg)
    agent, _ = _agent_in_two_worlds(world, NaiveParams(**cfg["naive"]), change_after=10 ** 8)
    known = agent._store.count
    # A sample of the first POV a third of the way round that senses its
    # sensation (a brief walk leaves most samples where its spline put them).
    samples = agent._store.samples[0]
    sensed = world.body(lights=world.initial_lights).sense(agent._to_body(samples))
    third = np.arange(len(samples) // 4, len(samples) // 2)
    on_loop = samples[third[np.argmin(np.linalg.norm(sensed[third] - sensed[0], axis=1))]]
    rest = agent.rest_motor_state
    agent.pending = on_loop[None].copy()
    assert agent.walk_pending(agent.sense_again(rest)[0]) == 0
    assert agent._store.count == known and not len(agent.pending)
    # The same state without the test: a second POV of the first one's pose.
    agent._pending_known = lambda state: False
    agent.pending = on_loop[None].copy()
    assert agent.walk_pending(agent.sense_again(rest)[0]) == 1
    twin = agent._store.samples[known]
    gap = (twin[:, None, :] - agent._store.samples[0][None] + np.pi) % (2 * np.pi) - np.pi
    assert np.linalg.norm(gap, axis=2).min(axis=1).max() < 0.05
    # Another pose is not taken for a known one.
    del agent._pending_known
    other = on_loop + np.array([0.0, 0.3, -0.3, 0.0])
    assert agent._pending_known(other) is False
    # Where nothing is lit, no sensation pins a pose: a blank state is no known POV.
    dark, _ = _agent_in_two_worlds(world, NaiveParams(**cfg["naive"]), change_after=0,
                                   shift=(100.0, 100.0))
    assert not np.any(dark.sense_again(dark._to_body(on_loop[None])))
    assert dark._pending_known(on_loop) is False


def test_a_frontier_target_a_known_unswept_pov_senses_is_not_searched(clocked_smoke):
    # The bounded sweep leaves POVs out; a frontier row's target may be one of
    # them. The known POVs nearest its start are sensed first (a few rows, not
    # a search): a target one senses is that POV and is not searched; a target
    # none senses, and every anchor, is.
    from sensorispace_ros.core.naive.anchors import Request
    from sensorispace_ros.core.naive.clock_known import NEAR_POVS

    agent = clocked_smoke[1].agent
    samples = agent._store.samples
    k = len(samples) // 2
    sensed = agent._body.sense(samples[:, 0])
    elsewhere = agent._body.sense(samples[k, 0][None] + 1.3)[0]
    current = np.full_like(sensed, np.nan)
    current[0] = sensed[0]                        # the one POV swept
    requests = [Request(0, 3, sensed[k], samples[3, 0], start=samples[k, 0] + 1e-3),
                Request(0, 4, elsewhere, samples[4, 0], start=samples[k, 0] + 1e-3),
                Request(0, -1, sensed[k], samples[0, 0])]
    agent._body.forget()                          # what the test sensed is not the agent's
    rows = agent._body.total_rows
    assert agent._unswept_targets(requests, current) == [1, 2]
    assert 0 < agent._body.total_rows - rows <= 2 * NEAR_POVS
    np.testing.assert_array_equal(current[k], sensed[k])


def test_an_undone_reaction_loses_its_compensations_and_sets_and_keeps_the_earlier_ones(
        clocked_smoke):
    from sensorispace_ros.core.naive.records import CompensationRecord

    _, run, _ = clocked_smoke
    agent = run.agent
    before = list(agent.compensations)
    pairs, set_ids = (x.copy() for x in agent.equality_sets())
    assert before and len(set_ids)
    saved = agent.checkpoint()
    assert "compensations" not in saved and "_sets" not in saved   # kept by length
    extra = CompensationRecord(event=-1, anchor_event=-1, anchor_motor_state=np.zeros(4),
                               motor_state=np.zeros(4), pov=-1, searched=True)
    agent.compensations.append(extra)
    assert agent._sets.add([0, 1], [2, 3]) >= 0
    agent.restore(saved, salvage=False)
    assert agent.compensations == before and extra not in agent.compensations
    for now, then in zip(agent.equality_sets(), (pairs, set_ids)):
        np.testing.assert_array_equal(now, then)
    assert all(a is b for a, b in zip(agent.compensations, before))
    # The lists a reaction only extends: no record of them changes later.
    agent.compensations.extend([extra])
    agent.restore(agent.checkpoint(), salvage=False)
    assert agent.compensations[-1] is extra
    agent.restore(saved, salvage=False)
    assert agent.compensations == before



@pytest.fixture(scope="module")
def clocked_rotations():
    """The rotation world's agent (``chained_anchors``) on the row clock."""
    cfg = config.load_config("config/rotations-smoke.yaml",
                             {"world.clock": "rows", "world.change_interval": 2000.0})
    assert cfg["naive"]["chained_anchors"]
    world = run_world(cfg)
    run = run_on_clock(world, NaiveParams(**cfg["naive"]), "rows", interval=2000.0)
    return world, run


def test_a_reaction_that_takes_no_snapshot_is_checked_against_its_own_rest(clocked_rotations):
    """With ``chained_anchors`` a reaction whose rest is not chained to the
    start's takes no snapshot: the check after it compares the rest sensed
    again with what this reaction sensed there, not with an older snapshot's
    (every such reaction would be undone as cut)."""
    world, run = clocked_rotations
    metrics = clock_metrics(run, world)
    assert metrics["naive.clock.detectable"] > 500
    assert metrics["naive.clock.recall"] >= 0.99
    assert metrics["naive.clock.false_detection_rate"] <= 0.01


def test_a_turning_world_on_the_clock_is_judged_in_the_worlds_the_agent_saw(clocked_rotations):
    """The pose a compensation is asked for is turned by the orientations of
    the worlds its reaction and its anchor's saw, not of the schedule's
    changes numbered as the reactions."""
    world, run = clocked_rotations
    metrics = evaluate_naive_run(run, world).metrics
    assert metrics["naive.compensations_accepted"] >= 10
    assert metrics["naive.wrong_poses"] == 0
    assert metrics["naive.pose_error_median"] < 1e-6


def test_the_checks_after_a_reaction_take_one_call():
    # The resting states and the witnesses are sensed together: one round
    # trip in the graph, whatever the witnesses.
    cfg = config.load_config(SMOKE)
    world = run_world(cfg)
    agent, body = _agent_in_two_worlds(world, NaiveParams(**cfg["naive"]), change_after=10 ** 6)
    agent.watched(agent.react, agent.sense_sentinels(agent.rest_motor_state))
    rest = agent.rest_motor_state
    states, _ = agent._witness_states()
    assert len(states) > 0
    calls, rows = agent._body.total_calls, agent.queries_total
    again, moved = agent.check_reaction([rest, rest])
    assert agent._body.total_calls == calls + 1
    assert agent.queries_total == rows + 2 + len(states)
    assert again.shape == (2, body.n_sensors) and not moved
    body.change_row = np.array([body.row])      # the lights move now
    _, moved = agent.check_reaction([rest])
    assert moved


def test_a_clocked_agent_senses_a_call_with_a_new_row_whole():
    # A row remembered from before a change the sentinels have not flagged
    # yet must not join rows of the new world in one call (the lockstep agent
    # senses only a call's new rows: its world waits for it).
    from sensorispace_ros.core.naive.agent import NaiveAgent
    from sensorispace_ros.core.naive.clocked_agent import ClockedAgent

    class Recording:
        n_motors, n_sensors = 2, 3

        def __init__(self):
            self.sent = []

        def sense(self, rows):
            rows = np.asarray(rows, dtype=float)
            self.sent.append(len(rows))
            return np.cos(rows @ np.ones((2, 3)))

    known, new = np.zeros((1, 2)), np.ones((1, 2))
    sent = {}
    for kind in (ClockedAgent, NaiveAgent):
        body = Recording()
        agent = kind(body, NaiveParams())
        agent._body.sense(known)
        agent._body.sense(np.vstack([known, new]))
        sent[kind] = body.sent
    assert sent[ClockedAgent] == [1, 2] and sent[NaiveAgent] == [1, 1]


def test_the_agent_places_its_povs_on_the_true_lattice_and_finds_povs_at_its_holes(clocked_smoke):
    # The lattice the clocked agent measured from its own equality sets is the
    # world's grid: the POVs it places have integer coordinates that an
    # integer map of determinant +-1 takes to their true grid offsets. Some of
    # its POVs were found by searching an empty point of that lattice, and
    # each sits at the point searched (the map stays exact with them placed).
    world, run, _ = clocked_smoke
    agent = run.agent
    holes = agent._hole_map
    assert holes is not None and np.count_nonzero(holes.placed) > agent._store.count // 2
    true_poses = world.arm.forward(np.asarray(run.povs)[:, 0])    # ground truth, as the evaluator's
    placed = np.flatnonzero(holes.placed[:agent._store.count])
    offsets = (true_poses[placed, :2] - true_poses[placed[0], :2]) / world.spacing
    truth = np.round(offsets).astype(int)
    np.testing.assert_allclose(offsets, truth, atol=1e-6)
    design = np.c_[holes.ij[placed], np.ones(len(placed))]
    coef = np.round(np.linalg.lstsq(design, truth.astype(float), rcond=None)[0])
    np.testing.assert_array_equal(design @ coef, truth)
    assert abs(round(np.linalg.det(coef[:2]))) == 1
    assert holes.found > 0 and holes.fails
