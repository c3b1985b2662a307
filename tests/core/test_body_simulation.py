"""The arm's forward model and the retina, as computed for the body, against
straightforward references: the dense broadcast evaluation they replaced
(same floating-point operations, so the bits must be equal) and a scalar
loop over rows, lights and receptors written from the paper's formulas.

The compiled simulator calls the C library's exp; NumPy's is its own on an
AVX-512 machine (core.numpy_math): the tests marked ``numpy_bits`` check the
bits where NumPy calls the C library (test_numpy_math.py sees to it)."""
import math

import numpy as np
import pytest
from numpy_bits import assert_numpy_bits

from sensorispace_ros.core import arm, retina
from sensorispace_ros.core.numpy_math import numpy_calls_c_math
from sensorispace_ros.core import body as body_module
from sensorispace_ros.core.body import SimulatedBody


def dense_forward(motor, lengths=(1.0, 1.0, 1.0)):
    motor = np.asarray(motor, dtype=float)
    theta = np.cumsum(motor[..., :3], axis=-1)
    lengths = np.asarray(lengths, dtype=float)
    return np.stack([np.sum(lengths * np.cos(theta), axis=-1),
                     np.sum(lengths * np.sin(theta), axis=-1),
                     np.sum(motor, axis=-1)], axis=-1)


def dense_sensation(pose, lights, receptors):
    """Every (pose, light, receptor) term evaluated, hidden lights masked out."""
    pose, lights = np.asarray(pose, float), np.asarray(lights, float)
    rel = lights - pose[..., None, :2]
    cos_a = np.cos(pose[..., 2])[..., None]
    sin_a = np.sin(pose[..., 2])[..., None]
    depth = rel[..., 0] * cos_a + rel[..., 1] * sin_a
    lateral = -rel[..., 0] * sin_a + rel[..., 1] * cos_a
    visible = depth > 0.0
    projection = np.where(visible, lateral / np.where(visible, depth, 1.0), np.inf)
    distance = np.where(visible, np.hypot(rel[..., 0], rel[..., 1]), 1.0)
    with np.errstate(invalid="ignore", over="ignore"):
        gap = receptors - projection[..., :, None]
        response = np.where(visible[..., :, None], np.exp(-gap * gap), 0.0)
    return np.sum(response / distance[..., :, None], axis=-2)


def scalar_sensation(pose, lights, receptors):
    x, y, alpha = (float(v) for v in pose)
    out = [0.0] * len(receptors)
    for lx, ly in lights:
        u = (lx - x) * math.cos(alpha) + (ly - y) * math.sin(alpha)    # depth
        v = -(lx - x) * math.sin(alpha) + (ly - y) * math.cos(alpha)   # lateral
        if u <= 0:
            continue
        for r, position in enumerate(receptors):
            out[r] += math.exp(-(position - v / u) ** 2) / math.hypot(lx - x, ly - y)
    return np.array(out)


def random_scene(rng, n):
    # Motor states all over the torus plus a cluster near the paper's m0 (lights in view).
    motor = np.concatenate([rng.uniform(-7, 7, (n, 4)),
                            [0.1, -1.5, 2.2, -3.0] + 0.05 * rng.standard_normal((n, 4))])
    lights = arm.forward([0.1, -1.5, 2.2, -3.0])[:2] + rng.uniform(-1, 1, 2) \
        + rng.uniform(-4, 4, (10, 2))
    return motor, lights, np.sort(rng.uniform(-1, 1, 6))


@pytest.mark.parametrize("shape", [(4,), (1, 4), (7, 4), (649, 4), (3, 5, 4), (0, 4)])
def test_forward_is_bit_identical_to_the_dense_evaluation(shape):
    motor = np.random.default_rng(1).uniform(-9, 9, shape)
    pose = arm.forward(motor)
    assert pose.shape == shape[:-1] + (3,)
    np.testing.assert_array_equal(pose, dense_forward(motor))
    lengths = (0.5, 1.3, 2.1)
    np.testing.assert_array_equal(arm.forward(motor, lengths), dense_forward(motor, lengths))


def test_forward_known_postures():
    np.testing.assert_allclose(arm.forward([0.0, 0.0, 0.0, 0.0]), [3.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(arm.forward([np.pi / 2, 0.0, 0.0, 1.0]),
                               [0.0, 3.0, np.pi / 2 + 1.0], atol=1e-15)
    np.testing.assert_allclose(arm.forward([0.0, np.pi / 2, np.pi / 2, 0.0]),
                               [0.0, 1.0, np.pi], atol=1e-15)
    with pytest.raises(ValueError, match="motor"):
        arm.forward([0.0, 1.0])


@pytest.mark.parametrize("n", [1, 3, 40, 649])
def test_sensation_is_bit_identical_to_the_dense_evaluation(n):
    rng = np.random.default_rng(n)
    motor, lights, receptors = random_scene(rng, n)
    pose = arm.forward(motor)
    got = retina.sensation(pose, lights, receptors)
    assert got.shape == (2 * n, 6)
    np.testing.assert_array_equal(got, dense_sensation(pose, lights, receptors))
    # Lights in front of and behind the lens: both branches are exercised.
    visible = retina.project(pose, lights)[2]
    assert visible.any() and not visible.all()


def test_sensation_matches_the_scalar_formula():
    rng = np.random.default_rng(7)
    motor, lights, receptors = random_scene(rng, 30)
    pose = arm.forward(motor)
    got = retina.sensation(pose, lights, receptors)
    expected = np.array([scalar_sensation(p, lights, receptors) for p in pose])
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-300)


def test_sensation_broadcasts_like_the_dense_evaluation():
    rng = np.random.default_rng(3)
    motor, lights, receptors = random_scene(rng, 6)
    pose = arm.forward(motor.reshape(3, 4, 4))
    np.testing.assert_array_equal(retina.sensation(pose, lights, receptors),
                                  dense_sensation(pose, lights, receptors))
    per_pose_lights = lights + rng.uniform(-1, 1, (3, 4, 1, 2))     # one scene per pose
    np.testing.assert_array_equal(retina.sensation(pose, per_pose_lights, receptors),
                                  dense_sensation(pose, per_pose_lights, receptors))
    single = retina.sensation(pose[1, 2], lights, receptors)
    assert single.shape == (6,)
    np.testing.assert_array_equal(single, dense_sensation(pose[1, 2], lights, receptors))
    empty = retina.sensation(np.zeros((0, 3)), lights, receptors)
    assert empty.shape == (0, 6)
    with pytest.raises(ValueError, match="receptor_positions"):
        retina.sensation(pose, lights, receptors[None])


def test_far_projections_add_exact_zeros():
    # A light almost in the lens plane projects ~1e6 away: exp underflows to 0 exactly,
    # and the sum equals the other light's term alone.
    receptors = np.array([-0.5, 0.0, 0.5])
    pose = np.array([0.0, 0.0, 0.0])
    near = np.array([[2.0, 0.1]])
    edge = np.array([[1e-6, 1.0]])
    both = retina.sensation(pose, np.concatenate([edge, near]), receptors)
    np.testing.assert_array_equal(both, retina.sensation(pose, near, receptors))
    assert np.all(both > 0)


@pytest.mark.numpy_bits
def test_simulated_body_returns_the_dense_sensations_and_poses():
    rng = np.random.default_rng(5)
    motor, lights, receptors = random_scene(rng, 100)
    body = SimulatedBody(receptors, lights, motor[0])
    sensations, poses = body.sense_with_poses(motor)
    np.testing.assert_array_equal(poses, dense_forward(motor))
    assert_numpy_bits(sensations, dense_sensation(dense_forward(motor), lights, receptors),
                      rtol=1e-15)
    np.testing.assert_array_equal(body.motor_state, motor[-1])


needs_numba = pytest.mark.skipif(not body_module.numba_available(),
                                 reason="the compiled simulator needs numba")


@pytest.mark.numpy_bits
@pytest.mark.parametrize("kernel", ["numpy", "numba", "python"])
@pytest.mark.parametrize("n", [1, 2, 649])
def test_simulate_kernels_give_the_numpy_bits(kernel, n):
    # "python": the loop the compiler gets, run as plain Python. Python's math.hypot is
    # its own (not the C library's, which NumPy and numba call): last-bit differences,
    # and NumPy's own exp (AVX-512) adds one ulp to some terms.
    rng = np.random.default_rng(100 + n)
    motor, lights, receptors = random_scene(rng, n)
    # Rows the body may meet: lights just behind and just in front of the lens plane
    # (the latter projects ~1e23 away: exp underflows), NaN and inf joints.
    motor[0] = [0.0, 0.0, 0.0, np.pi]
    edge_lights = np.concatenate([lights, [[3.0 + 1e-9, 5.0], [3.0, 1e-7]]])
    if n > 1:
        motor[1] = [np.nan, 0.0, 0.0, 0.0]
        if kernel != "python":                  # Python's math.cos(inf) raises
            motor[2] = [0.0, np.inf, 0.0, 0.0]
    with np.errstate(invalid="ignore"):         # cos(inf)
        expected_pose = arm.forward(motor)
        expected = retina.sensation(expected_pose, edge_lights, receptors)
    if kernel == "python":
        got = np.empty_like(expected)
        pose = np.empty_like(expected_pose)
        body_module._simulate_rows(motor, edge_lights, receptors, got, pose)
        np.testing.assert_allclose(got, expected, rtol=4e-16 if numpy_calls_c_math() else 1e-15,
                                   atol=0)
        assert pose.tobytes() == expected_pose.tobytes()
        return
    else:
        if kernel == "numba" and not body_module.numba_available():
            pytest.skip("numba is not installed")
        with np.errstate(invalid="ignore"):     # the NumPy path's cos(inf), as above
            got, pose = body_module.simulate(motor, edge_lights, receptors, kernel=kernel)
    # Bitwise (NaN == NaN at the same places): the compiled body must not change a result.
    if kernel == "numpy":
        assert got.tobytes() == expected.tobytes()
    else:
        assert_numpy_bits(got, expected, rtol=1e-15)
    assert pose.tobytes() == expected_pose.tobytes()
    # A NaN pose sees no light in front (NaN > 0 is false): zeros, in both paths.
    assert np.isfinite(got[0]).all() and (n == 1 or (np.isnan(pose[1]).all() and not got[1].any()))


def test_exp_is_exactly_zero_where_the_compiled_loop_skips_it():
    # The loop adds nothing for exponents >= _EXP_ZERO: exp must round to +0.0 there
    # (C library, as NumPy and numba call it) and not just below 745.1332.
    threshold = body_module._EXP_ZERO
    past = threshold + np.array([0.0, 1e-9, 0.5, 54.0, 1e6, np.inf])
    assert not np.exp(-past).any() and not np.signbit(np.exp(-past)).any()
    assert all(math.exp(-x) == 0.0 for x in past)
    assert np.exp(-745.13) > 0.0        # the skipped range is not wider than exp's zeros


@pytest.mark.numpy_bits
@pytest.mark.parametrize("kernel", ["numba", "python"])
def test_terms_around_the_underflow_keep_the_numpy_bits(kernel):
    # The eye at the origin looking along +x; a light at depth 1 and lateral v projects
    # at v, so a receptor at 0 gets exp(-v**2) / hypot(1, v). Exponents straddle exp's
    # last subnormals and the skip threshold, alone (the sum must stay +0.0, not -0.0)
    # and added to a light in view.
    if kernel == "numba" and not body_module.numba_available():
        pytest.skip("numba is not installed")
    exponents = np.array([700.0, 745.0, 745.13, 745.1332, 745.14, 745.9,
                          body_module._EXP_ZERO, 746.5, 800.0, 1e4])
    receptors = np.array([0.0])
    motor = np.zeros((1, 4))
    motor[0, 3] = -np.sum(np.cumsum(motor[0, :3]))      # alpha = 0
    pose = arm.forward(motor)
    singles, sums = [], []
    for exponent in exponents:
        far = pose[0, :2] + [1.0, math.sqrt(exponent)]
        singles.append(np.array([far]))
        sums.append(np.array([far, pose[0, :2] + [2.0, 0.1], far]))
    for lights in singles + sums:
        expected = retina.sensation(pose, lights, receptors)
        got = np.empty_like(expected)
        got_pose = np.empty_like(pose)
        if kernel == "numba":
            got, got_pose = body_module.simulate(motor, lights, receptors, kernel="numba")
        else:
            body_module._simulate_rows(motor, lights, receptors, got, got_pose)
        if kernel == "numba":
            assert_numpy_bits(got, expected, rtol=1e-15)
        else:           # Python's own math.hypot: last-bit differences (see above)
            np.testing.assert_allclose(got, expected,
                                       rtol=4e-16 if numpy_calls_c_math() else 1e-15, atol=0)
            assert (got == 0.0).tolist() == (expected == 0.0).tolist()
            assert not np.signbit(got).any()
    zeros = [retina.sensation(pose, lights, receptors)[0, 0] for lights in singles]
    assert zeros[0] > 0.0 and zeros[-1] == 0.0 and not np.signbit(zeros).any()


@needs_numba
@pytest.mark.numpy_bits
def test_compiled_simulator_on_the_paper_world_and_an_empty_batch():
    from sensorispace_ros.core.paper import exploration
    world = exploration.build_world(0, {})
    rng = np.random.default_rng(11)
    for lights in (world.initial_lights, world.initial_lights + rng.uniform(-6, 6, 2)):
        motor = world.m0 + rng.uniform(-1, 1, (500, 4)) * rng.uniform(0, 3, (500, 1))
        fast = SimulatedBody(world.receptors, lights, kernel="numba").sense_with_poses(motor)
        slow = SimulatedBody(world.receptors, lights, kernel="numpy").sense_with_poses(motor)
        assert_numpy_bits(fast[0], slow[0], rtol=1e-15)
        assert fast[1].tobytes() == slow[1].tobytes()
        assert np.count_nonzero(fast[0]) > 0.25 * fast[0].size     # lights were in view
    empty, poses = body_module.simulate(np.zeros((0, 4)), world.initial_lights, world.receptors)
    assert empty.shape == (0, 6) and poses.shape == (0, 3)


def test_simulate_rejects_bad_arguments():
    lights, receptors = np.zeros((3, 2)), np.zeros(6)
    with pytest.raises(ValueError, match="kernel"):
        body_module.simulate(np.zeros((1, 4)), lights, receptors, kernel="fortran")
    with pytest.raises(ValueError, match="kernel"):
        SimulatedBody(receptors, lights, kernel="fortran")
    if body_module.numba_available():
        with pytest.raises(ValueError, match="motor_states"):
            body_module.simulate(np.zeros(4), lights, receptors)
        with pytest.raises(ValueError, match="lights_world"):
            body_module.simulate(np.zeros((1, 4)), np.zeros((2, 3)), receptors)
