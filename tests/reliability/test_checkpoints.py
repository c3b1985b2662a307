"""What the nodes persist for a restart (issue #7), without a graph: the body's
resting-state file, the environment's progress file, the publisher retry."""
from __future__ import annotations

import numpy as np

from sensorispace_ros.nodes.body import RestingStateFile


def test_resting_state_file_returns_the_last_state_saved_after_a_reopen(tmp_path):
    path = tmp_path / "body.state"
    assert RestingStateFile(path, 4).load() is None          # fresh file: nothing to resume
    written = RestingStateFile(path, 4)
    for k in range(5):
        written.save(np.array([k, -1.5, 2.2, -3.0]))
    reopened = RestingStateFile(path, 4)                      # a restarted body
    np.testing.assert_array_equal(reopened.load(), [4, -1.5, 2.2, -3.0])
    reopened.save(np.array([9.0, 9.0, 9.0, 9.0]))             # numbering goes on
    np.testing.assert_array_equal(RestingStateFile(path, 4).load(), [9.0, 9.0, 9.0, 9.0])


def test_resting_state_file_ignores_a_slot_torn_by_a_kill_mid_write(tmp_path):
    path = tmp_path / "body.state"
    state = RestingStateFile(path, 4)
    state.save(np.array([1.0, 1.0, 1.0, 1.0]))
    state.save(np.array([2.0, 2.0, 2.0, 2.0]))
    # a kill after the first sequence number and half the row of the next save
    torn = state.slots[(state.seq + 1) % 2]
    torn[0] = state.seq + 1
    torn[1:3] = 7.0
    np.testing.assert_array_equal(RestingStateFile(path, 4).load(), [2.0, 2.0, 2.0, 2.0])


def test_resting_state_file_of_another_size_is_started_afresh(tmp_path):
    path = tmp_path / "body.state"
    path.write_bytes(b"\x01" * 13)
    assert RestingStateFile(path, 4).load() is None
