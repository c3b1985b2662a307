"""The naive agent's searches and walks where the pose's weakest direction
lies below the noise of one finite difference: averaged Jacobians
(``AveragedStep``), and walk corrections and POV samples that leave what is
noise (``loop_walk``)."""
import numpy as np

from sensorispace_ros.core.naive.jacobians import (AveragedStep, SymmetricStep,
    jacobian_stencil, minimum_norm_correction, sensory_jacobian, stencil_rows)
from sensorispace_ros.core.naive.jacobians import loop_smoothed_correction
from sensorispace_ros.core.naive.loop_walk import _correction_and_null
from sensorispace_ros.core.naive.noise import (averaged_search_params, finite_difference_step,
    jacobian_noise, noise_step)
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.sense_memory import CountingBody
from sensorispace_ros.core.naive.structure import BodyStructure

from imperfect_bodies import ImperfectSensing, SmoothBody


def _structure(noise, weakest=0.0133, gain=0.8):
    return BodyStructure(n_motors=4, pose_rank=3, rank_gap=10.0, gain=gain, floor=0.0,
                         votes=8, probes=8, noise=noise, fd_step=0.05, weakest=weakest,
                         repeat_noise=noise)


def test_an_averaged_step_senses_every_stencil_row_repeatedly_as_distinct_states():
    states = np.array([[0.1, 0.2], [0.3, -0.4]])
    step = AveragedStep(0.05, 4)
    stencil = jacobian_stencil(states, step)
    assert stencil_rows(2, step) == 5 * 4 and len(stencil) == 2 * 20
    # Every row is a motor state of its own (none answered from memory
    # instead of sensed), each within far less than the step of its row.
    assert len(np.unique(stencil, axis=0)) == len(stencil)
    base = jacobian_stencil(states, SymmetricStep(0.05)).reshape(2, 5, 1, 2)
    assert np.allclose(stencil.reshape(2, 5, 4, 2), base, atol=1e-10, rtol=0)


def test_an_averaged_jacobian_has_the_noise_of_one_over_its_repeats():
    m = np.array([0.3, -0.2])
    truth = SmoothBody().jacobian(m)
    errors = {}
    for name, step in (("single", SymmetricStep(0.02)), ("averaged", AveragedStep(0.02, 16))):
        body = ImperfectSensing(SmoothBody(), seed=3, noise=1e-3)
        _, jac, rows = sensory_jacobian(body, np.repeat(m[None], 200, axis=0), step)
        assert rows == 200 * stencil_rows(2, step)
        errors[name] = np.sqrt(np.mean((jac - truth) ** 2))
    # Truncation at 0.02 is ~1e-4 of the slopes: the noise dominates both.
    assert 3.0 < errors["single"] / errors["averaged"] < 5.3


def test_repeats_of_an_averaged_stencil_are_sensed_not_recalled():
    body = CountingBody(ImperfectSensing(SmoothBody(), seed=1, noise=1e-3), remember=True)
    m = np.array([[0.1, 0.2]])
    sensation, _, _ = sensory_jacobian(body, m, AveragedStep(0.02, 8))
    first = body.total_rows
    again, _, _ = sensory_jacobian(body, m, AveragedStep(0.02, 8))
    # The second call is answered from memory, bit for bit the same average.
    assert body.total_rows == first and np.array_equal(sensation, again)
    single, _, _ = sensory_jacobian(body, m, SymmetricStep(0.02))
    assert not np.array_equal(single, sensation)


def test_the_step_is_averaged_only_where_one_symmetric_difference_hides_the_weakest_direction():
    params = NaiveParams(fd_step=1e-6)
    for noise in (0.0, 1e-6, 1e-4):
        step = finite_difference_step(params, _structure(noise), 6)
        assert not isinstance(step, AveragedStep)
    loud = _structure(1e-3)
    step = finite_difference_step(params, loud, 6)
    assert isinstance(step, AveragedStep) and step.repeats > 1
    # Its noise is at most half the weakest singular value (what a rank test
    # at the Jacobian's noise then passes), its truncation as large.
    assert jacobian_noise(loud, 6, step) <= 0.5 * loud.weakest
    assert step ** 2 / 6.0 * loud.gain <= 0.5 * loud.weakest * (1 + 1e-9)
    # Capped by the budget of repeats.
    capped = finite_difference_step(NaiveParams(fd_step=1e-6, jacobian_max_repeats=2), loud, 6)
    assert capped.repeats == 2
    # Where one sensing per row would do at the averaged step's size, the
    # symmetric step as it was.
    assert not isinstance(finite_difference_step(params, _structure(3e-4), 6), AveragedStep)
    # Rounding (repeats that do not spread): never averaged.
    rounded = BodyStructure(n_motors=4, pose_rank=3, rank_gap=10.0, gain=0.8, floor=0.0,
                            votes=8, probes=8, noise=1e-3, fd_step=0.05, weakest=0.0133,
                            repeat_noise=0.0, quantum=3.5e-3)
    assert not isinstance(finite_difference_step(params, rounded, 6), AveragedStep)
    # 1: never averaged.
    assert not isinstance(finite_difference_step(
        NaiveParams(fd_step=1e-6, jacobian_max_repeats=1), loud, 6), AveragedStep)


def test_searches_are_held_to_the_averaged_noise_only_with_an_averaged_step():
    params = NaiveParams()
    loud = _structure(1e-3)
    assert averaged_search_params(params, loud, 6, SymmetricStep(0.05)) is params
    step = AveragedStep(0.2, 8)
    tight = averaged_search_params(params, loud, 6, step)
    # The quantile of the distance between an average of 8 and one sensing.
    distance = tight.lm_error_tol * loud.gain
    assert 1e-3 * np.sqrt(1.125) * 3 < distance < 1e-3 * np.sqrt(1.125) * 5
    assert noise_step(params, loud, step) < noise_step(params, loud)


def test_walk_corrections_keep_what_stands_out_of_the_noise_and_leave_the_rest():
    rng = np.random.default_rng(0)
    # Four joints, pose rank 3: the fourth joint is the level set's tangent.
    jac = np.repeat(np.diag([1.0, 0.5, 0.01, 0.0])[None], 2000, axis=0)
    noise = 1e-3
    residual = rng.normal(0.0, noise, (2000, 4))
    plain = minimum_norm_correction(jac, residual, 3)
    shrunk, _ = _correction_and_null(jac, residual, 3, np.full(2000, noise))
    # Pure noise: the weak direction's plain step is ~0.1, the shrunk one far less.
    assert np.median(np.abs(plain[:, 2])) > 0.05
    assert np.median(np.abs(shrunk[:, 2])) < 0.1 * np.median(np.abs(plain[:, 2]))
    # An offset well above the noise is corrected nearly in full.
    residual[:, 0] += 0.05
    shrunk, _ = _correction_and_null(jac, residual, 3, np.full(2000, noise))
    assert np.allclose(np.median(shrunk[:, 0]), -0.05, rtol=0.01)
    # Without noise the correction is the Gauss-Newton step, bit for bit.
    exact, _ = _correction_and_null(jac, residual, 3)
    assert np.array_equal(exact, minimum_norm_correction(jac, residual, 3))


def test_loop_samples_keep_a_smooth_offset_and_lose_most_of_the_noise():
    rng = np.random.default_rng(1)
    per_loop, noise = 99, 1e-3
    angle = 2 * np.pi * np.arange(per_loop) / per_loop
    # Jacobians turning smoothly along the loop (motor space rotated by the
    # angle), whose SVD vectors come with arbitrary signs.
    rotation = np.zeros((per_loop, 3, 3))
    rotation[:, 0, 0] = rotation[:, 1, 1] = np.cos(angle)
    rotation[:, 0, 1], rotation[:, 1, 0] = -np.sin(angle), np.sin(angle)
    rotation[:, 2, 2] = 1.0
    scale = np.zeros((4, 3))
    scale[0, 0], scale[1, 1], scale[2, 2] = 1.0, 0.5, 0.01
    jac = np.einsum("sk,bkm->bsm", scale, np.swapaxes(rotation, 1, 2))
    # Each sample off the level set by a smooth offset along the weak
    # direction and a sharper one along the strongest.
    offset = 0.1 * (1.0 + np.cos(angle))
    weak, strongest = rotation[:, :, 2], rotation[:, :, 0]
    motor = offset[:, None] * weak + 0.01 * np.sin(7 * angle)[:, None] * strongest
    residual = np.einsum("bsm,bm->bs", jac, motor) + rng.normal(0.0, noise, (per_loop, 4))
    plain = minimum_norm_correction(jac, residual, 3)
    smooth = loop_smoothed_correction(jac, residual, 3, noise, per_loop)
    plain_error = np.sqrt(np.mean(np.sum((plain + motor) ** 2, axis=1)))
    smooth_error = np.sqrt(np.mean(np.sum((smooth + motor) ** 2, axis=1)))
    # Three modes kept of 99 samples: ~sqrt(3 / 99) of the noise.
    assert plain_error > 0.07 and smooth_error < 0.4 * plain_error
    # The strong direction keeps its offset (noise 1e-3 there) as the plain step does.
    strong = np.einsum("bm,bm->b", strongest, smooth + motor)
    assert np.sqrt(np.mean(strong ** 2)) < 1e-3


def test_a_walk_steers_with_half_the_repeats_of_the_searches():
    from sensorispace_ros.core.naive.noise import walk_step
    step = walk_step(AveragedStep(0.2, 7))
    assert isinstance(step, AveragedStep) and step.repeats == 4 and float(step) == 0.2
    assert walk_step(AveragedStep(0.2, 1)).repeats == 1
    # Any other step is the walk's as it is.
    symmetric = SymmetricStep(0.05)
    assert walk_step(symmetric) is symmetric and walk_step(1e-6) == 1e-6
