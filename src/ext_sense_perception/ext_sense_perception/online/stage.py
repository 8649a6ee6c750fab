"""The window node's core without rclpy: sensor messages in, contact windows out.

The node, the offline replay, training from bags and device streams all run this code. Messages
are duck-typed (rclpy and rosbags share field names). A window closes when the stream passes its
end, and only packets move the stream (their events, or the time the driver had read up to); an
``end_of_stream`` packet closes every pending window, ``truncated``. No consumer clock enters, so a
replay of the packets a live node got cuts exactly its windows.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.pac_windower import PacWindower
from ext_sense_perception.online.window import ContactWindow, WindowConfig
from ext_sense_perception.online.windowers import EventWindower
from ext_sense_runtime.enums import Sensor
from ext_sense_runtime.records import EventBlock
from ext_sense_runtime.stamps import stamp_to_ns

JOIN_DEPTH = 64
"""BioTac frames of several sensors waiting for their siblings (same sequence) at most."""


class StageCounters(NamedTuple):
    """What a :class:`WindowStage` dropped or joined (monotonic)."""

    batches: int = 0
    events: int = 0
    frames: int = 0
    frames_unjoined: int = 0
    frames_wrong_sensor: int = 0
    bad_messages: int = 0
    packets: int = 0
    lost_packets: int = 0
    bad_packets: int = 0


class WindowStage:
    """Sensor messages in, contact windows out (``sensor_ids``: the BioTac slots, not empty)."""

    def __init__(self, config: WindowConfig, sensor_ids: tuple[int, ...] = (0,)) -> None:
        self.config = config
        self.sensor_ids = tuple(int(s) for s in sensor_ids)
        if config.sensor is Sensor.BIOTAC and not self.sensor_ids:
            raise PerceptionError("The 'sensor_ids' parameter must name at least one sensor.")
        self.windower: EventWindower | PacWindower = (
            EventWindower(config)
            if config.sensor is Sensor.NUSKIN
            else PacWindower(config, n_sensors=max(1, len(self.sensor_ids)))
        )
        self._counts = dict.fromkeys(StageCounters._fields, 0)
        self._join: OrderedDict[int, dict[int, Any]] = OrderedDict()
        self.last_data_ns: int | None = None
        """Stream time of the newest data fed, ns (None before any)."""
        self.decoder: Any = None
        """The packet decoder, made from the first packet's encoding (None before any)."""
        self.last_packet_error = ""
        """Why the last refused packet was refused ('' when none was)."""
        self.last_lost_packets = 0
        """Packets missing just before the last packet fed (its ``seq`` gap)."""

    @property
    def counters(self) -> StageCounters:
        """Counters since construction."""
        return StageCounters(**self._counts)

    def on_events(self, msg: Any) -> list[ContactWindow]:
        """Feed one ``TaxelEventBatch``; a malformed one is counted and dropped."""
        self._counts["batches"] += 1
        events = events_of(msg)
        if events is None:
            self._counts["bad_messages"] += 1
            return []
        return self.on_block(events, stamp_to_ns(msg.header.stamp))

    def on_block(
        self, events: EventBlock, stamp_ns: int | None = None, complete_ns: int | None = None
    ) -> list[ContactWindow]:
        """Feed a block of decoded events; returns the windows that became due.

        With no events, stream time still reaches the batch's ``stamp_ns`` (the stream is in order);
        ``complete_ns`` is a decoded packet's time up to which every event is out.
        """
        self._counts["events"] += events.size
        now = complete_ns if complete_ns is not None else (None if events.size else stamp_ns)
        end = int(events.t_ns.max()) if events.size else now
        if now is not None and end is not None:
            end = max(end, now)
        if end is not None:
            self.last_data_ns = end if self.last_data_ns is None else max(self.last_data_ns, end)
        return self.windower.feed(events, now_ns=now)

    def on_packet(
        self, msg: Any, thin: Callable[[EventBlock], EventBlock] | None = None
    ) -> list[ContactWindow]:
        """Feed one ``SensorPacket`` (rclpy, rosbags or a ``Packet``); windows that became due.

        ``thin`` (NUSkin, offline) reduces the decoded events first. The decoder is made again when
        the encoding or its options change. An unreadable packet is counted in ``bad_packets``
        (reason in :attr:`last_packet_error`); a ``seq`` gap in ``lost_packets``; an
        ``end_of_stream`` packet flushes.
        """
        from ext_sense_drivers.packets import Packet, PacketError, make_decoder

        self._counts["packets"] += 1
        self.last_lost_packets = 0
        try:
            options = msg.options if isinstance(msg, Packet) else msg.encoding_options
            key = (str(msg.encoding), str(options))
            if self.decoder is None or (self.decoder.encoding, self.decoder.options) != key:
                self.decoder = make_decoder(*key)
            decoded = self.decoder.decode(msg)
        except PacketError as err:
            self._counts["bad_packets"] += 1
            self.last_packet_error = str(err)
            return []
        self.last_lost_packets = decoded.lost_packets
        self._counts["lost_packets"] += decoded.lost_packets
        out: list[ContactWindow] = []
        if hasattr(decoded, "frames"):
            for frame in decoded.frames:
                out += self.on_frame(frame)
        else:
            self._counts["batches"] += 1
            events = decoded.events if thin is None else thin(decoded.events)
            out = self.on_block(events, complete_ns=decoded.complete_ns)
        if bool(msg.end_of_stream):  # nothing more of this stream: its windows are as full
            out += self.flush()  # as they will get
        return out

    def on_frame(self, msg: Any) -> list[ContactWindow]:
        """Feed one ``BioTacFrame``; frames of several sensors are joined by sequence number.

        Frames of other sensors are counted and dropped, as is a sequence whose siblings never
        arrive once ``JOIN_DEPTH`` newer ones wait.
        """
        self._counts["frames"] += 1
        sid = int(msg.sensor_id)
        if sid not in self.sensor_ids:
            self._counts["frames_wrong_sensor"] += 1
            return []
        seq = int(msg.sequence)
        group = self._join.setdefault(seq, {})
        group[sid] = msg
        if len(group) < len(self.sensor_ids):
            while len(self._join) > JOIN_DEPTH:
                _, dropped = self._join.popitem(last=False)
                self._counts["frames_unjoined"] += len(dropped)
            return []
        del self._join[seq]
        frames = [group[s] for s in self.sensor_ids]
        pac = np.stack([np.asarray(f.pac, dtype=np.float64) for f in frames])
        valid = np.ones_like(pac, dtype=bool)
        for row, frame in enumerate(frames):
            mask = int(frame.invalid_word_mask)
            if mask:
                shifts = 2 * np.arange(pac.shape[1], dtype=np.uint64)  # PAC words are even
                valid[row] = ((np.uint64(mask) >> shifts) & np.uint64(1)) == 0
        first = frames[0]  # a BioTacFrame, or a packet decoder's DecodedFrame (stamp_ns)
        t0 = first.stamp_ns if hasattr(first, "stamp_ns") else stamp_to_ns(first.header.stamp)
        period = int(frames[0].pac_sample_period_ns)
        try:
            out = self.windower.feed(t0, pac, period, valid=valid)
        except PerceptionError:
            self._counts["bad_messages"] += 1
            return []
        end = t0 + period * pac.shape[1]
        self.last_data_ns = end if self.last_data_ns is None else max(self.last_data_ns, end)
        return out

    def on_motion_start(self, onset_ns: int) -> bool:
        """Mark an onset known from outside (food: the arm starts moving); False if debounced."""
        return self.windower.mark_onset(int(onset_ns))

    def advance(self, now_ns: int) -> list[ContactWindow]:
        """Declare the stream complete up to ``now_ns`` (no more data before it will come)."""
        return self.windower.advance(int(now_ns))

    def flush(self) -> list[ContactWindow]:
        """Close every pending window (the stream stopped); tails are zero-padded."""
        return self.windower.flush()


def events_of(msg: Any) -> EventBlock | None:
    """The events of a ``TaxelEventBatch``, or None when its arrays differ or an offset is negative.

    An empty ``value`` stands for all zeros.
    """
    offset = np.asarray(msg.offset_ns, dtype=np.int64)
    taxel = np.asarray(msg.taxel, dtype=np.uint16)
    polarity = np.asarray(msg.polarity, dtype=np.int8)
    value = np.asarray(msg.value, dtype=np.uint16)
    n = len(offset)
    if not len(value):
        value = np.zeros(n, np.uint16)
    if not (n == len(taxel) == len(polarity) == len(value)) or (n and int(offset.min()) < 0):
        return None
    return EventBlock(offset + np.int64(stamp_to_ns(msg.header.stamp)), taxel, polarity, value)
