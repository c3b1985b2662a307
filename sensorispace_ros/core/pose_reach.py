"""Reaching in (position, orientation) space: a sensor pose is a point of the
plane times the circle.

When the object turns as well as translates, a point of view is a pose
``(x, y, theta)`` of the sensor, and a path through a representation's graph
(``core.reach``: pruned graph, Dijkstra) is judged by the straightness of the
sensor's external path in pose space. A length and an angle are put on one
scale by ``length_scale`` rho: a turn by ``dtheta`` counts as the arc
``rho * |dtheta|``, so a step ``(dx, dy, dtheta)`` has length
``sqrt(dx^2 + dy^2 + (rho * wrap(dtheta))^2)`` with ``dtheta`` wrapped into
(-pi, pi] (the short way round the circle). The straight distance between
two poses is the same formula on their difference: the geodesic of the flat
metric on plane x circle. A path scores 1 when it follows that geodesic, more
when it detours, in position or by turning the long way round.
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.cca import check_distance_matrix
from sensorispace_ros.core.reach import pair_paths

SAME_POSE_TOL = 1e-9      # relative to the length scale: start and target at one pose
LONG_WAY_TOL = 0.05       # rad past half a turn before a path counts as the long way round


def wrap(angle) -> np.ndarray:
    """Angles wrapped into [-pi, pi)."""
    return np.mod(np.asarray(angle, dtype=float) + np.pi, 2.0 * np.pi) - np.pi


def _check_poses(poses) -> np.ndarray:
    poses = np.asarray(poses, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"poses must have shape (P, 3) of (x, y, theta), got {poses.shape}")
    return poses


def _check_scale(length_scale: float) -> float:
    if not np.isfinite(length_scale) or length_scale <= 0:
        raise ValueError(f"length_scale must be a finite length > 0, got {length_scale!r}")
    return float(length_scale)


def pose_distance(a, b, length_scale: float) -> np.ndarray:
    """Distance on plane x circle between poses ``a`` and ``b`` (``(..., 3)``):
    ``sqrt(|dxy|^2 + (length_scale * wrap(dtheta))^2)``."""
    rho = _check_scale(length_scale)
    diff = np.asarray(b, dtype=float) - np.asarray(a, dtype=float)
    return np.sqrt(np.sum(diff[..., :2] ** 2, axis=-1) + (rho * wrap(diff[..., 2])) ** 2)


def net_turn(path, poses) -> float:
    """The orientation change accumulated along the path (each step the short
    way round), in rad: equal to ``wrap(theta_target - theta_start)`` when the
    path turns the short way, off by a multiple of 2 pi when it goes round."""
    theta = _check_poses(poses)[np.asarray(path, dtype=int), 2]
    return float(np.sum(wrap(np.diff(theta))))


def goes_long_way(path, poses, turn_tol: float = LONG_WAY_TOL) -> bool:
    """Whether the path turns the sensor round the circle the long way: its
    accumulated turn exceeds half a turn, which the short way never does, by
    more than ``turn_tol`` (rad). A target half a turn away is the short way
    round either way; the tolerance keeps a pose a hair past half a turn (a
    compensation's residual) from counting as a detour."""
    return bool(abs(net_turn(path, poses)) > np.pi + turn_tol)


def pose_path_straightness(path, poses, length_scale: float) -> float:
    """External length of the path in pose space / pose distance start-target
    (>= 1). Raises when start and target are one pose."""
    poses = _check_poses(poses)
    points = poses[np.asarray(path, dtype=int)]
    straight = float(pose_distance(points[0], points[-1], length_scale))
    if straight <= SAME_POSE_TOL * length_scale:
        raise ValueError("path starts and ends at the same pose: straightness undefined")
    return float(np.sum(pose_distance(points[:-1], points[1:], length_scale)) / straight)


def pose_reaching_evaluation(distance, poses, length_scale: float, *, n_pairs: int = 100,
                             random_state=None, max_degree: int = 50, radius=None) -> dict:
    """Straightness in pose space of Dijkstra paths between random start/target
    POVs of the graph of ``distance`` (pruned as ``core.reach.pruned_graph``).

    Pairs are drawn as ``core.reach.reaching_evaluation`` draws them. A pair
    is *reached* when the pruned graph joins its nodes; pairs at one pose
    (two POVs of one pose) are reached trivially and left out of the
    straightness (None). Returns plain Python types: ``straightness`` per pair
    (None: unreached or one pose), ``reached`` (count), ``same_pose``,
    ``long_way`` (reached paths turning the long way round), ``radius``,
    ``n_components``, ``pairs``, ``paths``.
    """
    D = check_distance_matrix(distance, "distance")
    P = D.shape[0]
    poses = _check_poses(poses)
    if poses.shape[0] != P:
        raise ValueError(f"poses must have one row per node ({P}), got {poses.shape[0]}")
    rho = _check_scale(length_scale)
    graph, starts, targets, paths = pair_paths(D, n_pairs, random_state, max_degree, radius)
    straightness = []
    reached = same_pose = long_way = 0
    for path, start, target in zip(paths, starts, targets):
        if path is None:
            straightness.append(None)
            continue
        reached += 1
        if pose_distance(poses[start], poses[target], rho) <= SAME_POSE_TOL * rho:
            same_pose += 1
            straightness.append(None)
            continue
        long_way += goes_long_way(path, poses)
        straightness.append(pose_path_straightness(path, poses, rho))
    return {"straightness": straightness, "reached": reached, "same_pose": same_pose,
            "long_way": long_way, "radius": graph.radius, "n_components": graph.n_components,
            "pairs": [[int(s), int(t)] for s, t in zip(starts, targets)], "paths": paths}


def angle_turns(angle, orientation, pairs, turn_tol: float = LONG_WAY_TOL) -> dict:
    """Whether an angle coordinate of the looped dimension tells the short
    way round: for each start/target pair, the turn it reads
    (``wrap(angle_t - angle_s)``, after the coordinate's direction is matched
    to the orientation's: a coordinate ``-theta + c`` is as good as ``theta + c``)
    against the true short turn. ``short_way_share``: pairs whose read turn
    has the true turn's sign, among those more than ``turn_tol`` from no turn
    and from half a turn (where either way is short); ``turn_error_median``
    (rad) over all pairs; ``scored`` pairs."""
    angle = np.asarray(angle, dtype=float).reshape(-1)
    orientation = np.asarray(orientation, dtype=float).reshape(-1)
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    if angle.shape != orientation.shape or not len(pairs):
        raise ValueError(f"need one angle per orientation and some pairs, got {angle.shape}, "
                         f"{orientation.shape} and {len(pairs)} pairs")
    same = abs(np.mean(np.exp(1j * (angle - orientation))))
    opposite = abs(np.mean(np.exp(1j * (angle + orientation))))
    sign = 1.0 if same >= opposite else -1.0
    read = wrap(sign * (angle[pairs[:, 1]] - angle[pairs[:, 0]]))
    true = wrap(orientation[pairs[:, 1]] - orientation[pairs[:, 0]])
    clear = (np.abs(true) > turn_tol) & (np.abs(true) < np.pi - turn_tol)
    agree = np.sign(read[clear]) == np.sign(true[clear])
    return {"short_way_share": float(np.mean(agree)) if clear.any() else float("nan"),
            "turn_error_median": float(np.median(np.abs(wrap(read - true)))),
            "scored": int(clear.sum())}
