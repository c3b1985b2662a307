"""The body node in a world on its own clock (``world.clock: rows`` or ``wall``).

No passive sensation announces a change. ``rows``: the body is the clock
(``core.world_clock.ClockedBody``, the schedule the offline driver plays:
``clock_events``, ``change_rows``): every row it executes is time, and a
change falls before the row it is due at, inside a command too; the
environment publishes nothing. ``wall``: the body applies each
``/environment/lights`` change when it comes (on the environment's timer),
between two commands, and announces none. Both answer ``/body/hold`` once:
they hold the arm at the motor state until a receptor leaves the band
(``rows``: the rows pass in the simulation; ``wall``: the body looks again
at every change of its world), or say ``end/<n>`` when the world has no
change left. When the world replays its schedule for simulation 2 the body
says ``equality/<k>`` before its next answer, and again before each answer
to a hold (an agent restarted from a snapshot may have missed it). A command sent again
is answered with its first answer (the clock does not run twice).

Restart on the row clock: with ``graph.checkpoint_dir`` the body writes, after
each command or hold it executes, the command's number and where the clock
and the arm stood before and after it (``<dir>/body.clock``, one ``os.pwrite``
as ``body.state``: ``ClockedBody.position``). A restarted body goes on from
there: the command sent again (the dead body may have executed it without its
answer getting out) is executed again from where it began, bit for bit, a later
one from where the last ended; an older one is dropped. The world's clock is
the rows executed, so a kill -9 of the body changes nothing the agent does.
The ground truth of time (``rows_after``, ``state_after``, ``rest_jumps``) is
appended to ``<dir>/body.truth.log`` as each command is answered
(``state.clock_truth.TruthLog``) and read back by a restarted body, so the
evaluation of a run whose body was killed is that of an uninterrupted one.

Restart on the ``wall`` clock: the body appends its record of time there too
and reads it back; it answers nothing until the environment's history of
lights (``/environment/lights`` keeps the latest changes for late joiners) is
back at the change it last answered in, and the agent sends again the hold
the dead body was watching when the body's description comes again. What
the world did meanwhile is not replayed: the wall clock is not reproducible.

Ground truth for the evaluator, never published to the agent: the rows
executed after each command (``rows_after``, rows) and the world state each
command was answered in (``state_after``); ``evaluation.graph_clock``. With
``graph.checkpoint_dir`` they are written there when the run is over
(``state.clock_truth``), for the evaluation of a launched run.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from rclpy.duration import Duration

from sensorispace_ros import contracts
from sensorispace_ros.core.world_clock import clock_body
from sensorispace_ros.graph.framework import frame
from sensorispace_ros.protocol import BODY_CLOCK_FILE, BODY_TRUTH_FILE, BODY_TRUTH_LOG_FILE
from sensorispace_ros.state.clock_truth import (TruthLog, clock_record, split_clock_record,
                                                write_clock_truth)
from sensorispace_ros.state.resting_state import RestingStateFile


class BodyClock:
    """What ``BodyNode`` does when ``world.clock`` is rows or wall."""

    def init_clock(self, world) -> None:
        self.n_events = len(world.events)
        self.clocked_body = None
        self.rows_after = {0: 0}          # command number -> rows executed after it
        self.state_after: dict[int, int] = {}
        self.last_answer: tuple[int, bytes] | None = None    # (command number, answer)
        self.clock_file = None
        self.truth_log = None             # with graph.checkpoint_dir: the TruthLog appended to
        self.jumps_logged = 0             # the changes whose rest jump the log holds
        self.truth_whole = True           # False: restarted without the dead body's log
        self.lights_before_restart = 0    # wall: the change the dead body answered in last
        self.resumed: tuple[int, np.ndarray] | None = None   # (number, position before it)
        self.holding = None               # wall: (number, motor (1, N), low, high)
        self.world_ended = False
        self.announced = False
        contracts.create_subscription(self, "/body/hold", self.on_hold, raw=True)
        if self.clock == "rows":
            self.clocked_body = clock_body(self.body, world, self.cfg)
            if self.graph["checkpoint_dir"]:
                self.resume_clock()
        elif self.clock == "wall":
            self.body.set_lights(world.initial_lights, change=0)
            self.lights_number = 0
            if self.graph["checkpoint_dir"]:
                self.resume_wall()

    def resume_clock(self) -> None:
        """Open ``<checkpoint_dir>/body.clock``; after a restart, stand where the
        last command executed left the clock (module docstring)."""
        size = 1 + 2 * self.clocked_body.position_size
        self.clock_file = RestingStateFile(Path(self.graph["checkpoint_dir"]) / BODY_CLOCK_FILE,
                                           size)
        saved = self.clock_file.load()
        self.open_truth_log(restarted=saved is not None)
        if saved is None:
            return
        number, before, after = split_clock_record(saved)
        self.clocked_body.resume(after)
        self.resumed = (number, before)
        self.get_logger().warning(
            f"restarted on the row clock: resumed after command {number} at row "
            f"{self.clocked_body.row} (world state {self.clocked_body.state}), from "
            f"{self.clock_file.path}")

    def resume_wall(self) -> None:
        """wall: the record of time of a body that ran before in this checkpoint
        directory (the launcher empties it for a new run), appended to."""
        restarted = self.truth_log_path.is_file()
        self.open_truth_log(restarted)
        if not restarted:
            return
        self.lights_before_restart = max(self.state_after.values(), default=0)
        self.get_logger().warning(
            f"restarted on the wall clock: {len(self.state_after)} commands in "
            f"{self.truth_log_path}; "
            f"commands wait for the world's lights of change {self.lights_before_restart} "
            "(the environment's history)")

    @property
    def truth_log_path(self) -> Path:
        return Path(self.graph["checkpoint_dir"]) / BODY_TRUTH_LOG_FILE

    def open_truth_log(self, restarted: bool) -> None:
        """``<checkpoint_dir>/body.truth.log``, appended to from now on; after a
        restart, the dead body's record of time read back from it first (without
        the log the record is not whole: the evaluator says so)."""
        logged = TruthLog.read(self.truth_log_path) if restarted else None
        self.truth_log = TruthLog(self.truth_log_path, fresh=logged is None)
        if not restarted:
            return
        if logged is None:
            self.truth_whole = False
            self.get_logger().warning(f"no {self.truth_log_path}: the ground truth of time "
                                      "covers the commands since the restart only")
            return
        rows_after, state_after, jumps = logged
        self.rows_after.update(rows_after)
        self.state_after.update(state_after)
        for change, jump in jumps.items():
            self.clocked_body.rest_jumps[change] = jump
        self.jumps_logged = max(jumps, default=-1) + 1

    def on_the_clock(self, number: int, topic: str = "/body/motor_command") -> bool:
        """Before executing command or hold ``number``: after a restart, the
        last one executed is executed again from where it began, an older one
        is dropped (False)."""
        if self.resumed is None:
            return True
        last, before = self.resumed
        if number < last:
            self.drop(topic, f"command {number} was answered before the restart")
            return False
        if number == last:
            self.clocked_body.resume(before)
        self.resumed = None
        return True

    def executed(self, number: int, before: np.ndarray) -> None:
        if self.clock_file is not None:
            self.clock_file.save(clock_record(number, before, self.clocked_body.position()))

    @property
    def world_state(self) -> int:
        return self.clocked_body.state if self.clocked_body is not None else self.lights_number

    def clock_lights(self, kind: str, number: int, lights: np.ndarray) -> None:
        """wall: a change of the world, applied and not announced; the end."""
        if kind == "end":
            self.world_ended = True
        elif number > self.lights_number:
            self.body.set_lights(lights, change=number)
            self.lights_number = number
        self.watch_hold()

    def clock_command(self, kind: str, number: int, command) -> None:
        """A command (``cmd/<n>``) or the agent's end of the run (``end/<n>``)."""
        if self.answered_before(number):
            return
        if self.clocked_body is not None:
            if not self.on_the_clock(number):
                return
            before = self.clocked_body.position()
            sensations = self.clocked_body.sense(command.matrix)
            self.executed(number, before)
        elif self.lights_number < self.lights_before_restart:
            self.drop("/body/motor_command",
                      f"restarted: the world's lights are at change {self.lights_number} of "
                      f"{self.lights_before_restart} (the agent re-sends it)")
            return
        else:
            sensations = self.body.sense(command.matrix)
        self.record(number)
        self.clock_answer(sensations, command.matrix, command.frame_id)
        if kind == "end":
            self.clock_over()

    def on_hold(self, msg) -> None:
        if self.description is None:
            return
        read = self.read_float_cloud("/body/hold", msg, kinds=("hold",))
        if read is None or self.clock == "agent":
            return
        (_, number), cloud = read
        n = self.description.n_motors
        row = cloud.matrix[0]
        motor, (low, high) = row[None, :n], np.split(row[n:], 2)
        if self.clocked_body is not None:
            if self.answered_before(number) or not self.on_the_clock(number, "/body/hold"):
                return
            before = self.clocked_body.position()
            sensed = None if self.clocked_body.ended else self.clocked_body.hold(motor, low, high)
            self.executed(number, before)
            self.record(number)
            self.hold_answered(number, motor, sensed)
        else:
            self.holding = (number, motor, low, high)
            self.watch_hold()

    def answered_before(self, number: int) -> bool:
        """Command or hold ``number`` sent again: its first answer again."""
        if self.last_answer is None or self.last_answer[0] != number:
            return False
        self.sensation_pub.publish(self.last_answer[1])
        return True

    def watch_hold(self) -> None:
        """wall: look at the held state in the world as it is now."""
        if self.holding is None or self.lights_number < self.lights_before_restart:
            return
        number, motor, low, high = self.holding
        if self.world_ended:
            self.holding = None
            self.record(number)
            self.hold_answered(number, motor, None)
            return
        sensed = self.body.sense(motor)[0]
        outside = np.all(np.isfinite(sensed)) and np.any((sensed < low) | (sensed > high))
        if outside:
            self.holding = None
            self.record(number)
            self.hold_answered(number, motor, sensed)

    def hold_answered(self, number: int, motor: np.ndarray, sensed) -> None:
        if sensed is None:
            self.clock_answer(np.zeros((1, self.description.receptors)), motor,
                              frame("end", number))
            self.clock_over()
        else:
            self.clock_answer(np.asarray(sensed)[None], motor, frame("hold", number))

    def record(self, number: int) -> None:
        if self.clocked_body is not None:
            self.rows_after[number] = int(self.clocked_body.row)
        self.state_after[number] = int(self.world_state)
        if self.truth_log is None:
            return
        if self.clocked_body is not None:
            changed = self.clocked_body.state
            if changed > self.jumps_logged:
                self.truth_log.changes(self.jumps_logged,
                                       self.clocked_body.rest_jumps[self.jumps_logged:changed])
                self.jumps_logged = changed
        self.truth_log.command(number, self.rows_after.get(number), self.state_after[number])

    def clock_answer(self, sensations: np.ndarray, motor: np.ndarray, frame_id: str) -> None:
        """Say simulation 2 once the world replays its schedule (again before a
        hold's answer), then answer."""
        if self.world_state > self.n_events and (
                not self.announced or frame_id.startswith("hold/")):
            self.announced = True
            self.sensation_pub.publish(self.sensation_packer.pack(
                np.zeros((1, self.description.receptors)),
                frame("equality", self.world_state), self.now_ns()))
        data = self.sensation_packer.pack(sensations, frame_id, self.now_ns())
        self.last_answer = (int(frame_id.rsplit("/", 1)[1]), data)
        self.sensation_pub.publish(data)
        stamp = self.now_ns()
        self.pose_pub.publish(self.pose_packer.pack(self.body.sensor_pose(motor), frame_id,
                                                    stamp))
        self.joint_pub.publish(self.joint_packer.pack(motor[-1], frame_id, stamp))

    def clock_over(self) -> None:
        self.get_logger().info(f"run over: world state {self.world_state} of "
                               f"{len(self.clock_events_played())} changes")
        if self.graph["checkpoint_dir"]:
            write_clock_truth(Path(self.graph["checkpoint_dir"]) / BODY_TRUTH_FILE,
                              self.rows_after, self.state_after, self.clocked_body,
                              whole=self.truth_whole)
        if self.graph["exit_when_done"]:
            self.sensation_pub.wait_for_all_acked(Duration(seconds=2.0))
            self.finished = True

    def clock_events_played(self) -> list:
        if self.clocked_body is not None:
            return list(self.clocked_body.change_row)
        return list(range(self.lights_number))
