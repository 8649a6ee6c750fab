"""Writing rosbag2 bags (mcap by default, or sqlite3) that ``ros2 bag play`` accepts.

The writer API (used by the simulator for its bags and by ``ext-sense record``)::

    from ext_sense_bags import BagWriter, Storage, taxel_event_batch, ground_truth

    with BagWriter("out/run1", storage=Storage.MCAP) as bag:     # a new directory
        bag.write("/extsense/nuskin/events", t_ns,
                  taxel_event_batch(t_ns, taxel, polarity, value, offset_ns))
        bag.write("/extsense/ground_truth", onset_ns,
                  ground_truth(onset_ns, "tap_localization", trial, tap_position_m=0.12))
        bag.write_raw("/extsense/contact_estimate", t_ns, cdr_bytes)  # rclpy raw=True bytes

- ``write(topic, log_time_ns, msg)`` takes a rosbags message object (build one with
  :func:`ext_sense_bags.make_message` or the helpers in :mod:`ext_sense_bags.messages`);
  ``write_raw`` takes CDR bytes as rclpy hands them out with ``raw=True`` or
  ``rclpy.serialization.serialize_message``.
- ``log_time_ns`` is the bag's receive time in integer nanoseconds (epoch); ``ros2 bag play``
  paces on it. Use the header stamp for simulated data.
- A topic is registered on its first write. Its type comes from the message object, from
  ``msgtype=`` or from :data:`ext_sense_bags.topics.STANDARD_TOPICS`; its offered QoS
  (recorded for ``ros2 bag play``) from ``add_topic`` or the standard table (sensor streams
  best effort, the rest reliable).
- Each channel carries the RIHS01 type hash of the rosidl build (metadata and mcap channel
  ``topic_type_hash``), and the full message definition as its schema, so ``mcap`` with
  ``mcap-ros2-support`` decodes the file without ROS.
- ``counts`` holds messages written per topic. The bag is complete only after ``close()``
  (the context manager closes it; on an exception the partial bag is still closed and
  readable).
"""

from __future__ import annotations

from enum import IntEnum
from io import BytesIO
from pathlib import Path
from types import TracebackType
from typing import Any, ClassVar

from rosbags.interfaces import (
    Connection,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.rosbag2.storage_mcap import Channel, McapWriter, write_channel, write_string

from ext_sense_bags.errors import BagError
from ext_sense_bags.topics import STANDARD_TOPICS, TopicSpec
from ext_sense_bags.typestore import make_typestore


class Storage(IntEnum):
    """Storage plugin of a bag."""

    MCAP = 1
    SQLITE3 = 2


_PLUGINS = {Storage.MCAP: StoragePlugin.MCAP, Storage.SQLITE3: StoragePlugin.SQLITE3}
_ZERO = QosTime(0, 0)


def offered_qos(reliable: bool, depth: int) -> Qos:
    """Return the QoS profile a topic is recorded as offered with (keep last, volatile)."""
    return Qos(
        history=QosHistory.KEEP_LAST,
        depth=int(depth),
        reliability=QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
        durability=QosDurability.VOLATILE,
        deadline=_ZERO,
        lifespan=_ZERO,
        liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=_ZERO,
        avoid_ros_namespace_conventions=False,
    )


class _McapWithHashes(McapWriter):
    """rosbags' mcap storage, adding ``topic_type_hash`` to the channel metadata as rosbag2 does."""

    def add_connection(self, connection: Connection, offered_qos_profiles: str) -> None:
        metadata = BytesIO()
        write_string(metadata, "offered_qos_profiles")
        write_string(metadata, offered_qos_profiles)
        write_string(metadata, "topic_type_hash")
        write_string(metadata, connection.digest)
        channel = Channel(
            connection.id,
            connection.msgtype,
            connection.topic,
            connection.ext.serialization_format,  # type: ignore[union-attr]
            metadata.getvalue(),
        )
        self.channels.append(channel)
        self.channel_stats[connection.id] = 0
        write_channel(self.chunk.bio, channel, self.schemas)


class _Writer(Writer):
    STORAGE_PLUGINS: ClassVar = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: _McapWithHashes}


class BagWriter:
    """A rosbag2 writer for ext_sense messages (see the module docstring for the API).

    Args:
        path: Directory of the new bag; must not exist yet.
        storage: :class:`Storage` (mcap by default) or its name ``"mcap"``/``"sqlite3"``.
        distro: Typestore distribution (``"kilted"`` or ``"jazzy"``).
        topics: Extra or overriding topic specs, merged over ``STANDARD_TOPICS``.

    Raises:
        BagError: The path exists or the storage is unknown.
    """

    def __init__(
        self,
        path: str | Path,
        storage: Storage | str = Storage.MCAP,
        *,
        distro: str = "kilted",
        topics: dict[str, TopicSpec] | None = None,
    ) -> None:
        self.path = Path(path)
        if isinstance(storage, str):
            try:
                storage = Storage[storage.upper()]
            except KeyError:
                raise BagError(
                    f"The 'storage' parameter must be 'mcap' or 'sqlite3'. Got {storage!r}."
                ) from None
        self.storage = storage
        self.distro = distro
        self.typestore = make_typestore(distro)
        self.specs = {**STANDARD_TOPICS, **(topics or {})}
        self.counts: dict[str, int] = {}
        self._connections: dict[str, Connection] = {}
        try:
            self._writer = _Writer(self.path, version=9, storage_plugin=_PLUGINS[storage])
        except WriterError as err:
            raise BagError(f"Cannot create bag at {self.path}: {err}") from err
        self._open = False

    def open(self) -> BagWriter:
        """Create the bag directory and storage file; returns ``self``."""
        try:
            self._writer.open()
        except WriterError as err:
            raise BagError(f"Cannot create bag at {self.path}: {err}") from err
        self._open = True
        return self

    def add_topic(
        self,
        topic: str,
        msgtype: str | None = None,
        *,
        reliable: bool | None = None,
        depth: int | None = None,
    ) -> None:
        """Register ``topic`` before its first message (optional: ``write`` does it too).

        Args:
            topic: Absolute topic name.
            msgtype: Full type name; defaults to the standard table's.
            reliable: Offered reliability; defaults to the standard table's (else True).
            depth: Offered history depth; defaults to the standard table's (else 100).

        Raises:
            BagError: Not open, type unknown, or the topic already registered with another type.
        """
        if not self._open:
            raise BagError(f"Bag {self.path} is not open; use 'with BagWriter(...)' or open().")
        spec = self.specs.get(topic)
        msgtype = msgtype or (spec.msgtype if spec else None)
        if msgtype is None:
            raise BagError(f"Topic {topic!r} is not a standard ext_sense topic: give its msgtype.")
        if topic in self._connections:
            known = self._connections[topic].msgtype
            if known != msgtype:
                raise BagError(f"Topic {topic!r} already holds {known}; cannot add {msgtype}.")
            return
        if msgtype not in self.typestore.fielddefs:
            raise BagError(f"Unknown message type {msgtype!r} for topic {topic!r}.")
        qos = offered_qos(
            reliable if reliable is not None else (spec.reliable if spec else True),
            depth if depth is not None else (spec.depth if spec else 100),
        )
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=self.typestore, offered_qos_profiles=[qos]
        )
        self.counts[topic] = 0

    def msgtype(self, topic: str) -> str | None:
        """The type registered for ``topic`` (None before its first message or ``add_topic``)."""
        conn = self._connections.get(topic)
        return conn.msgtype if conn else None

    def write(self, topic: str, log_time_ns: int, msg: Any) -> None:
        """Serialize a rosbags message object and append it.

        Raises:
            BagError: Not open, or the message does not match the topic's type.
        """
        msgtype = getattr(msg, "__msgtype__", None)
        if msgtype is None:
            raise BagError(
                f"write() needs a rosbags message object; got {type(msg).__name__} "
                "(use write_raw for serialized bytes)."
            )
        if topic not in self._connections:
            self.add_topic(topic, msgtype)
        elif self._connections[topic].msgtype != msgtype:
            raise BagError(
                f"Topic {topic!r} holds {self._connections[topic].msgtype}; got a {msgtype}."
            )
        data = self.typestore.serialize_cdr(msg, msgtype)
        self._append(topic, log_time_ns, data)

    def write_raw(
        self, topic: str, log_time_ns: int, data: bytes | memoryview, msgtype: str | None = None
    ) -> None:
        """Append already serialized CDR bytes (e.g. from an rclpy ``raw=True`` subscription).

        Raises:
            BagError: Not open, or the topic's type unknown.
        """
        if topic not in self._connections:
            self.add_topic(topic, msgtype)
        self._append(topic, log_time_ns, data)

    def _append(self, topic: str, log_time_ns: int, data: bytes | memoryview) -> None:
        if not self._open:
            raise BagError(f"Bag {self.path} is not open.")
        self._writer.write(self._connections[topic], int(log_time_ns), data)
        self.counts[topic] += 1

    def set_custom_data(self, key: str, value: str) -> None:
        """Store a string in the bag's metadata ``custom_data`` (e.g. the task or the seed)."""
        self._writer.set_custom_data(key, str(value))

    def close(self) -> None:
        """Write the index and ``metadata.yaml``; the bag is readable afterwards."""
        if self._open:
            self._open = False
            self._writer.close()

    def __enter__(self) -> BagWriter:
        return self.open()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
