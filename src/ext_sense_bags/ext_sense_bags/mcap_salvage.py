"""Reading the complete records of an mcap file a killed writer left, without its summary.

The file is walked record by record from its magic: every complete chunk (and loose message)
is kept, with the schemas and channels it defines; the scan stops at the first record that is
cut off or unreadable, and what follows is counted as dropped; a chunk whose CRC-32 does not
match its records is dropped and the scan goes on. Nothing here trusts the summary section,
which a crashed writer never wrote. Used through :func:`ext_sense_bags.salvage.open_salvaged`.
"""

from __future__ import annotations

import heapq
import os
import struct
import zlib
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import BinaryIO, NamedTuple

from ext_sense_bags.errors import BagError
from ext_sense_bags.records import SalvagedTopic, SalvageReport

MAGIC = b"\x89MCAP0\r\n"
_OP_HEADER, _OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK = 1, 2, 3, 4, 5, 6
_OP_DATA_END = 0x0F
_OP_PRIVATE = 0x80  # opcodes from here on are private records: skipped
_RECORD = struct.Struct("<BQ")
_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_SCHEMA_HEAD = struct.Struct("<H")
_CHANNEL_HEAD = struct.Struct("<HH")
_MESSAGE_HEAD = struct.Struct("<HIQQ")
_CHUNK_HEAD = struct.Struct("<QQQI")


class _CutError(Exception):
    """A record runs past the end of its buffer."""


def _string(buf: memoryview, pos: int) -> tuple[str, int]:
    raw, pos = _bytes(buf, pos)
    return raw.decode(), pos


def _bytes(buf: memoryview, pos: int) -> tuple[bytes, int]:
    if pos + 4 > len(buf):
        raise _CutError
    (n,) = _U32.unpack_from(buf, pos)
    end = pos + 4 + n
    if end > len(buf):
        raise _CutError
    return bytes(buf[pos + 4 : end]), end


def _records(buf: memoryview) -> Iterator[tuple[int, memoryview]]:
    """The ``(opcode, body)`` records packed in ``buf`` (a chunk's records)."""
    pos = 0
    while pos < len(buf):
        if pos + _RECORD.size > len(buf):
            raise _CutError
        op, length = _RECORD.unpack_from(buf, pos)
        start = pos + _RECORD.size
        if start + length > len(buf):
            raise _CutError
        yield op, buf[start : start + length]
        pos = start + length


def _decompress(data: bytes, compression: str) -> bytes:
    if compression == "":
        return data
    if compression == "zstd":
        try:
            from compression import zstd  # type: ignore[import-not-found]  # Python >= 3.14
        except ImportError:
            from backports import zstd

        return zstd.decompress(data)
    if compression == "lz4":
        from lz4.frame import decompress

        return decompress(data)
    raise ValueError(f"unknown chunk compression {compression!r}")


def _uncompressed(data: bytes, compression: str, usize: int, crc: int) -> bytes:
    """A chunk's records, checked against the size and checksum in its header.

    Raises:
        ValueError: They do not decompress or do not match.
    """
    try:
        raw = _decompress(data, compression)
    except ValueError:
        raise
    except Exception as err:  # zstd and lz4 raise their own types on bad input
        raise ValueError(f"it does not decompress ({compression}): {err}") from err
    if len(raw) != usize:
        raise ValueError(f"it holds {len(raw)} bytes, its header says {usize}")
    if crc and zlib.crc32(raw) != crc:
        raise ValueError("checksum mismatch")
    return raw


class _Chunk(NamedTuple):
    offset: int
    """File offset of the chunk's (compressed) records."""
    size: int
    uncompressed_size: int
    crc: int
    compression: str
    start_ns: int
    """Log time of its first message (found, not taken from the header)."""
    counts: dict[int, int]


class _Loose(NamedTuple):
    channel: int
    log_time_ns: int
    data: bytes


class McapSalvage:
    """The complete records of an mcap file, read without its summary or footer.

    Args:
        file: The ``.mcap`` file.

    Raises:
        BagError: The file cannot be opened or does not start like an mcap file.
    """

    def __init__(self, file: Path) -> None:
        self.file = Path(file)
        self.report = SalvageReport(self.file, "mcap")
        self.complete = False
        """The data section ended properly (the writer got to close the file)."""
        self.empty = False
        """The file holds no more than (part of) the mcap magic."""
        self.topics: dict[int, SalvagedTopic] = {}
        self.counts: dict[int, int] = {}
        self.start_ns = 0
        self.end_ns = 0
        self._schemas: dict[int, tuple[str, str, str]] = {}
        self._blocks: list[_Chunk | _Loose] = []
        try:
            self._bio: BinaryIO = self.file.open("rb")
        except OSError as err:
            raise BagError(f"Cannot read {self.file}: {err.strerror}.") from err
        try:
            self._scan()
        except BaseException:
            self._bio.close()
            raise

    # scanning -------------------------------------------------------------------------------

    def _scan(self) -> None:
        bio = self._bio
        size = os.fstat(bio.fileno()).st_size
        magic = bio.read(len(MAGIC))
        if len(magic) < len(MAGIC) and MAGIC.startswith(magic):
            self.report.problem = "empty: the recorder stopped before its first write"
            self.report.bytes_dropped = len(magic)
            self.empty = True
            return
        if magic != MAGIC:
            raise BagError(f"{self.file} is not an mcap file (it starts with {magic[:8]!r}).")
        pos = len(MAGIC)
        while True:
            head = bio.read(_RECORD.size)
            if not head:
                self._note("no footer: the recorder stopped without closing the bag", first=True)
                return
            if len(head) < _RECORD.size:
                return self._cut(pos, size, "a record header")
            op, length = _RECORD.unpack(head)
            if op == 0 or _OP_DATA_END < op < _OP_PRIVATE:
                return self._cut(pos, size, f"unreadable data (opcode {op:#04x})", garbage=True)
            if pos + _RECORD.size + length > size:
                what = f"a record (opcode {op:#04x})"
                if op == _OP_CHUNK:
                    what = "a chunk"
                    self.report.chunks_dropped += 1
                return self._cut(pos, size, what)
            if op in (_OP_DATA_END, _OP_FOOTER):
                self.complete = True
                return
            if op == _OP_CHUNK:
                self._read_chunk(pos + _RECORD.size, length)
                bio.seek(pos + _RECORD.size + length)
            elif op in (_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE):
                try:
                    self._meta_record(op, memoryview(bio.read(length)), loose=True)
                except (_CutError, struct.error, UnicodeDecodeError):
                    return self._cut(pos, size, f"a record (opcode {op:#04x})", garbage=True)
            else:
                bio.seek(length, os.SEEK_CUR)
            pos += _RECORD.size + length

    def _cut(self, pos: int, size: int, what: str, garbage: bool = False) -> None:
        self.report.bytes_dropped += size - pos
        how = "is unreadable" if garbage else "is cut off"
        self._note(
            f"no footer: the recorder stopped without closing the bag; {what} at byte {pos} "
            f"{how} ({size - pos} bytes to the end of the file dropped)",
            first=True,
        )

    def _note(self, problem: str, first: bool = False) -> None:
        old = self.report.problem
        parts = [problem, old] if first else [old, problem]
        self.report.problem = "; ".join(p for p in parts if p)

    def _read_chunk(self, offset: int, length: int) -> None:
        """Check one chunk record and note its schemas, channels and message counts."""
        counts: dict[int, int] = {}
        orphans, first, last = 0, 2**63 - 1, 0
        try:
            body = memoryview(self._bio.read(length))
            _start_ns, _end_ns, usize, crc = _CHUNK_HEAD.unpack_from(body, 0)
            compression, pos = _string(body, _CHUNK_HEAD.size)
            if pos + 8 > len(body):
                raise _CutError
            (csize,) = _U64.unpack_from(body, pos)
            data_at = pos + 8
            if data_at + csize > len(body):
                raise _CutError
            raw = _uncompressed(bytes(body[data_at : data_at + csize]), compression, usize, crc)
            for op, rec in _records(memoryview(raw)):
                if op == _OP_MESSAGE:
                    cid, _seq, t, _pub = _MESSAGE_HEAD.unpack_from(rec, 0)
                    if cid not in self.topics:
                        orphans += 1
                        continue
                    counts[cid] = counts.get(cid, 0) + 1
                    first, last = min(first, t), max(last, t)
                elif op in (_OP_SCHEMA, _OP_CHANNEL):
                    self._meta_record(op, rec, loose=False)
        except (_CutError, ValueError, struct.error, UnicodeDecodeError) as err:
            self.report.chunks_dropped += 1
            self.report.bytes_dropped += _RECORD.size + length
            why = str(err) or "a record inside it is cut off"
            self._note(f"an unreadable chunk at byte {offset - _RECORD.size} dropped: {why}")
            return
        self.report.orphans += orphans
        self.report.chunks += 1
        self._blocks.append(_Chunk(offset + data_at, csize, usize, crc, compression, first, counts))
        self._add_counts(counts)
        if counts:
            self._widen(first, last)

    def _meta_record(self, op: int, rec: memoryview, *, loose: bool) -> None:
        if op == _OP_SCHEMA:
            (sid,) = _SCHEMA_HEAD.unpack_from(rec, 0)
            name, pos = _string(rec, _SCHEMA_HEAD.size)
            encoding, pos = _string(rec, pos)
            data, _ = _bytes(rec, pos)
            self._schemas[sid] = (name, encoding, data.decode(errors="replace"))
        elif op == _OP_CHANNEL:
            cid, sid = _CHANNEL_HEAD.unpack_from(rec, 0)
            topic, pos = _string(rec, _CHANNEL_HEAD.size)
            _encoding, pos = _string(rec, pos)
            meta_raw, _ = _bytes(rec, pos)
            meta: dict[str, str] = {}
            mview, mpos = memoryview(meta_raw), 0
            while mpos < len(mview):
                key, mpos = _string(mview, mpos)
                meta[key], mpos = _string(mview, mpos)
            name, msgenc, msgdef = self._schemas.get(sid, ("", "", ""))
            self.topics[cid] = SalvagedTopic(
                topic,
                name,
                msgdef,
                msgenc or "ros2msg",
                meta.get("topic_type_hash", ""),
                meta.get("offered_qos_profiles", ""),
            )
        elif op == _OP_MESSAGE and loose:
            cid, _seq, t, _pub = _MESSAGE_HEAD.unpack_from(rec, 0)
            if cid not in self.topics:
                self.report.orphans += 1
                return
            self._blocks.append(_Loose(cid, t, bytes(rec[_MESSAGE_HEAD.size :])))
            self._add_counts({cid: 1})
            self._widen(t, t)

    def _add_counts(self, counts: dict[int, int]) -> None:
        for cid, n in counts.items():
            self.counts[cid] = self.counts.get(cid, 0) + n

    def _widen(self, first: int, last: int) -> None:
        if not self.start_ns and not self.end_ns:
            self.start_ns, self.end_ns = first, last
        else:
            self.start_ns, self.end_ns = min(self.start_ns, first), max(self.end_ns, last)

    # reading --------------------------------------------------------------------------------

    def _chunk_messages(self, chunk: _Chunk, wanted: set[int] | None) -> list[_Loose]:
        self._bio.seek(chunk.offset)
        data = self._bio.read(chunk.size)
        raw = _uncompressed(data, chunk.compression, chunk.uncompressed_size, chunk.crc)
        out = []
        for op, rec in _records(memoryview(raw)):
            if op == _OP_MESSAGE:
                cid, _seq, t, _pub = _MESSAGE_HEAD.unpack_from(rec, 0)
                if cid in chunk.counts and (wanted is None or cid in wanted):
                    out.append(_Loose(cid, t, bytes(rec[_MESSAGE_HEAD.size :])))
        return out

    def records(
        self, channels: Iterable[int] | None = None, *, ordered: bool = True
    ) -> Iterator[tuple[int, int, bytes]]:
        """Yield ``(channel id, log time ns, CDR bytes)`` of the complete messages.

        Args:
            channels: Channel ids to read (all when None).
            ordered: Log-time order (chunks are read lazily, merged by time); else file order.
        """
        wanted = None if channels is None else set(channels)

        def block_messages(block: _Chunk | _Loose) -> Iterator[_Loose]:
            if isinstance(block, _Loose):
                if wanted is None or block.channel in wanted:
                    yield block
                return
            if ordered:  # a marker at the chunk's start: the chunk is read when it is due
                yield _Loose(-1, block.start_ns, b"")
                yield from sorted(self._chunk_messages(block, wanted), key=lambda m: m[1])
            else:
                yield from self._chunk_messages(block, wanted)

        blocks = [
            b
            for b in self._blocks
            if wanted is None
            or (b.channel in wanted if isinstance(b, _Loose) else wanted & b.counts.keys())
        ]
        if ordered:
            stream = heapq.merge(*(block_messages(b) for b in blocks), key=lambda m: m[1])
        else:
            stream = (m for b in blocks for m in block_messages(b))
        for msg in stream:
            if msg.channel >= 0:
                yield msg.channel, msg.log_time_ns, msg.data

    def close(self) -> None:
        """Close the file."""
        self._bio.close()
