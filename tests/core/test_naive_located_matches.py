"""Sweep matches verified against the noise of their rows (``confirm.verify_matches``):
a match a single sensing cannot pin is still located, and the matches of one
snapshot are tested together (``confirm.pooled_within_noise``)."""
from types import SimpleNamespace

import numpy as np
from scipy.stats import chi2

from sensorispace_ros.core.naive.anchors import Snapshot, SnapshotMatching
from sensorispace_ros.core.naive.confirm import pooled_within_noise, verify_matches
from sensorispace_ros.core.naive.jacobians import SymmetricStep
from sensorispace_ros.core.naive.params import NaiveParams

from imperfect_bodies import ImperfectSensing
from test_naive_noisy_jacobians import RankTwoBody, Shifted

TARGET_STATE = np.array([0.3, 0.2, -0.4])


def _verify(body, states, targets, target_sd, max_error):
    return verify_matches(body, states, targets, np.full(len(states), target_sd ** 2),
                          noise_sd=1e-4, repeats=4, rank=2, fd_step=SymmetricStep(0.02),
                          confidence=0.999, max_error=max_error, max_step=4 * max_error)


def test_a_match_one_sensing_cannot_pin_is_located_not_precise():
    # Each row sensed once at noise 1e-4: the weak coordinate (gain ~0.01
    # per output) is known to ~1e-2, so held to 1e-3 no match is precise;
    # the known POV is the pose the row sensed, and every match is located.
    exact = RankTwoBody()
    rows = ImperfectSensing(exact, seed=5, noise=1e-4).sense(np.repeat(TARGET_STATE[None], 40, 0))
    states = np.repeat(TARGET_STATE[None], 40, axis=0)
    precise, located = _verify(ImperfectSensing(exact, seed=6, noise=1e-4), states, rows, 1e-4,
                               1e-3)
    assert not precise.any()
    assert located.mean() >= 0.95
    # Held to what one sensing pins (a pose error of 1), most are precise too.
    precise, _ = _verify(ImperfectSensing(exact, seed=6, noise=1e-4), states, rows, 1e-4, 1.0)
    assert precise.mean() >= 0.9


def test_a_match_to_another_pose_is_not_located():
    # The strong coordinate a few hundredths away moves the outputs ~100
    # noise sds: no fresh average of that POV reproduces the row.
    exact = RankTwoBody()
    rows = ImperfectSensing(exact, seed=7, noise=1e-4).sense(np.repeat(TARGET_STATE[None], 20, 0))
    states = np.repeat((TARGET_STATE + [0.03, 0.0, 0.0])[None], 20, axis=0)
    _, located = _verify(ImperfectSensing(exact, seed=8, noise=1e-4), states, rows, 1e-4, 1.0)
    assert not located.any()


def test_the_snapshots_matches_together_show_a_shift_each_alone_hides():
    # Every match's sensation moved by an offset no pose change explains,
    # 1.7 noise sds of a match's residual: alone each passes the 0.999
    # quantile of chi-square(6) almost always; 200 together exceed theirs.
    exact = RankTwoBody()
    n = 200
    states = np.repeat(TARGET_STATE[None], n, axis=0)
    rows = ImperfectSensing(exact, seed=9, noise=1e-4).sense(states)
    jac = np.stack([(exact.sense((TARGET_STATE + 1e-6 * e)[None])
                     - exact.sense((TARGET_STATE - 1e-6 * e)[None]))[0] / 2e-6
                    for e in np.eye(3)], axis=1)
    offset = 1.7 * 1e-4 * np.sqrt(1.25) * np.linalg.svd(jac)[0][:, 3]
    shifted = ImperfectSensing(Shifted(exact, offset), seed=10, noise=1e-4)
    _, located = _verify(shifted, states, rows, 1e-4, 1.0)
    assert located.mean() <= 0.6
    _, located = _verify(ImperfectSensing(exact, seed=10, noise=1e-4), states, rows, 1e-4, 1.0)
    assert located.mean() >= 0.95


def test_the_pooled_test_keeps_all_or_none():
    rng = np.random.default_rng(11)
    statistic = rng.chisquare(6, 300)
    candidates = statistic <= chi2.ppf(0.999, 6)
    kept = pooled_within_noise(statistic, candidates, 6, 0.999)
    assert np.array_equal(kept, candidates)
    # Every statistic raised by 3 (a shared error, each alone within its
    # quantile): the sum exceeds the pooled quantile and none is kept.
    raised = statistic + 3.0
    passing = raised <= chi2.ppf(0.999, 6)
    assert passing.mean() > 0.95
    assert not pooled_within_noise(raised, passing, 6, 0.999).any()
    # A non-candidate is never kept.
    assert not pooled_within_noise(statistic, np.zeros(300, bool), 6, 0.999).any()


class _Staged:
    """A noisy body the agent may label with its stage."""

    n_motors, n_sensors = 3, 6

    def __init__(self, body):
        self.body, self.stage = body, None

    def sense(self, motor_states):
        return self.body.sense(motor_states)


def _matching_agent(repeats, noisy=True):
    """The parts of a NaiveAgent ``_verify_matches`` reads: 8 known POVs,
    one snapshot whose rows sensed them once, matches row k -> POV k; no
    discrepancy measured beyond the noise (``_discrepancy`` 0)."""
    exact = RankTwoBody()
    states = TARGET_STATE + np.outer(np.linspace(-0.2, 0.2, 8), [1.0, 0.0, 0.5])
    rows = ImperfectSensing(exact, seed=12, noise=1e-4).sense(states)
    snap = Snapshot(0, rows, np.ones(8, int), rows[0], states[0], 0, counts=np.ones(8, int))
    return SimpleNamespace(
        _noisy=noisy, _repeats=repeats, _pool=[snap], params=NaiveParams(),
        _store=SimpleNamespace(samples=states[:, None, :]),
        _body=_Staged(ImperfectSensing(exact, seed=13, noise=1e-4)),
        structure=SimpleNamespace(noise=1e-4, pose_rank=2), _fd_step=SymmetricStep(0.02),
        _max_pose_error=lambda: 1e-3, _pinning_floor=lambda: 0.0, _discrepancy=0.0,
        _note_verified=lambda *noted: None)


def test_the_agent_keeps_located_matches_only_where_repeats_spread():
    matches = [(np.arange(8), np.arange(8))]
    # Held to 1e-3 no row sensed once is precise; located, all are kept.
    (before, after), = SnapshotMatching._verify_matches(_matching_agent(4), matches)
    assert len(before) >= 7 and np.array_equal(before, after)
    # Where repeats do not spread (one sensing: the error repeats exactly)
    # only the precise test counts.
    (before, _), = SnapshotMatching._verify_matches(_matching_agent(1), matches)
    assert len(before) == 0
    # A noiseless agent keeps its matches untested.
    assert SnapshotMatching._verify_matches(_matching_agent(4, noisy=False), matches) is matches
