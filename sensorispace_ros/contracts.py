"""Topic contracts (msg_schemas/topics.yaml) as Python objects.

Nodes create their publishers and subscriptions from here, and tests compare
the live graph with the same file, so the documentation of a topic and the
code that uses it cannot drift apart.
"""
from __future__ import annotations

import importlib
import os
import sys
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import yaml
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

PACKAGE = "sensorispace_ros"
_SCHEMA_FILE = Path("msg_schemas") / "topics.yaml"


@dataclass(frozen=True)
class TopicContract:
    name: str
    type_name: str                 # e.g. "sensor_msgs/msg/PointCloud2"
    qos: QoSProfile
    publisher: str
    subscribers: tuple[str, ...]
    ground_truth: bool
    columns: dict                  # {column: type name}, empty for non-table types
    frame_id: str
    meaning: str
    elements: tuple[str, ...] = ()  # names of a Float64MultiArray's data[i]

    @property
    def msg_type(self):
        package, _, name = self.type_name.split("/")
        return getattr(importlib.import_module(f"{package}.msg"), name)


def schema_path() -> Path:
    """topics.yaml: SENSORISPACE_SCHEMA, the source tree, an installed share/, or ament index."""
    override = os.environ.get("SENSORISPACE_SCHEMA")
    if override:
        return Path(override)
    here = Path(__file__).resolve().parent
    candidates = [here.parent / _SCHEMA_FILE]
    # pip / colcon install: data_files put msg_schemas under <prefix>/share/sensorispace_ros.
    # (<prefix>/lib/pythonX.Y/site-packages/sensorispace_ros -> parents[3] is <prefix>).
    for prefix in dict.fromkeys([Path(sys.prefix), *here.parents[3:4]]):
        candidates.append(prefix / "share" / PACKAGE / _SCHEMA_FILE)
    try:
        from ament_index_python.packages import get_package_share_directory
        candidates.append(Path(get_package_share_directory(PACKAGE)) / _SCHEMA_FILE)
    except Exception:  # not an ament install, or package not indexed: other candidates apply
        pass
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    raise FileNotFoundError("msg_schemas/topics.yaml not found; looked in "
                            + ", ".join(str(c) for c in candidates))


def qos_profile(spec: dict) -> QoSProfile:
    history = HistoryPolicy.KEEP_ALL if spec["history"] == "keep_all" else HistoryPolicy.KEEP_LAST
    return QoSProfile(
        history=history,
        depth=int(spec.get("depth", 1 if history == HistoryPolicy.KEEP_LAST else 0)),
        reliability={"reliable": ReliabilityPolicy.RELIABLE,
                     "best_effort": ReliabilityPolicy.BEST_EFFORT}[spec["reliability"]],
        durability={"volatile": DurabilityPolicy.VOLATILE,
                     "transient_local": DurabilityPolicy.TRANSIENT_LOCAL}[spec["durability"]])


@lru_cache(maxsize=None)
def load_contracts(path: str | None = None) -> dict[str, TopicContract]:
    raw = yaml.safe_load(Path(path or schema_path()).read_text())
    contracts = {}
    for name, spec in raw["topics"].items():
        contracts[name] = TopicContract(
            name=name, type_name=spec["type"], qos=qos_profile(spec["qos"]),
            publisher=spec["publisher"], subscribers=tuple(spec.get("subscribers", ())),
            ground_truth=bool(spec.get("ground_truth", False)),
            columns=dict(spec.get("columns") or {}), frame_id=str(spec.get("frame_id", "")),
            meaning=str(spec.get("meaning", "")),
            elements=tuple(spec.get("elements") or ()))
    return contracts


def contract(topic: str) -> TopicContract:
    try:
        return load_contracts()[topic]
    except KeyError:
        raise KeyError(f"topic {topic!r} has no contract in {schema_path()}") from None


def topics_published_by(node: str) -> list[str]:
    return [t for t, c in load_contracts().items() if c.publisher == node]


def topics_subscribed_by(node: str) -> list[str]:
    return [t for t, c in load_contracts().items() if node in c.subscribers]


def _incompatible_qos_warning(node, topic: str):
    def warn(event) -> None:
        node.get_logger().warning(f"{topic}: an endpoint with incompatible QoS "
                                  f"({event.last_policy_kind}) will not be connected")
    return warn


# rclpy adds two default event handlers (incompatible QoS, incompatible type)
# to every endpoint and rebuilds the wait set from all of them on every spin:
# measured 1.5 -> 1.1 ms per in-process round trip when only the QoS warning
# (the pitfall that silently loses data, ROS_NOTES.md) is kept.
def create_publisher(node, topic: str):
    """A publisher whose type and QoS come from the contract."""
    spec = contract(topic)
    return node.create_publisher(spec.msg_type, topic, spec.qos, event_callbacks=PublisherEventCallbacks(
        incompatible_qos=_incompatible_qos_warning(node, topic), use_default_callbacks=False))


def subscription_qos(topic: str) -> QoSProfile:
    """The contract's QoS with KEEP_ALL history.

    History is not part of QoS matching: ``keep_last(1)`` on a publisher
    bounds what it keeps for late joiners, but a depth-1 *subscription*
    drops every message but the newest of a burst (measured: a malformed
    message arriving just after the real /environment/lights replaced it
    and the run stalled).
    """
    spec = contract(topic)
    return QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=0, reliability=spec.qos.reliability,
                      durability=spec.qos.durability)


def create_subscription(node, topic: str, callback, **kwargs):
    spec = contract(topic)
    return node.create_subscription(
        spec.msg_type, topic, callback, subscription_qos(topic),
        event_callbacks=SubscriptionEventCallbacks(
            incompatible_qos=_incompatible_qos_warning(node, topic), use_default_callbacks=False),
        **kwargs)
