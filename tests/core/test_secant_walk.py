"""The secant loop walk (core/naive/secant_walk.py): a stencil every few
calls, Broyden's update and the chord's tangent in between."""
import numpy as np
import pytest

from sensorispace_ros import config
from sensorispace_ros.core.naive import clock_walks, points_of_view
from sensorispace_ros.core.naive.clocked_agent import ClockedAgent
from sensorispace_ros.core.naive.jacobians import VALID
from sensorispace_ros.core.naive.secant_walk import SecantLoopWalk, _chord_tangent, secant_update

from test_clocked_walk import SMOKE, _walks


def test_the_secant_update_maps_the_step_to_its_residual_and_keeps_the_rest():
    rng = np.random.default_rng(0)
    jac, step, residual = rng.normal(size=(5, 7, 4)), rng.normal(size=(5, 4)), rng.normal(size=(5, 7))
    updated = secant_update(jac, step, residual)
    np.testing.assert_allclose(np.einsum("bsm,bm->bs", updated, step), residual, atol=1e-12)
    across = rng.normal(size=(5, 4))
    across -= (np.sum(across * step, axis=1) / np.sum(step * step, axis=1))[:, None] * step
    np.testing.assert_allclose(np.einsum("bsm,bm->bs", updated, across),
                               np.einsum("bsm,bm->bs", jac, across), atol=1e-12)


def test_a_zero_step_leaves_the_jacobian():
    jac = np.ones((1, 3, 2))
    np.testing.assert_array_equal(secant_update(jac, np.zeros((1, 2)), np.ones((1, 3))), jac)


def test_the_chords_tangent_is_exact_on_a_circle_and_the_jacobians_null_vector():
    rng = np.random.default_rng(1)
    plane = np.linalg.qr(rng.normal(size=(4, 2)))[0].T              # a circle in a plane of R^4
    near, far = np.array([0.3, -1.2]), np.array([0.9, 0.1])         # angles of the chord's ends

    def point(a):
        return 2.0 * (np.cos(a)[:, None] * plane[0] + np.sin(a)[:, None] * plane[1])

    def tangent(a):
        return -np.sin(a)[:, None] * plane[0] + np.cos(a)[:, None] * plane[1]

    jac = rng.normal(size=(2, 6, 4))
    found, nulled = _chord_tangent(point(far) - point(near), tangent(near), jac)
    np.testing.assert_allclose(found, tangent(far), atol=1e-12)
    np.testing.assert_allclose(np.einsum("bsm,bm->bs", nulled, found), 0.0, atol=1e-12)
    # A degenerate chord keeps the near tangent.
    kept, _ = _chord_tangent(np.zeros((2, 4)), tangent(near), jac)
    np.testing.assert_array_equal(kept, tangent(near))


class _Rings:
    """Two joints sensing only their distance from the origin: the level sets
    are circles (a 1-D POV per radius)."""
    n_motors, n_sensors = 2, 3

    def __init__(self):
        self.rows = 0

    def sense(self, motors):
        motors = np.asarray(motors, dtype=float)
        self.rows += len(motors)
        r = np.linalg.norm(motors, axis=1)
        return np.stack([r, r * r, np.sin(2.0 * r)], axis=1)


def _ring_walk(secant_calls, noise_sd=0.0):
    body = _Rings()
    walked = points_of_view.brief_loop_walks(
        body, np.array([[1.0, 0.0]]), rank=1, n_samples=100, fd_step=1e-6, initial_step=0.05,
        min_step=1e-3, max_step=0.1, predictor_tol=4e-3, max_queries=20_000, closure_tol=0.05,
        checks=(1e-3, 1e-9, 0.0), knots_per_step=1, checked_samples=12, noise_sd=noise_sd,
        secant_calls=secant_calls)
    return walked, body.rows


def test_the_secant_walk_stays_on_the_ring_for_fewer_rows():
    (every, every_rows), (secant, secant_rows) = _ring_walk(1), _ring_walk(3)
    assert every.reason[0] == VALID and secant.reason[0] == VALID
    assert secant_rows < 0.6 * every_rows
    radius = np.linalg.norm(secant.samples[0], axis=1)
    assert np.max(np.abs(radius - 1.0)) < 1e-3
    # The whole ring: samples all round it.
    angles = np.sort(np.arctan2(secant.samples[0, :, 1], secant.samples[0, :, 0]))
    assert np.max(np.diff(np.concatenate([angles, [angles[0] + 2 * np.pi]]))) < 0.2


def test_a_noisy_walk_senses_every_stencil():
    # The secant update would take noise over a knot interval for slope.
    (every, every_rows), (secant, secant_rows) = _ring_walk(1, 1e-9), _ring_walk(3, 1e-9)
    assert secant_rows == every_rows
    np.testing.assert_array_equal(secant.samples, every.samples)


def test_refresh_calls_below_one_is_refused():
    with pytest.raises(ValueError, match="refresh_calls"):
        SecantLoopWalk(_Rings(), np.array([[1.0, 0.0]]), refresh_calls=0, rank=1, fd_step=1e-6,
                       min_step=1e-3, max_step=0.3, predictor_tol=4e-3, max_queries=100,
                       min_loop_length=0.3, knots_per_step=1, closure_tol=0.05)


def test_the_clocked_agents_secant_walk_gives_its_pov_on_the_level_set():
    world, ((_, every, every_rows), (agent, secant, secant_rows)) = _walks(
        (ClockedAgent, ClockedAgent),
        walk_overrides=({"clock_pov_secant_calls": 1}, {"clock_pov_secant_calls": 3}))
    assert secant_rows < 0.6 * every_rows
    sensed = world.body(lights=world.initial_lights).sense(agent._phase.to_body(secant))
    assert np.max(np.abs(sensed - sensed[0])) < 1e-3 * np.max(np.abs(sensed[0]))
    gap = (every[:, None, :] - secant[None, :, :] + np.pi) % (2 * np.pi) - np.pi
    distance = np.linalg.norm(gap, axis=2)
    spacing = np.median(np.linalg.norm(np.diff(every, axis=0), axis=1))
    assert max(distance.min(axis=0).max(), distance.min(axis=1).max()) < 0.1 * spacing


def test_clock_pov_secant_calls_is_checked_at_start_up():
    with pytest.raises(config.ConfigError, match=r"naive\.clock_pov_secant_calls"):
        config.load_config(SMOKE, {"naive.clock_pov_secant_calls": 0})


def test_an_agent_whose_noise_sized_its_tolerances_keeps_every_stencil(monkeypatch):
    _, ((agent, samples, _),) = _walks((ClockedAgent,),
                                       walk_overrides=({"clock_pov_secant_calls": 3},))
    asked = []
    walk = clock_walks.brief_loop_walks
    monkeypatch.setattr(clock_walks, "brief_loop_walks",
                        lambda *a, **k: asked.append(k["secant_calls"]) or walk(*a, **k))
    for noisy in (False, True):
        agent._noisy = noisy
        with agent._body.fresh():
            agent._walk_povs(samples[:1])
    assert asked == [3, 1]
