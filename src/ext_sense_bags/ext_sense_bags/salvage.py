"""Reading what a killed recorder left behind: mcap without footer, sqlite3 without metadata.

That is an mcap file without summary and footer, or a sqlite3 bag with no ``metadata.yaml``
and its write-ahead log still beside it.

The writer (:mod:`ext_sense_bags.writer`) closes an mcap chunk, and commits a sqlite3
transaction, at least every ``flush_period_s`` (1 s). What reached the file before a crash is
therefore a run of complete records followed, at worst, by one record cut off mid-write:

- mcap: :class:`ext_sense_bags.mcap_salvage.McapSalvage` walks the file record by record from
  its magic and keeps every complete chunk (what follows the first record cut off is dropped).
- sqlite3: SQLite's own crash recovery (replaying the committed part of the write-ahead log,
  discarding the uncommitted tail) runs when the database is opened read-write, in place.

:func:`open_salvaged` returns a :class:`McapSalvage` or :class:`SqliteSalvage`; both give the
topics, counts and messages (file order or log-time order) and a :class:`SalvageReport` saying
what was wrong and what was dropped. :class:`ext_sense_bags.BagReader` falls back to them when a
bag has no footer or metadata, and :func:`ext_sense_bags.recover.recover_bag` rewrites a valid bag
from them.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterable, Iterator
from pathlib import Path

from ext_sense_bags.errors import BagError
from ext_sense_bags.mcap_salvage import McapSalvage
from ext_sense_bags.records import SalvagedTopic, SalvageReport

__all__ = [
    "McapSalvage",
    "Salvage",
    "SalvageReport",
    "SalvagedTopic",
    "SqliteSalvage",
    "has_open_log",
    "open_salvaged",
    "storage_file",
]


class SqliteSalvage:
    """A sqlite3 bag database opened read-write in place, so SQLite recovers it.

    Opening replays the committed part of a write-ahead log left by a killed writer and
    discards its uncommitted tail (or rolls back a hot rollback journal): every committed
    transaction is kept.

    Args:
        file: The ``.db3`` file.
        problem: What is wrong with the bag (for the report).

    Raises:
        BagError: The database cannot be opened or lacks the rosbag2 tables.
    """

    def __init__(self, file: Path, problem: str = "") -> None:
        self.file = Path(file)
        self.report = SalvageReport(self.file, "sqlite3", problem)
        self.complete = False
        try:
            self._conn = sqlite3.connect(f"file:{self.file}?mode=rw", uri=True)
            self._load()
        except sqlite3.Error as err:
            raise BagError(f"Cannot read sqlite3 bag file {self.file}: {err}.") from err

    def _load(self) -> None:
        cur = self._conn.cursor()
        tables = {r[0] for r in cur.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        if not {"topics", "messages"} <= tables:
            raise BagError(f"{self.file} is not a rosbag2 database (no topics/messages tables).")
        cols = {r[1] for r in cur.execute("PRAGMA table_info(topics)")}
        qos = "offered_qos_profiles" if "offered_qos_profiles" in cols else "''"
        digest = "type_description_hash" if "type_description_hash" in cols else "''"
        defs: dict[str, tuple[str, str]] = {}
        if "message_definitions" in tables:
            for name, enc, text in cur.execute(
                "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions"
            ):
                defs[name] = (text, enc)
        self.topics: dict[int, SalvagedTopic] = {}
        for cid, topic, msgtype, q, h in cur.execute(
            f"SELECT id, name, type, {qos}, {digest} FROM topics ORDER BY id"
        ):
            text, enc = defs.get(msgtype, ("", "ros2msg"))
            self.topics[int(cid)] = SalvagedTopic(topic, msgtype, text, enc, h or "", q or "")
        self.counts: dict[int, int] = {}
        first, last = 2**63 - 1, 0
        for cid, n, lo, hi in cur.execute(
            "SELECT topic_id, count(*), min(timestamp), max(timestamp) FROM messages "
            "GROUP BY topic_id"
        ):
            if int(cid) in self.topics:
                self.counts[int(cid)] = int(n)
                first, last = min(first, int(lo)), max(last, int(hi))
            else:
                self.report.orphans += int(n)
        self.start_ns, self.end_ns = (first, last) if self.counts else (0, 0)

    def records(
        self, channels: Iterable[int] | None = None, *, ordered: bool = True
    ) -> Iterator[tuple[int, int, bytes]]:
        """Yield ``(topic id, log time ns, CDR bytes)``, in log-time (else insertion) order."""
        ids = sorted(self.topics if channels is None else set(channels) & self.topics.keys())
        if not ids:
            return
        order = "timestamp, id" if ordered else "id"
        marks = ",".join("?" * len(ids))
        try:
            for cid, t, data in self._conn.execute(
                f"SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN ({marks}) "
                f"ORDER BY {order}",
                ids,
            ):
                yield int(cid), int(t), bytes(data)
        except sqlite3.Error as err:
            raise BagError(f"Corrupt sqlite3 bag file {self.file}: {err}.") from err

    def close(self) -> None:
        """Close the database (SQLite checkpoints a recovered write-ahead log into it)."""
        self._conn.close()


Salvage = McapSalvage | SqliteSalvage


def storage_file(path: Path) -> Path:
    """The one ``.mcap``/``.db3`` file of a bag directory (or ``path`` itself if a file).

    Raises:
        BagError: None, or several.
    """
    path = Path(path)
    if not path.is_dir():
        return path
    files = sorted(p for p in path.iterdir() if p.suffix in (".mcap", ".db3") and p.is_file())
    if not files:
        raise BagError(f"Bag {path} holds no .mcap or .db3 file.")
    if len(files) > 1:
        names = [p.name for p in files]
        raise BagError(f"Bag {path} has no usable metadata.yaml and several files: {names}.")
    return files[0]


def has_open_log(db3: Path) -> bool:
    """Whether a sqlite3 file has a write-ahead log or hot journal beside it (not closed)."""
    return any(db3.with_name(db3.name + s).exists() for s in ("-wal", "-journal"))


def open_salvaged(path: Path, cause: str = "") -> Salvage:
    """Open a bag that lacks its footer or metadata, for reading what was written.

    Args:
        path: Bag directory, or its ``.mcap``/``.db3`` file.
        cause: Why a normal open failed (used in the error when nothing can be read).

    Returns:
        A :class:`McapSalvage` or :class:`SqliteSalvage` (close it after use).

    Raises:
        BagError: Nothing can be read: the error names the file and what is wrong.
    """
    path = Path(path)
    file = storage_file(path)
    no_meta = path.is_dir() and not (path / "metadata.yaml").exists()
    if file.suffix == ".db3":
        problem = (
            "an open write-ahead log: the recorder stopped without closing the bag"
            if has_open_log(file)
            else "no metadata.yaml"
            if no_meta
            else cause
        )
        return SqliteSalvage(file, problem)
    if file.suffix != ".mcap":
        raise BagError(f"Cannot read bag {path}: {cause or 'unknown storage format'}.")
    salvage = McapSalvage(file)
    if salvage.complete and not no_meta:  # the file is whole: the failure was something else
        salvage.close()
        raise BagError(f"Cannot read bag {path}: {cause}")
    if salvage.complete:
        salvage.report.problem = "no metadata.yaml (the mcap file itself is complete)"
    if not salvage.topics and salvage.report.bytes_dropped and not salvage.empty:
        report = salvage.report
        salvage.close()
        raise BagError(
            f"Cannot read bag {path}: {file.name} has {report.problem}; no complete chunk "
            "before it, so there is nothing to read."
        )
    return salvage
