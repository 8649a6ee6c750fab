"""A ``control_msgs/action/GripperCommand`` client with one callback per goal.

The handover commands the gripper through the standard action, not through anything of our
Robotiq node, so it works unchanged with ``ros2_control``'s ``GripperActionController`` (or
PickNik's Robotiq driver) on ``/robotiq_gripper_controller/gripper_cmd``. This wraps rclpy's
``ActionClient`` futures into one :class:`GripperReply` per goal, delivered on the executor, so
the node's decisions stay plain callbacks. Not an executable: a helper of the behaviour nodes.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

from action_msgs.msg import GoalStatus
from control_msgs.action import GripperCommand
from rclpy.action import ActionClient
from rclpy.node import Node


class GripperReply(NamedTuple):
    """How a goal ended.

    Attributes:
        succeeded: The server reported success.
        position_m: Final finger gap, metres (NaN when the server sent no result).
        stalled: The fingers stopped on an object (object detected).
        reached_goal: The fingers reached the commanded gap.
        reason: ``succeeded``, ``aborted``, ``canceled``, ``rejected`` or ``no server``.
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


class GripperClient:
    """Sends gripper goals, one at a time, and reports each outcome to a callback.

    Args:
        node: The node that owns the client.
        action_name: Full action name (``/robotiq_gripper_controller/gripper_cmd``).
    """

    def __init__(self, node: Node, action_name: str) -> None:
        self.action_name = action_name
        self._client = ActionClient(node, GripperCommand, action_name)
        self.busy = False
        self.sent = 0

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
        self.busy = True
        self.sent += 1

        def _on_result(future: Any) -> None:
            self.busy = False
            response = future.result()
            result = response.result
            on_done(
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
            if not handle.accepted:
                self.busy = False
                on_done(GripperReply(False, float("nan"), False, False, "rejected"))
                return
            handle.get_result_async().add_done_callback(_on_result)

        self._client.send_goal_async(goal).add_done_callback(_on_goal)

    def destroy(self) -> None:
        """Release the client's entities."""
        self._client.destroy()
