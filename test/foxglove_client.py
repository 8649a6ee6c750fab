"""A Foxglove WebSocket protocol client for the view's tests and benchmark (no Foxglove app).

Speaks the protocol as the app does (subprotocol ``foxglove.sdk.v1``: ``serverInfo`` and
``advertise`` JSON, ``subscribe``, binary message data ``0x01 | subscription u32 | log time
u64 | payload``) and decodes each payload by its channel's encoding: ``json``, ``protobuf``
(the FileDescriptorSet the channel advertises) or ``cdr`` (``ros2msg`` schemas, through the
ext_sense typestore).
"""

from __future__ import annotations

import base64
import json
import socket
import struct
import threading
import time
from typing import Any, NamedTuple

SUBPROTOCOL = "foxglove.sdk.v1"
_DATA = struct.Struct("<BIQ")


def free_port() -> int:
    """A TCP port on 127.0.0.1 free right now, for a view server under test."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Received(NamedTuple):
    """One message data frame: the channel's topic, arrival (monotonic s), log time, payload."""

    topic: str
    arrival_s: float
    log_time_ns: int
    payload: bytes


class FoxgloveClient:
    """Connects, subscribes to every channel advertised, and keeps every message in a thread."""

    def __init__(self, url: str, connect_timeout_s: float = 30.0) -> None:
        from websockets.sync.client import connect

        end = time.monotonic() + connect_timeout_s
        while True:
            try:
                self.ws = connect(url, subprotocols=[SUBPROTOCOL], open_timeout=2)
                break
            except OSError:
                if time.monotonic() > end:
                    raise
                time.sleep(0.3)
        self.channels: dict[int, dict[str, Any]] = {}
        self.subscriptions: dict[int, int] = {}
        self.received: list[Received] = []
        self.server_info: dict[str, Any] = {}
        self.statuses: list[dict[str, Any]] = []
        """The server's ``status`` messages (e.g. a refused subscription), for failure reports."""
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                frame = self.ws.recv(timeout=0.2)
            except TimeoutError:
                continue
            except Exception:  # the server closed: the node stopped
                return
            if isinstance(frame, str):
                self._on_text(json.loads(frame))
            elif frame and frame[0] == 0x01:
                _, sub, log_time = _DATA.unpack_from(frame)
                with self._lock:
                    channel = self.channels.get(self.subscriptions.get(sub, -1))
                    if channel is not None:
                        self.received.append(
                            Received(
                                channel["topic"], time.monotonic(), log_time, frame[_DATA.size :]
                            )
                        )

    def _on_text(self, msg: dict[str, Any]) -> None:
        if msg.get("op") == "serverInfo":
            self.server_info = msg
        elif msg.get("op") == "status":
            with self._lock:
                self.statuses.append(msg)
        elif msg.get("op") == "advertise":
            new = []
            with self._lock:
                for channel in msg["channels"]:
                    self.channels[channel["id"]] = channel
                    sub = len(self.subscriptions) + 1
                    self.subscriptions[sub] = channel["id"]
                    new.append({"id": sub, "channelId": channel["id"]})
            self.ws.send(json.dumps({"op": "subscribe", "subscriptions": new}))

    def topics(self) -> dict[str, dict[str, Any]]:
        """Advertised channels by topic."""
        with self._lock:
            return {c["topic"]: c for c in self.channels.values()}

    def messages(self, topic: str | None = None) -> list[Received]:
        """Received messages (of one topic), oldest first."""
        with self._lock:
            return [r for r in self.received if topic is None or r.topic == topic]

    def decode(self, item: Received) -> Any:
        """The payload decoded by its channel's encoding (a dict, protobuf or rosbags message)."""
        channel = self.topics()[item.topic]
        encoding = channel["encoding"]
        if encoding == "json":
            return json.loads(item.payload)
        if encoding == "protobuf":
            return _protobuf_class(channel["schemaName"], channel["schema"]).FromString(
                item.payload
            )
        if encoding == "cdr":
            from ext_sense_bags.typestore import make_typestore

            return make_typestore().deserialize_cdr(item.payload, channel["schemaName"])
        raise ValueError(f"Channel {item.topic}: no decoder for encoding {encoding!r}.")

    def close(self) -> None:
        """Stop reading and close the connection."""
        self._stop.set()
        self._thread.join(timeout=5)
        self.ws.close()


_CLASSES: dict[str, Any] = {}


def _protobuf_class(name: str, schema_b64: str) -> Any:
    if name not in _CLASSES:
        from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

        files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(schema_b64))
        pool = descriptor_pool.DescriptorPool()
        for f in files.file:
            pool.Add(f)
        _CLASSES[name] = message_factory.GetMessageClass(pool.FindMessageTypeByName(name))
    return _CLASSES[name]
