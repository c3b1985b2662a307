"""recorder: every topic of the contract, raw CDR, into a rosbag2 MCAP bag.

Subscriptions are raw (exact bytes as sent, see recording.bag_format) with each topic's
contract QoS (RELIABLE + KEEP_ALL on data topics, so nothing is dropped).
Messages are stamped with their receive time, as ``ros2 bag record`` does.

The run's configuration is stored as the bag's first message on
/session/config: the recorder is started with the same ``--params-file`` as
every node and declares every parameter it is given, so the bag holds the
whole configuration (seed included) without help from the launcher.

SIGTERM / Ctrl-C: stop, drain what is already queued, close the bag (summary
+ metadata.yaml). kill -9: every message a subscription callback has stored is
kept, because each callback ends with one unbuffered write of what it stored to
the bag's write-ahead log (BagWriter, ``recorder.write_ahead``, default
true; false: the open chunk, <= ``recorder.chunk_interval_s``, is lost). What
the middleware had received but the recorder not yet taken is lost.
``sensorispace bag recover`` (or the restarted recorder) rebuilds the bag.

``<bag>.complete``, beside the bag directory, says the recording holds the
agent's whole run (``recording.completeness``): the launcher waits for it before
it stops the nodes, so a recorder restarted late still gets the agent's
TRANSIENT_LOCAL history.
"""
from __future__ import annotations

import shutil
import signal
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from sensorispace_ros.recording import completeness
from sensorispace_ros.recording.bag_copy import merge_bags
from sensorispace_ros.recording.bag_format import (
    SESSION_CONFIG_TOPIC,
    SESSION_CONFIG_TYPE,
    BagError,
    session_config_cdr,
)
from sensorispace_ros.recording.bag_recovery import recover_bag
from sensorispace_ros.recording.bag_writer import BagWriter
from sensorispace_ros import config, contracts

# Parameters that are not the run's configuration: the launcher's plumbing
# (graph.*: graph.bag_dir is where to record), the recorder's own (recorder.*,
# parameters.yaml) and rclpy's built-ins. Everything else it is given is stored.
NOT_RUN_CONFIG_PREFIXES = ("graph.", "recorder.")
NOT_RUN_CONFIG_NAMES = ("use_sim_time", "start_type_description_service", "bag_path")  # rclpy, alias
BATCH_TAKE = 1000  # messages taken per callback at most, so timers still run


def is_run_config(name: str) -> bool:
    return name not in NOT_RUN_CONFIG_NAMES and not name.startswith(NOT_RUN_CONFIG_PREFIXES)


def qos_spec(profile) -> dict:
    """topics.yaml-style dict of an rclpy QoSProfile (for metadata.yaml)."""
    return {
        "history": "keep_all" if profile.history == HistoryPolicy.KEEP_ALL else "keep_last",
        "depth": int(profile.depth),
        "reliability": "reliable" if profile.reliability == ReliabilityPolicy.RELIABLE
        else "best_effort",
        "durability": "transient_local" if profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
        else "volatile",
    }


def lossless(profile: QoSProfile) -> QoSProfile:
    """The contract's reliability and durability with KEEP_ALL history: a KEEP_LAST(1)
    reader (the contract of the state topics) would overwrite messages not yet taken."""
    return QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=profile.reliability,
                      durability=profile.durability)


def default_bag_path() -> str:
    return str(Path("bags") / datetime.now(timezone.utc).strftime("run_%Y%m%d_%H%M%S"))


def config_yaml(parameters: dict) -> str:
    """ROS params-file text (``/**: ros__parameters:``) of dotted parameter values."""
    return config.to_parameter_file(config.unflatten(parameters))


RESTART_SUFFIX = ".part-"


def set_aside_earlier_recording(bag: Path) -> list[Path]:
    """A restarted recorder (e.g. after kill -9) finds its bag directory: recover it and
    move it aside as ``<bag>.part-<n>``; returns every part waiting to be merged."""
    if bag.exists():
        recover_bag(bag)
        existing = sorted(bag.parent.glob(f"{bag.name}{RESTART_SUFFIX}*"))
        bag.rename(bag.with_name(f"{bag.name}{RESTART_SUFFIX}{len(existing) + 1}"))
    return sorted(bag.parent.glob(f"{bag.name}{RESTART_SUFFIX}*"),
                  key=lambda p: int(p.name.rsplit("-", 1)[1]))


def merge_parts(bag: Path, parts: list[Path]) -> None:
    """Replace ``bag`` by the merge of the earlier parts and itself; remove the parts."""
    staging = Path(tempfile.mkdtemp(dir=bag.parent, prefix=f".{bag.name}.merge-"))
    merged = staging / bag.name  # same name, so the MCAP file is <bag>.mcap already
    merge_bags([*parts, bag], merged)
    shutil.rmtree(bag)
    merged.rename(bag)
    staging.rmdir()
    for part in parts:
        shutil.rmtree(part)


class Recorder(Node):
    def __init__(self, **kwargs):
        super().__init__("recorder", automatically_declare_parameters_from_overrides=True,
                         **kwargs)
        given = {name: (list(p.value) if isinstance(p.value, (list, tuple))
                        or hasattr(p.value, "tolist") else p.value)
                 for name, p in self._parameters.items()}
        own = config.load_recorder({
            name[len(config.RECORDER_PREFIX):]: value for name, value in given.items()
            if name.startswith(config.RECORDER_PREFIX)
            and not (name.endswith(".topics") and value in ([], [""]))})
        # graph.bag_dir (the launcher's graph.* plumbing) or bag_path (same meaning)
        bag_path = given.get("graph.bag_dir") or given.get("bag_path") or default_bag_path()
        available = contracts.load_contracts()
        unknown = sorted(set(own["topics"]) - set(available))
        if unknown:
            raise ValueError(f"recorder.topics: {', '.join(unknown)} not in the topic contract")
        self.contracts = {name: c for name, c in available.items()
                          if not own["topics"] or name in own["topics"]}
        run_config = {name: value for name, value in given.items() if is_run_config(name)}
        self.open_bag(Path(bag_path), run_config, own)
        self.received = 0
        self.stats_period_s = own["stats_period_s"]
        self._window_start, self._window_count = time.monotonic(), 0
        self.first_message_at: float | None = None
        self.last_message_at: float | None = None
        self.subscriptions_ = {
            name: self.create_subscription(contract.msg_type, name, self._recorder_for(name),
                                           lossless(contract.qos), raw=True)
            for name, contract in self.contracts.items()}
        # an idle graph still gets its last chunk onto disk within chunk_interval_s
        self.create_timer(min(0.25, own["chunk_interval_s"]), self.writer.flush_if_due)
        self.create_timer(self.stats_period_s, self._log_rate)
        self.get_logger().info(f"recording {len(self.contracts)} topics into {bag_path}")

    def open_bag(self, bag_path: Path, run_config: dict, own: dict) -> None:
        """The bag's writer (after a restart, the earlier recording set aside),
        with the run's configuration as its first message."""
        topics = {name: c.type_name for name, c in self.contracts.items()}
        qos = {name: qos_spec(c.qos) for name, c in self.contracts.items()}
        if run_config:
            topics[SESSION_CONFIG_TOPIC] = SESSION_CONFIG_TYPE
        self.earlier_parts = set_aside_earlier_recording(bag_path)
        if self.earlier_parts:
            self.get_logger().warning(
                f"{bag_path} exists (recorder restarted): recovered it; it is merged with "
                f"this recording when the bag is closed")
        self.writer = BagWriter(bag_path, topics, qos=qos,
                                chunk_interval_s=own["chunk_interval_s"],
                                write_ahead=own["write_ahead"])
        # Counted from this process's own messages: a restarted recorder gets the
        # agent's whole TRANSIENT_LOCAL history again.
        self.completeness = completeness.RunCompleteness()
        completeness.remove_marker(self.writer.path)
        if not set(completeness.TOPICS) <= set(self.contracts):
            # not recording the agent's data (recorder.topics): nothing to wait for
            self._mark_complete()
        if run_config:
            self.writer.write(SESSION_CONFIG_TOPIC, time.time_ns(),
                              session_config_cdr(config_yaml(run_config)))
            self.writer.flush_chunk()
        else:
            self.get_logger().warning(
                "started without a params file: the bag will hold no /session/config, "
                "so `sensorispace analyze` cannot rebuild this run")

    def _recorder_for(self, topic: str):
        # Two parameters, so rclpy passes the message info (receive timestamp).
        def record(cdr: bytes, info: dict) -> None:
            self._store(topic, cdr, info)
            # Measured: one executor round per message caps rclpy at ~2k msgs/s;
            # taking what is already queued on this subscription here is ~10x cheaper.
            subscription = self.subscriptions_[topic]
            for _ in range(BATCH_TAKE):
                with subscription.handle:
                    taken = subscription.handle.take_message(subscription.msg_type, True)
                if taken is None:
                    break
                self._store(topic, *taken)
            self.writer.commit()         # the batch survives a kill -9 from here on
        return record

    def _store(self, topic: str, cdr: bytes, info: dict) -> None:
        self.writer.write(topic, info.get("received_timestamp") or time.time_ns(), cdr)
        if topic in completeness.TOPICS and self.completeness.add(topic, cdr):
            self.writer.commit()         # on disk before the launcher may stop the run
            self._mark_complete()
        self.received += 1
        self._window_count += 1
        now = time.monotonic()
        self.last_message_at = now
        if self.first_message_at is None:
            self.first_message_at = now

    def _mark_complete(self) -> None:
        path = completeness.write_marker(self.writer.path, self.completeness.held)
        self.get_logger().info(f"holds the agent's whole run ({path.name})")

    def _log_rate(self) -> None:
        now = time.monotonic()
        rate = self._window_count / (now - self._window_start)
        self._window_start, self._window_count = now, 0
        if rate:
            self.get_logger().info(f"{rate:.0f} msgs/s, {self.received} recorded")

    def sustained_rate(self) -> float:
        """Messages per second between the first and the last received message."""
        if self.first_message_at is None or self.last_message_at == self.first_message_at:
            return 0.0
        return self.received / (self.last_message_at - self.first_message_at)

    def close(self) -> None:
        if self.writer.closed:
            return
        self.writer.close()
        completeness.remove_marker(self.writer.path)
        if self.earlier_parts:
            merge_parts(self.writer.path, self.earlier_parts)
        counts = ", ".join(f"{t} {n}" for t, n in sorted(self.writer.counts.items()))
        self.get_logger().info(
            f"bag {self.writer.path} closed: {self.received} messages "
            f"({self.sustained_rate():.0f} msgs/s sustained); {counts}")


def drain(executor, recorder: Recorder, quiet_s: float = 0.3, limit_s: float = 4.0) -> None:
    """Take what the middleware already queued before closing (no drops at shutdown).
    ``limit_s`` stays under the launcher's 5 s SIGTERM -> SIGKILL grace period."""
    deadline = time.monotonic() + limit_s
    quiet_since = time.monotonic()
    while time.monotonic() < deadline:
        before = recorder.received
        executor.spin_once(timeout_sec=0.05)
        if recorder.received != before:
            quiet_since = time.monotonic()
        elif time.monotonic() - quiet_since > quiet_s:
            return


def main(args=None) -> int:
    stop = []

    def request_stop(signum, frame):
        stop.append(signum)

    # Own handlers instead of rclpy's: rclpy's would shut the context down at once,
    # discarding messages still queued; we drain them first.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGTERM, request_stop)
    signal.signal(signal.SIGINT, request_stop)
    recorder = None
    try:
        try:
            recorder = Recorder()
        except (ValueError, BagError) as exc:
            print(f"recorder: {exc}", file=sys.stderr)
            return 2
        executor = SingleThreadedExecutor()
        executor.add_node(recorder)
        while not stop:
            executor.spin_once(timeout_sec=0.1)
        drain(executor, recorder)
        return 0
    finally:
        if recorder is not None:
            recorder.close()
            recorder.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
