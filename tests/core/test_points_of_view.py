import numpy as np
import pytest

from sensorispace_ros.core import arm
from sensorispace_ros.core.paper import points_of_view as pov

# Tip distances from the base: split fibres below 1 (paper Fig. 5b), whole
# loops between 1 and 3, near both ends of the ring included.
TIP_RADII = (0.4, 0.8, 0.95, 1.05, 1.5, 2.0, 2.5, 2.9)


def motor_reaching(radius, tip_angle, alpha):
    """A motor state with tip at polar (radius, tip_angle), built by hand:
    first segment towards the target, elbow of the remaining 2-link IK."""
    theta1 = tip_angle
    rest = radius - 1.0                           # signed, along tip_angle
    bend = np.arccos(abs(rest) / 2.0)
    base = tip_angle if rest >= 0 else tip_angle + np.pi
    theta2, theta3 = base + bend, base - bend
    return np.array([theta1, theta2 - theta1, theta3 - theta2, alpha - theta3])


@pytest.fixture(scope="module")
def starts():
    rng = np.random.default_rng(7)
    return np.array([motor_reaching(r, rng.uniform(-np.pi, np.pi), rng.uniform(-np.pi, np.pi))
                     for r in TIP_RADII])


PROGRESS = []


@pytest.fixture(scope="module")
def sampled(starts):
    return pov.sample_points_of_view(starts, progress=lambda done, total: PROGRESS.append(
        (done, total)))


def test_progress_counts_closed_loops_up_to_all(sampled):
    done = [d for d, _ in PROGRESS]
    assert done == sorted(done) and done[-1] == len(TIP_RADII)
    assert {t for _, t in PROGRESS} == {len(TIP_RADII)}


def test_motor_reaching_helper_reaches_the_radius(starts):
    pose = arm.forward(starts)
    np.testing.assert_allclose(np.hypot(pose[:, 0], pose[:, 1]), TIP_RADII, atol=1e-12)


# --- resample_closed_path / loop_winding -----------------------------------

def test_resample_is_equally_spaced_in_arc_length_on_a_circle():
    # An unevenly sampled circle in the (m0, m1) plane, open end before the start.
    t = np.sort(np.random.default_rng(0).uniform(0, 2 * np.pi, 400))
    t = np.concatenate([[0.0], t[t < 2 * np.pi - 0.05]])
    path = np.stack([np.cos(t), np.sin(t), 0 * t, 0 * t + 5.0], axis=1)
    samples = pov.resample_closed_path(path, 50)
    assert samples.shape == (50, 4)
    np.testing.assert_array_equal(samples[0], path[0])
    gaps = np.linalg.norm(np.diff(np.vstack([samples, samples[:1]]), axis=0), axis=1)
    # Chords of a polygon inscribed in the unit circle: equal within a few %.
    assert gaps.max() / gaps.min() < 1.05
    np.testing.assert_allclose(gaps.sum(), 2 * np.pi, rtol=2e-3)
    assert np.all(samples[:, 3] == 5.0)      # angles returned as given, not wrapped


def test_winding_loop_is_closed_through_the_shifted_start():
    # Joint 0 turns once around its circle; the path ends just short of 2 pi.
    t = np.linspace(0.0, 2 * np.pi - 0.01, 300)
    path = np.stack([t, np.sin(t), 0 * t, -t], axis=1)
    np.testing.assert_array_equal(pov.loop_winding(path), [1, 0, 0, -1])
    samples = pov.resample_closed_path(path, 40)
    # Samples go on increasing up to ~2 pi instead of jumping back to 0.
    assert np.all(np.diff(samples[:, 0]) > 0)
    assert samples[-1, 0] > 2 * np.pi - 0.2


def test_contractible_loop_has_zero_winding():
    t = np.linspace(0, 2 * np.pi, 100, endpoint=False)
    path = np.stack([3 + np.cos(t), np.sin(t), 0 * t, 0 * t], axis=1)
    np.testing.assert_array_equal(pov.loop_winding(path), [0, 0, 0, 0])


@pytest.mark.parametrize("bad", [np.zeros((1, 4)), np.zeros(4), np.full((3, 4), np.nan)])
def test_resample_rejects_bad_paths(bad):
    with pytest.raises(ValueError, match="path"):
        pov.resample_closed_path(bad)


def test_resample_rejects_bad_sample_count():
    with pytest.raises(ValueError, match="n_samples"):
        pov.resample_closed_path(np.eye(4)[:2], 0)


# --- kernel walk -------------------------------------------------------------

def test_kernel_direction_is_in_the_jacobian_null_space():
    motor = np.random.default_rng(1).uniform(-np.pi, np.pi, size=(200, 4))
    jac = arm.jacobian(motor)
    kernel = arm.kernel_direction(jac)
    assert np.all(np.linalg.norm(kernel, axis=-1) > 1e-6)
    residual = np.linalg.norm(jac @ kernel[..., None], axis=(-2, -1))
    assert residual.max() < 1e-12 * np.linalg.norm(kernel, axis=-1).max() + 1e-14


def test_fused_walk_step_matches_arm_and_pseudo_inverse():
    rng = np.random.default_rng(2)
    motor = rng.uniform(-np.pi, np.pi, size=(50, 4))
    target = arm.forward(motor + rng.normal(scale=1e-3, size=motor.shape))
    corrected, kernel = pov._corrected_kernel_step(motor.T.copy(), target.T.copy())
    reference = arm.kernel_direction(arm.jacobian(motor))
    reference /= np.linalg.norm(reference, axis=-1, keepdims=True)
    np.testing.assert_allclose(kernel.T, reference, atol=1e-12)
    residual = arm.forward(motor) - target
    newton = motor - np.einsum("pij,pj->pi", np.linalg.pinv(arm.jacobian(motor)), residual)
    np.testing.assert_allclose(corrected.T, newton, atol=1e-12)


def test_every_sample_has_its_start_pose(sampled, starts):
    target = arm.forward(starts)
    error = arm.pose_error(arm.forward(sampled.samples), target[:, None, :])
    assert error.max() <= 1e-6
    assert error.max() < 1e-10                       # what the projection actually reaches
    assert sampled.max_pose_drift == pytest.approx(error.max(), abs=1e-15)
    np.testing.assert_array_equal(sampled.samples[:, 0], starts)


def test_split_points_of_view_are_flagged_from_winding_alone(sampled):
    split = np.array(TIP_RADII) < 1.0
    np.testing.assert_array_equal(sampled.valid, ~split)
    assert [r == "split" for r in sampled.reason] == list(split)
    assert np.all(np.any(sampled.winding[split] != 0, axis=1))
    assert np.all(sampled.winding[~split] == 0)


def test_samples_are_distinct_and_evenly_spread_along_the_loop(sampled):
    for samples in sampled.samples[sampled.valid]:
        step = pov.periodic_distance(samples, np.roll(samples, -1, axis=0))
        assert step.min() > 0.5 * np.median(step) > 0
        assert step.max() < 2.0 * np.median(step)


def test_whole_loops_cover_the_feasible_arc_of_the_first_joint(sampled, starts):
    # Independent geometry: with the tip at distance r > 1, the first segment
    # direction t1 must keep |tip - e(t1)| <= 2, i.e. it sweeps the arc
    # |t1 - phi| <= arccos((r^2 - 3) / (2 r)); the loop reaches both ends.
    pose = arm.forward(starts)
    for samples, (x, y, _), valid in zip(sampled.samples, pose, sampled.valid):
        if not valid:
            continue
        r, phi = np.hypot(x, y), np.arctan2(y, x)
        half_arc = np.arccos((r * r - 3.0) / (2.0 * r))
        offset = np.abs(arm.wrap_angle(samples[:, 0] - phi))
        spacing = pov.periodic_distance(samples, np.roll(samples, 1, axis=0)).max()
        assert offset.max() <= half_arc + 1e-9
        assert offset.max() >= half_arc - spacing


def test_split_loops_turn_the_first_joint_around_its_circle(sampled):
    for samples, valid in zip(sampled.samples, sampled.valid):
        if valid:
            continue
        turn = np.sort(arm.wrap_angle(samples[:, 0]))
        gaps = np.diff(np.concatenate([turn, turn[:1] + 2 * np.pi]))
        assert gaps.max() < 0.3                       # no uncovered sector of the circle


def test_walk_that_cannot_close_is_reported():
    start = motor_reaching(2.0, 0.3, 0.1)[None, :]
    result = pov.sample_points_of_view(start, max_steps=200)
    assert result.reason == ["not_closed"] and not result.valid[0]
    assert result.steps[0] == 200


@pytest.mark.parametrize("kwargs, name", [
    ({"step": 0.0}, "step"), ({"close_tol": 1e-4}, "close_tol"), ({"n_samples": 0}, "n_samples"),
    ({"min_steps": 10, "max_steps": 5}, "min_steps"), ({"record_every": 0}, "record_every")])
def test_sampler_rejects_bad_parameters(kwargs, name):
    with pytest.raises(ValueError, match=name):
        pov.sample_points_of_view(np.zeros((1, 4)), **kwargs)


def test_sampler_rejects_bad_motor_states():
    with pytest.raises(ValueError, match="motor_states"):
        pov.sample_points_of_view(np.zeros((3, 3)))


# --- any body ------------------------------------------------------------------

from sensorispace_ros.core.arm import PAPER_ARM, Arm  # noqa: E402
from sensorispace_ros.core.paper import chain_walk  # noqa: E402
from tests.core.paper_bodies import BODIES, random_states  # noqa: E402


@pytest.fixture(scope="module", params=sorted(BODIES))
def body_povs(request):
    body_arm = BODIES[request.param]
    motor = random_states(body_arm, 6, seed=11)
    return body_arm, motor, pov.sample_points_of_view(motor, n_samples=40, n_samples_2d=150,
                                                      body_arm=body_arm)


def test_every_sample_of_every_body_has_its_pose(body_povs):
    body_arm, motor, sampled = body_povs
    rows = 150 if body_arm.pov_dim == 2 else 40
    assert sampled.samples.shape == (len(motor), rows, body_arm.n_joints)
    np.testing.assert_array_equal(sampled.samples[:, 0], motor)
    pose = body_arm.forward(motor)
    error = body_arm.pose_error(body_arm.forward(sampled.samples), pose[:, None, :])
    assert error.max() < 1e-9
    assert sampled.max_pose_drift < 1e-9


def test_points_of_view_are_more_than_their_start(body_povs):
    """A 1-D or 2-D POV spreads over its fibre; a 0-D one holds both elbows."""
    body_arm, motor, sampled = body_povs
    for samples, valid in zip(sampled.samples, sampled.valid):
        distinct = np.unique(samples, axis=0)
        if body_arm.pov_dim == 0:
            assert len(distinct) == 2
            assert np.sum(np.all(samples == samples[0], axis=1)) == len(samples) // 2
        elif valid:
            assert len(distinct) == len(samples)
            spread = pov.periodic_distance(body_arm.to_radians(samples),
                                           body_arm.to_radians(samples[0]))
            assert spread.max() > 0.5


def test_motor_units_change_no_point_of_view():
    degrees = BODIES["degrees"]
    motor = random_states(degrees, 5, seed=12)
    in_degrees = pov.sample_points_of_view(motor, n_samples=30, body_arm=degrees)
    in_radians = pov.sample_points_of_view(np.deg2rad(motor), n_samples=30)
    np.testing.assert_array_equal(in_degrees.samples[:, 0], motor)
    np.testing.assert_allclose(in_degrees.samples, np.rad2deg(in_radians.samples), atol=1e-9)
    assert in_degrees.reason == in_radians.reason


def test_the_chain_step_is_the_paper_arms_closed_form_step():
    """The general step on the paper arm's geometry gives the fast path's numbers."""
    rng = np.random.default_rng(13)
    motor = rng.uniform(-np.pi, np.pi, size=(40, 4))
    target = arm.forward(motor + rng.normal(scale=1e-3, size=motor.shape))
    fast = pov._corrected_kernel_step(motor.T.copy(), target.T.copy())
    general = chain_walk.kernel_step(PAPER_ARM)(motor.T.copy(), target.T.copy())
    np.testing.assert_allclose(general[0], fast[0], atol=1e-12)
    np.testing.assert_allclose(general[1], fast[1], atol=1e-12)


def test_the_chain_step_of_a_level_eye_follows_its_kernel():
    body_arm = BODIES["level-eye"]
    motor = random_states(body_arm, 30, seed=14)
    target = body_arm.forward(motor)
    corrected, kernel = chain_walk.kernel_step(body_arm)(motor.T.copy(), target.T.copy())
    jac = body_arm.jacobian(motor)[:, :2, :]
    np.testing.assert_allclose(np.einsum("pij,jp->pi", jac, kernel), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(kernel, axis=0), 1.0)
    np.testing.assert_allclose(corrected, motor.T, atol=1e-14)       # already on the pose


def test_the_general_walk_traces_the_paper_arms_loops():
    start = np.array([motor_reaching(r, 0.4, -0.3) for r in (1.5, 2.5)])
    fast = pov.sample_points_of_view(start, n_samples=50)
    target = arm.forward(start)
    walk = pov._walk_kernels(start, target, step=1e-3, min_steps=50, close_tol=1e-2,
                             max_steps=200_000, record_every=5, progress=None,
                             kernel_step=chain_walk.kernel_step(PAPER_ARM))
    samples, _, reason = pov._resample_walks(walk, 50, 5)
    assert reason == fast.reason == ["ok", "ok"]
    np.testing.assert_allclose(samples, fast.samples, atol=1e-5)   # before projection


def test_points_of_view_of_three_dimensions_are_refused():
    with pytest.raises(ValueError, match="dimension 3"):
        pov.sample_points_of_view(np.zeros((1, 6)), body_arm=Arm((1.0,) * 5, "joint", "rad"))
