"""The brief POV walk of the agent on a clock (points_of_view.brief_loop_walks):
the same POVs as the lockstep walk, on the level set, for fewer rows."""
import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.core.body import SensingOnly
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.clocked_agent import ClockedAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.run_world import run_world

SMOKE = "config/smoke.yaml"


def _walks(kinds, **overrides):
    """One state of the smoke world's start POV walked by each agent kind
    (each started alone in the same static world): ``(world, [(agent,
    samples, pov rows)])``."""
    cfg = config.load_config(SMOKE)
    world = run_world(cfg)
    params = NaiveParams(**{**cfg["naive"], **overrides})
    walks = []
    state = None
    for kind in kinds:
        agent = kind(SensingOnly(world.body(lights=world.initial_lights)), params)
        agent.start(world.m0, seed=world.seed)
        if state is None:
            state = agent.points_of_view[0, len(agent.points_of_view[0]) // 3][None]
        before = agent._body.rows.get("pov", 0)
        agent._body.stage = "pov"
        with agent._body.fresh():
            indices, _ = agent._sample_povs(agent._phase.to_phase(state))
        walks.append((agent, agent._store.samples[indices[0]],
                      agent._body.rows.get("pov", 0) - before))
    return world, walks


@pytest.fixture(scope="module")
def two_walks():
    """The lockstep agent's walk, then the clocked agent's."""
    return _walks((NaiveAgent, ClockedAgent))


def test_the_brief_walk_costs_fewer_rows(two_walks):
    _, ((_, _, full_rows), (_, _, brief_rows)) = two_walks
    assert brief_rows > 0
    assert brief_rows <= 0.6 * full_rows


def test_the_brief_walk_gives_the_same_pov(two_walks):
    _, ((_, full, _), (_, brief, _)) = two_walks
    gap = (full[:, None, :] - brief[None, :, :] + np.pi) % (2 * np.pi) - np.pi
    distance = np.linalg.norm(gap, axis=2)
    # Every sample of one lies on the other's loop (within the samples' spacing).
    spacing = np.median(np.linalg.norm(np.diff(full, axis=0), axis=1))
    assert max(distance.min(axis=0).max(), distance.min(axis=1).max()) < spacing


def test_the_brief_walks_samples_lie_on_the_level_set(two_walks):
    world, (_, (agent, brief, _)) = two_walks
    body = world.body(lights=world.initial_lights)
    sensed = body.sense(agent._phase.to_body(brief))
    scale = np.max(np.abs(sensed[0]))
    assert np.max(np.abs(sensed - sensed[0])) < 1e-5 * scale


def test_the_lockstep_agent_keeps_its_walk(two_walks):
    # The lockstep walk polishes its knots and repairs its samples: its
    # samples come back onto the level set to round-off.
    world, ((agent, full, _), _) = two_walks
    body = world.body(lights=world.initial_lights)
    sensed = body.sense(agent._phase.to_body(full))
    assert np.max(np.abs(sensed - sensed[0])) < 1e-8 * np.max(np.abs(sensed[0]))


def test_without_the_brief_walk_the_clocked_agent_walks_as_the_lockstep_one():
    _, ((_, full, full_rows), (_, clocked, clocked_rows)) = _walks(
        (NaiveAgent, ClockedAgent), clock_brief_walk=False)
    assert clocked_rows == full_rows
    np.testing.assert_array_equal(clocked, full)


@pytest.mark.parametrize("name, value", [("clock_pov_predictor_tol", 0.0),
                                         ("clock_pov_polish_iterations", -1),
                                         ("clock_brief_walk", 2)])
def test_the_brief_walks_parameters_are_checked_at_start_up(name, value):
    with pytest.raises(config.ConfigError, match=rf"naive\.{name}"):
        config.load_config(SMOKE, {f"naive.{name}": value})
