"""The representation node grows the Hausdorff matrix while the POVs
arrive: what it hands to the final build is the matrix computed at the
end, to the bit, whatever the messages' order, sizes and duplicates; of the
motor values as angles (the body's unit turned to rad: the same bits for a
body in rad)."""
from __future__ import annotations

import numpy as np
import pytest

from sensorispace_ros import contracts, messages
from sensorispace_ros.core.body_description import BodyDescription
from sensorispace_ros.graph import in_process
from sensorispace_ros.core import hausdorff
from sensorispace_ros.graph.nodes.representation import RepresentationNode, assemble_points_of_view

from shared import SMOKE

pytestmark = pytest.mark.skipif(not hausdorff.numba_available(),
                                reason="the growing matrix needs numba")
PAPER_BODY = BodyDescription.revolute(4, 6)


def _loops(rng, n_povs, n_samples=24):
    """Translated, phase-shifted copies of one loop: close to each other, as POVs."""
    t = 2 * np.pi * np.arange(n_samples) / n_samples
    base = np.stack([np.cos(t), np.sin(t), np.cos(2 * t), np.sin(t + 1)], axis=-1)
    shift = rng.normal(scale=0.8, size=(n_povs, 1, 4))
    roll = rng.integers(n_samples, size=n_povs)
    return np.stack([np.roll(base, r, axis=0) for r in roll]) + shift


def _pov_message(frame_id, ids, povs, samples=None, description=PAPER_BODY):
    n = povs.shape[1]
    samples = np.arange(n) if samples is None else samples
    pov = np.repeat(ids, len(samples))
    motor = povs[:, samples].reshape(-1, povs.shape[2])
    return messages.table_to_cloud(
        {"pov": pov, "sample": np.tile(samples, len(ids)),
         **{f"m{j}": motor[:, j] for j in range(povs.shape[2])}},
        contracts.contract("/agent/points_of_view").columns_for(description),
        messages.make_header(frame_id))


def _representation(context, tmp_path, description):
    node = RepresentationNode(context=context, parameter_overrides=in_process.parameter_overrides(
        SMOKE, {"graph.results_dir": str(tmp_path)}))
    node.build = lambda: None                       # the final build is not under test
    node.on_description(messages.description_to_msg(description))
    return node


@pytest.fixture
def node(context, tmp_path):
    node = _representation(context, tmp_path, PAPER_BODY)
    yield node
    node.destroy_node()


def test_grown_matrix_is_the_matrix_of_the_sorted_povs(node):
    rng = np.random.default_rng(3)
    povs = _loops(rng, 90)
    ids = rng.permutation(np.arange(1000, 1090))   # arrival order is not id order
    chunks = [1, 1, 30, 40, 2, 16]                 # crossing the 64 landmark rows
    start = 0
    for k, size in enumerate(chunks):
        node.on_points_of_view(_pov_message(f"change/{k}", ids[start:start + size],
                                            povs[start:start + size]))
        if k == 3:                                  # a restarted agent re-publishes
            node.on_points_of_view(_pov_message(f"change/{k}", ids[start:start + size],
                                                povs[start:start + size]))
        start += size
    sorted_ids, sorted_povs = assemble_points_of_view(list(node.pov_tables.values()), 4)
    grown = node.grown_hausdorff(sorted_ids)
    assert grown is not None and not node.hausdorff_failed
    assert node.duplicates == 1 and node.hausdorff.count == 90
    assert np.array_equal(grown, hausdorff.hausdorff_matrix(sorted_povs))
    assert np.array_equal(sorted_povs, povs[np.argsort(ids)])


def test_a_message_with_part_of_a_pov_gives_the_growing_matrix_up(node):
    # The agent publishes whole POVs; a message that does not is still stored
    # (the final build reports it), and the matrix is left to the end.
    povs = _loops(np.random.default_rng(4), 3)
    node.on_points_of_view(_pov_message("change/0", np.array([0, 1]), povs[:2]))
    assert not node.hausdorff_failed
    node.on_points_of_view(_pov_message("change/1", np.array([2]), povs[2:],
                                        samples=np.arange(10)))
    assert node.hausdorff_failed and 2 in node.pov_ids
    assert node.grown_hausdorff(np.array([0, 1, 2])) is None


def test_povs_of_a_body_in_degrees_are_measured_as_angles(context, tmp_path):
    degrees = BodyDescription.revolute(3, 5, "deg")
    node = _representation(context, tmp_path, degrees)
    try:
        povs = np.rad2deg(_loops(np.random.default_rng(5), 12)[:, :, :3])
        node.on_points_of_view(_pov_message("change/0", np.arange(12), povs,
                                            description=degrees))
        ids, held = assemble_points_of_view(list(node.pov_tables.values()), 3)
        assert np.array_equal(held, povs)               # kept in the body's unit
        grown = node.grown_hausdorff(ids)
        assert np.array_equal(grown, hausdorff.hausdorff_matrix(degrees.to_radians(povs)))
        assert not np.allclose(grown, hausdorff.hausdorff_matrix(povs))
    finally:
        node.destroy_node()


def test_povs_of_a_body_in_radians_are_passed_on_unchanged():
    povs = _loops(np.random.default_rng(6), 3)
    assert PAPER_BODY.to_radians(povs) is povs
