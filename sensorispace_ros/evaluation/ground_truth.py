"""Ground truth of a run, joined by the evaluator and never seen by the agent.

The sensor pose of a POV comes from the arm's forward model (or a recorded
``/body/sensor_pose``); the object's centre, the light layout and the kind of
each change come from the seeded schedule, or from ``/environment/event``
where a bag recorded it. ``RunTruth`` holds a run's world, built once per
evaluation and handed to every part of it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Mapping

import numpy as np

from sensorispace_ros.core.arm import PAPER_ARM, Arm
from sensorispace_ros.bodies import run_world
from sensorispace_ros.core.world import REDISTRIBUTION

if TYPE_CHECKING:
    from sensorispace_ros.core.paper.exploration import World


class RunTruth:
    """The ground truth of one run: its world (``core.run_world``), built when
    the truth is made unless the run producer hands over its own, and the sensor
    positions the paper strategy compensates (the naive coverage denominator),
    explored on first use."""

    def __init__(self, cfg: dict, world: World | None = None):
        self.cfg = cfg
        self.world = run_world(cfg) if world is None else world
        self._paper_poses: np.ndarray | None = None

    @property
    def paper_positions(self) -> np.ndarray:
        return self.paper_poses[:, :2].copy()

    @property
    def paper_poses(self) -> np.ndarray:
        """Sensor poses ``(Q, 3)`` the paper strategy compensates (with its initial POV)."""
        if self._paper_poses is None:
            self._paper_poses = paper_compensated_poses(self.world)
        return self._paper_poses


@dataclass
class NaiveGroundTruth:
    """The evaluator's side of a naive run, indexed by the agent's event ``t``
    (0 = the start): ``centers`` ``(T+1, 2)`` object centre, ``layout``
    ``(T+1,)`` light-layout version (+1 at each redistribution), ``kinds``
    event kinds (``"initial"`` first), ``grid_index`` ``(T+1,)`` the object's
    grid position (-1 at the start); ``true_poses`` ``(P, 3)`` the sensor
    pose of each POV's first sample; ``initial_motor_state``;
    ``paper_positions`` ``(Q, 2)`` the coverage denominator
    (``paper_compensated_positions``); ``spacing`` the object grid's step."""

    centers: np.ndarray
    layout: np.ndarray
    kinds: list
    grid_index: np.ndarray
    true_poses: np.ndarray
    initial_motor_state: np.ndarray
    paper_positions: np.ndarray
    arm: Arm = PAPER_ARM
    spacing: float = 1.0      # the grid step: a quarter of it tells poses apart
    # A turning object (``evaluation.rotations``): its orientation at each
    # event (None: it only translates) and the paper strategy's poses (Q, 3).
    orientations: np.ndarray | None = None
    paper_poses: np.ndarray | None = None
    rotation_count: int = 0

    @property
    def pose_tolerance(self) -> float:
        """A compensation further than this from the pose its anchor asks for
        is wrong; two POVs closer than this are one sensor position."""
        return self.spacing / 4

    @staticmethod
    def layout_of(kinds) -> np.ndarray:
        """Light-layout version of each event: the number of redistributions so far."""
        return np.cumsum([kind == REDISTRIBUTION for kind in kinds]).astype(np.int64)


def ground_truth_from_motor(povs: np.ndarray, cfg: dict) -> dict:
    """Ground truth of POVs recorded without it (a graph run): sensor poses
    from the forward model, object grid position from the tip displacement
    since the initial pose; ``grid`` the world's object positions, as the
    offline run writes them (a MuJoCo world lays its grid about the object's
    start, ``bodies.mujoco_world._grid_about``)."""
    from sensorispace_ros.core.world import grid_spacing, position_grid

    povs = np.asarray(povs, dtype=float)
    simulated = cfg.get("body", {}).get("kind", "simulated") == "simulated"
    # A MuJoCo body's chain is its model's (bodies.mujoco_model.planar_chain).
    body_world = None if simulated else run_world(cfg)
    body_arm = Arm.from_config(cfg["arm"]) if simulated else body_world.arm
    true_poses = body_arm.forward(povs[:, 0]).reshape(-1, 3)
    m0 = np.asarray(cfg["arm"]["initial_motor_state"], dtype=float)
    world = cfg["world"]
    grid = position_grid(world["grid_half_width"], world["grid_count"])
    spacing = grid_spacing(world["grid_half_width"], world["grid_count"])
    displacement = true_poses[:, :2] - body_arm.forward(m0)[:2]
    nearest = np.argmin(np.linalg.norm(displacement[:, None, :] - grid[None], axis=-1), axis=1)
    on_grid = np.linalg.norm(grid[nearest] - displacement, axis=1) < spacing / 4
    if body_world is not None:
        grid = body_world.grid
    return {"true_poses": true_poses, "true_positions": true_poses[:, :2].copy(),
            "motor_states": povs[:, 0], "grid": grid, "grid_spacing": np.float64(spacing),
            "grid_index": np.where(on_grid, nearest, -1), "initial_motor_state": m0}


def paper_compensated_positions(world) -> np.ndarray:
    """Sensor positions ``(Q, 2)`` the paper strategy compensates (with its
    initial POV), for the coverage denominator."""
    return paper_compensated_poses(world)[:, :2].copy()


def paper_compensated_poses(world) -> np.ndarray:
    """Sensor poses ``(Q, 3)`` the paper strategy compensates (with its initial POV)."""
    from sensorispace_ros.core.paper import exploration   # numba and scipy: on first use

    explored = exploration.explore_paper(m0=world.m0, grid=world.grid, events=world.events,
                             initial_center=world.initial_center, body_arm=world.arm)
    return explored.true_poses.copy()


def _turning(world, orientations=None) -> dict:
    """``NaiveGroundTruth``'s rotation fields of ``world`` (none when the object
    only translates). ``orientations``: the object's at each of the agent's
    events (a run on its own clock reacts to the worlds it saw); default: at
    each change of the schedule."""
    count = int(world.params.get("rotation_count", 0))
    if count < 2:
        return {}
    if orientations is None:
        orientations = [0.0] + [e.orientation for e in world.events]
    return {"orientations": np.asarray(orientations, dtype=float),
            "paper_poses": paper_compensated_poses(world), "rotation_count": count}


def compensable_grid(world) -> np.ndarray:
    """Grid indices whose object position a body can follow, from its geometry
    alone: the eye's initial pose moved by the object's displacement lies in
    the arm's workspace (``Arm.reachable``) for the eye's initial orientation."""
    pose0 = world.arm.forward(world.m0)
    targets = pose0[:2] + world.grid - np.asarray(world.initial_center, dtype=float)
    return np.flatnonzero(world.arm.reachable(targets, float(pose0[2])))


def body_truth(world: World) -> dict:
    """``body.*`` of a run's world: joints, the eye pose's rank, the points
    of view's dimension, receptors, the compensable grid positions, and the
    imperfections the body was given (to set beside what the agent measured)."""
    imperfect = world.imperfections
    return {"body.joints": world.arm.n_joints, "body.pose_rank": world.arm.pose_rank,
            "body.pov_dim": world.arm.pov_dim, "body.receptors": int(len(world.receptors)),
            "body.compensable_positions": int(len(compensable_grid(world))),
            "body.sensor_noise": imperfect.noise, "body.sensor_quantum": imperfect.quantum,
            "body.sensor_dropout": imperfect.dropout,
            "body.motor_noise": imperfect.motor_noise}


def naive_truth_of_run(run, world, paper_positions: np.ndarray | None = None
                       ) -> NaiveGroundTruth:
    """Ground truth of an offline naive run (``core.naive.run.run_naive``):
    what the driver saw at each of the agent's events, the schedule's grid
    positions, the forward model of each POV. ``paper_positions``: the
    coverage denominator, ``paper_compensated_positions(world)`` when not given."""
    if paper_positions is None:
        paper_positions = paper_compensated_positions(world)
    explored = run.exploration
    povs = np.asarray(run.povs)
    return NaiveGroundTruth(
        centers=np.asarray(explored.centers, dtype=float), layout=np.asarray(explored.layout),
        kinds=list(explored.kinds),
        grid_index=(np.asarray([-1] + [e.grid_index for e in world.events], dtype=np.int64)
                    if getattr(explored, "grid_index", None) is None
                    else np.asarray(explored.grid_index, dtype=np.int64)),
        true_poses=world.arm.forward(povs[:, 0]) if len(povs) else np.zeros((0, 3)),
        initial_motor_state=np.asarray(world.m0, dtype=float),
        paper_positions=np.asarray(paper_positions, dtype=float).reshape(-1, 2),
        arm=world.arm, spacing=float(world.spacing),
        **_turning(world, getattr(explored, "orientations", None)))


def naive_truth_of_changes(truth: RunTruth, n_changes: int, poses: np.ndarray,
                           recorded: Mapping[int, tuple] | None = None) -> NaiveGroundTruth:
    """Ground truth of a naive graph run of ``n_changes`` changes (agent event
    t = change t): ``recorded[k] = (centre (2,), kind, grid index)`` of the
    changes the environment was seen announcing (a bag's
    ``/environment/event``), the seeded schedule of the run's world for the
    others, the initial centre and the coverage denominator. ``poses``
    ``(P, 3)``: the sensor pose of each POV."""
    recorded = recorded or {}
    world = truth.world
    if n_changes > len(world.events):
        raise ValueError(f"the run ended after {n_changes} changes; its configuration "
                         f"schedules {len(world.events)}")
    centers, kinds, grid_index = [np.asarray(world.initial_center, float)], ["initial"], [-1]
    for k in range(1, n_changes + 1):
        if k in recorded:
            center, kind, grid = recorded[k]
        else:
            scheduled = world.events[k - 1]
            center, kind, grid = scheduled.center, scheduled.kind, scheduled.grid_index
        centers.append(np.asarray(center, dtype=float))
        kinds.append(kind)
        grid_index.append(int(grid))
    return NaiveGroundTruth(
        centers=np.asarray(centers), layout=NaiveGroundTruth.layout_of(kinds), kinds=kinds,
        grid_index=np.asarray(grid_index, dtype=np.int64), true_poses=poses,
        initial_motor_state=np.asarray(world.m0, dtype=float),
        paper_positions=truth.paper_positions, arm=world.arm, spacing=float(world.spacing),
        **_turning(world))
