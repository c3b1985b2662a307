"""The bag's write-ahead log: what a recorder committed survives kill -9.

Each case runs a writer in a child process that SIGKILLs itself (a real kill:
no interpreter shutdown flushes Python's buffers), then recovers the bag."""
from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

from sensorispace_ros.recording.bag_format import session_config_cdr
from sensorispace_ros.recording.bag_reader import read_bag
from sensorispace_ros.recording.bag_recovery import recover_bag
from sensorispace_ros.recording.bag_writer import WAL_NAME, BagWriter

from shared import REPO


def killed_writer(bag: Path, body: str, write_ahead: bool = True) -> None:
    """Run ``body`` with ``w`` (a BagWriter on topic /x, a 1000 s chunk interval) and
    ``send(i)`` (writes UInt64 i at time i + 1), then SIGKILL the child."""
    code = textwrap.dedent(f"""
        import os, signal, sys
        sys.path.insert(0, {str(REPO)!r})
        from rosbags.typesys import Stores, get_typestore
        from sensorispace_ros.recording.bag_writer import BagWriter
        store = get_typestore(Stores.ROS2_JAZZY)
        UInt64 = store.types["std_msgs/msg/UInt64"]
        w = BagWriter({str(bag)!r}, {{"/x": "std_msgs/msg/UInt64"}},
                      chunk_interval_s=1000.0, write_ahead={write_ahead})
        def send(i):
            w.write("/x", i + 1, bytes(store.serialize_cdr(UInt64(data=i), "std_msgs/msg/UInt64")))
    """) + textwrap.dedent(body) + "\nos.kill(os.getpid(), signal.SIGKILL)\n"
    child = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=60)
    assert child.returncode == -9, child.stderr.decode()


def recovered_values(bag: Path) -> list[int]:
    recover_bag(bag)
    return [int.from_bytes(cdr[4:12], "little") for _, _, _, cdr in read_bag(bag, ["/x"])]


def test_every_committed_message_survives_a_kill_and_an_uncommitted_one_does_not(tmp_path):
    killed_writer(tmp_path / "bag", """
        for i in range(3000):
            send(i)
            if i % 100 == 99:
                w.commit()
        send(3000)                       # written, never committed
    """)
    assert recovered_values(tmp_path / "bag") == list(range(3000))


def test_without_the_log_the_open_chunk_is_lost(tmp_path):
    killed_writer(tmp_path / "bag", """
        send(0)
        w.flush_chunk()                  # a first chunk on disk
        for i in range(1, 3000):
            send(i)
            w.commit()                   # a no-op without the log
    """, write_ahead=False)
    assert recovered_values(tmp_path / "bag") == [0]


def test_a_kill_between_chunk_flush_and_log_truncation_keeps_each_message_once(tmp_path):
    killed_writer(tmp_path / "bag", """
        for i in range(500):
            send(i)
        w.commit()
        w._empty_wal = lambda: None      # the kill falls after the chunk reached the OS ...
        w.flush_chunk()                  # ... and before the log was emptied
        for i in range(500, 800):
            send(i)
        w.commit()
    """)
    assert recovered_values(tmp_path / "bag") == list(range(800))


def test_a_record_cut_short_by_the_kill_is_left_out(tmp_path):
    bag = tmp_path / "bag"
    killed_writer(bag, """
        for i in range(10):
            send(i)
        w.commit()
    """)
    with open(bag / WAL_NAME, "ab") as log:
        log.write(b"\\x02\\x00" + b"\\x00" * 7)          # half a record header
    assert recovered_values(bag) == list(range(10))


def test_a_closed_bag_keeps_no_log(tmp_path):
    with BagWriter(tmp_path / "bag", {"/x": "std_msgs/msg/String"}, write_ahead=True) as w:
        w.write("/x", 1, session_config_cdr("a: 1"))
        w.commit()
        assert (tmp_path / "bag" / WAL_NAME).stat().st_size > 0
    assert not (tmp_path / "bag" / WAL_NAME).exists()
