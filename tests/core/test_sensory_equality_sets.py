"""Equality sets from sensation matching (simulation 2 without ground truth)."""
import functools

import numpy as np
import pytest

from sensorispace_ros.core import arm
from sensorispace_ros.core.body import SensingOnly, SimulatedBody
from sensorispace_ros.core.paper.exploration import build_world
from sensorispace_ros.core.paper.points_of_view import project_onto_pose
from sensorispace_ros.core.arm import PAPER_ARM
from sensorispace_ros.core.naive import equality_sets
from sensorispace_ros.core.naive.equality_sets import (EqualitySetCollection, match_sensations,
    merge_equality_sets)
from sensorispace_ros.core.world import draw_light_offsets

# The paper arm's pose rank (ground truth; the agent measures it, structure.py).
EqualitySetSweep = functools.partial(equality_sets.EqualitySetSweep, rank=PAPER_ARM.pose_rank)


def test_match_sensations_requires_closeness_and_uniqueness():
    reference = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [5.0, 5.0, 5.0]])
    current = np.array([[0, 1.0, 0],                     # reference 1, exactly
                        [1.0 + 5e-9, 0, 0],              # reference 0, within match_tol
                        [0, 0, 1.0 + 1e-9],              # reference 2 ...
                        [0, 0, 1.0 + 5e-7],              # ... but a second row is too near
                        [5.0, 5.0, 5.0 + 1e-6]])         # reference 3: too far
    ref, cur = match_sensations(reference, current, match_tol=1e-8, separation=1e-6)
    assert sorted(zip(ref.tolist(), cur.tolist())) == [(0, 1), (1, 0)]


def test_lost_rows_match_nothing_and_keep_the_others_indices():
    # A bounded sweep: most rows of both sides lost (NaN), a few sensed.
    rng = np.random.default_rng(11)
    truth = rng.uniform(0.0, 1.0, (12, 3))
    reference = np.full((40, 3), np.nan)
    current = np.full((40, 3), np.nan)
    reference[3::3][:12] = truth
    order = rng.permutation(12)
    current[5::3][:12] = truth[order]
    current[0, 1] = np.nan                     # a partly lost row is lost too
    current[0, [0, 2]] = truth[0, [0, 2]]
    ref, cur = match_sensations(reference, current, match_tol=1e-8, separation=1e-6)
    pairs = dict(zip(ref.tolist(), cur.tolist()))
    assert pairs == {3 + 3 * i: 5 + 3 * int(np.flatnonzero(order == i)[0]) for i in range(12)}
    assert match_sensations(np.full((5, 3), np.nan), current, match_tol=1e-8,
                            separation=1e-6)[0].size == 0


def test_two_references_on_one_row_match_neither():
    reference = np.array([[1.0, 0.0], [1.0, 1e-9]])
    ref, cur = match_sensations(reference, np.array([[1.0, 0.0], [0.0, 1.0]]),
                                match_tol=1e-8, separation=1e-6)
    assert len(ref) == len(cur) == 0


def test_noisy_matches_pair_noisy_repeats_and_refuse_what_noise_cannot_tell():
    rng = np.random.default_rng(3)
    sd, n_sensors = 1e-3, 6
    truth = rng.uniform(0.0, 1.0, (40, n_sensors))      # far apart against the noise
    order = rng.permutation(40)
    # The snapshot's rows: 16 sensings each; this sweep's: one each.
    reference = truth + rng.normal(0.0, sd / 4.0, truth.shape)
    current = truth[order] + rng.normal(0.0, sd, truth.shape)
    # Row 0's pose is not among the current rows: one lies 12 sd away, a
    # shift a tolerance for chains of compensations would have taken.
    current[np.flatnonzero(order == 0)[0]] = truth[0] + 12.0 * sd / np.sqrt(n_sensors)
    # Row 1's pose has a neighbour sensing within the noise of one sensing.
    current = np.vstack([current, truth[1] + 0.5 * sd])
    ref, cur = equality_sets.noisy_matches(reference, current, reference_var=(sd / 4.0) ** 2,
                                           current_var=sd ** 2, confidence=0.999)
    pairs = dict(zip(ref.tolist(), cur.tolist()))
    assert 0 not in pairs and 1 not in pairs
    assert all(order[j] == i for i, j in pairs.items())
    assert len(pairs) == 38


def test_noisy_matches_refuse_two_references_within_the_noise_of_one_row():
    sd = 1e-3
    reference = np.array([[0.3, 0.5, 0.7], [0.3, 0.5, 0.7 + 2.0 * sd], [0.9, 0.1, 0.2]])
    current = np.array([[0.3, 0.5, 0.7 + sd], [0.9, 0.1, 0.2 + 0.5 * sd]])
    ref, cur = equality_sets.noisy_matches(reference, current, reference_var=sd ** 2,
                                           current_var=sd ** 2, confidence=0.999)
    assert ref.tolist() == [2] and cur.tolist() == [1]


def test_errors_that_repeat_exactly_on_no_lattice_match_by_the_chain_tolerance():
    sd = 1.8e-8
    assert equality_sets.match_noise(sd, 0.9 * sd, 0.0) == sd          # random: averaged
    assert equality_sets.match_noise(sd, 0.0, 6.2e-8) == sd            # on a lattice
    assert equality_sets.match_noise(sd, 0.0, 0.0) == 0.0              # float rounding
    assert equality_sets.match_noise(0.0, 0.0, 0.0) == 0.0             # noiseless
    rng = np.random.default_rng(5)
    truth = rng.uniform(0.0, 1.0, (30, 6))
    # Poses of chained compensations: each row off by 60 rounding sds, far
    # more than a chi-square against the rounding allows, far less than the
    # rows' spacing.
    shifted = truth + 60.0 * sd * rng.standard_normal(truth.shape) / np.sqrt(6.0)
    tolerances = dict(match_tol=1e-4, separation=1e-3, ratio=3.0)
    ref, cur = equality_sets.match_counted(truth, shifted, noise_sd=sd, **tolerances)
    assert len(ref) < 5
    ref, cur = equality_sets.match_counted(
        truth, shifted, noise_sd=equality_sets.match_noise(sd, 0.0, 0.0), **tolerances)
    assert ref.tolist() == cur.tolist() == list(range(30))


def test_match_tolerance_must_be_below_separation():
    with pytest.raises(ValueError, match="match_tol"):
        match_sensations(np.zeros((1, 2)), np.zeros((1, 2)), match_tol=1e-3, separation=1e-4)


def test_collection_drops_zero_displacements_and_lonely_changes():
    sets = EqualitySetCollection(min_pairs=2)
    assert sets.add([0, 1, 2], [3, 1, 4]) == 0           # 1 -> 1 is no displacement
    assert sets.add([5], [6]) == -1                      # one change constrains nothing
    assert sets.add([7, 8], [9, 10]) == 1
    np.testing.assert_array_equal(sets.pairs, [[0, 3], [2, 4], [7, 9], [8, 10]])
    np.testing.assert_array_equal(sets.set_ids, [0, 0, 1, 1])
    assert sets.n_pairs == 4 and sets.n_sets == 2
    # An undone reaction's sets are forgotten; the next set takes their ids.
    sets.add([11, 12, 13], [14, 15, 16])
    sets.truncate(1)
    np.testing.assert_array_equal(sets.pairs, [[0, 3], [2, 4]])
    assert sets.n_pairs == 2 and sets.n_sets == 1
    assert sets.add([7, 8], [9, 10]) == 1
    with pytest.raises(ValueError, match=r"n_sets: must lie in \[0, 2\], got 3"):
        sets.truncate(3)


@pytest.fixture(scope="module")
def lattice_povs():
    """Stand-ins for known POVs: motor states whose sensor positions lie on a
    lattice (spacing 0.3) at the start's orientation, each the start of its
    POV (one sample is all a sweep uses)."""
    world = build_world(0)
    pose0 = arm.forward(world.m0)
    offsets = np.array([(i, j) for i in range(-2, 3) for j in range(-2, 3)]) * 0.3
    targets = pose0 + np.column_stack([offsets, np.zeros(len(offsets))])
    motor, error = project_onto_pose(np.repeat(world.m0[None, None], len(targets), axis=0),
                                     targets)
    assert error.max() < 1e-12
    return world, motor, offsets


def test_sweep_pairs_have_one_true_displacement_per_change(lattice_povs):
    world, motor, offsets = lattice_povs
    sim = SimulatedBody(world.receptors, world.initial_lights)
    sweep = EqualitySetSweep(SensingOnly(sim), motor)
    sweep.observe()
    changes = [np.array([0.3, 0.0]), np.array([0.0, -0.6]), np.array([0.3, 0.3])]
    center = np.zeros(2)
    for shift in changes:
        center = center + shift
        sim.set_lights(world.initial_lights + center)
        pairs = sweep.observe()
        moved = offsets[pairs[:, 1]] - offsets[pairs[:, 0]]
        np.testing.assert_allclose(moved, np.repeat(shift[None], len(pairs), axis=0), atol=1e-9)
        # Every lattice point whose displaced point is on the lattice is found.
        expected = sum(np.any(np.all(np.isclose(offsets, o + shift), axis=1)) for o in offsets)
        assert len(pairs) == expected
    assert sweep.sets.n_sets == len(changes)
    assert sweep.calls >= len(changes) + 1


def test_redistribution_gives_no_pairs(lattice_povs):
    world, motor, _ = lattice_povs
    sim = SimulatedBody(world.receptors, world.initial_lights)
    sweep = EqualitySetSweep(sim, motor)
    sweep.observe()
    rng = np.random.default_rng(3)
    sim.set_lights(world.initial_center + 0.3 + draw_light_offsets(rng, 10))
    assert len(sweep.observe()) == 0
    assert sweep.sets.n_sets == 0


def test_one_light_sensations_are_never_matched(lattice_povs):
    world, motor, offsets = lattice_povs
    # One light ahead of the eyes: sensations differ from pose to pose, but
    # two numbers (projection, distance) cannot pin a 3-D pose (rank 2).
    alpha = world.m0.sum()
    light = arm.forward(world.m0)[:2] + 5.0 * np.array([np.cos(alpha), np.sin(alpha)])
    sim = SimulatedBody(world.receptors, light[None])
    sensed = sim.sense(motor[:, 0])
    assert np.all(sensed.max(axis=1) > 1e-3)
    sweep = EqualitySetSweep(sim, motor)
    sweep.observe()
    sim.set_lights(light[None] + [0.3, 0.0])
    # Without the rank test these would match (the relative poses coincide).
    ref, cur = match_sensations(sensed, sim.sense(motor[:, 0]))
    assert len(ref) > 0
    assert len(sweep.observe()) == 0


def test_sweep_rejects_malformed_povs(lattice_povs):
    world, motor, _ = lattice_povs
    sim = SimulatedBody(world.receptors, world.initial_lights)
    with pytest.raises(ValueError, match="points_of_view"):
        EqualitySetSweep(sim, motor[:, 0])


def test_sets_sharing_a_change_are_merged():
    # Sets 0 and 2 share 0 -> 1 (2 lists it as 1 -> 0: the opposite
    # displacement, the same length); sets 1 and 3 share 4 -> 5.
    pairs = np.array([[0, 1], [2, 3], [4, 5], [1, 0], [6, 7], [5, 4], [8, 9], [10, 11]])
    set_ids = np.array([0, 0, 1, 2, 2, 3, 3, 4])
    merged_pairs, merged_ids = merge_equality_sets(pairs, set_ids)
    groups = {}
    for (i, j), s in zip(merged_pairs.tolist(), merged_ids.tolist()):
        groups.setdefault(s, set()).add((i, j))
    assert sorted(map(sorted, groups.values())) == [
        [(0, 1), (2, 3), (6, 7)], [(4, 5), (8, 9)], [(10, 11)]]
    assert len(merged_pairs) == 6            # each unordered change once


def test_merging_agrees_with_ground_truth_displacements(lattice_povs):
    world, motor, offsets = lattice_povs
    sim = SimulatedBody(world.receptors, world.initial_lights)
    sweep = EqualitySetSweep(sim, motor)
    sweep.observe()
    center = np.zeros(2)
    # The same displacement twice (far apart in time) and its opposite.
    for shift in ([0.3, 0.0], [0.0, 0.3], [0.3, 0.0], [-0.3, 0.0], [0.0, 0.3]):
        center = center + shift
        sim.set_lights(world.initial_lights + center)
        sweep.observe()
    pairs, set_ids = merge_equality_sets(sweep.pairs, sweep.set_ids)
    assert len(np.unique(set_ids)) == 2          # |dx| = 0.3 and |dy| = 0.3
    moved = np.abs(offsets[pairs[:, 1]] - offsets[pairs[:, 0]])
    for s in np.unique(set_ids):
        assert np.allclose(moved[set_ids == s], moved[set_ids == s][0])


def test_a_rank_test_given_the_states_own_sensations_senses_only_the_displaced_rows():
    world = build_world(0, {"grid_count": 4})
    body = world.body(lights=world.initial_lights)
    states = np.random.default_rng(3).uniform(-3, 3, (5, 4))
    states[0] = [0.0, 0.0, 0.0, 0.0]      # the eye folded back: rank deficient
    full, rows = equality_sets.check_pose_rank(body, states, rank=3, fd_step=1e-4)
    sensed = body.sense(states)
    again, fewer = equality_sets.check_pose_rank(body, states, rank=3, fd_step=1e-4,
                                                 sensed=sensed)
    np.testing.assert_array_equal(again, full)
    assert fewer == rows - len(states)
    from sensorispace_ros.core.naive.jacobians import AveragedStep
    with pytest.raises(ValueError, match="sensed"):
        equality_sets.check_pose_rank(body, states, rank=3, fd_step=AveragedStep(1e-4, 4),
                                      sensed=sensed)
