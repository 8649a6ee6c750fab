"""``recorder`` node: writes topics to a rosbag2 (mcap) bag without the ``ros2`` CLI.

Raw subscriptions: the CDR bytes go into the bag untouched, with the receive time as log time.
A publisher's type hash that differs from the bag's is an ERROR on ``/diagnostics``. The
writer flushes at least every ``flush_period_s``, so a killed recorder loses at most that
(``ext-sense bag recover``). A bag that cannot be created or written stops the recording, not
the node: logged once, an ERROR on ``/diagnostics``, later messages counted ``not_recorded``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSProfile

from ext_sense.nodes.bag_player import message_class
from ext_sense_bags import STANDARD_TOPICS, BagError, BagWriter, type_hash
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all, param
from ext_sense_runtime.qos import keep_last


def subscription_qos(topic: str) -> QoSProfile:
    """Best effort for sensor streams (and unknown topics), reliable for the rest; depth 1000."""
    spec = STANDARD_TOPICS.get(topic)
    return keep_last(1000, reliable=bool(spec and spec.reliable))


@dataclass(frozen=True)
class RecorderParameters:
    """``recorder``'s parameters, all read-only."""

    bag: str = param("", "Directory of the new bag (must not exist).", read_only=True)
    storage: str = param("mcap", "Storage plugin: mcap or sqlite3.", read_only=True)
    topics: tuple[str, ...] = param(
        tuple(sorted(STANDARD_TOPICS)),
        "Topics to record; types from the standard table or discovered from the graph.",
        read_only=True,
    )
    discover_period_s: float = param(
        0.5,
        "How often topics of unknown type are looked up, s.",
        low=0.05,
        high=60.0,
        read_only=True,
    )
    flush_period_s: float = param(
        1.0,
        "Longest time between writes to the disk (mcap chunk closed, sqlite3 commit), s: "
        "what a killed recorder can lose.",
        low=0.05,
        high=10.0,
        read_only=True,
    )


class RecorderNode(Node):
    """Records the given topics into a new bag until shut down."""

    PARAMETERS = RecorderParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "recorder"), **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        p = declare_all(self, RecorderParameters)
        self.path, storage, topics = p.bag, p.storage, list(p.topics)
        self.discover_s, self.flush_period_s = p.discover_period_s, p.flush_period_s
        self.failed = ""
        """Why recording stopped ('' while it records)."""
        self.not_recorded = 0
        self.received: dict[str, int] = {}
        self.hash_mismatch: dict[str, str] = {}
        self._checked_hash: set[str] = set()
        self._waiting = [t for t in topics if t not in STANDARD_TOPICS]
        self.updater = Updater(hardware_id=str(self.path))
        self.updater.add_check("recording", self._check)
        self.guard.attach(self.updater)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)
        try:
            self.writer = BagWriter(
                self.path, storage=storage, flush_period_s=self.flush_period_s
            ).open()
        except BagError as err:
            self._fail(err)
            return
        self.writer.set_custom_data("recorded_by", "ext-sense record")
        for topic in topics:
            if topic in STANDARD_TOPICS:
                self._subscribe(topic, STANDARD_TOPICS[topic].msgtype)
        self.create_timer(self.discover_s, self.guard(self._discover))
        self.create_timer(min(0.1, self.flush_period_s / 4), self.guard(self._flush_if_due))

    def _subscribe(self, topic: str, msgtype: str) -> None:
        try:
            cls = message_class(msgtype)
            self.writer.add_topic(topic, msgtype)
        except BagError as err:
            self.get_logger().error(f"not recording {topic}: {err}")
            return
        self.received[topic] = 0

        def callback(data: bytes, topic: str = topic) -> None:
            if self.failed:
                self.not_recorded += 1
                return
            try:
                self.writer.write_raw(topic, time.time_ns(), data)
            except BagError as err:
                self.not_recorded += 1
                self._fail(err)
                return
            self.received[topic] += 1

        self.create_subscription(
            cls,
            topic,
            self.guard.wrap(callback, name=f"record {topic}"),
            subscription_qos(topic),
            raw=True,
        )

    def _fail(self, err: BagError) -> None:
        """Stop recording (once): log the reason and show it on ``/diagnostics``."""
        if not self.failed:
            self.failed = str(err)
            self.get_logger().error(f"recording stopped: {self.failed}")

    def _flush_if_due(self) -> None:
        if self.failed:
            return
        try:
            self.writer.flush_if_due()
        except BagError as err:
            self._fail(err)

    def _discover(self) -> None:
        if self.failed:
            return
        if self._waiting:
            types = dict(self.get_topic_names_and_types())
            for topic in list(self._waiting):
                if types.get(topic):
                    self._waiting.remove(topic)
                    self._subscribe(topic, types[topic][0])
        for topic in self.received:
            if topic in self._checked_hash:
                continue
            infos = self.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            self._checked_hash.add(topic)
            expected = type_hash(self.writer.msgtype(topic) or "")
            for info in infos:
                got = str(info.topic_type_hash)
                if got.startswith("RIHS01_") and got != expected:
                    self.hash_mismatch[topic] = got
                    self.get_logger().error(
                        f"type hash of {topic} from {info.node_name} is {got}; the bag "
                        f"records {expected} (rebuild ext_sense_msgs?)"
                    )

    def _check(self) -> tuple[Level, str, dict[str, object]]:
        values: dict[str, object] = {f"messages_{t}": n for t, n in self.received.items()}
        values["waiting_for_type"] = ",".join(self._waiting)
        writer = getattr(self, "writer", None)  # absent when the bag could not be created
        values["flushed"] = writer.flushed if writer is not None else 0
        values["not_recorded"] = self.not_recorded
        if self.failed:
            return Level.ERROR, f"recording stopped: {self.failed}", values
        if self.hash_mismatch:
            return Level.ERROR, f"type hash mismatch on {sorted(self.hash_mismatch)}", values
        return Level.OK, "recording", values

    def destroy_node(self) -> None:
        """Close the bag (index and metadata) before the node goes."""
        if not self.failed:
            try:
                self.writer.close()
            except BagError as err:
                self._fail(err)
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the node (``ros2 run ext_sense recorder --ros-args -p bag:=DIR``)."""
    return run_node(RecorderNode, args)
