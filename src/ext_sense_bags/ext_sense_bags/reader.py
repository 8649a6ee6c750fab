"""Reading rosbag2 bags (mcap or sqlite3 directories, or a bare ``.mcap``/``.db3`` file).

::

    from ext_sense_bags import BagReader

    with BagReader("out/run1") as bag:
        print(bag.topics)                       # {topic: TopicSummary(msgtype, count, type_hash)}
        for rec in bag.records(["/extsense/nuskin/events"]):    # in log-time order
            msg = bag.decode(rec)               # rosbags message object (NumPy arrays)
            rec.data                            # the CDR bytes, as recorded
            bag.current_cdr(rec)                # the bytes in the current definition: publish

A bag recorded before a message definition changed keeps decoding: each topic's recorded type
hash is compared with the current typestore's, and a topic recorded with another definition
decodes with a typestore built from the definition the bag stores
(:mod:`ext_sense_bags.recorded`); its messages have the fields as recorded (a field added since
is missing: read it with ``getattr(msg, name, default)``). :meth:`BagReader.current_cdr` turns
such a message into the current type, the new fields at their defaults, for a live graph.

A bag a killed recorder left (an mcap file without footer, a bag directory without
``metadata.yaml``, a sqlite3 file with its write-ahead log) is read through
:mod:`ext_sense_bags.salvage`: every complete message, with ``salvaged`` saying what was wrong
(``ext-sense bag recover`` rewrites such a bag whole). When nothing can be read the
:class:`BagError` names the file and what is wrong with it.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path
from types import TracebackType
from typing import Any

from rosbags.rosbag2 import Reader

from ext_sense_bags.errors import BagError
from ext_sense_bags.recorded import TypeSource, decoding_store, to_current
from ext_sense_bags.records import BagRecord, SalvageReport, TopicSummary
from ext_sense_bags.salvage import Salvage, has_open_log, open_salvaged, storage_file
from ext_sense_bags.typestore import make_typestore

__all__ = ["BagReader", "BagRecord", "TopicSummary"]


class BagReader:
    """A rosbag2 reader decoding with the ext_sense typestore.

    Args:
        path: Bag directory, or a single ``.mcap`` / ``.db3`` file.
        distro: Typestore distribution for :meth:`decode` (topics recorded with the current
            definitions; the others decode with the definition the bag stores).

    Raises:
        BagError: The path does not exist or is not a readable bag (on :meth:`open`).
    """

    def __init__(self, path: str | Path, *, distro: str = "kilted") -> None:
        self.path = Path(path)
        self.distro = distro
        self.typestore = make_typestore(distro)
        self._reader: Reader | None = None
        self._salvage: Salvage | None = None
        self._sources: dict[tuple[str, str, str], TypeSource] = {}

    def open(self) -> BagReader:
        """Open the bag and read its index; returns ``self``.

        A bag without footer or metadata is read as far as it is complete (``salvaged``).
        """
        if not self.path.exists():
            raise BagError(f"Bag {self.path} does not exist.")
        if self._needs_salvage():
            self._salvage = open_salvaged(self.path)
            return self
        try:
            reader = Reader(self.path)
            reader.open()
        except Exception as err:  # rosbags raises several types for corrupt files
            if not _may_salvage(self.path):
                raise BagError(f"Cannot read bag {self.path}: {err}") from err
            self._salvage = open_salvaged(self.path, str(err))
            return self
        self._reader = reader
        return self

    def _needs_salvage(self) -> bool:
        """No metadata.yaml in a directory, or a sqlite3 file whose log was never closed."""
        if self.path.is_dir() and not (self.path / "metadata.yaml").exists():
            return True
        try:
            file = storage_file(self.path)
        except BagError:
            return False
        return file.suffix == ".db3" and has_open_log(file)

    @property
    def salvaged(self) -> str:
        """'' for a complete bag; else what was wrong and what was dropped (one line)."""
        if self._salvage is None:
            self._require()
            return ""
        return self._salvage.report.describe()

    @property
    def salvage_report(self) -> SalvageReport | None:
        """What the salvage of an incomplete bag found (None for a complete bag)."""
        if self._salvage is None:
            self._require()  # raises when not open
            return None
        return self._salvage.report

    def _require(self) -> Reader:
        if self._reader is None:
            raise BagError(f"Bag {self.path} is not open; use 'with BagReader(...)' or open().")
        return self._reader

    @property
    def topics(self) -> dict[str, TopicSummary]:
        """Topic -> :class:`TopicSummary`, sorted by topic name."""
        out: dict[str, TopicSummary] = {}
        if self._salvage is not None:
            found = self._salvage.topics
            rows = [
                (t.topic, t.msgtype, self._salvage.counts.get(i, 0), t.type_hash)
                for i, t in found.items()
            ]
        else:
            rows = [(c.topic, c.msgtype, c.msgcount, c.digest) for c in self._require().connections]
        for topic, msgtype, count, digest in sorted(rows):
            prev = out.get(topic)
            out[topic] = TopicSummary(msgtype, count + (prev.count if prev else 0), digest)
        return out

    @property
    def message_count(self) -> int:
        """Messages in the bag."""
        if self._salvage is not None:
            return sum(self._salvage.counts.values())
        return self._require().message_count

    @property
    def start_time_ns(self) -> int:
        """Log time of the first message, integer ns."""
        if self._salvage is not None:
            return self._salvage.start_ns
        return self._require().start_time

    @property
    def duration_ns(self) -> int:
        """Log time from the first to the last message, integer ns."""
        if self._salvage is not None:
            salvage = self._salvage
            return salvage.end_ns - salvage.start_ns + 1 if salvage.counts else 0
        return self._require().duration

    @property
    def custom_data(self) -> dict[str, str]:
        """The ``custom_data`` map of the bag's metadata (empty when there is none)."""
        if self._salvage is not None:
            return {}
        meta = getattr(self._require().storage, "metadata", None)
        return dict(getattr(meta, "custom", None) or {})

    def records(self, topics: Iterable[str] | None = None) -> Iterator[BagRecord]:
        """Yield the stored messages of ``topics`` (all when ``None``) in log-time order.

        Raises:
            BagError: A requested topic is not in the bag, or the file is corrupt.
        """
        if self._salvage is not None:
            yield from self._salvaged_records(topics)
            return
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
        except BagError:
            raise
        except Exception as err:
            raise BagError(f"Corrupt bag {self.path}: {err}") from err

    def _salvaged_records(self, topics: Iterable[str] | None) -> Iterator[BagRecord]:
        salvage = self._salvage
        assert salvage is not None
        found = salvage.topics
        ids = None
        if topics is not None:
            wanted = set(topics)
            have = {t.topic for t in found.values()}
            if missing := wanted - have:
                raise BagError(
                    f"Topic(s) {sorted(missing)} not in bag {self.path}; it has {sorted(have)}."
                )
            ids = [i for i, t in found.items() if t.topic in wanted]
        try:
            for cid, log_time, data in salvage.records(ids):
                info = found[cid]
                yield BagRecord(info.topic, info.msgtype, log_time, data, info.type_hash)
        except (OSError, ValueError) as err:
            raise BagError(f"Corrupt bag {self.path}: {err}") from err

    def type_source(self, record: BagRecord) -> TypeSource:
        """The typestore ``record`` decodes with: the current one, or its topic's recorded one.

        Resolved once per (topic, type, recorded hash) from the definition the bag stores for
        it, so a bag older than a ``.msg`` change decodes as it was written.
        """
        key = (record.topic, record.msgtype, record.type_hash)
        if key not in self._sources:
            stored = [d for d in self._definitions() if d[:3] == key]
            _, msgtype, digest, msgdef, encoding = next((d for d in stored if d[3]), (*key, "", ""))
            self._sources[key] = decoding_store(msgtype, digest, msgdef, encoding, self.distro)
        return self._sources[key]

    def _definitions(self) -> list[tuple[str, str, str, str, Any]]:
        """``(topic, type, recorded hash, definition text, its encoding)`` per connection."""
        if self._salvage is not None:
            return [
                (t.topic, t.msgtype, t.type_hash, t.msgdef, t.msgdef_encoding)
                for t in self._salvage.topics.values()
            ]
        return [
            (c.topic, c.msgtype, c.digest, c.msgdef.data, c.msgdef.format)
            for c in self._require().connections
        ]

    def decode(self, record: BagRecord) -> Any:
        """Deserialize one record to a rosbags message object, with the fields as recorded.

        Raises:
            BagError: The type is in neither the typestore nor the bag, or the bytes do not
                decode (the message says when the bag was recorded with another definition
                it does not store).
        """
        source = self.type_source(record)
        if record.msgtype not in source.store.fielddefs:
            raise BagError(f"Cannot decode {record.msgtype!r}: not in the typestore.")
        try:
            return source.store.deserialize_cdr(record.data, record.msgtype)
        except Exception as err:
            why = (
                f" (the bag recorded it with another definition, hash {record.type_hash}, "
                f"and {source.problem})"
                if source.problem
                else ""
            )
            raise BagError(
                f"Message on {record.topic} at {record.log_time_ns} ns does not decode as "
                f"{record.msgtype}{why}: {err}"
            ) from err

    def current_cdr(self, record: BagRecord) -> bytes:
        """``record``'s bytes in the current definition of its type (e.g. to publish them).

        The stored bytes when the topic was recorded with the current definition; else the
        message decoded as recorded, converted (fields added since at their defaults) and
        serialized anew, so a live subscriber of the current type can read it.

        Raises:
            BagError: The message does not decode or does not convert.
        """
        if not self.type_source(record).recorded:
            return record.data
        msg = to_current(self.decode(record), record.msgtype, self.distro)
        try:
            return bytes(self.typestore.serialize_cdr(msg, record.msgtype))
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
        """Close the bag."""
        if self._reader is not None:
            self._reader.close()
            self._reader = None
        if self._salvage is not None:
            self._salvage.close()
            self._salvage = None

    def __enter__(self) -> BagReader:
        return self.open()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def _may_salvage(path: Path) -> bool:
    """Whether a bag that rosbags cannot open may be an mcap file without its footer."""
    try:
        return storage_file(path).suffix == ".mcap"
    except BagError:
        return False
