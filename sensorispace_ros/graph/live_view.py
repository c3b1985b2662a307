"""The live view: the viewer's topics served to the Foxglove app (Foxglove SDK).

A WebSocket server (protocol ``foxglove.websocket.v1``) on localhost only
advertises one channel per topic with the topic's ROS 2 message definition
(``ros2msg`` schema, as rosbag2 stores it in an MCAP file) and sends each
message as the CDR bytes the viewer publishes on ROS: the app decodes and
draws them as it does a bag or a ROS 2 bridge. The SDK's server runs in its
own threads; ``log`` only hands the bytes over, and drops them while no
client is subscribed.
"""
from __future__ import annotations

from typing import Mapping

from sensorispace_ros.recording.bag_format import typestore

LOCALHOST = "127.0.0.1"
DEFAULT_PORT = 8765                       # Foxglove's usual WebSocket port
SERVER_NAME = "sensorispace_ros"


def ros2msg_definition(type_name: str) -> bytes:
    """The full ``ros2msg`` definition of ``type_name`` (``pkg/msg/Type``):
    its fields, then every nested type after a ``MSG: pkg/Type`` line."""
    store = typestore()
    if type_name not in store.types:
        raise ValueError(f"unknown message type {type_name!r}")
    text, _ = store.generate_msgdef(type_name)
    return text.encode("utf-8")


def websocket_url(port: int, host: str = LOCALHOST) -> str:
    return f"ws://{host}:{int(port)}"


class LiveView:
    """A Foxglove WebSocket server on ``host:port`` with one CDR channel per
    topic of ``topics`` ({topic: ROS 2 type name}). Raises RuntimeError when the
    port cannot be bound (the SDK's message names the cause)."""

    def __init__(self, port: int, topics: Mapping[str, str], host: str = LOCALHOST):
        import foxglove

        if not 0 < int(port) < 65536:
            raise ValueError(f"port: must be in 1..65535, got {port}")
        self.context = foxglove.Context()
        self.channels = {
            topic: foxglove.Channel(
                topic, message_encoding="cdr", context=self.context,
                schema=foxglove.Schema(name=type_name, encoding="ros2msg",
                                       data=ros2msg_definition(type_name)))
            for topic, type_name in topics.items()}
        self.server = foxglove.start_server(name=SERVER_NAME, host=host, port=int(port),
                                            context=self.context)
        self.url = websocket_url(self.server.port, host)

    def log(self, topic: str, cdr: bytes, time_ns: int) -> None:
        """Send ``cdr`` (a message of ``topic``) to the subscribed clients."""
        self.channels[topic].log(bytes(cdr), log_time=int(time_ns))

    def close(self) -> None:
        self.server.stop()
        for channel in self.channels.values():
            channel.close()
