"""``collector``: the ROS side of ``ext-sense collect``: records a session and hands events on.

Raw subscriptions write the sensor stream and the arm and gripper state into the session's bag;
windows, estimates, motion starts, offers, decisions and any independent truth are also queued
on :attr:`events` for the operator's loop. Labels go in as ``ContactGroundTruth``. It lives in
the command's process (not a graph node), which shares its bag writer and event queue.

The simulated device starts its trials when the collector subscribes to the simulator's truth,
so that subscription waits until the sensor stream's publisher has matched the recording (and
:data:`MATCH_SETTLE_S` more, for the publisher's side): without it, a loaded machine could play
the first trials before the stream reached the bag.
"""

from __future__ import annotations

import queue
import time
from typing import Any

from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from std_msgs.msg import Bool, String

from ext_sense.collect.graph import (
    COLLECTOR_NODE,
    MATCH_SETTLE_S,
    SIM_TRIGGER_TOPIC,
    SIM_TRUTH_TOPIC,
    STREAM_WAIT_S,
)
from ext_sense.nodes.bag_player import message_class
from ext_sense.nodes.recorder import subscription_qos
from ext_sense_bags import BagError, BagWriter, ground_truth
from ext_sense_msgs.msg import ContactEstimate, ContactGroundTruth, ContactWindow
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.qos import COMMAND_QOS
from ext_sense_runtime.stamps import fill_stamp

TRUTH_TOPIC = "/extsense/ground_truth"
DECODED = {
    "/extsense/contact_window": ContactWindow,
    "/extsense/contact_estimate": ContactEstimate,
    "/extsense/motion_start": ContactGroundTruth,
    "/extsense/handover/offer": ContactGroundTruth,
    SIM_TRUTH_TOPIC: ContactGroundTruth,
    "/food/decision": String,
    "/handover/decision": String,
}
STATE_HINTS = ("arm/state", "gripper/status", "joint_states", "robot_state")
"""Topics whose names end so are the arm and gripper state, recorded when the graph has them."""


class CollectorNode(Node):
    """Records a session's topics and queues the events the operator is asked about."""

    def __init__(
        self,
        writer: BagWriter,
        stream_topic: str,
        mocap_topic: str = "",
        **kwargs: Any,
    ) -> None:
        super().__init__(COLLECTOR_NODE, **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        self.writer = writer
        self.events: queue.Queue[tuple[str, Any]] = queue.Queue()
        self.received: dict[str, int] = {}
        self.skipped: set[str] = set()
        # topic -> the subscription recording it (not "_subscriptions": rclpy's Node has that)
        self._recorded_by: dict[str, Any] = {}
        self.failed = ""
        self.stream_topic = stream_topic
        self._record(stream_topic, message_class(writer.specs[stream_topic].msgtype))
        for topic, cls in DECODED.items():
            if topic != SIM_TRUTH_TOPIC:
                self._record(topic, cls, decode=cls)
        self._stream_wait_end = time.monotonic() + STREAM_WAIT_S
        self._stream_matched_at: float | None = None
        self._truth_timer = self.create_timer(0.05, self.guard(self._subscribe_truth_when_streamed))
        if mocap_topic:
            self._record(mocap_topic, PoseStamped, decode=PoseStamped, kind="mocap")
        self.food_start = self.create_publisher(Bool, "/food/start", COMMAND_QOS)
        self.sim_trigger = self.create_publisher(ContactGroundTruth, SIM_TRIGGER_TOPIC, COMMAND_QOS)
        self.create_timer(0.5, self.guard(self._discover))
        self.create_timer(0.1, self.guard(self._flush))

    def _record(self, topic: str, cls: type, decode: type | None = None, kind: str = "") -> None:
        msgtype = cls.__module__.split(".")[0] + "/msg/" + cls.__name__
        try:
            self.writer.add_topic(topic, msgtype)
        except BagError as err:  # e.g. a type outside the bag's typestore: noted once
            self.skipped.add(topic)
            self.get_logger().warning(f"not recording {topic}: {err}")
            return
        self.received[topic] = 0

        def callback(data: bytes, topic: str = topic) -> None:
            if not self.failed:
                try:
                    self.writer.write_raw(topic, time.time_ns(), data)
                except BagError as err:
                    self.failed = str(err)
            self.received[topic] += 1
            if decode is not None:
                self.events.put((kind or topic, deserialize_message(data, decode)))

        self._recorded_by[topic] = self.create_subscription(
            cls,
            topic,
            self.guard.wrap(callback, name=f"collect {topic}"),
            subscription_qos(topic),
            raw=True,
        )

    def _subscribe_truth_when_streamed(self) -> None:
        """Subscribe to the simulator's truth once the stream is recorded (or after its wait)."""
        now = time.monotonic()
        if self._stream_matched_at is None:
            if self.matched_publishers(self.stream_topic) == 0:
                if now < self._stream_wait_end:
                    return
                self.get_logger().warning(
                    f"no publisher of {self.stream_topic} within {STREAM_WAIT_S:.0f} s: the "
                    "simulated device may start before the stream is recorded"
                )
            self._stream_matched_at = now
        if now - self._stream_matched_at < MATCH_SETTLE_S:
            return
        self._truth_timer.cancel()  # once
        self.destroy_timer(self._truth_timer)
        if SIM_TRUTH_TOPIC not in self.received:
            self._record(SIM_TRUTH_TOPIC, ContactGroundTruth, decode=ContactGroundTruth)

    def _discover(self) -> None:
        """Record the arm and gripper state topics the graph has (found by name, typed by it)."""
        for topic, types in self.get_topic_names_and_types():
            seen = topic in self.received or topic in self.skipped
            if seen or not topic.endswith(STATE_HINTS) or not types:
                continue
            try:
                self._record(topic, message_class(types[0]))
            except Exception as err:  # a type outside the bag's typestore: noted, not fatal
                self.skipped.add(topic)
                self.get_logger().warning(f"not recording {topic}: {err}")

    def _flush(self) -> None:
        if not self.failed:
            try:
                self.writer.flush_if_due()
            except BagError as err:
                self.failed = str(err)

    def write_label(self, task: str, trial: int, onset_ns: int, label: str, rod_m: float) -> None:
        """Write one trial's label into the bag as ``ContactGroundTruth`` stamped at its onset."""
        tap = task == "tap_localization"
        msg = ground_truth(
            onset_ns,
            task,
            trial,
            tap_position_m=float(label) if tap else float("nan"),
            rod_length_m=rod_m if tap else float("nan"),
            class_label="" if tap else label,
            frame_id="collect",
        )
        self.writer.write(TRUTH_TOPIC, max(onset_ns, time.time_ns()), msg)

    def subscribers(self, topic: str) -> set[str]:
        """Names of the nodes subscribed to ``topic`` (to know who will hear a trigger)."""
        return {info.node_name for info in self.get_subscriptions_info_by_topic(topic)}

    def publishers(self, topic: str) -> set[str]:
        """Names of the nodes publishing ``topic`` (to know the recording will hear them)."""
        return {info.node_name for info in self.get_publishers_info_by_topic(topic)}

    def matched_publishers(self, topic: str) -> int:
        """Publishers matched to the recording's subscription to ``topic`` (0: not recorded)."""
        sub = self._recorded_by.get(topic)
        return sub.get_publisher_count() if sub is not None else 0

    def trigger_sim(self, task: str, label: str) -> None:
        """Have the simulated device play its next grasp now, as ``label`` (``""``: its draw)."""
        msg = ContactGroundTruth(
            task=task, tap_position_m=float("nan"), rod_length_m=float("nan"), class_label=label
        )
        fill_stamp(msg.header.stamp, time.time_ns())
        self.sim_trigger.publish(msg)

    def start_probe(self) -> None:
        """Ask the food behaviour for one probe (``/food/start``)."""
        self.food_start.publish(Bool(data=True))
