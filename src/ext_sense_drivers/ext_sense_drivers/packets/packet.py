"""The packet record, reading one from a message, and packing a driver's reads into packets.

A packet keeps whole reads with their return times: the NUSkin words carry no time, so the
reads' arrival stamps them, and decoding a packet later gives exactly the driver's events.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from ext_sense_drivers.packets.errors import PacketError
from ext_sense_drivers.transports.base import Chunk
from ext_sense_runtime.stamps import stamp_to_ns

NUSKIN_WORDS_V1 = "nuskin-words-v1"
"""The NUSkin receiver's 4-byte event words (docs/nuskin.md, "Receiver words")."""
ACES_LINE_V1 = "aces-line-v1"
"""Raw ACES line samples, int16 little-endian, one per chip (docs/nuskin.md, "ACES line")."""
BIOTAC_BRIDGE_V1 = "biotac-bridge-v1"
"""The BioTac bridge's framed stream (docs/biotac_bridge.md)."""
ENCODINGS = (NUSKIN_WORDS_V1, ACES_LINE_V1, BIOTAC_BRIDGE_V1)

QUIET_PACKETS_PERIOD_S = 0.002
"""Default ``quiet_packets_period_s``: about the packet cadence of a real receiver's idle stream."""


class QuietSchedule:
    """When a NUSkin words driver says it read nothing (:meth:`PacketPacker.nothing_read`).

    One packet every ``period_s`` (0 or less: never) after the last bytes while none come.
    Clock-free, so the driver's timer and ``bench/latency_figures.py`` follow one rule.
    """

    def __init__(self, period_s: float = QUIET_PACKETS_PERIOD_S) -> None:
        self.period_ns = max(0, round(period_s * 1e9))
        self.next_ns: int | None = None

    @property
    def enabled(self) -> bool:
        """Whether the driver says it read nothing at all (a positive period)."""
        return self.period_ns > 0

    def on_bytes(self, t_ns: int) -> None:
        """Bytes were drained at ``t_ns``: the first packet is due one period later."""
        if self.enabled:
            self.next_ns = int(t_ns) + self.period_ns

    def due(self, now_ns: int) -> bool:
        """Whether a packet is due at ``now_ns``; if so, the next is due one period later."""
        if self.next_ns is None or now_ns < self.next_ns:
            return False
        self.next_ns += self.period_ns
        return True


ACES_BYTES_PER_SAMPLE = 2
"""The ACES line's clock ticks once per 2 bytes: ``time_base`` counts samples."""


class Packet(NamedTuple):
    """One ``SensorPacket``, checked, in plain Python.

    Attributes:
        stamp_ns: Host time the first read returned, integer ns (ROS clock).
        seq: Packet number on its topic since the driver started.
        encoding: What the bytes are (:data:`ENCODINGS`).
        options: The driver's decoding settings, ``"key=value;..."``.
        time_base: The sensor's clock at the first byte (ACES: line samples since the
            connection opened); 0 where the bytes carry no time.
        connection: Link connection the bytes came on (1, 2, ...).
        end_of_stream: The link was lost or the capture ended after these bytes.
        read_end: ``(n_reads,)`` uint32, end of each read in ``data``.
        read_offset_ns: ``(n_reads,)`` int64, each read's return time minus ``stamp_ns``.
        data: The bytes.
        frame_id: The sensor's frame.
    """

    stamp_ns: int
    seq: int
    encoding: str
    options: str
    time_base: int
    connection: int
    end_of_stream: bool
    read_end: npt.NDArray[np.uint32]
    read_offset_ns: npt.NDArray[np.int64]
    data: bytes
    frame_id: str = ""

    @property
    def end_ns(self) -> int:
        """Host time the last read returned (the stamp for a packet of no reads)."""
        last = int(self.read_offset_ns[-1]) if len(self.read_offset_ns) else 0
        return self.stamp_ns + last

    def reads(self) -> list[Chunk]:
        """The reads as transport chunks, each with its return time (ROS clock, ns)."""
        out = []
        lo = 0
        for end, offset in zip(self.read_end.tolist(), self.read_offset_ns.tolist(), strict=True):
            out.append(Chunk(self.data[lo:end], self.stamp_ns + offset))
            lo = end
        return out

    def check(self) -> Packet:
        """Return the packet if its arrays agree, else raise PacketError."""
        ends, offsets = self.read_end, self.read_offset_ns
        where = f"packet seq {self.seq} ({self.encoding or 'no encoding'})"
        if len(ends) != len(offsets):
            raise PacketError(
                f"{where}: read_end and read_offset_ns must have one length. "
                f"Got {len(ends)} and {len(offsets)}."
            )
        if not len(ends):
            if self.data:
                raise PacketError(f"{where}: {len(self.data)} bytes but no read_end.")
            return self
        if int(ends[-1]) != len(self.data) or (np.diff(ends.astype(np.int64)) < 0).any():
            raise PacketError(
                f"{where}: read_end must rise to len(data) = {len(self.data)}. "
                f"Got {ends.tolist()[:8]}{'...' if len(ends) > 8 else ''}."
            )
        if int(offsets.min()) < 0:
            raise PacketError(f"{where}: read_offset_ns must be >= 0. Got {int(offsets.min())}.")
        return self


def _bytes_of(field: Any) -> bytes:
    """A ``uint8[]`` field as bytes: rclpy gives ``array.array('B')``, rosbags a NumPy array."""
    if isinstance(field, bytes | bytearray):
        return bytes(field)
    if isinstance(field, np.ndarray):
        return field.astype(np.uint8, copy=False).tobytes()
    try:
        return memoryview(field).cast("B").tobytes()
    except TypeError:
        return bytes(field)


def packet_of(msg: Any) -> Packet:
    """The checked :class:`Packet` of a ``SensorPacket`` message (rclpy or rosbags)."""
    return Packet(
        stamp_to_ns(msg.header.stamp),
        int(msg.seq),
        str(msg.encoding),
        str(msg.encoding_options),
        int(msg.time_base),
        int(msg.connection),
        bool(msg.end_of_stream),
        np.asarray(msg.read_end, dtype=np.uint32),
        np.asarray(msg.read_offset_ns, dtype=np.int64),
        _bytes_of(msg.data),
        str(msg.header.frame_id),
    ).check()


def format_options(options: dict[str, object]) -> str:
    """Options as ``encoding_options`` text: ``{"baud": 9600}`` -> ``"baud=9600"`` (keys sorted)."""
    return ";".join(f"{k}={v}" for k, v in sorted(options.items()))


def parse_options(text: str, known: Iterable[str]) -> dict[str, str]:
    """The ``key=value`` pairs of ``encoding_options`` (``"key=value;..."``, maybe empty).

    PacketError for a pair without ``=`` or a key not in ``known``: a newer driver's setting,
    without which decoding would give other events than the driver's.
    """
    known = set(known)
    out: dict[str, str] = {}
    for pair in filter(None, (p.strip() for p in text.split(";"))):
        key, sep, value = pair.partition("=")
        if not sep:
            raise PacketError(f"encoding_options must be key=value pairs. Got {pair!r}.")
        if key not in known:
            raise PacketError(
                f"encoding_options key {key!r} is not known to this decoder ({sorted(known)})."
            )
        out[key] = value
    return out


class PacketPacker:
    """A driver's reads in, packets out: one per drain and connection, numbered by ``seq``.

    Keeps the current connection, so a lost link ends its stream exactly once, and counts its
    bytes for the ACES line's ``time_base``. ``encoding`` is one of :data:`ENCODINGS`.
    """

    def __init__(self, encoding: str, options: str = "") -> None:
        if encoding not in ENCODINGS:
            raise PacketError(f"The 'encoding' must be one of {list(ENCODINGS)}. Got {encoding!r}.")
        self.encoding = encoding
        self.options = options
        self.seq = 0
        self._connection = 0
        self._finished = True
        self._bytes_on_connection = 0
        self._last_ns = 0

    @property
    def connection(self) -> int:
        """The connection of the stream packed last (0 before any)."""
        return self._connection

    def pack(
        self, tagged: Sequence[tuple[int, Chunk]], link_down: bool, to_ros_ns: int = 0
    ) -> list[Packet]:
        """Packets for one drain of the reader, in order.

        ``tagged`` holds ``(connection, chunk)`` pairs as queued (empty reads are left out);
        ``link_down`` (read before draining) ends the current stream after these bytes, with an
        empty packet if need be; ``to_ros_ns`` is the offset from the monotonic clock to ROS time.
        """
        groups: list[tuple[int, list[Chunk]]] = []
        for connection, chunk in tagged:
            if not chunk.data:
                continue
            if not groups or groups[-1][0] != connection:
                groups.append((connection, []))
            groups[-1][1].append(chunk)
        out = [self._packet(connection, chunks, to_ros_ns) for connection, chunks in groups]
        if link_down and not self._finished:
            if out and out[-1].connection == self._connection:
                out[-1] = out[-1]._replace(end_of_stream=True)
            else:
                out.append(self._no_bytes(end_of_stream=True))
            self._finished = True
        return out

    def _packet(self, connection: int, chunks: list[Chunk], to_ros_ns: int) -> Packet:
        if connection != self._connection:
            self._connection, self._finished, self._bytes_on_connection = connection, False, 0
        sizes = np.fromiter((len(c.data) for c in chunks), np.int64, len(chunks))
        times = np.fromiter((c.t_ns for c in chunks), np.int64, len(chunks))
        stamp = int(times[0]) + to_ros_ns
        self._last_ns = int(times[-1]) + to_ros_ns
        time_base = 0
        if self.encoding == ACES_LINE_V1:
            time_base = self._bytes_on_connection // ACES_BYTES_PER_SAMPLE
        self._bytes_on_connection += int(sizes.sum())
        packet = Packet(
            stamp,
            self.seq,
            self.encoding,
            self.options,
            time_base,
            connection,
            False,
            np.cumsum(sizes).astype(np.uint32),
            np.maximum(times - times[0], 0),
            b"".join(c.data for c in chunks),
        )
        self.seq += 1
        return packet

    def nothing_read(self, t_ns: int, to_ros_ns: int = 0) -> Packet | None:
        """A packet saying the link read nothing up to ``t_ns`` (monotonic): no reads, no bytes.

        The words carry no time, so without it a silent sensor's windows would close on the
        consumer's clock, which a replay cannot repeat. It holds no read, so the arrival clock does
        not move. ``None`` with no stream going, or for an encoding other than the receiver's words
        (the others send all the time).
        """
        if self._finished or self.encoding != NUSKIN_WORDS_V1:
            return None
        self._last_ns = max(int(t_ns) + to_ros_ns, self._last_ns)
        return self._no_bytes(end_of_stream=False)

    def opened(self, connection: int, t_ns: int, to_ros_ns: int = 0) -> Packet | None:
        """A packet saying the link opened ``connection`` at ``t_ns`` (monotonic), no bytes yet.

        A consumer then knows the stream from the open, so the first contact of a receiver silent
        until touched is not judged "joined mid-stream". ``None`` for the current connection or an
        encoding other than words.
        """
        if self.encoding != NUSKIN_WORDS_V1 or connection == self._connection:
            return None
        self._connection, self._finished, self._bytes_on_connection = connection, False, 0
        self._last_ns = int(t_ns) + to_ros_ns
        return self._no_bytes(end_of_stream=False)

    def _no_bytes(self, end_of_stream: bool) -> Packet:
        """The next packet of no reads, stamped at the last read or "nothing read" time."""
        packet = Packet(
            self._last_ns,
            self.seq,
            self.encoding,
            self.options,
            0,
            self._connection,
            end_of_stream,
            np.zeros(0, np.uint32),
            np.zeros(0, np.int64),
            b"",
        )
        self.seq += 1
        return packet
