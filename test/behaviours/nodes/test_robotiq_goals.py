"""GripperCommand goals to the Robotiq node on the emulated gripper, as a user sends them.

- Right after start (before the first status read, while the gripper still activates) a goal
  waits for the gripper and its result carries the measured gap, not NaN.
- A goal the gripper cannot carry out as asked (NaN or infinite effort or speed, a gap beyond
  the stroke) is rejected before anything moves; a goal at the full stroke reaches it.
"""

from __future__ import annotations

import math
import os

import pytest

rclpy = pytest.importorskip("rclpy")

from action_msgs.msg import GoalStatus  # noqa: E402
from control_msgs.action import GripperCommand, ParallelGripperCommand  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosutil import spin_until  # noqa: E402

from ext_sense_behaviours.nodes.robotiq_gripper import RobotiqGripperNode  # noqa: E402
from ext_sense_sim.devices.robotiq_emulator import (  # noqa: E402
    GripperModel,
    PtyGripper,
    RobotiqEmulator,
)

pytestmark = [pytest.mark.ros, pytest.mark.timeout(60)]

NS = f"/robotiq_goals_{os.getpid()}"
GRIPPER_ACTION = f"{NS}/gripper_cmd"
PARALLEL_ACTION = f"{NS}/parallel/gripper_cmd"


@pytest.fixture
def rig():
    """The gripper node on a fresh emulated 2F-85 (activation 2 s), and a client node."""
    context = rclpy.Context()
    rclpy.init(context=context, args=[])
    executor = SingleThreadedExecutor(context=context)
    emulator = RobotiqEmulator(GripperModel(activation_s=2.0, object_position=255))
    with PtyGripper(emulator) as pty:
        client = rclpy.create_node("client", context=context)
        executor.add_node(client)

        def start():
            gripper = RobotiqGripperNode(
                context=context,
                parameter_overrides=[
                    Parameter("port", value=pty.path),
                    Parameter("poll_rate_hz", value=20.0),
                    Parameter("controller_name", value=NS),
                    Parameter("parallel_controller_name", value=f"{NS}/parallel"),
                ],
            )
            executor.add_node(gripper)
            nodes.append(gripper)
            return gripper

        nodes = [client]
        try:
            yield executor, client, start
        finally:
            for node in nodes:
                executor.remove_node(node)
                node.destroy_node()
            executor.shutdown()
            rclpy.try_shutdown(context=context)


def _send(executor, action: ActionClient, goal):
    """``(accepted, status, result)`` of one goal; status and result ``None`` when rejected."""
    sent = action.send_goal_async(goal)
    assert spin_until(executor, sent.done)
    if not sent.result().accepted:
        return False, None, None
    result = sent.result().get_result_async()
    assert spin_until(executor, result.done, timeout_s=15.0)
    return True, result.result().status, result.result().result


def _gripper_goal(position: float, max_effort: float = 0.0):
    goal = GripperCommand.Goal()
    goal.command.position, goal.command.max_effort = position, max_effort
    return goal


def test_a_goal_sent_right_after_start_waits_for_the_gripper_and_reports_its_gap(rig):
    executor, client, start = rig
    action = ActionClient(client, GripperCommand, GRIPPER_ACTION)
    gripper = start()
    assert spin_until(executor, action.server_is_ready)
    status = gripper.status  # none read yet, or the gripper still activating
    assert status is None or not status.ready
    accepted, status, result = _send(executor, action, _gripper_goal(0.04, 50.0))
    assert accepted
    assert status == GoalStatus.STATUS_SUCCEEDED
    assert math.isfinite(result.position)
    assert result.position == pytest.approx(0.04, abs=0.001)
    assert result.reached_goal


def test_a_goal_the_gripper_cannot_carry_out_is_rejected_and_nothing_moves(rig):
    executor, client, start = rig
    action = ActionClient(client, GripperCommand, GRIPPER_ACTION)
    parallel = ActionClient(client, ParallelGripperCommand, PARALLEL_ACTION)
    gripper = start()
    assert spin_until(executor, lambda: gripper.status is not None and gripper.status.ready)
    assert spin_until(executor, action.server_is_ready)
    assert spin_until(executor, parallel.server_is_ready)
    for goal in (
        _gripper_goal(0.02, float("nan")),
        _gripper_goal(0.02, float("inf")),
        _gripper_goal(float("nan")),
        _gripper_goal(1.0),  # beyond the 2F-85's 0.085 m stroke
    ):
        assert _send(executor, action, goal) == (False, None, None)
    goal = ParallelGripperCommand.Goal()
    goal.command.position, goal.command.velocity = [0.02], [float("nan")]
    assert _send(executor, parallel, goal) == (False, None, None)
    assert gripper.goals["rejected"] == 5
    assert gripper.worker is not None
    assert gripper.worker.counters.commands_sent == 0  # nothing moved
    accepted, status, result = _send(executor, action, _gripper_goal(0.085))
    assert (accepted, status) == (True, GoalStatus.STATUS_SUCCEEDED)
    assert result.reached_goal
    assert result.position == pytest.approx(0.085)
