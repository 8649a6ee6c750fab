"""Intra-process delivery between nodes of one process, as rclcpp's intra-process comms.

rclpy has none (each hop a serialisation, a loopback delivery and a wake-up: docs/benchmarks.md,
run 8). After :func:`enable`, an :class:`IntraProcessPublisher` hands each message straight to
this process's subscriptions in the publishing callback, then publishes its bytes once; the
subscriptions drop the byte-identical middleware copies (rclpy's ``EventsExecutor`` cannot pass
a ``MessageInfo``). Delivery is synchronous: both nodes share one single-threaded executor, and
the message object itself is handed over (a subscriber must not change it, nor a publisher
reuse it).
"""

from __future__ import annotations

import weakref
from collections import deque
from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.subscription import Subscription

_enabled = False

HANDED_OVER_KEPT_MIN = 64
"""Fewest handed-over messages a subscription remembers until their middleware copies come."""


def enable() -> None:
    """Deliver between this process's nodes directly from now on (nodes built after the call)."""
    global _enabled
    _enabled = True


_TOPICS: weakref.WeakKeyDictionary[Any, dict[str, list[IntraProcessSubscription]]] = (
    weakref.WeakKeyDictionary()
)
"""The intra-process subscriptions per rclpy context (gone with it), per resolved topic name."""


def _topic(node: Node, name: str) -> list[IntraProcessSubscription]:
    return _TOPICS.setdefault(node.context, {}).setdefault(name, [])


class IntraProcessPublisher:
    """A publisher that also hands messages straight to this process's subscriptions."""

    def __init__(self, node: Node, publisher: Publisher) -> None:
        self.publisher = publisher
        self._topic = _topic(node, publisher.topic_name)

    def publish(self, msg: Any) -> None:
        """Hand ``msg`` to the local subscriptions' callbacks, then publish it."""
        subscriptions = tuple(self._topic)
        if not subscriptions:
            self.publisher.publish(msg)
            return
        delivered: list[IntraProcessSubscription] = []
        try:
            for subscription in subscriptions:
                if subscription.alive():
                    delivered.append(subscription)  # also when its callback raises: no copy
                    subscription.deliver_local(msg)
        finally:
            # serialised once, after the hand-over, and left with the subscriptions first
            raw = serialize_message(msg)
            for subscription in delivered:
                subscription.await_copy(raw)
            self.publisher.publish(raw)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.publisher, name)


def create_publisher(
    node: Node, msg_type: type, topic: str, qos: QoSProfile | int, **kwargs: Any
) -> Publisher | IntraProcessPublisher:
    """``node.create_publisher(...)``, intra-process when :func:`enable` was called."""
    publisher = node.create_publisher(msg_type, topic, qos, **kwargs)
    return IntraProcessPublisher(node, publisher) if _enabled else publisher


class IntraProcessSubscription:
    """A subscription fed directly by this process's publishers, and by the middleware else.

    Counters: ``local`` messages handed over in-process, ``remote`` ones from the middleware
    delivered, ``duplicates`` middleware copies of handed-over messages dropped.
    """

    def __init__(
        self,
        node: Node,
        msg_type: type,
        topic: str,
        callback: Callable[[Any], Any],
        qos: QoSProfile | int,
        **kwargs: Any,
    ) -> None:
        self.node = node
        self.msg_type = msg_type
        self.callback = callback
        self.local = self.remote = self.duplicates = 0
        # the bytes handed over whose middleware copy has not come yet, oldest first
        depth = qos if isinstance(qos, int) else qos.depth
        self._awaited: deque[bytes] = deque(maxlen=max(HANDED_OVER_KEPT_MIN, 2 * depth))
        self.subscription: Subscription = node.create_subscription(
            msg_type, topic, self._on_middleware, qos, raw=True, **kwargs
        )
        self._topic = _topic(node, self.subscription.topic_name)
        self._topic.append(self)

    def alive(self) -> bool:
        """Whether the subscription still exists; one destroyed with its node is forgotten."""
        if self.subscription in self.node.subscriptions:
            return True
        self._topic.remove(self)
        return False

    def deliver_local(self, msg: Any) -> None:
        """Hand over a message of this process's publisher."""
        if not self.local:
            self.node.get_logger().info(
                f"{self.subscription.topic_name}: messages of this process handed over in "
                "process (intra-process; their middleware copies are dropped)"
            )
        self.local += 1
        self.callback(msg)

    def await_copy(self, raw: bytes) -> None:
        """Remember the serialised form of a handed-over message: its middleware copy is dropped."""
        self._awaited.append(raw)

    def _on_middleware(self, raw: bytes) -> None:
        for i, awaited in enumerate(self._awaited):
            if len(awaited) == len(raw) and awaited == raw:
                del self._awaited[i]
                self.duplicates += 1
                return
        self.remote += 1
        self.callback(deserialize_message(raw, self.msg_type))


def delivery_values(subscription: Any, prefix: str) -> dict[str, int]:
    """Diagnostics values of an intra-process subscription's counters; none for a plain one."""
    if not isinstance(subscription, IntraProcessSubscription):
        return {}
    return {
        f"{prefix}_in_process": subscription.local,
        f"{prefix}_from_middleware": subscription.remote,
        f"{prefix}_middleware_copies_dropped": subscription.duplicates,
    }


def create_subscription(
    node: Node,
    msg_type: type,
    topic: str,
    callback: Callable[[Any], Any],
    qos: QoSProfile | int,
    **kwargs: Any,
) -> Subscription | IntraProcessSubscription:
    """``node.create_subscription(...)``, intra-process when :func:`enable` was called."""
    if not _enabled:
        return node.create_subscription(msg_type, topic, callback, qos, **kwargs)
    return IntraProcessSubscription(node, msg_type, topic, callback, qos, **kwargs)
