"""The agent's body over the body's topics: ``BodyOverTopics``.

The naive agent senses through a body; in the graph that body is a round trip.
``sense(batch)`` publishes one ``/body/motor_command`` (frame ``cmd/<n>``) and
spins the node's executor (``graph.framework.make_executor``) in this thread
until the sensation with that frame id arrives. ``move`` (the rest after a
change, when the agent already sensed that state) does not wait: its answer is
taken before the next command or the settle. ``presend`` sends, with each
settle, the first call of the next change (the sweep of the known POVs,
``NaiveAgent.next_sweep``) as ``next/<k>``: the body answers it right after
change k's passive sensation, so that call waits for no round trip.

A command unanswered after ``command_timeout_s`` is published again with the
same frame id (a restarted body lost it); a large command waits longer, in
proportion to the time per row the body has taken so far (a camera
rendering a cloud of thousands of rows is slow, not lost). After a restart the answers come from
the agent's journal (``state.agent_journal``), checked by command number and
crc, before the proxy goes live. It publishes and spins only through the two
callables it is given, so the node stays the ROS wiring.
"""
from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np

from sensorispace_ros.graph import tracing
from sensorispace_ros.graph.framework import frame
from sensorispace_ros.state.agent_journal import (JOURNAL_FILE, AgentJournal, CheckpointError,
                                                  command_check)

# A command is re-sent after command_timeout_s, or after this many times the
# body's time per row so far (``row_s``), times its rows, if that is longer.
RESEND_AFTER_ROW_TIMES = 4.0


# A band's open side on /body/hold (a table holds no inf): the largest float64.
BAND_LIMIT = float(np.finfo(float).max)


class RunAborted(RuntimeError):
    """The node is shutting down while the agent waits for its body."""


class _Sent(NamedTuple):
    """A command published (or, after a restart, answered from the journal)."""
    number: int
    check: int
    motor_states: np.ndarray
    frame_id: str
    started: float
    replayed: np.ndarray | None


class BodyOverTopics:
    """A SensingBody whose ``sense`` is a round trip over the body's topics;
    ``description`` is the body's own (``core.body_description.BodyDescription``).

    ``spin_once(timeout_s)`` services the executor while the reply is
    awaited: the agent runs in the thread that spins, so the answer is
    handled without a thread hand-off (a worker thread waiting on an Event
    pays a GIL switch per round trip: docs/benchmarks.md).
    """

    def __init__(self, publish_command, spin_once, n_motors: int, n_sensors: int,
                 command_timeout_s: float = 2.0, on_retransmit=None, description=None,
                 publish_hold=None, resend_holds: bool = False):
        if not command_timeout_s > 0:
            raise ValueError(f"command_timeout_s: must be > 0, got {command_timeout_s!r}")
        if description is not None and (description.n_motors, description.receptors) != (
                n_motors, n_sensors):
            raise ValueError(f"description: {description} is not a body of {n_motors} "
                             f"motors and {n_sensors} sensors")
        self._publish_command = publish_command
        # (motor_state (1, N), low (R,), high (R,), frame_id): a world on its own clock
        self._publish_hold = publish_hold
        # A hold on the row clock is answered at once: sent again when unanswered
        # (a restarted body node), as a command is. On the wall clock it lasts.
        self.resend_holds = bool(resend_holds)
        self._holding = None      # while a hold is waited for: publishes it again
        self._hold_resent = False  # sent again to a restarted body: re-sent by time too
        self._pending_end: str | None = None   # end/<n>: also answers hold/<n> or end/<n>
        self.reply_frame = ""                  # frame id of the last answer taken
        self._spin_once = spin_once
        self.n_motors = n_motors
        self.n_sensors = n_sensors
        # What the body said of itself (/body/description): its joints' periods.
        self.description = description
        self.command_timeout_s = float(command_timeout_s)
        self._on_retransmit = on_retransmit
        self._pending: tuple[str, int] | None = None
        self._reply: np.ndarray | None = None
        self._moving: _Sent | None = None    # a move's command, its answer not taken yet
        self._ahead: _Sent | None = None     # a presend's command, its answer not taken yet
        self.ahead_used = 0                  # presends that answered the agent's next call
        self.requests = 0
        self.retransmits = 0
        self.aborted = False
        self.round_trip_s = 0.0          # total time spent waiting for the body
        self._answered = [0.0, 0]        # seconds and rows of the answers waited for whole
        # Restart: answers read back from the journal, by command
        # number, served before going live; the journal new answers go to.
        self.replay: dict[int, tuple[int, np.ndarray]] = {}
        self.replayed = 0
        self.journal: AgentJournal | None = None

    def sense(self, motor_states: np.ndarray) -> np.ndarray:
        motor_states = self._checked(motor_states)
        self.await_move()
        ahead, self._ahead = self._ahead, None
        if ahead is not None:
            answer = self._receive(ahead, time.perf_counter())
            if ahead.motor_states.shape == motor_states.shape and np.array_equal(
                    ahead.motor_states.view(np.uint64), motor_states.view(np.uint64)):
                self.ahead_used += 1
                return answer
            # Not what the agent asks for after all: that answer is journaled (a
            # replay takes it the same way) and the call goes out as usual.
        sent = self._send(motor_states)
        return self._receive(sent, sent.started)

    def hold(self, motor_state: np.ndarray, low: np.ndarray, high: np.ndarray):
        """Hold still at ``motor_state`` until the sensation leaves ``[low, high]``
        (``core.world_clock.ClockedBody.hold`` over the topics): one ``/body/hold``
        message, numbered with the commands, answered once. Returns that
        sensation, or None when the body answers ``end/<n>`` (its world has no
        change left). Re-sent only with ``resend_holds`` (the row clock): on the
        wall clock a hold lasts as long as the world stays, and is sent again
        only to a body that started again (``hold_again``)."""
        motor_state = self._checked(np.reshape(motor_state, (1, -1)))
        self.await_move()
        self.await_ahead()
        band = [np.clip(np.asarray(x, dtype=float).reshape(-1), -BAND_LIMIT, BAND_LIMIT)
                for x in (low, high)]
        self.requests += 1
        frame_id = frame("hold", self.requests)
        self._pending, self._pending_end = (frame_id, 1), frame("end", self.requests)
        self._reply = None
        started = time.perf_counter()
        self._publish_hold(motor_state, band[0], band[1], frame_id)
        self._holding = lambda *_: self._publish_hold(motor_state, band[0], band[1], frame_id)
        try:
            reply = self._receive(
                _Sent(self.requests, 0, motor_state, frame_id, started, None), started,
                resend=self.resend_holds, publish=self._holding)
        finally:
            self._holding, self._hold_resent = None, False
        return None if self.reply_frame.startswith("end/") else reply[0]

    def hold_again(self) -> bool:
        """Publish the hold being waited for once more (a body that started again
        forgot it), and again every ``command_timeout_s`` until it is answered
        (the restarted body's subscription may not have matched yet); False when
        no hold is waited for."""
        if self._holding is None:
            return False
        self.retransmits += 1
        self._hold_resent = True
        self._holding()
        return True

    def end_run(self, motor_state: np.ndarray) -> None:
        """Tell the body the run is over (``end/<n>`` on ``/body/motor_command``,
        one row: where it rests) and take its answer."""
        motor_state = self._checked(np.reshape(motor_state, (1, -1)))
        self.await_move()
        self.await_ahead()
        sent = self._send(motor_state, frame("end", self.requests + 1))
        self._receive(sent, sent.started)

    def presend(self, motor_states: np.ndarray, change: int) -> None:
        """Send now the command the agent expects to send first after change
        ``change`` (``core.naive.agent.NaiveAgent.next_sweep``), as
        ``next/<change>``: the body answers it once that change's lights are
        applied, right after the passive sensation. If the agent's first call
        asks for the same rows (bit for bit) that answer is returned without a
        round trip; otherwise it is taken and dropped first."""
        motor_states = self._checked(motor_states)
        self.await_move()
        self.await_ahead()
        self._ahead = self._send(motor_states, frame("next", change))

    def move(self, motor_states: np.ndarray) -> None:
        """The command ``sense`` sends, when the agent already has its
        sensations (it rests at a state sensed since the last change,
        ``core.naive.sense_memory.SensedSinceChange``): sent now, its answer taken
        before the next command or by ``await_move``, which the node calls
        before it settles: the arm rests there before the environment moves,
        and the answer is journaled as any other."""
        motor_states = self._checked(motor_states)
        self.await_move()
        self.await_ahead()
        self._moving = self._send(motor_states)

    def await_move(self) -> None:
        """Take the answer of the command ``move`` sent, if not taken yet."""
        if self._moving is not None:
            sent, self._moving = self._moving, None
            self._receive(sent, time.perf_counter())

    def await_ahead(self) -> None:
        """Take (and drop) the answer of a presend nobody asked for."""
        if self._ahead is not None:
            sent, self._ahead = self._ahead, None
            self._receive(sent, time.perf_counter())

    def _checked(self, motor_states: np.ndarray) -> np.ndarray:
        motor_states = np.asarray(motor_states, dtype=float)
        if motor_states.ndim != 2 or motor_states.shape[1] != self.n_motors:
            raise ValueError(f"motor_states must have shape (B, {self.n_motors}), "
                             f"got {motor_states.shape}")
        if not np.isfinite(motor_states).all():
            # No body can be sent there, and the contract drops such a command:
            # re-sending it would wait for ever. The run stops, naming the rows.
            bad = np.flatnonzero(~np.isfinite(motor_states).all(axis=1))
            raise ValueError(f"motor_states: non-finite motor values in rows {bad[:5].tolist()} "
                             f"of {len(motor_states)} (command {self.requests + 1})")
        return motor_states

    def _send(self, motor_states: np.ndarray, frame_id: str | None = None) -> "_Sent":
        """Publish command ``requests + 1`` (frame ``cmd/<n>`` unless ``frame_id``),
        or take its answer from the journal being replayed."""
        self.requests += 1
        number = self.requests
        check = command_check(motor_states) if self.journal is not None else 0
        if self.replay:
            recorded = self.replay.pop(number, None)
            if recorded is not None:
                return _Sent(number, check, motor_states, "", 0.0,
                             self._replayed(number, check, recorded, len(motor_states)))
            self.replay.clear()     # answers are journaled in order: the rest is live
        frame_id = frame_id or frame("cmd", number)
        self._pending, self._pending_end = (frame_id, len(motor_states)), None
        self._reply = None
        started = time.perf_counter()
        self._publish_command(motor_states, frame_id)
        return _Sent(number, check, motor_states, frame_id, started, None)

    def _receive(self, sent: "_Sent", since: float, resend: bool = True,
                 publish=None) -> np.ndarray:
        """Spin until ``sent`` is answered (re-sent every ``command_timeout_s``
        by ``publish(motor_states, frame_id)``, default the command's);
        ``since``: when the agent began to wait (``round_trip_s``)."""
        publish = self._publish_command if publish is None else publish
        if sent.replayed is not None:
            return sent.replayed
        last_sent = sent.started
        wait_s = min(0.5, self.command_timeout_s)
        timeout_s = max(self.command_timeout_s,
                        RESEND_AFTER_ROW_TIMES * self.row_s * len(sent.motor_states))
        retransmits = self.retransmits
        while self._reply is None:
            if self.aborted:
                raise RunAborted("shutting down while waiting for the body")
            self._spin_once(wait_s)
            now = time.perf_counter()
            if (resend or self._hold_resent) and self._reply is None \
                    and now - last_sent >= timeout_s:
                self.retransmits += 1
                if self._on_retransmit is not None:
                    self._on_retransmit(sent.frame_id, now - sent.started)
                publish(sent.motor_states, sent.frame_id)
                last_sent = now
        if since == sent.started:        # waited from the publication on (not a move's)
            tracing.stamp("agent.resume")
        self.round_trip_s += time.perf_counter() - since
        if since == sent.started and self.retransmits == retransmits:
            self._answered[0] += time.perf_counter() - sent.started
            self._answered[1] += len(sent.motor_states)
        reply, self._reply = self._reply, None
        if self.journal is not None:
            self.journal.answer(sent.number, sent.check, reply)
        return reply

    @property
    def row_s(self) -> float:
        """Seconds per row the body has taken, over every answer waited for
        from its publication on and not re-sent (0 before the first)."""
        seconds, rows = self._answered
        return seconds / rows if rows else 0.0

    def _replayed(self, number: int, check: int, recorded, n_rows: int) -> np.ndarray:
        recorded_check, rows = recorded
        if recorded_check != check or len(rows) != n_rows or rows.shape[1] != self.n_sensors:
            path = self.journal.path if self.journal is not None else JOURNAL_FILE
            raise CheckpointError(f"{path}: command {number} differs from the journaled one "
                                  "(journal of another run or configuration?)")
        self.replayed += 1
        return rows

    @property
    def pending_number(self) -> int | None:
        return None if self._pending is None else self.requests

    def deliver(self, frame_id: str, sensations: np.ndarray) -> bool:
        """Hand a sensation to the waiting request; False if nobody waits for it."""
        if self._pending is None or frame_id not in (self._pending[0], self._pending_end):
            return False
        if len(sensations) != self._pending[1] or sensations.shape[1] != self.n_sensors:
            return False
        self._reply = sensations
        self.reply_frame = frame_id
        self._pending = self._pending_end = None
        return True
