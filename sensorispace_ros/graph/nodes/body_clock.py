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

Ground truth for the evaluator, never published to the agent: the rows
executed after each command (``rows_after``, rows) and the world state each
command was answered in (``state_after``); ``evaluation.graph_clock``.
"""
from __future__ import annotations

import numpy as np
from rclpy.duration import Duration

from sensorispace_ros import contracts
from sensorispace_ros.core.world_clock import ClockedBody, change_rows
from sensorispace_ros.graph.framework import frame


def clock_events(world, cfg: dict) -> list:
    """The changes a world on its own clock plays: the schedule, twice when the
    agent has an equality pass (``naive.clock_equality_changes``), as
    ``core.clocked_run.explore_clocked`` plays it."""
    twice = cfg["naive"]["clock_equality_changes"] > 0
    return list(world.events) * (2 if twice else 1)


class BodyClock:
    """What ``BodyNode`` does when ``world.clock`` is rows or wall."""

    def init_clock(self, world) -> None:
        self.n_events = len(world.events)
        self.clocked_body = None
        self.rows_after = {0: 0}          # command number -> rows executed after it
        self.state_after: dict[int, int] = {}
        self.last_answer: tuple[str, bytes] | None = None
        self.holding = None               # wall: (number, motor (1, N), low, high)
        self.world_ended = False
        self.announced = False
        contracts.create_subscription(self, "/body/hold", self.on_hold, raw=True)
        if self.clock == "rows":
            events = clock_events(world, self.cfg)
            self.clocked_body = ClockedBody(
                self.body, [world.initial_lights] + [e.lights for e in events],
                change_rows(len(events), self.cfg["world"]["change_interval"], self.cfg["seed"]))
        elif self.clock == "wall":
            self.body.set_lights(world.initial_lights, change=0)
            self.lights_number = 0

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
        if self.last_answer is not None and self.last_answer[0] == command.frame_id:
            self.sensation_pub.publish(self.last_answer[1])
            return
        if self.clocked_body is not None:
            sensations = self.clocked_body.sense(command.matrix)
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
            sensed = None if self.clocked_body.ended else self.clocked_body.hold(motor, low, high)
            self.record(number)
            self.hold_answered(number, motor, sensed)
        else:
            self.holding = (number, motor, low, high)
            self.watch_hold()

    def watch_hold(self) -> None:
        """wall: look at the held state in the world as it is now."""
        if self.holding is None:
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
        self.last_answer = (frame_id, data)
        self.sensation_pub.publish(data)
        stamp = self.now_ns()
        self.pose_pub.publish(self.pose_packer.pack(self.body.sensor_pose(motor), frame_id,
                                                    stamp))
        self.joint_pub.publish(self.joint_packer.pack(motor[-1], frame_id, stamp))

    def clock_over(self) -> None:
        self.get_logger().info(f"run over: world state {self.world_state} of "
                               f"{len(self.clock_events_played())} changes")
        if self.graph["exit_when_done"]:
            self.sensation_pub.wait_for_all_acked(Duration(seconds=2.0))
            self.finished = True

    def clock_events_played(self) -> list:
        if self.clocked_body is not None:
            return list(self.clocked_body.change_row)
        return list(range(self.lights_number))
