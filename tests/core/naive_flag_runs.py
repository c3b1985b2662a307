"""Two offline naive runs that differ in one boolean parameter meant to change
only the calls (``remember_sensations``, ``remember_split_povs``), and the
check that their results are the same."""
import numpy as np

from sensorispace_ros.core.paper.exploration import build_world
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.run import run_naive


def runs_on_and_off(flag: str, grid_count: int) -> tuple:
    """``(run with flag true, run with flag false)`` on ``build_world(0, grid)``."""
    world = build_world(0, {"grid_count": grid_count})
    return tuple(run_naive(world, NaiveParams(**{flag: value}))
                 for value in (True, False))


def assert_same_results(on, off) -> int:
    """POVs, equality sets and compensation records equal bit for bit; returns
    the number of compensation records."""
    np.testing.assert_array_equal(on.povs, off.povs)
    np.testing.assert_array_equal(on.pairs, off.pairs)
    np.testing.assert_array_equal(on.set_ids, off.set_ids)
    records = [[(r.event, r.anchor_event, r.pov, r.searched, r.motor_state.tobytes())
                for r in run.agent.compensations] for run in (on, off)]
    assert records[0] == records[1]
    return len(records[0])
