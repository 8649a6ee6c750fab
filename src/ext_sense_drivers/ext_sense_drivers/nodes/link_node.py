"""The link half every driver node shares: lifecycle, reader thread, publisher, diagnostics."""

from __future__ import annotations

import array
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from rclpy.node import Node
from rclpy.publisher import Publisher

from ext_sense_drivers.liveness import DriverLiveness
from ext_sense_drivers.packets import Packet
from ext_sense_drivers.transports.base import LinkState
from ext_sense_drivers.transports.reader import StreamReader
from ext_sense_msgs.msg import SensorPacket
from ext_sense_runtime import intra_process
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.qos import SENSOR_STREAM_QOS
from ext_sense_runtime.qos_events import QosEventCounter
from ext_sense_runtime.stamps import fill_stamp

LIVENESS_PERIOD_S = 0.1
"""How often the stream's liveness is judged; not shorter, as an idle driver wakes for it."""


def monotonic_to_ros_ns(node: Node) -> int:
    """Offset from monotonic ns (arrival times) to ROS time, taken once: stamps never step back."""
    return node.get_clock().now().nanoseconds - time.monotonic_ns()


def create_stream_publisher(
    node: Node, msg_type: type, topic: str
) -> tuple[Publisher | intra_process.IntraProcessPublisher, QosEventCounter]:
    """A raw sensor stream publisher (``SENSOR_STREAM_QOS``) and its QoS event counter."""
    qos_events = QosEventCounter()
    pub = intra_process.create_publisher(
        node, msg_type, topic, SENSOR_STREAM_QOS, event_callbacks=qos_events.publisher()
    )
    return pub, qos_events


def packet_message(packet: Packet, frame_id: str) -> SensorPacket:
    """A ``SensorPacket`` (arrays as ``array.array``: rclpy checks NumPy ones element-wise)."""
    msg = SensorPacket()
    fill_stamp(msg.header.stamp, packet.stamp_ns)
    msg.header.frame_id = frame_id
    msg.seq = packet.seq
    msg.encoding, msg.encoding_options = packet.encoding, packet.options
    msg.time_base, msg.connection = packet.time_base, packet.connection
    msg.end_of_stream = packet.end_of_stream
    msg.read_end = array.array("I", packet.read_end.astype(np.uint32).tobytes())
    msg.read_offset_ns = array.array("q", packet.read_offset_ns.astype(np.int64).tobytes())
    msg.data = packet.data
    return msg


def link_status(
    reader: StreamReader, lost: str, values: Mapping[str, object]
) -> tuple[Level, str, dict[str, object]]:
    """The ``link`` diagnostics check: reader state and counters, then the node's ``values``.

    OK while connected or a capture file is replayed to its end, ERROR while backing off,
    WARN otherwise; ``lost`` names what is unavailable (``"port"``, ``"link"``).
    """
    state = reader.state
    report: dict[str, object] = {
        "port_state": state.name.lower(),
        "connects": reader.connects,
        "disconnects": reader.disconnects,
        "open_failures": reader.open_failures,
        "bytes_total": reader.bytes_total,
        "dropped_bytes": reader.dropped_bytes,
        "last_error": reader.last_error,
        "reader_scheduling": reader.scheduling.describe() if reader.scheduling else "",
        **values,
    }
    if state == LinkState.CONNECTED:
        return Level.OK, "connected", report
    if state == LinkState.EXHAUSTED:
        return Level.OK, "capture file replayed to its end", report
    if state == LinkState.BACKOFF:
        return Level.ERROR, f"{lost} unavailable, retrying: {reader.last_error}", report
    return Level.WARN, state.name.lower(), report


class ManagedLink:
    """The lifecycle of a driver's link, mixed into a ``rclpy.lifecycle.LifecycleNode``.

    A missing or returning device is logged, a liveness change published at once. The node
    provides ``reader``, ``_tick``, ``_period_s``, ``guard``, ``liveness`` and ``_diagnostics``,
    and calls :meth:`start_managed` at the end of ``__init__``.
    """

    reader: StreamReader
    _period_s: float
    guard: CallbackGuard
    liveness: DriverLiveness
    _diagnostics: DiagnosticsPublisher

    def start_managed(self: Any, autostart: bool) -> None:
        """Leave the node unconfigured for a lifecycle manager, or configure and activate it."""
        self._drain_timer = None
        self._watch_timer = None
        self._seen_failures = 0
        self._was_connected = False
        self._liveness_timer = self.create_timer(
            LIVENESS_PERIOD_S, self.guard(self._check_liveness)
        )
        if autostart:
            self.trigger_configure()
            self.trigger_activate()
        else:
            self.get_logger().info("unconfigured: waiting for a lifecycle manager to configure")

    def on_configure(self: Any, state: Any) -> Any:
        """Open the device: the reader thread starts and retries until it is there."""
        from rclpy.lifecycle import TransitionCallbackReturn

        self.reader.start()
        self._watch_timer = self.create_timer(0.5, self.guard(self._watch_link))
        self.get_logger().info(f"configured: opening {self.reader.description}")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self: Any, state: Any) -> Any:
        """Stream: the drain timer publishes what arrives."""
        from rclpy.lifecycle import TransitionCallbackReturn

        if self.config.transport != "file":
            self.reader.drain()  # a live device's bytes from before activation are stale
        self._drain_timer = self.create_timer(self._period_s, self.guard(self._drain))
        self._drained_state = self.reader.state
        self.reader.on_data = self._wake_drain
        self.get_logger().info("active: streaming")
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self: Any, state: Any) -> Any:
        """Stop publishing; the device stays open."""
        from rclpy.lifecycle import TransitionCallbackReturn

        self._stop_streaming()
        self.reader.drain()  # what arrived while inactive is not published later
        return TransitionCallbackReturn.SUCCESS

    def on_cleanup(self: Any, state: Any) -> Any:
        """Release the device (the reader thread stops and closes it); also on shutdown."""
        from rclpy.lifecycle import TransitionCallbackReturn

        self._stop_streaming()
        if self._watch_timer is not None:
            self.destroy_timer(self._watch_timer)
            self._watch_timer = None
        self.reader.stop()
        return TransitionCallbackReturn.SUCCESS

    on_shutdown = on_cleanup

    def _stop_streaming(self: Any) -> None:
        self.reader.on_data = None
        if self._drain_timer is not None:
            self.destroy_timer(self._drain_timer)
            self._drain_timer = None

    def _drain(self: Any) -> None:
        """The drain timer: publish what arrived; with nothing more queued, stop ticking.

        Idle ticking would cost a good part of a core; the reader thread restarts the timer
        with the next chunk (:meth:`_wake_drain`). The queue is checked again after the cancel.
        """
        self._drained_state = self.reader.state
        self._tick()
        timer = self._drain_timer
        if timer is not None and not self.reader.queued_chunks:
            timer.cancel()
            if self.reader.queued_chunks:
                timer.reset()

    def _wake_drain(self: Any) -> None:
        """Restart a stopped drain timer (the reader thread, on each queued chunk).

        The executor is woken too: a wait-set executor would only see the reset timer at its
        next spin timeout.
        """
        timer = self._drain_timer
        try:
            if timer is not None and timer.is_canceled():
                timer.reset()
                executor = self.executor
                if executor is not None:
                    executor.wake()
        except Exception:  # the timer or executor went away with a deactivate or a shutdown
            pass

    def _check_liveness(self: Any) -> None:
        """Streaming is active with the link connected; publish diagnostics when the level moves."""
        streaming = self._drain_timer is not None and self.reader.state == LinkState.CONNECTED
        if self._drain_timer is not None and self.reader.state != self._drained_state:
            self._wake_drain()  # a lost link or an exhausted file: one tick finishes the stream
        self.liveness.set_streaming(streaming)
        if self.liveness.changed():
            self._diagnostics.publish()
            level, message, _ = self.liveness.check()
            # one call site per severity: rclpy refuses a severity change at one call site
            if level == Level.OK:
                self.get_logger().info(f"liveness {level.name}: {message}")
            else:
                self.get_logger().warning(f"liveness {level.name}: {message}")

    def _watch_link(self: Any) -> None:
        """Console lines for a device that is missing, lost, or back."""
        reader = self.reader
        failures = reader.open_failures + reader.disconnects
        if reader.state == LinkState.CONNECTED:
            if not self._was_connected and (failures or reader.connects > 1):
                self.get_logger().info(f"{reader.description}: connected")
            self._was_connected = True
        elif failures > self._seen_failures:
            self._was_connected = False
            delay = reader.backoff.delay(max(1, reader.failures_in_row))
            self.get_logger().warning(
                f"{reader.description} unavailable ({reader.last_error}); retrying in "
                f"{delay:.1f} s (failure {reader.failures_in_row} in a row)",
                throttle_duration_sec=5.0,
            )
        self._seen_failures = failures

    def destroy_node(self: Any) -> None:
        """Stop the reader thread (closing the link), if the constructor got that far."""
        reader = getattr(self, "reader", None)
        if reader is not None:
            reader.stop()
        super().destroy_node()
