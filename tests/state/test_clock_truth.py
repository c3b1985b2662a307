"""The body's record of time on its own clock (state.clock_truth): what a
launched run's evaluator reads back is what the body knew, and what a
restarted body reads back of the log the dead one appended to."""
import os

import numpy as np

from sensorispace_ros.core.body import SimulatedBody
from sensorispace_ros.core.world_clock import ClockedBody
from sensorispace_ros.state.clock_truth import TruthLog, read_clock_truth, write_clock_truth

LIGHTS = [np.array([[4.0, 1.0]]), np.array([[4.5, 1.0]])]


def test_the_row_clocks_record_reads_back_as_written(tmp_path):
    clocked = ClockedBody(SimulatedBody(np.linspace(-0.5, 0.5, 3)), LIGHTS, np.array([3]))
    clocked.sense(np.zeros((5, 4)))
    path = tmp_path / "checkpoints" / "body.truth.npz"
    write_clock_truth(path, {0: 0, 1: 5, 7: 9}, {1: 1, 7: 1}, clocked)
    truth = read_clock_truth(path)
    assert truth["rows_after"] == {0: 0, 1: 5, 7: 9} and truth["state_after"] == {1: 1, 7: 1}
    assert (truth["rows"], truth["held_rows"]) == (5, 0) and truth["whole"]
    np.testing.assert_array_equal(truth["rest_jumps"], clocked.rest_jumps)
    assert not list(path.parent.glob("*.partial"))          # replaced whole


def test_the_wall_clocks_record_has_no_rows_and_a_missing_one_reads_as_none(tmp_path):
    path = tmp_path / "body.truth.npz"
    assert read_clock_truth(path) is None
    write_clock_truth(path, {0: 0}, {3: 2, 4: 5}, whole=False)
    truth = read_clock_truth(path)
    assert truth["state_after"] == {3: 2, 4: 5} and "rows" not in truth and not truth["whole"]


def test_the_log_reads_back_the_last_record_of_each_command_and_skips_a_cut_one(tmp_path):
    path = tmp_path / "checkpoints" / "body.truth.log"
    assert TruthLog.read(path) is None
    log = TruthLog(path, fresh=True)
    log.command(1, 40, 0)
    log.changes(0, np.array([np.nan, 0.25]))
    log.command(2, 95, 2)
    log.command(2, 95, 2)                     # executed again after a restart: the same values
    log.changes(2, np.array([0.5]))
    log.command(3, 120, 3)
    del log
    rows_after, state_after, jumps = TruthLog.read(path)
    assert (rows_after, state_after) == ({1: 40, 2: 95, 3: 120}, {1: 0, 2: 2, 3: 3})
    assert list(jumps) == [0, 1, 2] and np.isnan(jumps[0]) and (jumps[1], jumps[2]) == (0.25, 0.5)
    # A kill in the middle of the last write: that record is not read.
    os.truncate(path, path.stat().st_size - 8)
    assert TruthLog.read(path)[:2] == ({1: 40, 2: 95}, {1: 0, 2: 2})
    # Opened again after a restart, it is appended to; opened fresh, emptied.
    TruthLog(path, fresh=False).command(3, 121, 3)
    assert TruthLog.read(path)[0] == {1: 40, 2: 95, 3: 121}
    TruthLog(path, fresh=True).command(5, 7, 0)
    assert TruthLog.read(path)[:2] == ({5: 7}, {5: 0})
