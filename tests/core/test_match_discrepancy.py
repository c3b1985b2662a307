"""What matched POVs differ by beyond their noise, measured from clear pairs."""
import numpy as np
from scipy.stats import chi2

from sensorispace_ros.core.naive import equality_sets
from sensorispace_ros.core.naive.match_discrepancy import (clear_pairs, match_discrepancy,
    sweep_discrepancy)

N_SENSORS = 6


def _sweeps(rng, n_rows, sd, tau):
    """A snapshot's rows (one sensing each) and a sweep of the same poses
    in another order, each row off by the noise of two sensings plus a pose
    discrepancy of per-receptor sd ``tau``."""
    truth = rng.uniform(0.0, 1.0, (n_rows, N_SENSORS))
    order = rng.permutation(n_rows)
    reference = truth + rng.normal(0.0, sd, truth.shape)
    current = truth[order] + rng.normal(0.0, np.hypot(sd, tau), truth.shape)
    return reference, current, order


def _measured(seed, n_rows, sd, tau):
    """``_sweeps`` and the discrepancy measured from their clear pairs."""
    reference, current, order = _sweeps(np.random.default_rng(seed), n_rows, sd, tau)
    ref, cur = clear_pairs(reference, current)
    differences = reference[ref] - current[cur]
    return reference, current, order, differences, match_discrepancy(
        differences, np.full(len(ref), 2 * sd ** 2))


def test_clear_pairs_are_mutual_nearest_rows_far_from_every_other():
    rng = np.random.default_rng(2)
    reference, current, order = _sweeps(rng, 50, 1e-4, 3e-4)
    # Row 0's pose has a second current row as near as its own: not clear.
    current = np.vstack([current, reference[0] + 2e-4])
    # Row 1 is lost on the reference side, row 2's partner on the current side.
    reference[1, 3] = np.nan
    current[np.flatnonzero(order == 2)[0], 0] = np.inf
    ref, cur = clear_pairs(reference, current)
    pairs = dict(zip(ref.tolist(), cur.tolist()))
    assert {0, 1, 2}.isdisjoint(pairs)
    assert all(order[j] == i for i, j in pairs.items())
    assert len(pairs) == 47


def test_the_discrepancy_puts_clear_pairs_at_the_chi_square_median():
    sd, tau = 1e-4, 4e-4
    *_, differences, measured = _measured(7, 400, sd, tau)
    assert 0.8 * tau ** 2 < measured < 1.25 * tau ** 2
    # The defining property, on the pairs it was measured from.
    statistic = np.sum(differences ** 2, axis=1) / (2 * sd ** 2 + measured)
    assert abs(np.median(statistic) - chi2.median(N_SENSORS)) < 1e-3 * chi2.median(N_SENSORS)


def test_no_excess_and_too_few_pairs_measure_nothing():
    sd = 1e-4
    reference, current, order, _, measured = _measured(8, 400, sd, 0.0)
    # Noise alone: the median statistic lies at or below chi-square's (the
    # estimate is 0, or a sliver of the noise where the draw ran high).
    assert measured < 0.2 * sd ** 2
    few = reference[:7] - current[np.argsort(order)[:7]] + 1.0
    assert match_discrepancy(few, np.full(7, sd ** 2)) == 0.0


def test_matches_refused_against_the_noise_are_made_with_the_discrepancy():
    sd, tau = 1e-4, 5e-4
    reference, current, order, _, tau2 = _measured(9, 200, sd, tau)
    alone = equality_sets.match_counted(reference, current, noise_sd=sd, confidence=0.999)
    widened = equality_sets.match_counted(reference, current, noise_sd=sd, confidence=0.999,
                                          discrepancy=tau2)
    assert len(alone[0]) < 40
    assert len(widened[0]) > 180
    assert all(order[j] == i for i, j in zip(*widened))



def test_a_sweep_pools_the_clear_pairs_of_every_snapshot():
    from types import SimpleNamespace
    rng = np.random.default_rng(10)
    sd, tau = 1e-4, 4e-4
    truth = rng.uniform(0.0, 1.0, (300, N_SENSORS))
    current = truth + rng.normal(0.0, np.hypot(sd, tau), truth.shape)
    # Single sensings of the first 150 poses; 16-sensing means of the others
    # (a sixteenth of the noise variance), behind 150 lost rows.
    single = truth[:150] + rng.normal(0.0, sd, (150, N_SENSORS))
    means = np.vstack([np.full((150, N_SENSORS), np.nan),
                       truth[150:] + rng.normal(0.0, sd / 4, (150, N_SENSORS))])
    pool = [SimpleNamespace(sensations=single, counts=None),
            SimpleNamespace(sensations=means, counts=np.full(300, 16))]
    measured = sweep_discrepancy(pool, current, sd)
    assert 0.8 * tau ** 2 < measured < 1.25 * tau ** 2
    # One snapshot alone measures it too; the lost rows pair nothing.
    alone = sweep_discrepancy(pool[:1], current, sd)
    assert 0.75 * tau ** 2 < alone < 1.3 * tau ** 2
    assert sweep_discrepancy([], current, sd) == 0.0
