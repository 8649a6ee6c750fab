"""A ``control_msgs/action/GripperCommand`` client with one callback per goal.

The handover uses the standard action, so any gripper action server works. rclpy's futures are
wrapped into one :class:`GripperReply` per goal, delivered on the executor. Every goal gets an
answer, since the middleware can lose a reply: a goal not accepted within ``accept_timeout_s``
ends ``unanswered``, a result not in within ``result_timeout_s`` ``timed out`` (and is
canceled); a later answer is ignored.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

from action_msgs.msg import GoalStatus
from control_msgs.action import GripperCommand
from rclpy.action import ActionClient
from rclpy.node import Node

from ext_sense_behaviours.nodes.deadline import Deadline


class GripperReply(NamedTuple):
    """How a goal ended: the result (``position_m`` NaN without one) and ``reason``.

    ``reason``: succeeded, aborted, canceled, rejected, no server, unanswered or timed out.
    """

    succeeded: bool
    position_m: float
    stalled: bool
    reached_goal: bool
    reason: str


_STATUS_NAMES = {
    GoalStatus.STATUS_SUCCEEDED: "succeeded",
    GoalStatus.STATUS_ABORTED: "aborted",
    GoalStatus.STATUS_CANCELED: "canceled",
}


ACCEPT_TIMEOUT_S = 2.0
"""Longest wait for a goal's acceptance (a server answers in milliseconds)."""
RESULT_TIMEOUT_S = 15.0
"""Longest wait for a goal's result (a 2F-85 closes fully in under 2 s at its slowest speed)."""


class GripperClient:
    """Sends gripper goals on ``action_name``, one at a time; a callback gets each outcome."""

    def __init__(
        self,
        node: Node,
        action_name: str,
        accept_timeout_s: float = ACCEPT_TIMEOUT_S,
        result_timeout_s: float = RESULT_TIMEOUT_S,
    ) -> None:
        self.action_name = action_name
        self._node = node
        self._client = ActionClient(node, GripperCommand, action_name)
        self.accept_timeout_s = float(accept_timeout_s)
        self.result_timeout_s = float(result_timeout_s)
        self.sent = 0
        self.timed_out = 0
        self._pending = 0  # the goal (``sent`` count) whose answer is awaited; 0: none
        self._deadline = Deadline(node)

    @property
    def busy(self) -> bool:
        """Whether a goal of ours awaits its answer."""
        return self._pending != 0

    def ready(self) -> bool:
        """Whether a server is there and no goal of ours is running."""
        return not self.busy and self._client.server_is_ready()

    def send(
        self, position_m: float, max_effort_n: float, on_done: Callable[[GripperReply], None]
    ) -> None:
        """Send one goal; ``on_done`` gets its outcome (also when no server answers)."""
        if not self._client.server_is_ready():
            on_done(GripperReply(False, float("nan"), False, False, "no server"))
            return
        goal = GripperCommand.Goal()
        goal.command.position, goal.command.max_effort = float(position_m), float(max_effort_n)
        self.sent += 1
        token = self._pending = self.sent

        def finish(reply: GripperReply) -> None:
            if self._pending != token:
                return  # answered already (a reply after its deadline)
            self._pending = 0
            self._deadline.disarm()
            on_done(reply)

        def _on_result(future: Any) -> None:
            response = future.result()
            result = response.result
            finish(
                GripperReply(
                    response.status == GoalStatus.STATUS_SUCCEEDED,
                    result.position,
                    result.stalled,
                    result.reached_goal,
                    _STATUS_NAMES.get(response.status, f"status {response.status}"),
                )
            )

        def _on_goal(future: Any) -> None:
            handle = future.result()
            if self._pending != token:
                if handle.accepted:  # accepted after its deadline: nobody waits for it
                    handle.cancel_goal_async()
                return
            if not handle.accepted:
                finish(GripperReply(False, float("nan"), False, False, "rejected"))
                return
            self._deadline.arm(self.result_timeout_s, lambda: no_result(handle))
            handle.get_result_async().add_done_callback(_on_result)

        def no_result(handle: Any) -> None:
            handle.cancel_goal_async()
            no_answer("timed out")

        def no_answer(reason: str) -> None:
            self.timed_out += 1
            finish(GripperReply(False, float("nan"), False, False, reason))

        self._deadline.arm(self.accept_timeout_s, lambda: no_answer("unanswered"))
        self._client.send_goal_async(goal).add_done_callback(_on_goal)

    def destroy(self) -> None:
        """Release the client's entities."""
        self._deadline.disarm()
        self._client.destroy()
