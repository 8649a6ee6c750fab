"""``biotac_driver`` node: BioTac bridge bytes in, ``SensorPacket`` out.

A timer publishes what the link (serial, CAN or a capture file) read on ``packets``
(``biotac-bridge-v1``). The node decodes its own packets (cheap at 100 frames/s) only to watch
each expected sensor's rate, counters and liveness on ``/diagnostics``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rclpy.lifecycle import LifecycleNode

from ext_sense_drivers.biotac.clock import FRAME_RATE_HZ
from ext_sense_drivers.biotac.driver_config import BioTacDriverConfig
from ext_sense_drivers.biotac.frame_layout import MAX_SENSORS
from ext_sense_drivers.liveness import DriverLiveness, StreamWatch
from ext_sense_drivers.nodes.link_node import (
    ManagedLink,
    create_stream_publisher,
    link_status,
    monotonic_to_ros_ns,
    packet_message,
)
from ext_sense_drivers.nodes.link_parameters import STALL_OFF, LinkParameters, link_field
from ext_sense_drivers.packets import (
    BIOTAC_BRIDGE_V1,
    BioTacPacketDecoder,
    DecodedFrame,
    PacketPacker,
    format_options,
)
from ext_sense_drivers.transports.base import LinkState
from ext_sense_drivers.transports.reader import Backoff
from ext_sense_msgs.msg import SensorPacket
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, RateTask, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all, param


@dataclass(frozen=True)
class BioTacParameters(LinkParameters):
    """``biotac_driver``'s parameters; reconnect_max_s changes live, the rest are read-only."""

    baud: int = link_field(
        "baud",
        BioTacDriverConfig.baud,
        "Serial line rate, bit/s (8N1; five sensors need >= 480000). Also sets the "
        "transmission time in the clock model.",
    )
    can_arbitration_id: int = link_field(
        "can_arbitration_id",
        BioTacDriverConfig.can_arbitration_id,
        "Arbitration id of the CAN frames carrying the bridge stream.",
    )
    file_bytes_per_s: float = link_field(
        "file_bytes_per_s",
        BioTacDriverConfig.file_bytes_per_s,
        "File replay rate, bytes/s (9600 per sensor is real time); 0 replays flat out.",
    )
    reconnect_max_s: float = param(2.0, "Longest reconnect delay, s.", low=0.001, high=600.0)
    expected_rate_hz: float = param(
        float(FRAME_RATE_HZ),
        "Least frame rate of each expected sensor while the link is up, frames/s (default "
        "100: the bridge sends every sensor's frames at 100 Hz whatever touches it)." + STALL_OFF,
        low=0.0,
        high=10_000_000.0,
        read_only=True,
    )
    frame_id_prefix: str = param(
        BioTacDriverConfig.frame_id_prefix,
        "header.frame_id of the packets: this prefix without its trailing '_' (one link "
        "carries every sensor slot; a frame's slot is in its bytes).",
        read_only=True,
    )
    expected_sensors: tuple[int, ...] = param(
        BioTacDriverConfig.expected_sensors,
        "Sensor slots (0..4) that must deliver 100 frames/s; diagnostics check their rate.",
        read_only=True,
    )
    latency_ns: int = param(
        BioTacDriverConfig.latency_ns,
        "Known fixed latency from the bridge to the host, ns, added to the clock model's "
        "lead (frame span 10 ms + serial transmission).",
        low=0,
        high=1_000_000_000,
        read_only=True,
    )
    clock_window_frames: int = param(
        BioTacDriverConfig.clock_window_frames,
        "Frames over which the clock model keeps the least-delayed arrival (200 = 2 s).",
        low=1,
        high=100_000,
        read_only=True,
    )
    publish_period_s: float = param(
        0.002,
        "Time between drains of the link (frames are published one message each), s.",
        low=0.0001,
        high=1.0,
        read_only=True,
    )

    def driver_config(self) -> BioTacDriverConfig:
        """The driver's config (checks the link and the sensor slots)."""
        return BioTacDriverConfig(
            **self.link(),
            frame_id_prefix=self.frame_id_prefix,
            expected_sensors=self.expected_sensors,
            latency_ns=self.latency_ns,
            clock_window_frames=self.clock_window_frames,
        )


class BioTacDriverNode(ManagedLink, LifecycleNode):
    """Publishes a BioTac bridge's bytes on ``packets`` from a serial, CAN or file source."""

    PARAMETERS = BioTacParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("biotac_driver", **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        self.p = p = declare_all(self, BioTacParameters, self._on_change, self.guard)
        self.config = p.driver_config()
        rate, (warn_ns, error_ns) = p.expected_rate_hz, p.stall_ns()
        where = self.config.hardware_id
        self._watches = {
            s: StreamWatch(f"frames of BioTac sensor {s} on {where}", rate, warn_ns, error_ns)
            for s in sorted(set(self.config.expected_sensors))
        }
        self.liveness = DriverLiveness(list(self._watches.values()))

        options = format_options(
            {
                "lead_ns": self.config.lead_ns,
                "clock_window_frames": self.config.clock_window_frames,
            }
        )
        self.packer = PacketPacker(BIOTAC_BRIDGE_V1, options)
        self.packet_decoder = BioTacPacketDecoder(BIOTAC_BRIDGE_V1, options)
        self.decoder = self.packet_decoder.decoder  # the bridge decoder and its counters
        self.reader = self.config.make_reader(p.backoff())
        self._mono_to_ros_ns = monotonic_to_ros_ns(self)
        self.frames_decoded = 0
        self.packets_published = 0
        self._failures_logged = 0
        self._packet_pub, self._qos_events = create_stream_publisher(self, SensorPacket, "packets")
        self._updater = Updater(self.config.hardware_id)
        self._updater.add_check("link", self._check_link)
        self._rates: dict[int, RateTask] = {}
        for s in sorted(set(self.config.expected_sensors)):
            task = RateTask(f"sensor {s} frames", FRAME_RATE_HZ, FRAME_RATE_HZ, unit="frames_per_s")
            self._rates[s] = task
            self._updater.add(task)
        self._updater.add_check("decode", self._check_decode)
        self._updater.add_check("liveness", self.liveness.check)
        self.guard.attach(self._updater)
        self._last_reported = self.decoder.counters
        self._diagnostics = DiagnosticsPublisher(self, self._updater)
        self._period_s = p.publish_period_s
        self.get_logger().info(
            f"reading the BioTac bridge from {self.config.transport} {self.config.hardware_id}"
        )
        self.start_managed(p.autostart)

    def _on_change(self, new: BioTacParameters) -> str | None:
        initial = self.reader.backoff.initial_s
        if new.reconnect_max_s < initial:
            return (
                f"The 'reconnect_max_s' parameter must be >= reconnect_initial_s ({initial}). "
                f"Got {new.reconnect_max_s} instead."
            )
        self.reader.backoff = Backoff(initial, new.reconnect_max_s)
        self.p = new
        return None

    def _tick(self) -> None:
        """Drain the reader, publish the packets, and decode them to watch every sensor.

        The state is read before draining: a packet after which the link is down ends the
        stream and flushes the decoder (a reconnection alone needs no flush).
        """
        link_down = self.reader.state != LinkState.CONNECTED
        tagged = self.reader.drain_tagged()
        for packet in self.packer.pack(tagged, link_down, self._mono_to_ros_ns):
            # one link carries every sensor slot: the packet's frame is the prefix's ("biotac")
            frame = self.config.frame_id_prefix.rstrip("_") or "biotac"
            self._packet_pub.publish(packet_message(packet, frame))
            self.packets_published += 1
            decoded = self.packet_decoder.decode(packet)
            failures = self.packet_decoder.counters.decode_failures
            if failures > self._failures_logged:
                self._failures_logged = failures
                self.get_logger().error(self.packet_decoder.last_error, throttle_duration_sec=1.0)
            self._watch(decoded.frames)

    def _watch(self, frames: list[DecodedFrame]) -> None:
        """Count each expected sensor's frames for its rate and liveness."""
        for f in frames:
            s = f.sensor_id
            if s in self._rates:
                self._rates[s].tick()
                self._watches[s].on_data(1, f.arrival_ns - self._mono_to_ros_ns)
        self.frames_decoded += len(frames)

    def _check_link(self) -> tuple[Level, str, dict[str, object]]:
        values = {
            "packets_published": self.packets_published,
            "frames_decoded": self.frames_decoded,
            **self._qos_events.as_values(),
        }
        return link_status(self.reader, "link", values)

    def _check_decode(self) -> tuple[Level, str, dict[str, object]]:
        c = self.decoder.counters
        last, self._last_reported = self._last_reported, c
        values: dict[str, object] = {
            "frames_total": c.frames,
            "crc_failures": c.crc_failures,
            "skipped_bytes": c.skipped_bytes,
            "truncated_frames": c.truncated,
            "other_frames": c.other_frames,
            "bad_sensor_frames": c.bad_sensor_frames,
        }
        for s in range(MAX_SENSORS):
            if c.sensor_frames[s] or s in self._rates:
                values[f"sensor_{s}_frames"] = c.sensor_frames[s]
                values[f"sensor_{s}_dropped_frames"] = c.dropped_frames[s]
                values[f"sensor_{s}_parity_errors"] = c.parity_errors[s]
                values[f"sensor_{s}_error_replies"] = c.error_replies[s]
                values[f"sensor_{s}_seq_resets"] = c.seq_resets[s]
        new = {
            "crc failures": c.crc_failures - last.crc_failures,
            "dropped frames": sum(c.dropped_frames) - sum(last.dropped_frames),
            "parity errors": sum(c.parity_errors) - sum(last.parity_errors),
            "error replies": sum(c.error_replies) - sum(last.error_replies),
        }
        problems = [f"{n} {what}" for what, n in new.items() if n]
        if problems:
            return Level.WARN, ", ".join(problems) + " since the last report", values
        return Level.OK, "clean stream", values


def main(args: list[str] | None = None) -> int:
    """Run the node (console script ``biotac_driver``)."""
    return run_node(BioTacDriverNode, args)
