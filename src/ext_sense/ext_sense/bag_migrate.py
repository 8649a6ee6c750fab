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

from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from ext_sense_bags.messages import sensor_packet

from ext_sense_bags import BagError, BagReader, BagWriter
from ext_sense_runtime.stamps import stamp_to_ns
from ext_sense_sim.output.bag import NuskinPackets, biotac_packer, frame_packets

EVENTS = "/extsense/nuskin/events"
FRAMES = "/extsense/biotac/frames"
PACKETS = {EVENTS: "/extsense/nuskin/packets", FRAMES: "/extsense/biotac/packets"}
"""Decoded topic -> the packet topic it becomes."""


class Migration(NamedTuple):
    """What :func:`migrate_bag` wrote: copies and packets by topic, events and frames encoded."""

    out: Path
    copied: dict[str, int]
    packets: dict[str, int]
    events: int
    frames: int


def migrate_bag(src: Path, out: Path) -> Migration:
    """Rewrite the bag ``src`` with its decoded arrays as packets into the new bag ``out``.

    Raises BagError when ``src`` cannot be read or holds no decoded arrays, or ``out`` exists.
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
        signed = EVENTS in decoded and any(
            np.any(np.asarray(m.polarity) != 0) for _, m in reader.messages([EVENTS])
        )  # the words' flag bit carries polarity when the events have any
        start, end = reader.start_time_ns, reader.start_time_ns + reader.duration_ns
        copied: dict[str, int] = {}
        counts = {PACKETS[t]: 0 for t in decoded}
        events = frames = 0
        with BagWriter(out) as writer:
            for key, value in reader.custom_data.items():
                writer.set_custom_data(key, value)
            nuskin, biotac = NuskinPackets(signed, start), biotac_packer()
            for rec in reader.records():
                if rec.topic == EVENTS:
                    msg = reader.decode(rec)
                    events += len(msg.taxel)
                    written = nuskin.batch(*_batch_arrays(msg, signed))
                elif rec.topic == FRAMES:
                    frames += 1
                    msg = reader.decode(rec)
                    written = frame_packets(
                        biotac,
                        stamp_to_ns(msg.header.stamp),
                        int(msg.sequence),
                        int(msg.sensor_id),
                        *(np.asarray(x) for x in (msg.pac, msg.electrodes)),
                        *(int(x) for x in (msg.pdc, msg.tac, msg.tdc)),
                    )
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


def _batch_arrays(msg: Any, signed: bool) -> tuple[np.ndarray, ...]:
    """A ``TaxelEventBatch``'s event times, taxels, values and word flag bits, ``(n,)`` each.

    The flag bits as received when the batch kept them, else from the polarity.
    """
    taxel = np.asarray(msg.taxel, np.int64)
    t = np.asarray(msg.offset_ns, np.int64) + np.int64(stamp_to_ns(msg.header.stamp))
    value = np.asarray(msg.value, np.int64) if len(msg.value) else np.zeros_like(taxel)
    if len(msg.flag):
        flag = np.asarray(msg.flag, np.int64)
    else:
        flag = (np.asarray(msg.polarity, np.int64) > 0).astype(np.int64) * signed
    return t, taxel, value, flag
