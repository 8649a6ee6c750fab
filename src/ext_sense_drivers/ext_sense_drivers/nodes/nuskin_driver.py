"""``nuskin_driver`` node: NUSkin receiver bytes in, ``SensorPacket`` out.

Every ``batch_period_s`` the bytes read (serial, CAN or a capture file) go out undecoded on
``packets`` (``nuskin-words-v1`` or ``aces-line-v1``). In words mode a silent stream gets a
"nothing read" packet every ``quiet_packets_period_s`` and each connection an "opened" packet,
so consumers and replays close the same windows.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

from rclpy.lifecycle import LifecycleNode

from ext_sense_drivers.liveness import NUSKIN_IDLE_WORDS_PER_S, DriverLiveness, StreamWatch
from ext_sense_drivers.nodes.link_node import (
    ManagedLink,
    create_stream_publisher,
    link_status,
    monotonic_to_ros_ns,
    packet_message,
)
from ext_sense_drivers.nodes.link_parameters import STALL_OFF, LinkParameters, link_field
from ext_sense_drivers.nuskin.driver_config import DriverConfig, Mode
from ext_sense_drivers.packets import (
    ACES_LINE_V1,
    NUSKIN_WORDS_V1,
    QUIET_PACKETS_PERIOD_S,
    Packet,
    PacketPacker,
    QuietSchedule,
    format_options,
)
from ext_sense_drivers.transports.base import Chunk, LinkState
from ext_sense_msgs.msg import SensorPacket
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, RateTask, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all, param

MAX_WORD_RATE_HZ = 320_000.0
"""80 taxels at 4 kHz: the most events per second the receiver can produce."""


def _not_empty(value: str) -> str | None:
    return "must not be empty" if not value else None


@dataclass(frozen=True)
class NuskinParameters(LinkParameters):
    """``nuskin_driver``'s parameters; frame_id changes live, the rest are read-only."""

    baud: int = link_field(
        "baud", DriverConfig.baud, "Serial line rate, bit/s (also caps the arrival-clock spread)."
    )
    file_bytes_per_s: float = link_field(
        "file_bytes_per_s",
        DriverConfig.file_bytes_per_s,
        "File replay rate, bytes/s; 0 uses file_pace.",
    )
    expected_rate_hz: float = param(
        float(NUSKIN_IDLE_WORDS_PER_S),
        "Least rate of the receiver's words while the link is up, words/s (default 540: a "
        "powered receiver sends its idle stream all the time, 511-536 words/s median on the "
        "real captures of April 2021). In aces_line mode the line's samples are watched at "
        "the line's sample rate instead, unless this is 0." + STALL_OFF,
        low=0.0,
        high=10_000_000.0,
        read_only=True,
    )
    file_pace: str = param(
        DriverConfig.file_pace,
        "File replay pace: recorded (from the lab .tact markers), serial (baud/10 bytes/s) "
        "or flat (as fast as possible).",
        read_only=True,
    )
    mode: str = param(
        DriverConfig.mode,
        "Byte format: words (receiver event words) or aces_line (raw line samples).",
        read_only=True,
    )
    flag_polarity: str = param(
        DriverConfig.flag_polarity,
        "Word flag bit: ignore (polarity 0, real receivers) or is_positive (1: +1, 0: -1).",
        read_only=True,
    )
    aces_threshold: float = param(
        DriverConfig.aces_threshold,
        "ACES detection threshold, fraction of a full signature match.",
        low=0.05,
        high=0.95,
        read_only=True,
    )
    frame_id: str = param("nuskin", "Frame of the sensor (header.frame_id).", check=_not_empty)
    batch_period_s: float = param(
        0.001, "Time between published batches, s.", low=0.0001, high=1.0, read_only=True
    )
    quiet_packets_period_s: float = param(
        QUIET_PACKETS_PERIOD_S,
        "While the stream goes and no bytes come, an empty packet ('nothing read up to now') "
        "every this long, s: the driver's own cadence. A consumer learns from it where "
        "stream time is when the sensor is silent and closes its windows on data, so a "
        "replay of the recorded packets cuts the same windows. Words mode only; 0: none.",
        low=0.0,
        high=1.0,
        read_only=True,
    )

    def driver_config(self) -> DriverConfig:
        """The driver's config (checks the link choice)."""
        return DriverConfig(
            **self.link(),
            file_pace=self.file_pace,
            mode=self.mode,
            flag_polarity=self.flag_polarity,
            aces_threshold=self.aces_threshold,
        )


def packet_encoding(config: DriverConfig) -> tuple[str, str]:
    """The packets' ``encoding`` and ``encoding_options`` for the driver's settings."""
    if config.mode_kind == Mode.WORDS:
        options = {"baud": int(config.baud), "flag_polarity": config.flag_polarity.lower()}
        return NUSKIN_WORDS_V1, format_options(options)
    return ACES_LINE_V1, format_options({"threshold": float(config.aces_threshold)})


def _liveness(p: NuskinParameters, config: DriverConfig, stream: str) -> DriverLiveness:
    """The stall check: receiver words (mode words) or line samples (aces_line) on ``stream``."""
    rate, (warn_ns, error_ns) = p.expected_rate_hz, p.stall_ns()
    what = f"receiver words on {stream}"
    if config.mode_kind != Mode.WORDS and rate > 0:
        from ext_sense_drivers.aces.bank import load_bank

        rate, what = float(load_bank().sample_rate_hz), f"ACES line samples on {stream}"
    return DriverLiveness([StreamWatch(what, rate, warn_ns, error_ns)])


class NuskinDriverNode(ManagedLink, LifecycleNode):
    """Publishes a NUSkin receiver's bytes on ``packets`` from a serial, CAN or file source."""

    PARAMETERS = NuskinParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("nuskin_driver", **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        self.p = p = declare_all(self, NuskinParameters, self._on_change, self.guard)
        self.config = p.driver_config()
        self.frame_id = p.frame_id
        quiet_period_s = p.quiet_packets_period_s
        self._quiet = QuietSchedule(quiet_period_s)
        self._quiet_timer = self.create_timer(
            max(quiet_period_s, 0.001), self.guard(self._say_quiet), autostart=False
        )
        self.liveness = _liveness(p, self.config, self.config.hardware_id)

        self.config.make_stream()  # checks mode and flag_polarity now, with a clear error
        encoding, options = packet_encoding(self.config)
        self.packer = PacketPacker(encoding, options)
        self.reader = self.config.make_reader(p.backoff())
        self._mono_to_ros_ns = monotonic_to_ros_ns(self)
        self.packets_published = 0
        self._packet_pub, self._qos_events = create_stream_publisher(self, SensorPacket, "packets")
        self._updater = Updater(self.config.hardware_id)
        self._rate = RateTask("words", 0.0, MAX_WORD_RATE_HZ, unit="words_per_s")
        self._updater.add(self._rate)
        self._updater.add_check("link", self._check_link)
        self._updater.add_check("liveness", self.liveness.check)
        self.guard.attach(self._updater)
        self._diagnostics = DiagnosticsPublisher(self, self._updater)
        self._period_s = p.batch_period_s
        self.get_logger().info(
            f"reading {self.config.mode} from {self.config.transport} {self.config.hardware_id}"
        )
        self.start_managed(p.autostart)

    def _on_change(self, new: NuskinParameters) -> None:
        self.p, self.frame_id = new, new.frame_id

    def _tick(self) -> None:
        """Drain the reader and publish the packets (a packet never spans a reconnect).

        The link state is read before draining, so a lost connection's chunks all go in the
        packet that ends its stream. Bytes, not decoded words, show the device alive.
        """
        link_down = self.reader.state != LinkState.CONNECTED
        tagged = self.reader.drain_tagged()
        watch = self.liveness.watches[0]
        per_item = 4 if self.config.mode_kind == Mode.WORDS else 2
        for _, chunk in tagged:
            watch.on_data(len(chunk.data) // per_item, chunk.t_ns)
            if per_item == 4:
                self._rate.add(len(chunk.data) // per_item)
        self._say_opened(tagged)
        for packet in self.packer.pack(tagged, link_down, self._mono_to_ros_ns):
            self._publish_packet(packet)
        read = any(chunk.data for _, chunk in tagged)
        if read and self._quiet.enabled and self.config.mode_kind == Mode.WORDS:
            self._quiet.on_bytes(time.monotonic_ns())
            self._quiet_timer.reset()  # its first tick one period after these bytes

    def _say_opened(self, tagged: list[tuple[int, Chunk]]) -> None:
        """Before a connection's first bytes, a packet stamped at its open (words mode).

        Sent with the first bytes' drain, so a recorder starting with them records it too.
        Off with ``quiet_packets_period_s`` 0, or when an older connection's chunks are queued.
        """
        connection, opened = self.reader.connects, self.reader.connected_ns
        if (
            opened is None
            or not tagged
            or connection == self.packer.connection  # its stream is going: said, or too late
            or not self._quiet.enabled
            or any(c != connection for c, _ in tagged)
        ):
            return
        opened = min(opened, tagged[0][1].t_ns)
        packet = self.packer.opened(connection, opened, self._mono_to_ros_ns)
        if packet is not None:
            self._publish_packet(packet)

    def _publish_packet(self, packet: Packet) -> None:
        self._packet_pub.publish(packet_message(packet, self.frame_id))
        self.packets_published += 1

    def _say_quiet(self) -> None:
        """The quiet timer: while no bytes come, say so every ``quiet_packets_period_s``.

        Not while bytes wait for the drain; stops with streaming or the link, restarted by bytes.
        """
        if self._drain_timer is None or self.reader.state != LinkState.CONNECTED:
            self._quiet_timer.cancel()
            return
        if self.reader.queued_chunks:
            return
        packet = self.packer.nothing_read(time.monotonic_ns(), self._mono_to_ros_ns)
        if packet is not None:
            self._publish_packet(packet)

    def _check_link(self) -> tuple[Level, str, dict[str, object]]:
        values = {
            "encoding": self.packer.encoding,
            "packets_published": self.packets_published,
            **self._qos_events.as_values(),
        }
        return link_status(self.reader, "port", values)


def main(args: list[str] | None = None) -> int:
    """Run the node (console script ``nuskin_driver``)."""
    return run_node(NuskinDriverNode, args)
