"""Hausdorff matrix over the periodic motor metric (paper Eq. hausdorff)."""
import numpy as np
import pytest
from scipy.spatial.distance import directed_hausdorff

from sensorispace_ros.core import hausdorff as hausdorff_module
from sensorispace_ros.core.hausdorff import (directed_hausdorff_pair, hausdorff_matrix,
    hausdorff_matrix_bruteforce, hausdorff_pair, motor_distance)

TWO_PI = 2 * np.pi


def literal_matrix(povs):
    """The paper's formula, arccos(cos(.)) and all, one pair at a time."""
    P = len(povs)
    out = np.zeros((P, P))
    for i in range(P):
        for j in range(P):
            diff = povs[i][:, None, :] - povs[j][None, :, :]
            d = np.sqrt(np.sum(np.arccos(np.cos(diff)) ** 2, axis=-1))
            out[i, j] = max(d.min(axis=1).max(), d.min(axis=0).max())
    return out


def closed_curves(rng, P, N, K=4, spread=20.0):
    """POV-like sets: smooth closed loops with centres spread over several 2 pi."""
    t = TWO_PI * np.arange(N) / N
    centre = rng.uniform(-spread, spread, size=(P, 1, K))
    amp = rng.uniform(0.2, 1.5, size=(P, 2, K))
    phase = rng.uniform(0, TWO_PI, size=(P, 1, K))
    return (centre + amp[:, :1] * np.cos(t[None, :, None] + phase)
            + amp[:, 1:] * np.sin(2 * t[None, :, None] + phase))


KERNELS = [
    "numpy",
    pytest.param("numba", marks=pytest.mark.skipif(not hausdorff_module.numba_available(),
                                                   reason="numba is not installed")),
]


@pytest.fixture(scope="module")
def random_sets():
    return np.random.default_rng(7).uniform(-4 * np.pi, 4 * np.pi, size=(11, 13, 4))


def test_motor_distance_is_periodic_and_bounded():
    a = np.array([0.1, -3.0, 2.0, 6.0])
    assert motor_distance(a, a + TWO_PI * np.array([1, -2, 3, 0])) == pytest.approx(0, abs=1e-12)
    # Each joint contributes at most pi: the farthest point is pi away per joint.
    assert motor_distance(np.zeros(4), np.full(4, np.pi)) == pytest.approx(2 * np.pi)
    assert motor_distance(np.zeros(4), np.full(4, np.pi + 0.3)) == pytest.approx(2 * (np.pi - 0.3))
    # Broadcasting over leading axes, same value as the arccos formula.
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-20, 20, size=(2, 5, 3, 4))
    expected = np.sqrt(np.sum(np.arccos(np.cos(x - y)) ** 2, axis=-1))
    np.testing.assert_allclose(motor_distance(x, y), expected, atol=1e-12)
    assert motor_distance(x, y[0, 0]).shape == (5, 3)


def test_matrix_equals_literal_arccos_formula(random_sets):
    expected = literal_matrix(random_sets)
    np.testing.assert_allclose(hausdorff_matrix(random_sets, block=3), expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(hausdorff_matrix_bruteforce(random_sets, block=4), expected,
                               rtol=0, atol=1e-12)


def test_pair_functions_match_literal(random_sets):
    A, B = random_sets[0], random_sets[1]
    expected = literal_matrix(random_sets[:2])[0, 1]
    assert hausdorff_pair(A, B) == pytest.approx(expected, abs=1e-12)
    assert hausdorff_pair(A, B) == max(directed_hausdorff_pair(A, B), directed_hausdorff_pair(B, A))


@pytest.mark.parametrize("kernel", KERNELS)
def test_fast_path_is_bitwise_the_brute_force(kernel):
    rng = np.random.default_rng(3)
    povs = closed_curves(rng, P=23, N=37)
    # Identical and nearly identical POVs make many exact ties for the screen.
    povs[5] = povs[4]
    povs[6] = povs[4] + 1e-7
    povs[7] = np.roll(povs[8], 5, axis=0) + TWO_PI
    fast = hausdorff_matrix(povs, block=4, kernel=kernel)
    brute = hausdorff_matrix_bruteforce(povs, block=5)
    assert np.array_equal(fast, brute)
    assert fast[4, 5] == 0.0
    assert np.array_equal(hausdorff_matrix(povs, block=7, n_jobs=2, kernel=kernel), brute)


def paper_like_loops(rng, P, N):
    """Translated, slightly deformed copies of one loop, sampled from random
    start points, with near-duplicates: most POV pairs are close relative to
    the loop length, as in the paper's POVs (where pruning matters)."""
    t = TWO_PI * np.arange(N) / N
    base = np.stack([np.cos(t), np.sin(t), np.cos(2 * t), np.sin(3 * t)], axis=-1) * 1.5
    shift = rng.uniform(-0.6, 0.6, size=(P, 1, 4))
    warp = 1.0 + rng.uniform(-0.05, 0.05, size=(P, 1, 4))
    povs = np.stack([np.roll(base, rng.integers(N), axis=0) for _ in range(P)]) * warp + shift
    povs[3] = povs[2] + 1e-9
    povs[4] = povs[2][::-1]                      # same set, other direction: H = 0
    povs[5] = povs[6] + TWO_PI * rng.integers(-2, 3, size=(1, 4))
    return povs


@pytest.mark.skipif(not hausdorff_module.numba_available(), reason="numba is not installed")
@pytest.mark.parametrize("n_jobs", [1, 2])
def test_compiled_kernel_is_bitwise_the_numpy_path_on_loops(n_jobs):
    povs = paper_like_loops(np.random.default_rng(12), P=70, N=60)
    compiled = hausdorff_matrix(povs, kernel="numba", n_jobs=n_jobs)
    reference = hausdorff_matrix(povs, kernel="numpy")
    assert np.max(np.abs(compiled - reference)) <= 1e-12      # the bar
    assert np.array_equal(compiled, reference)                # and in fact to the bit
    assert np.array_equal(reference, hausdorff_matrix_bruteforce(povs))
    assert compiled[2, 4] == 0.0 and compiled[2, 3] > 0.0


def test_pruned_rows_without_numba_equal_the_brute_force():
    """The kernel's algorithm itself (compiled or not): tiny input, every
    landmark/early-break/jump path taken."""
    povs = paper_like_loops(np.random.default_rng(4), P=20, N=12)
    R = np.ascontiguousarray(np.mod(povs, TWO_PI))
    brute = hausdorff_matrix_bruteforce(povs)
    for landmarks in (0, 4, 20):
        for n_jobs in (1, 2):
            assert np.array_equal(hausdorff_module._pruned_matrix(
                R, n_jobs=n_jobs, rows_per_task=3, landmarks=landmarks), brute)


@pytest.mark.parametrize("kernel", KERNELS)
def test_near_ties_below_the_screen_resolution_are_resolved_exactly(kernel):
    # The 16-bit screen cannot tell 1e-7 apart; the exact pass must.
    base = np.zeros((1, 4))
    A = np.array([[1.0, 0, 0, 0], [1.0 + 1e-7, 0, 0, 0], [1.0 - 1e-7, 0, 0, 0]])
    B = np.vstack([base, base, base])
    H = hausdorff_matrix(np.stack([A, B]), kernel=kernel)
    assert H[0, 1] == 1.0 + 1e-7


def test_symmetric_zero_diagonal_and_triangle_inequality():
    povs = closed_curves(np.random.default_rng(11), P=14, N=20)
    H = hausdorff_matrix(povs)
    assert np.array_equal(H, H.T)
    assert np.all(np.diag(H) == 0)
    assert np.all(H[~np.eye(14, dtype=bool)] > 0)
    triangle_gap = H[:, None, :] - (H[:, :, None] + H[None, :, :])   # H_ik - (H_ij + H_jk)
    assert triangle_gap.max() <= 1e-12


def test_invariant_to_whole_turns_of_any_joint():
    rng = np.random.default_rng(5)
    povs = closed_curves(rng, P=9, N=16)
    turns = rng.integers(-3, 4, size=povs.shape)
    np.testing.assert_allclose(hausdorff_matrix(povs + TWO_PI * turns), hausdorff_matrix(povs),
                               rtol=0, atol=1e-12)


def test_matches_scipy_when_no_difference_wraps():
    # Coordinates in [0, 3): every difference lies in (-pi, pi), the metric is Euclidean.
    povs = np.random.default_rng(2).uniform(0.0, 3.0, size=(6, 25, 4))
    H = hausdorff_matrix(povs)
    for i in range(6):
        for j in range(6):
            expected = max(directed_hausdorff(povs[i], povs[j])[0],
                           directed_hausdorff(povs[j], povs[i])[0])
            assert H[i, j] == pytest.approx(expected, abs=1e-12)


def test_other_shapes_and_progress():
    povs = closed_curves(np.random.default_rng(9), P=5, N=1, K=3)
    calls = []
    H = hausdorff_matrix(povs, block=2, kernel="numpy",
                         progress=lambda done, total: calls.append((done, total)))
    np.testing.assert_allclose(H, literal_matrix(povs), atol=1e-12)
    assert calls == [(1, 3), (2, 3), (3, 3)]
    calls.clear()
    assert np.array_equal(hausdorff_matrix(povs, progress=lambda *a: calls.append(a)), H)
    assert calls and calls[-1][0] == calls[-1][1]
    assert np.array_equal(hausdorff_matrix(povs[:1]), np.zeros((1, 1)))
    many_joints = closed_curves(np.random.default_rng(10), P=7, N=9, K=9)
    assert np.array_equal(hausdorff_matrix(many_joints), hausdorff_matrix_bruteforce(many_joints))


@pytest.mark.parametrize("bad, word", [
    (np.zeros((3, 4)), "shape"),
    (np.full((2, 3, 4), np.nan), "NaN"),
    (np.zeros((2, 3, 0)), "at least one"),
])
def test_bad_input_raises(bad, word):
    with pytest.raises(ValueError, match=word):
        hausdorff_matrix(bad)
    with pytest.raises(ValueError, match="block"):
        hausdorff_matrix(np.zeros((2, 3, 4)), block=0)


def test_unknown_kernel_raises(monkeypatch):
    with pytest.raises(ValueError, match="kernel"):
        hausdorff_matrix(np.zeros((2, 3, 4)), kernel="cuda")
    monkeypatch.setattr(hausdorff_module, "numba", None)
    with pytest.raises(ValueError, match="numba"):
        hausdorff_matrix(np.zeros((2, 3, 4)), kernel="numba")


# ---------------------------------------------- the growing matrix

needs_numba = pytest.mark.skipif(not hausdorff_module.numba_available(),
                                 reason="numba is not installed")


@needs_numba
@pytest.mark.parametrize("chunks", [[150], [1] * 5 + [40, 30, 1, 74], [63, 1, 1, 85],
                                    [10] * 15], ids=["one", "ragged", "landmarks", "tens"])
def test_growing_matrix_is_bitwise_the_whole_matrix(chunks):
    # More POVs than landmarks (64), added in batches that cross that boundary.
    povs = paper_like_loops(np.random.default_rng(5), P=sum(chunks), N=30)
    growing = hausdorff_module.GrowingHausdorffMatrix(30, 4)
    start = 0
    for size in chunks:
        growing.add(povs[start:start + size])
        start += size
    assert growing.count == len(povs)
    expected = hausdorff_matrix_bruteforce(povs)
    assert np.array_equal(growing.matrix(), expected)
    # Any order of the rows (the node sorts by POV id) is the whole matrix of
    # the POVs in that order.
    order = np.random.default_rng(1).permutation(len(povs))
    assert np.array_equal(growing.matrix(order), hausdorff_matrix_bruteforce(povs[order]))


@needs_numba
def test_growing_matrix_keeps_earlier_distances_and_checks_input():
    povs = paper_like_loops(np.random.default_rng(9), P=70, N=12)
    growing = hausdorff_module.GrowingHausdorffMatrix(12, 4)
    growing.add(povs[:40])
    first = growing.matrix()
    growing.add(povs[40:])
    assert np.array_equal(growing.matrix()[:40, :40], first)
    assert np.array_equal(first, hausdorff_matrix(povs[:40]))
    growing.add(povs[:0])                           # nothing to add
    assert growing.count == 70
    with pytest.raises(ValueError, match="shape"):
        growing.add(povs[:2, :11])
    bad = povs[:1].copy()
    bad[0, 3, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        growing.add(bad)
    with pytest.raises(ValueError, match="permutation"):
        growing.matrix(np.zeros(70, dtype=int))
    assert growing.count == 70
