"""What a bag of this project is, shared by its writer, reader and recovery.

A bag is a rosbag2 directory holding ``metadata.yaml`` (rosbag2 version 9, as
Jazzy writes) and one ``<dir>.mcap`` file with profile ``ros2``, ``ros2msg``
schemas, ``cdr`` messages in zstd-compressed chunks, every MCAP CRC (chunks,
data section, summary) and a summary with Statistics (recording.bag_storage,
recording.bag_writer; checked by recording.bag_verify; docs/bags.md).
Messages are stored as the exact CDR bytes a ``raw=True`` subscription
delivers (``rclpy.serialization.serialize_message`` appends 8-12 garbage
bytes on Jazzy that rosbags rejects).

The session configuration travels inside the bag as the first message of
``SESSION_CONFIG_TOPIC`` (std_msgs/msg/String holding the ROS params-file
YAML), so ``sensorispace analyze`` needs nothing but the bag. No rclpy here.
"""
from __future__ import annotations

SESSION_CONFIG_TOPIC = "/session/config"
SESSION_CONFIG_TYPE = "std_msgs/msg/String"


class BagError(Exception):
    """A bag that cannot be written, read or recovered; the message is one line."""


def one_line(exc: BaseException) -> str:
    """An exception's message on one line (for a BagError built from it)."""
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def typestore():
    """rosbags' type store of Jazzy: its RIHS01 hashes equal the ones the Jazzy
    wheels announce."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def session_config_cdr(params_yaml: str) -> bytes:
    """CDR bytes of a std_msgs/msg/String holding ``params_yaml``."""
    store = typestore()
    string_cls = store.types[SESSION_CONFIG_TYPE]
    return bytes(store.serialize_cdr(string_cls(data=params_yaml), SESSION_CONFIG_TYPE))
