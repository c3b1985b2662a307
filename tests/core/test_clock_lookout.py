"""A change that the resting state cannot see: the arm rests where it senses
nothing, before and after the change, and the change falls in the first
call of a reaction. The reaction must not be kept across it."""
import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.core.body import SensingOnly
from sensorispace_ros.core.clocked_run import ClockedRun, drive
from sensorispace_ros.core.naive.clock_witnesses import LOOKOUT_TRIES, brightest
from sensorispace_ros.core.naive.clocked_agent import ClockedAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.run_world import run_world
from sensorispace_ros.core.world_clock import ClockedBody

SMOKE = "config/smoke.yaml"
LEARN = 40         # changes the agent lives through first


def _sensation(world, lights, motor_states):
    return world.body(lights=lights).sense(np.atleast_2d(np.asarray(motor_states, float)))


def _blind_rest_worlds(world, lights, rest, known):
    """Two light layouts, the start's moved, among which the resting state
    ``rest`` senses nothing while some known POV (``known``: their states)
    senses something, and differently in each."""
    found = []
    for dx in np.linspace(-6.0, 6.0, 13):
        for dy in np.linspace(-6.0, 6.0, 13):
            moved = lights + np.array([dx, dy])
            sensed = _sensation(world, moved, np.vstack([rest, known]))
            if not np.any(sensed[0]) and np.max(np.linalg.norm(sensed[1:], axis=1)) > 0.05:
                if found and np.allclose(found[0][1], sensed[1:]):
                    continue
                found.append((moved, sensed[1:]))
                if len(found) == 2:
                    return found[0][0], found[1][0]
    return None


@pytest.fixture(scope="module")
def blind_rest():
    """The agent lives through the smoke schedule's first changes (it learns
    a few POVs); then world A, among whose lights its resting state senses
    nothing, and world B, the same again, from the second row of the
    reaction to A (in its first call, the sweep, whose first row is the
    resting POV)."""
    cfg = config.load_config(SMOKE)
    world = run_world(cfg)
    params = NaiveParams(**cfg["naive"])
    lights = [np.asarray(world.initial_lights, dtype=float)] + \
        [np.asarray(e.lights, dtype=float) for e in world.events[:LEARN]]
    never = 10 ** 9
    rows = np.concatenate([20_000 * np.arange(1, LEARN + 1), [never, never]])
    body = ClockedBody(world.body(lights=lights[0]), lights + [lights[0], lights[0]], rows)
    agent = ClockedAgent(SensingOnly(body), params)
    agent.start(world.m0, seed=world.seed)
    run = ClockedRun(agent, body)
    run.event_states.append((0, 0))
    seen = {}
    hold, checkpoint = run.hold, agent.checkpoint

    def hold_then_blind(reference, reference_row):
        if body.state == LEARN and "rest" not in seen:
            seen["rest"] = rest = agent.rest_motor_state
            seen["undone"] = run.undone
            worlds = _blind_rest_worlds(world, lights[0], rest,
                                        agent._to_body(agent.points_of_view[:, 0]))
            assert worlds is not None, "no light layout leaves the resting state blind"
            body._lights[LEARN + 1:] = worlds
            body.change_row[LEARN] = body.row
        return hold(reference, reference_row)

    def cut_in_first_call():
        if body.state == LEARN + 1 and body.change_row[LEARN + 1] == never:
            body.change_row[LEARN + 1] = body.row + 1
        return checkpoint()

    run.hold, agent.checkpoint = hold_then_blind, cut_in_first_call
    drive(run, equality_changes=0, second_round=lambda: False)
    return run, body, world, seen


def test_the_resting_state_is_blind_to_the_change(blind_rest):
    run, body, world, seen = blind_rest
    rest = seen["rest"]
    assert body.state == LEARN + 2               # every change happened
    lights = body.lights
    assert not np.any(_sensation(world, lights[LEARN + 1], rest))
    assert not np.any(_sensation(world, lights[LEARN + 2], rest))


def test_no_reaction_is_kept_across_the_unseen_change(blind_rest):
    run, body, world, seen = blind_rest
    states = np.asarray(run.event_states)
    assert np.all(states[:, 0] == states[:, 1]), states
    # The change in the first call was seen: that reaction was undone and
    # made again in world B.
    assert run.undone > seen["undone"]
    assert tuple(states[-1]) == (LEARN + 2, LEARN + 2)


def test_the_brightest_sentinel_must_sense_something():
    states = np.arange(6.0).reshape(3, 2)
    dark = np.zeros((3, 4))
    assert brightest(states, dark, 0.0) is None
    # Within the noise of nothing is nothing; a NaN row is never chosen.
    assert brightest(states, np.full((3, 4), 1e-4), 1e-3) is None
    sensed = np.array([[0.1, 0, 0, 0], [np.nan, 5, 5, 5], [0.3, 0.2, 0, 0]])
    state, sensation = brightest(states, sensed, 1e-3)
    np.testing.assert_array_equal(state, states[2])
    np.testing.assert_array_equal(sensation, sensed[2])


class _Switched:
    """The smoke world's body under light layouts the test switches between."""

    def __init__(self, world, lights):
        self.world, self.lights = world, lights
        self.n_motors, self.n_sensors = 4, world.body(lights=lights).n_sensors

    def sense(self, motor_states):
        return _sensation(self.world, self.lights, motor_states)


@pytest.fixture(scope="module")
def started_agent():
    """An agent started in the smoke world, then the lights moved where some
    of its known POVs sense something and at least 5 random states nothing:
    ``(world, agent, dark states, lit states, the moved lights)``."""
    cfg = config.load_config(SMOKE)
    world = run_world(cfg)
    body = _Switched(world, np.asarray(world.initial_lights, dtype=float))
    agent = ClockedAgent(SensingOnly(body), NaiveParams(**cfg["naive"]))
    agent.start(world.m0, seed=world.seed)
    known = agent._to_body(agent.points_of_view[:, 0])
    states = np.random.default_rng(0).uniform(-np.pi, np.pi, size=(400, agent.n_motors))
    for dx in np.linspace(-6.0, 6.0, 13):
        for dy in np.linspace(-6.0, 6.0, 13):
            moved = body.lights + np.array([dx, dy])
            sensed = _sensation(world, moved, states)
            dark = ~np.any(sensed, axis=1)
            if dark.sum() >= 5 and (~dark).sum() and \
                    np.max(np.linalg.norm(_sensation(world, moved, known), axis=1)) > 0.05:
                body.lights = moved
                return world, agent, states[dark], states[~dark], moved
    raise AssertionError("no light layout with dark states and lit known POVs")


def test_sentinels_that_sense_nothing_take_a_known_pov_that_senses_something(started_agent):
    world, agent, dark, _, lights = started_agent
    assert len(dark) >= 5 and agent._store.count > 0
    agent._lookouts = agent._phase.to_phase(dark[1:5])
    rows = agent.queries_total
    agent.sense_sentinels(dark[0])
    state, held = agent._lookout
    np.testing.assert_allclose(held, _sensation(world, lights, state)[0])
    assert np.any(held)
    # The rest and the 4 candidates, then the known POVs in turn, at most LOOKOUT_TRIES.
    assert 5 < agent.queries_total - rows <= 5 + LOOKOUT_TRIES


def test_a_resting_state_that_senses_something_needs_no_more_rows(started_agent):
    _, agent, dark, lit, _ = started_agent
    agent._lookouts = agent._phase.to_phase(dark[1:5])
    rows = agent.queries_total
    agent.sense_sentinels(lit[0])
    assert agent.queries_total - rows == 5 and agent._lookout is None
