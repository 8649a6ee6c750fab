"""Reading rosbag2 bags (mcap or sqlite3 directories, or a bare ``.mcap``/``.db3`` file).

::

    with BagReader("out/run1") as bag:
        for rec, msg in bag.messages(["/extsense/nuskin/packets"]):  # in log-time order
            bag.current_cdr(rec)        # the bytes in the current definition: publish them

Reading goes through rosbags' ``AnyReader`` with the definitions the bag stores, so a bag
recorded before a ``.msg`` changed decodes as written (read new fields with ``getattr``);
:meth:`BagReader.current_cdr` converts to the current definition for a live graph. A bag a
killed recorder left is recovered into a temporary directory and read from there
(``salvaged`` says what was wrong).
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from types import TracebackType
from typing import Any, NamedTuple

from rosbags.highlevel import AnyReader
from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

from ext_sense_bags.errors import BagError, why
from ext_sense_bags.messages import make_message
from ext_sense_bags.recover import recover_bag
from ext_sense_bags.salvage import incomplete, storage_file
from ext_sense_bags.typestore import make_typestore

__all__ = ["BagReader", "BagRecord", "TopicSummary", "to_current"]


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
    type_hash: str = ""
    """RIHS01 hash its topic recorded ('' when none)."""


class BagReader:
    """A rosbag2 reader decoding with the definitions the bag stores.

    Args:
        path: Bag directory, or a single ``.mcap`` / ``.db3`` file.
        distro: Distribution of the current typestore (types the bag stores no definition
            of; the target of :meth:`current_cdr`).

    Raises:
        BagError: The path does not exist or is not a readable bag (on :meth:`open`).
    """

    def __init__(self, path: str | Path, *, distro: str = "kilted") -> None:
        self.path = Path(path)
        self.distro = distro
        self.current = make_typestore(distro)
        self.salvaged = ""
        """'' for a complete bag; else what was wrong and what was dropped (one line)."""
        self._reader: AnyReader | None = None
        self._copy: Path | None = None
        self._differs: dict[str, bool] = {}

    def open(self) -> BagReader:
        """Open the bag (a damaged one as far as it is complete); returns ``self``."""
        if incomplete(self.path):
            return self._open_recovered()
        try:
            self._reader = _open(self.path)
        except BagError as err:  # an mcap file cut inside, its footer intact: salvage it
            if not _is_mcap(self.path):
                raise
            return self._open_recovered(err)
        return self

    def _open_recovered(self, cause: BagError | None = None) -> BagReader:
        """Read a recovered copy in a temporary directory (removed on :meth:`close`)."""
        self._copy = Path(tempfile.mkdtemp(prefix="ext_sense_bag-"))
        try:
            result = recover_bag(self.path, self._copy / "bag")
            if cause is not None and not result.report.problem:  # the file is whole
                raise cause
            self._reader = _open(result.out, self.path)
        except BaseException:
            self.close()
            raise
        self.salvaged = result.report.describe()
        return self

    def _require(self) -> AnyReader:
        if self._reader is None:
            raise BagError(f"Bag {self.path} is not open; use 'with BagReader(...)' or open().")
        return self._reader

    @property
    def topics(self) -> dict[str, TopicSummary]:
        """Topic -> :class:`TopicSummary`, sorted by topic name."""
        out: dict[str, TopicSummary] = {}
        for c in sorted(self._require().connections, key=lambda c: c.topic):
            prev = out.get(c.topic)
            out[c.topic] = TopicSummary(
                c.msgtype, c.msgcount + (prev.count if prev else 0), c.digest
            )
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
        """Log time from the first to just after the last message, integer ns."""
        return self._require().duration if self.message_count else 0

    @property
    def custom_data(self) -> dict[str, str]:
        """The ``custom_data`` map of the bag's metadata (empty when there is none)."""
        storage = self._require().readers[0].storage
        return dict(getattr(getattr(storage, "metadata", None), "custom", None) or {})

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
                yield BagRecord(conn.topic, conn.msgtype, int(log_time), bytes(data), conn.digest)
        except Exception as err:  # rosbags raises several types for corrupt files
            raise BagError(f"Corrupt bag {self.path}: {why(err)}") from err

    def _store(self, record: BagRecord) -> Typestore:
        """The typestore ``record`` decodes with: the bag's definitions, else the current one.

        Raises:
            BagError: The bag stores no definition of the type and recorded another hash for
                it than the current one, or the type is in neither.
        """
        bag = self._require().typestore
        if record.msgtype in bag.fielddefs:
            return bag
        if record.msgtype not in self.current.fielddefs:
            raise BagError(f"Cannot decode {record.msgtype!r}: not in the typestore.")
        if record.type_hash and record.type_hash != self.current.hash_rihs01(record.msgtype):
            raise BagError(
                f"Message on {record.topic} at {record.log_time_ns} ns does not decode as "
                f"{record.msgtype} (the bag recorded it with another definition, hash "
                f"{record.type_hash}, and the bag stores no definition of it)."
            )
        return self.current

    def differs(self, msgtype: str) -> bool:
        """Whether the bag stores a definition of ``msgtype`` other than the current one."""
        if msgtype not in self._differs:
            bag = self._require().typestore
            self._differs[msgtype] = msgtype in bag.fielddefs and (
                msgtype not in self.current.fielddefs
                or bag.hash_rihs01(msgtype) != self.current.hash_rihs01(msgtype)
            )
        return self._differs[msgtype]

    def decode(self, record: BagRecord) -> Any:
        """Deserialize one record to a rosbags message object, with the fields as recorded.

        Raises:
            BagError: The type is in neither the bag nor the typestore, or does not decode.
        """
        store = self._store(record)
        try:
            return store.deserialize_cdr(record.data, record.msgtype)
        except Exception as err:
            raise BagError(
                f"Message on {record.topic} at {record.log_time_ns} ns does not decode as "
                f"{record.msgtype}: {why(err)}"
            ) from err

    def current_cdr(self, record: BagRecord) -> bytes:
        """``record``'s bytes in the current definition of its type (e.g. to publish them).

        The stored bytes when the bag recorded the current definition; else converted with
        :func:`to_current` and serialized anew.

        Raises:
            BagError: The message does not decode or does not convert.
        """
        if not self.differs(record.msgtype):
            return record.data
        msg = to_current(self.decode(record), record.msgtype, self.distro)
        try:
            return bytes(self.current.serialize_cdr(msg, record.msgtype))
        except Exception as err:
            raise BagError(
                f"Message on {record.topic} at {record.log_time_ns} ns does not convert to the "
                f"current {record.msgtype}: {err}"
            ) from err

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[tuple[BagRecord, Any]]:
        """Like :meth:`records`, with each record's decoded message."""
        for rec in self.records(topics):
            yield rec, self.decode(rec)

    def close(self) -> None:
        """Close the bag (and remove a recovered copy)."""
        if self._reader is not None:
            self._reader.close()
            self._reader = None
            self._differs.clear()
        if self._copy is not None:
            shutil.rmtree(self._copy, ignore_errors=True)
            self._copy = None

    def __enter__(self) -> BagReader:
        return self.open()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def _open(path: Path, name: Path | None = None) -> AnyReader:
    """Open rosbags' ``AnyReader`` on a bag; its errors as :class:`BagError` naming ``name``."""
    try:
        reader = AnyReader([path], default_typestore=make_typestore())
        reader.open()
    except Exception as err:  # rosbags raises several types for unreadable files
        raise BagError(f"Cannot read bag {name or path}: {why(err)}") from err
    return reader


def _is_mcap(path: Path) -> bool:
    try:
        return storage_file(path).suffix == ".mcap"
    except BagError:
        return False


def to_current(msg: Any, msgtype: str, distro: str = "kilted") -> Any:
    """``msg`` (of any definition of ``msgtype``) as a message of the current definition.

    Fields the current type has and ``msg`` lacks (added since the recording) get their ROS
    defaults; fields ``msg`` has and the current type lacks are dropped. Nested messages are
    converted the same way.

    Raises:
        BagError: ``msgtype`` is not in the current typestore, or a field does not convert.
    """
    store = make_typestore(distro)
    if msgtype not in store.fielddefs:
        raise BagError(f"Unknown message type {msgtype!r}: not in the {distro} typestore.")
    fields: dict[str, Any] = {}
    for name, (kind, detail) in store.fielddefs[msgtype][1]:
        if not hasattr(msg, name):
            continue
        value = getattr(msg, name)
        if kind == Nodetype.NAME:
            value = to_current(value, detail, distro)
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE) and detail[0][0] == Nodetype.NAME:
            value = [to_current(v, detail[0][1], distro) for v in value]
        fields[name] = value
    try:
        return make_message(msgtype, distro, **fields)
    except (TypeError, ValueError) as err:
        raise BagError(f"A recorded {msgtype} does not convert to the current type: {err}") from err
