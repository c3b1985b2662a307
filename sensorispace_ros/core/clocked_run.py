"""Offline driver of the naive agent in a world on its own clock
(``world.clock: rows``).

The world changes after a seeded number of rows (``core.world_clock``),
wherever that falls; the agent gets no notice. It holds still at its
resting state while its sensation stays within its noise band
(``change_detection.band``, one ``hold`` call), reacts when it leaves it
(confirmed by sensing the state once more). Every call of a reaction ends
with sentinel rows (``change_detection.Tripwire``: the resting state and a lookout,
``ClockedAgent.sense_sentinels``); after each reaction the
agent senses again its resting state of before, its new one and the
witnesses of its sweep: if any moved, the world changed while it worked,
and the reaction is undone
(``ClockedAgent.restore``; its rows stay counted as work lost) and made
again in the world as it is at that row.

The driver notes, for the evaluator, the world state (ground truth) at each
kept reaction's first and last row and every test the agent made
(``change_detection.ChangeLog``); the agent never sees any of it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from sensorispace_ros import config
from sensorispace_ros.core.body import SensingOnly
from sensorispace_ros.core.naive import change_detection
from sensorispace_ros.core.naive.change_detection import ChangeLog
from sensorispace_ros.core.naive.clocked_agent import ClockedAgent, WorldChanged
from sensorispace_ros.core.naive.agent import EXPLORING
from sensorispace_ros.core.naive.params import NaiveParams
from sensorispace_ros.core.naive.run import (NaiveExploration, NaiveRunResult, run_naive,
                                             summarize_naive)
from sensorispace_ros.core.world import REDISTRIBUTION
from sensorispace_ros.core.world_clock import ClockedBody, clock_plays, world_on_clock


@dataclass
class ClockTruth:
    """Ground truth of a clocked run: ``change_row`` ``(C,)`` the rows the
    world changed before, ``rest_jumps`` how far each moved the sensation at
    the arm's state then, ``event_states`` ``(T + 1, 2)`` the world state at
    each kept reaction's first and last row (event 0: the start), the tests
    the agent made (``log``), ``lost_rows`` rows of undone reactions,
    ``undone`` their number, ``salvaged`` the POVs kept from them,
    ``rows`` / ``held_rows`` the clock at the end, ``lights`` of each world
    state; ``lost_by_stage`` the lost rows per stage of the agent,
    ``cuts_by_stage`` the stage each change that cut a reaction or a
    pending walk fell in (``check``: the checks after a reaction),
    ``pending_povs`` the POVs added by walks of pending solutions,
    ``crossed`` the reactions kept whose walk went on through a change;
    ``restarts`` the times the agent resumed from a snapshot (graph only),
    ``rows_lost_to_restart`` the rows it sent between the snapshot and its death;
    ``start_lost_rows`` the rows of the starts a change cut (in ``lost_rows``)."""

    change_row: np.ndarray
    rest_jumps: np.ndarray
    event_states: np.ndarray
    log: ChangeLog
    lost_rows: int
    undone: int
    salvaged: int
    rows: int
    held_rows: int
    lost_by_stage: dict = field(default_factory=dict)
    cuts_by_stage: dict = field(default_factory=dict)
    pending_povs: int = 0
    crossed: int = 0
    state_of: object = field(repr=False, default=None)
    lights: list = field(repr=False, default_factory=list)   # of each world state
    restarts: int = 0
    rows_lost_to_restart: int = 0
    start_lost_rows: int = 0


def run_on_clock(world, params: NaiveParams, clock: str, *, interval: float,
                 progress=None) -> NaiveRunResult:
    """The naive agent's run in ``world`` as ``world.clock`` has it:
    ``agent`` (the world waits for the agent: ``run.run_naive``) or ``rows``
    (it changes every ``interval`` rows on average, unannounced:
    ``explore_clocked``; no equality pass of the lockstep kind)."""
    if clock == "agent":
        return run_naive(world, params, progress=progress)
    if clock != "rows":
        raise config.ConfigError(f"world.clock: offline runs take agent or rows, got {clock!r} "
                                 "(wall needs the graph: docs/clock.md)")
    explored, truth = explore_clocked(world, params, interval=interval,
                                      sweep_budget=params.clock_sweep_budget,
                                      equality_changes=params.clock_equality_changes,
                                      progress=progress)
    return summarize_naive(explored, truth)


def explore_clocked(world, params: NaiveParams | None = None, *, interval: float,
                    sweep_budget: int = 64, equality_changes: int = 0, progress=None):
    """Run the agent through ``world.events`` on a row clock of mean
    ``interval`` rows; then, with ``equality_changes``, through the schedule
    once more in simulation 2 (``begin_equality_pass``) for that many of the
    changes it detects. Returns ``(NaiveExploration, ClockTruth)``."""
    params = params if params is not None else NaiveParams()
    started = time.perf_counter()
    events = list(world.events) * clock_plays(equality_changes)
    body = world_on_clock(world.body(lights=world.initial_lights), world, events,
                          interval=interval)
    run = begin_run(body, world.m0, world.seed, params, sweep_budget)
    tick = None if progress is None or not callable(progress) else \
        (lambda: progress(body.state, len(events)))
    drive(run, equality_changes=equality_changes,
          second_round=lambda: body.state > len(world.events), after_reaction=tick)
    exploration_s = time.perf_counter() - started
    return run.exploration(world, events, exploration_s), run.truth()


def begin_run(body, m0: np.ndarray, seed: int, params: NaiveParams, sweep_budget: int
              ) -> "ClockedRun":
    """A run whose agent has started in one world (``start_clocked``), its
    start noted as event 0."""
    agent, first_row, lost = start_clocked(body, m0, seed, params, sweep_budget)
    run = ClockedRun(agent, body)
    run.lost_rows = run.start_lost_rows = lost
    run.event_states.append((body.state_at(first_row), body.state_at(body.row - 1)))
    return run


def drive(run: "ClockedRun", *, equality_changes: int, second_round, after_reaction=None,
          resume: bool = False) -> None:
    """The agent's life on the clock: it holds still at rest, walks the
    solutions a change cut, reacts to each change it detects; once
    ``second_round()`` says the world replays its schedule, or the agent
    finds that exploring no longer pays (``ClockedAgent.explored``), it spends
    ``equality_changes`` reactions on simulation 2 (``begin_equality_pass``).
    Ends when the body has no change left (a hold answers None). The loop's
    state is the run's (``reference``, ``reference_row``, ``equality_left``),
    so that a run saved by ``after_reaction`` goes on with ``resume``."""
    agent = run.agent
    if not resume:
        run.reference, run.reference_row = agent.anchor_sensation, run.body.row - 1
        run.equality_left = int(equality_changes)
    while True:
        sensed = run.walk_pending(run.reference, run.reference_row) \
            if agent.phase == EXPLORING else None
        if sensed is None:
            sensed = run.hold(run.reference, run.reference_row)
            if sensed is None:
                break
            if sensed is False:
                continue
        if agent.phase == EXPLORING and (second_round() or agent.explored()) \
                and run.equality_left:
            run.reference, run.reference_row = run.react(sensed, agent.begin_equality_pass)
            continue
        run.reference, run.reference_row = run.react(sensed)
        if agent.phase != EXPLORING:
            run.equality_left -= 1
            if run.equality_left <= 0:
                break
        if after_reaction is not None:
            after_reaction()


def start_clocked(body, m0: np.ndarray, seed: int, params: NaiveParams, sweep_budget: int):
    """A started agent whose start saw one world: the start state is sensed
    before and after ``start`` and compared by the noise the start measured,
    and watches every call of the start once that noise is known
    (``ClockedAgent.start``); a start the world changed under is made again
    by a new agent (its rows counted as lost). A start is kept only with at
    least the highest pose rank a start cut after its structure measured:
    a world that shows the start state less than another did gives a lower
    rank, never a higher one. Returns the agent, the start's first row and
    the rows lost."""
    lost, rank_seen = 0, 0
    while True:
        first_row = body.row
        agent = ClockedAgent(SensingOnly(body), params, sweep_budget=sweep_budget)
        before = agent.sense_again(m0)[0]
        try:
            agent.start(m0, seed=seed)
        except WorldChanged:
            lost += agent.queries_total
            if agent.structure is not None:         # measured before the cut, in one world
                rank_seen = max(rank_seen, agent.structure.pose_rank)
            continue
        after = agent.sense_again(m0)[0]
        rest_now = agent.sense_again(agent.rest_motor_state)[0]
        if not (change_detection.differs(agent.noise_sd, before, after) or
                change_detection.differs(agent.noise_sd, agent.anchor_sensation, rest_now)) \
                and agent.structure.pose_rank >= rank_seen:
            return agent, first_row, lost
        lost += agent.queries_total


class ClockedRun:
    """The reactions of one clocked run and what ground truth notes of them."""

    def __init__(self, agent: ClockedAgent, body: ClockedBody):
        self.agent, self.body = agent, body
        self.log = ChangeLog()
        self.event_states: list[tuple[int, int]] = []
        self.lost_rows = 0
        self.start_lost_rows = 0       # of ``lost_rows``: the starts a change cut
        self._sentinel_row = -1        # the row the resting state was last sensed at
        self.undone = 0
        self.salvaged = 0
        self.pending_povs = 0
        self.crossed = 0
        self.lost_by_stage: dict[str, int] = {}
        self.cut_in: dict[str, int] = {}
        # ``drive``'s loop: the sensation at rest held, the row it was sensed
        # at, the reactions of simulation 2 left.
        self.reference, self.reference_row, self.equality_left = None, -1, 0
        # Resumptions after the agent's process died (graph.nodes.agent_restart),
        # and the rows its commands sent between its last snapshot and its death.
        self.restarts = 0
        self.rows_lost_to_restart = 0

    def hold(self, reference: np.ndarray, reference_row: int):
        """Hold still until the sensation at rest leaves its band; confirm by
        sensing once more. Returns that sensation, False (not confirmed) or
        None (the world has no change left)."""
        agent, body = self.agent, self.body
        low, high = change_detection.band(agent.noise_sd, reference)
        rest = agent.rest_motor_state
        if body.hold(rest, low, high) is None:
            return None
        sensed = self._sense_sentinels(rest)
        changed = change_detection.differs(agent.noise_sd, reference, sensed)
        self.log.add(reference_row, self._sentinel_row, changed, rest, "hold")
        return sensed if changed else False

    def react(self, sensed_at_rest: np.ndarray, reaction=None):
        """React (``reaction``, default ``agent.react``) until a reaction is
        not cut by a change; ``sensed_at_rest`` was sensed by the last call
        (``ClockedAgent.sense_sentinels``).
        Returns the new reference sensation and the row it was sensed at."""
        agent, body = self.agent, self.body
        reference_row = self._sentinel_row
        while True:
            saved = agent.checkpoint()
            before_rest = agent.rest_motor_state
            first_row, rows_before = body.row, agent.queries_total
            stages_before, cut_in, sent = agent.queries_by_stage, "check", agent.rows_sent
            try:
                agent.watched(reaction or agent.react, sensed_at_rest)
                after_rest = agent.rest_motor_state
                again, moved = agent.check_reaction([before_rest, after_rest])
                if agent.crossing is not None:
                    # Kept; the world its sweep saw is gone: react again at
                    # once, for a snapshot of the world as it is.
                    self._crossed(reference_row, first_row, first_row - sent, before_rest, again)
                    sensed_at_rest = self._sense_sentinels(before_rest)
                    reference_row = self._sentinel_row
                    continue
                cut = change_detection.differs(agent.noise_sd, sensed_at_rest, again[0]) or \
                    (agent.phase == EXPLORING and
                     change_detection.differs(agent.noise_sd, agent.anchor_sensation, again[1])) \
                    or moved
            except WorldChanged:
                cut, cut_in = True, agent.cut_stage
            self.log.add(reference_row, body.row - 1, cut, before_rest, "cut")
            if not cut:
                self.event_states.append((body.state_at(first_row), body.state_at(body.row - 1)))
                return again[1], body.row - 1
            self._undo(saved, rows_before, stages_before, cut_in)
            # The world of this row, at the resting state the undone reaction started from.
            sensed_at_rest = self._sense_sentinels(before_rest)
            reference_row = self._sentinel_row

    def _sense_sentinels(self, rest: np.ndarray) -> np.ndarray:
        """``ClockedAgent.sense_sentinels``; notes the row the resting state
        was sensed at (the call's first: the body's position before it)."""
        row = self.body.row
        sensed = self.agent.sense_sentinels(rest)
        self._sentinel_row = row
        return sensed

    def _crossed(self, reference_row: int, first_row: int, offset: int, rest: np.ndarray,
                 again: np.ndarray) -> None:
        """Note a reaction whose walk went on through a change
        (``ClockedAgent._cross``): its search's rows, up to the last sentinel
        before the change (row ``offset + crossing["passed"] - 1``), saw one
        world, its walk another; ``again``: its resting state sensed after it."""
        agent, body = self.agent, self.body
        crossing = agent.crossing
        self.log.add(reference_row, offset + crossing["fired"] - 1, True, rest, "walk")
        moved = change_detection.differs(agent.noise_sd, crossing["reference"], again[0])
        self.log.add(offset + crossing["latest"] - 1, body.row - 2, moved, rest, "cut")
        self.crossed += 1
        self.event_states.append((body.state_at(first_row),
                                  body.state_at(offset + crossing["passed"] - 1)))

    def walk_pending(self, reference: np.ndarray, reference_row: int):
        """Walk the pending solutions one by one while the world stays
        (``reference``: the sensation at rest, sensed at ``reference_row``);
        returns None, or the sensation at rest of a world that changed."""
        agent, body = self.agent, self.body
        while len(agent.pending):
            saved = agent.checkpoint()
            rows_before, stages_before = agent.queries_total, agent.queries_by_stage
            try:
                self.pending_povs += agent.walk_pending(reference)
                if agent.crossing is not None:
                    fired = body.row - agent.rows_sent + agent.crossing["fired"] - 1
                    self.log.add(reference_row, fired, True, agent.rest_motor_state, "walk")
                    return self._sense_sentinels(agent.rest_motor_state)
            except WorldChanged:
                self.log.add(reference_row, body.row - 1, True, agent.rest_motor_state, "walk")
                self._count_lost(rows_before, stages_before, "pending_walk")
                agent.restore(saved, salvage=False)
                return self._sense_sentinels(agent.rest_motor_state)
        return None

    def _count_lost(self, rows_before: int, stages_before: dict, cut_in: str) -> None:
        """Count the rows since ``rows_before`` as lost, per stage, and the
        stage (``cut_in``) a change cut."""
        self.lost_rows += self.agent.queries_total - rows_before
        for stage, rows in self.agent.queries_by_stage.items():
            lost = rows - stages_before.get(stage, 0)
            if lost:
                self.lost_by_stage[stage] = self.lost_by_stage.get(stage, 0) + lost
        self.cut_in[cut_in] = self.cut_in.get(cut_in, 0) + 1

    def _undo(self, saved: dict, rows_before: int, stages_before: dict, cut_in: str) -> None:
        self._count_lost(rows_before, stages_before, cut_in)
        self.undone += 1
        self.salvaged += self.agent.restore(saved)

    def exploration(self, world, events: list, exploration_s: float) -> NaiveExploration:
        """The ``NaiveExploration`` of the kept reactions: the world at each
        one's first row (``events``: the changes the clock played)."""
        states = np.asarray([s for s, _ in self.event_states], dtype=int)
        centers_all = [np.asarray(world.initial_center, float)] + \
            [np.asarray(e.center, float) for e in events]
        kinds_all = ["initial"] + [e.kind for e in events]
        layout_all = np.cumsum([k == REDISTRIBUTION for k in kinds_all])
        centers = [centers_all[s] for s in states]
        layout = [int(layout_all[s]) for s in states]
        kinds = ["initial"] + [REDISTRIBUTION if layout[t] != layout[t - 1] else "translation"
                               for t in range(1, len(states))]
        grid_all = [-1] + [e.grid_index for e in events]
        explored = NaiveExploration(self.agent, centers, layout, kinds, exploration_s, 0.0)
        explored.grid_index = np.asarray([grid_all[s] for s in states], dtype=np.int64)
        orientation_all = np.asarray([0.0] + [e.orientation for e in events])
        explored.orientations = orientation_all[states]
        return explored

    def truth(self) -> ClockTruth:
        return ClockTruth(change_row=self.body.change_row.copy(),
                          rest_jumps=self.body.rest_jumps.copy(),
                          event_states=np.asarray(self.event_states, dtype=int).reshape(-1, 2),
                          log=self.log, lost_rows=int(self.lost_rows), undone=int(self.undone),
                          salvaged=int(self.salvaged),
                          rows=int(self.body.row), held_rows=int(self.body.held_rows),
                          lost_by_stage=dict(self.lost_by_stage),
                          cuts_by_stage=dict(self.cut_in), pending_povs=int(self.pending_povs),
                          crossed=int(self.crossed),
                          state_of=self.body.state_at, lights=self.body.lights,
                          restarts=int(self.restarts),
                          rows_lost_to_restart=int(self.rows_lost_to_restart),
                          start_lost_rows=int(self.start_lost_rows))
