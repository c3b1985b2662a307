"""The body's record of time on its own clock (state.clock_truth): what a
launched run's evaluator reads back is what the body knew."""
import numpy as np

from sensorispace_ros.core.body import SimulatedBody
from sensorispace_ros.core.world_clock import ClockedBody
from sensorispace_ros.state.clock_truth import read_clock_truth, write_clock_truth

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
