"""2-D points of view: every sample on the fibre, samples spread evenly and
covering the whole surface (a much denser sampling lies close to them),
every piece of a split fibre, the compiled and NumPy loops the same."""
import numpy as np
import pytest

from sensorispace_ros.core.arm import Arm
from sensorispace_ros.core.paper import surfaces
from sensorispace_ros.core.paper.fibres import closing_vector, free_links, link_angles
from tests.core.paper_bodies import BODIES, random_states

TWO_D = ("five-joint", "level-2d")


def covering_radius(points: np.ndarray, kept: np.ndarray) -> float:
    """Largest periodic distance from one of ``points`` to its nearest in ``kept``."""
    nearest = np.full(len(points), np.inf)
    columns = np.ascontiguousarray(points.T)
    for sample in kept:
        np.minimum(nearest, surfaces._sq_distance_numpy(columns, sample), out=nearest)
    return float(np.sqrt(nearest.max()))


def packing_distance(kept: np.ndarray) -> float:
    """Smallest periodic distance between two of ``kept``."""
    columns = np.ascontiguousarray(kept.T)
    return float(min(np.sqrt(np.delete(surfaces._sq_distance_numpy(columns, s), n).min())
                     for n, s in enumerate(kept)))


@pytest.fixture(scope="module", params=TWO_D)
def body_and_states(request):
    body_arm = BODIES[request.param]
    return body_arm, random_states(body_arm, 3, seed=5)


def test_candidates_and_samples_have_the_pose(body_and_states):
    body_arm, states = body_and_states
    for motor in states:
        pose = body_arm.forward(motor)
        candidates = surfaces.surface_candidates(body_arm, motor, grid=40)
        assert len(candidates) > 500
        assert body_arm.pose_error(body_arm.forward(candidates), pose).max() < 1e-9
        assert np.abs(candidates - motor).max() <= np.pi + 1e-12
        samples = surfaces.sample_surface(body_arm, motor, 300)
        assert samples.shape == (300, body_arm.n_joints)
        np.testing.assert_array_equal(samples[0], motor)
        assert body_arm.pose_error(body_arm.forward(samples), pose).max() < 1e-9
        assert len(np.unique(samples, axis=0)) == 300


def test_samples_cover_a_denser_sampling_evenly(body_and_states):
    """Every state of a ~30x denser sampling lies within 1.6 times the
    smallest distance between two samples of the nearest sample: no part of the
    surface is left out, and the samples are spread evenly over it."""
    body_arm, states = body_and_states
    for motor in states:
        kept = surfaces.sample_surface(body_arm, motor, 300)
        dense = surfaces.surface_candidates(body_arm, motor, grid=200)
        assert len(dense) > 30 * 300
        assert covering_radius(dense, kept) < 1.6 * packing_distance(kept)


def test_link_angles_stay_in_their_range():
    body_arm = BODIES["five-joint"]
    motor = random_states(body_arm, 1, seed=6)[0]
    pose = body_arm.forward(motor)
    links = free_links(body_arm)
    theta = link_angles(body_arm, surfaces.surface_candidates(body_arm, motor, grid=200))
    for n in range(4):
        centre, half_width = surfaces.link_angle_range(links, n, closing_vector(body_arm, pose))
        offset = np.abs((theta[:, n] - centre + np.pi) % (2 * np.pi) - np.pi)
        assert offset.max() <= half_width + 1e-9
        assert offset.max() >= 0.9 * half_width                 # the range is not loose


def test_both_pieces_of_a_split_surface_are_sampled():
    """Three long links (1, 1, 1) close to a triangle turning one way or the
    other: two pieces, told apart by the sign of the first bend."""
    body_arm = Arm((1.0, 1.0, 1.0, 0.25), "level", "rad")
    theta = np.array([0.0, 2.0 * np.pi / 3, 4.0 * np.pi / 3 + 0.1, 0.5])
    motor = np.diff(theta, prepend=0.0)
    assert np.hypot(*body_arm.forward(motor)[:2]) < 0.75            # Kapovich-Millson: split
    kept = surfaces.sample_surface(body_arm, motor, 300)
    dense = surfaces.surface_candidates(body_arm, motor, grid=200)
    for samples in (kept, dense):
        bend = np.sin(samples[:, 1])
        assert np.abs(bend).min() > 0.3 and (bend > 0).any() and (bend < 0).any()
    for sign in (1, -1):
        piece = dense[np.sign(np.sin(dense[:, 1])) == sign]
        assert covering_radius(piece, kept) < 1.6 * packing_distance(kept)


def test_compiled_loops_pick_the_same_samples():
    pytest.importorskip("numba")
    body_arm = BODIES["five-joint"]
    motor = random_states(body_arm, 1, seed=7)[0]
    candidates = surfaces.surface_candidates(body_arm, motor, grid=60)
    fast = surfaces.farthest_point_indices(candidates, 200, motor, kernel="numba")
    slow = surfaces.farthest_point_indices(candidates, 200, motor, kernel="numpy")
    np.testing.assert_array_equal(fast[0], slow[0])
    assert fast[1] == slow[1]
    picked = candidates[fast[0]]
    np.testing.assert_array_equal(surfaces.nearest_neighbour_tour(picked, kernel="numba"),
                                  surfaces.nearest_neighbour_tour(picked, kernel="numpy"))


def test_farthest_points_are_farther_apart_than_the_radius_they_leave():
    body_arm = BODIES["level-2d"]
    motor = random_states(body_arm, 1, seed=8)[0]
    candidates = surfaces.surface_candidates(body_arm, motor, grid=60)
    picked, radius = surfaces.farthest_point_indices(candidates, 150, motor)
    assert len(set(picked.tolist())) == 150
    assert packing_distance(np.vstack([motor, candidates[picked]])) >= radius - 1e-12
    assert covering_radius(candidates, np.vstack([motor, candidates[picked]])) == \
        pytest.approx(radius, abs=1e-12)


def test_a_tiny_fibre_gets_a_fine_lattice():
    body_arm = BODIES["five-joint"]
    motor = np.array([0.3, 0.01, -0.01, 0.01, 1.0])          # nearly stretched: a tiny surface
    samples = surfaces.sample_surface(body_arm, motor, 400)
    np.testing.assert_array_equal(samples[0], motor)
    assert len(np.unique(samples, axis=0)) == 400
    assert body_arm.pose_error(body_arm.forward(samples), body_arm.forward(motor)).max() < 1e-9
    assert np.abs(samples - motor).max() < 0.1


def test_a_fully_stretched_arm_is_its_own_point_of_view():
    body_arm = BODIES["five-joint"]
    motor = np.array([0.3, 0.0, 0.0, 0.0, 1.0])
    samples = surfaces.sample_surface(body_arm, motor, 50)
    assert samples.shape == (50, 5)
    assert np.abs(samples - motor).max() < 1e-6
