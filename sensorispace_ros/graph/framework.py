"""The executables of the graph: one thin rclpy node per module.

What they share lives here: reading the run configuration from ROS
parameters (``--ros-args --params-file config/paper.yaml``), the run's world
(``core.run_world``) and frame ids (``protocol``), logging-and-dropping of malformed
messages, the body description a node sizes itself from (the latched
/body/description: messages sized by the body wait for it), and a
``main`` that exits cleanly on SIGTERM / Ctrl-C and stops with the
parameter's name (no traceback) on an invalid configuration.
"""
from __future__ import annotations

import array
import functools
import sys
import time
from typing import Callable

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.publisher import Publisher

from sensorispace_ros import config, contracts, messages
from sensorispace_ros.bodies import run_world as build_world  # noqa: F401 (the nodes' name)
from sensorispace_ros.protocol import MAX_FRAME_NUMBER, frame, parse_frame  # noqa: F401
from sensorispace_ros.graph import tracing

# Parameters of the graph itself (not of the science): config.GRAPH_SCHEMA.
GRAPH_PREFIX = config.GRAPH_PREFIX
EXECUTORS = config.GRAPH_SCHEMA["executor"].check.options
# Parameters every rclpy node has; not part of the run configuration.
_ROS_OWN = {"use_sim_time", "start_type_description_service"}
# How long publish() keeps retrying after "cannot publish data" (RCLError): a
# RELIABLE + KEEP_ALL writer whose history is full of samples a kill -9'd reader
# never acknowledges frees it when the reader's participant lease expires
# (dds_environment.LEASE_DURATION_S = 3 s; Fast DDS's default is 20 s).
PUBLISH_RETRY_S = 25.0
PUBLISH_RETRY_PAUSE_S = 0.05
# Exit code of a node that asks whoever runs it (the launcher) to start it
# again with the same command line (EX_TEMPFAIL); it resumes from its
# checkpoint. The body does so when its answers stop reaching the agent.
RESTART_EXIT_CODE = 75
DESCRIPTION_TOPIC = "/body/description"
# Messages kept while a node waits for the body description; more are dropped.
MAX_WAITING = 10_000


class GraphNode(Node):
    """A node whose parameters are the run configuration (plus ``graph.*``).

    Parameters are declared from the parameter file
    (``automatically_declare_parameters_from_overrides``) so that every one,
    typos included, reaches ``config.load_config`` / ``config.load_graph``,
    which name the bad parameter. Only the simulated body checks
    ``arm.initial_motor_state`` against the simulated arm
    (``simulated_body``); a body of one's own says what it is itself.
    """

    simulated_body = False

    def __init__(self, name: str, *, context=None, parameter_overrides=None):
        super().__init__(name, context=context, parameter_overrides=parameter_overrides,
                         allow_undeclared_parameters=False,
                         automatically_declare_parameters_from_overrides=True,
                         start_parameter_services=False)
        flat, graph = {}, {}
        for pname, param in self.get_parameters_by_prefix("").items():
            if pname in _ROS_OWN or pname.startswith("qos_overrides."):
                continue
            value = param.value
            if isinstance(value, array.array):
                value = value.tolist()
            elif isinstance(value, (list, tuple)):
                value = list(value)
            if pname.startswith(GRAPH_PREFIX):
                graph[pname[len(GRAPH_PREFIX):]] = value
            else:
                flat[pname] = value
        self.cfg = config.load_config(None, overrides=flat, simulated_body=self.simulated_body)
        # agent: the lockstep protocol (change/<k>, /agent/settled); rows, wall:
        # the world on its own clock, no notice (docs/clock.md, graph section).
        self.clock = self.cfg["world"]["clock"]
        self.graph = config.load_graph(graph)
        self.dropped: dict[str, int] = {}
        self._cloud_readers: dict[str, messages.CloudCdrReader] = {}
        # Messages read_float_cloud could not take by the fast path, per topic:
        # 0 in a healthy graph (the probe topics carry CloudCdrPacker's bytes).
        self.general_reads: dict[str, int] = {}
        # Set by whoever spins the node (run_node, tests): lets a node that
        # waits for an answer keep the executor turning (see graph.body_over_topics).
        self.spin_once: Callable[[float], None] | None = None
        self.publish_failures = 0
        # The body description (/body/description), once taken; what waits for it.
        self.description = None
        self._columns: dict[str, dict] = {}
        self._waiting: list = []
        self._on_described: Callable | None = None

    # ------------------------------------------------------------ the body description

    def subscribe_description(self, on_first: Callable) -> None:
        """Take the body description from /body/description; ``on_first(description)``
        sizes the node when the first one comes, then the messages that waited for
        it (``when_described``) are handed over in their order of arrival."""
        self._on_described = on_first
        contracts.create_subscription(self, DESCRIPTION_TOPIC, self.on_description)

    def body_started_again(self) -> None:
        """The body's description came again: a body process (re)started and
        published it anew. Nothing by default."""

    def on_description(self, msg) -> None:
        """A malformed description, or one that differs from the one taken, is dropped."""
        try:
            description = messages.description_from_msg(msg)
        except messages.MessageError as exc:
            self.drop(DESCRIPTION_TOPIC, str(exc))
            return
        if self.description is not None:
            if description != self.description:
                self.drop(DESCRIPTION_TOPIC, f"{description} differs from the body "
                                             f"description taken, {self.description}")
            else:
                self.body_started_again()
            return
        self.description = description
        self._columns.clear()
        self._cloud_readers.clear()
        self.get_logger().info(f"body: {description.n_motors} joints "
                               f"({', '.join(description.joint_names)}) in "
                               f"{description.unit}, {description.receptors} receptors")
        if self._on_described is not None:
            self._on_described(description)
        waiting, self._waiting = self._waiting, []
        for callback, waiting_msg in waiting:
            callback(waiting_msg)

    def when_described(self, topic: str, callback: Callable) -> Callable:
        """``callback`` for messages on ``topic`` that need the body description:
        until it is taken they wait (at most MAX_WAITING in all, then dropped)."""
        def call(msg) -> None:
            if self.description is not None:
                callback(msg)
            elif len(self._waiting) < MAX_WAITING:
                self._waiting.append((callback, msg))
            else:
                self.drop(topic, f"more than {MAX_WAITING} messages before the body description")
        return call

    def columns_of(self, topic: str) -> dict:
        """The contract's columns of ``topic`` for this node's body description
        (contracts.ContractError for a topic sized by the body before it is known)."""
        columns = self._columns.get(topic)
        if columns is None:
            columns = contracts.contract(topic).columns_for(self.description)
            self._columns[topic] = columns
        return columns

    def create_publisher(self, *args, **kwargs) -> Publisher:
        """rclpy's publisher whose ``publish`` survives a full writer history
        (see ``publish_retrying``); every node's publishers are made here."""
        publisher = super().create_publisher(*args, **kwargs)
        publisher.publish = functools.partial(self.publish_retrying, publisher,
                                              Publisher.publish.__get__(publisher))
        return publisher

    def publish_retrying(self, publisher: Publisher, publish: Callable, msg) -> bool:
        """``publish(msg)``; on RCLError ("cannot publish data": the history is full
        of samples a dead reader will never acknowledge) wait and retry for up to
        PUBLISH_RETRY_S, logging (throttled), instead of letting the error end the
        node. Only the middleware's threads free the history (lease expiry, acks),
        so the retry sleeps rather than spinning the executor (no re-entrant
        callbacks). Any other RCLError, or one still there after PUBLISH_RETRY_S, is
        logged as an error and the message given up (False); during shutdown it is
        given up at once."""
        deadline = None
        while True:
            try:
                publish(msg)
                if deadline is not None:
                    self.get_logger().warning(f"published on {publisher.topic_name} again")
                return True
            except _rclpy.RCLError as exc:
                now = time.monotonic()
                if deadline is None:
                    deadline = now + PUBLISH_RETRY_S
                self.publish_failures += 1
                if not self.context.ok():
                    return False               # shutting down (SIGTERM): nothing to wait for
                if "cannot publish data" not in str(exc) or now >= deadline:
                    self.get_logger().error(f"gave up publishing on {publisher.topic_name} "
                                            f"after {now - deadline + PUBLISH_RETRY_S:.1f} s: "
                                            f"{exc}")
                    return False
                self.get_logger().warning(f"publish on {publisher.topic_name} failed, "
                                          f"retrying: {exc}", throttle_duration_sec=2.0)
                time.sleep(PUBLISH_RETRY_PAUSE_S)

    def now_ns(self) -> int:
        """The node clock's time in ns (ROS time: the simulated time with
        ``use_sim_time``), as ``get_clock().now().nanoseconds`` without building
        an rclpy ``Time``: 3.3 -> 0.7 us in a hot loop, for every command.
        rclpy's ``Clock.now`` also enters the handle's use guard; a clock's
        handle is never destroyed while its node lives."""
        return self.get_clock().handle.get_now().nanoseconds

    def step(self) -> None:
        """Work to do between callbacks (never inside one); called after every spin."""

    def decode(self, topic: str, msg, kinds: tuple[str, ...],
               as_table: bool = False):
        """``(kind, number), data`` of a message on ``topic`` whose frame id is
        one of ``kinds`` (topics.yaml), or None once it has been dropped. The
        data is a float matrix, or a structured copy with ``as_table``. ``msg``
        is a PointCloud2 or, from a ``raw=True`` subscription, what
        ``read_serialized`` made of its bytes."""
        parsed = self.frame_of(topic, msg.header.frame_id, kinds)
        if parsed is None:
            return None
        columns = self.columns_of(topic)
        try:
            data = (messages.cloud_to_table(msg, columns).copy() if as_table
                    else messages.cloud_to_matrix(msg, columns))
        except messages.MessageError as exc:
            self.drop(topic, str(exc))
            return None
        return parsed, data

    def frame_of(self, topic: str, frame_id: str,
                 kinds: tuple[str, ...]) -> tuple[str, int] | None:
        """``(kind, number)`` of a frame id of one of ``kinds``, or None once the
        message has been dropped."""
        parsed = parse_frame(frame_id)
        if parsed is None or parsed[0] not in kinds:
            self.drop(topic, f"frame id {frame_id!r}")
            return None
        return parsed

    def read_float_cloud(self, topic: str, msg, kinds: tuple[str, ...]
                         ) -> tuple[tuple[str, int], messages.FloatCloud] | None:
        """``(kind, number), cloud`` of a ``raw=True`` subscription's message on
        ``topic`` (columns of one type, or ``number`` columns: read as float64)
        whose frame id is one of ``kinds``, or
        None once it has been dropped: ``read_serialized`` then ``decode``, the
        same checks and drop reasons, with ``messages.CloudCdrReader``'s fast
        path for the bytes ``CloudCdrPacker`` writes (the probe topics)."""
        reader = self._cloud_readers.get(topic)
        if reader is None:
            reader = self._cloud_readers[topic] = messages.CloudCdrReader(
                self.columns_of(topic))
        cloud = reader.read_packed(msg)
        if cloud is not None:
            parsed = self.frame_of(topic, cloud.frame_id, kinds)
            return None if parsed is None else (parsed, cloud)
        self.general_reads[topic] = self.general_reads.get(topic, 0) + 1
        msg = self.read_serialized(topic, msg)
        decoded = None if msg is None else self.decode(topic, msg, kinds)
        if decoded is None:
            return None
        parsed, matrix = decoded
        return parsed, messages.FloatCloud(msg.header.frame_id, messages.stamp_ns(msg.header),
                                           matrix)

    def read_serialized(self, topic: str, msg):
        """A ``raw=True`` subscription's bytes as a ``messages.SerializedCloud``
        (None once dropped: not a PointCloud2's CDR); any other message as it is."""
        if not isinstance(msg, bytes):
            return msg
        try:
            return messages.cloud_from_cdr(msg)
        except messages.MessageError as exc:
            self.drop(topic, str(exc))
            return None

    def drop(self, topic: str, reason: str) -> None:
        """Log (throttled) and count a message that breaks its contract."""
        self.dropped[topic] = self.dropped.get(topic, 0) + 1
        self.get_logger().warning(f"dropped a message on {topic}: {reason} "
                                  f"({self.dropped[topic]} dropped so far)",
                                  throttle_duration_sec=5.0)


def make_executor(kind: str = "events", context=None):
    """The executor that spins a node's process: ``(executor, kind used)``.

    "events" is rclpy's EventsExecutor (``rclpy.experimental``, in C++; the pinned
    rclpy 7.1.6 has it): it hands each message to its callback from the
    middleware's new-message events, where ``SingleThreadedExecutor`` rebuilds
    a wait set from every entity of its nodes at each ``spin_once`` and runs
    each callback as a Task, at every one of the agent's and the body's many
    spins a run (round trips of each: docs/benchmarks.md). Without it (an
    older rclpy) "events" falls back to "single_threaded".
    """
    if kind not in EXECUTORS:
        raise ValueError(f"executor: must be one of {', '.join(EXECUTORS)}, got {kind!r}")
    if kind == "events":
        try:
            from rclpy.experimental import EventsExecutor
        except ImportError:
            kind = "single_threaded"
        else:
            return EventsExecutor(context=context), kind
    return SingleThreadedExecutor(context=context), kind


def run_node(make_node: Callable[[], GraphNode], name: str, args=None) -> int:
    """``main`` of every executable: init, spin until shutdown or done, clean exit.

    rclpy's own signal handlers turn SIGINT/SIGTERM into a context shutdown;
    spinning then ends with ExternalShutdownException / KeyboardInterrupt,
    which is a normal stop here.
    """
    rclpy.init(args=args)
    tracing.enable(name)           # only with SENSORISPACE_TRACE_DIR set
    node = None
    try:
        try:
            node = make_node()
        except config.ConfigError as exc:
            print(f"{name}: invalid parameter {exc}", file=sys.stderr)
            return 2
        executor, kind = make_executor(node.graph["executor"])
        if kind != node.graph["executor"]:
            node.get_logger().warning(f"graph.executor {node.graph['executor']!r} is not "
                                      f"available in this rclpy: spinning {kind!r}")
        executor.add_node(node)
        node.spin_once = lambda timeout_s: executor.spin_once(timeout_sec=timeout_s)
        while rclpy.ok() and not getattr(node, "finished", False):
            executor.spin_once(timeout_sec=0.2)
            node.step()
        return int(getattr(node, "exit_code", 0))
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        if node is not None:
            close = getattr(node, "close", None)
            if close is not None:
                close()
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
