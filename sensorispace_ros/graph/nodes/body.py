"""Body node: the simulated arm + retina (core.body.SimulatedBody), or the
MuJoCo model of ``body.kind: mujoco`` (bodies.mujoco_body.MujocoBody).

At start it publishes what it is on the latched ``/body/description``
(``core.body_description.BodyDescription``: joint names, unit, periods,
receptors), which the agent and the representation size themselves from.
Answers each ``/body/motor_command`` batch with one ``/body/sensation``
carrying the same header (the request id), and after each lights message a
one-row passive sensation of the resting arm (frame ``change/<k>`` or
``end/<k>``). A ``next/<k>`` command (the agent's first call of change k, sent
with its settle of k-1) that arrives before change k's lights is held and
answered right after that change's passive sensation. Ground truth for the
evaluator goes to ``/body/sensor_pose`` and ``/body/joint_states``; the agent
never subscribes to those. An imperfect body (docs/bodies.md) publishes its
sensations in ``world.retina.dtype``, its ground truth at the joints reached,
and numbers its commands and changes as the offline driver does, so both
draw the same noise (``core.imperfections``). In a world on its own clock
(``world.clock`` rows or wall) it announces no change: ``graph.nodes.body_clock``.

Restart: with ``graph.checkpoint_dir`` set, the resting motor state
and the number of the last lights applied are written on every command and
change into ``<dir>/body.state`` (state.resting_state: one ``os.pwrite``, in
the page cache before the answer is published, survives kill -9, no fsync) and
read back at start, so a restarted body computes passive sensations at the
right pose. The lights come back by themselves (``/environment/lights`` keeps
100 changes for late joiners, oldest first; each re-delivered one is answered
with a passive sensation, which the agent ignores when old); until the change
applied before the kill is back, commands are dropped (the agent re-sends
them), so none is answered in an old layout. Every well-formed command is
answered, duplicates too (the answer depends only on the commanded rows and
the lights); the third answer to one command ends the process with
RESTART_EXIT_CODE, to be started again (``note_repeated_command``). It
exits after the end's passive sensation unless ``graph.exit_when_done`` is false.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from rclpy.duration import Duration

from sensorispace_ros import contracts, messages
from sensorispace_ros.graph import tracing
from sensorispace_ros.graph.framework import RESTART_EXIT_CODE, GraphNode, build_world, run_node
from sensorispace_ros.graph.nodes.body_clock import BodyClock
from sensorispace_ros.state.resting_state import RestingStateFile


class BodyNode(BodyClock, GraphNode):

    simulated_body = True

    def __init__(self, **kwargs):
        super().__init__("body", **kwargs)
        world = build_world(self.cfg)
        self.body = world.body()
        self.description = self.body.description
        self.resting_file = None
        # After a restart: commands wait until the lights history (transient_local,
        # re-delivered interleaved with commands) is back at the change applied
        # before the kill; measured: a re-sent command was answered with change 4's
        # lights of the history instead of change 61's.
        self.lights_before_kill: int | None = None
        self.lights_number = -1
        # Times the latest command was asked for (the agent re-sends a command it
        # has had no answer to after graph.command_timeout_s).
        self.command_asked: tuple[str, int] = ("", 0)
        # A ``next/<k>`` command that arrived before change k's lights: answered
        # right after them (one at a time: the agent sends the next only after
        # it has this one's answer).
        self.held: "messages.FloatCloud | None" = None
        self.held_for = -1
        # The last command answered and its number in the body's noise stream
        # (core.imperfections): a command sent again is answered alike.
        self.answered: tuple[str, int] = ("", -1)
        if self.graph["checkpoint_dir"]:
            # [m0..m{N-1}, k]: the resting state and the number of the last lights applied
            self.resting_file = RestingStateFile(
                Path(self.graph["checkpoint_dir"]) / "body.state", self.description.n_motors + 1)
            saved = self.resting_file.load()
            if saved is not None:
                resting, self.lights_before_kill = saved[:-1], int(saved[-1])
                self.body.motor_state = resting
                self.get_logger().warning(f"restarted: resting motor state {resting.tolist()} "
                                          f"restored from {self.resting_file.path}")
        self.columns = {topic: self.columns_of(topic) for topic in (
            "/environment/lights", "/body/motor_command", "/body/sensation", "/body/sensor_pose")}
        # Replies go out, and commands and lights come in, as serialized bytes (messages.
        # CloudCdrPacker, GraphNode.read_float_cloud): rclpy's message conversions
        # would cost more than the rest of an answer, and every command gets
        # three publications.
        # A MuJoCo body's pixels are uint8 (bodies.mujoco_world.MujocoWorld.sensation_dtype).
        dtype = getattr(world, "sensation_dtype", world.imperfections.dtype)
        self.sensation_packer = messages.CloudCdrPacker(messages.with_number_type(
            self.columns["/body/sensation"], dtype))
        self.pose_packer = messages.CloudCdrPacker(self.columns["/body/sensor_pose"])
        self.joint_packer = messages.JointStateCdrPacker(
            contracts.contract("/body/joint_states").joint_names_for(self.description))
        self.description_pub = contracts.create_publisher(self, "/body/description")
        self.sensation_pub = contracts.create_publisher(self, "/body/sensation")
        self.pose_pub = contracts.create_publisher(self, "/body/sensor_pose")
        self.joint_pub = contracts.create_publisher(self, "/body/joint_states")
        # Lights come in as bytes too: the agent waits for the passive sensation
        # they trigger at every change (rclpy's message took ~30 us of it).
        contracts.create_subscription(self, "/environment/lights", self.on_lights, raw=True)
        contracts.create_subscription(self, "/body/motor_command", self.on_command, raw=True)
        self.init_clock(world)        # world.clock rows or wall: graph.nodes.body_clock
        # Once, kept for late joiners (transient_local): what this body is; last, when
        # every subscription exists (a restarted body's description tells the agent
        # to send its hold again).
        self.description_pub.publish(messages.description_to_msg(self.description, self.now_ns()))

    def on_lights(self, msg) -> None:
        read = self.read_float_cloud("/environment/lights", msg, kinds=("change", "end"))
        if read is None:
            return
        (kind, number), cloud = read
        tracing.stamp("body.lights", number)
        lights = cloud.matrix
        if self.clock != "agent":     # rows: the body's own schedule; wall: no notice
            return None if self.clock == "rows" else self.clock_lights(kind, number, lights)
        if kind == "change":
            if len(lights) == 0:
                self.drop("/environment/lights", "no lights")
                return
            self.body.set_lights(lights, change=number)
        elif self.body.lights_world is None:
            self.drop("/environment/lights", "end of run before any lights")
            return
        self.lights_number = number
        if self.lights_before_kill is not None and number >= self.lights_before_kill:
            self.lights_before_kill = None
        if self.resting_file is not None and self.lights_before_kill is None:
            self.resting_file.save((*self.body.motor_state.tolist(), number))
        self.publish_passive(cloud.frame_id, cloud.stamp_ns, number)
        tracing.stamp("body.passive", number)
        if kind == "end" and self.graph["exit_when_done"]:
            # The run is over once the agent has this passive sensation.
            self.sensation_pub.wait_for_all_acked(Duration(seconds=2.0))
            self.get_logger().info(f"run over after {number - 1} changes")
            self.finished = True
        if self.held is not None and number >= self.held_for \
                and self.lights_before_kill is None:
            held, self.held = self.held, None
            self.answer(held.matrix, held.frame_id, held.stamp_ns)

    def publish_passive(self, frame_id: str, stamp_ns: int, number: int) -> None:
        """What the resting eye sees after a change. Not a query of the agent's:
        ``SimulatedBody.sense_at_rest``, as the offline driver computes it
        (core.naive.run._passive_sensation), by the compiled kernel (2 instead
        of 54 us: the agent waits for this on every change)."""
        rest = self.body.motor_state
        sensation, pose = self.body.sense_at_rest(change=number)
        self.publish_answer(sensation[None], pose[None], rest, frame_id, stamp_ns)

    def on_command(self, msg) -> None:
        tracing.stamp("body.command")
        read = self.read_float_cloud("/body/motor_command", msg, kinds=("cmd", "next", "end"))
        if read is None:
            return
        (kind, number), command = read
        if len(command.matrix) == 0:
            self.drop("/body/motor_command", "empty batch")
            return
        if self.clock != "agent":
            return self.clock_command(kind, number, command)
        if kind == "next" and (number > self.lights_number or self.lights_before_kill is not None):
            # For a change not applied yet: sensed in its lights, once they come.
            self.held, self.held_for = command, number
            return
        if self.body.lights_world is None or self.lights_before_kill is not None:
            self.drop("/body/motor_command", "no current lights yet (the agent re-sends it)")
            return
        self.note_repeated_command(command.frame_id)
        self.answer(command.matrix, command.frame_id, command.stamp_ns)

    def close(self) -> None:
        self.get_logger().info(
            f"answered {self.body.calls} commands, "
            f"{self.general_reads.get('/body/motor_command', 0)} not read by the fast path")

    def note_repeated_command(self, frame_id: str) -> None:
        """When a command is to be answered a third time (the agent asked again
        twice: two answers have not reached it), say so and, with a checkpoint
        to resume from, stop with RESTART_EXIT_CODE after this answer: the
        launcher starts the body again. Seen after the recorder was killed with
        SIGKILL (README, Known limitations): this process's Fast DDS shared
        memory had no room left for a large answer while small ones still went
        out, for good; a new process has a new segment."""
        name, times = self.command_asked
        times = times + 1 if name == frame_id else 1
        self.command_asked = (frame_id, times)
        if times != 3:
            return
        restart = self.resting_file is not None
        self.get_logger().error(
            f"{frame_id} asked for a third time: the answers sent do not reach the agent "
            "(if a subscriber was killed with kill -9, this process's shared memory "
            "transport may have no room left for large messages); "
            + ("exiting to be restarted (it resumes from its checkpoint)" if restart
               else "restart the body node"))
        if restart:
            self.exit_code = RESTART_EXIT_CODE
            self.finished = True

    def answer(self, motor: np.ndarray, frame_id: str, stamp_ns: int) -> None:
        # One forward model per row for both replies (it was run twice: sense + sensor_pose);
        # the sensation goes first so the waiting agent proceeds while the ground truth is sent.
        again = self.answered[0] == frame_id
        sensations, poses = self.body.sense_with_poses(motor, self.answered[1] if again else None)
        self.answered = (frame_id, self.body.calls - 1)
        if self.resting_file is not None:
            # before the answer: once the agent has it, a restart rests where it did
            self.resting_file.save((*self.body.motor_state.tolist(), self.lights_number))
        self.publish_answer(sensations, poses, self.body.motor_state, frame_id, stamp_ns,
                            traced=True)

    def publish_answer(self, sensations: np.ndarray, poses: np.ndarray, rest: np.ndarray,
                       frame_id: str, stamp_ns: int, traced: bool = False) -> None:
        """The sensation first (the agent waits for it), then the ground truth; the
        header (frame id and stamp of the command or the change) of all three."""
        data = self.sensation_packer.pack(sensations, frame_id, stamp_ns)
        if traced:
            tracing.stamp("body.publish")
        self.sensation_pub.publish(data)
        if traced:
            tracing.stamp("body.published")
        self.pose_pub.publish(self.pose_packer.pack(poses, frame_id, stamp_ns))
        self.joint_pub.publish(self.joint_packer.pack(rest, frame_id, stamp_ns))


def main(args=None) -> int:
    return run_node(BodyNode, "body", args)


if __name__ == "__main__":
    raise SystemExit(main())
