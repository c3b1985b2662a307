"""Points of view of dimension 2 (four free links, e.g. four links and an eye
joint): an even sampling of the fibre's surface.

The surface is sampled densely first, then thinned. Any two free links can
parametrise it: on a ``grid x grid`` lattice of their absolute angles,
each spanning the range that link takes on this fibre, the other two links
close the polygon by the two-link solution (two elbow branches). A chart stretches where its two solved links come near collinear
(its fold, where the surface turns back over the lattice); a point is kept
from the chart whose solved links are farthest from collinear there, so the
six charts share the surface out between them, each where it is regular,
and together cover every connected piece of it. Farthest-point sampling in
the periodic motor metric, from the POV's own motor state, then keeps
``n_samples`` of those candidates spread evenly, and a nearest-neighbour
tour orders them so that consecutive samples are close (the Hausdorff
kernel's bounds along a POV's samples work best then).

The two greedy loops run compiled with numba when it is installed, and as
NumPy otherwise: the same arithmetic, the same samples (tests compare).
"""
from __future__ import annotations

from itertools import combinations

import numpy as np

from sensorispace_ros.core.arm import Arm
from sensorispace_ros.core.paper.fibres import (closing_vector, free_links,
    motor_from_link_angles, two_link_angles)

try:
    import numba
except ImportError:             # optional: the NumPy loops are the fallback
    numba = None

TWO_PI = 2.0 * np.pi
DEFAULT_GRID = 96
CANDIDATES_PER_SAMPLE = 4
REFINEMENTS = 3
CHARTS = tuple(combinations(range(4), 2))        # the parameter pair of each chart


def surface_candidates(body_arm: Arm, motor: np.ndarray, *, grid: int = DEFAULT_GRID
                       ) -> np.ndarray:
    """Dense motor states ``(C, J)`` (radians, within pi of ``motor`` per
    joint) on the fibre of ``motor``'s pose, each from its best chart.

    A chart's lattice spans the angles its two links can take on this fibre
    (``link_angle_range``), so small fibres get as fine a lattice as large ones.
    """
    links = free_links(body_arm)
    if len(links) != 4:
        raise ValueError(f"a 2-D point of view needs four free links, got {len(links)}")
    motor = np.asarray(motor, dtype=float)
    pose = body_arm.forward(motor)
    closing = closing_vector(body_arm, pose)
    lattice = [_lattice(*link_angle_range(links, n, closing), int(grid)) for n in range(4)]
    parts = []
    for chart, (i, j) in enumerate(CHARTS):
        k, m = (n for n in range(4) if n not in (i, j))
        first, second = (a.ravel() for a in np.meshgrid(lattice[i], lattice[j], indexing="ij"))
        rest = closing - links[i] * np.stack([np.cos(first), np.sin(first)], axis=-1) \
            - links[j] * np.stack([np.cos(second), np.sin(second)], axis=-1)
        theta_k, theta_m, feasible = two_link_angles(links[k], links[m], rest)
        for branch in range(2):
            theta = np.empty((int(feasible.sum()), 4))
            theta[:, i], theta[:, j] = first[feasible], second[feasible]
            theta[:, k], theta[:, m] = theta_k[feasible, branch], theta_m[feasible, branch]
            parts.append(theta[_best_chart(theta) == chart])
    theta = np.concatenate(parts)
    return motor_from_link_angles(body_arm, theta, pose, motor)


def link_angle_range(links: np.ndarray, n: int, closing: np.ndarray) -> tuple:
    """``(centre, half_width)`` of the absolute angles link ``n`` takes on the
    fibre: the rest of the chain must reach ``|closing - l_n e(theta)|``,
    which bounds ``|theta - heading|`` (the rest's inner hole only removes
    angles inside that range)."""
    outer = float(np.delete(links, n).sum())
    length, distance = links[n], float(np.hypot(*closing))
    heading = float(np.arctan2(closing[1], closing[0]))
    if distance == 0.0:
        return heading, np.pi
    # |closing - l e|^2 = d^2 + l^2 - 2 d l cos(theta - heading) <= outer^2
    lowest = (distance ** 2 + length ** 2 - outer ** 2) / (2.0 * distance * length)
    return heading, float(np.arccos(np.clip(lowest, -1.0, 1.0)))


def _lattice(centre: float, half_width: float, count: int) -> np.ndarray:
    """``count`` angles evenly over ``centre +- half_width`` (the whole circle
    without repeating its end when the range is the whole circle)."""
    if half_width >= np.pi:
        return centre + np.arange(count) * (TWO_PI / count)
    return centre - half_width + (np.arange(count) + 0.5) * (2.0 * half_width / count)


def _best_chart(theta: np.ndarray) -> np.ndarray:
    """The chart each link-angle row ``(n, 4)`` is most regular in: the one
    whose solved pair is farthest from collinear (largest |sin| of their angle)."""
    spread = np.stack([np.abs(np.sin(theta[:, m] - theta[:, k]))
                       for k, m in ((n for n in range(4) if n not in pair) for pair in CHARTS)],
                      axis=-1)
    return np.argmax(spread, axis=-1)


def sample_surface(body_arm: Arm, motor: np.ndarray, n_samples: int, *,
                   grid: int | None = None, kernel: str = "auto") -> np.ndarray:
    """``n_samples`` motor states ``(n_samples, J)`` spread evenly over the 2-D
    fibre of ``motor``'s pose, ``motor`` first, each joint within pi of it.

    The lattice (``grid`` per chart axis; by default twice the square root of
    ``n_samples``) is refined until the candidates outnumber the samples
    ``CANDIDATES_PER_SAMPLE`` times; a fibre too small for that even on the
    finest lattice (the arm near full stretch) repeats its candidates.
    """
    motor = np.asarray(motor, dtype=float)
    n_samples = int(n_samples)
    if n_samples < 1:
        raise ValueError(f"n_samples must be a positive integer, got {n_samples}")
    grid = int(grid) if grid is not None else max(16, int(np.ceil(2.0 * np.sqrt(n_samples))))
    wanted = CANDIDATES_PER_SAMPLE * n_samples
    for _ in range(REFINEMENTS + 1):
        candidates = surface_candidates(body_arm, motor, grid=grid)
        if len(candidates) >= wanted:
            break
        grid = int(np.ceil(grid * min(4.0, 1.1 * np.sqrt(wanted / max(len(candidates), 1)))))
    count = min(n_samples - 1, len(candidates))
    picked, _ = farthest_point_indices(candidates, count, motor, kernel=kernel)
    samples = np.vstack([motor[None, :], candidates[picked]])
    samples = samples[nearest_neighbour_tour(samples, kernel=kernel)]
    return samples[np.arange(n_samples) * len(samples) // n_samples]


def farthest_point_indices(points: np.ndarray, count: int, first: np.ndarray, *,
                           kernel: str = "auto") -> tuple:
    """Indices of ``count`` of ``points`` ``(C, J)`` picked by farthest-point
    sampling in the periodic motor metric, starting from ``first`` ``(J,)``
    (not itself in ``points``), and the covering radius reached: the
    largest distance from a point to the picked ones and ``first``."""
    columns = np.ascontiguousarray(np.asarray(points, dtype=float).T)
    first = np.ascontiguousarray(first, dtype=float)
    if count > columns.shape[1]:
        raise ValueError(f"count ({count}) exceeds the {columns.shape[1]} points")
    run = _farthest_compiled if _compiled(kernel) else _farthest_numpy
    picked, radius_sq = run(columns, first, int(count))
    return picked, float(np.sqrt(radius_sq))


def nearest_neighbour_tour(samples: np.ndarray, *, kernel: str = "auto") -> np.ndarray:
    """An order of ``samples`` ``(S, J)``: the first, then each time the
    nearest one not yet visited (periodic motor metric)."""
    columns = np.ascontiguousarray(np.asarray(samples, dtype=float).T)
    run = _tour_compiled if _compiled(kernel) else _tour_numpy
    return run(columns)


def _compiled(kernel: str) -> bool:
    if kernel not in ("auto", "numpy", "numba"):
        raise ValueError(f"kernel must be auto, numpy or numba, got {kernel!r}")
    if kernel == "numba" and numba is None:
        raise ValueError("kernel 'numba' needs the numba package, which is not installed")
    return kernel != "numpy" and numba is not None


def _wrapped(diff):
    """A joint difference of two states within pi of one reference (so
    within 2 pi of 0) taken onto [-pi, pi], elementwise."""
    return np.where(diff > np.pi, diff - TWO_PI, np.where(diff < -np.pi, diff + TWO_PI, diff))


def _sq_distance_numpy(columns, point):
    """Squared periodic distance of every column of ``columns`` ``(J, C)`` to
    ``point``, joint by joint in order (the compiled loops' arithmetic)."""
    total = np.zeros(columns.shape[1])
    for row, value in zip(columns, point):
        diff = _wrapped(row - value)
        total += diff * diff
    return total


def _farthest_numpy(columns, first, count):
    nearest = _sq_distance_numpy(columns, first)
    picked = np.empty(count, dtype=np.int64)
    for n in range(count):
        picked[n] = np.argmax(nearest)
        np.minimum(nearest, _sq_distance_numpy(columns, columns[:, picked[n]]), out=nearest)
    return picked, nearest.max(initial=0.0)


def _tour_numpy(columns):
    left = np.ones(columns.shape[1], dtype=bool)
    order = np.zeros(columns.shape[1], dtype=np.int64)
    left[0] = False
    for n in range(1, columns.shape[1]):
        distance = np.where(left, _sq_distance_numpy(columns, columns[:, order[n - 1]]), np.inf)
        order[n] = np.argmin(distance)
        left[order[n]] = False
    return order


def _sq_distance_below(columns, c, point, bound):
    """Squared periodic distance of column ``c`` to ``point`` as
    ``_sq_distance_numpy`` sums it, or any partial sum that reaches
    ``bound`` (the sum only grows: the caller keeps ``bound`` then)."""
    total = 0.0
    for j in range(columns.shape[0]):
        diff = columns[j, c] - point[j]
        if diff > np.pi:
            diff -= TWO_PI
        elif diff < -np.pi:
            diff += TWO_PI
        total += diff * diff
        if total >= bound:
            return total
    return total


def _farthest_loops(columns, first, count):
    size = columns.shape[1]
    nearest = np.empty(size)
    for c in range(size):
        nearest[c] = _sq_distance_below(columns, c, first, np.inf)
    picked = np.empty(count, dtype=np.int64)
    for n in range(count):
        best = 0
        for c in range(1, size):
            if nearest[c] > nearest[best]:
                best = c
        picked[n] = best
        point = columns[:, best].copy()
        for c in range(size):
            value = _sq_distance_below(columns, c, point, nearest[c])
            if value < nearest[c]:
                nearest[c] = value
    return picked, nearest.max() if size else 0.0


def _tour_loops(columns):
    size = columns.shape[1]
    left = np.ones(size, dtype=np.bool_)
    order = np.zeros(size, dtype=np.int64)
    left[0] = False
    for n in range(1, size):
        point = columns[:, order[n - 1]].copy()
        best, best_value = -1, np.inf
        for c in range(size):
            if left[c]:
                value = _sq_distance_below(columns, c, point, best_value)
                if value < best_value:
                    best, best_value = c, value
        order[n] = best
        left[best] = False
    return order


if numba is None:
    _farthest_compiled = _tour_compiled = None
else:
    _sq_distance_below = numba.njit(nogil=True, cache=True, inline="always")(_sq_distance_below)
    _farthest_compiled = numba.njit(nogil=True, cache=True)(_farthest_loops)
    _tour_compiled = numba.njit(nogil=True, cache=True)(_tour_loops)
