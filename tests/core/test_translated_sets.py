"""Sets of segments inferred from the sets of changes
(``clock_equality.translated_sets``): a displacement carries every POV of
one set, so it carries the segments between them, and keeps their length."""
import numpy as np

from sensorispace_ros.core.naive.clock_equality import translated_sets
from sensorispace_ros.core.naive.clocked_agent import ClockedAgent
from sensorispace_ros.core.naive.equality_sets import EqualitySetCollection
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.seeding import CounterStream

GRID = np.array([(x, y) for x in range(6) for y in range(6)], dtype=float)


def _change_sets(shifts):
    """One set per shift: every POV ``j`` of the grid with ``j + shift`` on it."""
    index = {tuple(p): i for i, p in enumerate(GRID)}
    pairs, ids = [], []
    for k, shift in enumerate(shifts):
        for i, p in enumerate(GRID):
            j = index.get(tuple(p + shift))
            if j is not None:
                pairs.append((i, j))
                ids.append(k)
    return np.array(pairs), np.array(ids)


def test_each_set_of_segments_is_one_vector_and_covers_more_pairs_of_povs():
    pairs, ids = _change_sets([(1, 0), (0, 2), (2, 1)])
    more, more_ids = translated_sets(pairs, ids, len(GRID), per_set=1000,
                                     stream=CounterStream(0, "naive.clock_translated"))
    vectors = GRID[more[:, 1]] - GRID[more[:, 0]]
    for set_id in np.unique(more_ids):
        members = vectors[more_ids == set_id]
        assert len(members) >= 2 and np.all(members == members[0])
    slots = {tuple(sorted(p)) for p in pairs.tolist()}
    new = {tuple(sorted(p)) for p in more.tolist()} - slots
    assert len(new) > 5 * len(slots)


def test_a_set_of_changes_links_at_most_per_set_of_its_changes():
    pairs, ids = _change_sets([(1, 0)])
    few, _ = translated_sets(pairs, ids, len(GRID), per_set=2,
                             stream=CounterStream(0, "naive.clock_translated"))
    assert len(few) == 2            # one segment and its image
    again, _ = translated_sets(pairs, ids, len(GRID), per_set=2,
                               stream=CounterStream(3, "naive.clock_translated"))
    same, _ = translated_sets(pairs, ids, len(GRID), per_set=2,
                              stream=CounterStream(3, "naive.clock_translated"))
    assert np.array_equal(again, same)
    # The draw follows the seed: another seed links other changes.
    others = [translated_sets(pairs, ids, len(GRID), per_set=2,
                              stream=CounterStream(seed, "naive.clock_translated"))[0]
              for seed in range(4, 8)]
    assert any(not np.array_equal(again, o) for o in others)


def test_the_clocked_agent_adds_the_segment_sets_after_its_own():
    pairs, ids = _change_sets([(1, 0), (0, 1)])
    agent = ClockedAgent.__new__(ClockedAgent)
    agent._sets = EqualitySetCollection()
    for set_id in np.unique(ids):
        agent._sets.add(pairs[ids == set_id, 0], pairs[ids == set_id, 1])
    agent._store = type("Store", (), {"count": len(GRID), "samples": None})()
    agent.params = NaiveParams(clock_translated_pairs=0)
    plain, plain_ids = agent.equality_sets()
    assert np.array_equal(plain, pairs) and np.array_equal(plain_ids, ids)
    agent.params = NaiveParams(clock_translated_pairs=50)
    both, both_ids = agent.equality_sets()
    assert np.array_equal(both[:len(pairs)], pairs)
    assert both_ids[len(pairs):].min() == agent._sets.n_sets > 0
