"""Which known POV a noisy agent's search end lies on, in motor space: a
pose on a known POV's loop is that POV, a POV the sensations name keeps an
end only when the end lies on its loop, and an end between loops is
neither that POV nor a new one."""
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial import cKDTree

from sensorispace_ros.core.naive.known_loops import APART, ON_LOOP, KnownLoops
from sensorispace_ros.core.naive.points_of_view import PovStore
from sensorispace_ros.core.naive.searching import SearchAndSample

SEPARATION = 0.4


def _circle(center, radius=0.2, n=16):
    angle = np.linspace(0, 2 * np.pi, n, endpoint=False)
    loop = np.zeros((n, 4))
    loop[:, 0], loop[:, 1] = radius * np.cos(angle), radius * np.sin(angle)
    return loop + center


class _Agent(SearchAndSample):
    """Loops of radius 0.2 centred 0.6 apart along joint 1, their measured
    separation ``SEPARATION``."""

    def __init__(self, noisy=True, count=10, pov_dim=1):
        self._noisy = noisy
        self.structure = SimpleNamespace(pov_dim=pov_dim)
        self.params = SimpleNamespace(pose_precision_povs=8, match_tol=1.0)
        self._store = PovStore(16, 4)
        for k in range(count):
            self._store.append(_circle(np.array([0, 0.6 * k - 3.0, 0, 0])))
        self._store.separation = lambda: SEPARATION
        self._fd_step = 0.01
        self._tol = SimpleNamespace(ratio=0.0, separation=1.0)


def _off_loop_2(distance):
    """A state ``distance`` off loop 2 (centre (0, -1.8)), across its plane."""
    return np.array([0.2, -1.8, distance, 0])


def test_a_noisy_agent_takes_a_pose_on_a_known_loop_for_that_pov():
    near, far = _off_loop_2(0.9 * ON_LOOP * SEPARATION), _off_loop_2(1.1 * ON_LOOP * SEPARATION)
    assert KnownLoops._walked_pose(_Agent(), near) == 2
    assert KnownLoops._walked_pose(_Agent(), far) == -1
    # Noiseless, with too few POVs to measure their separation, or POVs that
    # are not loops: nothing is taken for a known POV by motor distance.
    assert KnownLoops._walked_pose(_Agent(noisy=False), near) == -1
    assert KnownLoops._walked_pose(_Agent(count=5), near) == -1
    assert KnownLoops._walked_pose(_Agent(pov_dim=2), near) == -1


@pytest.mark.parametrize("share, kept", [(0.9 * ON_LOOP, True), (1.1 * ON_LOOP, False)])
def test_a_pov_the_sensations_name_keeps_only_a_state_on_its_loop(share, kept):
    assert _Agent()._on_known_loop(_off_loop_2(share * SEPARATION), 2) is kept
    # Where loops do not tell poses the sensations decide alone.
    assert _Agent(noisy=False)._on_known_loop(_off_loop_2(2 * SEPARATION), 2) is True


@pytest.mark.parametrize("share, between", [(0.9 * ON_LOOP, False), (1.1 * ON_LOOP, True),
                                            (0.9 * APART, True), (1.1 * APART, False)])
def test_a_state_between_a_loop_and_a_neighbours_distance_is_between_loops(share, between):
    assert _Agent()._placed_end(_off_loop_2(share * SEPARATION))[1] is between
    assert _Agent(noisy=False)._placed_end(_off_loop_2(share * SEPARATION))[1] is False


def test_a_solution_off_its_pov_is_a_new_pov_or_refused():
    # Every target senses exactly like known POV 2 now. Group 0 lies on POV
    # 2's loop; group 1 a separation away, on no known loop (a new POV);
    # group 2 on POV 4's loop (0.6 along joint 1 twice); group 3 between
    # loop 2 and a neighbour's distance: refused (-1, not walked).
    agent = _Agent()
    targets = np.zeros((4, 6))
    tree = cKDTree(np.r_[np.ones((2, 6)), np.zeros((1, 6)), np.ones((7, 6))])
    solution = {0: _off_loop_2(0.0), 1: _off_loop_2(SEPARATION),
                2: np.array([0.2, -0.6, 0.0, 0]), 3: _off_loop_2(0.4 * SEPARATION)}
    known, fresh = agent._known_solutions(solution, targets, np.ones(4), tree, np.zeros((0, 6)))
    assert known == {0: 2, 2: 4, 3: -1}
    assert fresh == [1]
    assert agent.ends_between_loops == 1
    # Noiseless, the sensation alone names POV 2 for every one of them.
    known, fresh = _Agent(noisy=False)._known_solutions(solution, targets, np.ones(4), tree,
                                                        np.zeros((0, 6)))
    assert known == {0: 2, 1: 2, 2: 2, 3: 2} and fresh == []
