"""bench/noisy_sets.py's ground-truth helpers: sets of one displacement, and
the pairs that do not belong to their set."""
import sys

import numpy as np

from shared import REPO
sys.path.insert(0, str(REPO))

from bench import noisy_sets  # noqa: E402

STEP = 0.2


def _lattice(n=5, jitter=0.0, seed=0):
    grid = np.stack(np.meshgrid(np.arange(n), np.arange(n)), axis=-1).reshape(-1, 2) * STEP
    return grid + np.random.default_rng(seed).uniform(-jitter, jitter, grid.shape)


def test_every_pair_of_a_true_set_has_its_displacement():
    positions = _lattice(jitter=0.1 * STEP)
    pairs, set_ids = noisy_sets.true_sets(positions, STEP)
    shift = np.rint((positions[pairs[:, 1]] - positions[pairs[:, 0]]) / STEP)
    for s in np.unique(set_ids):
        assert len(np.unique(shift[set_ids == s], axis=0)) == 1
    # Different sets, different displacements; every set of two pairs or more.
    firsts = np.array([shift[set_ids == s][0] for s in np.unique(set_ids)])
    assert len(np.unique(firsts, axis=0)) == len(firsts)
    assert np.unique(set_ids, return_counts=True)[1].min() >= 2
    # 5 x 5 points: each displacement but the two corner-to-corner diagonals joins two pairs or more.
    assert len(pairs) == 25 * 24 // 2 - 2


def test_a_pair_off_its_sets_displacement_is_wrong():
    positions = _lattice()
    pairs, set_ids = noisy_sets.true_sets(positions, STEP)
    assert not noisy_sets.wrong_pairs(positions, pairs, set_ids, STEP).any()
    bad = np.flatnonzero(np.bincount(set_ids)[set_ids] >= 3)[0]
    corrupted = pairs.copy()
    corrupted[bad] = corrupted[bad][::-1]           # the opposite displacement
    wrong = noisy_sets.wrong_pairs(positions, corrupted, set_ids, STEP)
    assert wrong.sum() == 1 and wrong[bad]


def test_sampled_sets_are_whole_sets_within_the_count():
    positions = _lattice()
    pairs, set_ids = noisy_sets.true_sets(positions, STEP)
    kept_pairs, kept_ids = noisy_sets.sampled_sets(pairs, set_ids, 60, np.random.default_rng(1))
    assert 0 < len(kept_pairs) <= 60
    for s in np.unique(kept_ids):
        assert (kept_ids == s).sum() == (set_ids == s).sum()


def test_sets_with_their_segments_keep_the_sets_and_number_the_segments_after():
    positions = _lattice()
    pairs, set_ids = noisy_sets.true_sets(positions, STEP)
    both, both_ids = noisy_sets.with_segments(pairs, set_ids, len(positions), 150, seed=0)
    assert np.array_equal(both[:len(pairs)], pairs)
    assert np.array_equal(both_ids[:len(pairs)], set_ids)
    segments, segment_ids = both[len(pairs):], both_ids[len(pairs):]
    assert len(segments) > 0 and segment_ids.min() == set_ids.max() + 1
    # Under a translation a segment and its images are one vector, as the sets' pairs are.
    vector = positions[segments[:, 1]] - positions[segments[:, 0]]
    for s in np.unique(segment_ids):
        assert np.allclose(vector[segment_ids == s], vector[segment_ids == s][0])


def test_lattice_offsets_measure_each_position_from_the_lattice_of_their_mean_phase():
    rng = np.random.default_rng(2)
    jitter = rng.uniform(-0.05, 0.05, (25, 2)) * STEP
    jitter -= jitter.mean(axis=0)                   # the lattice's phase is the shift's alone
    positions = _lattice() + 0.37 * STEP + jitter
    offsets, snapped = noisy_sets.lattice_offsets(positions, STEP)
    np.testing.assert_allclose(offsets, np.linalg.norm(jitter, axis=1) / STEP, atol=1e-3)
    steps = (snapped - snapped[0]) / STEP
    np.testing.assert_allclose(steps, np.rint(steps), atol=1e-12)
    np.testing.assert_allclose(snapped[0] % STEP, 0.37 * STEP, atol=5e-3 * STEP)


def test_samples_moved_onto_a_pose_sense_from_it_and_move_little():
    from sensorispace_ros.core.arm import PAPER_ARM

    rng = np.random.default_rng(3)
    start = np.array([0.1, -1.5, 2.2, -3.0])
    povs = start + rng.normal(0.0, 0.02, (3, 10, 4))
    poses = PAPER_ARM.forward(start + rng.normal(0.0, 0.01, (3, 4)))
    moved = noisy_sets.moved_onto(PAPER_ARM, povs, poses)
    np.testing.assert_allclose(PAPER_ARM.pose_error(PAPER_ARM.forward(moved), poses[:, None]), 0.0,
                               atol=1e-9)
    assert np.max(np.linalg.norm(moved - povs, axis=-1)) < 0.2


def test_the_lattice_variant_adds_sets_of_true_displacements_after_the_own():
    positions = _lattice(n=8)
    pairs, set_ids = noisy_sets.true_sets(positions, STEP)
    keep = np.random.default_rng(2).random(len(pairs)) < 0.3       # a sparse sample of them
    own, own_ids = pairs[keep], set_ids[keep]
    wrong = noisy_sets.wrong_pairs(positions, own, own_ids, STEP)
    name, both, both_ids = noisy_sets.lattice_variant(own, own_ids, wrong, len(positions), {})
    assert name == "own + lattice" and len(both) > len(own)
    np.testing.assert_array_equal(both[:len(own)], own)
    assert both_ids[len(own):].min() > own_ids.max()
    assert not noisy_sets.wrong_pairs(positions, both, both_ids, STEP).any()


def test_the_trimmed_variant_drops_the_found_pair_the_lattice_refuses_and_no_implied_one():
    from sensorispace_ros.core.naive.lattice_sets import lattice_equalities
    positions = _lattice(n=8)
    pairs, set_ids = noisy_sets.true_sets(positions, STEP)
    keep = np.random.default_rng(2).random(len(pairs)) < 0.3
    found, found_ids = pairs[keep], set_ids[keep]
    _, found_ids = np.unique(found_ids, return_inverse=True)
    # One pair of the first set moved to a POV off its set's displacement.
    bad = np.flatnonzero(found_ids == 0)[0]
    found = found.copy()
    found[bad, 1] = (found[bad, 1] + 9) % len(positions)
    implied = lattice_equalities(found, found_ids, len(positions), 4)
    pairs = np.concatenate([found, implied.pairs])
    set_ids = np.concatenate([found_ids, implied.set_ids + found_ids.max() + 1])
    assert noisy_sets.found_count(pairs, set_ids, len(positions), 4) == found_ids.max() + 1
    name, kept, kept_ids = noisy_sets.trimmed_variant(pairs, set_ids, len(positions), {})
    assert name == "own, trimmed" and len(kept) < len(pairs)
    assert not noisy_sets.wrong_pairs(positions, kept, kept_ids, STEP).any()
    assert len(kept) >= len(pairs) - 0.05 * len(found)
