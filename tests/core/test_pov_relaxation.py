"""POVs moved onto one lattice by their matches (core/naive/pov_relaxation.py).

Synthetic worlds where the truth is known: every POV ``b`` has a pose error
``delta_b`` (3-D) and a pose Jacobian ``P_b`` (3 x 4, its motors to its pose);
a match of ``b`` at event ``k`` with ``a`` at ``k'`` sees one sensory slope
``G`` (6 x 3) on both sides, so ``J_b = G P_b``, ``J_a = G P_a`` and the
two POVs' averages differ by ``G (delta_b - delta_a)``.
"""
import numpy as np
import pytest

from sensorispace_ros.core.arm import PAPER_ARM, wrap_angle
from sensorispace_ros.core.naive.pov_relaxation import (MatchEvidence, loop_displacements,
                                                         neighbour_transport, off_loop,
                                                         relaxed_corrections)
from sensorispace_ros.core.paper.points_of_view import sample_points_of_view

S, M, RANK = 6, 4, 3
# The per-receptor variance the POVs' offsets put between two matched sensings.
DISCREPANCY = 1e-2


def _world(n_povs=40, n_matches=600, noise=0.0, seed=0, one_sided=0):
    """Each match senses its two POVs afresh, each in its own world (its own
    offset of the sensation), with one slope ``G``: their averages differ by
    ``G (delta_b - delta_a)`` plus their noise."""
    rng = np.random.default_rng(seed)
    pose_jac = rng.normal(size=(n_povs, RANK, M))
    delta = rng.normal(scale=0.01, size=(n_povs, RANK))
    evidence = MatchEvidence()
    for k in range(n_matches):
        b, a = rng.choice(n_povs, size=2, replace=False)
        slope, world = rng.normal(size=(S, RANK)), rng.normal(size=S)
        event, snap_event = 2 * k + 1, 2 * k
        if k >= one_sided:
            mean_a = world + slope @ delta[a] + rng.normal(scale=noise, size=S)
            evidence.note(snap_event, np.array([a]), (slope @ pose_jac[a])[None], mean_a[None],
                          np.array([True]), noise ** 2 + 1e-12, -1, np.array([0]),
                          np.array([False]), DISCREPANCY)
        mean_b = world + slope @ delta[b] + rng.normal(scale=noise, size=S)
        evidence.note(event, np.array([b]), (slope @ pose_jac[b])[None], mean_b[None],
                      np.array([True]), noise ** 2 + 1e-12, snap_event, np.array([a]),
                      np.array([True]), DISCREPANCY)
    return pose_jac, delta, evidence


def _spread(errors):
    """How far the POVs' pose errors lie from their common shift."""
    return float(np.sqrt(np.mean(np.sum((errors - errors.mean(axis=0)) ** 2, axis=1))))


@pytest.mark.parametrize("n_matches", [600, 6000])
def test_the_corrections_bring_every_pov_to_one_shift_of_the_lattice(n_matches):
    pose_jac, delta, evidence = _world(n_matches=n_matches)
    corrections = relaxed_corrections(evidence, len(delta), M)[0]
    after = delta + np.einsum("pkm,pm->pk", pose_jac, corrections)
    assert _spread(delta) > 0.01
    # Exact pairs: what is left is the prior's hold, one pair's worth of
    # each POV's ~2 n_matches / n_povs pairs.
    assert _spread(after) < 3.0 * len(delta) / n_matches * _spread(delta)


def test_noisy_residuals_leave_the_povs_nearer_than_before():
    pose_jac, delta, evidence = _world(noise=0.002, n_matches=2000)
    corrections = relaxed_corrections(evidence, len(delta), M)[0]
    after = delta + np.einsum("pkm,pm->pk", pose_jac, corrections)
    assert _spread(after) < 0.25 * _spread(delta)


def test_a_match_whose_partner_was_never_sensed_with_a_jacobian_adds_nothing():
    pose_jac, delta, evidence = _world(n_matches=5, one_sided=5)
    assert evidence.pairs() is None
    assert not np.any(relaxed_corrections(evidence, len(delta), M)[0])


def test_matches_the_agent_did_not_keep_never_enter():
    evidence = MatchEvidence()
    jac = np.ones((1, S, M))
    evidence.note(0, np.array([1]), jac, np.zeros((1, S)), np.array([True]), 1.0, -1,
                  np.array([0]), np.array([False]), DISCREPANCY)
    evidence.note(1, np.array([0]), jac, np.ones((1, S)), np.array([True]), 1.0, 0,
                  np.array([1]), np.array([False]), DISCREPANCY)
    assert evidence.pairs() is None
    evidence.note(2, np.array([0]), jac, np.ones((1, S)), np.array([True]), 1.0, 0,
                  np.array([1]), np.array([True]), DISCREPANCY)
    assert len(evidence.pairs()[0]) == 1


def test_a_pair_differs_by_its_two_povs_own_averages_and_their_variances():
    evidence = MatchEvidence()
    jac = np.ones((1, S, M))
    evidence.note(3, np.array([1]), jac, np.full((1, S), 0.25), np.array([True]), 0.01, -1,
                  np.array([0]), np.array([False]), DISCREPANCY)
    evidence.note(7, np.array([0]), 2 * jac, np.full((1, S), 1.0), np.array([True]), 0.04, 3,
                  np.array([1]), np.array([True]), DISCREPANCY)
    b, a, jac_b, jac_a, residual, variance = evidence.pairs()
    assert (b.tolist(), a.tolist()) == ([0], [1])
    np.testing.assert_array_equal(residual, np.full((1, S), 0.75))
    np.testing.assert_allclose(variance, [0.05 + DISCREPANCY])
    np.testing.assert_array_equal(jac_b, 2 * jac)
    np.testing.assert_array_equal(jac_a, jac)


def test_a_side_sensed_without_its_whole_stencil_or_a_lost_frame_ties_nothing():
    evidence = MatchEvidence()
    jac = np.ones((1, S, M))
    lost = np.full((1, S), np.nan)
    evidence.note(3, np.array([1]), jac, lost, np.array([True]), 0.01, -1,
                  np.array([0]), np.array([False]), DISCREPANCY)
    evidence.note(4, np.array([2]), jac, np.zeros((1, S)), np.array([False]), 0.01, -1,
                  np.array([0]), np.array([False]), DISCREPANCY)
    evidence.note(7, np.array([0]), jac, np.ones((2, S)), np.array([True]), 0.01, 3,
                  np.array([1]), np.array([True]), DISCREPANCY)
    evidence.note(8, np.array([0]), jac, np.ones((2, S)), np.array([True]), 0.01, 4,
                  np.array([2]), np.array([True]), DISCREPANCY)
    assert evidence.pairs() is None


def _onto(motor, pose, iterations=8):
    """``motor`` moved by the least joint change onto the arm's ``pose``."""
    motor = np.array(motor, dtype=float)
    for _ in range(iterations):
        diff = PAPER_ARM.forward(motor) - pose
        diff[..., 2] = wrap_angle(diff[..., 2])
        motor -= np.linalg.pinv(PAPER_ARM.jacobian(motor)) @ diff
    return motor


@pytest.fixture(scope="module")
def lattice_loops():
    """The paper arm's POV loop at a pose and at its four lattice neighbours
    (0.2 apart, the eye's orientation kept)."""
    start = np.array([0.1, -1.5, 2.2, -3.0])
    pose = PAPER_ARM.forward(start)
    offsets = [(0, 0), (0.2, 0), (-0.2, 0), (0, 0.2), (0, -0.2)]
    states = np.stack([_onto(start, pose + np.array([dx, dy, 0.0])) for dx, dy in offsets])
    loops = sample_points_of_view(states, n_samples=60).samples
    return pose, loops[0], loops[1:]


def _pose_errors(loop, shift, wanted):
    moved = PAPER_ARM.forward(loop + shift)
    error = moved - wanted
    error[:, 2] = wrap_angle(error[:, 2])
    return np.linalg.norm(error, axis=1)


# Neighbours on one side only: a forward difference over a lattice step.
@pytest.mark.parametrize("sides, share", [([0, 1, 2, 3], 0.03), ([0, 2], 0.15)],
                         ids=["around", "one side"])
def test_the_loop_moves_with_its_first_sample_by_its_neighbours_loops(lattice_loops, sides, share):
    pose, loop, neighbours = lattice_loops
    neighbours = neighbours[sides]
    step = np.array([0.004, -0.003, 0.0])
    # The first sample's least move toward that pose.
    jac = PAPER_ARM.jacobian(loop[0])
    correction = np.linalg.pinv(jac) @ step
    shift = neighbour_transport(loop, neighbours, correction)
    errors = _pose_errors(loop, shift, pose + step)
    # Every sample lands on the moved pose, to a small share of the move;
    # the first sample's move applied to every sample would not.
    assert np.max(errors) < share * np.linalg.norm(step)
    assert np.max(_pose_errors(loop, correction, pose + step)) > 0.5 * np.linalg.norm(step)


def test_a_loop_without_neighbours_stays(lattice_loops):
    _, loop, neighbours = lattice_loops
    assert neighbour_transport(loop, neighbours[:0], np.full(M, 0.01)) is None


def test_a_samples_displacement_ends_on_the_nearest_edge_not_vertex():
    square = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    inside = np.array([[0.5, -0.3], [0.5, 0.2], [-0.2, 0.6]])
    np.testing.assert_allclose(loop_displacements(inside, square),
                               [[0.5, 0.0], [0.5, 0.0], [0.0, 0.4]], atol=1e-12)
    # Across the period of a phase: the nearest edge lies the short way round.
    np.testing.assert_allclose(loop_displacements(inside + 2 * np.pi, square),
                               [[0.5, 0.0], [0.5, 0.0], [0.0, 0.4]], atol=1e-12)


def test_a_turn_of_the_eye_no_lattice_step_holds_leaves_the_loop_one_pose(lattice_loops):
    pose, loop, neighbours = lattice_loops
    step = np.array([0.004, -0.003, 0.002])
    correction = np.linalg.pinv(PAPER_ARM.jacobian(loop[0])) @ step
    shift = neighbour_transport(loop, neighbours, correction)
    moved = PAPER_ARM.forward(loop + shift)
    # Every sample lands where the first one does (one pose), the eye's
    # orientation as it was; the position moves most of the way asked (the
    # turn's part the lattice steps cannot hold is not fitted by them).
    apart = moved - moved[0]
    apart[:, 2] = wrap_angle(apart[:, 2])
    assert np.max(np.linalg.norm(apart, axis=1)) < 0.05 * np.linalg.norm(step)
    assert abs(wrap_angle(moved[0, 2] - pose[2])) < 0.1 * step[2]
    assert np.linalg.norm(moved[0, :2] - pose[:2] - step[:2]) < 0.5 * np.linalg.norm(step[:2])


def test_a_move_along_its_own_loop_keeps_the_pov_on_its_pose(lattice_loops):
    # The first sample slid to the loop's fourth sample: the same pose, as
    # far in motor space as a step to a neighbour's pose; only the step off
    # the loop (toward the neighbour's, or the slide plus that step) counts.
    _, loop, neighbours = lattice_loops
    along = wrap_angle(loop[3] - loop[0])
    toward, toward_there = loop_displacements(loop[[0, 3]], neighbours[0])
    assert np.linalg.norm(along) > np.linalg.norm(toward)
    moves = np.stack([np.zeros(M), along, toward, along + 0.3 * toward_there])
    lands = off_loop(np.repeat(loop[None], 4, axis=0), moves)
    np.testing.assert_allclose(lands, [0.0, 0.0, np.linalg.norm(toward),
                                       0.3 * np.linalg.norm(toward_there)], rtol=0.02, atol=1e-3)
