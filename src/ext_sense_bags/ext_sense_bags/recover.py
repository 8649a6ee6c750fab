"""Rewriting a bag a killed recorder left into a complete one (``ext-sense bag recover``).

::

    from ext_sense_bags.recover import recover_bag

    result = recover_bag("out/run1")   # in place; the damaged original moves to out/run1.damaged
    result.counts                      # {topic: messages recovered}
    result.report.describe()           # what was wrong, chunks and bytes dropped

Every complete message (:mod:`ext_sense_bags.salvage`) is written, in the order it was
recorded, into a new bag of the same storage through :class:`ext_sense_bags.BagWriter`, which
writes the index and a rosbag2 ``metadata.yaml`` with the message counts, the offered QoS and
the type hashes as the original recorded them. Where it recorded no hash, the hash is computed
from the definition it stored (a bag older than a ``.msg`` change keeps its own definition and
hash, so it still decodes as written), and only without either from the current typestore.
The original is never deleted: in place, it is renamed ``<bag>.damaged`` (``.damaged.2``, ...).
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path
from typing import NamedTuple

from rosbags.rosbag2.metadata import parse_qos

from ext_sense_bags.errors import BagError
from ext_sense_bags.reader import BagReader
from ext_sense_bags.recorded import decoding_store
from ext_sense_bags.salvage import SalvageReport, open_salvaged
from ext_sense_bags.typestore import make_typestore
from ext_sense_bags.writer import BagWriter


class Recovery(NamedTuple):
    """What :func:`recover_bag` did."""

    out: Path
    """The complete bag written."""
    counts: dict[str, int]
    """Messages recovered per topic."""
    report: SalvageReport
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
    """'' when the bag at ``path`` is complete, else what is wrong with it (one line).

    Raises:
        BagError: It cannot be read at all.
    """
    with BagReader(path) as bag:
        report = bag.salvage_report
        return "" if report is None else report.problem or "incomplete"


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
    salvage = open_salvaged(path)
    typestore = make_typestore()
    try:
        with BagWriter(out, storage=salvage.report.storage) as bag:
            bag.set_custom_data("recovered_by", "ext-sense bag recover")
            if salvage.report.problem:
                bag.set_custom_data("recovered_problem", salvage.report.problem)
            skipped: list[str] = []
            topic_of: dict[int, str] = {}
            for cid, info in salvage.topics.items():
                known = info.msgtype in typestore.fielddefs
                digest = info.type_hash or _stored_hash(
                    info.msgtype, info.msgdef, info.msgdef_encoding
                )
                digest = digest or (typestore.hash_rihs01(info.msgtype) if known else "")
                if not (info.msgtype and digest and (info.msgdef or known)):
                    skipped.append(info.topic)
                    continue
                try:
                    qos = parse_qos(info.qos) if info.qos else None
                except Exception:  # a QoS string rosbags cannot parse: the standard table's
                    qos = None
                definition = (info.msgdef, digest) if info.msgdef else None
                bag.add_topic(info.topic, info.msgtype, definition=definition, qos=qos)
                topic_of[cid] = info.topic
            for cid, log_time, data in salvage.records(topic_of, ordered=False):
                bag.write_raw(topic_of[cid], log_time, data)
            counts = dict(bag.counts)
    except (OSError, ValueError) as err:
        raise BagError(f"Cannot recover {path}: {err}") from err
    finally:
        salvage.close()
    return Recovery(out, counts, salvage.report, None, tuple(skipped))


def _stored_hash(msgtype: str, msgdef: str, encoding: str) -> str:
    """RIHS01 hash of the definition a bag stored without its hash ('' when it stored none).

    The current typestore's hash would not do: it names the current definition, which an old
    bag's bytes do not follow.
    """
    if not msgdef:
        return ""
    source = decoding_store(msgtype, "", msgdef, encoding)
    if source.problem or msgtype not in source.store.fielddefs:
        return ""
    return str(source.store.hash_rihs01(msgtype))
