"""Topic contracts (msg_schemas/topics.yaml) as Python objects.

Nodes create their publishers and subscriptions from here, and tests compare
the live graph with the same file, so the documentation of a topic and the
code that uses it cannot drift apart.

Some topics are sized by the body: their columns are written with a
placeholder, ``m<j>`` for one column per joint of the body description
(``m0..m{N-1}``) and ``s<i>`` for one per receptor (``s0..s{R-1}``), and a
JointState's ``joint_names: description`` names the description's joints.
``TopicContract.columns_for(description)`` expands them (the description is
what the body publishes on ``/body/description``:
``core.body_description.BodyDescription``); ``columns`` of such a topic is a
ContractError, so nothing can size it from anything but a description.

The table itself is plain Python (the analysis of a bag reads it without
rclpy); a contract's QoS profile and the publishers and subscriptions made
from it import rclpy when asked for.

A column's type is one of COLUMN_TYPES. ``number`` (the sensations' columns)
stands for any of NUMBER_TYPES, the PointField types a real sensor gives
(FLOAT64, FLOAT32, UINT16, UINT8), one type for every such column of a
message, as its fields say: readers convert it to float64
(``messages.cloud_to_matrix``), and a row of NaN in it is a lost frame.
"""
from __future__ import annotations

import importlib
import os
import sys
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import yaml

PACKAGE = "sensorispace_ros"
_SCHEMA_FILE = Path("msg_schemas") / "topics.yaml"


PER_JOINT = "<j>"           # in a column name: one column per joint, j = 0..N-1
PER_RECEPTOR = "<i>"        # in a column name: one column per receptor, i = 0..R-1
DESCRIBED = "description"   # joint_names: the body description's joint names
NUMBER_TYPES = ("float64", "float32", "uint16", "uint8")
COLUMN_TYPES = ("float64", "float32", "uint32", "int32", "uint16", "uint8", "number")


class ContractError(ValueError):
    """A topic's layout asked for without what it depends on (the body description)."""


def _expanded(names, description, topic: str) -> list[str]:
    """``names`` with every placeholder name expanded over the description's
    joints or receptors."""
    out = []
    for name in names:
        placeholder = next((p for p in (PER_JOINT, PER_RECEPTOR) if p in name), None)
        if placeholder is None:
            out.append(name)
            continue
        if description is None:
            raise ContractError(f"{topic}: {name!r} depends on the body description "
                                "(/body/description); use columns_for(description)")
        count = description.n_motors if placeholder == PER_JOINT else description.receptors
        out.extend(name.replace(placeholder, str(k)) for k in range(count))
    return out


@dataclass(frozen=True)
class TopicContract:
    name: str
    type_name: str                 # e.g. "sensor_msgs/msg/PointCloud2"
    qos_spec: dict                 # topics.yaml's qos entry (history, depth, reliability, ...)
    publisher: str
    subscribers: tuple[str, ...]
    ground_truth: bool
    column_spec: dict              # {column: type name} as written, placeholders included
    frame_id: str
    meaning: str
    element_spec: tuple[str, ...] = ()   # names of a Float64MultiArray's data[i], as written
    joint_names_spec: tuple[str, ...] | str = ()   # a JointState's names, or DESCRIBED

    @property
    def qos(self):
        """The topic's ``rclpy.qos.QoSProfile``."""
        return qos_profile(self.qos_spec)

    @property
    def msg_type(self):
        package, _, name = self.type_name.split("/")
        return getattr(importlib.import_module(f"{package}.msg"), name)

    @property
    def described(self) -> bool:
        """Whether the body description fixes this topic's columns, elements or joint names."""
        names = (*self.column_spec, *self.element_spec)
        return (self.joint_names_spec == DESCRIBED
                or any(PER_JOINT in n or PER_RECEPTOR in n for n in names))

    def columns_for(self, description) -> dict:
        """{column: type name} for a body of ``description`` (None: a topic
        whose columns do not depend on the body)."""
        columns = {}
        for name, kind in self.column_spec.items():
            columns.update(dict.fromkeys(_expanded([name], description, self.name), kind))
        return columns

    @property
    def columns(self) -> dict:
        """{column: type name}, empty for non-table types; ContractError for a
        topic sized by the body (``columns_for``)."""
        return self.columns_for(None)

    def elements_for(self, description) -> tuple[str, ...]:
        return tuple(_expanded(self.element_spec, description, self.name))

    @property
    def elements(self) -> tuple[str, ...]:
        return self.elements_for(None)

    def joint_names_for(self, description) -> tuple[str, ...]:
        if self.joint_names_spec != DESCRIBED:
            return tuple(self.joint_names_spec)
        if description is None:
            raise ContractError(f"{self.name}: its joint names are the body description's "
                                "(/body/description)")
        return tuple(description.joint_names)


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


def qos_profile(spec: dict):
    """An ``rclpy.qos.QoSProfile`` from a topics.yaml qos entry."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

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
        unknown = set((spec.get("columns") or {}).values()) - set(COLUMN_TYPES)
        if unknown:
            raise ContractError(f"{name}: column types {sorted(unknown)} are not among "
                                f"{', '.join(COLUMN_TYPES)}")
        contracts[name] = TopicContract(
            name=name, type_name=spec["type"], qos_spec=dict(spec["qos"]),
            publisher=spec["publisher"], subscribers=tuple(spec.get("subscribers", ())),
            ground_truth=bool(spec.get("ground_truth", False)),
            column_spec=dict(spec.get("columns") or {}), frame_id=str(spec.get("frame_id", "")),
            meaning=str(spec.get("meaning", "")),
            element_spec=tuple(spec.get("elements") or ()),
            joint_names_spec=_joint_names_spec(spec.get("joint_names")))
    return contracts


def _joint_names_spec(spec) -> tuple[str, ...] | str:
    if spec == DESCRIBED:
        return DESCRIBED
    return tuple(str(name) for name in spec or ())


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
# to every endpoint and rebuilds the wait set from all of them on every spin;
# only the QoS warning (the pitfall that silently loses data, ROS_NOTES.md) is
# kept, which shortens every round trip (docs/benchmarks.md).
def create_publisher(node, topic: str):
    """A publisher whose type and QoS come from the contract."""
    from rclpy.event_handler import PublisherEventCallbacks

    spec = contract(topic)
    return node.create_publisher(spec.msg_type, topic, spec.qos, event_callbacks=PublisherEventCallbacks(
        incompatible_qos=_incompatible_qos_warning(node, topic), use_default_callbacks=False))


def subscription_qos(topic: str):
    """The contract's QoS with KEEP_ALL history.

    History is not part of QoS matching: ``keep_last(1)`` on a publisher
    bounds what it keeps for late joiners, but a depth-1 *subscription*
    drops every message but the newest of a burst (a malformed message
    arriving just after the real /environment/lights would replace it).
    """
    from rclpy.qos import HistoryPolicy, QoSProfile

    spec = contract(topic)
    return QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=0, reliability=spec.qos.reliability,
                      durability=spec.qos.durability)


def create_subscription(node, topic: str, callback, **kwargs):
    from rclpy.event_handler import SubscriptionEventCallbacks

    spec = contract(topic)
    return node.create_subscription(
        spec.msg_type, topic, callback, subscription_qos(topic),
        event_callbacks=SubscriptionEventCallbacks(
            incompatible_qos=_incompatible_qos_warning(node, topic), use_default_callbacks=False),
        **kwargs)
