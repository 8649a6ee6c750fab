"""``contact_window`` node: sensor stream in, contact windows (provisional and final) out.

Subscribes ``packets`` (``SensorPacket``, the driver's raw bytes: ``input`` packets, the default)
and decodes them with the drivers' library decoder, or the decoded ``events``
(``TaxelEventBatch``, NUSkin) or ``frames`` (``BioTacFrame``) (``input`` decoded: bags recorded
before packets); and, for food, ``motion_start`` (``ContactGroundTruth``; its stamp is the arm's
motion start). Packets are the default so that the live node and the offline replay of a bag
decode the same bytes with the same code: identical windows (docs/runtime.md, Raw packets). A
``seq`` gap is lost input (counted, on ``/diagnostics``, the windows across it degraded); a
packet that cannot be read is counted and dropped with the reason logged. Publishes
``window`` (``ContactWindow``): provisional windows at the configured shorter post-onset times,
then the final one. The windowing itself is
:class:`~ext_sense_perception.online.stage.WindowStage`; the window and the anytime times come
from the task profile (:mod:`ext_sense_perception.profiles`).

Windows close on data: the batch whose events (or, empty, whose stamp) pass ``onset + post``
cuts the window in the subscription callback. A NUSkin window must also close when no event
follows it, so one one-shot deadline timer is armed for the moment the stream clock (the newest
data's stream time plus the wall time since it arrived, minus ``advance_slack_ms`` for events
still in flight, and with packets ``packet_wait_ms`` for the driver's next packet: its empty
"nothing read" packets close a window on data when the sensor is quiet) reaches the next
pending window's end, or the liveness status would change,
or ``stream_timeout_ms`` passes with no data (the pending windows are then flushed, marked
truncated); see :mod:`ext_sense_perception.online.deadline`. With nothing pending the timer is
off: an idle node does not wake (a 1 ms polling timer here cost 12 % of a core while idle).

Liveness (:mod:`ext_sense_perception.online.liveness`): the node knows the rate its input
should have (``expected_rate_hz``) and when it must arrive (BioTac: always; NUSkin: while a
contact detected in the signal is open; a food window, opened by the arm's motion start, may
be silent for seconds). Silence then beyond ``stall_warn_ms`` is a stall: WARN on ``/diagnostics``
(status ``liveness``, naming the silent topic), ERROR beyond ``stall_error_ms``, published at
once (not at the next 1 Hz tick), cleared when data returns. Every window overlapping a stall
or input lost on the way (a ``seq`` gap, or the driver's word count ran ahead of the events
received) goes out with ``degraded`` and the reason, as does a window reaching back before the
first input the node got (it joined mid-stream: the onset found may be the tail of a contact
already under way; the windower's rule, offline too). Degraded is decided on whether the
window's data is complete, not on lateness: packets later than ``late_ms`` are counted
(``late_packets``), but a window closes on data past its end and the stream is in order, so a
late packet inside it is in it; the one window a late packet can miss is one the clock closed
first (``windows_missed_late_data``, WARN on the console). Contacts are counted, not gaps: a
final window across a fault is a degraded contact (``contacts_degraded``), lost input no window
came to cover a lost one (``contacts_lost``, see :mod:`.online.liveness`). QoS deadline
events are not used for this: a subscription's deadline is incompatible with the drivers'
publishers, which offer none, and it would cut the stream instead of reporting it.

Stuck taxels (NUSkin, :mod:`ext_sense_perception.online.stuck_taxels`): a taxel firing at
``stuck_rate_hz`` or more for longer than ``stuck_after_ms`` (longer than any contact lasts) is
masked from onset detection until it quiets, and reported at once: WARN on ``/diagnostics``
(status ``taxels``, naming the taxel ids) and on the console; windows cut meanwhile go out
degraded. An onset needs events from ``activity_min_taxels`` taxels, so one taxel at its ceiling
never opens a contact, even before it is masked.
"""

from __future__ import annotations

import array
import time
from typing import Any

from rclpy.node import Node

from ext_sense_msgs.msg import (
    BioTacFrame,
    ContactGroundTruth,
    ContactWindow,
    SensorPacket,
    TaxelEventBatch,
)
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.nodes.window_parameters import (
    declare_input_liveness,
    declare_window_config,
)
from ext_sense_perception.online.deadline import next_wake_ns, stall_change_ns
from ext_sense_perception.online.messages import window_fields
from ext_sense_perception.online.stage import WindowStage
from ext_sense_perception.online.windowers import EventWindower
from ext_sense_runtime import intra_process
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, RateTask, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.enums import Sensor, Task
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare
from ext_sense_runtime.qos import COMMAND_QOS, SENSOR_STREAM_QOS, WINDOW_QOS
from ext_sense_runtime.qos_events import QosEventCounter
from ext_sense_runtime.stamps import MS, fill_stamp, stamp_to_ns

MIN_WAIT_NS = 50_000
"""Shortest deadline wait: a deadline already passed fires at once, without a zero period."""


class ContactWindowNode(Node):
    """Cuts contact windows from the NUSkin event stream or the BioTac frames."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "contact_window"), **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        config, sensor_ids, profile_source = declare_window_config(self)
        self.slack_ns = int(
            declare(
                self,
                "advance_slack_ms",
                0.5,
                "Allowance for events still in flight when the timer closes a window, ms.",
                low=0.0,
                high=1000.0,
            )
            * MS
        )
        self.timeout_ns = int(
            declare(
                self,
                "stream_timeout_ms",
                500.0,
                "No data for this long: flush pending windows as truncated, ms.",
                low=10.0,
                high=60000.0,
            )
            * MS
        )
        try:
            self.stage = WindowStage(config, sensor_ids)
        except PerceptionError as err:
            raise ValueError(f"contact_window: {err}") from err
        self.config = config
        self.input = declare(
            self,
            "input",
            "packets",
            "What to cut windows from: packets (the driver's raw SensorPacket on packets, decoded "
            "here: live and offline see the same bytes) or decoded (TaxelEventBatch on events, "
            "BioTacFrame on frames: bags recorded before packets).",
            read_only=True,
        )
        if self.input not in ("packets", "decoded"):
            raise ValueError(
                f"The 'input' parameter must be one of ['packets', 'decoded']. "
                f"Got {self.input!r} instead."
            )
        decoded_topic = "events" if config.sensor is Sensor.NUSKIN else "frames"
        input_topic = self.resolve_topic_name(
            "packets" if self.input == "packets" else decoded_topic
        )
        self.liveness = declare_input_liveness(self, config, input_topic)
        if self.input == "packets":
            # the NUSkin driver sends a packet every batch period (1 ms) for quiet_packets_fast_s
            # after its last bytes, then every quiet_packets_period_s (5 ms), while the sensor
            # is quiet ("nothing read"): windows close on those, as a replay of the packets
            # does; the clock closes one only when they stop coming (a stalled stream)
            self.slack_ns += round(
                declare(
                    self,
                    "packet_wait_ms",
                    20.0,
                    "Longest wait past a window's end for the driver's next packet (bytes, or its "
                    "empty 'nothing read' packet, every quiet_packets_period_s while the sensor is "
                    "quiet) "
                    "before the window is closed on this node's clock, ms: added to "
                    "advance_slack_ms when reading packets. A window the clock closes may miss "
                    "a late packet a replay of the recording would put in it.",
                    low=0.0,
                    high=1000.0,
                    read_only=True,
                )
                * MS
            )
        self._first_packet = True
        self._stall_state = (False, False)
        self._wall_at_data: int | None = None
        self.published = 0
        self.provisional_published = 0
        self.motion_starts = 0

        self.qos_events = QosEventCounter()
        # in a node group, windows go straight to contact_inference, packets come straight from
        # the driver (intra_process); a process of its own publishes and subscribes as rclpy does
        self.pub = intra_process.create_publisher(
            self, ContactWindow, "window", WINDOW_QOS, event_callbacks=self.qos_events.publisher()
        )
        if self.input == "packets":
            self.input_subscription = intra_process.create_subscription(
                self,
                SensorPacket,
                "packets",
                self.guard(self._on_packet),
                SENSOR_STREAM_QOS,
                event_callbacks=self.qos_events.subscription(),
            )
        elif config.sensor is Sensor.NUSKIN:
            self.input_subscription = intra_process.create_subscription(
                self,
                TaxelEventBatch,
                "events",
                self.guard(self._on_events),
                SENSOR_STREAM_QOS,
                event_callbacks=self.qos_events.subscription(),
            )
        else:
            self.input_subscription = intra_process.create_subscription(
                self,
                BioTacFrame,
                "frames",
                self.guard(self._on_frame),
                SENSOR_STREAM_QOS,
                event_callbacks=self.qos_events.subscription(),
            )
        if config.external_onsets:
            self.create_subscription(
                ContactGroundTruth, "motion_start", self.guard(self._on_motion_start), COMMAND_QOS
            )
        # one-shot, re-armed by _arm(); the period given here is replaced before each start
        self._deadline = self.create_timer(1.0, self.guard(self._on_deadline), autostart=False)
        self._armed_ns: int | None = None
        self.wakeups = 0
        self.closed_by_clock = 0
        self._clock_closed_end_ns = 0
        self.windows_missed_late_data = 0
        """Windows the clock closed before a late packet with bytes inside them came."""

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
            self.updater.add_check("taxels", self._check_taxels)
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

    def _on_events(self, msg: TaxelEventBatch) -> None:
        self._arrived(msg)
        lost = self.liveness.words_lost
        self.liveness.on_counts(
            stamp_to_ns(msg.header.stamp), msg.words_total, msg.bad_taxel_words, len(msg.taxel)
        )
        if self.liveness.words_lost > lost:
            self.get_logger().warning(
                f"lost input: {self.liveness.words_lost - lost} words the driver decoded never "
                f"reached this node ({self.liveness.words_lost} so far; {self._contacts_said()})",
                throttle_duration_sec=1.0,
            )
        self._publish(self.stage.on_events(msg))
        self._report_stuck_change()
        self._arm(earlier_only=True)

    def _on_packet(self, msg: SensorPacket) -> None:
        if self._first_packet:
            self._first_packet = False
            late = f": joined late, {msg.seq} earlier packets were not seen" if msg.seq else ""
            self.get_logger().info(
                f"first packet on {self.liveness.stream}: seq {msg.seq}, {msg.encoding}{late}"
            )
        previous_ns = self.liveness.last_stamp_ns
        self._arrived(msg)
        if msg.data and stamp_to_ns(msg.header.stamp) < self._clock_closed_end_ns:
            self._clock_closed_end_ns = 0  # once per closing
            self.windows_missed_late_data += 1
            self.get_logger().warning(
                "a late packet held bytes read before the end of a window the clock had closed: "
                f"its estimate went out without them ({self.windows_missed_late_data} so far; "
                "packet_wait_ms sets how long a window waits)",
                throttle_duration_sec=1.0,
            )
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

    def _on_frame(self, msg: BioTacFrame) -> None:
        self._arrived(msg)
        self._publish(self.stage.on_frame(msg))
        self._arm(earlier_only=True)

    def _arrived(self, msg: TaxelEventBatch | BioTacFrame | SensorPacket) -> None:
        self.rate.tick()
        self._wall_at_data = time.monotonic_ns()
        lost = self.liveness.contacts_lost
        self.liveness.on_message(stamp_to_ns(msg.header.stamp), time.time_ns())
        if self.liveness.contacts_lost > lost:  # a gap no window covered, now settled
            self.get_logger().warning(
                f"lost input may have held a whole contact: no window covered it "
                f"({self._contacts_said()})"
            )
        self._report_stall_change()

    def _streaming(self) -> bool:
        """Whether input must be arriving now: BioTac always, NUSkin during a tap or grasp.

        A NUSkin window opened by an external onset (food: the arm's motion start) is not a
        contact: the fork moves seconds in it without touching anything, and silence is normal.
        """
        if self.config.sensor is Sensor.BIOTAC:
            return True
        return bool(self.stage.windower.pending_onsets) and not self.config.external_onsets

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
        level, message, _ = self._check_taxels()
        if level is Level.OK:
            self.get_logger().info("no taxel stuck any more: every taxel detects onsets again")
        else:
            self.get_logger().warning(message)
        self.diagnostics.publish()

    def _check_taxels(self) -> tuple[Level, str, dict[str, object]]:
        """Taxels stuck at their ceiling (NUSkin): WARN naming them while any is."""
        if self.event_windower is None:  # not added for BioTac
            return Level.OK, "no taxels", {}
        return self.event_windower.stuck_status()

    def _on_motion_start(self, msg: ContactGroundTruth) -> None:
        if self.stage.on_motion_start(stamp_to_ns(msg.header.stamp)):
            self.motion_starts += 1
        self._arm(earlier_only=True)

    def _on_deadline(self) -> None:
        """The stream went quiet past a deadline: stall check, clock-closed windows, timeout.

        The timer is periodic: it ends by re-arming it for the next deadline or cancelling it.
        """
        self.wakeups += 1
        last = self.stage.last_data_ns
        if last is None or self._wall_at_data is None:
            self._arm()
            return
        self.liveness.update(self._streaming())
        self._report_stall_change()
        idle = time.monotonic_ns() - self._wall_at_data
        if idle >= self.timeout_ns:
            if self.stage.windower.pending_onsets:
                self._publish(self.stage.flush())
        elif self.config.sensor is Sensor.NUSKIN:
            closed = self.stage.advance(last + idle - self.slack_ns)
            self.closed_by_clock += len(closed)
            for win in closed:
                end = win.onset_ns + win.post_onset_ns
                self._clock_closed_end_ns = max(self._clock_closed_end_ns, end)
            if closed and self.input == "packets":  # no packet, not even "nothing read", came
                self.get_logger().info(
                    f"the clock closed {len(closed)} window(s): no packet for {idle / MS:.1f} ms "
                    "(a replay of the packets may put a late one in them)",
                    throttle_duration_sec=1.0,
                )
            self._publish(closed)
        self._arm()

    def _arm(self, earlier_only: bool = False) -> None:
        """Arm the deadline timer for the next moment a quiet stream needs the node, or stop it.

        Args:
            earlier_only: Keep an armed deadline unless the new one is earlier (called per
                message: data only moves the stall and timeout deadlines later, and a deadline
                that fires early re-arms itself for the rest, so most messages cost no timer
                call).
        """
        streaming = self._streaming()
        wake = next_wake_ns(
            data_wall_ns=self._wall_at_data,
            data_stream_ns=self.stage.last_data_ns,
            due_ns=self.stage.next_due_ns() if self.config.sensor is Sensor.NUSKIN else None,
            pending=bool(self.stage.windower.pending_onsets),
            slack_ns=self.slack_ns,
            timeout_ns=self.timeout_ns,
            stall_ns=stall_change_ns(self.liveness, streaming),
        )
        if wake is None:
            if self._armed_ns is not None:
                self._deadline.cancel()
                self._armed_ns = None
            return
        if earlier_only and self._armed_ns is not None and self._armed_ns <= wake:
            return
        self._deadline.timer_period_ns = max(wake - time.monotonic_ns(), MIN_WAIT_NS)
        self._deadline.reset()
        self._armed_ns = wake

    def _check_windows(self) -> tuple[Level, str, dict[str, object]]:
        wc = self.stage.windower.counters
        sc = self.stage.counters
        values = {
            "windows_final": wc.windows,
            "windows_provisional": wc.provisional_windows,
            "windows_truncated": wc.truncated_windows,
            "windows_joined_mid_stream": wc.joined_mid_stream_windows,
            "windows_closed_by_clock": self.closed_by_clock,
            "windows_missed_late_data": self.windows_missed_late_data,
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
            "input": self.input,
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
