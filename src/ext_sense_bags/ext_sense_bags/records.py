"""The records bag reading hands out: topic summaries, stored messages, salvage reports.

A salvage report and its topics say what :mod:`ext_sense_bags.salvage` found in a crashed bag.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple


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
    """RIHS01 hash its topic recorded ('' when none): tells a message of an older definition
    of ``msgtype`` (:mod:`ext_sense_bags.recorded`), so it decodes as it was written."""


class SalvagedTopic(NamedTuple):
    """One topic (an mcap channel or a sqlite3 topic row) as found in the file."""

    topic: str
    msgtype: str
    msgdef: str
    """Message definition text as stored ('' when the file holds none)."""
    msgdef_encoding: str
    """``ros2msg`` or ``ros2idl``."""
    type_hash: str
    """RIHS01 hash as stored ('' when the file holds none)."""
    qos: str
    """``offered_qos_profiles`` as stored (YAML; '' when absent)."""


@dataclass
class SalvageReport:
    """What a salvage found: the storage file, what was wrong, and what was dropped."""

    file: Path
    storage: str
    problem: str = ""
    """What was wrong ('' when the file was complete)."""
    chunks: int = 0
    """Complete mcap chunks read."""
    chunks_dropped: int = 0
    """mcap chunks cut off or unreadable (their messages are lost)."""
    bytes_dropped: int = 0
    """Bytes of the file that could not be used (a record cut off, unreadable data)."""
    orphans: int = 0
    """Messages whose channel record was lost (not returned)."""

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
