"""``foxglove_view`` node: a live Foxglove view of the sensor, the windows and the estimates.

It sends its pictures at ``display_rate_hz`` and passes the graph's low-rate topics through
(:mod:`.channels`). Unwatched it costs nothing: packets are subscribed only while a client
watches a sensor channel. It runs in a process of its own at a lower priority (``nice``), so it
never starves perception. The protocol has no authentication.
"""

from __future__ import annotations

import functools
import json
import os
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

import foxglove
import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from ext_sense_bags.typestore import make_typestore
from foxglove import Channel, Schema
from foxglove.channels import RawImageChannel
from foxglove.messages import RawImage, Timestamp
from rclpy.node import Node
from rclpy.serialization import deserialize_message

from ext_sense.topics import (
    TOPIC_DIAGNOSTICS,
    TOPIC_ESTIMATE,
    TOPIC_GROUND_TRUTH,
    TOPIC_PROVISIONAL_ESTIMATE,
    TOPIC_WINDOW,
)
from ext_sense.view import channels as ch
from ext_sense.view.estimate import (
    diagnostics_message,
    estimate_image,
    estimate_message,
    matching_truth,
)
from ext_sense.view.feed import SensorFeed
from ext_sense.view.images import Image
from ext_sense.view.pacing import DisplayPacer
from ext_sense.view.raster import raster_image
from ext_sense.view.taxels import ElectrodeActivity, TaxelActivity, biotac_grid, nuskin_grid
from ext_sense.view.traces import PacTrace, rates_message
from ext_sense_msgs.msg import (
    ContactEstimate,
    ContactGroundTruth,
    ContactWindow,
    SensorPacket,
)
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all, param
from ext_sense_runtime.qos import (
    DIAGNOSTICS_QOS,
    ESTIMATE_QOS,
    GROUND_TRUTH_QOS,
    SENSOR_STREAM_QOS,
    WINDOW_QOS,
)
from ext_sense_runtime.records import estimate_of, truth_of
from ext_sense_runtime.stamps import split_ns

MAX_PENDING_ESTIMATES = 16
"""Estimates (distinct contacts) kept for the next frame; older ones are dropped first."""

PASSED = {  # graph topic (relative, remapped by the graph) -> (channel, type, QoS)
    "contact_estimate": (TOPIC_ESTIMATE, ContactEstimate, ESTIMATE_QOS),
    "contact_estimate/provisional": (TOPIC_PROVISIONAL_ESTIMATE, ContactEstimate, ESTIMATE_QOS),
    "ground_truth": (TOPIC_GROUND_TRUTH, ContactGroundTruth, GROUND_TRUTH_QOS),
    "window": (TOPIC_WINDOW, ContactWindow, WINDOW_QOS),
    TOPIC_DIAGNOSTICS: (TOPIC_DIAGNOSTICS, DiagnosticArray, DIAGNOSTICS_QOS),
}


_ro = functools.partial(param, read_only=True)


@dataclass(frozen=True)
class ViewParameters:
    """``foxglove_view``'s parameters, all read-only."""

    sensor: str = _ro("nuskin", "Sensor drawn: 'nuskin' or 'biotac'.", choices=("nuskin", "biotac"))
    host: str = _ro(
        "127.0.0.1",
        "Address the WebSocket server listens on. The protocol has no authentication: "
        "anything but a loopback address shows every channel to whoever reaches the port.",
    )
    port: int = _ro(8765, "TCP port of the server; 0: any free port.", low=0, high=65535)
    display_rate_hz: float = _ro(15.0, "Frames sent per second, 1/s.", low=1.0, high=30.0)
    rate_tau_s: float = _ro(
        0.5, "Smoothing time constant of the taxel rates, s.", low=0.05, high=10.0
    )
    dead_after_s: float = _ro(
        10.0,
        "A taxel silent this long while its finger fires is marked dead, s.",
        low=1.0,
        high=3600.0,
    )
    saturation_hz: float = _ro(
        3800.0,
        "A taxel at or above this rate is marked saturated, events/s.",
        low=1.0,
        high=100000.0,
    )
    top_rate_hz: float = _ro(
        4000.0, "Rate at the top of the colour scale, events/s.", low=1.0, high=100000.0
    )
    rod_length_m: float = _ro(
        0.3,
        "Rod drawn under a tap estimate when no ground truth gives its length, m.",
        low=0.01,
        high=5.0,
    )
    match_tolerance_ms: float = _ro(
        300.0,
        "Largest onset difference between an estimate and its trial's truth, ms.",
        low=1.0,
        high=10000.0,
    )
    nice: int = _ro(
        10,
        "CPU niceness the view's process takes at start (0: unchanged), so perception's "
        "nodes come first on a busy machine; the graphs run the view in a process of its own.",
        low=0,
        high=19,
    )


class FoxgloveViewNode(Node):
    """Draws the graph's topics at display rate and serves them to Foxglove over WebSocket."""

    PARAMETERS = ViewParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "foxglove_view"), **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        p = declare_all(self, ViewParameters)
        if p.nice:  # before the server's threads start: they inherit it
            _lower_priority(p.nice)
        self.sensor = p.sensor
        host, port, rate_hz = p.host, p.port, p.display_rate_hz
        self.top_hz = p.top_rate_hz
        self.rod_m = p.rod_length_m
        self.tolerance_ns = int(p.match_tolerance_ms * 1e6)
        self.taxels = TaxelActivity(p.rate_tau_s, p.dead_after_s, p.saturation_hz)
        self.electrodes = ElectrodeActivity()
        self.pac = PacTrace()
        self.pacer = DisplayPacer(rate_hz)
        self.truths: deque = deque(maxlen=200)
        self.statuses: dict[str, tuple[int, str]] = {}
        self._window: Image | None = None
        self._estimates: dict[int, tuple[Image, dict[str, Any]]] = {}
        """Estimates waiting for the next frame, by onset: a contact's final replaces its
        provisional ones, and each contact is drawn even when several wait for one frame."""
        self._final_onsets: deque[int] = deque(maxlen=MAX_PENDING_ESTIMATES)
        """Onsets of the latest final estimates: a provisional one for them comes too late."""
        self._diag_dirty = False
        self.feed = SensorFeed(self.sensor, self.taxels, self.electrodes, self.pac)

        # Every channel before the server listens: one added while a client is connected can
        # be refused to it with "Unknown channel ID" (foxglove-sdk 0.30).
        self.context_fg = foxglove.Context()
        self.images = {t: RawImageChannel(t, context=self.context_fg) for t in ch.IMAGES}
        own = set(ch.view_channels(self.sensor))
        self.json = {
            t: Channel(
                t,
                schema=Schema(name=name, encoding="jsonschema", data=json.dumps(schema).encode()),
                message_encoding="json",
                context=self.context_fg,
            )
            for t, (name, schema) in ch.JSON_SCHEMAS.items()
            if t in own
        }
        store = make_typestore()
        self.passed = {}
        for topic, type_name in ch.PASSED_THROUGH.items():
            text, _ = store.generate_msgdef(type_name, ros_version=2)
            self.passed[topic] = Channel(
                topic,
                schema=Schema(name=type_name, encoding="ros2msg", data=text.encode()),
                message_encoding="cdr",
                context=self.context_fg,
            )
        try:
            self.server = foxglove.start_server(
                name=f"ext_sense {self.get_name()}", host=host, port=port, context=self.context_fg
            )
        except RuntimeError as err:  # foxglove-sdk's error: the address is taken or not ours
            raise ValueError(
                f"foxglove_view cannot listen on ws://{host}:{port}: {err}. Another program "
                f"holds the port, or the host is not an address of this machine: choose another "
                f"with view_port:=N (0: any free port) or view_host:=ADDRESS."
            ) from err
        for rel, (topic, msg_type, qos) in PASSED.items():
            self.create_subscription(
                msg_type, rel, self.guard(self._passer(topic, msg_type)), qos, raw=True
            )
        self.packets_subscription = None
        """The packet subscription, there only while a client watches a sensor channel."""
        self.sensor_channels = [
            self.images[ch.TAXELS],
            self.json[ch.RATES if self.sensor == "nuskin" else ch.PAC],
        ]
        self.all_channels = [*self.images.values(), *self.json.values(), *self.passed.values()]
        self.create_timer(1.0 / rate_hz, self.guard(self._on_tick))
        self.updater = Updater(hardware_id=f"ws://{host}:{self.server.port}")
        self.updater.add_check("view", self._check)
        self.guard.attach(self.updater)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)
        self.get_logger().info(
            f"Foxglove view on ws://{host}:{self.server.port} "
            f"(open the layout {ch.NS} panels; docs/view.md)"
        )

    @property
    def port(self) -> int:
        """The server's TCP port (the one chosen when ``port`` is 0)."""
        return int(self.server.port)

    # -- input: cheap, at the stream's rate ------------------------------------------------

    def _on_packet(self, msg: SensorPacket) -> None:
        bad = self.feed.counters.bad_packets
        self.feed.on_packet(msg)
        if self.feed.counters.bad_packets > bad:
            self.get_logger().warning(
                f"dropped a packet: {self.feed.last_packet_error}", throttle_duration_sec=5.0
            )

    def _passer(self, topic: str, msg_type: type) -> Any:
        channel = self.passed[topic]

        def on_raw(data: bytes) -> None:
            channel.log(bytes(data), log_time=self._now_ns())
            msg = deserialize_message(data, msg_type)
            if msg_type is ContactGroundTruth:
                self.truths.append(truth_of(msg))
            elif msg_type is ContactWindow:
                self._on_window(msg)
            elif msg_type is ContactEstimate:
                self._on_estimate(msg)
            else:
                self._on_diagnostics(msg)

        return on_raw

    def _on_window(self, msg: ContactWindow) -> None:
        if not self.images[ch.WINDOW].has_sinks():
            return
        shape = tuple(int(x) for x in msg.shape)
        data = np.asarray(msg.data, dtype=np.float32).reshape(shape)
        self._window = raster_image(
            data,
            int(msg.pre_onset_ns),
            int(msg.sample_period_ns),
            provisional=bool(msg.provisional),
            finger_rows=40 if self.sensor == "nuskin" else 0,
        )

    def _on_estimate(self, msg: ContactEstimate) -> None:
        est = estimate_of(msg)
        # the two estimate topics are two subscriptions, taken in either order when both are
        # ready: a contact's provisional estimate handled after its final one is stale
        if est.provisional and est.onset_ns in self._final_onsets:
            return
        if not est.provisional:
            self._final_onsets.append(est.onset_ns)
        truth = matching_truth(est, self.truths, self.tolerance_ns)
        self._estimates[est.onset_ns] = (
            estimate_image(est, truth, self.rod_m),
            estimate_message(est, truth),
        )
        while len(self._estimates) > MAX_PENDING_ESTIMATES:  # unwatched: keep the newest
            del self._estimates[min(self._estimates)]

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            raw = status.level  # a ``byte`` field: bytes of length 1 in rclpy
            level = raw[0] if isinstance(raw, (bytes, bytearray)) else int(raw)
            self.statuses[status.name] = (int(level), str(status.message))
        self._diag_dirty = True

    # -- output: at display rate -----------------------------------------------------------

    def _follow_clients(self) -> bool:
        """Read packets only while a client watches a sensor channel; whether any client is on."""
        watched = any(c.has_sinks() for c in self.sensor_channels)
        if watched and self.packets_subscription is None:
            self.packets_subscription = self.create_subscription(
                SensorPacket, "packets", self.guard(self._on_packet), SENSOR_STREAM_QOS
            )
        elif not watched and self.packets_subscription is not None:
            self.destroy_subscription(self.packets_subscription)
            self.packets_subscription = None
        return watched or any(c.has_sinks() for c in self.all_channels)

    def _on_tick(self) -> None:
        if not self._follow_clients():
            return
        now = time.monotonic_ns()
        if not self.pacer.ready(now):
            return
        stamp = self._now_ns()
        if self.sensor == "nuskin":
            rates = self.taxels.update(now)
            if self.images[ch.TAXELS].has_sinks():
                grid = nuskin_grid(
                    rates, self.taxels.dead(now), self.taxels.saturated(), top_hz=self.top_hz
                )
                self._send_image(ch.TAXELS, grid, stamp)
            self.json[ch.RATES].log(
                rates_message(self.taxels.finger_rates(), self.taxels.rejected), log_time=stamp
            )
        else:
            if self.images[ch.TAXELS].has_sinks():
                self._send_image(ch.TAXELS, biotac_grid(self.electrodes), stamp)
            if self.json[ch.PAC].has_sinks():
                self.json[ch.PAC].log(self.pac.message(), log_time=stamp)
        if self._window is not None:
            self._send_image(ch.WINDOW, self._window, stamp)
            self._window = None
        for k, onset in enumerate(sorted(self._estimates)):  # a ns apart: one log time each
            image, numbers = self._estimates[onset]
            self._send_image(ch.ESTIMATE, image, stamp + k)
            self.json[ch.ESTIMATE_INFO].log(numbers, log_time=stamp + k)
        self._estimates.clear()
        if self._diag_dirty:
            self.json[ch.DIAGNOSTICS].log(diagnostics_message(self.statuses), log_time=stamp)
            self._diag_dirty = False

    def _send_image(self, topic: str, img: Image, stamp_ns: int) -> None:
        sec, nsec = split_ns(stamp_ns)
        height, width = img.shape[:2]
        self.images[topic].log(
            RawImage(
                timestamp=Timestamp(sec, nsec),
                frame_id="extsense_view",
                width=width,
                height=height,
                encoding="rgb8",
                step=width * 3,
                data=img.tobytes(),
            ),
            log_time=stamp_ns,
        )

    def _now_ns(self) -> int:
        return int(self.get_clock().now().nanoseconds)

    def _check(self) -> tuple[Level, str, dict[str, object]]:
        level, why, fed = self.feed.status()
        c = self.feed.counters
        values = {
            "frames": self.pacer.frames,
            "events_seen": c.events + c.frames,
            "rejected_events": self.taxels.rejected,
            "port": self.port,
            "reading_packets": self.packets_subscription is not None,
            **fed,
        }
        return level, "serving" if level == Level.OK else why, values

    def destroy_node(self) -> None:
        """Stop the WebSocket server with the node (clients see the connection close)."""
        try:
            server = getattr(self, "server", None)  # absent when it could not start
            if server is not None:
                server.stop()
        finally:
            super().destroy_node()


def _lower_priority(nice: int) -> None:
    """Give every thread of this process at least niceness ``nice`` (later ones inherit it).

    Where the OS refuses, the view runs as it was.
    """
    try:
        threads = [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        threads = [0]
    for tid in threads:
        try:
            os.setpriority(os.PRIO_PROCESS, tid, max(os.getpriority(os.PRIO_PROCESS, tid), nice))
        except OSError:
            continue


def main(args: list[str] | None = None) -> int:
    """Run the node (``ros2 run ext_sense foxglove_view``)."""
    return run_node(FoxgloveViewNode, args)
