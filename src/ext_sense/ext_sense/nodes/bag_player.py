"""``bag_player`` node: publishes a recorded bag's messages, at recorded pace or flat out.

Messages go out as the bag stores them (CDR bytes), converted only when recorded with an older
definition of their type (``BagReader.current_cdr``). A reader thread paces them. By default
only a graph's inputs are played, so the graph recomputes its own windows and estimates.
"""

from __future__ import annotations

import functools
import importlib
import threading
import time
from dataclasses import dataclass
from typing import Any

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from ext_sense.topics import TOPIC_BIOTAC_PACKETS, TOPIC_GROUND_TRUTH, TOPIC_NUSKIN_PACKETS
from ext_sense_bags import STANDARD_TOPICS, BagError, BagReader
from ext_sense_runtime.callback_guard import CallbackGuard
from ext_sense_runtime.diagnostics import Level, Updater
from ext_sense_runtime.diagnostics_ros import DiagnosticsPublisher
from ext_sense_runtime.node_main import run_node
from ext_sense_runtime.parameters import declare_all, param
from ext_sense_runtime.qos import keep_last

_ro = functools.partial(param, read_only=True)
DEFAULT_TOPICS = [TOPIC_NUSKIN_PACKETS, TOPIC_BIOTAC_PACKETS, TOPIC_GROUND_TRUTH]
"""The graph inputs: the drivers' raw packets and the ground truth."""


def message_class(msgtype: str) -> type:
    """The rclpy message class of ``"pkg/msg/Name"`` (BagError: not importable here)."""
    pkg, _, name = msgtype.rpartition("/")
    module = pkg.replace("/", ".")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as err:
        raise BagError(f"Message type {msgtype!r} is not available to rclpy here.") from err


def publisher_qos(topic: str) -> QoSProfile:
    """The QoS a topic is published with: the standard table's, else reliable depth 100."""
    spec = STANDARD_TOPICS.get(topic)
    return keep_last(spec.depth if spec else 100, reliable=spec.reliable if spec else True)


@dataclass(frozen=True)
class BagPlayerParameters:
    """``bag_player``'s parameters, all read-only."""

    bag: str = _ro("", "rosbag2 directory or .mcap/.db3 file.")
    rate: float = _ro(1.0, "Playback speed: 1.0 recorded pace, 0 flat out.", low=0.0, high=1000.0)
    topics: tuple[str, ...] = _ro(
        tuple(DEFAULT_TOPICS), "Topics to play (those in the bag); ['all'] plays every topic."
    )
    start_delay_s: float = _ro(
        1.0, "Wait before the first message so subscribers can connect, s.", low=0.0, high=60.0
    )
    wait_subscribers_s: float = _ro(
        15.0,
        "Before playing, wait up to this long until every played topic has a subscriber, s.",
        low=0.0,
        high=600.0,
    )
    linger_s: float = _ro(
        0.5,
        "After the last message, wait this long "
        "(and for reliable subscribers' acks) before reporting done, s.",
        low=0.0,
        high=60.0,
    )


class BagPlayerNode(Node):
    """Replays a bag's topics on a reader thread."""

    PARAMETERS = BagPlayerParameters

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(kwargs.pop("node_name", "bag_player"), **kwargs)
        self.guard = CallbackGuard(self.get_logger().error)
        p = declare_all(self, BagPlayerParameters)
        self.bag_path, self.rate, topics = p.bag, p.rate, list(p.topics)
        self.start_delay_s, self.wait_subscribers_s = p.start_delay_s, p.wait_subscribers_s
        self.linger_s = p.linger_s
        self.published = 0
        self.play_seconds = 0.0
        self.total = 0
        self.error = ""
        self.finished = threading.Event()
        self._stop = threading.Event()
        self._pubs: dict[str, Any] = {}
        self._topics: list[str] = []
        try:
            with BagReader(self.bag_path) as bag:
                have = bag.topics
            wanted = list(have) if topics == ["all"] else [t for t in topics if t in have]
            for topic in wanted:
                cls = message_class(have[topic].msgtype)
                self._pubs[topic] = self.create_publisher(cls, topic, publisher_qos(topic))
                self.total += have[topic].count
            self._topics = wanted
        except BagError as err:
            self.error = str(err)
            self.get_logger().error(f"cannot play: {err}")
        self.updater = Updater(hardware_id=str(self.bag_path))
        self.updater.add_check("playback", self._check)
        self.guard.attach(self.updater)
        self.diagnostics = DiagnosticsPublisher(self, self.updater)
        self._thread = threading.Thread(
            target=self.guard(self._play), name="bag_player", daemon=True
        )
        if self._topics:
            self._thread.start()
        else:
            if not self.error:
                self.error = f"none of the topics {topics} is in the bag"
                self.get_logger().error(self.error)
            self.finished.set()

    def _play(self) -> None:
        try:
            deadline = time.monotonic() + self.wait_subscribers_s
            while time.monotonic() < deadline and not all(
                p.get_subscription_count() for p in self._pubs.values()
            ):
                if self._stop.wait(0.05):
                    return
            if self._stop.wait(self.start_delay_s):
                return
            wall0 = log0 = None
            started = time.monotonic()
            with BagReader(self.bag_path) as bag:
                for rec in bag.records(self._topics):
                    if self._stop.is_set():
                        return
                    if self.rate > 0:
                        if wall0 is None:
                            wall0, log0 = time.monotonic_ns(), rec.log_time_ns
                        due = wall0 + (rec.log_time_ns - log0) / self.rate
                        delay = (due - time.monotonic_ns()) / 1e9
                        if delay > 0 and self._stop.wait(delay):
                            return
                    self._pubs[rec.topic].publish(bag.current_cdr(rec))
                    self.published += 1
                    self.play_seconds = time.monotonic() - started
            self._linger()
            self.get_logger().info(f"played {self.published} messages from {self.bag_path}")
        except BagError as err:
            self.error = str(err)
            self.get_logger().error(f"playback stopped: {err}")
        finally:
            self.finished.set()

    def _linger(self) -> None:
        """Let the last messages reach their subscribers before ``finished`` is set."""
        from rclpy.duration import Duration

        for topic, pub in self._pubs.items():
            if publisher_qos(topic).reliability == ReliabilityPolicy.RELIABLE:
                pub.wait_for_all_acked(Duration(seconds=self.linger_s))
        self._stop.wait(self.linger_s)

    def _check(self) -> tuple[Level, str, dict[str, object]]:
        values = {"published": self.published, "total": self.total, "rate": self.rate}
        if self.error:
            return Level.ERROR, self.error, values
        return Level.OK, "done" if self.finished.is_set() else "playing", values

    def destroy_node(self) -> None:
        """Stop the reader thread before the publishers go."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the node (``ros2 run ext_sense bag_player``)."""
    return run_node(BagPlayerNode, args)
