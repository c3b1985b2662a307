"""The clocked agent over the body's topics (``world.clock: rows`` or ``wall``).

The agent node runs the offline driver's reactions (``core.clocked_run``:
``begin_run``, ``drive``) on a ``BodyOverTopics``, in the order
``clocked_run.explore_clocked`` runs them, so that a graph run on the row
clock makes every call the offline run makes. Nothing tells the agent when
the world changes: it holds still at rest (one ``/body/hold`` message) until
its sensation leaves its noise band, and tells a change in a reaction by its
sentinels. The body says two things besides sensations: that the run is over
(``end/<n>``, the answer to a hold when its world has no change left) and
that its world replays the schedule for simulation 2 (``equality/<k>``,
``second_round``), as the offline driver switches to the equality pass.

Positions on the clock, for the evaluator only (the agent never reads
them): a driver's row ``2n + 1`` stands for the first row of command
``n + 1`` and ``2n`` for the last row of command ``n``;
``evaluation.graph_clock`` turns them into the body's rows and world states.

A run pickles whole (the agent node's snapshot, ``graph.nodes.agent_restart``)
but for the link to the node's topics: ``ClockOverTopics`` leaves out its
body, which a restarted node binds again (``bind``).
"""
from __future__ import annotations

import numpy as np

from sensorispace_ros.core.clocked_run import begin_run, drive
from sensorispace_ros.core.naive.params import NaiveParams


class ClockOverTopics:
    """What ``core.clocked_run`` drives, over a ``BodyOverTopics``: ``sense``,
    ``move`` and ``hold`` go to the body; ``row`` and ``state_at`` are the
    driver's positions (module docstring), ``state`` says whether the body
    announced simulation 2."""

    def __init__(self, body):
        self._body = body
        self.n_motors = int(body.n_motors)
        self.n_sensors = int(body.n_sensors)
        self.description = body.description
        self.second_round = False
        self.ended = False
        self.holds = 0                 # /body/hold messages sent
        self.rows_sent = 0             # rows of the commands sensed or moved to

    def __getstate__(self) -> dict:
        state = dict(vars(self))
        state["_body"] = None          # this process's topics: ``bind``
        return state

    def bind(self, body) -> None:
        """Sense through ``body`` (a restarted node's ``BodyOverTopics``), the
        body this view was made for: ValueError naming what differs otherwise."""
        if body.description != self.description:
            raise ValueError(f"description: the run was made for {self.description}, "
                             f"the body is {body.description}")
        self._body = body
        self.ended = False

    def sense(self, motor_states: np.ndarray) -> np.ndarray:
        self.rows_sent += len(motor_states)
        return self._body.sense(motor_states)

    def move(self, motor_states: np.ndarray) -> None:
        self.rows_sent += len(motor_states)
        self._body.move(motor_states)

    def hold(self, motor_state, low, high):
        self.holds += 1
        sensed = self._body.hold(motor_state, low, high)
        self.ended = sensed is None
        return sensed

    @property
    def row(self) -> int:
        return 2 * self._body.requests + 1

    @property
    def state(self) -> int:
        return 1 if self.second_round else 0

    @staticmethod
    def state_at(row):
        return np.asarray(row)


def explore_over_topics(clock: ClockOverTopics, m0: np.ndarray, seed: int,
                        params: NaiveParams, *, sweep_budget: int, equality_changes: int,
                        after_reaction=None, run=None):
    """``clocked_run.explore_clocked``'s run on ``clock``; returns the driver
    (``ClockedRun``: its agent, its tests and the positions of its reactions).
    ``after_reaction(run)`` is called at each reaction's end (the agent idle);
    ``run``: a run saved there, to go on with (its body ``clock``)."""
    resume = run is not None
    if not resume:
        run = begin_run(clock, m0, seed, params, sweep_budget)
    drive(run, equality_changes=equality_changes, second_round=lambda: clock.state > 0,
          after_reaction=None if after_reaction is None else (lambda: after_reaction(run)),
          resume=resume)
    return run
