"""The fibre geometry the paper strategy uses on any body: the closing
vector, link angles back to motor states, the two-link solutions, the 0-D
fibres and the split rule, checked against the forward model and the
kernel walk."""
import numpy as np
import pytest

from sensorispace_ros.core.arm import PAPER_ARM, Arm
from sensorispace_ros.core.paper import fibres
from sensorispace_ros.core.paper.points_of_view import sample_points_of_view
from tests.core.paper_bodies import BODIES, random_states


def radian(body_arm: Arm) -> Arm:
    return Arm(body_arm.segments, body_arm.eye, "rad")


@pytest.mark.parametrize("name", sorted(BODIES))
def test_link_angles_give_the_motor_state_back(name):
    body_arm = radian(BODIES[name])
    motor = random_states(body_arm, 20, seed=1)
    pose = body_arm.forward(motor)
    theta = fibres.link_angles(body_arm, motor)
    links = fibres.free_links(body_arm)
    reached = np.stack([np.sum(links * np.cos(theta), axis=-1),
                        np.sum(links * np.sin(theta), axis=-1)], axis=-1)
    np.testing.assert_allclose(reached, fibres.closing_vector(body_arm, pose), atol=1e-12)
    again = fibres.motor_from_link_angles(body_arm, theta, pose, motor)
    np.testing.assert_allclose(again, motor, atol=1e-12)


def test_two_link_solutions_reach_the_target_and_flag_the_rest():
    rng = np.random.default_rng(2)
    target = rng.uniform(-2.5, 2.5, (500, 2))
    theta_a, theta_b, feasible = fibres.two_link_angles(1.2, 0.7, target)
    distance = np.hypot(*target.T)
    np.testing.assert_array_equal(feasible, (distance >= 0.5) & (distance <= 1.9))
    for branch in range(2):
        reached = 1.2 * np.stack([np.cos(theta_a[:, branch]), np.sin(theta_a[:, branch])], -1) \
            + 0.7 * np.stack([np.cos(theta_b[:, branch]), np.sin(theta_b[:, branch])], -1)
        np.testing.assert_allclose(reached[feasible], target[feasible], atol=1e-12)
    bend = np.sin(theta_b - theta_a)[feasible]            # the two elbows mirror each other
    assert np.all(bend[:, 0] * bend[:, 1] <= 1e-12)


@pytest.mark.parametrize("name", ["three-joint", "link-eye-0d"])
def test_zero_dimensional_fibres_hold_both_elbows(name):
    body_arm = BODIES[name]
    for motor in random_states(body_arm, 10, seed=3):
        found = fibres.discrete_fibre(body_arm, motor)
        assert len(found) == 2
        np.testing.assert_array_equal(found[0], motor)
        poses = body_arm.forward(found)
        assert body_arm.pose_error(poses, poses[0]).max() < 1e-12
        # The other elbow: the relative angle of the two free links changes sign.
        elbow = np.sin(found[:, 1])
        assert elbow[0] * elbow[1] < 0
        assert np.abs(found[1] - found[0]).max() <= np.pi + 1e-12    # taken near the first


def test_a_stretched_pose_has_one_solution():
    body_arm = BODIES["three-joint"]
    motor = np.array([0.4, 0.0, 0.3])
    assert len(fibres.discrete_fibre(body_arm, motor)) == 1


def test_the_split_rule_is_the_papers_on_the_paper_arm():
    radii = np.linspace(0.0, 3.0, 301)
    poses = np.stack([radii * np.cos(0.7), radii * np.sin(0.7), np.full_like(radii, 2.0)], -1)
    split = fibres.fibre_is_split(PAPER_ARM, poses)
    interior = np.abs(radii - 1.0) > 1e-9
    np.testing.assert_array_equal(split[interior], radii[interior] < 1.0)


@pytest.mark.parametrize("name", ["paper", "level-eye", "link-eye-1d", "uneven-1d"])
def test_the_split_rule_agrees_with_the_walks_winding(name):
    """Grashof's condition (three long sides) from the link lengths alone,
    against what the kernel walk finds: a loop that winds around a joint."""
    body_arm = BODIES[name]
    motor = random_states(body_arm, 14, seed=4)
    expected = fibres.fibre_is_split(radian(body_arm), radian(body_arm).forward(
        body_arm.to_radians(motor)))
    assert 0 < expected.sum() < len(expected)           # both kinds among the states
    sampled = sample_points_of_view(motor, n_samples=20, body_arm=body_arm)
    np.testing.assert_array_equal([r == "split" for r in sampled.reason], expected)
    np.testing.assert_array_equal(np.any(sampled.winding != 0, axis=1), expected)
