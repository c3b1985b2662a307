"""recording.completeness: a recording holds the agent's whole run when its POVs and
equality rows (first message of each frame id) add up to /agent/done's totals;
the marker beside the bag, and the wait for it."""
import threading
import time

import numpy as np
from rclpy.serialization import serialize_message

from sensorispace_ros import contracts, messages
from sensorispace_ros.core.body_description import BodyDescription
from sensorispace_ros.recording.completeness import (DONE, POVS, ROWS, RunCompleteness,
    marker_path, remove_marker, wait_for_complete_recording, write_marker)


PAPER_BODY = BodyDescription.revolute(4, 6)


def _cdr(topic: str, frame_id: str, table: dict, description=PAPER_BODY) -> bytes:
    return serialize_message(messages.table_to_cloud(
        table, contracts.contract(topic).columns_for(description),
        messages.make_header(frame_id, 1)))


def _povs(frame_id: str, ids, samples: int = 3, joints: int = 4) -> bytes:
    ids = np.asarray(ids)
    return _cdr(POVS, frame_id, {"pov": np.repeat(ids, samples),
                                 "sample": np.tile(np.arange(samples), len(ids)),
                                 **{f"m{j}": np.zeros(samples * len(ids)) for j in range(joints)}},
                BodyDescription.revolute(joints, 1))


def _rows(frame_id: str, n: int) -> bytes:
    return _cdr(ROWS, frame_id, {"set": np.zeros(n), "pov_from": np.zeros(n),
                                 "pov_to": np.ones(n)})


def _done(povs: int, rows: int, moved: int = 0) -> bytes:
    return _cdr(DONE, "end/9", {"changes": [9], "points_of_view": [povs],
                                "compensation_rows": [rows], "compensated": [1],
                                "queries": [1], "calls": [1], "moved_povs": [moved]})


def test_complete_only_once_povs_and_rows_add_up_to_the_agents_totals():
    run = RunCompleteness()
    assert not run.add(DONE, _done(povs=3, rows=5))       # the totals first (transient local)
    assert not run.add(POVS, _povs("change/1", [0, 1]))
    assert not run.add(ROWS, _rows("change/2", 2))
    assert not run.add(POVS, _povs("change/1", [0, 1]))   # a re-sent copy counts once
    assert not run.add(ROWS, _rows("change/2", 2))
    assert run.held == {"points_of_view": 2, "compensation_rows": 2, "moved_povs": 0}
    assert not run.add(POVS, _povs("change/3", [2]))
    assert run.add(ROWS, _rows("change/4", 3))            # now 3 POVs, 5 rows
    assert run.complete and run.held == run.totals
    assert not run.add(ROWS, _rows("change/5", 1))        # said once


def test_the_povs_of_a_body_of_any_size_are_counted():
    run = RunCompleteness()
    assert not run.add(DONE, _done(povs=3, rows=0))
    assert not run.add(POVS, _povs("change/1", [0], joints=2))
    assert run.add(POVS, _povs("change/2", [1, 2], joints=2))
    assert run.held == {"points_of_view": 3, "compensation_rows": 0, "moved_povs": 0}


def test_povs_moved_at_the_end_count_apart_and_withdrawn_rows_count_as_rows():
    run = RunCompleteness()
    assert not run.add(DONE, _done(povs=3, rows=4, moved=2))
    assert not run.add(POVS, _povs("change/1", [0, 1, 2]))
    assert not run.add(ROWS, _rows("change/2", 3))
    assert not run.add(ROWS, _rows("withdrawn/9", 1))
    assert run.held == {"points_of_view": 3, "compensation_rows": 4, "moved_povs": 0}
    assert run.add(POVS, _povs("end/9", [0, 2]))          # the moved POVs, not new ones
    assert run.held == {"points_of_view": 3, "compensation_rows": 4, "moved_povs": 2}


def test_without_the_agents_totals_nothing_is_complete():
    run = RunCompleteness()
    for k in range(3):
        run.add(POVS, _povs(f"change/{k}", [k]))
    assert not run.complete and run.totals is None
    assert not run.add("/agent/settled", b"\x00\x01\x00\x00")     # not a counted topic


def test_an_undecodable_message_counts_for_nothing():
    run = RunCompleteness()
    assert not run.add(POVS, b"\x00\x01\x00\x00 not a cloud")
    assert run.undecodable == 1 and run.held == {"points_of_view": 0, "compensation_rows": 0,
                                                     "moved_povs": 0}
    assert run.add(DONE, _done(povs=0, rows=0))               # an empty run is complete


def test_the_marker_sits_beside_the_bag_and_the_wait_ends_when_it_appears(tmp_path):
    bag = tmp_path / "bags" / "run1"
    bag.mkdir(parents=True)
    assert marker_path(bag) == tmp_path / "bags" / "run1.complete"
    assert wait_for_complete_recording(bag, timeout_s=0.2) is None          # timed out
    assert wait_for_complete_recording(bag, timeout_s=5.0, alive=lambda: False) is None

    def later():
        time.sleep(0.3)
        write_marker(bag, {"points_of_view": 4, "compensation_rows": 7})
    writer = threading.Thread(target=later)
    writer.start()
    waited = wait_for_complete_recording(bag, timeout_s=5.0)
    writer.join()
    assert waited is not None and 0.2 <= waited < 5.0
    assert marker_path(bag).read_text() == '{"points_of_view": 4, "compensation_rows": 7}'
    remove_marker(bag)
    remove_marker(bag)                                      # already gone: no error
    assert not marker_path(bag).exists() and bag.is_dir()
