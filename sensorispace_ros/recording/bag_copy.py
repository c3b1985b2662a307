"""New bags made of others' messages, bytes and timestamps unchanged: a copy of
some topics (``copy_bag``), the parts of one recording merged (``merge_bags``)."""
from __future__ import annotations

import heapq
import os
from pathlib import Path

from sensorispace_ros.recording.bag_format import BagError
from sensorispace_ros.recording.bag_reader import bag_info, read_bag
from sensorispace_ros.recording.bag_writer import BagWriter


def copy_bag(source: str | os.PathLike, target: str | os.PathLike,
             topics: list[str] | None = None) -> dict[str, int]:
    """Copy ``topics`` (default all) of a bag into a new bag (e.g. a small sample
    without the bulky probing streams), with their offered QoS. Returns the counts."""
    from rosbags.rosbag2 import Reader

    info = bag_info(source)
    chosen = list(info.topics) if topics is None else list(topics)
    missing = sorted(set(chosen) - set(info.topics))
    if missing:
        raise BagError(f"bag {source} has no topic {', '.join(missing)}")
    with Reader(Path(source)) as reader:
        qos = {c.topic: list(c.ext.offered_qos_profiles) for c in reader.connections}
    with BagWriter(target, {name: info.topics[name] for name in chosen},
                   qos={name: qos.get(name, []) for name in chosen}) as writer:
        for topic, _, timestamp, cdr in read_bag(source, chosen):
            writer.write(topic, timestamp, cdr)
        return dict(writer.counts)


def merge_bags(sources: list, target: str | os.PathLike) -> dict[str, int]:
    """One bag holding every message of ``sources`` in timestamp order (e.g. the parts
    of a recording interrupted by a recorder restart). Returns the counts."""
    infos = [bag_info(source) for source in sources]
    topics: dict[str, str] = {}
    for info in infos:
        for name, msgtype in info.topics.items():
            if topics.setdefault(name, msgtype) != msgtype:
                raise BagError(f"cannot merge: topic {name} is {topics[name]} in one bag "
                               f"and {msgtype} in {info.path}")
    streams = [((t, topic, cdr) for topic, _, t, cdr in read_bag(s)) for s in sources]
    with BagWriter(target, topics) as writer:
        for timestamp, topic, cdr in heapq.merge(*streams, key=lambda m: m[0]):
            writer.write(topic, timestamp, cdr)
        return dict(writer.counts)
