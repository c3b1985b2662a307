import numpy as np
import pytest

from sensorispace_ros.core import arm
from sensorispace_ros.core.paper.compensation import _squared_pose_error, compensate_pose


def test_objective_equals_squared_pose_error_of_the_forward_model():
    rng = np.random.default_rng(0)
    target = np.array([0.7, -1.2, 5.0])               # unwrapped orientation on purpose
    objective = _squared_pose_error(target)
    for motor in rng.uniform(-4, 4, size=(20, 4)):
        expected = arm.pose_error(arm.forward(motor), target) ** 2
        assert objective(motor) == pytest.approx(expected, rel=1e-12, abs=1e-15)


def test_reaches_in_reach_targets_from_a_distant_start():
    rng = np.random.default_rng(1)
    tried = 0
    for _ in range(30):
        true_motor = rng.uniform(-np.pi, np.pi, 4)
        target = arm.forward(true_motor)
        if not 1.2 < np.hypot(target[0], target[1]) < 2.8:
            continue
        tried += 1
        start = true_motor + rng.normal(scale=0.4, size=4)
        motor, error, success = compensate_pose(start, target)
        assert success
        assert error <= 1e-3
        assert arm.pose_error(arm.forward(motor), target) == pytest.approx(error)
        assert error < 1e-5                             # far below the threshold in practice
    assert tried >= 8


def test_fails_for_targets_beyond_reach():
    start = np.array([0.1, -1.5, 2.2, -3.0])
    for angle in (0.0, 2.0, -2.5):
        target = np.array([3.05 * np.cos(angle), 3.05 * np.sin(angle), -2.2])
        motor, error, success = compensate_pose(start, target)
        assert not success
        # The arm stretched towards the target: error ~ the 0.05 beyond reach.
        assert 0.049 < error < 0.06


def test_threshold_applies_to_the_error_norm():
    # A target 0.02 beyond reach: its squared error (4e-4) is below 1e-3,
    # its norm (0.02) is not.
    target = np.array([3.02, 0.0, 0.0])
    _, error, success = compensate_pose(np.array([0.1, 0.1, -0.1, -0.1]), target)
    assert error ** 2 < 1e-3 < error
    assert not success
    _, _, loose = compensate_pose(np.array([0.1, 0.1, -0.1, -0.1]), target, threshold=0.03)
    assert loose


def test_result_is_continuous_with_the_start():
    # A start with large unwrapped angles stays near them (no wrap to [-pi, pi)).
    start = np.array([0.1, -1.5, 2.2, -3.0]) + 2 * np.pi * np.array([3, -2, 1, 4])
    target = arm.forward(start) + np.array([-0.2, 0.1, 0.0])
    motor, _, success = compensate_pose(start, target)
    assert success
    assert np.abs(motor - start).max() < 2.0


@pytest.mark.parametrize("kwargs, name", [
    ({"threshold": 0.0}, "threshold"), ({"initial_simplex_size": -1.0}, "initial_simplex_size"),
    ({"maxiter": 0}, "maxiter")])
def test_rejects_bad_parameters(kwargs, name):
    with pytest.raises(ValueError, match=name):
        compensate_pose(np.zeros(4), np.array([2.0, 0.0, 0.0]), **kwargs)


def test_rejects_bad_shapes():
    with pytest.raises(ValueError, match="motor_start"):
        compensate_pose(np.zeros(3), np.array([2.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="target_pose"):
        compensate_pose(np.zeros(4), np.array([2.0, 0.0]))


# --- any body ------------------------------------------------------------------

from sensorispace_ros.core.arm import PAPER_ARM  # noqa: E402
from sensorispace_ros.core.paper.compensation import _chain_squared_pose_error  # noqa: E402
from tests.core.paper_bodies import BODIES, random_states  # noqa: E402


@pytest.mark.parametrize("name", sorted(BODIES))
def test_chain_objective_is_the_squared_pose_error(name):
    body_arm = BODIES[name]
    target = np.array([0.7, -1.2, 5.0])
    objective = _chain_squared_pose_error(body_arm, target)
    for motor in random_states(body_arm, 15, seed=21):
        error = body_arm.pose_error(body_arm.forward(motor), target)
        if body_arm.eye == "level":
            error = np.hypot(*(body_arm.forward(motor) - target)[:2])
        assert objective(motor) == pytest.approx(error ** 2, rel=1e-12, abs=1e-15)


def test_chain_objective_on_the_paper_geometry_is_the_papers():
    target = np.array([1.1, 0.4, -2.0])
    fast, general = _squared_pose_error(target), _chain_squared_pose_error(PAPER_ARM, target)
    for motor in np.random.default_rng(22).uniform(-4, 4, size=(20, 4)):
        assert general(motor) == pytest.approx(fast(motor), rel=1e-13, abs=1e-16)


@pytest.mark.parametrize("name", sorted(BODIES))
def test_every_body_reaches_its_targets(name):
    """From 0.4 rad away (in the arm's unit), Nelder-Mead finds the pose."""
    body_arm = BODIES[name]
    rng = np.random.default_rng(23)
    reached = 0
    for true_motor in random_states(body_arm, 8, seed=24):
        target = body_arm.forward(true_motor)
        start = true_motor + body_arm.from_radians(rng.normal(scale=0.4, size=len(true_motor)))
        motor, error, success = compensate_pose(start, target, body_arm=body_arm)
        assert error == pytest.approx(body_arm.pose_error(body_arm.forward(motor), target),
                                      abs=1e-15)
        reached += success and error < 1e-5
    assert reached >= 7


def test_the_simplex_is_converted_to_the_motor_unit():
    """Degrees search the same path as radians, 180 / pi times larger."""
    degrees = BODIES["degrees"]
    start = np.array([0.1, -1.5, 2.2, -3.0])
    target = arm.forward(start) + np.array([-0.3, 0.2, 0.0])
    in_radians, _, ok_radians = compensate_pose(start, target)
    in_degrees, _, ok_degrees = compensate_pose(np.rad2deg(start), target, body_arm=degrees)
    assert ok_radians and ok_degrees
    np.testing.assert_allclose(np.deg2rad(in_degrees), in_radians, atol=1e-4)


def test_a_level_eye_ignores_the_orientation():
    body_arm = BODIES["level-eye"]
    start = np.array([0.1, -1.5, 2.2])
    target = np.array([*body_arm.forward(start)[:2] + [0.2, -0.1], 2.5])
    motor, error, success = compensate_pose(start, target, body_arm=body_arm)
    assert success and error < 1e-5
    assert error == pytest.approx(np.hypot(*(body_arm.forward(motor) - target)[:2]))
    with pytest.raises(ValueError, match=r"\(3,\)"):
        compensate_pose(np.zeros(4), target, body_arm=body_arm)
