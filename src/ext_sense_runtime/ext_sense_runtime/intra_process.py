"""Intra-process delivery between nodes of one process, as rclcpp's intra-process comms.

When the hot path runs in one process (``hot_path:=one_process``), a packet still went from the
driver's publisher through the middleware to the window node's subscription in the same
process, and the window likewise to the inference node: each hop a serialisation, a loopback
delivery and an executor wake-up (docs/benchmarks.md, run 8). rclcpp avoids this
for composed nodes (``use_intra_process_comms``); rclpy has no such thing, so this module does
the same for the hot path's topics:

- :class:`IntraProcessPublisher` hands each message, before it goes to the middleware, straight
  to the callbacks of this process's :func:`create_subscription` subscriptions on that topic
  (same context, same resolved topic name), in the publishing callback: the chain driver ->
  window -> estimate runs in the driver's one callback.
- The subscription still takes what the middleware delivers (a bag replay, another process's
  driver), but drops its copies of what this process's intra-process publishers handed over:
  the publisher serialises each message once, publishes those bytes, and leaves them with the
  local subscriptions, which take the middleware's messages serialised (``raw``) and drop a
  byte-identical one (so a dropped copy is never deserialised). Matching bytes rather than
  publisher gids: rclpy's ``EventsExecutor`` cannot call a subscription with its
  ``MessageInfo`` ("SystemError: null argument to internal routine", Kilted), and the bytes
  need no graph lookups.

It applies only after :func:`enable` (the node group's process calls it before building its
nodes: ``ext_sense.runner.run_in_process``); a process of one node publishes and subscribes as
rclpy does. Delivery is synchronous on the publisher's thread, so both nodes must be spun by
one single-threaded executor (the node group's is). As with rclcpp's, the message object itself
is handed over: a subscriber must not change it, nor a publisher reuse it after publishing.
"""

from __future__ import annotations

import weakref
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.subscription import Subscription

_enabled = False

HANDED_OVER_KEPT_MIN = 64
"""Fewest handed-over messages a subscription remembers until the middleware's copy comes (at
least its QoS depth: a copy further back than that was dropped from the reader's queue)."""


def enable() -> None:
    """Deliver between this process's nodes directly from now on (nodes built after the call)."""
    global _enabled
    _enabled = True


def enabled() -> bool:
    """Whether :func:`enable` was called in this process."""
    return _enabled


@dataclass
class _Topic:
    """The intra-process subscriptions of one topic in one context."""

    subscriptions: list[IntraProcessSubscription] = field(default_factory=list)


_TOPICS: weakref.WeakKeyDictionary[Any, dict[str, _Topic]] = weakref.WeakKeyDictionary()
"""Per rclpy context (gone with it), per resolved topic name."""


def _topic(node: Node, name: str) -> _Topic:
    return _TOPICS.setdefault(node.context, {}).setdefault(name, _Topic())


class IntraProcessPublisher:
    """A publisher that also hands messages straight to this process's subscriptions.

    Attributes not defined here are the rclpy publisher's (``topic_name``,
    ``get_subscription_count``...).
    """

    def __init__(self, node: Node, publisher: Publisher) -> None:
        self.publisher = publisher
        self._topic = _topic(node, publisher.topic_name)

    def publish(self, msg: Any) -> None:
        """Hand ``msg`` to the local subscriptions' callbacks, then publish it."""
        subscriptions = tuple(self._topic.subscriptions)
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
            # serialised after the hand-over (0.04-0.18 ms for a 380 kB window, off the hot path),
            # once as publish would, and left with the subscriptions before their copy can come
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
        self._topic.subscriptions.append(self)

    def alive(self) -> bool:
        """Whether the subscription still exists; one destroyed with its node is forgotten."""
        if self.subscription in self.node.subscriptions:
            return True
        self._topic.subscriptions.remove(self)
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
