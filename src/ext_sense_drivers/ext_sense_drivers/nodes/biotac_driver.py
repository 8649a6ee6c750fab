"""``biotac_driver`` node: BioTac bridge bytes in, one ``BioTacFrame`` message per frame out.

A :class:`~ext_sense_drivers.transports.reader.StreamReader` thread owns the link (serial, CAN
or a capture file) and reconnects with exponential backoff; a timer drains what arrived, decodes
it with :class:`~ext_sense_drivers.biotac.decoder.BridgeDecoder` and publishes every frame as it
came: 22 raw PAC samples per message, never averaged. Words failing parity or BioTac error
replies are flagged in ``invalid_word_mask`` and counted; corrupt bytes are counted, never fatal.
``header.stamp`` is the first PAC sample's time from the per-sensor
:class:`~ext_sense_drivers.biotac.clock.FrameClock`. ``/diagnostics`` carries the link state,
frames/s per expected sensor, the decode counters and the liveness of every expected sensor:
a bridge sends each sensor's frames at 100 Hz whatever touches it, so a sensor silent while
the link is up is a stall (WARN, then ERROR, naming the sensor).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.lifecycle import LifecycleNode
from rclpy.node import Node

from ext_sense_drivers.biotac.clock import FRAME_RATE_HZ, PAC_PERIOD_NS, FrameClock
from ext_sense_drivers.biotac.decoder import BridgeDecoder
from ext_sense_drivers.biotac.driver_config import BioTacDriverConfig
from ext_sense_drivers.biotac.frame_layout import MAX_SENSORS, STANDARD_FRAME_SIZE
from ext_sense_drivers.biotac.frames import BridgeFrames
from ext_sense_drivers.liveness import DriverLiveness, StreamWatch
from ext_sense_drivers.nodes.link_node import (
    ManagedLink,
    create_stream_publisher,
    declare_autostart,
    declare_backoff,
    declare_link_parameters,
    declare_liveness,
    link_status,
    monotonic_to_ros_ns,
    stop_reader,
)
from ext_sense_drivers.transports.base import LinkState
from ext_sense_drivers.transports.reader import Backoff, StreamReader
from ext_sense_msgs.msg import BioTacFrame
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, RateTask, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare
from ext_sense_runtime.stamps import fill_stamp


def _declare_config(node: Node) -> BioTacDriverConfig:
    d = BioTacDriverConfig()
    link = declare_link_parameters(
        node,
        d,
        {
            "port": "Serial device of the bridge or pyserial URL.",
            "baud": "Serial line rate, bit/s (8N1; five sensors need >= 480000). Also sets the "
            "transmission time in the clock model.",
            "can_arbitration_id": "Arbitration id of the CAN frames carrying the bridge stream.",
            "can_extended_id": "29-bit extended CAN id.",
            "file_path": "Recorded bridge stream (transport file).",
            "file_bytes_per_s": "File replay rate, bytes/s (9600 per sensor is real time); "
            "0 replays flat out.",
        },
    )
    return BioTacDriverConfig(
        **link,
        frame_id_prefix=declare(
            node,
            "frame_id_prefix",
            d.frame_id_prefix,
            "header.frame_id is this prefix plus the sensor slot (biotac_0 ... biotac_4).",
            read_only=True,
        ),
        expected_sensors=tuple(
            declare(
                node,
                "expected_sensors",
                list(d.expected_sensors),
                "Sensor slots (0..4) that must deliver 100 frames/s; diagnostics check their rate.",
                read_only=True,
            )
        ),
        latency_ns=declare(
            node,
            "latency_ns",
            d.latency_ns,
            "Known fixed latency from the bridge to the host, ns, added to the clock model's "
            "lead (frame span 10 ms + serial transmission).",
            low=0,
            high=1_000_000_000,
            read_only=True,
        ),
        clock_window_frames=declare(
            node,
            "clock_window_frames",
            d.clock_window_frames,
            "Frames over which the clock model keeps the least-delayed arrival (200 = 2 s).",
            low=1,
            high=100_000,
            read_only=True,
        ),
    )


class BioTacDriverNode(ManagedLink, LifecycleNode):
    """Publishes BioTac frames on ``frames`` from a serial, CAN or file bridge stream."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("biotac_driver", **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        self.config = _declare_config(self)
        period_s = declare(
            self,
            "publish_period_s",
            0.002,
            "Time between drains of the link (frames are published one message each), s.",
            low=0.0001,
            high=1.0,
            read_only=True,
        )
        backoff = declare_backoff(self, "link", max_read_only=False)
        rate, warn_ns, error_ns = declare_liveness(
            self,
            FRAME_RATE_HZ,
            "Least frame rate of each expected sensor while the link is up, frames/s "
            "(default 100: the bridge sends every sensor's frames at 100 Hz whatever touches "
            "it).",
        )
        where = self.config.hardware_id
        self._watches = {
            s: StreamWatch(f"frames of BioTac sensor {s} on {where}", rate, warn_ns, error_ns)
            for s in sorted(set(self.config.expected_sensors))
        }
        self.liveness = DriverLiveness(list(self._watches.values()))
        self.add_on_set_parameters_callback(
            self.guard.wrap(
                self._on_set,
                fallback=lambda err: SetParametersResult(successful=False, reason=str(err)),
            )
        )

        self.decoder = BridgeDecoder()
        self.clocks: list[FrameClock] = [self.config.make_clock() for _ in range(MAX_SENSORS)]
        self.reader = StreamReader(self.config.make_transport(), backoff=backoff)
        self._mono_to_ros_ns = monotonic_to_ros_ns(self)
        self._last_arrival_ns = time.monotonic_ns()
        self._bytes_fed = 0  # stream position of the next byte given to the decoder
        self._dropped = [0] * MAX_SENSORS
        self._parity = [0] * MAX_SENSORS
        self._errors = [0] * MAX_SENSORS
        self.frames_published = 0
        self._pub, self._qos_events = create_stream_publisher(self, BioTacFrame, "frames")
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
        self._period_s = period_s
        self.get_logger().info(
            f"reading the BioTac bridge from {self.config.transport} {self.config.hardware_id}"
        )
        self.start_managed(declare_autostart(self))

    def _on_set(self, params: list[Any]) -> SetParametersResult:
        for p in params:
            if p.name == "reconnect_max_s" and float(p.value) < self.reader.backoff.initial_s:
                return SetParametersResult(
                    successful=False,
                    reason=f"The 'reconnect_max_s' parameter must be >= reconnect_initial_s "
                    f"({self.reader.backoff.initial_s}). Got {p.value} instead.",
                )
        for p in params:
            if p.name == "reconnect_max_s":
                self.reader.backoff = Backoff(self.reader.backoff.initial_s, float(p.value))
        return SetParametersResult(successful=True)

    def _tick(self) -> None:
        """Drain the reader, decode, publish every frame.

        A reconnection needs no flush: the old link's cut-off frame fails its CRC against the
        new bytes and the decoder resynchronises, while a complete frame still queued from the
        old link is kept. The state is read before draining, so an exhausted file's last chunks
        are decoded before the held-back bytes are flushed.
        """
        exhausted = self.reader.state == LinkState.EXHAUSTED
        chunks = self.reader.drain()
        if chunks:
            # One decoder call per tick (its fixed cost dominates at a frame or two per chunk);
            # each frame keeps the arrival time of the chunk that completed it.
            ends = self._bytes_fed + np.cumsum([len(c.data) for c in chunks])
            times = np.array([c.t_ns for c in chunks], dtype=np.int64)
            frames = self.decoder.feed(b"".join(c.data for c in chunks))
            self._bytes_fed = int(ends[-1])
            self._last_arrival_ns = int(times[-1])
            done = np.searchsorted(ends, frames.offset + STANDARD_FRAME_SIZE, side="left")
            self._publish(frames, times[np.minimum(done, len(chunks) - 1)])
        if exhausted and self.decoder.pending_bytes:
            frames = self.decoder.flush()
            self._publish(frames, np.full(frames.n, self._last_arrival_ns, dtype=np.int64))

    def _publish(self, frames: BridgeFrames, arrival_ns: np.ndarray) -> None:
        """One message per frame, stamped with the first PAC sample's ROS time.

        Args:
            frames: Decoded frames.
            arrival_ns: ``(n,)`` monotonic host arrival time of each frame, integer ns.
        """
        arrivals = (arrival_ns + np.int64(self._mono_to_ros_ns)).tolist()
        for k in range(frames.n):
            s = int(frames.sensor_id[k])
            gap = int(frames.gap[k])
            first_ns = self.clocks[s].update(arrivals[k], gap, bool(frames.seq_reset[k]))
            self._dropped[s] += gap
            self._parity[s] += int(frames.parity_errors[k])
            self._errors[s] += int(frames.error_replies[k])
            msg = BioTacFrame()
            fill_stamp(msg.header.stamp, first_ns)
            msg.header.frame_id = self.config.frame_id(s)
            msg.sensor_id = s
            msg.sequence = int(frames.seq[k])
            msg.pac_sample_period_ns = PAC_PERIOD_NS
            msg.pac = frames.pac[k]
            msg.electrodes = frames.electrodes[k]
            msg.pdc = int(frames.pdc[k])
            msg.tac = int(frames.tac[k])
            msg.tdc = int(frames.tdc[k])
            msg.invalid_word_mask = int(frames.invalid_mask[k])
            msg.dropped_frames = min(self._dropped[s], 0xFFFFFFFF)
            msg.parity_errors = min(self._parity[s], 0xFFFFFFFF)
            msg.error_replies = min(self._errors[s], 0xFFFFFFFF)
            self._pub.publish(msg)
            if s in self._rates:
                self._rates[s].tick()
                self._watches[s].on_data(1, int(arrival_ns[k]))
        self.frames_published += frames.n

    def _check_link(self) -> tuple[Level, str, dict[str, object]]:
        values = {"frames_published": self.frames_published, **self._qos_events.as_values()}
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

    def destroy_node(self) -> None:
        """Stop the reader thread (closing the link) before the node goes."""
        stop_reader(self)
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the node (console script ``biotac_driver``)."""
    return run_node(BioTacDriverNode, args)
