"""What the view draws the sensor from: the drivers' raw packets, decoded here.

With the drivers' decoder library, as the window node does: a ``seq`` gap is counted and
restarts the byte stream; a packet that cannot be read is counted and dropped, never raised.
One decoder per ``(encoding, options, connection)``, so two publishers on one topic do not
break each other's streams. Messages are read duck-typed (rclpy, rosbags or plain records).
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any, NamedTuple

import numpy as np

from ext_sense.view.errors import ViewError
from ext_sense.view.taxels import ElectrodeActivity, TaxelActivity
from ext_sense.view.traces import PacTrace
from ext_sense_drivers.packets import (
    ACES_LINE_V1,
    BIOTAC_BRIDGE_V1,
    ENCODINGS,
    NUSKIN_WORDS_V1,
    Packet,
    PacketError,
    make_decoder,
)
from ext_sense_runtime.diagnostics import Level

SENSOR_ENCODINGS: dict[str, tuple[str, ...]] = {
    "nuskin": (NUSKIN_WORDS_V1, ACES_LINE_V1),
    "biotac": (BIOTAC_BRIDGE_V1,),
}
"""Sensor -> the packet encodings the view draws for it."""

MAX_DECODERS = 8
"""Decoders kept at most (one per stream seen); the least recently fed goes first."""


class FeedCounters(NamedTuple):
    """What a :class:`SensorFeed` took, dropped and ignored (monotonic).

    ``lost_packets`` are ``seq`` gaps; ``bad_packets`` were refused (malformed, unknown
    encoding, another sensor's); ``decode_failures`` are reads a decoder failed on.
    """

    packets: int = 0
    lost_packets: int = 0
    bad_packets: int = 0
    decode_failures: int = 0
    events: int = 0
    frames: int = 0


class SensorFeed:
    """Packets in, the view's taxel (NUSkin), electrode and PAC (BioTac) state fed.

    Raises:
        ViewError: An unknown sensor.
    """

    def __init__(
        self,
        sensor: str,
        taxels: TaxelActivity,
        electrodes: ElectrodeActivity,
        pac: PacTrace,
    ) -> None:
        if sensor not in SENSOR_ENCODINGS:
            raise ViewError(
                f"The 'sensor' parameter must be one of {list(SENSOR_ENCODINGS)}. "
                f"Got {sensor!r} instead."
            )
        self.sensor = sensor
        self.taxels, self.electrodes, self.pac = taxels, electrodes, pac
        self._counts = dict.fromkeys(FeedCounters._fields, 0)
        self._decoders: OrderedDict[tuple[str, str, int], Any] = OrderedDict()
        self._retired_failures = 0
        self.last_packet_error = ""
        """Why the last refused packet was refused ('' when none was)."""
        self.last_lost_packets = 0
        """Packets missing just before the last packet fed (its ``seq`` gap)."""

    @property
    def counters(self) -> FeedCounters:
        """Counters since construction (``decode_failures`` summed over every decoder)."""
        live = sum(d.counters.decode_failures for d in self._decoders.values())
        return FeedCounters(**{**self._counts, "decode_failures": self._retired_failures + live})

    def on_packet(self, msg: Any) -> None:
        """Feed one ``SensorPacket`` (rclpy, rosbags or a :class:`Packet`); bad ones counted."""
        self._counts["packets"] += 1
        self.last_lost_packets = 0
        try:
            decoded = self._decoder_for(msg).decode(msg)
        except PacketError as err:
            self._counts["bad_packets"] += 1
            self.last_packet_error = str(err)
            return
        self.last_lost_packets = decoded.lost_packets
        self._counts["lost_packets"] += decoded.lost_packets
        if self.sensor == "nuskin":
            ids = np.asarray(decoded.events.taxel, dtype=np.int64)
            self._counts["events"] += ids.size
            self.taxels.add(ids)
            return
        for frame in decoded.frames:
            self._counts["frames"] += 1
            self.electrodes.add(int(frame.sensor_id), np.asarray(frame.electrodes))
            self.pac.add(int(frame.sensor_id), np.asarray(frame.pac))

    def _decoder_for(self, msg: Any) -> Any:
        """The decoder of the packet's stream, made on its first packet (or a PacketError)."""
        encoding = str(msg.encoding)
        options = str(msg.options if isinstance(msg, Packet) else msg.encoding_options)
        key = (encoding, options, int(msg.connection))
        decoder = self._decoders.get(key)
        if decoder is not None:
            self._decoders.move_to_end(key)
            return decoder
        wanted = SENSOR_ENCODINGS[self.sensor]
        if encoding in ENCODINGS and encoding not in wanted:
            raise PacketError(
                f"packet seq {int(msg.seq)} is {encoding!r}: the {self.sensor} view reads "
                f"{list(wanted)}"
            )
        decoder = make_decoder(encoding, options)
        self._decoders[key] = decoder
        while len(self._decoders) > MAX_DECODERS:
            _, old = self._decoders.popitem(last=False)
            self._retired_failures += old.counters.decode_failures
        return decoder

    def status(self) -> tuple[Level, str, dict[str, object]]:
        """The input's part of the view's status: WARN once a packet was refused, else OK."""
        c = self.counters
        values: dict[str, object] = {
            "packets": c.packets,
            "lost_packets": c.lost_packets,
            "dropped_bad_packets": c.bad_packets,
            "decode_failures": c.decode_failures,
        }
        if c.bad_packets:
            why = f"dropped {c.bad_packets} bad packet(s): {self.last_packet_error}"
            return Level.WARN, why, values
        reading = "reading packets" if c.packets else "waiting for packets"
        return Level.OK, reading, values
