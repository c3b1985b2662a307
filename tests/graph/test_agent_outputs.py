"""What the agent node publishes at the end of its run (graph/agent_outputs.py):
the POVs it moved, the sets its lattice implies, then the rows it withdraws
(no graph, fast)."""
from types import SimpleNamespace

import numpy as np

from sensorispace_ros import messages
from sensorispace_ros.graph.agent_outputs import done_totals, publish_end_of_run

POVS = np.arange(3 * 2 * 2, dtype=float).reshape(3, 2, 2)     # 3 POVs, 2 samples, 2 joints


def _agent(implied, withdrawn, moved=()):
    rows = (lambda r: (lambda: np.asarray(r, dtype=np.int64).reshape(-1, 3)))
    agent = SimpleNamespace(implied_rows=rows(implied), withdrawn_rows=rows(withdrawn),
                            points_of_view=POVS, relaxed_ids=np.asarray(moved, dtype=np.int64),
                            povs_relaxed=0)

    def relax_povs():
        agent.povs_relaxed = len(agent.relaxed_ids)
        return agent.povs_relaxed
    agent.relax_povs = relax_povs
    return agent


def _published(agent):
    sent = []

    def publish(topic, table, header):
        columns = ("set", "pov_from", "pov_to") if "set" in table else ("pov", "sample", "m0", "m1")
        sent.append((topic, header.frame_id, messages.stamp_ns(header),
                     np.column_stack([table[c] for c in columns]).tolist()))
    count = publish_end_of_run(agent, publish, messages.make_header("end/7", 1_234_567_890_123))
    return count, sent


def test_the_end_publishes_the_implied_rows_then_withdraws_the_dropped_ones():
    count, sent = _published(_agent([[5, 1, 2], [5, 3, 4]], [[0, 1, 3]]))
    assert count == 3
    assert sent == [("/agent/compensations", "end/7", 1_234_567_890_123, [[5, 1, 2], [5, 3, 4]]),
                    ("/agent/compensations", "withdrawn/7", 1_234_567_890_123, [[0, 1, 3]])]


def test_nothing_to_imply_or_withdraw_publishes_nothing():
    assert _published(_agent([], [])) == (0, [])
    count, sent = _published(_agent([], [[0, 1, 3], [2, 4, 5]]))
    assert count == 2 and [s[1] for s in sent] == ["withdrawn/7"]


def test_povs_moved_at_the_end_go_first_with_their_samples_now_and_are_counted():
    agent = _agent([[5, 1, 2]], [], moved=[0, 2])
    count, sent = _published(agent)
    assert count == 1
    topic, frame_id, _, rows = sent[0]
    assert (topic, frame_id) == ("/agent/points_of_view", "end/7")
    assert rows == [[0, 0, 0, 1], [0, 1, 2, 3], [2, 0, 8, 9], [2, 1, 10, 11]]
    assert sent[1][:2] == ("/agent/compensations", "end/7")
    agent.compensated, agent.queries_total, agent.calls_total = 1, 2, 3
    assert done_totals(agent, 7, 3, 1)["moved_povs"] == 2
