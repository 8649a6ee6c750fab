"""Reading rosbag2 bags (mcap or sqlite3 directories, or a bare ``.mcap``/``.db3`` file).

::

    from ext_sense_bags import BagReader

    with BagReader("out/run1") as bag:
        print(bag.topics)                       # {topic: TopicSummary(msgtype, count, type_hash)}
        for rec in bag.records(["/extsense/nuskin/events"]):    # in log-time order
            msg = bag.decode(rec)               # rosbags message object (NumPy arrays)
            rec.data                            # the CDR bytes, e.g. to publish(bytes) with rclpy
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path
from types import TracebackType
from typing import Any, NamedTuple

from rosbags.rosbag2 import Reader

from ext_sense_bags.errors import BagError
from ext_sense_bags.typestore import make_typestore


class TopicSummary(NamedTuple):
    """One topic of a bag."""

    msgtype: str
    count: int
    type_hash: str


class BagRecord(NamedTuple):
    """One stored message: topic, type, log time in integer ns and the CDR bytes."""

    topic: str
    msgtype: str
    log_time_ns: int
    data: bytes


class BagReader:
    """A rosbag2 reader decoding with the ext_sense typestore.

    Args:
        path: Bag directory, or a single ``.mcap`` / ``.db3`` file.
        distro: Typestore distribution for :meth:`decode`.

    Raises:
        BagError: The path does not exist or is not a readable bag (on :meth:`open`).
    """

    def __init__(self, path: str | Path, *, distro: str = "kilted") -> None:
        self.path = Path(path)
        self.typestore = make_typestore(distro)
        self._reader: Reader | None = None

    def open(self) -> BagReader:
        """Open the bag and read its index; returns ``self``."""
        if not self.path.exists():
            raise BagError(f"Bag {self.path} does not exist.")
        try:
            reader = Reader(self.path)
            reader.open()
        except Exception as err:  # rosbags raises several types for corrupt files
            raise BagError(f"Cannot read bag {self.path}: {err}") from err
        self._reader = reader
        return self

    def _require(self) -> Reader:
        if self._reader is None:
            raise BagError(f"Bag {self.path} is not open; use 'with BagReader(...)' or open().")
        return self._reader

    @property
    def topics(self) -> dict[str, TopicSummary]:
        """Topic -> :class:`TopicSummary`, sorted by topic name."""
        reader = self._require()
        out: dict[str, TopicSummary] = {}
        for conn in sorted(reader.connections, key=lambda c: c.topic):
            prev = out.get(conn.topic)
            count = conn.msgcount + (prev.count if prev else 0)
            out[conn.topic] = TopicSummary(conn.msgtype, count, conn.digest)
        return out

    @property
    def message_count(self) -> int:
        """Messages in the bag."""
        return self._require().message_count

    @property
    def start_time_ns(self) -> int:
        """Log time of the first message, integer ns."""
        return self._require().start_time

    @property
    def duration_ns(self) -> int:
        """Log time from the first to the last message, integer ns."""
        return self._require().duration

    @property
    def custom_data(self) -> dict[str, str]:
        """The ``custom_data`` map of the bag's metadata (empty when there is none)."""
        meta = getattr(self._require().storage, "metadata", None)
        return dict(getattr(meta, "custom", None) or {})

    def records(self, topics: Iterable[str] | None = None) -> Iterator[BagRecord]:
        """Yield the stored messages of ``topics`` (all when ``None``) in log-time order.

        Raises:
            BagError: A requested topic is not in the bag, or the file is corrupt.
        """
        reader = self._require()
        conns = reader.connections
        if topics is not None:
            wanted = set(topics)
            if missing := wanted - {c.topic for c in conns}:
                have = sorted({c.topic for c in conns})
                raise BagError(f"Topic(s) {sorted(missing)} not in bag {self.path}; it has {have}.")
            conns = [c for c in conns if c.topic in wanted]
            if not conns:
                return
        try:
            for conn, log_time, data in reader.messages(connections=conns):
                yield BagRecord(conn.topic, conn.msgtype, int(log_time), bytes(data))
        except BagError:
            raise
        except Exception as err:
            raise BagError(f"Corrupt bag {self.path}: {err}") from err

    def decode(self, record: BagRecord) -> Any:
        """Deserialize one record to a rosbags message object.

        Raises:
            BagError: The type is not in the typestore or the bytes do not decode.
        """
        if record.msgtype not in self.typestore.fielddefs:
            raise BagError(f"Cannot decode {record.msgtype!r}: not in the typestore.")
        try:
            return self.typestore.deserialize_cdr(record.data, record.msgtype)
        except Exception as err:
            raise BagError(
                f"Message on {record.topic} at {record.log_time_ns} ns does not decode as "
                f"{record.msgtype}: {err}"
            ) from err

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[tuple[BagRecord, Any]]:
        """Like :meth:`records`, with each record's decoded message."""
        for rec in self.records(topics):
            yield rec, self.decode(rec)

    def close(self) -> None:
        """Close the bag."""
        if self._reader is not None:
            self._reader.close()
            self._reader = None

    def __enter__(self) -> BagReader:
        return self.open()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
