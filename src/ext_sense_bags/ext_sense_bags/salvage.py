"""Reading what a killed recorder left: an mcap file without footer, a sqlite3 bag left open.

The writer flushes every ``flush_period_s``, so such a file is complete records followed at worst
by one cut off. mcap: read record by record with mcap's ``StreamReader``; a chunk failing its
size or CRC is dropped, the scan ends at the first record cut off. sqlite3: SQLite's own crash
recovery runs on opening read-write, then rosbags reads it. :func:`salvage` yields topics and
messages in file order and fills a :class:`Report`.
"""

from __future__ import annotations

import contextlib
import sqlite3
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

from mcap.exceptions import McapError
from mcap.records import Channel, Chunk, DataEnd, McapRecord, Message, Schema
from mcap.stream_reader import CRCValidationError, StreamReader, breakup_chunk
from rosbags.interfaces import MessageDefinitionFormat, Qos
from rosbags.rosbag2 import Reader
from rosbags.rosbag2.metadata import parse_qos

from ext_sense_bags.errors import BagError, why

MAGIC = b"\x89MCAP0\r\n"
STOPPED = "the recorder stopped without closing the bag"


class SalvagedTopic(NamedTuple):
    """One topic (an mcap channel or a sqlite3 topic row) as the file stores it."""

    id: int
    topic: str
    msgtype: str
    msgdef: str
    """Message definition text ('' when none)."""
    encoding: str
    """``ros2msg`` or ``ros2idl``."""
    type_hash: str
    """RIHS01 hash ('' when none)."""
    qos: list[Qos] | None


Item = SalvagedTopic | tuple[int, int, bytes]
"""A topic, or one message: ``(topic id, log time ns, CDR bytes)``."""


@dataclass
class Report:
    """What a salvage found: the storage file, what was wrong, and what was dropped."""

    file: Path
    storage: str
    notes: list[str] = field(default_factory=list)
    """What was wrong, in the order found (none: the file was complete)."""
    empty: bool = False
    """The file holds no more than (part of) the mcap magic."""
    chunks: int = 0
    """Complete mcap chunks read."""
    chunks_dropped: int = 0
    """mcap chunks cut off or unreadable (their messages are lost)."""
    bytes_dropped: int = 0
    """Bytes of the file that could not be used."""
    orphans: int = 0
    """Messages whose channel record was lost (not returned)."""

    @property
    def problem(self) -> str:
        """What was wrong ('' when the file was complete)."""
        return "; ".join(self.notes)

    def describe(self) -> str:
        """One line: the problem and what was dropped."""
        dropped = (
            f"{self.chunks} complete chunks read, {self.chunks_dropped} dropped, "
            f"{self.bytes_dropped} bytes dropped"
            if self.storage == "mcap"
            else "committed transactions kept, the uncommitted last one discarded"
        )
        orphans = f", {self.orphans} messages of lost channels" if self.orphans else ""
        return f"{self.problem or 'complete'} ({dropped}{orphans})"


def storage_file(path: Path) -> Path:
    """The one ``.mcap``/``.db3`` file of a bag directory (or ``path`` itself if a file).

    Raises:
        BagError: None, or several.
    """
    if not path.is_dir():
        return path
    files = sorted(p for p in path.iterdir() if p.suffix in (".mcap", ".db3") and p.is_file())
    if not files:
        raise BagError(f"Bag {path} holds no .mcap or .db3 file.")
    if len(files) > 1:
        names = [p.name for p in files]
        raise BagError(f"Bag {path} has no usable metadata.yaml and several files: {names}.")
    return files[0]


def incomplete(path: Path) -> str:
    """Why the bag at ``path`` was not closed by its writer ('' when it was).

    Raises:
        BagError: ``path`` does not exist, or is a directory without ``metadata.yaml`` and
            not exactly one storage file.
    """
    if not path.exists():
        raise BagError(f"Bag {path} does not exist.")
    files = (
        sorted(p for p in path.iterdir() if p.suffix in (".mcap", ".db3"))
        if path.is_dir()
        else [path]
    )
    if len(files) == 1 and files[0].suffix == ".db3":
        if any(files[0].with_name(files[0].name + s).exists() for s in _LOGS):
            return f"an open write-ahead log or journal: {STOPPED}"
    elif len(files) == 1 and files[0].suffix == ".mcap" and not _ends_with_magic(files[0]):
        return f"no footer: {STOPPED}"
    if path.is_dir() and not (path / "metadata.yaml").exists():
        storage_file(path)  # exactly one storage file, else the error says what is there
        return "no metadata.yaml"
    return ""


_LOGS = ("-wal", "-journal")


def _ends_with_magic(file: Path) -> bool:
    try:
        with file.open("rb") as bio:
            size = bio.seek(0, 2)
            bio.seek(max(0, size - len(MAGIC)))
            return size > len(MAGIC) and bio.read() == MAGIC
    except OSError as err:
        raise BagError(f"Cannot read {file}: {why(err)}") from err


def salvage(path: Path) -> tuple[Report, Iterator[Item]]:
    """Open a bag a killed writer left, to read what it holds.

    Args:
        path: Bag directory, or its ``.mcap``/``.db3`` file.

    Returns:
        The report (complete once the items are consumed) and the topics and messages in file
        order, each topic before its first message.

    Raises:
        BagError: The file is not a bag file (the error names it and what is wrong).
    """
    file = storage_file(path)
    if file.suffix == ".db3":
        report = Report(file, "sqlite3")
        return report, _sqlite_items(file, report, incomplete(path))
    if file.suffix != ".mcap":
        raise BagError(f"Cannot read bag {path}: unknown storage format {file.suffix!r}.")
    report = Report(file, "mcap")
    try:
        with file.open("rb") as bio:
            head = bio.read(len(MAGIC))
    except OSError as err:
        raise BagError(f"Cannot read {file}: {why(err)}") from err
    if len(head) < len(MAGIC) and MAGIC.startswith(head):
        report.notes.append("empty: the recorder stopped before its first write")
        report.bytes_dropped, report.empty = len(head), True
        return report, iter(())
    if head != MAGIC:
        raise BagError(f"{file} is not an mcap file (it starts with {head!r}).")
    no_meta = path.is_dir() and not (path / "metadata.yaml").exists()
    return report, _mcap_items(file, report, no_meta=no_meta)


def messages_in_file(path: Path) -> int:
    """Messages a salvage of the mcap bag at ``path`` gets back (0 when none)."""
    try:
        _, items = salvage(path)
        return sum(1 for item in items if not isinstance(item, SalvagedTopic))
    except BagError:
        return 0


def _mcap_items(file: Path, report: Report, *, no_meta: bool) -> Iterator[Item]:
    schemas: dict[int, Schema] = {}
    topics: set[int] = set()
    with file.open("rb") as bio:
        size = bio.seek(0, 2)
        bio.seek(0)
        pos = len(MAGIC)  # the magic was checked; the first record follows
        try:
            for record in StreamReader(bio, emit_chunks=True, record_size_limit=size).records:
                if isinstance(record, DataEnd):  # the writer closed the file
                    if no_meta:
                        report.notes.append("no metadata.yaml (the mcap file itself is complete)")
                    return
                records: list[McapRecord] = [record]
                if isinstance(record, Chunk):
                    try:
                        records = _chunk_records(record)
                        report.chunks += 1
                    except ValueError as err:
                        report.chunks_dropped += 1
                        report.bytes_dropped += bio.tell() - pos
                        report.notes.append(f"a chunk at byte {pos} dropped: {err}")
                        records = []
                for rec in records:
                    if isinstance(rec, Schema):
                        schemas[rec.id] = rec
                    elif isinstance(rec, Channel) and rec.id not in topics:
                        topics.add(rec.id)
                        yield _mcap_topic(rec, schemas.get(rec.schema_id))
                    elif isinstance(rec, Message) and rec.channel_id in topics:
                        yield rec.channel_id, rec.log_time, rec.data
                    elif isinstance(rec, Message):
                        report.orphans += 1
                pos = bio.tell()
        except (McapError, ValueError, struct.error):  # a record cut off, or not mcap data
            pass
        cut = bio.seek(0, 2) - pos  # measured again: a bag being recorded grows meanwhile
    report.bytes_dropped += cut
    where = f"; the record at byte {pos} is cut off or unreadable ({cut} bytes dropped)"
    report.notes.insert(0, f"no footer: {STOPPED}" + (where if cut else ""))


def _chunk_records(chunk: Chunk) -> list[McapRecord]:
    """The records of a chunk whose size and CRC check out.

    Raises:
        ValueError: The chunk is cut off, does not decompress, or fails its CRC.
    """
    if chunk.compression == "" and len(chunk.data) != chunk.uncompressed_size:
        raise ValueError("it is cut off")
    try:
        return breakup_chunk(chunk, validate_crc=True)
    except CRCValidationError:
        raise ValueError("checksum mismatch") from None
    except Exception as err:  # the decompressors and the record parser raise several types
        raise ValueError(f"it does not read: {why(err)}") from err


def _mcap_topic(channel: Channel, schema: Schema | None) -> SalvagedTopic:
    qos = None
    with contextlib.suppress(Exception):  # a QoS text rosbags cannot parse: the standard one
        qos = parse_qos(channel.metadata.get("offered_qos_profiles", ""))
    return SalvagedTopic(
        channel.id,
        channel.topic,
        schema.name if schema else "",
        schema.data.decode(errors="replace") if schema else "",
        schema.encoding if schema else "",
        channel.metadata.get("topic_type_hash", ""),
        qos or None,
    )


def _sqlite_items(file: Path, report: Report, problem: str) -> Iterator[Item]:
    try:  # SQLite recovers the file when it is first read, read-write
        with contextlib.closing(sqlite3.connect(f"file:{file}?mode=rw", uri=True)) as db:
            db.execute("SELECT count(*) FROM sqlite_master").fetchone()
            db.execute("PRAGMA journal_mode=DELETE")  # a write-ahead log checkpointed into it
    except sqlite3.Error as err:
        raise BagError(f"Cannot read sqlite3 bag file {file}: {why(err)}.") from err
    if problem:
        report.notes.append(problem)
    try:
        with Reader(file) as reader:
            for conn in reader.connections:
                idl = conn.msgdef.format == MessageDefinitionFormat.IDL
                qos = getattr(conn.ext, "offered_qos_profiles", None) or None
                yield SalvagedTopic(
                    conn.id,
                    conn.topic,
                    conn.msgtype,
                    conn.msgdef.data,
                    "ros2idl" if idl else "ros2msg",
                    conn.digest,
                    qos,
                )
            for conn, log_time, data in reader.messages():
                yield conn.id, log_time, bytes(data)
    except BagError:
        raise
    except Exception as err:  # rosbags and apsw raise several types for a broken database
        raise BagError(f"Cannot read sqlite3 bag file {file}: {why(err)}") from err
