"""Packet decoders: ``SensorPacket`` in, events or BioTac frames out (no rclpy).

One decoder per stream, fed every packet in order; it keeps the byte decoders' state across
packets as the driver would. Loss is counted: a ``seq`` gap is ``lost_packets`` (the byte
stream restarts), a malformed packet raises :class:`PacketError` (``bad_packets``), a decoder
failure costs its read (``decode_failures``, ``last_error``).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.packets.errors import PacketError
from ext_sense_drivers.packets.packet import (
    ACES_LINE_V1,
    BIOTAC_BRIDGE_V1,
    NUSKIN_WORDS_V1,
    Packet,
    packet_of,
    parse_options,
)
from ext_sense_runtime.records import EventBlock

NUSKIN_DEFAULT_BAUD = 4_000_000
"""The NUSkin driver's default baud (caps the arrival clock's spread)."""


class PacketCounters(NamedTuple):
    """What a decoder saw since it was made (monotonic)."""

    packets: int = 0
    lost_packets: int = 0
    bad_packets: int = 0
    decode_failures: int = 0
    driver_restarts: int = 0


class DecodedEvents(NamedTuple):
    """The events of one NUSkin packet, stamped in ROS time, and the packets lost before it.

    ``flag`` (the word's flag bit) and ``complete_ns`` (stream time up to which every event is
    decoded: the last read's return) are ``None`` for the ACES line, whose events come out late.
    """

    events: EventBlock
    flag: npt.NDArray[np.uint8] | None
    complete_ns: int | None
    lost_packets: int


class DecodedFrame(NamedTuple):
    """One BioTac frame, the fields of ``ext_sense_msgs/BioTacFrame`` in plain Python."""

    stamp_ns: int
    sensor_id: int
    sequence: int
    pac_sample_period_ns: int
    pac: npt.NDArray[np.uint16]
    electrodes: npt.NDArray[np.uint16]
    pdc: int
    tac: int
    tdc: int
    invalid_word_mask: int
    dropped_frames: int
    parity_errors: int
    error_replies: int
    arrival_ns: int


class DecodedFrames(NamedTuple):
    """The frames of one BioTac packet, and the packets missing just before it."""

    frames: list[DecodedFrame]
    lost_packets: int


class _SeqDecoder:
    """The shared part: checking packets, following ``seq`` and connections, counting."""

    def __init__(self, encoding: str, options: str) -> None:
        self.encoding, self.options = encoding, options
        self._counts = dict.fromkeys(PacketCounters._fields, 0)
        self._last_seq: int | None = None
        self.last_error = ""
        """Why the last packet was refused or a read failed to decode ('' when none)."""

    @property
    def counters(self) -> PacketCounters:
        """Counters since construction."""
        return PacketCounters(**self._counts)

    def _accept(self, packet: Any) -> tuple[Packet, int, bool]:
        """The checked packet, the packets lost before it, and whether its stream broke."""
        try:
            packet = packet.check() if isinstance(packet, Packet) else packet_of(packet)
            if (packet.encoding, packet.options) != (self.encoding, self.options):
                raise PacketError(
                    f"packet seq {packet.seq} is {packet.encoding!r} ({packet.options!r}); this "
                    f"decoder reads {self.encoding!r} ({self.options!r})"
                )
        except PacketError as err:
            self._counts["bad_packets"] += 1
            self.last_error = str(err)
            raise
        self._counts["packets"] += 1
        lost, broke = 0, False
        last = self._last_seq
        if last is not None and packet.seq > last + 1:
            lost = packet.seq - last - 1
            self._counts["lost_packets"] += lost
            broke = True
        elif last is not None and packet.seq <= last:
            self._counts["driver_restarts"] += 1
            broke = True
        self._last_seq = packet.seq
        return packet, lost, broke

    def _failed(self, packet: Packet, err: Exception) -> None:
        self._counts["decode_failures"] += 1
        self.last_error = f"decoding packet seq {packet.seq} failed, a read dropped: {err!r}"

    def _packet_values(self) -> dict[str, object]:
        return {"encoding": self.encoding, **self.counters._asdict()}


class NuskinPacketDecoder(_SeqDecoder):
    """``nuskin-words-v1`` and ``aces-line-v1`` packets -> stamped events.

    ``options``: ``baud`` and ``flag_polarity`` (words), ``threshold`` (ACES line); PacketError
    for another encoding or option.
    """

    def __init__(self, encoding: str, options: str = "") -> None:
        from ext_sense_drivers.nuskin.clock import ArrivalClock
        from ext_sense_drivers.nuskin.errors import NuskinError
        from ext_sense_drivers.nuskin.streams import AcesLineStream, WordStream
        from ext_sense_drivers.nuskin.wire import FlagPolarity

        super().__init__(encoding, options)
        try:
            if encoding == NUSKIN_WORDS_V1:
                opts = parse_options(options, ("baud", "flag_polarity"))
                polarity = opts.get("flag_polarity", "ignore").upper()
                if polarity not in FlagPolarity.__members__:
                    raise PacketError(f"flag_polarity {polarity.lower()!r} is not known.")
                baud = int(opts.get("baud", NUSKIN_DEFAULT_BAUD))
                self.stream: Any = WordStream(FlagPolarity[polarity], ArrivalClock.for_baud(baud))
            elif encoding == ACES_LINE_V1:
                opts = parse_options(options, ("threshold",))
                self.stream = AcesLineStream(threshold=float(opts.get("threshold", 0.5)))
            else:
                raise PacketError(f"NUSkin packets are {NUSKIN_WORDS_V1} or {ACES_LINE_V1}.")
        except (ValueError, NuskinError, ImportError) as err:
            raise PacketError(f"encoding {encoding!r} options {options!r}: {err}") from err
        self._connection = 0
        self._finished = True

    def decode(self, packet: Any) -> DecodedEvents:
        """Decode one packet; the stream restarts at a new connection, a gap or its end.

        PacketError (counted, dropped) for a malformed packet or another encoding.
        """
        from ext_sense_drivers.nuskin.streams import FlaggedEvents

        packet, lost, broke = self._accept(packet)
        parts: list[FlaggedEvents] = []
        if not self._finished and (broke or packet.connection != self._connection):
            parts.append(FlaggedEvents(self.stream.restart(), None))
            self._finished = True
        if self._finished and packet.data:
            self._connection, self._finished = packet.connection, False
            if self.encoding == ACES_LINE_V1:
                self.stream.samples_before = packet.time_base
        for chunk in packet.reads():
            try:
                parts.append(self.stream.feed_flagged(chunk))
            except Exception as err:  # a decoder bug costs a read, not the consumer
                self._failed(packet, err)
                parts.append(FlaggedEvents(self.stream.restart(), None))
        if packet.end_of_stream and not self._finished:
            parts.append(FlaggedEvents(self.stream.restart(), None))
            self._finished = True
        block, flag = FlaggedEvents.concat(parts)
        complete = packet.end_ns if self.encoding == NUSKIN_WORDS_V1 else None
        return DecodedEvents(block, flag, complete, lost)

    def diagnostics(self) -> dict[str, object]:
        """Packet counters, then the byte decoder's."""
        return {**self._packet_values(), **self.stream.diagnostics()}


class BioTacPacketDecoder(_SeqDecoder):
    """``biotac-bridge-v1`` packets -> frames stamped by the per-sensor frame clock.

    ``options``: ``lead_ns``, ``clock_window_frames``; PacketError for another encoding or option.
    """

    def __init__(self, encoding: str = BIOTAC_BRIDGE_V1, options: str = "") -> None:
        from ext_sense_drivers.biotac.clock import FRAME_PERIOD_NS, FrameClock
        from ext_sense_drivers.biotac.decoder import BridgeDecoder
        from ext_sense_drivers.biotac.errors import BioTacError
        from ext_sense_drivers.biotac.frame_layout import MAX_SENSORS

        super().__init__(encoding, options)
        if encoding != BIOTAC_BRIDGE_V1:
            raise PacketError(f"BioTac packets are {BIOTAC_BRIDGE_V1}. Got {encoding!r}.")
        opts = parse_options(options, ("lead_ns", "clock_window_frames"))
        try:
            lead = int(opts.get("lead_ns", FRAME_PERIOD_NS))
            window = int(opts.get("clock_window_frames", 200))
            self.clocks = [FrameClock(FRAME_PERIOD_NS, lead, window) for _ in range(MAX_SENSORS)]
        except (ValueError, BioTacError) as err:
            raise PacketError(f"encoding {encoding!r} options {options!r}: {err}") from err
        self.decoder = BridgeDecoder()
        self._bytes_fed = 0
        self._last_arrival_ns = 0
        n = MAX_SENSORS
        self._dropped, self._parity, self._errors = [0] * n, [0] * n, [0] * n

    def decode(self, packet: Any) -> DecodedFrames:
        """Decode one packet; each frame keeps the arrival of the read that completed it.

        No flush at a reconnection (a cut-off frame fails its CRC), only at ``end_of_stream``.
        PacketError (counted, dropped) for a malformed packet or another encoding.
        """
        from ext_sense_drivers.biotac.frame_layout import STANDARD_FRAME_SIZE

        packet, lost, _ = self._accept(packet)
        out: list[DecodedFrame] = []
        if packet.data:
            ends = self._bytes_fed + packet.read_end.astype(np.int64)
            times = packet.stamp_ns + packet.read_offset_ns
            try:
                frames = self.decoder.feed(packet.data)
            except Exception as err:  # a decoder bug costs the packet, not the consumer
                self._failed(packet, err)
                frames = None
            self._bytes_fed = int(ends[-1])
            self._last_arrival_ns = int(times[-1])
            if frames is not None:
                done = np.searchsorted(ends, frames.offset + STANDARD_FRAME_SIZE, side="left")
                out += self._frames(frames, times[np.minimum(done, len(ends) - 1)])
        if packet.end_of_stream and self.decoder.pending_bytes:
            frames = self.decoder.flush()
            out += self._frames(frames, np.full(frames.n, self._last_arrival_ns, np.int64))
        return DecodedFrames(out, lost)

    def _frames(self, frames: Any, arrival_ns: npt.NDArray[np.int64]) -> list[DecodedFrame]:
        from ext_sense_drivers.biotac.clock import PAC_PERIOD_NS

        out = []
        for k, arrival in enumerate(arrival_ns.tolist()):
            s = int(frames.sensor_id[k])
            gap = int(frames.gap[k])
            first_ns = self.clocks[s].update(arrival, gap, bool(frames.seq_reset[k]))
            self._dropped[s] += gap
            self._parity[s] += int(frames.parity_errors[k])
            self._errors[s] += int(frames.error_replies[k])
            out.append(
                DecodedFrame(
                    first_ns,
                    s,
                    int(frames.seq[k]),
                    PAC_PERIOD_NS,
                    frames.pac[k],
                    frames.electrodes[k],
                    int(frames.pdc[k]),
                    int(frames.tac[k]),
                    int(frames.tdc[k]),
                    int(frames.invalid_mask[k]),
                    min(self._dropped[s], 0xFFFFFFFF),
                    min(self._parity[s], 0xFFFFFFFF),
                    min(self._errors[s], 0xFFFFFFFF),
                    arrival,
                )
            )
        return out

    def diagnostics(self) -> dict[str, object]:
        """Packet counters, then the bridge decoder's."""
        c = self.decoder.counters
        return {
            **self._packet_values(),
            "frames_total": c.frames,
            "crc_failures": c.crc_failures,
            "skipped_bytes": c.skipped_bytes,
        }


def make_decoder(encoding: str, options: str = "") -> NuskinPacketDecoder | BioTacPacketDecoder:
    """The decoder of an encoding (PacketError if unknown or its options are not taken)."""
    if encoding in (NUSKIN_WORDS_V1, ACES_LINE_V1):
        return NuskinPacketDecoder(encoding, options)
    if encoding == BIOTAC_BRIDGE_V1:
        return BioTacPacketDecoder(encoding, options)
    raise PacketError(
        f"Unknown packet encoding {encoding!r}: expected one of "
        f"{[NUSKIN_WORDS_V1, ACES_LINE_V1, BIOTAC_BRIDGE_V1]}."
    )
