"""The naive agent on bodies that round their outputs to a step no
parameter names: the lattice it measures, Jacobians fitted over clouds of
states (``CloudStep``), and the structure they give where one sensing per
state hides the weakest pose direction; a search's end refined until what
is left of its pose error is the rounding's."""
import pickle
from types import SimpleNamespace

import numpy as np
import pytest

from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.jacobians import (CloudStep, SymmetricStep, jacobian_stencil,
                                                   sensory_jacobian, stencil_rows)
from sensorispace_ros.core.naive.noise import measure_body, measure_noise
from sensorispace_ros.core.naive.noise_spread import output_lattice
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.searching import SearchAndSample
from sensorispace_ros.core.naive.sense_memory import CountingBody
from sensorispace_ros.core.paper.exploration import build_world

from imperfect_bodies import ImperfectSensing, SmoothBody



CENTER = np.array([0.3, -0.7])


@pytest.mark.parametrize("quantum", [3.7e-3, 2.5e-4, 1.0])
def test_the_lattice_of_rounded_outputs_is_its_step(quantum):
    # Outputs ~0.5, or ~128 for a step of 1 (the gray levels of an image).
    scale = 255.0 if quantum == 1.0 else 1.0
    body = ImperfectSensing(_Scaled(SmoothBody(), scale), seed=1, quantum=quantum)
    noise = measure_noise(body, CENTER)
    assert noise.quantum == pytest.approx(quantum, rel=1e-6)
    assert noise.rounded
    assert noise.sd == pytest.approx(quantum / np.sqrt(12.0))


@pytest.mark.parametrize("imperfections", [{}, {"float32": True}, {"noise": 1e-6}],
                         ids=["float64", "float32", "gaussian"])
def test_no_lattice_where_the_outputs_are_not_rounded_to_a_step(imperfections):
    noise = measure_noise(ImperfectSensing(SmoothBody(), seed=1, **imperfections), CENTER)
    assert noise.quantum == 0.0 and not noise.rounded


def test_a_lattice_needs_every_gap_a_whole_multiple_of_the_smallest():
    rows = np.array([[0.0], [0.1], [0.25], [0.37], [0.5]])
    assert output_lattice(rows) == 0.0
    assert output_lattice(rows.round(1)) == pytest.approx(0.1)


def test_a_cloud_jacobian_of_a_smooth_body_is_its_jacobian():
    body = SmoothBody()
    step = CloudStep(0.01, 64, 2)
    sensation, jac, rows = sensory_jacobian(body, CENTER[None], step)
    assert rows == stencil_rows(2, step) == 129
    assert np.allclose(sensation[0], body.sense(CENTER[None])[0], atol=1e-6)
    assert np.allclose(jac[0], body.jacobian(CENTER), atol=2e-3)    # third order: step^2
    assert pickle.loads(pickle.dumps(step)).pairs == 64
    # The state itself is the stencil's first row; its mirror pairs follow.
    stencil = jacobian_stencil(CENTER[None], step)
    assert np.array_equal(stencil[0], CENTER)
    assert np.allclose(stencil[1:65] + stencil[65:], 2 * CENTER)


def test_a_cloud_fit_averages_rounding_that_repeats_cannot():
    # Rounded to 1e-2 (outputs ~0.5): a central difference at 0.05 errs by
    # up to 0.1 per entry (0.095 here); the fit over 1,025 states by far less.
    body = ImperfectSensing(SmoothBody(), seed=1, quantum=1e-2)
    true = SmoothBody().jacobian(CENTER)
    _, jac, _ = sensory_jacobian(body, CENTER[None], CloudStep(0.05, 512, 2))
    _, central, _ = sensory_jacobian(body, CENTER[None], SymmetricStep(0.05))
    assert np.max(np.abs(jac[0] - true)) < 0.2 * np.max(np.abs(central[0] - true))


class _Scaled:
    def __init__(self, body, scale):
        self.body, self.scale = body, scale
        self.n_motors, self.n_sensors = body.n_motors, body.n_sensors

    def sense(self, rows):
        return self.scale * self.body.sense(rows)


@pytest.mark.parametrize("start,quantum", [("grid", 1e-5), ("grid", 1e-4), ("center", 2.7e-3)])
def test_a_rounding_body_measures_its_pose_rank(start, quantum):
    # The smoke-sized world's grid start senses its third pose direction
    # faintly (third singular value 0.001-0.003 of ~1): one sensing per
    # stencil row, rounded to 1e-5, measures pose rank 2 there. The
    # centred start's third is 0.02-0.1: rounding to 2.7e-3 hides it.
    world = build_world(0, {"grid_count": 16, "initial_center": start})
    body = ImperfectSensing(world.body(lights=world.initial_lights), seed=5, quantum=quantum)
    agent = NaiveAgent(body, NaiveParams())
    start = agent._phase.to_phase(world.m0)
    structure, params = measure_body(agent._body, start, NaiveParams())
    assert (structure.pose_rank, structure.pov_dim) == (3, 1)
    assert structure.noise == pytest.approx(quantum / np.sqrt(12.0), rel=1e-6)
    assert structure.metrics()["naive.noise_quantum"] == pytest.approx(quantum, rel=1e-6)


# The second joint moves the outputs ~40 times less than the first (singular
# values; the paper eye's position against its orientation).
_WEAK_SECOND = 0.15


def test_a_rounded_search_end_is_refined_until_its_step_is_rounding():
    # Rounded outputs repeat exactly, yet each refined state rounds anew: the
    # rounds of Gauss-Newton steps go on until the residual in range is what
    # the rounding explains. One step accepted whatever its residual (the
    # single-difference Jacobian's noise hides the weak joint) leaves ends
    # several of the rounding's standard deviations off along it.
    quantum, rng = 1e-3, np.random.default_rng(0)
    sd = quantum / np.sqrt(12.0)
    truth = rng.uniform(-1.0, 1.0, (200, 2))
    weak_offsets = rng.choice([-1.0, 1.0], 200) * rng.choice([0.1, 0.3], 200)
    starts = truth + np.c_[np.zeros(200), weak_offsets]
    targets = ImperfectSensing(SmoothBody(_WEAK_SECOND), quantum=quantum).sense(truth)
    body = ImperfectSensing(SmoothBody(_WEAK_SECOND), seed=1, quantum=quantum)
    agent = SimpleNamespace(
        _body=CountingBody(body, remember=False),
        _repeats=1, _fd_step=SymmetricStep(0.02), _max_pose_error=lambda: np.inf,
        structure=SimpleNamespace(noise=sd, quantum=quantum, pose_rank=2),
        params=SimpleNamespace(noise_confidence=0.999, confirm_rounds=3))
    agent._pinning_floor = lambda: SearchAndSample._pinning_floor(agent)
    kept = SearchAndSample._confirm(agent, dict(enumerate(starts)), targets,
                                    dict.fromkeys(range(200), 1))
    assert len(kept) >= 20
    for g, state in kept.items():
        # The weak joint's error one sensing of the end and of the target pin.
        jacobian = SmoothBody(_WEAK_SECOND).jacobian(truth[g])
        weakest = np.linalg.svd(jacobian, compute_uv=False)[-1]
        assert abs(state[1] - truth[g, 1]) <= 5.0 * np.sqrt(2.0) * sd / weakest
