"""The naive agent moves its POVs onto one lattice at the end of exploring
(``naive.relax_povs``, core/naive/pov_relaxation.py), on a body whose noise
no parameter names: ground truth (the arm's forward model) checks that a
moved POV is still one pose. How much nearer the lattice the POVs come is
measured on the paper grid (docs/noise.md, "POVs moved onto one lattice")."""
import functools

import numpy as np
import pytest

from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.pov_relaxation import RelaxedPOVs
from sensorispace_ros.core.naive.run import explore_naive
from sensorispace_ros.core.paper.exploration import build_world

from imperfect_bodies import ImperfectSensing


@pytest.fixture(scope="module")
def relaxed_run():
    world = build_world(0, {"grid_count": 16, "initial_center": "center"})
    wrapper = functools.partial(ImperfectSensing, seed=5, noise=1e-4)
    found = {}
    original = RelaxedPOVs.relax_povs

    def spied(agent):
        found["samples"] = agent._store.samples.copy()
        return original(agent)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(RelaxedPOVs, "relax_povs", spied)
        agent = explore_naive(world, NaiveParams(relax_povs=True), body_wrapper=wrapper).agent
    return world, found["samples"], agent


def test_a_moved_pov_stays_one_pose(relaxed_run):
    world, before, agent = relaxed_run
    moved = np.any(agent._store.samples != before, axis=(1, 2))
    assert agent.povs_relaxed == moved.sum() > 0
    spread = {name: np.ptp(world.arm.forward(s)[:, :, :2], axis=1).max(axis=1)
              for name, s in (("before", before), ("after", agent._store.samples))}
    # No loop spreads by more than a small share of a grid step beyond what its walk left.
    assert np.max(spread["after"] - spread["before"]) < 0.02 * world.spacing


def test_the_moved_povs_are_named_and_a_second_call_moves_nothing_more(relaxed_run):
    # What the graph's agent publishes at the end: the POVs moved, by id.
    _, before, agent = relaxed_run
    moved = np.flatnonzero(np.any(agent._store.samples != before, axis=(1, 2)))
    np.testing.assert_array_equal(agent.relaxed_ids, moved)
    samples = agent._store.samples.copy()
    assert agent.relax_povs() == len(moved)
    np.testing.assert_array_equal(agent.relaxed_ids, moved)
    np.testing.assert_array_equal(agent._store.samples, samples)


def test_without_the_option_nothing_is_kept_or_moved():
    world = build_world(0, {"grid_count": 6, "initial_center": "center"})
    wrapper = functools.partial(ImperfectSensing, seed=5, noise=1e-4)
    agent = explore_naive(world, NaiveParams(relax_povs=False), body_wrapper=wrapper).agent
    assert getattr(agent, "_match_evidence", None) is None
    assert agent.relax_povs() == 0


def _bare_agent(kind):
    """An agent of ``kind`` with only what ``_note_verified`` reads: repeats
    that spread, a measured noise, no discrepancy."""
    from types import SimpleNamespace
    agent = kind.__new__(kind)
    agent.params, agent._repeats, agent._event = NaiveParams(), 3, 5
    agent.structure, agent._discrepancy = SimpleNamespace(noise=1e-4), 0.0
    return agent


def test_on_a_clock_the_agent_keeps_nothing_to_move_its_povs():
    # The option is on by default; a world on its own clock leaves the POVs as
    # found, so the clocked agent keeps no match evidence even where the
    # repeats spread (the lockstep agent would keep this snapshot's matches).
    from types import SimpleNamespace

    from sensorispace_ros.core.naive.agent import NaiveAgent
    from sensorispace_ros.core.naive.clocked_agent import ClockedAgent
    sensed = (np.zeros((1, 6)), np.zeros((1, 6, 4)), np.ones(1, dtype=bool), np.zeros(1))
    snap = SimpleNamespace(event=1, sensations=np.zeros((3, 6)))
    args = (snap, np.array([0]), np.array([2]), sensed, 4, np.ones(1, dtype=bool))
    for kind, keeps in ((NaiveAgent, True), (ClockedAgent, False)):
        agent = _bare_agent(kind)
        agent._note_verified(*args)
        assert (getattr(agent, "_match_evidence", None) is not None) is keeps, kind


def test_a_pov_whose_stencil_bends_ties_no_pair():
    # Two sides of one match: the later side's stencil straddles a jump
    # (bend 1), so its Jacobian is no slope of its pose and the pair is left out.
    from types import SimpleNamespace

    from sensorispace_ros.core.naive.agent import NaiveAgent
    agent = _bare_agent(NaiveAgent)
    jac, whole = np.ones((1, 6, 4)), np.ones(1, dtype=bool)
    for bend, pairs in ((0.1, 1), (1.0, 0)):
        agent._match_evidence = None
        agent._event = 1
        agent._note_verified(SimpleNamespace(event=0), np.array([0]), np.array([1]),
                             (np.zeros((1, 6)), jac, whole, np.zeros(1)), 3, ~whole)
        agent._event = 2
        agent._note_verified(SimpleNamespace(event=1), np.array([1]), np.array([0]),
                             (np.ones((1, 6)), jac, whole, np.full(1, bend)), 3, whole)
        found = agent._match_evidence.pairs()
        assert (0 if found is None else len(found[0])) == pairs, bend
