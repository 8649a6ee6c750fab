"""``ext-sense bag migrate``: a bag of decoded arrays from before packets, as a packet bag.

The graphs, the view and the offline replay read packets only, so a bag of ``TaxelEventBatch``
or ``BioTacFrame`` is rewritten once: other topics are copied (in the current definitions), the
decoded arrays encoded again with the drivers' encoders. The sensor's own bytes cannot be
rebuilt (dropped words and read times are gone): NUSkin events become one read per distinct
event time and one packet per batch, with the driver's "nothing read" packets while the
recording is silent and the stream's end at its end; a BioTac frame becomes one read arriving
its clock's lead after its stamp. A replay's windows then close as the current graphs close them.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from ext_sense_bags.messages import sensor_packet

from ext_sense_bags import BagError, BagReader, BagWriter
from ext_sense_drivers.biotac.clock import FRAME_PERIOD_NS, transmission_ns
from ext_sense_drivers.biotac.encoder import encode_standard_frame
from ext_sense_drivers.biotac.frame_layout import STANDARD_FRAME_SIZE
from ext_sense_drivers.nuskin.wire import encode_words
from ext_sense_drivers.packets import (
    BIOTAC_BRIDGE_V1,
    NUSKIN_WORDS_V1,
    QUIET_PACKETS_PERIOD_S,
    Packet,
    PacketPacker,
    format_options,
)
from ext_sense_drivers.transports.base import Chunk
from ext_sense_runtime.stamps import stamp_to_ns

EVENTS = "/extsense/nuskin/events"
FRAMES = "/extsense/biotac/frames"
PACKETS = {EVENTS: "/extsense/nuskin/packets", FRAMES: "/extsense/biotac/packets"}
"""Decoded topic -> the packet topic it becomes."""

NUSKIN_BAUD = 4_000_000
BIOTAC_BAUD = 1_000_000
BIOTAC_LEAD_NS = FRAME_PERIOD_NS + transmission_ns(STANDARD_FRAME_SIZE, BIOTAC_BAUD)
"""The BioTac driver's default clock lead (a serial bridge at its default baud)."""
QUIET_NS = round(QUIET_PACKETS_PERIOD_S * 1e9)
CONNECTION = 1


class Migration(NamedTuple):
    """What :func:`migrate_bag` wrote: copies and packets by topic, events and frames encoded."""

    out: Path
    copied: dict[str, int]
    packets: dict[str, int]
    events: int
    frames: int


def migrate_bag(src: Path, out: Path) -> Migration:
    """Rewrite the bag ``src`` with its decoded arrays as packets, into the new bag ``out``.

    Raises:
        BagError: ``src`` cannot be read or holds no decoded arrays, or ``out`` exists.
    """
    src, out = Path(src), Path(out)
    if out.exists():
        raise BagError(f"The output {out} exists: give a new directory.")
    with BagReader(src) as reader:
        topics = reader.topics
        decoded = [t for t in (EVENTS, FRAMES) if t in topics and topics[t].count]
        if not decoded:
            packets = [t for t in PACKETS.values() if t in topics]
            why = f"it holds packets already ({', '.join(packets)})" if packets else "none"
            raise BagError(f"{src} holds no decoded arrays ({EVENTS}, {FRAMES}) to migrate: {why}.")
        nuskin_options = _nuskin_options(reader) if EVENTS in decoded else ""
        start, end = reader.start_time_ns, reader.start_time_ns + reader.duration_ns
        copied: dict[str, int] = {}
        counts = {PACKETS[t]: 0 for t in decoded}
        events = frames = 0
        with BagWriter(out) as writer:
            for key, value in reader.custom_data.items():
                writer.set_custom_data(key, value)
            nuskin = _NuskinStream(nuskin_options, start)
            biotac = PacketPacker(
                BIOTAC_BRIDGE_V1,
                format_options({"clock_window_frames": 200, "lead_ns": BIOTAC_LEAD_NS}),
            )
            for rec in reader.records():
                if rec.topic == EVENTS:
                    msg = reader.decode(rec)
                    events += len(msg.taxel)
                    written = nuskin.batch(msg)
                elif rec.topic == FRAMES:
                    frames += 1
                    written = _frame_packets(biotac, reader.decode(rec))
                else:
                    writer.write_raw(
                        rec.topic, rec.log_time_ns, reader.current_cdr(rec), rec.msgtype
                    )
                    copied[rec.topic] = copied.get(rec.topic, 0) + 1
                    continue
                topic = PACKETS[rec.topic]
                for packet in written:  # logged when the driver would have published it
                    writer.write(topic, packet.end_ns, sensor_packet(packet))
                    counts[topic] += 1
            if EVENTS in decoded:
                for packet in nuskin.finish(end):
                    writer.write(PACKETS[EVENTS], packet.end_ns, sensor_packet(packet))
                    counts[PACKETS[EVENTS]] += 1
    return Migration(out, copied, counts, events, frames)


def _nuskin_options(reader: BagReader) -> str:
    """The words' encoding options: the flag bit carries polarity when the events have any."""
    signed = any(np.any(np.asarray(m.polarity) != 0) for _, m in reader.messages([EVENTS]))
    flag = "is_positive" if signed else "ignore"
    return format_options({"baud": NUSKIN_BAUD, "flag_polarity": flag})


class _NuskinStream:
    """The NUSkin driver's packets of the recorded batches, "nothing read" between them."""

    def __init__(self, options: str, start_ns: int) -> None:
        self.packer = PacketPacker(NUSKIN_WORDS_V1, options)
        self.signed = "is_positive" in options
        self.start_ns = start_ns
        self.last_ns: int | None = None

    def batch(self, msg: Any) -> list[Packet]:
        """The packets of one ``TaxelEventBatch``: the silence before it, then its reads."""
        taxel = np.asarray(msg.taxel, np.int64)
        if not taxel.size:
            return []
        t = np.asarray(msg.offset_ns, np.int64) + np.int64(stamp_to_ns(msg.header.stamp))
        order = np.argsort(t, kind="stable")
        t, taxel = t[order], taxel[order]
        value = np.asarray(msg.value, np.int64)[order] if len(msg.value) else np.zeros_like(taxel)
        flag = _flags(msg, order, self.signed)
        out = [] if self.last_ns is None else list(self._quiet(self.last_ns, int(t[0])))
        if self.last_ns is None:
            opened = self.packer.opened(CONNECTION, min(self.start_ns, int(t[0])))
            out += [] if opened is None else [opened]
        cuts = np.flatnonzero(np.diff(t)) + 1
        reads = [
            (CONNECTION, Chunk(encode_words(k, v, f), int(ts[-1])))
            for k, v, f, ts in zip(
                np.split(taxel, cuts),
                np.split(value, cuts),
                np.split(flag, cuts),
                np.split(t, cuts),
                strict=True,
            )
        ]
        out += self.packer.pack(reads, link_down=False)
        self.last_ns = max(int(t[-1]), self.last_ns or 0)
        return out

    def _quiet(self, from_ns: int, to_ns: int) -> Iterator[Packet]:
        """The driver's "nothing read" packets between two reads."""
        for t in range(from_ns + QUIET_NS, to_ns, QUIET_NS):
            packet = self.packer.nothing_read(t)
            if packet is not None:
                yield packet

    def finish(self, end_ns: int) -> list[Packet]:
        """The silence up to the recording's end, then the end of the stream."""
        if self.last_ns is None:
            return []
        out = list(self._quiet(self.last_ns, max(end_ns, self.last_ns) + QUIET_NS))
        return out + self.packer.pack([], link_down=True)


def _flags(msg: Any, order: np.ndarray, signed: bool) -> np.ndarray:
    """The words' flag bits: as received when the batch kept them, else from the polarity."""
    if len(msg.flag):
        return np.asarray(msg.flag, np.int64)[order]
    if signed:
        return (np.asarray(msg.polarity, np.int64)[order] > 0).astype(np.int64)
    return np.zeros(order.size, np.int64)


def _frame_packets(packer: PacketPacker, msg: Any) -> list[Packet]:
    """One ``BioTacFrame`` as the bridge frame a driver would have read, one packet."""
    data = encode_standard_frame(
        int(msg.sequence),
        int(msg.sensor_id),
        np.asarray(msg.pac),
        np.asarray(msg.electrodes),
        int(msg.pdc),
        int(msg.tac),
        int(msg.tdc),
    )
    arrival = stamp_to_ns(msg.header.stamp) + BIOTAC_LEAD_NS
    return packer.pack([(CONNECTION, Chunk(data, arrival))], link_down=False)
