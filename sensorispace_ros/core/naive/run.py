"""Offline driver of the naive agent.

The driver owns the world (``core.paper.exploration.World``): it steps a
``SimulatedBody`` through the event schedule and hands the agent only
``SensingOnly(body)`` and the passive sensation after each change. It notes
what the environment did at each of the agent's events (object centre,
light layout, event kind) for the evaluator, which joins it with ground
truth afterwards (``evaluation.naive.evaluate_naive_run``); the agent never
sees any of it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from sensorispace_ros.core.body import SensingOnly, SimulatedBody
from sensorispace_ros.core.naive.agent import NaiveAgent
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.world import REDISTRIBUTION


@dataclass
class NaiveExploration:
    """The naive agent after it went through a world's schedule, with what the
    environment did at each of the agent's events ``t`` (0 = the start):
    ``centers`` object centre, ``layout`` light-layout version (+1 at each
    redistribution), ``kinds`` event kinds (``"initial"`` first);
    ``exploration_s`` / ``equality_s`` wall time of the schedule and of the
    equality pass."""

    agent: NaiveAgent
    centers: list
    layout: list
    kinds: list
    exploration_s: float
    equality_s: float
    grid_index: np.ndarray | None = None     # per event; None: event t is world.events[t - 1]
    orientations: np.ndarray | None = None   # the object's, per event; None: as grid_index


@dataclass
class NaiveRunResult:
    """What one naive run produced: ``povs`` ``(P, N, M)`` the agent's POVs,
    ``pairs``/``set_ids`` its equality sets, ``metrics`` its own timings
    (``naive.timings_s.*``, ``naive.seconds_by_stage.*``) and its measure of
    itself (``naive.pose_rank``, ``naive.pov_dim``, ``naive.rank_gap``, ...:
    ``structure.BodyStructure.metrics``), ``timings_s`` per
    stage, and the ``exploration`` (with the agent) for the evaluator."""

    povs: np.ndarray
    pairs: np.ndarray
    set_ids: np.ndarray
    metrics: dict
    timings_s: dict
    exploration: NaiveExploration = field(repr=False)
    clock: object = field(repr=False, default=None)    # ground truth: core.clocked_run.ClockTruth

    @property
    def agent(self) -> NaiveAgent:
        return self.exploration.agent

def explore_naive(world, params: NaiveParams | None = None, *, progress=None,
                  equality_pass: bool = False, body_wrapper=SensingOnly) -> NaiveExploration:
    """Step the naive agent through ``world.events``: what the ROS graph
    computes. Arguments as ``run_naive``'s."""
    params = params if params is not None else NaiveParams()
    started = time.perf_counter()
    body = world.body(lights=world.initial_lights)
    agent = NaiveAgent(body_wrapper(body), params)

    centers = [np.asarray(world.initial_center, float)]
    layout = [0]                    # light layout version: +1 at each redistribution
    kinds = ["initial"]
    agent.start(world.m0, seed=world.seed)
    n_events = len(world.events)
    for k, event in enumerate(world.events):
        body.set_lights(event.lights)
        centers.append(np.asarray(event.center, float))
        layout.append(layout[-1] + (event.kind == REDISTRIBUTION))
        kinds.append(event.kind)
        agent.react(_passive_sensation(body))
        if progress is not None and callable(progress) and (k + 1) % 100 == 0:
            progress(k + 1, n_events)
    agent.relax_povs()
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


def run_naive(world, params: NaiveParams | None = None, *, progress=None,
              equality_pass: bool = False, body_wrapper=SensingOnly) -> NaiveRunResult:
    """Run the naive agent through ``world.events``.

    ``equality_pass``: after exploring, replay the schedule once more with
    the agent in simulation-2 mode (sweep and match only).
    ``body_wrapper``: what the agent receives instead of the simulator
    (default ``SensingOnly``: ``sense`` and the vector sizes).
    ``progress(done, total)`` is called every 100 events.
    """
    return summarize_naive(explore_naive(world, params, progress=progress,
                                         equality_pass=equality_pass, body_wrapper=body_wrapper))


def summarize_naive(explored: NaiveExploration, clock_truth=None) -> NaiveRunResult:
    """The run's products and the agent's own timings and measures, from an
    exploration (``clock_truth``: the ground truth of a world on its own clock)."""
    agent = explored.agent
    pov_s = agent.seconds_by_stage.get("pov", 0.0)
    pairs, set_ids = agent.equality_sets()
    timings = {"exploration": explored.exploration_s - pov_s, "points_of_view": pov_s,
               "equality_sets": explored.equality_s}
    metrics = {f"naive.timings_s.{k}": float(v) for k, v in timings.items()}
    metrics.update({f"naive.seconds_by_stage.{k}": float(v)
                    for k, v in agent.seconds_by_stage.items()})
    if agent.structure is not None:
        metrics.update(agent.structure.metrics())
    return NaiveRunResult(povs=agent.points_of_view, pairs=pairs, set_ids=set_ids,
                          metrics=metrics, timings_s=timings, exploration=explored,
                          clock=clock_truth)


def _passive_sensation(body: SimulatedBody) -> np.ndarray:
    """What the resting eye sees after a change (not a query of the agent's)."""
    return body.sense_at_rest(kernel="numpy")[0]
