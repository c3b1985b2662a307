"""Reaching in (position, orientation) space, for a world whose object turns.

``reaching.*`` (``evaluator``) judges a path by the sensor's external path in
position only; with turns a point of view is a sensor pose ``(x, y, theta)``
and the path is judged on plane x circle (``core.pose_reach``), on the same
start/target pairs and the same pruned graphs (the Hausdorff metric and
every embedding). An angle is weighed against a length by the arc it moves
the sensor at the arm's working radius (``pose_length_scale``): every
compensable pose lies in the working ring, and a turn by ``dtheta`` about
the base (or about an object centred near it, keeping the sensor's pose
relative to the object) carries a sensor at radius ``rho`` along
``rho * dtheta``. Radians times the middle of the ring: a turn and a
translation cost alike when they move the sensor alike.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.distance import pdist, squareform

from sensorispace_ros.core.arm import Arm
from sensorispace_ros.core.pose_reach import angle_turns, pose_reaching_evaluation
from sensorispace_ros.offline.representation import STAGES, Representation, random_state


def pose_length_scale(arm: Arm) -> float:
    """The length a turn of one radian counts for: the middle radius of the
    arm's working ring (2 for the paper arm's 1 <= |tip| <= 3)."""
    inner, outer = arm.working_ring
    return 0.5 * (inner + outer)


def pose_reaching_numbers(representation: Representation, true_poses: np.ndarray,
                          cfg: dict, seed: int, angle: np.ndarray | None = None) -> dict:
    """``pose_reaching.<graph>.*`` for the Hausdorff metric and every embedding:
    ``straightness_median`` and ``straightness_p90`` in pose space,
    ``reached_share`` (pairs the pruned graph joins), ``long_way_share`` (of
    the reached pairs, paths that turn the long way round the circle),
    ``same_pose`` (pairs of two POVs at one pose, left out of the
    straightness); ``pose_reaching.length_scale``. Pairs and pruning are
    ``reaching.*``'s (``representation.reaching`` and the ``reaching``
    stream). With the angle coordinate of the looped dimension (``angle``,
    ``evaluation.rotations.angle_numbers``), ``pose_reaching.angle.*``: on
    the same pairs, whether the turn it reads is the short way round
    (``core.pose_reach.angle_turns``)."""
    reaching = cfg["representation"]["reaching"]
    options = {"n_pairs": reaching["pairs"], "max_degree": reaching["max_degree"],
               "radius": reaching["radius"]}
    rho = pose_length_scale(Arm.from_config(cfg["arm"]))
    pair_seed = random_state(seed, "reaching")
    graphs = {"hausdorff": representation.distance}
    for dim in representation.before:
        for stage in STAGES:
            graphs[f"{dim}.{stage}"] = squareform(pdist(representation.embedding(dim, stage)))
    poses = np.asarray(true_poses, dtype=float).reshape(-1, 3)
    metrics: dict = {"pose_reaching.length_scale": rho}
    for name, distance in graphs.items():
        result = pose_reaching_evaluation(distance, poses, rho, random_state=pair_seed,
                                          **options)
        scored = [v for v in result["straightness"] if v is not None]
        prefix = f"pose_reaching.{name}"
        metrics.update({
            f"{prefix}.straightness_median": float(np.median(scored)) if scored
            else float("nan"),
            f"{prefix}.straightness_p90": float(np.percentile(scored, 90)) if scored
            else float("nan"),
            f"{prefix}.reached_share": result["reached"] / options["n_pairs"],
            f"{prefix}.long_way_share": result["long_way"] / max(result["reached"], 1),
            f"{prefix}.same_pose": result["same_pose"],
        })
        pairs = result["pairs"]
    if angle is not None:
        for key, value in angle_turns(angle, poses[:, 2], pairs).items():
            metrics[f"pose_reaching.angle.{key}"] = value
    return metrics
