"""Counting QoS events (deadline missed, messages lost, incompatible QoS) per node.

Registering the callbacks is what ros2/demos recommends; counting them lets diagnostics show
a mismatch (e.g. a reliable subscriber on a best-effort stream) instead of silence.
"""

from __future__ import annotations

from collections import Counter

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks


class QosEventCounter:
    """Hands out event callbacks for publishers and subscriptions and counts what they see."""

    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()

    def _count(self, key: str, attr: str | None = None):
        def callback(event: object) -> None:
            self.counts[key] += int(getattr(event, attr, 1) or 1) if attr else 1

        return callback

    def subscription(self) -> SubscriptionEventCallbacks:
        """Callbacks for ``create_subscription(..., event_callbacks=...)``."""
        return SubscriptionEventCallbacks(
            deadline=self._count("deadline_missed"),
            incompatible_qos=self._count("incompatible_qos"),
            message_lost=self._count("messages_lost", "total_count_change"),
        )

    def publisher(self) -> PublisherEventCallbacks:
        """Callbacks for ``create_publisher(..., event_callbacks=...)``."""
        return PublisherEventCallbacks(
            deadline=self._count("deadline_missed"),
            incompatible_qos=self._count("incompatible_qos"),
        )

    def as_values(self) -> dict[str, object]:
        """Counters as diagnostics key-values."""
        return {
            "qos_deadline_missed": self.counts["deadline_missed"],
            "qos_incompatible": self.counts["incompatible_qos"],
            "qos_messages_lost": self.counts["messages_lost"],
        }
