"""Offline driver and ground-truth evaluation of the naive agent (issue #3).

This is the evaluator's side: it owns the world (``core.exploration.World``),
steps a ``SimulatedBody`` through the event schedule, hands the agent only
``SensingOnly(body)`` and the passive sensation after each change, and
afterwards joins what the agent produced with ground truth (true poses via
``arm.forward``, object positions, event kinds). The agent never sees any
of it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from sensorispace_ros.core import arm, retina
from sensorispace_ros.core.body import SensingOnly, SimulatedBody
from sensorispace_ros.core.naive.agent import STAGES as NAIVE_STAGES
from sensorispace_ros.core.naive.agent import NaiveAgent, NaiveAgentRecords
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.world import REDISTRIBUTION

WRONG_POSE_TOL = 1e-3


@dataclass
class NaiveGroundTruth:
    """The evaluator's side of a naive run, indexed by the agent's event ``t``
    (0 = the start): ``centers`` ``(T+1, 2)`` object centre, ``layout``
    ``(T+1,)`` light-layout version (+1 at each redistribution), ``kinds``
    event kinds (``"initial"`` first), ``grid_index`` ``(T+1,)`` the object's
    grid position (-1 at the start); ``true_poses`` ``(P, 3)`` the sensor
    pose of each POV's first sample; ``initial_motor_state``;
    ``paper_positions`` ``(Q, 2)`` the coverage denominator
    (``paper_compensated_positions``)."""

    centers: np.ndarray
    layout: np.ndarray
    kinds: list
    grid_index: np.ndarray
    true_poses: np.ndarray
    initial_motor_state: np.ndarray
    paper_positions: np.ndarray

    @staticmethod
    def layout_of(kinds) -> np.ndarray:
        """Light-layout version of each event: the number of redistributions so far."""
        return np.cumsum([kind == REDISTRIBUTION for kind in kinds]).astype(np.int64)


@dataclass
class NaiveRunResult:
    """Everything one naive run produced, joined with ground truth.

    ``povs`` ``(P, N, 4)`` the agent's POVs; ``true_poses`` ``(P, 3)`` their
    sensor poses; ``grid_index`` ``(P,)`` the object's grid position when
    the POV was found (-1 for the initial POV), as in the paper strategy;
    ``pairs``/
    ``set_ids`` the agent's equality sets; ``metrics`` dotted keys
    (``exploration.*``, ``naive.*``); ``timings_s`` per stage.
    """

    povs: np.ndarray
    true_poses: np.ndarray
    grid_index: np.ndarray
    pairs: np.ndarray
    set_ids: np.ndarray
    metrics: dict
    timings_s: dict
    agent: NaiveAgent = field(repr=False, default=None)


@dataclass
class NaiveExploration:
    """The naive agent after it went through a world's schedule, with what the
    evaluator saw at each of the agent's events (``centers``, ``layout``,
    ``kinds``: see ``NaiveGroundTruth``); ``exploration_s`` /
    ``equality_s`` wall time of the schedule and of the equality pass."""

    agent: NaiveAgent
    centers: list
    layout: list
    kinds: list
    exploration_s: float
    equality_s: float


def explore_naive(world, params: NaiveParams | None = None, seed: int = 0, progress=None, *,
                  equality_pass: bool = False, body_wrapper=SensingOnly) -> NaiveExploration:
    """Step the naive agent through ``world.events``: what the ROS graph
    computes, without any evaluation (``run_naive`` adds it). Arguments as
    ``run_naive``'s."""
    params = params if params is not None else NaiveParams()
    started = time.perf_counter()
    body = SimulatedBody(world.receptors, world.initial_lights)
    agent = NaiveAgent(body_wrapper(body), params, seed)

    centers = [np.asarray(world.initial_center, float)]
    layout = [0]                    # light layout version: +1 at each redistribution
    kinds = ["initial"]
    agent.start(world.m0)
    n_events = len(world.events)
    for k, event in enumerate(world.events):
        body.set_lights(event.lights)
        centers.append(np.asarray(event.center, float))
        layout.append(layout[-1] + (event.kind == REDISTRIBUTION))
        kinds.append(event.kind)
        agent.react(_passive_sensation(body))
        if progress is not None and callable(progress) and (k + 1) % 100 == 0:
            progress(k + 1, n_events)
    exploration_s = time.perf_counter() - started

    equality_s = 0.0
    if equality_pass:
        t0 = time.perf_counter()
        body.set_lights(world.initial_lights)
        agent.begin_equality_pass()
        for event in world.events:
            body.set_lights(event.lights)
            agent.react(_passive_sensation(body))
        equality_s = time.perf_counter() - t0
    return NaiveExploration(agent, centers, layout, kinds, exploration_s, equality_s)


def run_naive(world, params: NaiveParams | None = None, seed: int = 0, progress=None, *,
              equality_pass: bool = False, paper_positions: np.ndarray | None = None,
              body_wrapper=SensingOnly) -> NaiveRunResult:
    """Run the naive agent through ``world.events`` and evaluate it.

    ``equality_pass``: after exploring, replay the schedule once more with
    the agent in simulation-2 mode (sweep and match only).
    ``paper_positions`` ``(Q, 2)``: the sensor positions the paper strategy
    compensates for this world (the coverage denominator); computed with
    ``exploration.explore_paper`` when not given.
    ``body_wrapper``: what the agent receives instead of the simulator
    (default ``SensingOnly``: ``sense`` and the vector sizes).
    ``progress(done, total)`` is called every 100 events.
    """
    explored = explore_naive(world, params, seed, progress, equality_pass=equality_pass,
                             body_wrapper=body_wrapper)
    agent = explored.agent

    t0 = time.perf_counter()
    if paper_positions is None:
        paper_positions = paper_compensated_positions(world)
    metrics, true_poses, grid_index = evaluate_naive_run(
        agent, world, np.asarray(explored.centers), np.asarray(explored.layout), explored.kinds,
        paper_positions)
    evaluation_s = time.perf_counter() - t0

    pov_s = agent.seconds_by_stage.get("pov", 0.0)
    pairs, set_ids = agent.equality_sets()
    timings = {"exploration": explored.exploration_s - pov_s, "points_of_view": pov_s,
               "equality_sets": explored.equality_s, "evaluation": evaluation_s}
    metrics.update({f"naive.timings_s.{k}": float(v) for k, v in timings.items()})
    metrics.update({f"naive.seconds_by_stage.{k}": float(v)
                    for k, v in agent.seconds_by_stage.items()})
    return NaiveRunResult(povs=agent.points_of_view, true_poses=true_poses,
                          grid_index=grid_index, pairs=pairs, set_ids=set_ids, metrics=metrics,
                          timings_s=timings, agent=agent)


def _passive_sensation(body: SimulatedBody) -> np.ndarray:
    """What the resting eye sees after a change (not a query of the agent's)."""
    pose = arm.forward(body.motor_state)
    return retina.sensation(pose, body.lights_world, body.receptor_positions)


def paper_compensated_positions(world) -> np.ndarray:
    """Sensor positions ``(Q, 2)`` the paper strategy compensates (with its
    initial POV), for the coverage denominator."""
    from sensorispace_ros.core.paper.exploration import explore_paper

    explored = explore_paper(m0=world.m0, grid=world.grid, events=world.events,
                             initial_center=world.initial_center)
    return explored.true_poses[:, :2].copy()


def evaluate_naive_run(agent: NaiveAgent, world, centers: np.ndarray, layout: np.ndarray,
                       kinds: list, paper_positions: np.ndarray):
    """Ground-truth metrics of a finished offline run (``centers[t]``,
    ``layout[t]``, ``kinds[t]``: object centre, light-layout version and event
    kind seen at the agent's event ``t``; event 0 is the start)."""
    records = NaiveAgentRecords.from_agent(agent)
    povs = records.povs
    truth = NaiveGroundTruth(
        centers=np.asarray(centers, dtype=float), layout=np.asarray(layout), kinds=list(kinds),
        grid_index=np.asarray([-1] + [e.grid_index for e in world.events], dtype=np.int64),
        true_poses=arm.forward(povs[:, 0]) if len(povs) else np.zeros((0, 3)),
        initial_motor_state=np.asarray(world.m0, dtype=float),
        paper_positions=np.asarray(paper_positions, dtype=float).reshape(-1, 2))
    return evaluate_naive_records(records, truth)


def evaluate_naive_records(records: NaiveAgentRecords, truth: NaiveGroundTruth):
    """Ground-truth metrics (``exploration.*``, ``pov.*``, ``naive.*``) of what
    a naive agent produced, offline or in the ROS graph. Returns
    ``(metrics, true_poses (P, 3), grid_index (P,))``."""
    povs = records.povs
    true_poses = np.asarray(truth.true_poses, dtype=float).reshape(-1, 3)
    if len(true_poses) != len(povs):
        raise ValueError(f"truth.true_poses: {len(true_poses)} poses for {len(povs)} POVs")
    unknown = (set(records.queries_by_stage) | set(records.calls_by_stage)) - set(NAIVE_STAGES)
    if unknown:
        raise ValueError(f"records.queries_by_stage: stages {sorted(unknown)} not in NAIVE_STAGES")
    centers, layout, kinds = truth.centers, truth.layout, truth.kinds
    paper_positions = truth.paper_positions
    pose0 = arm.forward(truth.initial_motor_state)
    drift = (float(np.max(arm.pose_error(arm.forward(povs), true_poses[:, None, :])))
             if len(povs) else 0.0)

    # Each accepted compensation against the pose its anchor asks for.
    events = records.compensation_event
    anchors = records.compensation_anchor_event
    n_comp = len(events)
    worst, wrong = 0.0, 0
    if n_comp:
        target = arm.forward(records.compensation_anchor_motor_state)
        target[:, :2] += centers[events] - centers[anchors]
        error = arm.pose_error(arm.forward(records.compensation_motor_state), target)
        worst = float(np.max(error))
        wrong = int(np.sum(error > WRONG_POSE_TOL))
    across_layouts = int(np.sum(layout[events] != layout[anchors]))
    on_redistribution = int(sum(kinds[t] == REDISTRIBUTION for t in events))

    # Coverage (issue #3): distinct compensated sensor positions over the
    # number the paper strategy compensates. The naive agent's positions need
    # not be the paper's: an anchor recorded while the object is on the grid
    # gives positions p0 + (grid differences), the start's anchor (object at
    # the off-grid initial centre) gives the paper's p0 + (grid - centre).
    # ``coverage_of_paper_positions`` counts the paper's positions reached.
    distinct = 0
    covered = 0
    if len(povs):
        pairs_close = cKDTree(true_poses[:, :2]).query_pairs(WRONG_POSE_TOL, output_type="ndarray")
        duplicate = np.zeros(len(povs), dtype=bool)
        duplicate[pairs_close.max(axis=1) if len(pairs_close) else []] = True
        distinct = int(np.sum(~duplicate))
        if len(paper_positions):
            distance, _ = cKDTree(true_poses[:, :2]).query(paper_positions, k=1)
            covered = int(np.sum(distance <= WRONG_POSE_TOL))
    orientation_error = (float(np.max(np.abs(arm.wrap_angle(true_poses[:, 2] - pose0[2]))))
                         if len(povs) else 0.0)

    # The object's grid position when each POV was found (event 0: the start).
    grid_index = (np.asarray(truth.grid_index)[np.asarray(records.pov_events, dtype=int)]
                  if len(povs) else np.zeros(0, dtype=int))

    pairs, set_ids = records.pairs, records.set_ids
    set_deviation = 0.0
    if len(pairs):
        displacement = true_poses[pairs[:, 1], :2] - true_poses[pairs[:, 0], :2]
        _, first, inverse = np.unique(set_ids, return_index=True, return_inverse=True)
        reference = displacement[first[inverse.reshape(-1)]]
        set_deviation = float(np.max(np.abs(displacement - reference)))

    pov_q = np.asarray(records.pov_queries, dtype=float)
    state_changes = sum(k == REDISTRIBUTION for k in kinds)
    metrics = {
        "exploration.events": len(kinds) - 1,
        "exploration.state_changes": int(state_changes),
        "exploration.compensated": int(records.compensated),
        "exploration.state_changes_compensated": on_redistribution,
        "pov.count": int(len(povs)),
        "pov.max_pose_drift": drift,
        "naive.queries_total": int(records.queries_total),
        "naive.calls_total": int(records.calls_total),
        "naive.queries_per_pov": float(pov_q.mean()) if len(pov_q) else 0.0,
        "naive.queries_per_pov_max": int(pov_q.max()) if len(pov_q) else 0,
        # Every row of an event that found a compensation except its POV walks
        # (sweep, rank tests, searches, rest command), averaged over those events.
        "naive.queries_per_compensation":
            records.compensation_queries / records.compensated if records.compensated else 0.0,
        # Search rows (LM) of the whole run per accepted compensation.
        "naive.search_queries_per_compensation":
            records.queries_by_stage.get("compensation", 0) / max(n_comp, 1),
        "naive.coverage": distinct / max(len(paper_positions), 1),
        "naive.distinct_positions": distinct,
        "naive.duplicate_povs": int(len(povs) - distinct),
        "naive.paper_positions": int(len(paper_positions)),
        "naive.coverage_of_paper_positions": covered / max(len(paper_positions), 1),
        "naive.wrong_poses": wrong,
        "naive.worst_pose_error": worst,
        "naive.state_changes_accepted": on_redistribution,
        "naive.accepted_across_redistribution": across_layouts,
        "naive.compensations_accepted": int(n_comp),
        "naive.compensations_searched": int(np.sum(records.compensation_searched)),
        "naive.max_orientation_error": orientation_error,
        "naive.equality_sets": int(len(np.unique(set_ids))),
        "naive.equality_pairs": int(len(pairs)),
        "naive.equality_set_max_deviation": set_deviation,
    }
    for stage in NAIVE_STAGES:
        metrics[f"naive.queries_by_stage.{stage}"] = int(records.queries_by_stage.get(stage, 0))
    for stage in NAIVE_STAGES:
        metrics[f"naive.calls_by_stage.{stage}"] = int(records.calls_by_stage.get(stage, 0))
    return metrics, true_poses, grid_index
