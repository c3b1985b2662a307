"""The body's resting-state file: the bytes ``save`` writes (two seqlocked slots
of native float64, ``[seq, values..., seq]``, slot ``seq % 2``: the format a
restarted body reads), visible at once to another reader of the file."""
import numpy as np
import pytest

from sensorispace_ros.state.resting_state import RestingStateFile


def test_save_writes_the_slot_format(tmp_path):
    path = tmp_path / "body.state"
    state = RestingStateFile(path, 5)
    state.save((0.1, -1.5, 2.2, -3.0, 7))
    assert path.read_bytes() == np.array([[0.0] * 7, [1, 0.1, -1.5, 2.2, -3.0, 7, 1]]).tobytes()
    state.save(np.array([0.5, 0.25, -0.125, 3.0, 8.0]))
    assert path.read_bytes() == np.array([[2, 0.5, 0.25, -0.125, 3.0, 8, 2],
                                          [1, 0.1, -1.5, 2.2, -3.0, 7, 1]]).tobytes()
    # Another reader (the restarted body) sees the last save without a close.
    np.testing.assert_array_equal(RestingStateFile(path, 5).load(), [0.5, 0.25, -0.125, 3, 8])
    np.testing.assert_array_equal(state.load(), [0.5, 0.25, -0.125, 3, 8])


def test_save_refuses_a_vector_of_another_size(tmp_path):
    state = RestingStateFile(tmp_path / "body.state", 5)
    with pytest.raises(ValueError, match="values: 5 numbers"):
        state.save((1.0, 2.0, 3.0, 4.0))
    assert state.load() is None and state.seq == 0
