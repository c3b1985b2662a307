"""POVs few sets tie, taken where their motor neighbours stand near their place."""
import numpy as np

from sensorispace_ros.core.naive.lattice_sets import lattice_equalities, pair_support
from sensorispace_ros.core.naive.motor_agreement import NEIGHBOURS, agreeing, lattice_spread

from test_lattice import _sets, _square_patch

PERIOD = 2.0 * np.pi


def loops(points: np.ndarray, offset: float = 1.0, samples: int = 40) -> np.ndarray:
    """``(P, samples, 3)`` closed loops on the torus of phases, one per
    integer position: the position's two coordinates (0.3 phase a step,
    bent a little along the loop), the loop's phase third."""
    phase = np.linspace(0.0, PERIOD, samples, endpoint=False)
    x = 0.3 * points[:, :1] + offset + 0.05 * np.sin(phase)
    y = 0.3 * points[:, 1:] + offset + 0.05 * np.cos(phase)
    return np.stack([x, y, np.broadcast_to(phase, x.shape)], axis=2) % PERIOD


def test_the_povs_nearest_in_motor_space_stand_a_step_from_each_other():
    points = _square_patch(0)
    spread = lattice_spread(loops(points), points, np.arange(len(points)),
                            np.arange(len(points)))
    assert np.all(np.isfinite(spread))
    assert np.median(spread) == 1 and spread.max() <= 2


def test_neighbours_across_the_wrap_of_a_phase_are_neighbours():
    # Positions -3..10 put the first columns' loops just below a phase of
    # 2 pi: they are next to those just above 0.
    points = _square_patch(1)
    samples = loops(points, offset=-0.3 * 3 + 0.1)
    assert (samples[..., 0] > 5.5).any() and (samples[..., 0] < 1.0).any()
    spread = lattice_spread(samples, points, np.arange(len(points)), np.arange(len(points)))
    assert spread.max() <= 2


def test_a_loose_pov_is_taken_at_its_place_and_refused_far_from_it():
    points = _square_patch(2)
    loose = len(points) // 2
    tied = np.ones(len(points), dtype=bool)
    tied[loose] = False
    candidates = ~tied
    samples = loops(points)
    assert agreeing(samples, points, tied, candidates)[loose]
    for shift in ([6, 0], [0, -7], [5, 5]):
        moved = points.copy()
        moved[loose] += shift
        assert not agreeing(samples, moved, tied, candidates).any()


def test_only_loose_povs_are_judged_and_too_few_tied_vouch_for_none():
    points = _square_patch(3)
    samples = loops(points)
    tied = np.ones(len(points), dtype=bool)
    assert not agreeing(samples, points, tied, tied).any()
    few = np.zeros(len(points), dtype=bool)
    few[:NEIGHBOURS] = True
    assert not agreeing(samples, points, few, ~few).any()


def _with_stray(points, seed: int):
    """Sets over ``points`` and one more POV in one pair of the first set:
    ``(pairs, ids, stray, its place)``."""
    pairs, ids = _sets(points, 300, seed)
    step = points[pairs[0, 1]] - points[pairs[0, 0]]
    stray = len(points)
    source = next(i for i in range(len(points))
                  if not (points == points[i] + step).all(axis=1).any())
    pairs = np.vstack([pairs, [[source, stray]]])
    ids = np.append(ids, ids[0])
    return pairs, ids, stray, points[source] + step


def test_the_implied_sets_take_a_stray_whose_loop_stands_at_its_place():
    points = _square_patch(4)
    pairs, ids, stray, place = _with_stray(points, 4)
    assert pair_support(pairs, ids, stray + 1)[stray] == 1
    right = loops(np.vstack([points, place]))
    taken = lattice_equalities(pairs, ids, stray + 1, support=2, samples=right)
    assert np.isin(stray, taken.pairs) and taken.usable == stray + 1
    far = loops(np.vstack([points, place + [0, 9]]))
    refused = lattice_equalities(pairs, ids, stray + 1, support=2, samples=far)
    assert not np.isin(stray, refused.pairs) and refused.usable == stray
    assert not np.isin(stray, lattice_equalities(pairs, ids, stray + 1, support=2).pairs)
