"""A minimal client of the Foxglove WebSocket protocol, for tests: it reads the
channels a server advertises, subscribes to all of them and collects the
message data frames, in a thread of its own. The Foxglove SDK's server speaks
``foxglove.sdk.v1`` (the framing of ``foxglove.websocket.v1``, which it
refuses); the client offers both, as the Foxglove app does."""
from __future__ import annotations

import json
import struct
import threading
import time

from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")
MESSAGE_DATA = 0x01                       # binary opcode: subscription id, log time, payload
_MESSAGE_HEADER = struct.Struct("<BIQ")


class FoxgloveClient:
    """Connects to ``url`` (retrying until ``connect_timeout_s``) and collects,
    per topic, the (log time, payload) of every message until ``stop``."""

    def __init__(self, url: str, connect_timeout_s: float = 60.0):
        self.url = url
        self.connect_timeout_s = connect_timeout_s
        self.channels: dict[int, dict] = {}       # channel id -> advertised channel
        self.messages: dict[str, list[tuple[int, bytes]]] = {}
        self.error: BaseException | None = None
        self.subprotocol: str | None = None      # what the server chose
        self._subscribed: dict[int, str] = {}     # subscription id -> topic
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self.thread = threading.Thread(target=self._run, name="foxglove-client", daemon=True)

    def start(self) -> "FoxgloveClient":
        self.thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self.thread.join(timeout=10)

    def received(self, topic: str) -> list[tuple[int, bytes]]:
        with self._lock:
            return list(self.messages.get(topic, ()))

    def _connect(self):
        deadline = time.monotonic() + self.connect_timeout_s
        while True:
            try:
                return connect(self.url, subprotocols=list(SUBPROTOCOLS), open_timeout=5)
            except (OSError, TimeoutError):
                if time.monotonic() > deadline or self._stop.is_set():
                    raise
                time.sleep(0.2)

    def _run(self) -> None:
        try:
            with self._connect() as socket:
                self.subprotocol = socket.subprotocol
                while not self._stop.is_set():
                    try:
                        frame = socket.recv(timeout=0.2)
                    except TimeoutError:
                        continue
                    except ConnectionClosed:
                        return
                    if isinstance(frame, str):
                        self._on_text(socket, json.loads(frame))
                    else:
                        self._on_binary(frame)
        except BaseException as exc:      # reported to the test by ``error``
            self.error = exc

    def _on_text(self, socket, message: dict) -> None:
        if message.get("op") != "advertise":
            return
        subscriptions = []
        for channel in message["channels"]:
            self.channels[channel["id"]] = channel
            subscription = len(self._subscribed)
            self._subscribed[subscription] = channel["topic"]
            subscriptions.append({"id": subscription, "channelId": channel["id"]})
        socket.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))

    def _on_binary(self, frame: bytes) -> None:
        if frame[0] != MESSAGE_DATA:
            return
        _, subscription, log_time = _MESSAGE_HEADER.unpack_from(frame)
        topic = self._subscribed[subscription]
        with self._lock:
            self.messages.setdefault(topic, []).append(
                (log_time, bytes(frame[_MESSAGE_HEADER.size:])))
