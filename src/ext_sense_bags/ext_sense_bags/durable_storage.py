"""The bag writer's storages: rosbags' mcap and sqlite3 writers made durable (no ROS).

:class:`McapWithHashes` and :class:`DurableSqlite3` are what :class:`~ext_sense_bags.BagWriter`
writes through (its ``flush`` after each ``flush_period_s``): each flush leaves every message
written so far readable after a crash, and after a failed write the mcap storage says how many
messages a salvage gets back (:meth:`McapWithHashes.messages_in_file`).
"""

from __future__ import annotations

import os
import zlib
from collections import defaultdict
from io import BytesIO
from pathlib import Path

from rosbags.interfaces import Connection
from rosbags.rosbag2.enums import CompressionMode
from rosbags.rosbag2.storage_mcap import (
    Channel,
    McapWriter,
    PendingChunk,
    write_channel,
    write_record,
    write_string,
    write_uint16,
    write_uint32,
    write_uint64,
)
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer


class McapWithHashes(McapWriter):
    """rosbags' mcap storage with ``topic_type_hash`` in the channel metadata, and ``flush``.

    rosbag2 writes the hash there too; :meth:`flush` closes the pending chunk, writes it out
    and fsyncs. Chunks carry the CRC-32 of their records (rosbags writes 0), so a salvage can
    tell a chunk spoiled by a failed write from a whole one.
    """

    def __init__(self, path: Path, compression: CompressionMode) -> None:
        super().__init__(path, compression)
        self.bio.flush()  # the magic and header are on disk before the first chunk
        self._chunk_ends: list[tuple[int, int]] = []  # (file offset after a chunk, messages)

    def messages_in_file(self) -> int:
        """Messages whose chunk record is whole in the file now (what a salvage finds).

        After a failed write (disk full, file too large) the chunk a flush was writing may be
        whole in the file with only its indexes cut: ``bag recover`` gets its messages, so the
        writer counts them as flushed too (it said fewer than the recovery found, 245 of 832).
        """
        size = os.fstat(self.bio.fileno()).st_size
        return sum(n for end, n in self._chunk_ends if end <= size)

    def close_chunk(self) -> None:
        """Close the pending chunk as rosbags does, with its records' CRC-32 in the header."""
        records = self.chunk.bio.getvalue()
        compressed = self.compressor(records)
        rec = BytesIO()
        write_uint64(rec, self.chunk.message_start_time)
        write_uint64(rec, self.chunk.message_end_time)
        write_uint64(rec, len(records))
        write_uint32(rec, zlib.crc32(records))
        write_string(rec, self.compression)
        write_uint64(rec, len(compressed))
        rec.write(compressed)
        chunk_start = self.bio.tell()
        n_messages = sum(len(msgs) for msgs in self.chunk.msgs.values())
        self._chunk_ends.append((chunk_start + 9 + len(rec.getvalue()), n_messages))
        write_record(self.bio, 0x06, rec)
        chunk_end = self.bio.tell()

        offsets: list[tuple[int, int]] = []
        for cid, msgs in self.chunk.msgs.items():
            offsets.append((cid, self.bio.tell()))
            rec = BytesIO()
            write_uint16(rec, cid)
            write_uint32(rec, len(msgs) * 16)
            for ts, offset in msgs:
                write_uint64(rec, ts)
                write_uint64(rec, offset)
            write_record(self.bio, 0x07, rec)

        rec = BytesIO()
        write_uint64(rec, self.chunk.message_start_time)
        write_uint64(rec, self.chunk.message_end_time)
        write_uint64(rec, chunk_start)
        write_uint64(rec, chunk_end - chunk_start)
        write_uint32(rec, len(offsets) * 10)
        for cid, offset in offsets:
            write_uint16(rec, cid)
            write_uint64(rec, offset)
        write_uint64(rec, self.bio.tell() - chunk_end)
        write_string(rec, self.compression)
        write_uint64(rec, len(compressed))
        write_uint64(rec, len(records))
        self.chunks.append(rec)
        self.chunk = PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))

    def flush(self) -> None:
        """Close the pending chunk (if any) and push the file to the disk."""
        if self.chunk.bio.tell():
            self.close_chunk()
        self.bio.flush()
        os.fsync(self.bio.fileno())

    def add_connection(self, connection: Connection, offered_qos_profiles: str) -> None:
        """Register a channel: its offered QoS and its type hash in the channel's metadata."""
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


class DurableSqlite3(Sqlite3Writer):
    """rosbags' sqlite3 storage in write-ahead-log mode with :meth:`flush` (commit).

    rosbags commits only on close, so a killed writer lost every message; here each flush
    commits. On close the log is checkpointed and the journal mode set back to ``DELETE``, so
    the finished bag is one self-contained ``.db3`` file, as rosbags writes it.
    """

    def __init__(self, path: Path, compression: CompressionMode) -> None:
        super().__init__(path, compression)
        self.conn.execute("PRAGMA journal_mode=WAL")
        self.conn.execute("PRAGMA synchronous=NORMAL")
        self.conn.commit()

    def flush(self) -> None:
        """Commit what was written since the last flush."""
        self.conn.commit()

    def close(self, version: int, metadata: str) -> None:
        """Store the metadata, commit, checkpoint the log into the database and close."""
        self.cursor.execute(
            "INSERT INTO metadata(metadata_version, metadata) VALUES(?, ?)", (version, metadata)
        )
        self.conn.commit()
        self.conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        self.conn.execute("PRAGMA journal_mode=DELETE")
        self.conn.execute("PRAGMA optimize")
        self.conn.close()
