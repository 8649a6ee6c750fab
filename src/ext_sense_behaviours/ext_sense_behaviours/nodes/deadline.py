"""One deadline at a time on a node's executor: how long an action client waits for an answer.

The middleware can lose an action's answer, so the action clients end the goal themselves when
it expires; on the node's executor, the expiry never runs beside the node's callbacks.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.node import Node


class Deadline:
    """A one-shot timer on ``node`` that can be re-armed or disarmed (``guard`` wraps it)."""

    def __init__(
        self, node: Node, guard: Callable[[Callable[..., Any]], Callable[..., Any]] | None = None
    ) -> None:
        self._node = node
        self._wrap = guard or (lambda f: f)
        self._timer: Any = None

    @property
    def armed(self) -> bool:
        """Whether an expiry is pending."""
        return self._timer is not None

    def arm(self, timeout_s: float, on_expiry: Callable[[], None]) -> None:
        """Call ``on_expiry`` once, ``timeout_s`` from now, unless disarmed or re-armed first."""
        self.disarm()

        def expired() -> None:
            self.disarm()
            on_expiry()

        self._timer = self._node.create_timer(timeout_s, self._wrap(expired))

    def disarm(self) -> None:
        """Cancel the pending expiry (nothing when none is pending)."""
        if self._timer is not None:
            self._node.destroy_timer(self._timer)
            self._timer = None
