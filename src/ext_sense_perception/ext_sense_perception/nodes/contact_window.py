"""``contact_window`` node: sensor packets in, contact windows (provisional and final) out.

Subscribes ``packets`` (``SensorPacket``) and, for food, ``motion_start`` (``ContactGroundTruth``
at the arm's motion start); publishes ``window``. Windows are cut by
:class:`~ext_sense_perception.online.stage.WindowStage` on stream time only, so a replay of the
packets cuts exactly these windows; the node's one timer is for liveness. Stalls
(``stall_warn_ms`` WARN, ``stall_error_ms`` ERROR) and lost input (``seq`` gaps) are published on
``/diagnostics`` at once and degrade the windows across them; late packets are only counted (the
drivers offer no QoS deadlines). Stuck taxels are masked from onset detection, reported at once
(``taxels``) and degrade the windows cut meanwhile.
"""

from __future__ import annotations

import array
import time
from typing import Any

from rclpy.node import Node

from ext_sense_msgs.msg import ContactGroundTruth, ContactWindow, SensorPacket
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.nodes.window_parameters import (
    WindowParameters,
    input_liveness,
    window_config,
)
from ext_sense_perception.online.messages import window_fields
from ext_sense_perception.online.stage import WindowStage
from ext_sense_perception.online.windowers import EventWindower
from ext_sense_runtime import intra_process
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, RateTask, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.enums import Sensor, Task
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all
from ext_sense_runtime.qos import COMMAND_QOS, SENSOR_STREAM_QOS, WINDOW_QOS
from ext_sense_runtime.qos_events import QosEventCounter
from ext_sense_runtime.stamps import MS, fill_stamp, stamp_to_ns

MIN_WAIT_NS = 50_000
"""Shortest timer wait: a moment already passed fires at once, without a zero period."""


class ContactWindowNode(Node):
    """Cuts contact windows from the sensor's packets (NUSkin events or BioTac frames)."""

    PARAMETERS = WindowParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "contact_window"), **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        p = declare_all(self, WindowParameters)
        config, sensor_ids, profile_source = window_config(p, self.get_logger())
        try:
            self.stage = WindowStage(config, sensor_ids)
        except PerceptionError as err:
            raise ValueError(f"contact_window: {err}") from err
        self.config = config
        self.liveness = input_liveness(p, config, self.resolve_topic_name("packets"))
        self._first_packet = True
        self._stall_state = (False, False)
        self.published = 0
        self.provisional_published = 0
        self.motion_starts = 0

        self.qos_events = QosEventCounter()
        # in a node group, windows go straight to contact_inference, packets come straight from
        # the driver (intra_process); a process of its own publishes and subscribes as rclpy does
        self.pub = intra_process.create_publisher(
            self, ContactWindow, "window", WINDOW_QOS, event_callbacks=self.qos_events.publisher()
        )
        self.input_subscription = intra_process.create_subscription(
            self,
            SensorPacket,
            "packets",
            self.guard(self._on_packet),
            SENSOR_STREAM_QOS,
            event_callbacks=self.qos_events.subscription(),
        )
        if config.external_onsets:
            self.create_subscription(
                ContactGroundTruth, "motion_start", self.guard(self._on_motion_start), COMMAND_QOS
            )
        # one-shot, re-armed by _arm(); the period given here is replaced before each start
        self._stall_timer = self.create_timer(1.0, self.guard(self._on_silence), autostart=False)
        self._armed_ns: int | None = None
        self._stream_going = False
        self.wakeups = 0

        self.updater = Updater(hardware_id=f"{config.task.label}/{config.sensor.label}")
        self.rate = self.updater.add(
            RateTask("input", min_hz=0.0, max_hz=1e6, clock=time.monotonic_ns, unit="msgs_per_s")
        )
        self.updater.add_check("windows", self._check_windows)
        self.updater.add_check("liveness", self.liveness.check)
        self.event_windower = (
            self.stage.windower if isinstance(self.stage.windower, EventWindower) else None
        )
        if self.event_windower is not None:
            self.updater.add_check("taxels", self.event_windower.stuck_status)
        self.guard.attach(self.updater)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)
        self.get_logger().info(
            f"cutting {config.task.label} windows from {config.sensor.label}: "
            f"{config.pre_ns / MS:g} ms before to {config.post_ns / MS:g} ms after onset "
            f"(profile of {profile_source})"
        )

    def _publish(self, windows: list) -> None:
        for win in windows:
            end = win.onset_ns + win.post_onset_ns
            reason = self.liveness.fault_in(win.start_ns, end, final=not win.provisional)
            if reason:  # beside the windower's own reason (a window begun before the first input)
                both = "; ".join(r for r in (win.degraded_reason, reason) if r)
                win = win._replace(degraded=True, degraded_reason=both)
            f = window_fields(win)
            msg = ContactWindow()
            fill_stamp(msg.header.stamp, f["stamp_ns"])
            msg.header.frame_id = self.config.sensor.label
            msg.task, msg.sensor = f["task"], f["sensor"]
            msg.pre_onset_ns, msg.post_onset_ns = f["pre_onset_ns"], f["post_onset_ns"]
            msg.sample_period_ns = f["sample_period_ns"]
            msg.shape = f["shape"].tolist()
            msg.channels = array.array("H", f["channels"].tobytes())
            msg.data = array.array("f", f["data"].tobytes())  # ~100x faster than from NumPy
            msg.provisional = f["provisional"]
            msg.truncated = f["truncated"]
            msg.degraded, msg.degraded_reason = f["degraded"], f["degraded_reason"]
            self.pub.publish(msg)
            self.published += 1
            self.provisional_published += int(win.provisional)

    def _on_packet(self, msg: SensorPacket) -> None:
        if self._first_packet:
            self._first_packet = False
            late = f": joined late, {msg.seq} earlier packets were not seen" if msg.seq else ""
            self.get_logger().info(
                f"first packet on {self.liveness.stream}: seq {msg.seq}, {msg.encoding}{late}"
            )
        previous_ns = self.liveness.last_stamp_ns
        self._stream_going = not msg.end_of_stream
        self.rate.tick()
        lost = self.liveness.contacts_lost
        self.liveness.on_message(stamp_to_ns(msg.header.stamp), time.time_ns())
        if self.liveness.contacts_lost > lost:  # a gap no window covered, now settled
            self.get_logger().warning(
                f"lost input may have held a whole contact: no window covered it "
                f"({self._contacts_said()})"
            )
        self._report_stall_change()
        bad = self.stage.counters.bad_packets
        windows = self.stage.on_packet(msg)
        if self.stage.counters.bad_packets > bad:
            self.get_logger().error(
                f"dropped a packet ({self.stage.counters.bad_packets} so far): "
                f"{self.stage.last_packet_error}",
                throttle_duration_sec=1.0,
            )
        lost = self.stage.last_lost_packets
        if lost:
            stamp = stamp_to_ns(msg.header.stamp)
            self.liveness.on_lost_packets(previous_ns or stamp, stamp, lost)
            self.get_logger().warning(
                f"lost input: {lost} packet(s) missing before seq {msg.seq} "
                f"({self.liveness.packets_lost} so far; {self._contacts_said()})",
                throttle_duration_sec=1.0,
            )
            self.diagnostics.publish()
        self._publish(windows)
        self._report_stuck_change()
        self._arm(earlier_only=True)

    def _contacts_said(self) -> str:
        """The contacts faults cost so far: lost (no window came) and degraded (windowed)."""
        live = self.liveness
        return f"{live.contacts_lost} contact(s) lost, {live.contacts_degraded} degraded"

    def _streaming(self) -> bool:
        """Whether input must be arriving now: BioTac always, NUSkin until ``end_of_stream``."""
        return self.config.sensor is Sensor.BIOTAC or self._stream_going

    def _report_stall_change(self) -> None:
        """Publish diagnostics at once when a stall starts, turns ERROR, or ends."""
        silent = self.liveness.silence_ns() if self.liveness.stalled else 0
        state = (self.liveness.stalled, silent > self.liveness.error_ns)
        if state != self._stall_state:
            self._stall_state = state
            self.diagnostics.publish()

    def _report_stuck_change(self) -> None:
        """Log and publish diagnostics at once when a taxel turns stuck or quiets again."""
        if self.event_windower is None or not self.event_windower.stuck_changed:
            return
        level, message, _ = self.event_windower.stuck_status()
        if level is Level.OK:
            self.get_logger().info("no taxel stuck any more: every taxel detects onsets again")
        else:
            self.get_logger().warning(message)
        self.diagnostics.publish()

    def _on_motion_start(self, msg: ContactGroundTruth) -> None:
        if self.stage.on_motion_start(stamp_to_ns(msg.header.stamp)):
            self.motion_starts += 1
        self._arm(earlier_only=True)

    def _on_silence(self) -> None:
        """The input went quiet past a liveness threshold: report the stall, re-arm or stop."""
        self.wakeups += 1
        self.liveness.update(self._streaming())
        self._report_stall_change()
        self._arm()

    def _arm(self, earlier_only: bool = False) -> None:
        """Arm the timer for the next moment the liveness status may change, or stop it.

        ``earlier_only`` (per message) keeps an armed timer unless the moment is earlier: data only
        moves it later, and an early timer re-arms itself.
        """
        wake = self.liveness.next_change_ns(self._streaming())
        if wake is None:
            if self._armed_ns is not None:
                self._stall_timer.cancel()
                self._armed_ns = None
            return
        if earlier_only and self._armed_ns is not None and self._armed_ns <= wake:
            return
        self._stall_timer.timer_period_ns = max(wake - time.monotonic_ns(), MIN_WAIT_NS)
        self._stall_timer.reset()
        self._armed_ns = wake

    def _check_windows(self) -> tuple[Level, str, dict[str, object]]:
        wc = self.stage.windower.counters
        sc = self.stage.counters
        values = {
            "windows_final": wc.windows,
            "windows_provisional": wc.provisional_windows,
            "windows_truncated": wc.truncated_windows,
            "windows_joined_mid_stream": wc.joined_mid_stream_windows,
            "onsets": wc.onsets,
            "motion_starts": self.motion_starts,
            "events_total": sc.events,
            "frames_total": sc.frames,
            "dropped_bad_messages": sc.bad_messages,
            "dropped_bad_taxel_events": wc.bad_taxel_events,
            "late_events": wc.late_events,
            "frames_unjoined": sc.frames_unjoined,
            "frames_wrong_sensor": sc.frames_wrong_sensor,
            "pending_onsets": len(self.stage.windower.pending_onsets),
            **self.qos_events.as_values(),
            **intra_process.delivery_values(self.input_subscription, "input"),
        }
        if self.stage.decoder is not None:
            values.update({f"packet_{k}": v for k, v in self.stage.decoder.diagnostics().items()})
            values["dropped_bad_packets"] = sc.bad_packets
        if sc.bad_packets:
            return Level.WARN, f"dropped bad packets: {self.stage.last_packet_error}", values
        if sc.bad_messages or self.qos_events.counts["incompatible_qos"]:
            return Level.WARN, "dropped malformed input", values
        if self.config.task is Task.FOOD_IDENTIFICATION and not self.motion_starts:
            return Level.OK, "waiting for motion_start", values
        return Level.OK, "ok", values


def main(args: list[str] | None = None) -> int:
    """Run the node (``ros2 run ext_sense_perception contact_window``)."""
    return run_node(ContactWindowNode, args)
