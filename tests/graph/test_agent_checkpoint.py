"""The agent's journal and snapshot files (sensorispace_ros.state.agent_journal):
a kill mid-write loses only the record being written, damage
elsewhere is an error naming the file. Pure Python, no ROS."""
import numpy as np
import pytest

from sensorispace_ros.state.agent_journal import (AgentJournal, CheckpointError, command_check,
    read_journal, read_snapshot, write_snapshot)


def _write_some(path):
    journal = AgentJournal(path)
    journal.passive("change", 3, np.arange(6.0))
    journal.answer(7, 1234, np.arange(12.0).reshape(2, 6))
    journal.settled(3)
    journal.passive("end", 4, np.full(6, 0.5))
    journal.answer(8, 99, np.ones((3, 6)))
    journal.close()
    return path.read_bytes()


def test_journal_round_trip(tmp_path):
    _write_some(tmp_path / "agent.journal")
    content = read_journal(tmp_path / "agent.journal")
    assert [(k, n) for k, n, _ in content.passives] == [("change", 3), ("end", 4)]
    np.testing.assert_array_equal(content.passives[0][2], np.arange(6.0))
    assert sorted(content.answers) == [7, 8] and content.answers[7][0] == 1234
    np.testing.assert_array_equal(content.answers[7][1], np.arange(12.0).reshape(2, 6))
    assert content.settled == [3] and content.torn_bytes == 0


@pytest.mark.parametrize("cut", [1, 5, 20, 60])
def test_a_write_cut_by_a_kill_loses_only_the_last_record(tmp_path, cut):
    data = _write_some(tmp_path / "whole")
    path = tmp_path / "agent.journal"
    path.write_bytes(data[:-cut])
    content = read_journal(path)
    assert sorted(content.answers) == [7]              # answer 8 was being written
    assert [n for _, n, _ in content.passives] == [3, 4] and content.settled == [3]
    assert content.torn_bytes > 0 and content.valid_bytes + content.torn_bytes == len(data) - cut
    # Appending after the restart cuts the torn tail off first.
    journal = AgentJournal(path, content.valid_bytes)
    journal.settled(4)
    journal.close()
    again = read_journal(path)
    assert again.settled == [3, 4] and again.torn_bytes == 0 and sorted(again.answers) == [7]


def test_damage_inside_the_journal_names_the_file(tmp_path):
    data = bytearray(_write_some(tmp_path / "whole"))
    data[30] ^= 0xFF                                  # inside the first record
    path = tmp_path / "agent.journal"
    path.write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match="agent.journal.*corrupt"):
        read_journal(path)


def test_missing_files_are_a_fresh_start(tmp_path):
    assert read_snapshot(tmp_path / "agent.snapshot") is None
    content = read_journal(tmp_path / "agent.journal")
    assert not content.passives and not content.answers and content.valid_bytes == 0


def test_snapshot_round_trip_and_truncate(tmp_path):
    path = tmp_path / "cp" / "agent.snapshot"
    state = {"agent": {"x": np.arange(5)}, "node": {"last_settled": 4}}
    assert write_snapshot(path, state) == path.stat().st_size
    loaded = read_snapshot(path)
    np.testing.assert_array_equal(loaded["agent"]["x"], np.arange(5))
    assert loaded["node"] == {"last_settled": 4}
    assert [p.name for p in path.parent.iterdir()] == ["agent.snapshot"]   # no tmp left


@pytest.mark.parametrize("damage", ["cut", "garbage", "other"])
def test_a_corrupt_snapshot_is_a_clear_error_naming_the_file(tmp_path, damage):
    path = tmp_path / "agent.snapshot"
    write_snapshot(path, {"agent": {"x": np.arange(1000)}})
    data = path.read_bytes()
    if damage == "cut":
        path.write_bytes(data[:len(data) // 2])
    elif damage == "garbage":
        path.write_bytes(b"\x00garbage" * 10)
    else:
        import pickle
        path.write_bytes(pickle.dumps([1, 2, 3]))
    with pytest.raises(CheckpointError, match=r"agent\.snapshot"):
        read_snapshot(path)


def test_command_check_tells_commands_apart():
    a = np.array([[0.1, -1.5, 2.2, -3.0]])
    assert command_check(a) == command_check(a.copy())
    assert command_check(a) != command_check(a + 1e-12)
    assert command_check(a) != command_check(np.vstack([a, a]))
