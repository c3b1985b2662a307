"""Planar chains of any size: forward model, Jacobian, structure and the
compiled body kernel against the NumPy path, for every kind of eye and unit."""
from __future__ import annotations

import numpy as np
import pytest
from numpy_bits import assert_numpy_bits

from sensorispace_ros.core import arm, body as body_module
from sensorispace_ros.core.arm import PAPER_ARM, Arm
from sensorispace_ros.core.body import SimulatedBody, simulate
from sensorispace_ros.core.sensor_code import SensorCode

ARMS = {
    "paper": PAPER_ARM,
    "five-joint": Arm((0.75,) * 4),
    "three-joint": Arm((1.5, 1.5)),
    "level-eye": Arm(eye="level"),
    "link-eye": Arm(eye="link"),
    "degrees": Arm(unit="deg"),
    "uneven": Arm((0.3, 0.7, 1.1, 0.2, 0.5)),
    "one link": Arm((2.0,)),
}


def _motor(body_arm: Arm, n: int, seed: int = 0) -> np.ndarray:
    angles = np.random.default_rng(seed).uniform(-7.0, 7.0, (n, body_arm.n_joints))
    return body_arm.from_radians(angles)


def _brute_pose(body_arm: Arm, motor: np.ndarray) -> np.ndarray:
    """The pose of one motor state, link by link in plain Python."""
    angles = np.deg2rad(motor) if body_arm.unit == "deg" else motor
    theta, x, y = 0.0, 0.0, 0.0
    for k, length in enumerate(body_arm.segments):
        theta += angles[k]
        x += length * np.cos(theta)
        y += length * np.sin(theta)
    alpha = {"joint": theta + angles[-1], "link": theta, "level": arm.LEVEL_DIRECTION}
    return np.array([x, y, alpha[body_arm.eye]])


@pytest.mark.parametrize("name", ARMS)
def test_forward_is_the_chain_link_by_link(name):
    body_arm = ARMS[name]
    motor = _motor(body_arm, 50)
    expected = np.stack([_brute_pose(body_arm, m) for m in motor])
    np.testing.assert_allclose(body_arm.forward(motor), expected, rtol=0, atol=1e-12)
    assert body_arm.forward(motor.reshape(5, 10, -1)).shape == (5, 10, 3)


@pytest.mark.parametrize("name", ARMS)
def test_jacobian_is_the_derivative_per_motor_unit(name):
    body_arm = ARMS[name]
    motor = _motor(body_arm, 20, seed=1)
    step = 1e-6 * body_arm.period / (2 * np.pi)
    numeric = np.stack([(body_arm.forward(motor + step * e) - body_arm.forward(motor - step * e))
                        / (2 * step) for e in np.eye(body_arm.n_joints)], axis=-1)
    np.testing.assert_allclose(body_arm.jacobian(motor), numeric, atol=1e-7 * 2 * np.pi
                               / body_arm.period)


@pytest.mark.parametrize("name", ARMS)
def test_pose_rank_and_pov_dimension_are_the_jacobians(name):
    body_arm = ARMS[name]
    ranks = [np.linalg.matrix_rank(j) for j in body_arm.jacobian(_motor(body_arm, 30, seed=2))]
    assert max(ranks) == body_arm.pose_rank
    assert body_arm.pov_dim == body_arm.n_joints - body_arm.pose_rank


def test_catalogue_structure():
    structure = {name: (a.n_joints, a.pose_rank, a.pov_dim) for name, a in ARMS.items()}
    assert structure["paper"] == (4, 3, 1)
    assert structure["five-joint"] == (5, 3, 2)
    assert structure["three-joint"] == (3, 3, 0)
    assert structure["level-eye"] == (3, 2, 1)


@pytest.mark.parametrize("name", ARMS)
def test_reachable_is_where_some_motor_state_puts_the_eye(name):
    body_arm = ARMS[name]
    poses = body_arm.forward(_motor(body_arm, 4000, seed=3))
    if body_arm.eye == "link":      # the eye's orientation is the last link's
        assert all(body_arm.reachable(p[:2], p[2]) for p in poses)
    else:
        assert np.all(body_arm.reachable(poses[:, :2], 0.0))
        outside = poses[:, :2] * (1.0 + 1e-6) * body_arm.reach / np.hypot(*poses[:, :2].T)[:, None]
        assert not np.any(body_arm.reachable(outside, 0.0))


def test_the_paper_arm_keeps_its_written_out_path():
    motor = _motor(PAPER_ARM, 100, seed=4)
    assert PAPER_ARM.forward(motor).tobytes() == arm.forward(motor).tobytes()
    assert PAPER_ARM.jacobian(motor).tobytes() == arm.jacobian(motor).tobytes()


def test_degrees_are_radians_in_another_unit():
    motor = _motor(PAPER_ARM, 100, seed=5)
    np.testing.assert_allclose(ARMS["degrees"].forward(np.rad2deg(motor)),
                               PAPER_ARM.forward(motor), atol=1e-12)


@pytest.mark.parametrize("kwargs, message", [
    ({"segments": ()}, "arm.segments: needs at least one link"),
    ({"segments": (1.0, -1.0)}, "arm.segments: every link length must be finite and > 0"),
    ({"segments": (1.0, np.inf)}, "arm.segments"),
    ({"eye": "wrist"}, "arm.eye: must be one of joint, link, level"),
    ({"unit": "grad"}, "arm.motor_unit: must be one of rad, deg"),
])
def test_a_bad_arm_names_the_parameter(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Arm(**kwargs)


def test_a_motor_state_of_the_wrong_length_is_refused():
    with pytest.raises(ValueError, match=r"\(\.\.\., 5\)"):
        ARMS["five-joint"].forward(np.zeros((2, 4)))


@pytest.mark.numpy_bits
@pytest.mark.skipif(not body_module.numba_available(), reason="numba is not installed")
@pytest.mark.parametrize("name", ARMS)
def test_the_compiled_kernel_gives_the_numpy_bits_on_every_chain(name):
    body_arm = ARMS[name]
    rng = np.random.default_rng(6)
    lights = rng.uniform(-7.0, 7.0, (10, 2))
    receptors = np.sort(rng.uniform(-1.0, 1.0, 6))
    motor = _motor(body_arm, 3000, seed=7)
    fast = simulate(motor, lights, receptors, "numba", body_arm)
    slow = simulate(motor, lights, receptors, "numpy", body_arm)
    assert fast[1].tobytes() == slow[1].tobytes()
    assert_numpy_bits(fast[0], slow[0], rtol=1e-15)


def test_a_body_describes_its_joints_and_applies_its_code():
    rng = np.random.default_rng(8)
    lights, receptors = rng.uniform(-7.0, 7.0, (10, 2)), np.sort(rng.uniform(-1, 1, 6))
    code = SensorCode("scale", 1e-3, 6)
    coded = SimulatedBody(receptors, lights, kernel="numpy", body_arm=ARMS["degrees"], code=code)
    raw = SimulatedBody(receptors, lights, kernel="numpy", body_arm=ARMS["degrees"])
    motor = _motor(ARMS["degrees"], 10, seed=9)
    np.testing.assert_array_equal(coded.sense(motor), 1e-3 * raw.sense(motor))
    assert coded.description.unit == "deg" and coded.description.periods == (360.0,) * 4
    assert (coded.n_motors, coded.n_sensors) == (4, 6)
    sensation, pose = coded.sense_at_rest()
    np.testing.assert_array_equal(sensation, coded.sense(motor[-1:])[0])
    np.testing.assert_array_equal(pose, ARMS["degrees"].forward(motor[-1]))
