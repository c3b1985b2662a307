"""`sensorispace bag recover | bag verify | analyze | replay`: results and one-line
errors (exit 2)."""
from __future__ import annotations

import pytest
from rosbags.typesys import Stores, get_typestore

from sensorispace_ros.recording.bag_reader import read_bag
from sensorispace_ros.recording.bag_writer import BagWriter
from sensorispace_ros.cli import main as cli

STORE = get_typestore(Stores.ROS2_JAZZY)


def uint64_cdr(n: int) -> bytes:
    return bytes(STORE.serialize_cdr(STORE.types["std_msgs/msg/UInt64"](data=n),
                                     "std_msgs/msg/UInt64"))


def killed_bag(tmp_path, n=500):
    """A bag as a killed recorder leaves it: MCAP cut inside the last chunk, no metadata.yaml."""
    full = tmp_path / "full"
    with BagWriter(full, {"/agent/settled": "std_msgs/msg/UInt64"},
                   chunk_interval_s=1e-9) as writer:
        for i in range(n):
            writer.write("/agent/settled", 100 + i, uint64_cdr(i))
    data = (full / "full.mcap").read_bytes()
    killed = tmp_path / "killed"
    killed.mkdir()
    (killed / "killed.mcap").write_bytes(data[: len(data) * 2 // 3])
    return killed


def test_bag_recover_command(tmp_path, capsys):
    killed = killed_bag(tmp_path)
    assert cli.main(["bag", "recover", str(killed)]) == 0
    out = capsys.readouterr().out
    assert "recovered" in out
    values = [STORE.deserialize_cdr(cdr, t).data for _, t, _, cdr in read_bag(killed)]
    assert len(values) > 200 and values == list(range(len(values)))
    assert cli.main(["bag", "recover", str(killed)]) == 0
    assert "already complete" in capsys.readouterr().out


@pytest.mark.parametrize("command", [["analyze"], ["replay"], ["bag", "recover"],
                                     ["bag", "verify"]])
def test_missing_bag_is_one_line_exit_2(tmp_path, capsys, command):
    assert cli.main([*command, str(tmp_path / "absent")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("sensorispace: error: bag ") and "absent" in err
    assert len(err.splitlines()) == 1


def test_truncated_bag_is_one_line_exit_2_with_the_fix(tmp_path, capsys):
    killed = killed_bag(tmp_path)
    assert cli.main(["analyze", str(killed), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no metadata.yaml" in err[0] and "bag recover" in err[0]


def test_bag_of_another_schema_is_one_line_exit_2(tmp_path, capsys):
    with BagWriter(tmp_path / "other", {"/agent/settled": "std_msgs/msg/String"}):
        pass
    assert cli.main(["replay", str(tmp_path / "other"), "--fast"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "another schema: topic /agent/settled has type std_msgs/msg/String" in err[0]
