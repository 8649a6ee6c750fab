"""Writing rosbag2 bags (mcap by default, or sqlite3) that ``ros2 bag play`` accepts.

::

    with BagWriter("out/run1", storage=Storage.MCAP) as bag:     # a new directory
        bag.write("/extsense/ground_truth", onset_ns, ground_truth(onset_ns, task, trial))
        bag.write_raw("/extsense/contact_estimate", t_ns, cdr_bytes)  # rclpy raw=True bytes

Log times are receive times in integer ns (``ros2 bag play`` paces on them). Each topic
carries its full definition and RIHS01 hash, so rosbag2 decodes the bag without ext_sense.
Every ``flush_period_s`` the pending mcap chunk is written and fsynced (sqlite3: committed),
so a killed writer leaves every flushed message recoverable. A failed write raises
:class:`BagError` naming the cause and sets ``failed``.
"""

from __future__ import annotations

import contextlib
import os
import sqlite3
import time
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import Any, ClassVar

from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rosbags.interfaces import (
    Connection,
    MessageDefinitionFormat,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.rosbag2.enums import CompressionMode
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer

from ext_sense_bags.errors import BagError
from ext_sense_bags.salvage import messages_in_file
from ext_sense_bags.topics import STANDARD_TOPICS, TopicSpec
from ext_sense_bags.typestore import make_typestore

Storage = StoragePlugin
"""Storage plugin of a bag: rosbags' enum, ``Storage.MCAP`` or ``Storage.SQLITE3``."""
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


class McapStorage:
    """rosbag2's mcap storage for rosbags' ``Writer``, written by mcap's: flushed on demand."""

    def __init__(self, path: Path, compression: CompressionMode) -> None:
        self.path = path / f"{path.name}.mcap"
        self._file = self.path.open("xb")
        self._mcap = McapWriter(self._file, compression=CompressionType.NONE)
        self._mcap.start(profile="ros2", library="ext_sense_bags")
        self._file.flush()  # the magic and header are on disk before the first chunk
        self._schemas: dict[str, int] = {}
        self._channels: dict[int, int] = {}

    def add_msgtype(self, connection: Connection) -> None:
        """Register the schema of a type (its definition text)."""
        idl = connection.msgdef.format == MessageDefinitionFormat.IDL
        self._schemas[connection.msgtype] = self._mcap.register_schema(
            connection.msgtype, "ros2idl" if idl else "ros2msg", connection.msgdef.data.encode()
        )

    def add_connection(self, connection: Connection, offered_qos_profiles: str) -> None:
        """Register a channel with its offered QoS and type hash."""
        metadata = {"offered_qos_profiles": offered_qos_profiles}
        metadata["topic_type_hash"] = connection.digest
        schema = self._schemas[connection.msgtype]
        self._channels[connection.id] = self._mcap.register_channel(
            connection.topic, "cdr", schema, metadata
        )

    def write(self, connection: Connection, timestamp: int, data: bytes | memoryview) -> None:
        """Append one message to the pending chunk."""
        self._mcap.add_message(self._channels[connection.id], timestamp, data, timestamp)

    def flush(self) -> None:
        """Close the pending chunk (if any), write it out and fsync."""
        self._mcap.flush()
        os.fsync(self._file.fileno())

    def close(self, version: int, metadata: str) -> None:
        """Write the last chunk, rosbag2's metadata record and the summary; close the file."""
        self._mcap.flush()
        self._mcap.add_metadata("rosbag2", {"serialized_metadata": metadata})
        self._mcap.finish()
        self._file.close()

    def abort(self) -> None:
        """Close the file as it is (after a failed write)."""
        with contextlib.suppress(OSError):
            self._file.close()


class Sqlite3Storage(Sqlite3Writer):
    """rosbags' sqlite3 storage with :meth:`flush` (rosbags commits only on close)."""

    def flush(self) -> None:
        """Commit what was written since the last flush."""
        self.conn.commit()


class _Writer(Writer):
    STORAGE_PLUGINS: ClassVar = {
        StoragePlugin.MCAP: McapStorage,
        StoragePlugin.SQLITE3: Sqlite3Storage,
    }


_WRITE_ERRORS = (OSError, sqlite3.Error, ValueError)
"""What a storage raises when the disk is full, the file too large, or the file gone."""


def _reason(err: BaseException) -> str:
    """An OS or SQLite error in a few words (``[Errno 28] No space left on device``)."""
    if isinstance(err, OSError) and err.strerror:
        return f"[Errno {err.errno}] {err.strerror}" + (f": {err.filename}" if err.filename else "")
    return f"{type(err).__name__}: {err}" if not isinstance(err, sqlite3.Error) else str(err)


class BagWriter:
    """A rosbag2 writer for ext_sense messages.

    Args:
        path: Directory of the new bag; must not exist yet.
        storage: :class:`Storage` (mcap by default) or its name ``"mcap"``/``"sqlite3"``.
        distro: Typestore distribution (``"kilted"`` or ``"jazzy"``).
        topics: Extra or overriding topic specs, merged over ``STANDARD_TOPICS``.
        flush_period_s: Close the pending chunk / commit at least this often (s); a writer
            killed at any moment loses at most the messages of the last period.

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
        flush_period_s: float = 1.0,
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
        if not flush_period_s > 0:
            raise BagError(f"The 'flush_period_s' must be > 0. Got {flush_period_s!r}.")
        self.flush_period_s = float(flush_period_s)
        self.counts: dict[str, int] = {}
        self.flushed = 0
        """Messages written and flushed to the disk (what survives a crash now)."""
        self.failed = ""
        """Why writing stopped ('' while it works)."""
        self._written = 0
        self._last_flush = time.monotonic()
        self._connections: dict[str, Connection] = {}
        try:
            self._writer = _Writer(self.path, version=9, storage_plugin=storage)
        except WriterError as err:
            raise BagError(f"Cannot create bag at {self.path}: {err}") from err
        self._open = False

    def open(self) -> BagWriter:
        """Create the bag directory and storage file; returns ``self``.

        Raises:
            BagError: The path exists, or cannot be created or written (permissions, disk).
        """
        try:
            self._writer.open()
        except WriterError as err:
            raise BagError(f"Cannot create bag at {self.path}: {err}") from err
        except (OSError, sqlite3.Error) as err:
            self._writer.storage = None
            raise BagError(f"Cannot create bag at {self.path}: {_reason(err)}.") from err
        self._open = True
        self._last_flush = time.monotonic()
        return self

    def add_topic(
        self,
        topic: str,
        msgtype: str | None = None,
        *,
        reliable: bool | None = None,
        depth: int | None = None,
        definition: tuple[str, str] | None = None,
        qos: Sequence[Qos] | None = None,
    ) -> None:
        """Register ``topic`` before its first message (optional: ``write`` does it too).

        Args:
            topic: Absolute topic name.
            msgtype: Full type name; defaults to the standard table's.
            reliable: Offered reliability; defaults to the standard table's (else True).
            depth: Offered history depth; defaults to the standard table's (else 100).
            definition: ``(definition text, RIHS01 hash)`` to store instead of the typestore's.
            qos: Offered QoS profiles to store instead of ``reliable``/``depth``.

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
        if definition is None and msgtype not in self.typestore.fielddefs:
            raise BagError(f"Unknown message type {msgtype!r} for topic {topic!r}.")
        profiles = (
            list(qos)
            if qos is not None
            else [
                offered_qos(
                    reliable if reliable is not None else (spec.reliable if spec else True),
                    depth if depth is not None else (spec.depth if spec else 100),
                )
            ]
        )
        msgdef, rihs01 = definition if definition is not None else (None, None)
        self._connections[topic] = self._guard(
            lambda: self._writer.add_connection(
                topic,
                msgtype,
                typestore=self.typestore,
                msgdef=msgdef,
                rihs01=rihs01,
                offered_qos_profiles=profiles,
            )
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
        conn, t_ns = self._connections[topic], int(log_time_ns)
        if not 0 <= t_ns < 2**63:
            raise BagError(f"The log time of a message on {topic} must be >= 0 ns. Got {t_ns}.")
        self._guard(lambda: self._writer.write(conn, t_ns, data))
        self.counts[topic] += 1
        self._written += 1
        if time.monotonic() - self._last_flush >= self.flush_period_s:
            self.flush()

    def flush(self) -> None:
        """Write what is pending to the disk now (close the mcap chunk and fsync; commit)."""
        if not self._open:
            raise BagError(f"Bag {self.path} is not open.")
        self._guard(lambda: self._writer.storage.flush())  # type: ignore[union-attr]
        self.flushed = self._written
        self._last_flush = time.monotonic()

    def flush_if_due(self) -> bool:
        """Flush when messages are pending and ``flush_period_s`` has passed; whether it did."""
        due = time.monotonic() - self._last_flush >= self.flush_period_s
        if self._open and due and self._written > self.flushed:
            self.flush()
            return True
        return False

    def _guard(self, action: Any) -> Any:
        """Run a storage action; a failure stops the writer with a clear :class:`BagError`."""
        if self.failed:
            raise BagError(self.failed)
        try:
            return action()
        except WriterError as err:  # a misuse (rosbags checks), not the disk
            raise BagError(f"Bag {self.path}: {err}") from err
        except _WRITE_ERRORS as err:
            self._stop(err)

    def _stop(self, err: BaseException) -> None:
        self._open = False
        with contextlib.suppress(Exception):  # the storage is broken already; the error says so
            self._writer.abort()
        if self.storage == Storage.MCAP:  # a chunk may be whole in the file with its index cut
            self.flushed = max(self.flushed, messages_in_file(self.path))
        self.failed = (
            f"Cannot write bag {self.path}: {_reason(err)}; recording stopped after "
            f"{self._written} messages, {self.flushed} of them flushed to the disk "
            f"(`ext-sense bag recover {self.path}` rewrites them as a complete bag)."
        )
        raise BagError(self.failed) from err

    def set_custom_data(self, key: str, value: str) -> None:
        """Store a string in the bag's metadata ``custom_data`` (e.g. the task or the seed)."""
        self._writer.set_custom_data(key, str(value))

    def close(self) -> None:
        """Write the index and ``metadata.yaml``; the bag is readable afterwards.

        Raises:
            BagError: The final write failed (disk full): the flushed part stays recoverable.
        """
        if self._open:
            self._guard(self._writer.close)
            self._open = False
            self.flushed = self._written

    def __enter__(self) -> BagWriter:
        return self.open()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
