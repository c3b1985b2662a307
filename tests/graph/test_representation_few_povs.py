"""The representation node with fewer points of view than a representation
needs (4): it writes its result file with the agent's outputs and the reason,
in the run directory named by /agent/done's stamp, and exits cleanly."""
from __future__ import annotations

import numpy as np

from sensorispace_ros import contracts, messages
from sensorispace_ros.core.body_description import BodyDescription
from sensorispace_ros.graph import in_process
from sensorispace_ros.graph.nodes.representation import RESULT_FILE, RepresentationNode

from shared import SMOKE

BODY = BodyDescription.revolute(2, 3)
END_STAMP_NS = 1_796_000_000_123_000_000        # 2026-11-30 00:53:20.123 UTC


def _table(topic, frame_id, stamp_ns=0, **columns):
    return messages.table_to_cloud(columns, contracts.contract(topic).columns_for(BODY),
                                   messages.make_header(frame_id, stamp_ns))


def test_three_povs_give_a_result_with_the_reason_and_a_clean_exit(context, tmp_path):
    node = RepresentationNode(context=context, parameter_overrides=in_process.parameter_overrides(
        SMOKE, {"graph.results_dir": str(tmp_path / "{run}")}))
    try:
        node.on_description(messages.description_to_msg(BODY))
        node.on_points_of_view(_table("/agent/points_of_view", "change/0",
                                      pov=np.repeat([0, 1, 2], 2), sample=np.tile([0, 1], 3),
                                      m0=np.arange(6.0), m1=np.arange(6.0)))
        node.on_done(_table("/agent/done", "end/5", END_STAMP_NS, changes=np.array([5]),
                            points_of_view=np.array([3]), compensation_rows=np.array([0]),
                            compensated=np.array([1]), queries=np.array([10]),
                            calls=np.array([2]), moved_povs=np.array([0])))
        node.worker.join(timeout=60)
        assert node.finished and node.exit_code == 0
        [written] = tmp_path.glob(f"run-*/{RESULT_FILE}")
        assert written.parent.name.endswith("-123")      # the end stamp's milliseconds
        with np.load(written) as stored:
            assert str(stored["reason"]) == "3 points of view: a representation needs at least 4"
            assert list(stored["pov_ids"]) == [0, 1, 2] and stored["povs"].shape == (3, 2, 2)
            assert int(stored["agent_changes"]) == 5 and "hausdorff" not in stored
    finally:
        node.destroy_node()


def test_moved_povs_replace_their_samples_and_withdrawn_rows_leave(context, tmp_path):
    # What the agent sends at the end of its run: POV 1 moved (end/5), the
    # implied set (end/5) and one found row withdrawn (withdrawn/5). The node
    # waits for the moved POV /agent/done announces, then builds from the
    # moved samples and the rows left.
    node = RepresentationNode(context=context, parameter_overrides=in_process.parameter_overrides(
        SMOKE, {"graph.results_dir": str(tmp_path / "{run}")}))

    def rows(frame_id, *triples):
        triples = np.array(triples)
        node.on_compensations(_table("/agent/compensations", frame_id, set=triples[:, 0],
                                     pov_from=triples[:, 1], pov_to=triples[:, 2]))
    try:
        node.on_description(messages.description_to_msg(BODY))
        node.on_points_of_view(_table("/agent/points_of_view", "change/0",
                                      pov=np.repeat([0, 1, 2], 2), sample=np.tile([0, 1], 3),
                                      m0=np.arange(6.0), m1=np.arange(6.0)))
        rows("change/1", (0, 0, 1), (0, 1, 2), (1, 0, 2))
        rows("end/5", (2, 0, 1))
        rows("withdrawn/5", (0, 1, 2))
        node.on_done(_table("/agent/done", "end/5", END_STAMP_NS, changes=np.array([5]),
                            points_of_view=np.array([3]), compensation_rows=np.array([5]),
                            compensated=np.array([1]), queries=np.array([10]),
                            calls=np.array([2]), moved_povs=np.array([1])))
        assert node.worker is None                      # the moved POV is still in flight
        node.on_points_of_view(_table("/agent/points_of_view", "end/5", pov=np.array([1, 1]),
                                      sample=np.array([0, 1]), m0=np.array([9.0, 9.5]),
                                      m1=np.array([8.0, 8.5])))
        node.worker.join(timeout=60)
        assert node.finished and node.exit_code == 0
        [written] = tmp_path.glob(f"run-*/{RESULT_FILE}")
        with np.load(written) as stored:
            np.testing.assert_array_equal(stored["povs"][1], [[9.0, 8.0], [9.5, 8.5]])
            np.testing.assert_array_equal(stored["povs"][[0, 2]], [[[0, 0], [1, 1]],
                                                                   [[4, 4], [5, 5]]])
            assert stored["pairs"].tolist() == [[0, 1], [0, 2], [0, 1]]
            assert stored["set_ids"].tolist() == [0, 1, 2]
    finally:
        node.destroy_node()


def test_a_second_run_gets_a_directory_of_its_own():
    from pathlib import Path

    from sensorispace_ros.protocol import run_directory

    first = run_directory("results/graph/{run}", END_STAMP_NS)
    second = run_directory("results/graph/{run}", END_STAMP_NS + 1_000_000)
    assert first.parent == second.parent == Path("results/graph") and first != second
    assert first.name == "run-20261130-005320-123"
    assert run_directory("results/mine", END_STAMP_NS) == Path("results/mine")
