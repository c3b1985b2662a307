"""The environment's progress record and the launcher's progress line, which
polls it instead of subscribing to /agent/settled (no ROS here)."""
import io
import json
import re

import pytest

from sensorispace_ros.state.environment_record import (PROGRESS_BYTES, ProgressWriter,
    decode_progress, encode_progress, read_progress)
from sensorispace_ros.graph.launcher import Monitor


def test_a_record_round_trips_and_is_always_the_same_size():
    for current, settled in ((0, -1), (7, 6), (4231, 4231), (10**12, 10**12 - 1)):
        data = encode_progress(current, settled)
        assert len(data) == PROGRESS_BYTES
        assert decode_progress(data) == (current, settled)
        assert json.loads(data) == {"current": current, "settled": settled}


def test_a_record_that_does_not_fit_is_refused():
    with pytest.raises(ValueError, match="bytes"):
        encode_progress(10**40, 0)


def test_a_shorter_record_overwrites_a_longer_one_in_place(tmp_path):
    path = tmp_path / "checkpoints" / "environment.json"
    writer = ProgressWriter(path)
    try:
        writer.write(123456789, 123456788)
        writer.write(5, 4)
    finally:
        writer.close()
    assert path.stat().st_size == PROGRESS_BYTES
    assert read_progress(path) == (5, 4)


@pytest.mark.parametrize("content", [b"", b"{\"current\": 12, \"sett", b"not json",
                                     b"{\"current\": 3}", b"[1, 2]",
                                     b"{\"current\": \"x\", \"settled\": 1}"])
def test_an_unreadable_or_torn_record_reads_as_none(tmp_path, content):
    path = tmp_path / "environment.json"
    path.write_bytes(content)
    assert read_progress(path) is None
    with pytest.raises(ValueError, match="not a progress record"):
        decode_progress(content)


def test_a_missing_record_reads_as_none(tmp_path):
    assert read_progress(tmp_path / "absent.json") is None


def test_the_launchers_progress_line_follows_the_record_and_never_goes_back(tmp_path):
    path = tmp_path / "environment.json"
    stream = io.StringIO()
    monitor = Monitor(path, total_changes=40, stream=stream, interval_s=0.0)
    monitor.poll()                       # no record yet: nothing to show
    assert stream.getvalue() == "" and monitor.settled == -1
    writer = ProgressWriter(path)
    try:
        writer.write(11, 10)
        monitor.poll()
        path.write_bytes(b"{\"curr")     # read in the middle of a write: ignored
        monitor.poll()
        writer.write(9, 8)               # a resumed environment: shown as it was
        monitor.poll()
        writer.write(41, 41)             # the end is past the last change
        monitor.poll()
    finally:
        writer.close()
    lines = stream.getvalue().splitlines()
    assert [re.match(r"\[launch\] change (\d+)/40 \((\d+) %\) after [\d.]+ s$", line).groups()
            for line in lines] == [("10", "25"), ("10", "25"), ("40", "100")], lines


def test_on_the_row_clock_the_progress_line_is_the_row_the_bodys_clock_stands_at(tmp_path):
    import numpy as np

    from sensorispace_ros.graph.launcher import ClockMonitor
    from sensorispace_ros.state.resting_state import RestingStateFile, peek

    path = tmp_path / "body.clock"
    stream = io.StringIO()
    # Changes before rows 10, 20, 30, 40; the first two are the schedule, the
    # last two its replay for simulation 2.
    monitor = ClockMonitor(path, np.array([10, 20, 30, 40]), total_changes=2, stream=stream,
                           interval_s=0.0)
    monitor.poll()                                  # no file yet: nothing to show
    assert stream.getvalue() == "" and peek(path) is None
    joints = 2
    clock = RestingStateFile(path, 1 + 2 * (3 + joints))
    for number, (before, after) in enumerate(((0, 15), (15, 20), (20, 35)), start=1):
        clock.save((number, before, 0, 0, 0.1, 0.2, after, 0, 0, 0.3, 0.4))
        monitor.poll()
    lines = stream.getvalue().splitlines()
    assert [re.match(r"\[launch\] row ([\d,]+): (.*) after [\d.]+ s$", line).groups()
            for line in lines] == [("15", "change 1/2 (50 %)"), ("20", "change 2/2 (100 %)"),
                                   ("35", "simulation 2, change 1")], lines
    # Read without writing: the body's file is as it wrote it.
    np.testing.assert_array_equal(peek(path), clock.load())
