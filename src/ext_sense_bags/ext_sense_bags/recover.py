"""Rewriting a bag a killed recorder left into a complete one (``ext-sense bag recover``).

Every complete message (:mod:`ext_sense_bags.salvage`) is written in recorded order into a new
bag of the same storage, with the definitions, type hashes and QoS the original recorded (a hash
it did not record is computed from its stored definition, else the current typestore's). The
original is never deleted: in place, it is renamed ``<bag>.damaged`` (``.damaged.2``, ...).
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path
from typing import NamedTuple

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from ext_sense_bags.errors import BagError, why
from ext_sense_bags.salvage import Report, SalvagedTopic, incomplete, salvage
from ext_sense_bags.typestore import make_typestore
from ext_sense_bags.writer import BagWriter


class Recovery(NamedTuple):
    """What :func:`recover_bag` did."""

    out: Path
    """The complete bag written."""
    counts: dict[str, int]
    """Messages recovered per topic."""
    report: Report
    """The storage file read, what was wrong with it, chunks and bytes dropped."""
    kept: Path | None
    """Where the damaged original went (in-place recovery), else None."""
    skipped_topics: tuple[str, ...]
    """Topics that could not be rewritten: the file holds neither their definition nor hash."""

    @property
    def messages(self) -> int:
        """Messages recovered."""
        return sum(self.counts.values())


def bag_problem(path: str | Path) -> str:
    """'' when the bag at ``path`` was closed by its writer, else what is wrong (one line).

    Raises:
        BagError: It does not exist or holds no storage file.
    """
    return incomplete(Path(path))


def recover_bag(path: str | Path, out: str | Path | None = None) -> Recovery:
    """Rewrite every complete message of a bag into a complete bag with its metadata.

    Args:
        path: Bag directory, or its ``.mcap``/``.db3`` file.
        out: New bag directory (must not exist). None: in place, the damaged original renamed
            ``<bag>.damaged`` beside it (for a bare file: a new directory ``<stem>_recovered``).

    Returns:
        A :class:`Recovery`.

    Raises:
        BagError: Nothing can be read (the message names the file and what is wrong), or the
            new bag cannot be written.
    """
    path = Path(path)
    if not path.exists():
        raise BagError(f"Bag {path} does not exist.")
    if out is not None:
        return _rewrite(path, Path(out))
    if not path.is_dir():
        return _rewrite(path, path.with_name(f"{path.stem}_recovered"))
    staging = Path(tempfile.mkdtemp(prefix=f".{path.name}.recovering-", dir=path.parent))
    try:
        result = _rewrite(path, staging / path.name)
        kept = _free_name(path.with_name(f"{path.name}.damaged"))
        path.rename(kept)
        (staging / path.name).rename(path)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return result._replace(out=path, kept=kept)


def _free_name(path: Path) -> Path:
    n, candidate = 1, path
    while candidate.exists():
        n += 1
        candidate = path.with_name(f"{path.name}.{n}")
    return candidate


def _rewrite(path: Path, out: Path) -> Recovery:
    report, items = salvage(path)
    current = make_typestore()
    skipped: list[str] = []
    topic_of: dict[int, str] = {}
    bag = BagWriter(out, storage=report.storage)
    created = False
    try:
        with bag:
            created = True
            bag.set_custom_data("recovered_by", "ext-sense bag recover")
            for item in items:
                if not isinstance(item, SalvagedTopic):
                    if topic_of.get(item[0]):
                        bag.write_raw(topic_of[item[0]], item[1], item[2])
                    continue
                topic_of[item.id] = ""  # seen; named once it can be rewritten
                known = item.msgtype in current.fielddefs
                digest = item.type_hash or _stored_hash(item)
                digest = digest or (current.hash_rihs01(item.msgtype) if known else "")
                if not (item.msgtype and digest and (item.msgdef or known)):
                    skipped.append(item.topic)
                    continue
                definition = (item.msgdef, digest) if item.msgdef else None
                bag.add_topic(item.topic, item.msgtype, definition=definition, qos=item.qos)
                topic_of[item.id] = item.topic
            if report.problem:
                bag.set_custom_data("recovered_problem", report.problem)
            if not topic_of and report.bytes_dropped and not report.empty:
                raise BagError(
                    f"Cannot read bag {path}: {report.file.name} has {report.problem}; no "
                    "complete chunk before it, so there is nothing to read."
                )
    except (BagError, OSError, ValueError) as err:
        if created:  # the partial output is no use
            shutil.rmtree(out, ignore_errors=True)
        if isinstance(err, BagError):
            raise
        raise BagError(f"Cannot recover {path}: {why(err)}") from err
    return Recovery(out, dict(bag.counts), report, None, tuple(skipped))


def _stored_hash(topic: SalvagedTopic) -> str:
    """RIHS01 hash of the ``ros2msg`` definition a file stored without one ('' if none)."""
    if not topic.msgdef or topic.encoding != "ros2msg":
        return ""
    store = get_typestore(Stores.EMPTY)
    try:
        store.register(get_types_from_msg(topic.msgdef, topic.msgtype))
        return str(store.hash_rihs01(topic.msgtype))
    except Exception:  # rosbags' parser and type system raise several types
        return ""
