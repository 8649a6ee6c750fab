"""``contact_window`` node: sensor stream in, contact windows (provisional and final) out.

Subscribes ``events`` (``TaxelEventBatch``, NUSkin) or ``frames`` (``BioTacFrame``) and, for
food, ``motion_start`` (``ContactGroundTruth``; its stamp is the arm's motion start). Publishes
``window`` (``ContactWindow``): provisional windows at the configured shorter post-onset times,
then the final one. The windowing itself is
:class:`~ext_sense_perception.online.stage.WindowStage`; the window and the anytime times come
from the task profile (:mod:`ext_sense_perception.profiles`).

A NUSkin window must close at ``onset + post`` even when no event follows it, so a timer
advances the stream clock: stream time is the newest event's stamp plus the wall time elapsed
since it arrived, minus ``advance_slack_ms`` for events still in flight. When no data arrives
for ``stream_timeout_ms`` the pending windows are flushed (marked truncated).
"""

from __future__ import annotations

import array
import time
from dataclasses import replace
from typing import Any

from rclpy.node import Node

from ext_sense_msgs.msg import BioTacFrame, ContactGroundTruth, ContactWindow, TaxelEventBatch
from ext_sense_perception.errors import PerceptionError
from ext_sense_perception.online.messages import window_fields
from ext_sense_perception.online.model_card import read_card
from ext_sense_perception.online.model_store import locate_model
from ext_sense_perception.online.stage import WindowStage
from ext_sense_perception.online.window import WindowConfig
from ext_sense_runtime.diagnostics import Level, RateTask, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.enums import Sensor, Task
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare
from ext_sense_runtime.qos import COMMAND_QOS, SENSOR_STREAM_QOS, WINDOW_QOS
from ext_sense_runtime.qos_events import QosEventCounter
from ext_sense_runtime.stamps import MS, US, fill_stamp, stamp_to_ns


class ContactWindowNode(Node):
    """Cuts contact windows from the NUSkin event stream or the BioTac frames."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "contact_window"), **kwargs)
        task = declare(
            self,
            "task",
            "tap_localization",
            "Task: tap_localization, handover_stability or food_identification.",
            read_only=True,
        )
        sensor = declare(self, "sensor", "nuskin", "Sensor: nuskin or biotac.", read_only=True)
        model_path = declare(
            self,
            "model_path",
            "",
            "Model bundle whose card's task profile cuts the windows: a directory, or a model "
            "name looked up as contact_inference does (empty: the task's default model, "
            "<task>_<sensor>); without a readable card, the task's own profile.",
            read_only=True,
        )
        base, profile_source = self._base_config(task, sensor, model_path)
        pre_ms = declare(
            self,
            "pre_onset_ms",
            base.pre_ns / MS,
            "Signal kept before the onset, ms (negative: the window starts after it).",
            low=-60000.0,
            high=10000.0,
            read_only=True,
        )
        post_ms = declare(
            self,
            "post_onset_ms",
            base.post_ns / MS,
            "Signal after the onset in the final window, ms.",
            low=1.0,
            high=60000.0,
            read_only=True,
        )
        sample_us = declare(
            self,
            "sample_us",
            base.profile.sample_ns / US,
            "NUSkin window sample (bin of signed event counts), microseconds.",
            low=10.0,
            high=1_000_000.0,
            read_only=True,
        )
        prov = declare(
            self,
            "anytime_post_ms",
            [p / MS for p in base.anytime_post_ns],
            "Post-onset times of the provisional (anytime) windows, ms; empty: none.",
            read_only=True,
        )
        debounce_ms = declare(
            self,
            "debounce_ms",
            base.debounce_ns / MS,
            "Minimum time between two onsets, ms.",
            low=0.0,
            high=60000.0,
            read_only=True,
        )
        min_events = declare(
            self,
            "activity_min_events",
            base.activity_min_events,
            "NUSkin onset: events within activity_window_ms that mean contact.",
            low=1,
            high=100000,
            read_only=True,
        )
        act_ms = declare(
            self,
            "activity_window_ms",
            base.activity_window_ns / MS,
            "NUSkin onset: sliding window events are counted in, ms.",
            low=0.01,
            high=1000.0,
            read_only=True,
        )
        sensor_ids = declare(
            self,
            "sensor_ids",
            [0],
            "BioTac sensor slots joined into one window (channels in this order).",
            read_only=True,
        )
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
        period_s = (
            declare(
                self,
                "advance_period_ms",
                1.0,
                "Period of the stream-clock timer, ms.",
                low=0.1,
                high=1000.0,
                read_only=True,
            )
            / 1000.0
        )
        try:
            config = replace(
                base.with_profile(
                    pre_ns=round(pre_ms * MS),
                    post_ns=round(post_ms * MS),
                    sample_ns=round(sample_us * US),
                    anytime_post_ns=tuple(round(p * MS) for p in prov),
                    debounce_ns=round(debounce_ms * MS),
                ),
                activity_min_events=int(min_events),
                activity_window_ns=round(act_ms * MS),
            )
            self.stage = WindowStage(config, tuple(int(s) for s in sensor_ids))
        except PerceptionError as err:
            raise ValueError(f"contact_window: {err}") from err
        self.config = config
        self._wall_at_data: int | None = None
        self.published = 0
        self.provisional_published = 0
        self.motion_starts = 0

        self.qos_events = QosEventCounter()
        self.pub = self.create_publisher(
            ContactWindow, "window", WINDOW_QOS, event_callbacks=self.qos_events.publisher()
        )
        if config.sensor is Sensor.NUSKIN:
            self.create_subscription(
                TaxelEventBatch,
                "events",
                self._on_events,
                SENSOR_STREAM_QOS,
                event_callbacks=self.qos_events.subscription(),
            )
        else:
            self.create_subscription(
                BioTacFrame,
                "frames",
                self._on_frame,
                SENSOR_STREAM_QOS,
                event_callbacks=self.qos_events.subscription(),
            )
        if config.external_onsets:
            self.create_subscription(
                ContactGroundTruth, "motion_start", self._on_motion_start, COMMAND_QOS
            )
        self.create_timer(period_s, self._on_timer)

        self.updater = Updater(hardware_id=f"{config.task.label}/{config.sensor.label}")
        self.rate = self.updater.add(
            RateTask("input", min_hz=0.0, max_hz=1e6, clock=time.monotonic_ns, unit="msgs_per_s")
        )
        self.updater.add_check("windows", self._check_windows)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)
        self.get_logger().info(
            f"cutting {config.task.label} windows from {config.sensor.label}: "
            f"{config.pre_ns / MS:g} ms before to {config.post_ns / MS:g} ms after onset "
            f"(profile of {profile_source})"
        )

    def _base_config(self, task: str, sensor: str, model_path: str) -> tuple[WindowConfig, str]:
        """The window configuration of the model's card, else of the task; and where from."""
        try:
            config = WindowConfig.for_task(task, sensor)
        except PerceptionError as err:
            raise ValueError(f"contact_window: {err}") from err
        try:
            path = locate_model(model_path, task, sensor)
            card = read_card(path)
        except PerceptionError as err:
            self.get_logger().info(f"task profile of {task} (no model card: {err})")
            return config, "task"
        if card.task != config.task.label or card.sensor != config.sensor.label:
            self.get_logger().warning(
                f"model card {path} is for {card.task}/{card.sensor}: using the task profile"
            )
            return config, "task"
        return replace(config, profile=card.profile), str(path)

    def _publish(self, windows: list) -> None:
        for win in windows:
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
            self.pub.publish(msg)
            self.published += 1
            self.provisional_published += int(win.provisional)

    def _on_events(self, msg: TaxelEventBatch) -> None:
        self.rate.tick()
        self._wall_at_data = time.monotonic_ns()
        self._publish(self.stage.on_events(msg))

    def _on_frame(self, msg: BioTacFrame) -> None:
        self.rate.tick()
        self._wall_at_data = time.monotonic_ns()
        self._publish(self.stage.on_frame(msg))

    def _on_motion_start(self, msg: ContactGroundTruth) -> None:
        if self.stage.on_motion_start(stamp_to_ns(msg.header.stamp)):
            self.motion_starts += 1

    def _on_timer(self) -> None:
        last = self.stage.last_data_ns
        if last is None or self._wall_at_data is None:
            return
        idle = time.monotonic_ns() - self._wall_at_data
        if idle >= self.timeout_ns:
            if self.stage.windower.pending_onsets:
                self._publish(self.stage.flush())
            return
        if self.config.sensor is Sensor.NUSKIN:
            self._publish(self.stage.advance(last + idle - self.slack_ns))

    def _check_windows(self) -> tuple[Level, str, dict[str, object]]:
        wc = self.stage.windower.counters
        sc = self.stage.counters
        values = {
            "windows_final": wc.windows,
            "windows_provisional": wc.provisional_windows,
            "windows_truncated": wc.truncated_windows,
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
        }
        if sc.bad_messages or self.qos_events.counts["incompatible_qos"]:
            return Level.WARN, "dropped malformed input", values
        if self.config.task is Task.FOOD_IDENTIFICATION and not self.motion_starts:
            return Level.OK, "waiting for motion_start", values
        return Level.OK, "ok", values


def main(args: list[str] | None = None) -> int:
    """Run the node (``ros2 run ext_sense_perception contact_window``)."""
    return run_node(ContactWindowNode, args)
