"""What an agent on a clock spends its rows on: simulation 2 senses a
bounded, seeded sample of the known POVs per change
(``clock_equality.AllPairsSweep``), and unconfirmed anchors are searched in a
share of the reactions that follows their success
(``ClockedAgent._unconfirmed_rate``)."""
import numpy as np
import pytest

from sensorispace_ros.core.naive.clock_equality import AllPairsSweep
from sensorispace_ros.core.naive.clocked_agent import ClockedAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.seeding import CounterStream


class ShiftedLine:
    """POVs on a line (one motor); the world is an offset of the object: POV
    ``x`` senses ``(x - offset, (x - offset)^2)``, so POV ``j'`` after a
    change senses what POV ``j`` sensed before exactly when ``j' - j`` is the
    change of the offset."""

    n_motors, n_sensors = 1, 2

    def __init__(self):
        self.offset = 0.0
        self.rows = 0

    def sense(self, states):
        u = np.asarray(states, float)[:, 0] - self.offset
        self.rows += len(u)
        return np.stack([u, u * u], axis=1)


def _sweep(body, budget, seed=0, count=40):
    povs = np.arange(count, dtype=float)[:, None, None]
    sweep = AllPairsSweep(body, povs, rank=1, fd_step=1e-6, match_tol=1e-6, separation=1e-3)
    sweep.history, sweep.budget = [], budget
    sweep.stream = CounterStream(seed, "naive.clock_equality")
    return sweep


def _replay(sweep, body, offsets):
    """Observe once per offset; per observe, the sets it added and the offsets before."""
    added = []
    for t, offset in enumerate(offsets):
        body.offset = float(offset)
        before_sets, before_rows = sweep.sets.n_sets, body.rows
        sweep.observe()
        rows = sweep.sets.rows_since(before_sets)
        added.append((rows, offsets[:t], body.rows - before_rows))
    return added


def test_each_sweep_senses_its_budget_and_each_set_is_one_displacement():
    rng = np.random.default_rng(3)
    offsets = rng.integers(0, 6, size=30)
    body = ShiftedLine()
    sweep = _sweep(body, budget=10)
    added = _replay(sweep, body, offsets)
    for ids, _, _ in sweep.history:
        assert len(ids) == 10 and len(np.unique(ids)) == 10
    # Fresh samples: the sweeps do not all sense the same POVs.
    assert len({tuple(ids) for ids, _, _ in sweep.history}) > 1
    found = 0
    for t, (rows, earlier, _) in enumerate(added):
        for set_id in np.unique(rows[:, 0]):
            shift = rows[rows[:, 0] == set_id, 2] - rows[rows[:, 0] == set_id, 1]
            # One displacement per set: the offset's change since some earlier sweep.
            assert np.all(shift == shift[0]) and shift[0] in offsets[t] - np.asarray(earlier)
            found += 1
    assert found > 0


def test_a_sweep_costs_its_budget_and_rank_tests_not_the_povs_known():
    rng = np.random.default_rng(4)
    offsets = rng.integers(0, 6, size=20)
    body = ShiftedLine()
    sweep = _sweep(body, budget=10, count=200)
    added = _replay(sweep, body, offsets)
    # Each observe: 10 rows sensed plus (M + 1) rows per rank test, at most one per row.
    assert all(rows <= 10 + 2 * 10 for _, _, rows in added)
    full = ShiftedLine()
    everything = _sweep(full, budget=0, count=200)
    _replay(everything, full, offsets)
    assert all(len(ids) == 200 for ids, _, _ in everything.history)
    assert body.rows < full.rows / 5


def test_the_same_seed_draws_the_same_samples():
    offsets = [0, 2, 1, 3]
    runs = []
    for seed in (5, 5, 6):
        body = ShiftedLine()
        sweep = _sweep(body, budget=8, seed=seed)
        _replay(sweep, body, offsets)
        runs.append([tuple(ids) for ids, _, _ in sweep.history])
    assert runs[0] == runs[1] and runs[0] != runs[2]


class _Store:
    def __init__(self, count):
        self.count = count


@pytest.mark.parametrize("min_rate", [1.0, 0.25])
def test_unconfirmed_anchors_follow_their_success(min_rate):
    agent = ClockedAgent.__new__(ClockedAgent)
    agent.params = NaiveParams(unconfirmed_max_povs=10, clock_unconfirmed_min_rate=min_rate)
    agent._store = _Store(50)
    searched = 0
    for _ in range(200):
        attempts = agent._anchor_params().unconfirmed_attempts
        searched += attempts
        # The reaction asks one unconfirmed anchor when allowed, never found.
        agent._spend_unconfirmed(attempts)
        for _ in range(attempts):
            agent._unconfirmed_found(False)
    if min_rate == 1.0:
        assert searched == 200                  # every reaction, as without the rate
    else:
        # Searched every reaction while they might succeed, then one in four.
        assert 200 * 0.25 <= searched <= 200 * 0.25 + 30
    # Fewer POVs than unconfirmed_max_povs: the lockstep agent's attempts.
    agent._store = _Store(5)
    assert agent._anchor_params().unconfirmed_attempts == agent.params.unconfirmed_attempts


class HalfLit(ShiftedLine):
    """``ShiftedLine`` whose object lights the side ``u > 0`` only: POVs on
    the dark side sense ``(0, 0)`` and have no full pose rank there."""

    def sense(self, states):
        lit = np.maximum(super().sense(states)[:, 0], 0.0)
        return np.stack([lit, lit * lit], axis=1)


def test_a_rank_test_senses_the_displaced_rows_only():
    from sensorispace_ros.core.naive.clock_equality import swept_rank
    from sensorispace_ros.core.naive.equality_sets import check_pose_rank

    body = HalfLit()
    body.offset = 10.5
    sweep = _sweep(body, budget=0)
    states = sweep.probe_states
    sensed = body.sense(states)
    before = body.rows
    full, rows = swept_rank(sweep, states, sensed)
    assert rows == len(states) == body.rows - before      # M = 1 row a state, not M + 1
    expected, _ = check_pose_rank(body, states, rank=1, fd_step=1e-6)
    assert np.array_equal(full, expected)
    assert full.any() and not full.all()


def test_rows_that_can_make_no_set_are_not_rank_tested():
    body = ShiftedLine()
    sweep = _sweep(body, budget=0, count=40)
    _replay(sweep, body, [0, 39])       # one match: POV 39 now senses what POV 0 did
    assert sweep.tested == 0 and sweep.sets.n_sets == 0
    body = ShiftedLine()
    sweep = _sweep(body, budget=0, count=40)
    _replay(sweep, body, [0, 37])       # three matches (one blank), a set: all tested
    assert sweep.tested == 3 and sweep.sets.n_sets == 1 and sweep.sets.n_pairs == 2
