"""The naive agent's pose rank under imperfections no parameter names: rank
probes averaged while what the rank leaves uncounted holds a direction the
averaging budget would count (``noise.averaged_structure``,
``structure.residual_could_count``), and clouds grown by the same rule where
the outputs are rounded (``noise.rounded_structure``)."""
import numpy as np
import pytest

from sensorispace_ros.core.naive.noise import measure_body
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.start import choose_start
from sensorispace_ros.core.naive.structure import BodyStructure, residual_could_count

from imperfect_bodies import ImperfectSensing


class FaintBody:
    """Six outputs (~0.5) of four joints through a pose of three: the pose is
    ``(m0 + m1, m1 - m2, m2 + m3)``, so one motor direction changes nothing
    (POV dimension 1); the third pose direction moves the outputs about
    ``faint`` times as much as the others (``faint`` 0: pose rank 2, POV
    dimension 2). Smooth at the scale of a phase radian, as the paper's eye."""

    n_motors, n_sensors = 4, 6

    def __init__(self, faint):
        self.faint = faint

    def sense(self, motor_states):
        m = np.asarray(motor_states, dtype=float)
        pose = np.column_stack([m[:, 0] + m[:, 1], m[:, 1] - m[:, 2], m[:, 2] + m[:, 3]])
        k = np.arange(1, 7)
        return 0.5 + 0.3 * np.sin(np.cos(k) * pose[:, :1] + np.cos(2 * k) * pose[:, 1:2]
                                  + self.faint * np.sin(3 * k) * pose[:, 2:] + k)


CENTER = np.array([0.3, -0.7, 0.2, 0.4])
BUDGET = NaiveParams().structure_max_repeats * 8 * (1 + 4 * 4)   # rows of the rank probes


class _Counted:
    def __init__(self, body):
        self.body, self.rows = body, 0
        self.n_motors, self.n_sensors = body.n_motors, body.n_sensors

    def sense(self, rows):
        self.rows += len(rows)
        return self.body.sense(rows)


def _measured(faint, seed=11, **imperfections):
    body = _Counted(ImperfectSensing(FaintBody(faint), seed=seed, **imperfections))
    structure, _ = measure_body(body, CENTER, NaiveParams())
    return structure, body.rows


@pytest.mark.parametrize("imperfections", [
    {"noise": 1e-3},
    {"laplace": 7e-4},                   # heavy tails
    {"motor_noise": 2e-3},               # errs along the Jacobian's range, not across it
    {"noise": 1e-3, "quantum": 1e-3, "motor_noise": 1e-3, "dropout": 1e-3},
], ids=["gaussian", "laplace", "motor", "combined"])
def test_a_faint_pose_direction_is_averaged_out_of_the_noise(imperfections):
    # The third direction (singular value ~0.005) lies under one sensing's
    # floor (~0.06 at the step the noise asks for): only averaged probes see it.
    structure, _ = _measured(0.02, **imperfections)
    assert (structure.pose_rank, structure.pov_dim) == (3, 1)
    assert structure.votes > structure.probes // 2


def test_a_direction_that_is_not_there_is_not_chased():
    # Pose rank 2: averaging stops once what the rank leaves uncounted is the
    # noise's, far below the budget.
    structure, rows = _measured(0.0, noise=1e-3)
    assert (structure.pose_rank, structure.pov_dim) == (2, 2)
    assert rows < BUDGET / 8


def test_a_fainter_direction_takes_more_sensings_within_the_budget():
    _, strong = _measured(0.1, noise=1e-3)
    structure, faint = _measured(0.02, noise=1e-3)
    assert structure.pose_rank == 3
    assert strong < faint <= BUDGET + 4096      # the noise measure's rows besides


def test_rounded_outputs_grow_their_clouds_until_the_faint_direction_counts():
    structure, _ = _measured(0.02, quantum=4e-3)
    assert structure.quantum == pytest.approx(4e-3)
    assert (structure.pose_rank, structure.pov_dim) == (3, 1)


def test_the_residual_of_pure_noise_counts_nothing_a_faint_direction_does():
    rng = np.random.default_rng(0)
    left = np.linalg.qr(rng.normal(size=(8, 6, 6)))[0]
    right = np.linalg.qr(rng.normal(size=(8, 4, 4)))[0]
    entry = 1e-3
    floor = np.full(8, entry * (np.sqrt(6) + 2))

    def jacobians(values):
        clean = np.einsum("bsi,i,bmi->bsm", left[:, :, :4], np.asarray(values), right)
        return clean + rng.normal(0, entry, clean.shape), rng.normal(0, entry, clean.shape)

    jac, noise = jacobians([1.0, 0.3, 0.0, 0.0])
    assert not residual_could_count(jac, noise, floor, 2, 4.0, 1.0)
    # 3 entry sds, under the floor (4.45): a floor a tenth of this one counts it,
    # this one does not (the budget spent).
    jac, noise = jacobians([1.0, 0.3, 3e-3, 0.0])
    assert residual_could_count(jac, noise, floor, 2, 4.0, 0.01)
    assert not residual_could_count(jac, noise, floor, 2, 4.0, 1.0)


def test_a_noisy_start_is_kept_when_some_probes_count_less():
    # Averaged probes that disagree see a direction fainter than their floor;
    # single sensings elsewhere could only see less: nothing is sensed.
    class Unsensed:
        def sense(self, rows):
            raise AssertionError("sensed")

    structure = BodyStructure(4, 3, 4.5, 0.6, 1e-3, votes=5, probes=8)
    start = np.zeros(4)
    kept, choice = choose_start(Unsensed(), start, structure, NaiveParams(), seed=0,
                                noise_sd=1e-3)
    assert kept is start and choice is None


@pytest.mark.parametrize("imperfections, receptors", [
    ({"noise": 1e-3}, 1e-3),
    ({"laplace": 7e-4}, 7e-4 * np.sqrt(2.0)),
    ({"motor_noise": 2e-3}, 0.0),
    ({"noise": 1e-3, "motor_noise": 2e-3}, 1e-3),
], ids=["gaussian", "laplace", "motor", "both"])
def test_the_receptors_part_of_the_noise_leaves_the_joints_error_out(imperfections, receptors):
    # A joint's error moves the sensation along the Jacobian's range; the
    # probes' repeats across it are the receptors' noise alone.
    structure, _ = _measured(1.0, **imperfections)
    if receptors:
        assert 0.8 * receptors < structure.receptor_noise < 1.25 * receptors
    else:
        assert structure.receptor_noise < 0.02 * structure.noise


def test_the_pinning_floor_stands_above_the_receptors_noise_alone():
    from types import SimpleNamespace

    from sensorispace_ros.core.naive.jacobians import SymmetricStep
    from sensorispace_ros.core.naive.noise import jacobian_noise
    from sensorispace_ros.core.naive.searching import _RECEPTOR_GAP, SearchAndSample

    step, params = SymmetricStep(0.05), NaiveParams()
    for imperfections, ratio in (({"noise": 1e-3}, _RECEPTOR_GAP), ({"motor_noise": 2e-3}, 1.0)):
        structure, _ = _measured(1.0, **imperfections)
        agent = SimpleNamespace(params=params, _repeats=16, _fd_step=step, structure=structure,
                                _body=SimpleNamespace(n_sensors=FaintBody.n_sensors))
        norm = jacobian_noise(structure, FaintBody.n_sensors, step)
        assert SearchAndSample._pinning_floor(agent) / norm == pytest.approx(ratio, rel=0.25)
