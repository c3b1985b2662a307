"""The brief POV walk of the agent on a clock (points_of_view.brief_loop_walks):
the same POVs as the lockstep walk, on the level set, for fewer rows."""
from dataclasses import replace

import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.core.body import SensingOnly
from sensorispace_ros.core.naive import points_of_view
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.clocked_agent import ClockedAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.run_world import run_world

SMOKE = "config/smoke.yaml"


def _walks(kinds, walk_overrides=(), **overrides):
    """One state of the smoke world's start POV walked by each agent kind
    (each started alone in the same static world; ``walk_overrides`` ``{name:
    value}`` per kind, set after the start): ``(world, [(agent, samples, pov
    rows)])``."""
    cfg = config.load_config(SMOKE)
    world = run_world(cfg)
    params = NaiveParams(**{**cfg["naive"], **overrides})
    walks = []
    state = None
    for kind, walk_params in zip(kinds, list(walk_overrides) or [{}] * len(kinds)):
        agent = kind(SensingOnly(world.body(lights=world.initial_lights)), params)
        agent.start(world.m0, seed=world.seed)
        agent.params = replace(agent.params, **walk_params)
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
    # Its knots between two stencils were corrected with a secant Jacobian
    # (clock_pov_secant_calls): they lie a little farther off than the stencil's.
    assert np.max(np.abs(sensed - sensed[0])) < 1e-4 * scale


def _pushed_brief_walk(agent, monkeypatch, push):
    """The clocked agent's brief walk of its start POV's third sample, every
    knot but the start pushed ``push`` times the walk's ``predictor_tol`` off
    the level set (along its Jacobian's strongest direction, one sign along
    the loop) before the samples are drawn from the knots."""
    class Pushed:
        def resample(self, n_samples, polish_knots=True):
            for path, jacobians in zip(self.paths, self.jacobians_along):
                along = None
                for k in range(1, len(path)):
                    away = np.linalg.svd(jacobians[k])[2][0]
                    if along is not None and away @ along < 0:
                        away = -away
                    path[k], along = path[k] + push * self.predictor_tol * away, away
            return super().resample(n_samples, polish_knots)
    # Whichever walk the agent takes (a stencil every call or secant knots).
    for name in ("LoopWalk", "SecantLoopWalk"):
        walk = getattr(points_of_view, name)
        monkeypatch.setattr(points_of_view, name, type(name, (Pushed, walk), {}))
    state = agent.points_of_view[0, len(agent.points_of_view[0]) // 3][None]
    with agent._body.fresh():
        return agent._walk_povs(agent._phase.to_phase(state))


@pytest.mark.parametrize("push, kept", [(0.0, True), (0.3, True), (3.0, False)])
def test_a_brief_walk_whose_knots_left_the_level_set_is_no_pov(two_walks, monkeypatch,
                                                                push, kept):
    # The brief walk never senses its knots again: a sample its step moves
    # farther than the walk's predictor_tol came from knots off the level set.
    _, (_, (agent, _, _)) = two_walks
    walked = _pushed_brief_walk(agent, monkeypatch, push)
    assert bool(walked.valid[0]) is kept
    assert walked.reason[0] == (points_of_view.VALID if kept else points_of_view.NOT_CLOSED)


def test_a_brief_walk_senses_and_steps_only_its_checked_samples():
    _, ((_, every, every_rows), (_, none, none_rows), (_, some, some_rows)) = _walks(
        (ClockedAgent,) * 3, walk_overrides=(
            {"clock_pov_checked_samples": checked, "clock_pov_polish_iterations": n}
            for checked, n in ((0, 1), (0, 0), (12, 1))))
    # 12 of the 99 samples after the start, evenly spread: the first and last among them.
    stepped = np.flatnonzero(np.any(some != none, axis=1))
    assert len(stepped) == 12 and stepped[0] == 1 and stepped[-1] == len(some) - 1
    assert np.all(np.diff(stepped) >= 8)
    # Each sensed sample takes the step it takes when every one is sensed; the others
    # stay where the walk's spline put them, and no row is spent on them.
    np.testing.assert_array_equal(some[stepped], every[stepped])
    unsensed = np.setdiff1d(np.arange(len(some)), stepped)
    np.testing.assert_array_equal(some[unsensed], none[unsensed])
    assert some_rows - none_rows == 12 and every_rows - none_rows == len(some) - 1


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
                                         ("clock_pov_checked_samples", -1),
                                         ("clock_brief_walk", 2)])
def test_the_brief_walks_parameters_are_checked_at_start_up(name, value):
    with pytest.raises(config.ConfigError, match=rf"naive\.{name}"):
        config.load_config(SMOKE, {f"naive.{name}": value})
