"""The packet record, reading one from a message, and packing a driver's reads into packets.

A packet holds whole reads of the link (the bytes of each read and when it returned), because
the NUSkin words carry no time: the arrival of each read is what stamps them
(:class:`~ext_sense_drivers.nuskin.clock.ArrivalClock`). Keeping the reads keeps a packet
lossless: decoding it later gives exactly the events the driver would have stamped.
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
"""Default time between the NUSkin driver's "nothing read" packets (``quiet_packets_period_s``,
:meth:`PacketPacker.nothing_read`) while its stream goes and no bytes come: the driver's own
cadence, as a real receiver's idle stream (about 540 words/s) makes a packet every 2 ms or so.
A consumer learns from them where stream time is when the sensor is silent."""


class QuietSchedule:
    """When a NUSkin words driver says it read nothing (:meth:`PacketPacker.nothing_read`).

    After bytes drained at ``t``, one "nothing read" packet is due every ``period_s`` while no
    bytes come, for as long as the stream goes: a fixed cadence of the driver's own, which
    knows nothing of its consumers' windows. Clock-free, so that the driver (whose periodic
    timer, reset by bytes, is this schedule) and the latency bench (which drives the driver's
    packer on simulated drains, ``bench/latency_figures.py``, asking :meth:`due` at each drain)
    follow one rule.

    Args:
        period_s: ``quiet_packets_period_s``; 0 or less: never.
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
        """Host time the last read returned: every byte of the packet had arrived by then.

        A packet of no reads (a stream's end, or "nothing read") ends at its stamp.
        """
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
        """Return the packet if its arrays agree, else raise.

        Raises:
            PacketError: ``read_end`` and ``read_offset_ns`` differ in length, the ends are not
                non-decreasing up to ``len(data)``, or an offset is negative.
        """
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
    """The checked :class:`Packet` of a ``SensorPacket`` message (rclpy or rosbags).

    Raises:
        PacketError: The message's arrays disagree (see :meth:`Packet.check`).
    """
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
    """The ``key=value`` pairs of ``encoding_options``.

    Args:
        text: ``"key=value;..."`` (empty: no options).
        known: The keys the encoding's decoder understands.

    Raises:
        PacketError: A pair without ``=`` or a key the decoder does not know (a newer driver's
            setting: decoding without it would give other events than the driver's).
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

    Plain Python so that the driver node only fills messages. The packer keeps the connection
    the last packet came on, so a lost link ends that stream exactly once, and counts the
    bytes of each connection for the ACES line's ``time_base``.

    Args:
        encoding: One of :data:`ENCODINGS`.
        options: The driver's decoding settings (:func:`format_options`).
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
        """Packets for one drain of the reader.

        Args:
            tagged: ``(connection, chunk)`` pairs as the reader queued them; empty reads are
                kept out (they carry no bytes, and the arrival clock only moves with data).
            link_down: The link is not connected (read before draining): the stream of the
                current connection ends after these bytes.
            to_ros_ns: Offset from the chunks' clock (monotonic) to ROS time, ns.

        Returns:
            Zero or more packets in order; an empty one only to say a stream ended.
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
                out.append(self._empty_end())
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
        """A packet saying the link read nothing up to ``t_ns``: no reads, no bytes.

        A NUSkin receiver's words carry no time, so a consumer learns that its stream time
        passed a window's end only from the next read; when the sensor falls silent there is
        none, and a window would close on the consumer's clock, which a replay of the packets
        cannot repeat. This packet, recorded like any other, says where stream time is: its
        ``complete_ns`` is ``t_ns``, live and in a replay alike. It holds no read, so the
        decoder's arrival clock does not move: the words of the next read are still spread
        over the time since the previous read (bytes may wait in the kernel while the reader
        thread is not running; a floor at ``t_ns`` moved the stamps of a quarter of a handover
        run's events, by up to 10 ms). A word of that next read stamped before ``t_ns`` is then
        late for a window this packet closed (the window node counts it), the same live and
        replayed.

        Args:
            t_ns: When the driver found nothing queued (the chunks' clock, monotonic).
            to_ros_ns: Offset from that clock to ROS time, ns.

        Returns:
            The packet; ``None`` with no stream going (no bytes yet, or its end was sent), or
            for another encoding than the receiver's words (the ACES line and the BioTac
            bridge send samples and frames all the time, and their decoders do not stamp by
            arrival).
        """
        if self._finished or self.encoding != NUSKIN_WORDS_V1:
            return None
        self._last_ns = max(int(t_ns) + to_ros_ns, self._last_ns)
        return self._no_bytes(end_of_stream=False)

    def opened(self, connection: int, t_ns: int, to_ros_ns: int = 0) -> Packet | None:
        """A packet saying the link opened ``connection`` at ``t_ns`` and read nothing yet.

        A consumer knows a stream from its first packet on: a window reaching back before it
        lacks its head (the consumer joined mid-stream). A receiver's words come from the open
        on, so the words' stream is known from the open, not from the first word: with a
        receiver that sends nothing until touched (the emulated one), the first contact's
        window began before the first word and was judged incomplete. Like
        :meth:`nothing_read`, it holds no read and leaves the arrival clock alone.

        Args:
            connection: The link's connection number (1, 2, ...).
            t_ns: When it opened (the chunks' clock, monotonic).
            to_ros_ns: Offset from that clock to ROS time, ns.

        Returns:
            The packet; ``None`` for a connection this packer already has bytes of, or for
            another encoding than the receiver's words (see :meth:`nothing_read`).
        """
        if self.encoding != NUSKIN_WORDS_V1 or connection == self._connection:
            return None
        self._connection, self._finished, self._bytes_on_connection = connection, False, 0
        self._last_ns = int(t_ns) + to_ros_ns
        return self._no_bytes(end_of_stream=False)

    def _empty_end(self) -> Packet:
        """A packet with no bytes that ends the stream, stamped at its last read."""
        return self._no_bytes(end_of_stream=True)

    def _no_bytes(self, end_of_stream: bool) -> Packet:
        """The next packet of no reads on the current connection.

        Stamped at the last read's return, or at the "nothing read" time.
        """
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
