"""The manifold the known POVs' loops sweep in motor space: its
codimension measured from the loops, a state's offset from it, and the
search ends it decides between a known loop and a new position."""
from types import SimpleNamespace

import numpy as np
import pytest

from sensorispace_ros.core.naive import loop_manifold
from sensorispace_ros.core.naive.known_loops import APART, HALF, OFF_FACTOR, ON_LOOP
from sensorispace_ros.core.naive.points_of_view import PovStore
from sensorispace_ros.core.naive.searching import SearchAndSample

RADIUS, BEND, STEP = 0.2, 0.05, 0.3
GRID = STEP * np.arange(-2, 3)


def _embed(u, v, t):
    """A motor state of the curved 3-manifold ``x3^2 + (x4 - BEND (x1^2 +
    x2^2))^2 = RADIUS^2`` in four joints: position ``(u, v)``, loop phase ``t``."""
    u, v, t = np.broadcast_arrays(u, v, t)
    return np.stack([u, v, RADIUS * np.cos(t), RADIUS * np.sin(t) + BEND * (u * u + v * v)],
                    axis=-1)


def _normal(state):
    """Unit normal of that manifold at ``state``."""
    x1, x2, x3, x4 = state
    w = x4 - BEND * (x1 * x1 + x2 * x2)
    gradient = np.array([-2 * BEND * x1 * w, -2 * BEND * x2 * w, x3, w])
    return gradient / np.linalg.norm(gradient)


def _lattice_loops(hole=True, n=96, noise=0.0, seed=0):
    """Loops on the 5 x 5 lattice of positions ``GRID``, the centre one left
    out when ``hole``."""
    phase = np.linspace(0, 2 * np.pi, n, endpoint=False)
    loops = [_embed(u, v, phase) for u in GRID for v in GRID if not (hole and u == v == 0)]
    loops = np.array(loops)
    return loops + noise * np.random.default_rng(seed).standard_normal(loops.shape)


def _filling_loops(n=96):
    """Loops on a 3 x 3 x 3 lattice, each a circle in joints 3-4 about its
    position: together they leave no motor direction out."""
    phase = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.array([np.stack([np.full(n, u), np.full(n, v), w + RADIUS * np.cos(phase),
                               RADIUS * np.sin(phase)], axis=1)
                     for u in GRID[1:4] for v in GRID[1:4] for w in GRID[1:4]])


@pytest.mark.parametrize("noise", [0.0, 1e-4])
def test_the_loops_of_a_lattice_of_positions_leave_one_motor_direction_out(noise):
    loops = _lattice_loops(noise=noise)
    assert loop_manifold.measure(loops, np.arange(len(loops)))[0] == 1


def test_loops_that_fill_the_motor_space_leave_none_out():
    loops = _filling_loops()
    assert loop_manifold.measure(loops, np.arange(len(loops))) == (0, None)


def test_a_new_position_lies_on_the_manifold_and_a_changed_orientation_off_it():
    loops = _lattice_loops()
    own = loop_manifold.measure(loops, np.arange(len(loops)))[1]
    new_position = _embed(0.0, 0.0, 1.0)
    off = new_position + 0.03 * _normal(new_position)
    # The hole's nearest loops lie a step away, the POVs' own nearest ones
    # nearer: the manifold's bend shows more, within the agent's limit.
    on_offset, reach = loop_manifold.normal_offset(new_position, loops, 1)
    assert on_offset < OFF_FACTOR * np.median(own)
    assert reach == pytest.approx(STEP, rel=0.01)
    off_offset, _ = loop_manifold.normal_offset(off, loops, 1)
    assert off_offset == pytest.approx(0.03, abs=0.005)
    assert off_offset > OFF_FACTOR * np.median(own)


def test_local_samples_leave_the_excluded_loop_out():
    loops = _lattice_loops()
    point = loops[7, 3]
    with_it, reach = loop_manifold.local_samples(point, loops)
    without, reach_without = loop_manifold.local_samples(point, loops, exclude=7)
    assert reach == 0.0 and reach_without == pytest.approx(STEP, rel=0.01)
    assert np.any(np.all(np.isclose(with_it, point), axis=1))
    assert not np.any(np.all(np.isclose(without, point), axis=1))
    assert len(with_it) == len(without) == loop_manifold.K_LOOPS * (2 * loop_manifold.AROUND + 1)


class _Agent(SearchAndSample):
    """A noisy agent whose POVs are the lattice's loops (hole at the centre),
    their separation one lattice step."""

    def __init__(self, loops):
        self._noisy = True
        self.structure = SimpleNamespace(pov_dim=1)
        self.params = SimpleNamespace(pose_precision_povs=8, match_tol=1.0)
        self._store = PovStore(loops.shape[1], 4)
        for loop in loops:
            self._store.append(loop)
        self._store.separation = lambda: STEP
        self.ends_between_loops = self.ends_off_manifold = 0


def _toward_neighbour(share, t=1.0):
    """On the manifold between the hole and the loop at ``(STEP, 0)``,
    ``share`` of a step from that loop."""
    return _embed(STEP * (1 - share), 0.0, t)


@pytest.mark.parametrize("loops", [_lattice_loops(), _lattice_loops(noise=1e-4)])
def test_an_end_past_half_a_step_is_new_on_the_manifold_and_refused_off_it(loops):
    agent = _Agent(loops)
    share = 0.5 * (HALF + APART)
    on = _toward_neighbour(share)
    assert agent._placed_end(on)[1] is False
    assert agent._placed_end(on + 0.03 * _normal(on))[1] is True
    assert agent.ends_off_manifold == 1
    # Nearer a known loop than half a step it is refused on the manifold too,
    # and within a quarter step it is that POV (never between loops).
    assert agent._placed_end(_toward_neighbour(0.5 * (ON_LOOP + HALF)))[1] is True
    assert agent._placed_end(_toward_neighbour(0.8 * ON_LOOP))[1] is False
    assert agent.ends_off_manifold == 1


def test_an_end_off_the_manifold_is_refused_however_far_from_a_known_loop():
    agent = _Agent(_lattice_loops())
    hole = _embed(0.0, 0.0, 2.0)    # a step from the nearest loops
    assert agent._placed_end(hole)[1] is False
    assert agent._placed_end(hole + 0.03 * _normal(hole))[1] is True


def test_the_limit_grows_with_the_square_of_the_distance_to_the_nearest_loop():
    # Two steps beyond the lattice's edge the fitted plane is extrapolated:
    # an offset twice the limit measured a step away is allowed there, not
    # one step away.
    loops = _lattice_loops()
    agent = _Agent(loops)
    far = _embed(GRID[-1] + 2 * STEP, 0.0, 2.0)
    near = _embed(0.0, 0.0, 2.0)
    for state in (far, near):
        samples, reach = loop_manifold.local_samples(state, loops)
        centroid, _, directions = loop_manifold._plane(samples)
        normal = directions[-1]
        shifted = state + (0.02 - normal @ (state - centroid)) * normal    # offset 0.02
        assert loop_manifold.normal_offset(shifted, loops, 1)[0] == pytest.approx(0.02)
        assert agent._off_manifold(shifted, 1, 0.01) is (reach < 1.5 * STEP)


def test_without_a_measured_manifold_ends_up_to_apart_are_refused():
    # Loops that fill the motor space leave nothing to be off of: the rule of
    # motor distance alone holds, up to ``APART``.
    loops = _lattice_loops()
    agent = _Agent(loops)
    agent._manifold_cache = (len(loops), 0, None)
    assert agent._placed_end(_toward_neighbour(0.5 * (HALF + APART)))[1] is True
    assert agent.ends_off_manifold == 0
