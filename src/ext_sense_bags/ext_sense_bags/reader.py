"""Reading rosbag2 bags (mcap or sqlite3 directories, or a bare ``.mcap``/``.db3`` file).

::

    from ext_sense_bags import BagReader

    with BagReader("out/run1") as bag:
        print(bag.topics)                       # {topic: TopicSummary(msgtype, count, type_hash)}
        for rec in bag.records(["/extsense/nuskin/events"]):    # in log-time order
            msg = bag.decode(rec)               # rosbags message object (NumPy arrays)
            rec.data                            # the CDR bytes, e.g. to publish(bytes) with rclpy

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
from ext_sense_bags.records import BagRecord, SalvageReport, TopicSummary
from ext_sense_bags.salvage import Salvage, has_open_log, open_salvaged, storage_file
from ext_sense_bags.typestore import make_typestore

__all__ = ["BagReader", "BagRecord", "TopicSummary"]


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
        self._salvage: Salvage | None = None

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
                yield BagRecord(conn.topic, conn.msgtype, int(log_time), bytes(data))
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
                yield BagRecord(info.topic, info.msgtype, log_time, data)
        except (OSError, ValueError) as err:
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
