"""replay: republish a recorded bag, raw CDR, with its original timing or as fast as possible.

Publishers take the topic contract's reliability and durability with KEEP_ALL
history (a KEEP_LAST(1) writer may overwrite a sample before a reader has
it), replay starts only once subscribers have matched, and ends only when
every reliable message is acknowledged, so a fast replay loses nothing.
"""
from __future__ import annotations

import os
import sys
import time

import rclpy
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from sensorispace_ros.recording.bag_format import BagError
from sensorispace_ros.recording.bag_reader import check_contract, message_class, read_bag
from sensorispace_ros import config, contracts
from sensorispace_ros.graph.nodes.recorder import lossless

# /session/config is not in the contract: a late subscriber should still get it
SESSION_CONFIG_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                                reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _message_class(type_name: str):
    return message_class(type_name)


def publish_blocking(publisher, cdr: bytes, give_up_s: float = 30.0) -> None:
    """Publish, waiting while a KEEP_ALL writer's history is full.

    Measured: publishing faster than a reliable reader acknowledges makes Fast
    DDS fail the call ("cannot publish data") once its history is full and
    max_blocking_time has passed; the sample was not sent, so back off and
    send it again. Gives up (RuntimeError) after ``give_up_s`` without progress.
    """
    deadline = time.monotonic() + give_up_s
    pause = 0.001
    while True:
        try:
            publisher.publish(cdr)
            return
        except Exception as exc:  # rclpy's RCLError is not public
            if type(exc).__name__ != "RCLError" or time.monotonic() > deadline:
                raise RuntimeError(f"cannot publish on {publisher.topic_name}: "
                                   f"{' '.join(str(exc).split())}") from None
            time.sleep(pause)
            pause = min(2 * pause, 0.05)


class Replay(Node):
    """Publishers for the bag's topics; ``run`` does the replay."""

    def __init__(self, bag_path: str | None = None, rate: float | None = None,
                 topics: list[str] | None = None, **kwargs):
        super().__init__("replay", automatically_declare_parameters_from_overrides=True,
                         **kwargs)
        # Its own parameters (parameters.yaml replay:), the ROS ones over the
        # arguments; others (a run's parameter file) are not its business.
        given = {name: value for name, value in
                 (("bag_path", bag_path), ("rate", rate), ("topics", topics))
                 if value is not None}
        given.update({name: (list(p.value) if isinstance(p.value, (list, tuple))
                             or hasattr(p.value, "tolist") else p.value)
                      for name, p in self._parameters.items() if name in config.REPLAY_SCHEMA})
        if given.get("topics") in ([], [""]):
            del given["topics"]
        own = config.load_replay(given)
        bag_path, self.rate, wanted = own["bag_path"], own["rate"], own["topics"]
        self.match_timeout_s, self.match_grace_s = own["match_timeout_s"], own["match_grace_s"]
        if not bag_path:
            raise ValueError("bag_path: required (the bag directory to replay)")
        self.bag_path = bag_path
        available = contracts.load_contracts()
        info = check_contract(bag_path, {n: c.type_name for n, c in available.items()})
        unknown = sorted(set(wanted) - set(info.topics))
        if unknown:
            raise ValueError(f"topics: {', '.join(unknown)} not in bag {bag_path}")
        self.topics = wanted or sorted(info.topics)
        self.expected = {t: info.counts.get(t, 0) for t in self.topics}
        self.publishers_ = {}
        for name in self.topics:
            qos = lossless(available[name].qos) if name in available else SESSION_CONFIG_QOS
            self.publishers_[name] = self.create_publisher(
                _message_class(info.topics[name]), name, qos)
        self.published = {t: 0 for t in self.topics}

    def wait_for_subscribers(self) -> list[str]:
        """Wait until every replayed topic with messages has a subscriber, or the
        timeout, then ``match_grace_s`` more if any matched (the subscribers'
        side of discovery may not be done); returns the topics nobody subscribes to."""
        deadline = time.monotonic() + self.match_timeout_s
        first_match = None
        with_messages = sum(1 for n in self.expected.values() if n)
        while True:
            lonely = [t for t, p in self.publishers_.items()
                      if self.expected[t] and p.get_subscription_count() == 0]
            now = time.monotonic()
            if not lonely or now > deadline:
                if len(lonely) < with_messages:
                    time.sleep(self.match_grace_s)
                return lonely
            if first_match is None and len(lonely) < with_messages:
                # a node's subscriptions are discovered together: once one topic
                # matched, give the rest 2 s rather than the whole timeout
                first_match = now
                deadline = min(deadline, now + 2.0)
            time.sleep(0.05)

    def run(self) -> dict[str, int]:
        lonely = self.wait_for_subscribers()
        if lonely:
            self.get_logger().warning(f"no subscriber for {', '.join(lonely)}; publishing anyway")
        mode = "as fast as possible" if self.rate <= 0 else f"at {self.rate:g}x"
        self.get_logger().info(f"replaying {self.bag_path} {mode}")
        start_wall = time.monotonic()
        first_stamp = None
        for topic, _, stamp_ns, cdr in read_bag(self.bag_path, self.topics):
            if self.rate > 0:
                if first_stamp is None:
                    first_stamp = stamp_ns
                delay = start_wall + (stamp_ns - first_stamp) / 1e9 / self.rate - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            publish_blocking(self.publishers_[topic], cdr)
            self.published[topic] += 1
        for publisher in self.publishers_.values():
            publisher.wait_for_all_acked(Duration(seconds=10))
        total = sum(self.published.values())
        self.get_logger().info(
            f"replayed {total} messages in {time.monotonic() - start_wall:.2f} s")
        return dict(self.published)


def replay_bag(bag_path: str, rate: float = 1.0, topics: list[str] | None = None) -> dict[str, int]:
    """Replay in this process (``sensorispace replay``); localhost-only discovery by default."""
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    rclpy.init()
    node = None
    try:
        node = Replay(bag_path=bag_path, rate=rate, topics=topics)
        return node.run()
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


def main(args=None) -> int:
    rclpy.init(args=args)
    node = None
    try:
        node = Replay()
        node.run()
        return 0
    except (ValueError, BagError) as exc:
        print(f"replay: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
